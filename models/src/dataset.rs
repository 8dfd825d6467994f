//! Character motion datasets (paper §4, §7.1): the kinematic controllers of [`crate::controller`]
//! rolled out under random commands, stored with the x^r layout, normalisation statistics, the seed and
//! the generator's configuration.
//!
//! [`generate`] runs episodes of random length, each restarting from the standing pose
//! ([`crate::kinematics::KinematicTree::standing_pose`]) at the origin, until `frames` frames exist. Frame
//! `t` of an episode has x^r from [`write_state`] with frame `t − 1` as the previous frame (the first
//! frame uses itself, so its velocities are zero). Everything is drawn from one PCG-64 generator seeded
//! with `seed`, and the file has no timestamps and a fixed key order, so the same configuration gives
//! the same file, byte for byte (with the same build on the same platform: `sin`, `exp` and friends
//! may round differently elsewhere).
//!
//! A rigged glTF creature's own animation clips can join the controllers' episodes
//! ([`DatasetConfig::own_clips`], `ace dataset --include-clips`): they show how its artist meant it to
//! move. They fill their share of the frames at the end of the dataset, one episode per clip, taken in
//! turn until the share is full (the last one cut short), played on the character's tree
//! with each leg solved to the file's foot ([`crate::character::clips::clip_poses_on_feet`]) and carried
//! across the ground by their planted feet
//! ([`crate::character::clips::with_travel`]); their `commands` are the root's own velocity and their
//! `contacts` the feet within the UFR's contact height of the ground.
//!
//! # File format (version 1)
//! A [safetensors](https://huggingface.co/docs/safetensors) file: an 8-byte little-endian header
//! length, a JSON header, then the tensor bytes (little-endian, row-major). `N` frames, `K` episodes,
//! `D = layout.dim`, `F` feet.
//!
//! | tensor     | dtype | shape    | content                                                         |
//! |------------|-------|----------|-----------------------------------------------------------------|
//! | `episodes` | I64   | `[K, 2]` | frame ranges `[start, end)`, in order, covering `0..N`          |
//! | `commands` | F32   | `[N, 3]` | commanded `(vx, vy, wz)` (m/s, rad/s, heading frame): the random target the base is driven toward (the base follows it through a first-order filter) |
//! | `mean`     | F32   | `[D]`    | mean of each x^r entry over all frames                          |
//! | `q`        | F32   | `[N, dof]` | joint positions (rad or m) in DoF order                       |
//! | `roots`    | F32   | `[N, 7]` | root link world pose `x y z qw qx qy qz`                        |
//! | `states`   | F32   | `[N, D]` | x^r ([`CharacterLayout`])                                       |
//! | `std`      | F32   | `[D]`    | standard deviation of each entry, floored at [`STD_FLOOR`]      |
//! | `contacts` | U8    | `[N, F]` | 1 when the foot is in stance, in [`Morphology::feet`] order     |
//!
//! `__metadata__` (all values strings): `format` = `ace_motion_set`, `format_version` = `1`,
//! `character` (robot name), optionally `character_source` (the absolute path of the character file it was read from; older files: the path as given), `fps`, `seed`, `config` ([`DatasetConfig`] as JSON), `layout`
//! (`{"dof", "end_effectors", "dim"}` as JSON), `dof_names` and `end_effector_links` (JSON arrays; the
//! first `n_feet` end effectors are the feet), `n_feet`.
//!
//! Files are written to a temporary file in the same directory and renamed into place, so a crash
//! never leaves a half-written dataset. [`MotionSet::load`] checks the format, version, every tensor's
//! dtype and shape, the episode ranges and that every value is finite, and names the file and the
//! problem when something is off; [`MotionSet::save`] refuses a dataset with a NaN or an infinity.

use std::fs;
use std::ops::Range;
use std::path::{Path, PathBuf};

use nalgebra::{Isometry3, Quaternion, Translation3, UnitQuaternion};
use rand::SeedableRng;
use safetensors::{Dtype, SafeTensorError, SafeTensors};
use serde::{Deserialize, Serialize};
use serde_json::{Value, json};
use thiserror::Error;

use crate::character_state::{CharacterLayout, write_state};
use crate::controller::{Controller, ControllerConfig, ControllerError, Rig, uniform};
use crate::kinematics::{CharacterPose, KinematicTree};
use crate::morphology::Morphology;

/// The `format` metadata value.
pub const FORMAT: &str = "ace_motion_set";
/// The format version this build writes and reads.
pub const FORMAT_VERSION: u32 = 1;
/// Smallest standard deviation stored (a constant entry normalises to 0, not to ±∞).
pub const STD_FLOOR: f32 = 1e-3;
/// Frame rates a dataset may have (frames per second).
pub const FPS_RANGE: (f32, f32) = (1.0, 1000.0);

/// How a dataset is generated. Every field has a default; TOML/JSON may give any subset.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct DatasetConfig {
    /// Frames in total (paper: 200k).
    pub frames: usize,
    /// Frame rate (frames per second).
    pub fps: f32,
    /// Seed of the random generator.
    pub seed: u64,
    /// Episode length range (s); the last episode may be shorter.
    pub episode_seconds: [f32; 2],
    /// The controllers.
    pub controller: ControllerConfig,
    /// The creature's own animation clips in the dataset (none by default).
    pub own_clips: OwnClipsConfig,
}

/// A rigged creature's own clips in its dataset (module docs).
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct OwnClipsConfig {
    /// Fraction of the dataset's frames that are the clips (0 to [`OwnClipsConfig::MAX_SHARE`]); 0
    /// leaves them out.
    pub share: f32,
    /// The clips to use, by name; empty: every clip of the file.
    pub names: Vec<String>,
}

