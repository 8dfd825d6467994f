//! `ace retarget FOLDER --out DIR`: every BVH clip below a folder (recursively) onto one character, in
//! parallel, with a progress bar and a summary.
//!
//! Each clip is written as a single `ace retarget` writes it, at the same relative path under `DIR`
//! (`walk/01.bvh` → `DIR/walk/01.glb`, `.json`, `.csv`, `.metrics.json`), each clip's files committed
//! together once the clip is done. A clip that fails (a malformed file, a skeleton nothing can read) is
//! listed with its error and the others still run; its earlier outputs, if any, are left as they were.
//! `DIR/summary.json` lists every clip (frames, UFR, L_fea, following, pops, joints over their velocity
//! limits) and every failure, and the
//! command fails when any clip did.
//!
//! Workers pull clips from a shared counter, each with its own networks and scorer, so the outputs do
//! not depend on `--jobs` or on which worker took a clip.

use std::path::{Path, PathBuf};
use std::sync::Mutex;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::mpsc;
use std::time::Instant;

use ace::models::human::HumanClip;
use ace::models::human_set::find_bvh_files;
use ace::models::kinematics::KinematicTree;
use ace::models::morphology::Morphology;
use anyhow::{Context, Result, bail};
use serde::Serialize;

use crate::output::{Outputs, Planned};
use crate::progress;
use crate::retarget::{Networks, RetargetArgs, check_rig_options, default_checkpoint, import_options, joint_limit_warning, output_paths, OUTPUT_ROLES, retarget_and_score, write_with};
use crate::scoring::Scorer;
use crate::characters;

/// One clip retargeted.
#[derive(Clone, Debug, Serialize)]
pub struct ClipDone {
    /// The clip, relative to the folder.
    pub clip: PathBuf,
    /// Its glTF binary.
    pub glb: PathBuf,
    pub frames: usize,
    /// Share of frames flagged by UFR.
    pub ufr: f32,
    /// Mean L_fea against the human.
    pub feature_loss: Option<f32>,
    /// The following score ([`ace::models::metrics::following()`]), when the mapping has pairs.
    pub following: Option<f32>,
    /// Share of the feet's swings that are pops (legged characters).
    pub pops: Option<f32>,
    /// Share of frames into which a joint moves faster than its velocity limit (characters with
    /// limits).
    pub over_velocity: Option<f32>,
    /// Warnings the import gave (a posture it doubts), and the trajectory's joint limits warning.
    pub warnings: Vec<String>,
}

/// One clip that failed.
#[derive(Clone, Debug, Serialize)]
pub struct ClipFailed {
    /// The clip, relative to the folder.
    pub clip: PathBuf,
    /// What went wrong, with its causes.
    pub error: String,
}

/// `DIR/summary.json`.
#[derive(Debug, Serialize)]
pub struct Summary {
    pub folder: PathBuf,
    pub character: String,
    pub checkpoint: PathBuf,
    pub jobs: usize,
    pub clips: usize,
    pub frames: usize,
    pub seconds: f64,
    pub clips_per_second: f64,
    pub frames_per_second: f64,
    pub done: Vec<ClipDone>,
    pub failed: Vec<ClipFailed>,
}

/// Options of a folder run: those of one clip (`clip` is the folder, `out` the output folder) and the
/// number of workers (`None`: one per core).
pub struct BatchArgs {
    pub one: RetargetArgs,
    pub jobs: Option<usize>,
}

/// The file name of the summary inside the output folder.
pub const SUMMARY: &str = "summary.json";

