//! `ace retarget`: a human clip onto a character with a trained checkpoint, written as a glTF binary
//! (a URDF character's animation, optionally with the human skeleton beside it; a rigged glTF
//! creature's own model with the clip as a new animation on its skeleton), a robot command trajectory
//! (JSON and CSV) and the clip's metrics.

use std::path::{Path, PathBuf};

use ace::models::cleanup::Cleanup;
use ace::models::character::{is_gltf, load_creature};
use ace::models::export::gltf::{GltfOptions, HumanOverlay, write_glb};
use ace::models::export::{RigClipOptions, write_rig_clip};
use ace::models::export::trajectory::CommandTrajectory;
use ace::models::features::human_body_length;
use ace::models::human::{HumanClip, ImportOptions, Joint, JointMapping};
use ace::models::human_set::{HumanRow, PROJECT_FPS};
use ace::models::kinematics::{CharacterPose, KinematicTree};
use ace::models::checkpoint::ace::AceRecord;
use ace::models::checkpoint::{CharacterInfo, FileRecord, LearnError};
use ace::models::learn::retarget::Retargeter as TchRetargeter;
use ace::models::runtime::{RetargetedMotion, Retargeter};
use ace::models::metrics::{MetricsReport, percent};
use ace::models::morphology::Morphology;
use ace::models::nalgebra::Vector3;
use anyhow::{Context, Result, bail};

use crate::characters;
use crate::output::{Outputs, Planned};
use crate::scoring::{FrameFlags, HumanSource, Scorer};

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

/// Which implementation runs the networks (`--backend`): `Rust` is [`ace::models::runtime`], `Tch`
/// is [`ace::models::learn::retarget`]. (The variants' own comments are the CLI's help, which prints
/// them as they are written.)
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, clap::ValueEnum)]
pub enum Backend {
    /// Pure Rust: what a game ships.
    #[default]
    Rust,
    /// libtorch, for comparison.
    Tch,
}

/// A step of the cleanup `ace retarget --without` leaves out ([`ace::models::cleanup`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum CleanupStep {
    /// Steering the root back onto the person's heading.
    HeadingSteering,
    /// Holding the root while the person stands.
    StandingHold,
    /// Holding an arm (or the head) while the person's matching hand (or head) rests.
    EffectorHold,
    /// Planting the feet that come down.
    FootLock,
    /// Moving colliding poses back to the last free one.
    CollisionGuard,
}

/// The cleanup with every step on but those in `without`, or none at all (`raw`).
pub fn cleanup_without(raw: bool, without: &[CleanupStep]) -> Cleanup {
    if raw {
        return Cleanup::NONE;
    }
    let mut c = Cleanup::default();
    for step in without {
        match step {
            CleanupStep::HeadingSteering => c.heading = None,
            CleanupStep::StandingHold => c.standing = None,
            CleanupStep::EffectorHold => c.effector_hold = None,
            CleanupStep::FootLock => c.foot_lock = None,
            CleanupStep::CollisionGuard => c.collision_guard = false,
        }
    }
    c
}

/// A checkpoint's networks loaded on one [`Backend`]; both give the same poses up to float rounding.
pub enum Networks {
    Rust(Retargeter),
    Tch(TchRetargeter),
}

impl Networks {
    /// Loads the checkpoint in `dir` on `backend` (libtorch's on its default device).
    pub fn load(dir: &Path, backend: Backend) -> Result<Networks, LearnError> {
        Ok(match backend {
            Backend::Rust => Networks::Rust(Retargeter::load(dir)?),
            Backend::Tch => Networks::Tch(TchRetargeter::load(dir, ace::models::learn::default_device())?),
        })
    }

    /// Sets the cleanup of the rollouts.
    pub fn set_cleanup(&mut self, cleanup: Cleanup) {
        match self {
            Networks::Rust(r) => r.set_cleanup(cleanup),
            Networks::Tch(r) => r.set_cleanup(cleanup),
        }
    }

    /// Fails unless `tree`/`morph` is the checkpoint's character.
    pub fn check_character(&self, tree: &KinematicTree, morph: &Morphology) -> Result<(), LearnError> {
        match self {
            Networks::Rust(r) => r.check_character(tree, morph),
            Networks::Tch(r) => r.check_character(tree, morph),
        }
    }

    /// The character states and poses of x^h rows at the project frame rate, from the standing pose.
    pub fn retarget_states(
        &self,
        tree: &KinematicTree,
        morph: &Morphology,
        x_h: &[HumanRow],
    ) -> Result<RetargetedMotion, LearnError> {
        match self {
            Networks::Rust(r) => r.retarget_states(tree, morph, x_h),
            Networks::Tch(r) => r.retarget_states(tree, morph, x_h),
        }
    }