impl OwnClipsConfig {
    /// The share `ace dataset --include-clips` sets when the configuration gives none: 2 %. Trained
    /// with a tenth of its frames from its three clips, the shared Fox's prior learned to stand; with
    /// 2 % it walked, at a lower held-out FID than without them (docs/datasets.md).
    pub const DEFAULT_SHARE: f32 = 0.02;
    /// The largest share: the controllers keep at least half of the frames, with every gait, turn and
    /// reach the retargeter needs that an artist's few clips do not show.
    pub const MAX_SHARE: f32 = 0.5;
}

impl DatasetConfig {
    /// The configuration a dataset file or a prior's provenance recorded. Settings added since are
    /// read as the behaviour the record was made with, not as today's defaults, so that a recorded
    /// dataset regenerates byte for byte: a record without `controller.legs.cadence_limit` predates
    /// the cadence limit and reads as `None`, and one without `controller.legs.walks_by_body_speed`
    /// judged the walks by the feet's speed and reads as `false`; one without
    /// `controller.scaling.wheel_limits` drove wheeled bases past their wheels' limits and reads as
    /// `false`, as one without `controller.scaling.leg_limits` for legged robots' leg joints; one
    /// without `controller.scaling.walking_pace` scaled speeds by the body alone and reads as `None`.
    pub fn from_record(mut record: serde_json::Value) -> Result<Self, serde_json::Error> {
        if let Some(legs) = record
            .get_mut("controller")
            .and_then(|c| c.get_mut("legs"))
            .and_then(|l| l.as_object_mut())
        {
            legs.entry("cadence_limit").or_insert(serde_json::Value::Null);
            legs.entry("walks_by_body_speed").or_insert(serde_json::Value::Bool(false));
        }
        if let Some(scaling) = record
            .get_mut("controller")
            .and_then(|c| c.get_mut("scaling"))
            .and_then(|l| l.as_object_mut())
        {
            scaling.entry("wheel_limits").or_insert(serde_json::Value::Bool(false));
            scaling.entry("leg_limits").or_insert(serde_json::Value::Bool(false));
            scaling.entry("walking_pace").or_insert(serde_json::Value::Null);
        }
        serde_json::from_value(record)
    }
}

impl Default for DatasetConfig {
    fn default() -> Self {
        DatasetConfig {
            frames: 200_000,
            fps: 30.0,
            seed: 0,
            episode_seconds: [8.0, 24.0],
            controller: ControllerConfig::default(),
            own_clips: OwnClipsConfig::default(),
        }
    }
}

/// Why a dataset could not be generated, saved or loaded.
#[derive(Debug, Clone, Error, PartialEq)]
pub enum DatasetError {
    /// The controllers cannot drive the character.
    #[error("character `{character}`{}: {problem}", file.as_ref().map(|f| format!(" ({})", f.display())).unwrap_or_default())]
    Controller {
        /// Robot name.
        character: String,
        /// The file it was read from, when it came from one.
        file: Option<PathBuf>,
        /// What the controllers report.
        problem: ControllerError,
    },
    /// A configuration value out of range.
    #[error("invalid dataset configuration: {0}")]
    Config(String),
    /// A file that cannot be written or read, or is not a valid dataset.
    #[error("{}: {problem}", path.display())]
    File {
        /// The file.
        path: PathBuf,
        /// What is wrong.
        problem: String,
    },
}

fn file_error(path: &Path, problem: impl Into<String>) -> DatasetError {
    DatasetError::File {
        path: path.to_path_buf(),
        problem: problem.into(),
    }
}

/// A character motion dataset (see the module docs for the meaning of each field and the file format).
#[derive(Clone, Debug, PartialEq)]
pub struct MotionSet {
    /// Robot name.
    pub character: String,
    /// The file the character was read from, as an absolute path (older datasets: as it was given),
    /// when it came from a file, so that the dataset can be scored without naming the character again.
    pub character_source: Option<String>,
    /// Frame rate.
    pub fps: f32,
    /// Seed it was generated with.
    pub seed: u64,
    /// Configuration it was generated with.
    pub config: DatasetConfig,
    /// Layout of `states`.
    pub layout: CharacterLayout,
    /// Joint name of each DoF.
    pub dof_names: Vec<String>,
    /// End-effector link names (feet, manipulators, head).
    pub end_effector_links: Vec<String>,
    /// How many of `end_effector_links` (the first ones) are feet; columns of `contacts`.
    pub n_feet: usize,
    /// Frame ranges of the episodes.
    pub episodes: Vec<Range<usize>>,
    /// Root world pose per frame.
    pub roots: Vec<Isometry3<f32>>,
    /// Joint positions, `N × dof` row-major.
    pub q: Vec<f32>,
    /// x^r, `N × layout.dim()` row-major.
    pub states: Vec<f32>,
    /// Mean of each x^r entry.
    pub mean: Vec<f32>,
    /// Standard deviation of each x^r entry (at least [`STD_FLOOR`]).
    pub std: Vec<f32>,
    /// Commanded `(vx, vy, wz)` per frame (heading frame).
    pub commands: Vec<[f32; 3]>,
    /// `N × n_feet`, 1 = stance.
    pub contacts: Vec<u8>,
}

/// The human-equivalent speed scale of the controller that [`generate`] builds for `cfg`
/// ([`Rig::speed_scale`]): character speed = scale × commanded human speed.
pub fn speed_scale(tree: &KinematicTree, morph: &Morphology, cfg: &DatasetConfig) -> Result<f32, DatasetError> {
    Ok(rig(tree, morph, cfg)?.speed_scale)
}

fn rig(tree: &KinematicTree, morph: &Morphology, cfg: &DatasetConfig) -> Result<Rig, DatasetError> {
    Rig::new(tree, morph, &cfg.controller, cfg.fps).map_err(|problem| DatasetError::Controller {
        character: tree.name.clone(),
        file: tree.source.clone(),
        problem,
    })
}

