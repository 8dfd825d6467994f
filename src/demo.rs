//! `ace demo`: the main job on the bundled defaults. Every bundled human clip (`assets/motions/`) is
//! retargeted onto every bundled character with its shipped checkpoint (`assets/checkpoints/`); for
//! each pair it writes the glTF binary (with the human beside the character), the robot command
//! trajectory (JSON, CSV) and the clip's metrics, then a report over all pairs (`report.md`,
//! `report.json`) and, per character, a picture of the retargeted first clip (`<character>.png`: the
//! character at five moments, the human beside it).

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use ace::models::human::HumanClip;
use ace::models::metrics::{MetricsReport, percent};
use ace::models::nalgebra::Vector3;
use anyhow::{Context, Result, bail};
use serde_json::json;

use crate::output::{Outputs, Planned};
use crate::scoring::Scorer;
use crate::{characters, picture, retarget};

/// The bundled clips, sorted by name.
fn bundled_clips() -> Result<Vec<PathBuf>> {
    let dir = characters::assets_dir().join("motions");
    let mut clips: Vec<PathBuf> = std::fs::read_dir(&dir)
        .with_context(|| format!("listing {}", dir.display()))?
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.extension().is_some_and(|e| e.eq_ignore_ascii_case("bvh")))
        .collect();
    clips.sort();
    if clips.is_empty() {
        bail!("{}: no bundled BVH clips", dir.display());
    }
    Ok(clips)
}

/// Names of the clips' outputs: each file stem, with `-2`, `-3`, … added to the second and later of
/// clips that share a stem (`a/walk.bvh` and `b/walk.bvh` must not write the same files).
pub fn unique_names(clips: &[PathBuf]) -> Vec<String> {
    // Compared ignoring case, as the file systems that ignore it would.
    let mut used = std::collections::HashSet::new();
    clips
        .iter()
        .map(|p| {
            let stem = p.file_stem().map_or_else(|| "clip".to_string(), |s| s.to_string_lossy().into_owned());
            let mut name = stem.clone();
            let mut k = 1;
            while !used.insert(name.to_lowercase()) {
                k += 1;
                name = format!("{stem}-{k}");
            }
            name
        })
        .collect()
}

/// Runs the demo for `characters` (bundled names) and `clips` (BVH files; the bundled ones when empty),
/// writing into `out`; `mapping` is a joint-mapping file for every clip; `backend` runs the networks.
pub fn run(
    characters_arg: &[String],
    clips: &[PathBuf],
    out: &Path,
    mapping: Option<&Path>,
    backend: retarget::Backend,
) -> Result<()> {
    let clips = if clips.is_empty() { bundled_clips()? } else { clips.to_vec() };
    let import = retarget::import_options(mapping)?;
    let names = unique_names(&clips);
    let mut outputs = Outputs::new();
    for p in &clips {
        outputs.input_clip(p, "an input clip", mapping);
    }
    let mut loaded = Vec::new();
    for name in characters_arg {
        let (urdf, tree, morph) = characters::load(name)?;
        let dir = retarget::default_checkpoint(name)?;
        outputs.input_character(&urdf).input(&dir, "a shipped checkpoint");
        loaded.push((name, tree, morph, dir));
    }
    // Every output path is gathered and checked against every input before any work: no two clips
    // may write one file (the trajectory of `walk.metrics.bvh` would be the metrics of `walk.bvh`).
    let mut planned = Planned::new();
    for (p, what) in [(out.join("report.md"), "the report (Markdown)"), (out.join("report.json"), "the report (JSON)")] {
        planned.add(&p, what.into(), "rename the clip")?;
    }
    for (_, tree, ..) in &loaded {
        planned.add(&out.join(format!("{}.png", tree.name)), format!("the picture of {}", tree.name), "rename the clip")?;
        for (clip, n) in clips.iter().zip(&names) {
            let glb = out.join(&tree.name).join(format!("{n}.glb"));
            for (p, role) in retarget::output_paths(&glb).iter().zip(retarget::OUTPUT_ROLES) {
                planned.add(p, format!("{role} of {} on {}", clip.display(), tree.name), "rename one of the clips")?;
            }
        }
    }
    for p in planned.paths() {
        outputs.check(p)?;
    }
    let mut humans: Vec<HumanClip> = Vec::with_capacity(clips.len());
    for (p, name) in clips.iter().zip(&names) {
        let mut clip = HumanClip::from_bvh_file(p, &import)?;
        for w in clip.warnings() {
            eprintln!("warning: {w}");
        }
        if *name != clip.name {
            eprintln!("note: {} is written as `{name}`: another clip has the same file name", p.display());
        }
        clip.name = name.clone();
        humans.push(clip);
    }
    // Everything is written into a staging folder beside `out`, moved into place at the end.
    let staging = outputs.stage_dir(out)?;
    let mut rows: Vec<(String, String, MetricsReport, PathBuf)> = Vec::new();
    for (name, tree, morph, dir) in &loaded {
        let retargeter = retarget::Networks::load(dir, backend)
            .with_context(|| format!("the shipped checkpoint of `{name}`"))?;
        let scorer = Scorer::new(retargeter.record(), retargeter.character(), dir)?;
        for (k, clip) in humans.iter().enumerate() {
            let rel = Path::new(&tree.name).join(format!("{}.glb", clip.name));
            let r = retarget::retarget_and_score(&retargeter, &scorer, tree, morph, clip)?;
            let mut files = Outputs::new();
            let w = retarget::write(&r, tree, clip, &staging.join(&rel), true, &mut files)?;
            files.commit()?;
            let glb = out.join(&rel);
            println!(
                "{:>8} ← {:<8} {:>4} frames  L_fea {:.3}  following {:>5}  UFR {:5.2} %  → {}",
                tree.name,
                clip.name,
                w.report.frames,
                w.report.feature_loss.unwrap_or(f32::NAN),
                crate::eval::following_score(&w.report).map_or("n/a".into(), |v| format!("{v:.2}")),
                100.0 * w.report.ufr.rates.ufr,
                glb.display()
            );
            if k == 0 {
                picture_of(tree, &w.poses, clip, &staging.join(format!("{}.png", tree.name)))?;
            }
            rows.push((tree.name.clone(), clip.name.clone(), w.report, glb));
        }
    }
    let (md, json_path) = (out.join("report.md"), out.join("report.json"));
    let md_tmp = staging.join("report.md");
    std::fs::write(&md_tmp, report_markdown(&rows)).with_context(|| format!("writing {}", md.display()))?;
    let v: Vec<_> = rows
        .iter()
        .map(|(c, clip, r, glb)| json!({ "character": c, "clip": clip, "glb": glb, "metrics": r }))
        .collect();
    std::fs::write(staging.join("report.json"), serde_json::to_string_pretty(&v)?)
        .with_context(|| format!("writing {}", json_path.display()))?;
    outputs.commit()?;
    println!("wrote {} retargeted clips under {}, {} and {}", rows.len(), out.display(), md.display(), json_path.display());
    Ok(())
}