    /// The generator's record (`ace.json`).
    pub fn record(&self) -> &AceRecord {
        match self {
            Networks::Rust(r) => r.record(),
            Networks::Tch(r) => &r.ace().record,
        }
    }

    /// The checkpoint's character.
    pub fn character(&self) -> &CharacterInfo {
        match self {
            Networks::Rust(r) => r.character(),
            Networks::Tch(r) => &r.prior().character,
        }
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

/// Options of `ace retarget`.
pub struct RetargetArgs {
    pub clip: PathBuf,
    pub character: String,
    pub checkpoint: Option<PathBuf>,
    pub out: PathBuf,
    pub with_human: bool,
    /// How a glTF creature's rig clip is written (its name is the clip's).
    pub rig: RigClipOptions,
    /// The cleanup of the poses written.
    pub cleanup: Cleanup,
    /// A joint-mapping file for the clip's skeleton.
    pub mapping: Option<PathBuf>,
    /// Which implementation runs the networks.
    pub backend: Backend,
}

/// The import options of a clip retargeted at the project frame rate, with `--mapping` when given.
pub fn import_options(mapping: Option<&Path>) -> Result<ImportOptions> {
    let mapping = mapping.map(JointMapping::from_file).transpose()?;
    Ok(ImportOptions { fps: Some(PROJECT_FPS), mapping })
}

/// The warning for a character file that is not the one `record`'s checkpoint was trained with (the
/// same joints and size, other content: [`AceRecord::character_file_difference`]); `None` when it is,
/// or when the checkpoint does not record its character file.
pub fn character_file_warning(record: &AceRecord, character: &Path) -> Result<Option<String>> {
    let bytes = ace::models::input::read_regular(character, ace::models::input::MAX_MESH_BYTES)
        .with_context(|| format!("{}: cannot read the character file", character.display()))?;
    Ok(record.character_file_difference(&FileRecord::of(&character.display().to_string(), &bytes)))
}

/// Prints on stderr what a user should know of the checkpoint before its results: that its training
/// stopped early ([`AceRecord::unfinished`]), and [`character_file_warning`].
pub fn warn_about_checkpoint(record: &AceRecord, character: &Path) -> Result<()> {
    for w in record.unfinished().into_iter().chain(character_file_warning(record, character)?) {
        eprintln!("warning: {w}");
    }
    Ok(())
}

/// Runs `ace retarget`.
pub fn run(a: &RetargetArgs) -> Result<()> {
    let (urdf, tree, morph) = characters::load(&a.character)?;
    check_rig_options(&urdf, &a.rig)?;
    let dir = match &a.checkpoint {
        Some(d) => d.clone(),
        None => default_checkpoint(&a.character)?,
    };
    // Every output is checked against every input before any work.
    let mut outputs = Outputs::new();
    outputs
        .input_clip(&a.clip, "the input clip", a.mapping.as_deref())
        .input(&dir, "the checkpoint directory")
        .input_character(&urdf);
    // The inputs first: `--out walk.bvh` is refused as the clip, not for its extension.
    let paths = output_paths(&a.out);
    for p in &paths {
        outputs.check(p)?;
    }
    check_model_name(&a.out)?;
    let mut planned = Planned::new();
    for (p, role) in paths.iter().zip(OUTPUT_ROLES) {
        planned.add(p, role.to_string(), "give --out a name ending in .glb")?;
    }
    let mut retargeter = Networks::load(&dir, a.backend)?;
    retargeter.check_character(&tree, &morph)?;
    warn_about_checkpoint(retargeter.record(), &urdf)?;
    retargeter.set_cleanup(a.cleanup);
    let clip = HumanClip::from_bvh_file(&a.clip, &import_options(a.mapping.as_deref())?)?;
    for w in clip.warnings() {
        eprintln!("warning: {w}");
    }
    let scorer = Scorer::new(retargeter.record(), retargeter.character(), &dir)?;
    let r = retarget_and_score(&retargeter, &scorer, &tree, &morph, &clip)?;
    let w = write_with(&r, &tree, &clip, &a.out, a.with_human, &a.rig, &mut outputs)?;
    outputs.commit()?;
    println!("{} on {} ({} frames)\n{}", clip.name, tree.name, w.report.frames, w.report);
    println!("wrote {}, {}, {} and {}", w.glb.display(), w.json.display(), w.csv.display(), w.metrics.display());
    if let Some(warning) = joint_limit_warning(&w.report, &w.json) {
        eprintln!("warning: {warning}");
    }
    Ok(())
}

/// The warning for a trajectory (`trajectory`, scored in `report`) in which some joint moves faster
/// than its velocity limit or leaves its position limits, naming the file and the joints fastest
/// against their limits; `None` when every joint keeps to its limits.
pub fn joint_limit_warning(report: &MetricsReport, trajectory: &Path) -> Option<String> {
    let j = report.joint_limits.as_ref()?;
    let mut problems = Vec::new();
    if j.over_velocity > 0.0 {
        let fastest: Vec<String> = j
            .over()
            .iter()
            .take(3)
            .map(|u| format!("{} at up to {:.2} times its limit", u.joint, u.peak_ratio().unwrap_or(0.0)))
            .collect();
        problems.push(format!(
            "{} of the frames move a joint faster than its velocity limit ({})",
            percent(j.over_velocity),
            fastest.join(", ")
        ));
    }
    if j.outside_position > 0.0 {
        let outside: Vec<&str> = j.joints.iter().filter(|u| u.frames_outside > 0).map(|u| u.joint.as_str()).collect();
        problems.push(format!(
            "{} of the frames put a joint outside its position limits ({})",
            percent(j.outside_position),
            outside.join(", ")
        ));
    }
    (!problems.is_empty()).then(|| {
        format!(
            "{}: {}; a robot would not execute it as written{}",
            trajectory.display(),
            problems.join("; "),
            if j.over_velocity > 0.0 { " (--limit-velocity holds the joints to their limits)" } else { "" }
        )
    })
}

/// Fails unless `out` names a glTF file: `x.txt`, `x` or `.glb` got a GLB under that name.
pub fn check_model_name(out: &Path) -> Result<()> {
    let gltf = out.extension().and_then(|e| e.to_str()).is_some_and(|e| e.eq_ignore_ascii_case("glb") || e.eq_ignore_ascii_case("gltf"));
    if !gltf {
        bail!(
            "{}: --out is the glTF file, a name ending in .glb (binary) or .gltf (JSON); the trajectory and the \
             metrics are written beside it",
            out.display()
        );
    }
    Ok(())
}

/// The files [`write()`] makes for `out`: the glTF binary, the trajectory (`.json`, `.csv`) and the
/// metrics (`.metrics.json`).
pub fn output_paths(out: &Path) -> [PathBuf; 4] {
    [out.to_path_buf(), out.with_extension("json"), out.with_extension("csv"), out.with_extension("metrics.json")]
}

/// What each of [`output_paths`] is, in its order (for errors).
pub const OUTPUT_ROLES: [&str; 4] = ["the glTF binary", "the trajectory (JSON)", "the trajectory (CSV)", "the metrics"];

/// One clip retargeted and scored.
pub struct Retargeted {
    /// The clip's x^h, the generator's input.
    pub human: Vec<HumanRow>,
    /// The character's states and poses.
    pub motion: RetargetedMotion,
    /// DIV, FID, L_fea and UFR of the motion.
    pub report: MetricsReport,
    /// Per frame, whether a UFR detector flags it and whether a foot pops.
    pub flags: FrameFlags,
}

/// Retargets one clip (already at the project frame rate) and scores it with the checkpoint's
/// conventions.
pub fn retarget_and_score(
    retargeter: &Networks,
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
    let psi = scorer.shown_psi(tree, morph, &motion.states, &motion.poses);
    let body = scorer.human_body(human_body_length(clip));
    let human_psi = scorer.human_psi(&human, body);
    let source = HumanSource { psi: &human_psi, bodies: &[body] };
    let (report, flags) = scorer.report_with_flags(tree, morph, &psi, Some(source), &motion.poses, &[0..motion.poses.len()]);
    Ok(Retargeted { human, motion, report, flags })
}

/// Fails when `rig` asks for something only a rigged glTF creature has and `character` is a URDF, or
/// when a file a creature's model reads beside it is missing and the model is to be written whole.
pub fn check_rig_options(character: &Path, rig: &RigClipOptions) -> Result<()> {
    if !is_gltf(character) && (rig.keep_animations || rig.animation_only) {
        let flag = if rig.keep_animations { "--keep-animations" } else { "--animation-only" };
        bail!(
            "{flag} is for rigged glTF creatures (.glb, .gltf), whose own model the clip is written onto; \
             {} is a URDF robot",
            character.display()
        );
    }
    // The model written with the clip embeds the files it reads beside it: one missing (a texture left
    // behind when the model was copied) failed only when the output was written, after the whole clip.
    if is_gltf(character) && !rig.animation_only {
        for f in ace::models::character::gltf::external_files(character).unwrap_or_default() {
            if let Err(e) = std::fs::metadata(&f) {
                bail!(
                    "{}: cannot read {}, a file of the model ({e}); the clip is written onto the model with its \
                     files embedded: put the file back beside the model, or pass --animation-only to write the \
                     skeleton and the clip alone",
                    character.display(),
                    f.display()
                );
            }
        }
    }
    Ok(())
}

/// [`write_with`] with the default rig clip options (the model whole, without its own animations).
pub fn write(
    r: &Retargeted,
    tree: &KinematicTree,
    clip: &HumanClip,
    out: &Path,
    with_human: bool,
    outputs: &mut Outputs,
) -> Result<Written> {
    write_with(r, tree, clip, out, with_human, &RigClipOptions::default(), outputs)
}

/// Writes a retargeted clip: `out` (.glb: for a URDF character its animation, with the human skeleton
/// beside it when `with_human`; for a rigged glTF creature its own model with the clip as a new
/// animation named after the clip, as `rig` says), the robot command trajectory beside it (`.json`,
/// `.csv`) and its metrics (`.metrics.json`), each staged in `outputs` (they appear when it is
/// committed).
pub fn write_with(
    r: &Retargeted,
    tree: &KinematicTree,
    clip: &HumanClip,
    out: &Path,
    with_human: bool,
    rig: &RigClipOptions,
    outputs: &mut Outputs,
) -> Result<Written> {
    let [glb_path, json, csv, metrics] = output_paths(out);
    let motion = &r.motion;
    match tree.source.as_deref().filter(|s| is_gltf(s)) {
        Some(model) => {
            // The creature again, for its rig: it must still be the one the tree was built from.
            let creature = load_creature(model)?;
            if creature.tree.dof_names() != tree.dof_names() {
                let file = model.display();
                bail!("{file}: the creature's file changed since it was loaded (its DoFs differ); run again");
            }
            let name = rig.name.clone().unwrap_or_else(|| clip.name.clone());
            let opts = RigClipOptions { name: Some(name), ..rig.clone() };
            write_rig_clip(&outputs.stage(&glb_path)?, &creature, &motion.poses, motion.fps, &opts)
                .with_context(|| format!("writing {}", glb_path.display()))?;
        }
        None => {
            check_rig_options(tree.source.as_deref().unwrap_or(Path::new(&tree.name)), rig)?;
            // The human walks beside the character: its first pelvis position is put 1.2 m to its left.
            let first = clip.frames.first().context("the clip has no frames")?.positions[Joint::Pelvis.index()];
            let offset = Vector3::new(-first.x, 1.2 - first.y, 0.0);
            let opts = GltfOptions {
                human: with_human.then(|| HumanOverlay::new(&clip.frames, offset)),
                ..GltfOptions::default()
            };
            let glb = write_glb(&outputs.stage(&glb_path)?, tree, &motion.poses, motion.fps, &opts)
                .with_context(|| format!("writing {}", glb_path.display()))?;
            for w in &glb.warnings {
                eprintln!("warning: {w}");
            }
        }
    }
    let trajectory = CommandTrajectory::from_poses(tree, &motion.poses, motion.fps)?;
    // Errors name the output, not its staged temporary (removed with the set).
    trajectory.write_json(&outputs.stage(&json)?).with_context(|| format!("writing {}", json.display()))?;
    trajectory.write_csv(&outputs.stage(&csv)?).with_context(|| format!("writing {}", csv.display()))?;
    let metrics_tmp = outputs.stage(&metrics)?;
    std::fs::write(&metrics_tmp, serde_json::to_string_pretty(&r.report)?)
        .with_context(|| format!("writing {}", metrics.display()))?;
    Ok(Written { glb: glb_path, json, csv, metrics, report: r.report.clone(), poses: motion.poses.clone() })
}

/// Retargets one clip (already at the project frame rate) and writes it ([`retarget_and_score`],
/// [`write()`]) into `outputs`.
#[allow(clippy::too_many_arguments)]
pub fn retarget(
    retargeter: &Networks,
    scorer: &Scorer,
    tree: &KinematicTree,
    morph: &Morphology,
    clip: &HumanClip,
    out: &Path,
    with_human: bool,
    outputs: &mut Outputs,
) -> Result<Written> {
    let r = retarget_and_score(retargeter, scorer, tree, morph, clip)?;
    write(&r, tree, clip, out, with_human, outputs)
}