/// Rolls out the controllers of a character (see the module docs). `progress` is called with the
/// number of frames done every 1024 frames and at the end.
pub fn generate(
    tree: &KinematicTree,
    morph: &Morphology,
    cfg: &DatasetConfig,
    progress: &mut dyn FnMut(usize),
) -> Result<MotionSet, DatasetError> {
    check_config(cfg)?;
    check_budget(cfg, tree, morph)?;
    let rig = rig(tree, morph, cfg)?;
    let layout = CharacterLayout::new(tree, morph);
    let (n, dof, dim, n_feet) = (cfg.frames, tree.dof(), layout.dim(), morph.feet.len());
    let dt = 1.0 / cfg.fps;
    let mut rng = rand_pcg::Pcg64::seed_from_u64(cfg.seed);
    let mut ctl = Controller::new(tree, &rig, &cfg.controller, cfg.fps);

    let mut set = MotionSet {
        character: tree.name.clone(),
        // Absolute, so that the dataset can be scored from any folder.
        character_source: tree
            .source
            .as_ref()
            .map(|p| fs::canonicalize(p).unwrap_or_else(|_| p.clone()).display().to_string()),
        fps: cfg.fps,
        seed: cfg.seed,
        config: cfg.clone(),
        layout,
        dof_names: tree.dof_names().into_iter().map(String::from).collect(),
        end_effector_links: morph.end_effector_links(tree),
        n_feet,
        episodes: Vec::new(),
        roots: Vec::with_capacity(n),
        q: Vec::with_capacity(n * dof),
        states: vec![0.0; n * dim],
        mean: Vec::new(),
        std: Vec::new(),
        commands: Vec::with_capacity(n),
        contacts: Vec::with_capacity(n * n_feet),
    };
    let clips = own_clip_episodes(tree, morph, cfg)?;
    let clip_frames: usize = clips.iter().map(Vec::len).sum();
    let mut prev = CharacterPose {
        root: Isometry3::identity(),
        q: vec![0.0; dof],
    };
    let mut cur = prev.clone();
    let (mut prev_links, mut cur_links) = (Vec::new(), Vec::new());
    let mut done = 0;
    while done < n - clip_frames {
        let seconds = uniform(&mut rng, cfg.episode_seconds[0], cfg.episode_seconds[1]);
        let len = ((seconds * cfg.fps).round() as usize).max(2).min(n - clip_frames - done);
        ctl.reset(&mut rng);
        for k in 0..len {
            if k > 0 {
                ctl.step(&mut rng);
            }
            cur.root = ctl.root();
            cur.q.copy_from_slice(ctl.q());
            tree.forward_kinematics_into(&cur, &mut cur_links);
            let row = &mut set.states[done * dim..(done + 1) * dim];
            if k == 0 {
                write_state(&layout, morph, &cur, &cur, &cur_links, &cur_links, dt, row);
            } else {
                write_state(&layout, morph, &prev, &cur, &prev_links, &cur_links, dt, row);
            }
            set.roots.push(cur.root);
            set.q.extend_from_slice(&cur.q);
            set.commands.push(ctl.command().to_array());
            set.contacts.extend(ctl.contacts().map(u8::from));
            std::mem::swap(&mut prev, &mut cur);
            std::mem::swap(&mut prev_links, &mut cur_links);
            done += 1;
            if done % 1024 == 0 {
                progress(done);
            }
        }
        set.episodes.push(done - len..done);
    }
    let contact_height = crate::metrics::UfrConfig::for_character(tree, morph).contact_height;
    for poses in &clips {
        for (k, pose) in poses.iter().enumerate() {
            tree.forward_kinematics_into(pose, &mut cur_links);
            let row = &mut set.states[done * dim..(done + 1) * dim];
            let before = if k == 0 { pose } else { &poses[k - 1] };
            if k == 0 {
                write_state(&layout, morph, pose, pose, &cur_links, &cur_links, dt, row);
            } else {
                write_state(&layout, morph, before, pose, &prev_links, &cur_links, dt, row);
            }
            set.roots.push(pose.root);
            set.q.extend_from_slice(&pose.q);
            set.commands.push(root_velocity(&before.root, &pose.root, dt));
            set.contacts
                .extend(morph.feet.iter().map(|&f| u8::from(morph.ee_point(f, &cur_links).z < contact_height)));
            std::mem::swap(&mut prev_links, &mut cur_links);
            done += 1;
        }
        set.episodes.push(done - poses.len()..done);
        progress(done);
    }
    progress(done);
    (set.mean, set.std) = statistics(&set.states, dim);
    if let Some(problem) = set.non_finite() {
        return Err(DatasetError::Config(format!(
            "the controllers of `{}` produced a dataset that {problem}; nothing was written",
            tree.name
        )));
    }
    Ok(set)
}

/// The heading-frame velocity `(vx, vy, wz)` of a root moving from `a` to `b` in `dt` seconds.
fn root_velocity(a: &Isometry3<f32>, b: &Isometry3<f32>, dt: f32) -> [f32; 3] {
    let yaw = |r: &Isometry3<f32>| crate::frame::heading_yaw(&(r.rotation * nalgebra::Vector3::x()));
    let (ya, yb) = (yaw(a), yaw(b));
    let d = b.translation.vector - a.translation.vector;
    let (s, c) = ya.sin_cos();
    let turn = (yb - ya + std::f32::consts::PI).rem_euclid(std::f32::consts::TAU) - std::f32::consts::PI;
    [(c * d.x + s * d.y) / dt, (c * d.y - s * d.x) / dt, turn / dt]
}