/// Runs `ace retarget FOLDER --out DIR`.
pub fn run(b: &BatchArgs) -> Result<()> {
    let a = &b.one;
    let folder = &a.clip;
    let (urdf, tree, morph) = characters::load(&a.character)?;
    check_rig_options(&urdf, &a.rig)?;
    let dir = match &a.checkpoint {
        Some(d) => d.clone(),
        None => default_checkpoint(&a.character)?,
    };
    if a.out.extension().is_some_and(|e| e.eq_ignore_ascii_case("glb")) || a.out.is_file() {
        bail!(
            "{}: the output of a folder of clips is a folder (one .glb per clip and {SUMMARY}), not a file",
            a.out.display()
        );
    }
    // (The parser bounds --jobs; this is for callers of the library.)
    if let Some(n) = b.jobs.filter(|n| !(1..=crate::limits::MAX_JOBS).contains(n)) {
        bail!("--jobs {n}: expected a number of clips at once from 1 to {}", crate::limits::MAX_JOBS);
    }
    let files = find_bvh_files(folder).with_context(|| format!("{}: cannot list its clips", folder.display()))?;
    if files.is_empty() {
        bail!("{}: no .bvh files in it or below it", folder.display());
    }
    let inputs = || {
        let mut o = Outputs::new();
        // (The joint-mapping files beside the clips are inside the folder.)
        o.input(folder, "the folder of input clips").input(&dir, "the checkpoint directory").input_character(&urdf);
        if let Some(m) = &a.mapping {
            o.input(m, "the joint-mapping file");
        }
        o
    };
    // Every output path is checked against every input before any work.
    let jobs_out: Vec<(PathBuf, PathBuf)> = files
        .iter()
        .map(|f| {
            let rel = f.strip_prefix(folder).unwrap_or(f).to_path_buf();
            let out = a.out.join(&rel).with_extension("glb");
            (rel, out)
        })
        .collect();
    // … and no two clips write the same file (`walk.bvh` and `walk.BVH` both make `walk.glb`; the
    // trajectory of `walk.metrics.bvh` is the metrics of `walk.bvh`).
    let check = inputs();
    let mut planned = Planned::new();
    let summary_path = a.out.join(SUMMARY);
    planned.add(&summary_path, "the summary".into(), "rename the clip")?;
    for (rel, out) in &jobs_out {
        for (p, role) in output_paths(out).iter().zip(OUTPUT_ROLES) {
            planned.add(p, format!("{role} of {}", rel.display()), "rename one of the clips")?;
            check.check(p)?;
        }
    }
    check.check(&summary_path)?;
    // Fails early on a checkpoint that cannot be read or does not fit the character.
    let first = Networks::load(&dir, a.backend)?;
    first.check_character(&tree, &morph)?;
    crate::retarget::warn_about_checkpoint(first.record(), &urdf)?;
    drop(first);
    let opts = import_options(a.mapping.as_deref())?;

    let jobs = b
        .jobs
        .unwrap_or_else(|| std::thread::available_parallelism().map_or(1, |n| n.get()))
        .clamp(1, files.len());
    let start = Instant::now();
    let bar = progress::bar(files.len() as u64, "clips");
    let next = AtomicUsize::new(0);
    let slots: Mutex<Vec<Option<Result<ClipDone, ClipFailed>>>> = Mutex::new(vec![None; files.len()]);
    let (tx, rx) = mpsc::channel::<usize>();
    std::thread::scope(|s| -> Result<()> {
        let mut workers = Vec::new();
        for _ in 0..jobs {
            let tx = tx.clone();
            let (next, slots, files, jobs_out, opts, tree, morph, dir, inputs) =
                (&next, &slots, &files, &jobs_out, &opts, &tree, &morph, &dir, &inputs);
            workers.push(s.spawn(move || -> Result<()> {
                let mut networks = Networks::load(dir, a.backend)?;
                networks.set_cleanup(a.cleanup);
                let scorer = Scorer::new(networks.record(), networks.character(), dir)?;
                loop {
                    let i = next.fetch_add(1, Ordering::Relaxed);
                    let Some(file) = files.get(i) else { break };
                    let (rel, out) = &jobs_out[i];
                    let r = one_clip(&networks, &scorer, tree, morph, file, out, opts, a, inputs())
                        .map(|mut d| {
                            d.clip = rel.clone();
                            d
                        })
                        .map_err(|e| {
                            // Named once: the import's errors begin with the clip's path already.
                            let (e, f) = (format!("{e:#}"), file.display().to_string());
                            ClipFailed { clip: rel.clone(), error: if e.starts_with(&f) { e } else { format!("{f}: {e}") } }
                        });
                    slots.lock().unwrap_or_else(|e| e.into_inner())[i] = Some(r);
                    if tx.send(i).is_err() {
                        break;
                    }
                }
                Ok(())
            }));
        }
        drop(tx);
        for i in rx.iter() {
            bar.inc(1);
            bar.set_message(jobs_out[i].0.display().to_string());
        }
        for w in workers {
            w.join().map_err(|_| anyhow::anyhow!("a retargeting worker panicked"))??;
        }
        Ok(())
    })?;
    bar.finish_and_clear();
    let seconds = start.elapsed().as_secs_f64();

    let mut done = Vec::new();
    let mut failed = Vec::new();
    for r in slots.into_inner().unwrap_or_else(|e| e.into_inner()) {
        match r.context("a clip was never retargeted")? {
            Ok(d) => done.push(d),
            Err(f) => failed.push(f),
        }
    }
    let frames = done.iter().map(|d| d.frames).sum();
    let summary = Summary {
        folder: folder.clone(),
        character: tree.name.clone(),
        checkpoint: dir.clone(),
        jobs,
        clips: files.len(),
        frames,
        seconds,
        clips_per_second: done.len() as f64 / seconds.max(1e-9),
        frames_per_second: frames as f64 / seconds.max(1e-9),
        done,
        failed,
    };
    let mut outputs = inputs();
    let tmp = outputs.stage(&summary_path)?;
    std::fs::write(&tmp, serde_json::to_string_pretty(&summary)?).with_context(|| format!("writing {}", summary_path.display()))?;
    outputs.commit()?;

    for d in &summary.done {
        for w in &d.warnings {
            eprintln!("warning: {}: {w}", d.clip.display());
        }
    }
    println!(
        "{} of {} clips onto {} ({} frames) in {:.1} s on {} workers: {:.1} clips/s, {:.0} frames/s",
        summary.done.len(),
        summary.clips,
        summary.character,
        summary.frames,
        summary.seconds,
        jobs,
        summary.clips_per_second,
        summary.frames_per_second
    );
    println!("wrote {} and one .glb, .json, .csv and .metrics.json per clip under {}", summary_path.display(), a.out.display());
    if !summary.failed.is_empty() {
        for f in &summary.failed {
            eprintln!("failed: {}", f.error);
        }
        bail!("{} of {} clips failed (listed above and in {})", summary.failed.len(), summary.clips, summary_path.display());
    }
    Ok(())
}

