//! `ace retarget`: a human clip onto a character with a trained checkpoint, written as a glTF binary
//! (the character's animation, optionally with the human skeleton beside it), a robot command
//! trajectory (JSON and CSV) and the clip's metrics.

use std::path::{Path, PathBuf};

use ace::models::cleanup::Cleanup;
use ace::models::export::gltf::{GltfOptions, HumanOverlay, write_glb};
use ace::models::export::trajectory::CommandTrajectory;
use ace::models::features::human_body_length;
use ace::models::human::{HumanClip, ImportOptions, Joint};
use ace::models::human_set::{HumanRow, PROJECT_FPS};
use ace::models::kinematics::{CharacterPose, KinematicTree};
use ace::models::learn::retarget::{RetargetedMotion, Retargeter};
use ace::models::metrics::MetricsReport;
use ace::models::morphology::Morphology;
use ace::models::nalgebra::Vector3;
use anyhow::{Context, Result, bail};

use crate::characters;
use crate::scoring::Scorer;

/// Where a bundled character's shipped checkpoint lives.
pub fn shipped_checkpoint(name: &str) -> PathBuf {
    characters::assets_dir().join("checkpoints").join(name)
}

/// The checkpoint for `--character` when `--checkpoint` is not given.
pub fn default_checkpoint(character_arg: &str) -> Result<PathBuf> {
    if characters::BUNDLED.contains(&character_arg) {
        Ok(shipped_checkpoint(character_arg))
    } else {
        bail!("`{character_arg}` has no shipped checkpoint: pass --checkpoint DIR (made by `ace train-prior` and `ace train`)")
    }
}

/// The files one retargeted clip produced, with its metrics and the character's poses.
pub struct Written {
    pub glb: PathBuf,
    pub json: PathBuf,
    pub csv: PathBuf,
    pub metrics: PathBuf,
    pub report: MetricsReport,
    pub poses: Vec<CharacterPose>,
}

/// Runs `ace retarget`.
pub fn run(clip: &Path, character: &str, checkpoint: Option<&Path>, out: &Path, with_human: bool, cleanup: bool) -> Result<()> {
    let (_, tree, morph) = characters::load(character)?;
    let dir = match checkpoint {
        Some(d) => d.to_path_buf(),
        None => default_checkpoint(character)?,
    };
    let mut retargeter = Retargeter::load(&dir, ace::models::learn::default_device())?;
    if !cleanup {
        retargeter.set_cleanup(Cleanup::NONE);
    }
    let clip = HumanClip::from_bvh_file(clip, &ImportOptions { fps: Some(PROJECT_FPS), mapping: None })?;
    let scorer = Scorer::new(&retargeter, &dir)?;
    let w = retarget(&retargeter, &scorer, &tree, &morph, &clip, out, with_human)?;
    println!("{} on {} ({} frames)\n{}", clip.name, tree.name, w.report.frames, w.report);
    println!("wrote {}, {}, {} and {}", w.glb.display(), w.json.display(), w.csv.display(), w.metrics.display());
    Ok(())
}

/// One clip retargeted and scored.
pub struct Retargeted {
    /// The clip's x^h, the generator's input.
    pub human: Vec<HumanRow>,
    /// The character's states and poses.
    pub motion: RetargetedMotion,
    /// DIV, FID, L_fea and UFR of the motion.
    pub report: MetricsReport,
    /// Per frame, whether a UFR detector flags it.
    pub flagged: Vec<bool>,
}

/// Retargets one clip (already at the project frame rate) and scores it with the checkpoint's
/// conventions.
pub fn retarget_and_score(
    retargeter: &Retargeter,
    scorer: &Scorer,
    tree: &KinematicTree,
    morph: &Morphology,
    clip: &HumanClip,
) -> Result<Retargeted> {
    retargeter.check_character(tree, morph)?;
    if (clip.fps - PROJECT_FPS).abs() > 1e-3 {
        bail!("{}: retargeting needs the clip at {PROJECT_FPS} fps, it is at {}", clip.name, clip.fps);
    }
    // x^h once: the generator's input and the source of the human Ψ for L_fea.
    let human: Vec<HumanRow> = clip.states().into_iter().map(|s| s.0).collect();
    let motion = retargeter.retarget_states(tree, morph, &human)?;
    let psi = scorer.character_psi(&motion.states);
    let human_psi = scorer.human_psi(&human, human_body_length(clip));
    let (report, ufr) =
        scorer.report_with_flags(tree, morph, &psi, Some(&human_psi), &motion.poses, &[0..motion.poses.len()]);
    Ok(Retargeted { human, motion, report, flagged: ufr.any })
}

/// Writes a retargeted clip: `out` (.glb, the character's animation, with the human skeleton beside
/// it when `with_human`), the robot command trajectory beside it (`.json`, `.csv`) and its metrics
/// (`.metrics.json`).
pub fn write(r: &Retargeted, tree: &KinematicTree, clip: &HumanClip, out: &Path, with_human: bool) -> Result<Written> {
    if let Some(parent) = out.parent().filter(|p| !p.as_os_str().is_empty()) {
        std::fs::create_dir_all(parent).with_context(|| format!("creating {}", parent.display()))?;
    }
    // The human walks beside the character: its first pelvis position is put 1.2 m to its left.
    let first = clip.frames.first().context("the clip has no frames")?.positions[Joint::Pelvis.index()];
    let offset = Vector3::new(-first.x, 1.2 - first.y, 0.0);
    let opts = GltfOptions {
        human: with_human.then(|| HumanOverlay::new(&clip.frames, offset)),
        ..GltfOptions::default()
    };
    let motion = &r.motion;
    let glb = write_glb(out, tree, &motion.poses, motion.fps, &opts)?;
    for w in &glb.warnings {
        eprintln!("warning: {w}");
    }
    let trajectory = CommandTrajectory::from_poses(tree, &motion.poses, motion.fps)?;
    let (json, csv) = (out.with_extension("json"), out.with_extension("csv"));
    trajectory.write_json(&json)?;
    trajectory.write_csv(&csv)?;
    let metrics = out.with_extension("metrics.json");
    std::fs::write(&metrics, serde_json::to_string_pretty(&r.report)?).with_context(|| format!("writing {}", metrics.display()))?;
    Ok(Written { glb: out.to_path_buf(), json, csv, metrics, report: r.report.clone(), poses: motion.poses.clone() })
}

/// Retargets one clip (already at the project frame rate) and writes it ([`retarget_and_score`],
/// [`write`]).
pub fn retarget(
    retargeter: &Retargeter,
    scorer: &Scorer,
    tree: &KinematicTree,
    morph: &Morphology,
    clip: &HumanClip,
    out: &Path,
    with_human: bool,
) -> Result<Written> {
    let r = retarget_and_score(retargeter, scorer, tree, morph, clip)?;
    write(&r, tree, clip, out, with_human)
}