/// The episodes of the creature's own clips that `cfg.own_clips` asks for (none when its share is 0):
/// the clips in turn, carried by their feet, until their share of `cfg.frames` is full. Errors name
/// the character file and what is wrong.
fn own_clip_episodes(
    tree: &KinematicTree,
    morph: &Morphology,
    cfg: &DatasetConfig,
) -> Result<Vec<Vec<CharacterPose>>, DatasetError> {
    use crate::character::clips::{clip_poses_on_feet, exact_profile, with_travel};
    let own = &cfg.own_clips;
    let wanted = (f64::from(own.share) * cfg.frames as f64).round() as usize;
    if wanted == 0 {
        return Ok(Vec::new());
    }
    let source = tree.source.clone().unwrap_or_else(|| PathBuf::from(&tree.name));
    let fail = |problem: String| Err(file_error(&source, format!("its own clips (`own_clips`): {problem}")));
    if tree.source.is_none() || !crate::character::is_gltf(&source) {
        return fail("only a rigged glTF creature (.glb, .gltf) has animation clips".into());
    }
    let c = crate::character::load_creature(&source).map_err(|e| file_error(&source, e.to_string()))?;
    if c.tree.dof_names() != tree.dof_names() {
        return fail("the file now gives the creature other joints than the character being generated".into());
    }
    let exact = crate::character::load_creature_with(&source, &exact_profile(&c))
        .map_err(|e| file_error(&source, e.to_string()))?;
    let names: Vec<&str> = c.rig.animations.iter().map(|a| a.name.as_str()).collect();
    let chosen: Vec<usize> = if own.names.is_empty() {
        (0..names.len()).collect()
    } else {
        let mut chosen = Vec::new();
        for n in &own.names {
            match names.iter().position(|m| m == n) {
                Some(k) => chosen.push(k),
                None => return fail(format!("no clip is named `{n}`; its clips: {}", list(&names))),
            }
        }
        chosen
    };
    let contact_height = crate::metrics::UfrConfig::for_character(tree, morph).contact_height;
    let played: Vec<Vec<CharacterPose>> = chosen
        .iter()
        .map(|&k| with_travel(&c, clip_poses_on_feet(&c, &exact, k, cfg.fps), contact_height))
        .filter(|p| p.len() >= 2)
        .collect();
    if played.is_empty() {
        return fail(if names.is_empty() {
            "the file has no animation clips".into()
        } else {
            "none of its clips lasts two frames".into()
        });
    }
    let mut out = Vec::new();
    let mut left = wanted;
    for poses in played.iter().cycle() {
        let take = poses.len().min(left);
        // An episode needs two frames for its velocities; a last single frame is left to the controllers.
        if take < 2 {
            break;
        }
        out.push(poses[..take].to_vec());
        left -= take;
    }
    Ok(out)
}

/// `names` as "`a`, `b`" (or "none").
fn list(names: &[&str]) -> String {
    if names.is_empty() {
        return "none".into();
    }
    names.iter().map(|n| format!("`{n}`")).collect::<Vec<_>>().join(", ")
}

/// Most frames a dataset may have: 25 times the paper's 200k, a few GB of states and poses. Checked
/// before anything is allocated.
pub const MAX_FRAMES: usize = 5_000_000;

/// Most bytes of states and joint positions a dataset may hold (4 GiB): `frames` × (x^r + DoF) × 4 B.
/// [`MAX_FRAMES`] of a bundled character stay far below it; 5 million frames of a 1,024-link robot
/// would take 40 GB. Checked before anything is allocated ([`check_budget`]).
pub const MAX_DATASET_BYTES: u64 = 4 << 30;

/// Checks that `cfg.frames` of this character fit in [`MAX_DATASET_BYTES`]; the error names `frames`,
/// the character's DoF and state width, the bytes and the most frames that fit.
pub fn check_budget(cfg: &DatasetConfig, tree: &KinematicTree, morph: &Morphology) -> Result<(), DatasetError> {
    let (dof, dim) = (tree.dof(), CharacterLayout::new(tree, morph).dim());
    let per_frame = 4 * (dim + dof) as u64;
    let bytes = (cfg.frames as u64).saturating_mul(per_frame);
    if bytes <= MAX_DATASET_BYTES {
        return Ok(());
    }
    Err(DatasetError::Config(format!(
        "`frames` = {} of `{}` ({dof} DoF, x^r of {dim} values: {per_frame} bytes a frame) is {bytes} bytes, \
         more than the {MAX_DATASET_BYTES} a dataset may hold: at most {} frames of this character",
        cfg.frames,
        tree.name,
        MAX_DATASET_BYTES / per_frame
    )))
}

/// Checks that every value of `cfg` is in range, the controllers' included, before anything is
/// generated; errors name the field (as the TOML file spells it) and the valid range. Probabilities
/// lie in 0 to 1, durations, time constants, lengths and speeds are positive and bounded, and
/// `[low, high]` ranges are finite and in order: a value outside these would make the controllers'
/// speeds or filters infinite or NaN (`human_leg_length = 0` made the speed scale infinite) or their
/// draws meaningless.
pub fn check_config(cfg: &DatasetConfig) -> Result<(), DatasetError> {
    let bad = |m: String| Err(DatasetError::Config(m));
    if !(1..=MAX_FRAMES).contains(&cfg.frames) {
        return bad(format!(
            "`frames` = {} is out of range: expected 1 to {MAX_FRAMES}",
            cfg.frames
        ));
    }
    if !(FPS_RANGE.0..=FPS_RANGE.1).contains(&cfg.fps) {
        return bad(format!("`fps` = {} is out of range: expected {} to {}", cfg.fps, FPS_RANGE.0, FPS_RANGE.1));
    }
    let [a, b] = cfg.episode_seconds;
    if !(a.is_finite() && b.is_finite() && a > 0.0 && a <= b) {
        return bad(format!(
            "episode_seconds must be an increasing pair of positive numbers, not [{a}, {b}]"
        ));
    }
    in_range("own_clips.share", cfg.own_clips.share, 0.0, OwnClipsConfig::MAX_SHARE, "").map_err(DatasetError::Config)?;
    check_controller(&cfg.controller).map_err(DatasetError::Config)
}

/// A value in `lo..=hi` (finite), or the error naming `field`, the value and the range (`unit` after
/// the range, e.g. " s").
fn in_range(field: &str, v: f32, lo: f32, hi: f32, unit: &str) -> Result<(), String> {
    if v.is_finite() && (lo..=hi).contains(&v) {
        return Ok(());
    }
    Err(format!("`{field}` = {v} is out of range: expected {lo} to {hi}{unit}"))
}