/// Imports, retargets and writes one clip into `outputs`, then commits its files.
#[allow(clippy::too_many_arguments)]
fn one_clip(
    networks: &Networks,
    scorer: &Scorer,
    tree: &KinematicTree,
    morph: &Morphology,
    file: &Path,
    out: &Path,
    opts: &ace::models::human::ImportOptions,
    a: &RetargetArgs,
    mut outputs: Outputs,
) -> Result<ClipDone> {
    let clip = HumanClip::from_bvh_file(file, opts)?;
    let mut warnings = clip.warnings();
    let r = retarget_and_score(networks, scorer, tree, morph, &clip)?;
    let w = write_with(&r, tree, &clip, out, a.with_human, &a.rig, &mut outputs)?;
    outputs.commit()?;
    warnings.extend(joint_limit_warning(&w.report, &w.json));
    let gait = w.report.gait.as_ref();
    Ok(ClipDone {
        clip: file.to_path_buf(),
        glb: w.glb,
        frames: w.report.frames,
        ufr: w.report.ufr.rates.ufr,
        feature_loss: w.report.feature_loss,
        following: w.report.following.as_ref().and_then(|f| f.score),
        pops: gait.filter(|g| g.swings > 0).map(|g| g.pops as f32 / g.swings as f32),
        over_velocity: crate::eval::over_velocity_share(&w.report),
        warnings,
    })
}