fn report_markdown(rows: &[(String, String, MetricsReport, PathBuf)]) -> String {
    let mut s = String::from(
        "| character | clip | frames | L_fea | following | heading error | pace | standing: travel, turning | UFR | self-collision | penetration | sliding | DIV | FID | pops | micro-steps | over a velocity limit |\n|---|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|\n",
    );
    let opt = |v: Option<f32>| v.map_or("n/a".into(), |v| format!("{v:.3}"));
    for (c, clip, r, _) in rows {
        let u = &r.ufr.rates;
        let _ = writeln!(
            s,
            "| {c} | {clip} | {} | {} | {} | {} | {} | {} | {:.2} % | {:.2} % | {:.2} % | {:.2} % | {:.3} | {} | {} | {} | {} |",
            r.frames,
            opt(r.feature_loss),
            opt(crate::eval::following_score(r)),
            crate::eval::heading(r),
            crate::eval::pace(r),
            crate::eval::standing(r),
            100.0 * u.ufr,
            100.0 * u.self_collision,
            100.0 * u.penetration,
            100.0 * u.sliding,
            r.div,
            opt(r.fid),
            r.gait.as_ref().map_or("n/a".into(), |g| format!("{} of {}", percent(g.pop_rate()), g.swings)),
            r.gait.as_ref().map_or("n/a".into(), |g| percent(g.micro_step_rate())),
            crate::eval::velocity_limits(r),
        );
    }
    s
}

/// A filmstrip of the retargeted motion: the character at five moments side by side (each moved back
/// to where it started, so progress along the ground does not pile them up), the human behind each.
fn picture_of(
    tree: &ace::models::kinematics::KinematicTree,
    poses: &[ace::models::kinematics::CharacterPose],
    clip: &HumanClip,
    path: &Path,
) -> Result<()> {
    const SAMPLES: usize = 5;
    const SPACING: f32 = 1.6;
    let first_root = poses.first().context("no retargeted frames")?.root.translation.vector;
    let mut segments = Vec::new();
    for k in 0..SAMPLES {
        let t = (poses.len() - 1) * k / (SAMPLES - 1);
        let slot = Vector3::new(0.0, -(k as f32) * SPACING, 0.0);
        let mut pose = poses[t].clone();
        let r = pose.root.translation.vector;
        pose.root.translation.vector = Vector3::new(first_root.x, first_root.y, r.z) + slot;
        segments.extend(picture::character_segments(tree, &pose, [214, 140, 30]));
        let frame = &clip.frames[t.min(clip.frames.len() - 1)];
        let pelvis = frame.positions[0];
        let behind = Vector3::new(-pelvis.x - 1.2, -pelvis.y, 0.0) + slot;
        segments.extend(picture::human_segments(frame, behind, [40, 100, 235]));
    }
    // The grid goes underneath: drawn first, everything else over it.
    let mut scene = picture::ground_segments(&segments);
    scene.extend(segments);
    picture::render(&scene, 1280, 720, 0.9, 0.35, path)
}