/// A `[low, high]` pair with `lo ≤ low ≤ high ≤ hi`, or the error naming `field`, the pair and the range.
fn pair_in_range(field: &str, [a, b]: [f32; 2], lo: f32, hi: f32, unit: &str) -> Result<(), String> {
    if a.is_finite() && b.is_finite() && lo <= a && a <= b && b <= hi {
        return Ok(());
    }
    Err(format!(
        "`{field}` = [{a}, {b}] is out of range: expected [low, high] with {lo} ≤ low ≤ high ≤ {hi}{unit}"
    ))
}

/// A probability (0 to 1).
fn probability(field: &str, v: f32) -> Result<(), String> {
    in_range(field, v, 0.0, 1.0, " (a probability)")
}

/// The bounds of every `controller.*` field (see [`check_config`]).
fn check_controller(c: &ControllerConfig) -> Result<(), String> {
    // Speeds in human-equivalent m/s (the paper's forward range is −1.5 to 5), durations in s.
    const SPEED: f32 = 20.0;
    const HOLD: [f32; 2] = [0.01, 3600.0];
    const TAU: [f32; 2] = [0.001, 60.0];
    let m = &c.commands;
    let f = |name: &str| format!("controller.commands.{name}");
    pair_in_range(&f("forward"), m.forward, -SPEED, SPEED, " (human-equivalent m/s)")?;
    pair_in_range(&f("lateral"), m.lateral, -SPEED, SPEED, " (human-equivalent m/s)")?;
    pair_in_range(&f("slow"), m.slow, -SPEED, SPEED, " (human-equivalent m/s)")?;
    pair_in_range(&f("yaw_rate"), m.yaw_rate, -10.0, 10.0, " (rad/s)")?;
    pair_in_range(&f("hold_seconds"), m.hold_seconds, HOLD[0], HOLD[1], " (s)")?;
    in_range(&f("time_constant"), m.time_constant, TAU[0], TAU[1], " (s)")?;
    probability(&f("p_stand"), m.p_stand)?;
    probability(&f("p_turn"), m.p_turn)?;
    probability(&f("p_lateral"), m.p_lateral)?;
    probability(&f("p_slow"), m.p_slow)?;
    if m.p_stand + m.p_turn > 1.0 {
        return Err(format!(
            "`controller.commands.p_stand` + `controller.commands.p_turn` = {} + {} is more than 1: they are \
             probabilities of one draw",
            m.p_stand, m.p_turn
        ));
    }

    let s = &c.scaling;
    in_range("controller.scaling.human_leg_length", s.human_leg_length, 0.1, 10.0, " (m)")?;
    in_range("controller.scaling.human_height", s.human_height, 0.1, 10.0, " (m)")?;
    if let Some(k) = s.speed_scale {
        in_range("controller.scaling.speed_scale", k, 0.001, 100.0, " (character m/s per human-equivalent m/s)")?;
    }
    if let Some(v) = s.walking_pace {
        in_range("controller.scaling.walking_pace", v, 0.1, 10.0, " (m/s)")?;
    }

    let p = &c.posture;
    let f = |name: &str| format!("controller.posture.{name}");
    pair_in_range(&f("height"), p.height, -0.9, 1.0, " (fractions of the nominal height)")?;
    in_range(&f("pitch"), p.pitch, 0.0, 1.5, " (rad)")?;
    in_range(&f("roll"), p.roll, 0.0, 1.5, " (rad)")?;
    pair_in_range(&f("hold_seconds"), p.hold_seconds, HOLD[0], HOLD[1], " (s)")?;
    in_range(&f("time_constant"), p.time_constant, TAU[0], TAU[1], " (s)")?;

    let l = &c.legs;
    let f = |name: &str| format!("controller.legs.{name}");
    in_range(&f("max_extension"), l.max_extension, 0.05, 1.0, " (a fraction of the leg's reach)")?;
    in_range(&f("swing_height"), l.swing_height, 0.01, 1.0, " (a fraction of the leg length)")?;
    for (name, n) in [
        ("min_swing_frames", l.min_swing_frames),
        ("walking_min_swing_frames", l.walking_min_swing_frames),
    ] {
        if !(1..=1000).contains(&n) {
            return Err(format!("`{}` = {n} is out of range: expected 1 to 1000 (frames)", f(name)));
        }
    }
    probability(&f("bound_probability"), l.bound_probability)?;
    in_range(&f("frequency_time_constant"), l.frequency_time_constant, TAU[0], TAU[1], " (s)")?;
    if let Some(k) = l.cadence_limit {
        in_range(&f("cadence_limit"), k, 1.0, 10.0, " (times the law's stride frequency)")?;
    }

    let r = &c.reach;
    let f = |name: &str| format!("controller.reach.{name}");
    probability(&f("stow_probability"), r.stow_probability)?;
    pair_in_range(&f("hold_seconds"), r.hold_seconds, HOLD[0], HOLD[1], " (s)")?;
    in_range(&f("speed_fraction"), r.speed_fraction, 0.001, 1.0, " (a fraction of the velocity limit)")?;
    in_range(&f("max_speed_fraction"), r.max_speed_fraction, 0.001, 1.0, " (a fraction of the velocity limit)")?;
    if r.speed_fraction > r.max_speed_fraction {
        return Err(format!(
            "`controller.reach.speed_fraction` = {} is more than `controller.reach.max_speed_fraction` = {}: they are \
             the low and high ends of one range",
            r.speed_fraction, r.max_speed_fraction
        ));
    }
    probability(&f("local_probability"), r.local_probability)?;
    in_range(&f("local_fraction"), r.local_fraction, 0.0, 1.0, " (a fraction of each DoF's range)")?;
    if let Some(h) = r.home_reach {
        in_range(&f("home_reach"), h, 0.0, 10.0, " (a fraction of the arm's length)")?;
    }
    in_range(&f("default_angular_speed"), r.default_angular_speed, 0.01, 100.0, " (rad/s)")?;
    in_range(&f("default_linear_speed"), r.default_linear_speed, 0.001, 10.0, " (m/s)")?;
    in_range(&f("min_duration"), r.min_duration, 0.01, 60.0, " (s)")?;
    in_range(&f("margin"), r.margin, 0.0, 1.0, " (m)")?;
    Ok(())
}

/// Mean and standard deviation (floored at [`STD_FLOOR`]) of each column of a `rows × dim` matrix,
/// accumulated in `f64`.
pub fn statistics(data: &[f32], dim: usize) -> (Vec<f32>, Vec<f32>) {
    let rows = data.len().checked_div(dim).unwrap_or(0);
    let mut sum = vec![0.0f64; dim];
    for r in data.chunks_exact(dim.max(1)) {
        for (s, &x) in sum.iter_mut().zip(r) {
            *s += f64::from(x);
        }
    }
    let mean: Vec<f64> = sum.iter().map(|s| s / rows.max(1) as f64).collect();
    let mut var = vec![0.0f64; dim];
    for r in data.chunks_exact(dim.max(1)) {
        for ((v, &x), m) in var.iter_mut().zip(r).zip(&mean) {
            let d = f64::from(x) - m;
            *v += d * d;
        }
    }
    let std = var
        .iter()
        .map(|v| ((v / rows.max(1) as f64).sqrt() as f32).max(STD_FLOOR))
        .collect();
    (mean.iter().map(|&m| m as f32).collect(), std)
}

impl MotionSet {
    /// Number of frames.
    pub fn len(&self) -> usize {
        self.roots.len()
    }

    /// True when there are no frames.
    pub fn is_empty(&self) -> bool {
        self.roots.is_empty()
    }

    /// Number of DoFs.
    pub fn dof(&self) -> usize {
        self.layout.dof
    }

    /// x^r of frame `i`.
    pub fn state(&self, i: usize) -> &[f32] {
        let d = self.layout.dim();
        &self.states[i * d..(i + 1) * d]
    }

    /// Stance flags of frame `i`, one per foot.
    pub fn contact(&self, i: usize) -> &[u8] {
        &self.contacts[i * self.n_feet..(i + 1) * self.n_feet]
    }

    /// The pose of frame `i`.
    pub fn pose(&self, i: usize) -> CharacterPose {
        let d = self.dof();
        CharacterPose {
            root: self.roots[i],
            q: self.q[i * d..(i + 1) * d].to_vec(),
        }
    }

    /// The poses of episode `episode`.
    pub fn poses(&self, episode: usize) -> Vec<CharacterPose> {
        self.episodes[episode].clone().map(|i| self.pose(i)).collect()
    }

    /// The root poses as 7 values a frame: translation, then the quaternion (w, i, j, k), as saved.
    fn root_values(&self) -> Vec<f32> {
        self.roots
            .iter()
            .flat_map(|r| {
                let (t, q) = (r.translation.vector, r.rotation.quaternion());
                [t.x, t.y, t.z, q.w, q.i, q.j, q.k]
            })
            .collect()
    }

    /// What is not finite in the dataset's values (x^r, joint positions, root poses, commands and
    /// statistics): the first tensor that holds a NaN or an infinity, how many it holds and the first
    /// frame (or entry); `None` when every value is finite.
    pub fn non_finite(&self) -> Option<String> {
        let roots = self.root_values();
        let commands: Vec<f32> = self.commands.iter().flatten().copied().collect();
        let dim = self.layout.dim();
        [
            ("states", &self.states[..], dim),
            ("q", &self.q[..], self.dof()),
            ("roots", &roots[..], 7),
            ("commands", &commands[..], 3),
            ("mean", &self.mean[..], 0),
            ("std", &self.std[..], 0),
        ]
        .into_iter()
        .find_map(|(name, values, width)| non_finite_in(name, values, width))
    }

    /// Writes the dataset (see the module docs), atomically: a temporary file in the same directory is
    /// renamed into place. A dataset with a non-finite value ([`MotionSet::non_finite`]) is refused,
    /// naming the file, and nothing is written.
    pub fn save(&self, path: &Path) -> Result<(), DatasetError> {
        if let Some(problem) = self.non_finite() {
            return Err(file_error(path, format!("refusing to write a dataset that {problem}")));
        }
        let bytes = self.to_bytes()?;
        path.file_name().ok_or_else(|| file_error(path, "not a file path"))?;
        crate::temporary::write_atomically(path, &bytes)
            .map_err(|e| file_error(path, format!("cannot write the dataset: {e}")))
    }

    /// The file's bytes (see the module docs).
    pub fn to_bytes(&self) -> Result<Vec<u8>, DatasetError> {
        let (n, dim, dof, f) = (self.len(), self.layout.dim(), self.dof(), self.n_feet);
        let mut episodes = Vec::with_capacity(self.episodes.len() * 16);
        for e in &self.episodes {
            episodes.extend((e.start as i64).to_le_bytes());
            episodes.extend((e.end as i64).to_le_bytes());
        }
        let roots = self.root_values();
        let commands: Vec<f32> = self.commands.iter().flatten().copied().collect();
        // Data order: the 8-byte dtype first so that every tensor stays aligned.
        let tensors: Vec<(&str, Dtype, Vec<usize>, Vec<u8>)> = vec![
            ("episodes", Dtype::I64, vec![self.episodes.len(), 2], episodes),
            ("commands", Dtype::F32, vec![n, 3], f32_bytes(&commands)),
            ("mean", Dtype::F32, vec![dim], f32_bytes(&self.mean)),
            ("q", Dtype::F32, vec![n, dof], f32_bytes(&self.q)),
            ("roots", Dtype::F32, vec![n, 7], f32_bytes(&roots)),
            ("states", Dtype::F32, vec![n, dim], f32_bytes(&self.states)),
            ("std", Dtype::F32, vec![dim], f32_bytes(&self.std)),
            ("contacts", Dtype::U8, vec![n, f], self.contacts.clone()),
        ];
        let config = serde_json::to_string(&self.config).map_err(|e| DatasetError::Config(e.to_string()))?;
        let mut meta = serde_json::Map::new();
        let mut put = |k: &str, v: String| {
            meta.insert(k.into(), Value::String(v));
        };
        put("format", FORMAT.into());
        put("format_version", FORMAT_VERSION.to_string());
        put("character", self.character.clone());
        if let Some(source) = &self.character_source {
            put("character_source", source.clone());
        }
        put("fps", self.fps.to_string());
        put("seed", self.seed.to_string());
        put("config", config);
        put(
            "layout",
            json!({"dof": self.layout.dof, "end_effectors": self.layout.end_effectors, "dim": dim}).to_string(),
        );
        put("dof_names", json!(self.dof_names).to_string());
        put("end_effector_links", json!(self.end_effector_links).to_string());
        put("n_feet", self.n_feet.to_string());
        let mut header = serde_json::Map::new();
        header.insert("__metadata__".into(), Value::Object(meta));
        let mut offset = 0;
        for (name, dtype, shape, data) in &tensors {
            header.insert(
                (*name).into(),
                json!({"dtype": dtype_name(*dtype), "shape": shape, "data_offsets": [offset, offset + data.len()]}),
            );
            offset += data.len();
        }
        let mut head = Value::Object(header).to_string().into_bytes();
        head.resize(head.len().next_multiple_of(8), b' ');
        let mut out = Vec::with_capacity(8 + head.len() + offset);
        out.extend((head.len() as u64).to_le_bytes());
        out.extend(head);
        for (_, _, _, data) in &tensors {
            out.extend(data);
        }
        Ok(out)
    }

    /// Reads a dataset written by [`MotionSet::save`] from a regular file ([`crate::input::read_regular`]),
    /// checking it (see the module docs).
    pub fn load(path: &Path) -> Result<MotionSet, DatasetError> {
        let bytes = crate::input::read_regular(path, crate::input::MAX_DATA_BYTES).map_err(|e| match e {
            crate::input::ReadError::Io(e) => file_error(path, format!("cannot read the file: {e}")),
            other => file_error(path, other.to_string()),
        })?;
        MotionSet::from_bytes(&bytes).map_err(|p| file_error(path, p))
    }

    /// Parses a dataset file's bytes; the error is the problem (without the file name).
    pub fn from_bytes(bytes: &[u8]) -> Result<MotionSet, String> {
        let st = SafeTensors::deserialize(bytes).map_err(|e| describe(e, bytes.len()))?;
        let (_, header) = SafeTensors::read_metadata(bytes).map_err(|e| describe(e, bytes.len()))?;
        let meta = header.metadata().clone().unwrap_or_default();
        let get = |k: &str| meta.get(k).ok_or_else(|| format!("the metadata has no `{k}` entry"));
        let format = get("format")?;
        if format != FORMAT {
            return Err(format!(
                "not an ACE motion set (format `{format}`, expected `{FORMAT}`)"
            ));
        }
        let version = get("format_version")?;
        if version.parse::<u32>().ok() != Some(FORMAT_VERSION) {
            return Err(format!(
                "format version {version} is not supported (this build reads version {FORMAT_VERSION})"
            ));
        }
        let parse = |k: &str| -> Result<Value, String> {
            serde_json::from_str(get(k)?).map_err(|e| format!("metadata `{k}` is not valid JSON: {e}"))
        };
        let number = |k: &str| -> Result<f64, String> {
            get(k)?
                .parse::<f64>()
                .map_err(|_| format!("metadata `{k}` is not a number"))
        };
        let fps = number("fps")? as f32;
        if !(FPS_RANGE.0..=FPS_RANGE.1).contains(&fps) {
            return Err(format!("metadata `fps` is {fps}; expected {} to {} frames per second", FPS_RANGE.0, FPS_RANGE.1));
        }
        let config = serde_json::from_str(get("config")?)
            .and_then(DatasetConfig::from_record)
            .map_err(|e| format!("metadata `config` is not a dataset configuration: {e}"))?;
        let layout_v = parse("layout")?;
        // Bounded before `dim()` adds them: a robot has at most MAX_LINKS links of at most 6 DoF.
        let most = crate::urdf::MAX_LINKS * 6;
        let field = |k: &str| {
            let v = layout_v[k].as_u64().ok_or_else(|| format!("metadata `layout` has no `{k}`"))?;
            usize::try_from(v)
                .ok()
                .filter(|&v| v <= most || k == "dim")
                .ok_or_else(|| format!("metadata `layout`: `{k}` is {v}; at most {most} (6 per link of the most a robot has)"))
        };
        let layout = CharacterLayout {
            dof: field("dof")?,
            end_effectors: field("end_effectors")?,
        };
        if field("dim")? != layout.dim() {
            return Err(format!(
                "metadata `layout`: dim {} does not match dof {} and {} end effectors",
                field("dim")?,
                layout.dof,
                layout.end_effectors
            ));
        }
        let strings = |k: &str| -> Result<Vec<String>, String> {
            serde_json::from_str(get(k)?).map_err(|e| format!("metadata `{k}` is not a JSON array of strings: {e}"))
        };
        let dof_names = strings("dof_names")?;
        let end_effector_links = strings("end_effector_links")?;
        let n_feet: usize = get("n_feet")?
            .parse()
            .map_err(|_| "metadata `n_feet` is not a whole number of feet".to_string())?;
        if dof_names.len() != layout.dof
            || end_effector_links.len() != layout.end_effectors
            || n_feet > layout.end_effectors
        {
            return Err("metadata: the DoF names, end-effector links or foot count disagree with the layout".into());
        }

        let tensor = |name: &str, dtype: Dtype, cols: Option<usize>| -> Result<(Vec<usize>, &[u8]), String> {
            let t = st.tensor(name).map_err(|_| format!("missing tensor `{name}`"))?;
            if t.dtype() != dtype {
                return Err(format!(
                    "tensor `{name}` has dtype {:?}, expected {:?}",
                    t.dtype(),
                    dtype
                ));
            }
            let shape = t.shape().to_vec();
            let ok = match cols {
                Some(c) => shape.len() == 2 && shape[1] == c,
                None => shape.len() == 1,
            };
            if !ok {
                let want = cols.map_or("[D]".to_string(), |c| format!("[N, {c}]"));
                return Err(format!("tensor `{name}` has shape {shape:?}, expected {want}"));
            }
            Ok((shape, t.data()))
        };
        let dim = layout.dim();
        let (s_states, states) = tensor("states", Dtype::F32, Some(dim))?;
        let n = s_states[0];
        let rows = |name: &str, shape: &[usize]| {
            if shape[0] == n {
                Ok(())
            } else {
                Err(format!("tensor `{name}` has {} rows, `states` has {n}", shape[0]))
            }
        };
        let (s, roots) = tensor("roots", Dtype::F32, Some(7))?;
        rows("roots", &s)?;
        let (s, q) = tensor("q", Dtype::F32, Some(layout.dof))?;
        rows("q", &s)?;
        let (s, commands) = tensor("commands", Dtype::F32, Some(3))?;
        rows("commands", &s)?;
        let (s, contacts) = tensor("contacts", Dtype::U8, Some(n_feet))?;
        rows("contacts", &s)?;
        let (s, mean) = tensor("mean", Dtype::F32, None)?;
        let (s2, std) = tensor("std", Dtype::F32, None)?;
        if s[0] != dim || s2[0] != dim {
            return Err(format!(
                "tensors `mean` and `std` must have {dim} entries, they have {} and {}",
                s[0], s2[0]
            ));
        }
        let (_, episodes) = tensor("episodes", Dtype::I64, Some(2))?;
        let bounds: Vec<i64> = episodes
            .chunks_exact(8)
            .map(|c| i64::from_le_bytes(c.try_into().expect("8 bytes")))
            .collect();
        let mut ranges = Vec::with_capacity(bounds.len() / 2);
        let mut expect = 0i64;
        for (k, e) in bounds.chunks_exact(2).enumerate() {
            if e[0] != expect || e[1] <= e[0] || e[1] > n as i64 {
                return Err(format!(
                    "episode {k} is [{}, {}): episodes must be non-empty, in order and cover the {n} frames",
                    e[0], e[1]
                ));
            }
            expect = e[1];
            ranges.push(e[0] as usize..e[1] as usize);
        }
        if expect != n as i64 {
            return Err(format!("the episodes cover {expect} of the {n} frames"));
        }
        let roots = floats(roots)
            .chunks_exact(7)
            .map(|r| {
                Isometry3::from_parts(
                    Translation3::new(r[0], r[1], r[2]),
                    UnitQuaternion::new_unchecked(Quaternion::new(r[3], r[4], r[5], r[6])),
                )
            })
            .collect();
        let set = MotionSet {
            character: get("character")?.clone(),
            character_source: meta.get("character_source").cloned(),
            fps,
            seed: get("seed")?
                .parse()
                .map_err(|_| "metadata `seed` is not an integer".to_string())?,
            config,
            layout,
            dof_names,
            end_effector_links,
            n_feet,
            episodes: ranges,
            roots,
            q: floats(q),
            states: floats(states),
            mean: floats(mean),
            std: floats(std),
            commands: floats(commands).chunks_exact(3).map(|c| [c[0], c[1], c[2]]).collect(),
            contacts: contacts.to_vec(),
        };
        if let Some(problem) = set.non_finite() {
            return Err(format!("the dataset {problem}"));
        }
        // Training divides by the deviations: one below the floor gave NaN losses blamed on the
        // learning rate.
        if let Some((i, sd)) = set.std.iter().enumerate().find(|(_, sd)| **sd < STD_FLOOR) {
            return Err(format!("tensor `std` entry {i} is {sd}; every standard deviation is at least {STD_FLOOR}"));
        }
        Ok(set)
    }
}

/// "holds N non-finite value(s) …" for the tensor `name` (rows of `width` values; 0: a vector), or
/// `None` when all its values are finite.
fn non_finite_in(name: &str, values: &[f32], width: usize) -> Option<String> {
    let first = values.iter().position(|x| !x.is_finite())?;
    let count = values.iter().filter(|x| !x.is_finite()).count();
    let at = if width == 0 {
        format!("entry {first}")
    } else {
        format!("frame {} (column {})", first / width, first % width)
    };
    Some(format!(
        "holds {count} non-finite value(s) (NaN or infinity) in `{name}`, the first at {at}"
    ))
}

fn f32_bytes(v: &[f32]) -> Vec<u8> {
    v.iter().flat_map(|x| x.to_le_bytes()).collect()
}

fn floats(b: &[u8]) -> Vec<f32> {
    b.chunks_exact(4)
        .map(|c| f32::from_le_bytes(c.try_into().expect("4 bytes")))
        .collect()
}

fn dtype_name(d: Dtype) -> &'static str {
    match d {
        Dtype::I64 => "I64",
        Dtype::F32 => "F32",
        Dtype::U8 => "U8",
        _ => unreachable!("only I64, F32 and U8 are written"),
    }
}

/// A readable sentence for a safetensors error on a file of `len` bytes.
fn describe(e: SafeTensorError, len: usize) -> String {
    match e {
        SafeTensorError::HeaderTooSmall | SafeTensorError::InvalidHeaderLength => {
            format!("not a safetensors file, or truncated: the header does not fit in the file's {len} bytes")
        }
        SafeTensorError::MetadataIncompleteBuffer => {
            format!("truncated or corrupted: the tensors the header lists do not match the file's {len} bytes")
        }
        SafeTensorError::InvalidHeader(_) | SafeTensorError::InvalidHeaderDeserialization(_) => {
            "not a safetensors file: the header is not valid JSON".into()
        }
        SafeTensorError::HeaderTooLarge => "not a safetensors file: the header length is implausible".into(),
        other => format!("corrupted safetensors file: {other}"),
    }
}
