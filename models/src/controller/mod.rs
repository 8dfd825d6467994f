//! Kinematic controllers that generate a character's motion dataset (paper §4, §7.1): random base
//! commands, stepping gaits for any number of legs, reaching for manipulators and other free DoFs,
//! rolling wheels, a creature's spine bending with its turns and strides ([`spine`]) and a legless
//! creature's crawl ([`undulation`]) — all derived from the morphology analysis, with no per-robot code.
//!
//! - [`Rig`] analyses the character once (leg chains, nominal stance, step radius, wheels, reach groups,
//!   speed scale, gaits).
//! - [`Controller`] runs an episode frame by frame: [`Controller::reset`] puts the character in its
//!   standing pose, [`Controller::step`] advances one frame, [`Controller::root`] and
//!   [`Controller::q`] give the pose.
//!
//! # Speed scaling
//! Commands are drawn in human-equivalent m/s (the paper's −1.5…5 m/s forward, ±1 m/s sideways) and
//! multiplied by the speed scale: `leg length / 0.9 m` for legged characters (leg length = mean hip–foot
//! distance at the nominal stance; 0.9 m is a human's), `standing height / 1.7 m` otherwise. The yaw
//! rate (−1…1 rad/s) is not scaled. A character whose top speed ([`Rig::max_speed`]) is below what a
//! person walking at [`ScalingConfig::walking_pace`] asks of it gets a smaller scale, so that the
//! person's walk maps to its top speed. Linear speed is further limited to what the legs can follow cleanly:
//! `|v| + |ω|·R ≤` [`Rig::max_speed`] (R = mean foot distance from the root), and, with
//! [`LegConfig::cadence_limit`] (1.25 by default), to what they follow at that multiple of the law's
//! stride frequency: the ellipse of [`Rig::cadence_speeds`] forward and sideways, a turn counted as a
//! sidestep of its feet ([`CommandGenerator::with_cadence_speeds`]). A wheeled base is limited the same
//! way by its wheels' velocity limits (R = the farthest wheel's distance; [`ScalingConfig::wheel_limits`]),
//! and a legged robot by its leg joints' ([`joint_speed`]; [`ScalingConfig::leg_limits`]): no gait is
//! used faster than its swinging feet can move with every leg joint within its velocity limit.
//! [`ScalingConfig::speed_scale`] overrides the scale.
//!
//! # Gait timing
//! Legs step as animals do ([`crate::dynamic_similarity`]): the gait, its duty factor and the stride
//! frequency follow the Froude number of the foot speed `|v| + |ω|·R` and the hip height — the stride
//! frequency is Alexander's `v / (2.3·h·Fr^0.3)`. Where a stance would not fit in the step radius,
//! the duty factor is first lowered within the gait's range ([`gait::Gait::duty_fitting`]) and only
//! then the frequency raised; it is capped so that swings last at least [`LegConfig::min_swing_frames`] frames
//! ([`LegConfig::walking_min_swing_frames`] in the walks, judged by the body's speed now and over the
//! stride: [`LegConfig::walks_by_body_speed`]). The bundled Spot-like
//! character (0.53 m legs) gets a speed scale of 0.585: 5 m/s becomes 2.9 m/s, held to 1.9 m/s by its
//! leg joints. Stretch-like (1.3 m tall, scale 0.77 by its height) drives at up to 0.6 m/s, what its
//! wheels allow, so its scale is 0.4 (the walking pace above).
//!
//! # Clean motion
//! Stance feet are fixed in the world (IK to 0.01 mm), feet never go below the ground, every joint value
//! is clamped into its limits, legs stay within a calibrated step radius clear of the body and each
//! other ([`calibrate`]), swing feet rise before they move and come straight down, and reach paths are
//! checked against the body, the legs and each other ([`reach`]). Legs with DoFs to spare (ball joints)
//! are solved from the nominal stance every frame, so that their pose is the one the calibration
//! checked for that foot position rather than wherever the IK's null space drifted.

pub mod calibrate;
pub mod chain;
pub mod collide;
pub mod commands;
pub mod gait;
pub mod joint_speed;
pub mod legs;
pub mod reach;
pub mod rig;
pub mod spine;
pub mod undulation;
pub mod wheels;

use nalgebra::{Isometry3, Point3, Translation3, UnitQuaternion, Vector2};
use rand::RngExt;
use serde::{Deserialize, Serialize};
use thiserror::Error;

pub use chain::{Chain, ChainScratch, IkResult};
pub use commands::{Command, CommandConfig, CommandGenerator};
pub use gait::{Gait, GaitKind, GaitSelector};
pub use legs::{BaseMotion, LegPhase, LegState, StepParams, StrideWalk};
pub use reach::{ReachConfig, ReachEvents, ReachState};
pub use rig::{BaseMode, Leg, ReachGroup, ReachKind, Rig, Wheel};

use crate::dynamic_similarity;
use crate::kinematics::{CharacterPose, KinematicTree};

/// Uniform draw in `[lo, hi)` (`lo` when the range is empty).
pub(crate) fn uniform<R: rand::Rng + ?Sized>(rng: &mut R, lo: f32, hi: f32) -> f32 {
    if hi > lo {
        lo + (hi - lo) * rng.random::<f32>()
    } else {
        lo
    }
}

/// Everything the controllers can be tuned with. Every field has a default; TOML/JSON may give any
/// subset.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct ControllerConfig {
    /// Random base commands.
    pub commands: CommandConfig,
    /// Human-to-character speed scaling.
    pub scaling: ScalingConfig,
    /// Body height, pitch and roll variation.
    pub posture: PostureConfig,
    /// Legs and gaits.
    pub legs: LegConfig,
    /// Reaching.
    pub reach: ReachConfig,
}

/// How human-equivalent speeds become character speeds (see the module docs).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct ScalingConfig {
    /// A human's leg length (m).
    pub human_leg_length: f32,
    /// A human's height (m), for characters without legs.
    pub human_height: f32,
    /// Fixed scale instead of the automatic one.
    pub speed_scale: Option<f32>,
    /// Keep a wheeled base within its wheels' velocity limits (the URDF's `<limit velocity>`): its top
    /// speed, turning included, is what the slowest wheel allows ([`Rig::max_speed`]). Off, the base
    /// drives at the scaled commands whatever its wheels can do (datasets recorded before this
    /// setting).
    pub wheel_limits: bool,
    /// Keep a legged robot's leg joints within their velocity limits: each gait is used, and the base
    /// driven, no faster than its swinging feet can move with every leg joint within its limit
    /// ([`joint_speed`]; [`Rig::foot_speed_limit`]), so that a hexapod on slow servos takes to its
    /// faster gaits early and walks more slowly. Off, the legs step at the animal timing whatever their
    /// joints can do (datasets recorded before this setting). Joints without a limit bound nothing.
    pub leg_limits: bool,
    /// A person's walking pace (m/s) that the character's top speed must keep up with: the automatic
    /// speed scale is at most [`Rig::max_speed`] / this, so that a robot held to a slow top speed by
    /// its joints or wheels walks at its top speed where a person walks this fast, rather than its
    /// commands and L_fea asking of it a speed it cannot reach (the bundled crab: 0.252 → 0.089, Stretch
    /// 0.771 → 0.400; characters faster than that keep their body's scale). `None`: the body's scale
    /// alone (records before this setting). An explicit `speed_scale` is used as given.
    pub walking_pace: Option<f32>,
}

impl Default for ScalingConfig {
    fn default() -> Self {
        ScalingConfig {
            human_leg_length: 0.9,
            human_height: 1.7,
            speed_scale: None,
            wheel_limits: true,
            leg_limits: true,
            walking_pace: Some(1.5),
        }
    }
}

/// Body posture variation of legged characters: random targets held for random times, filtered.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct PostureConfig {
    /// Body height range as fractions of the nominal height (e.g. −0.12 = 12 % lower).
    pub height: [f32; 2],
    /// Largest pitch (rad).
    pub pitch: f32,
    /// Largest roll (rad).
    pub roll: f32,
    /// How long a posture target is held (s).
    pub hold_seconds: [f32; 2],
    /// Filter time constant (s).
    pub time_constant: f32,
}

impl Default for PostureConfig {
    fn default() -> Self {
        PostureConfig {
            height: [-0.08, 0.03],
            pitch: 0.08,
            roll: 0.06,
            hold_seconds: [1.0, 4.0],
            time_constant: 0.5,
        }
    }
}

/// Legs and gaits.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct LegConfig {
    /// Largest hip–foot distance at the nominal stance, as a fraction of the leg's maximal reach.
    pub max_extension: f32,
    /// Peak swing height as a fraction of the leg length.
    pub swing_height: f32,
    /// Shortest swing in frames, from the lift-off frame to the touchdown frame (so `n − 1` frames with
    /// the foot in the air). Together with the frame rate it caps the cadence and thus the top speed.
    pub min_swing_frames: u32,
    /// Shortest swing in frames (as `min_swing_frames`) in the walks, below
    /// [`crate::dynamic_similarity::WALK_TROT_FROUDE`].
    pub walking_min_swing_frames: u32,
    /// Whether a walk, for the shortest swing, is judged by the body's own speed, as Froude's number
    /// and the gait measure's walking swings are, rather than by the feet's `|v| + |ω|·R`, which a turn
    /// raises: judged by the feet's, a turning long-legged spider took trotting swings at walking
    /// speeds. By the body's, the speed now and the stride's mean speed both count, also while the
    /// foot is in the air ([`StrideWalk`]). `false`: the feet's, at lift-off (the datasets recorded
    /// before this setting, which the shipped checkpoints were trained on).
    pub walks_by_body_speed: bool,
    /// Probability per episode that the fast quadruped gait is the bound rather than the gallop.
    pub bound_probability: f32,
    /// Time constant of the stepping frequency filter (s).
    pub frequency_time_constant: f32,
    /// The highest stride frequency a command may ask of the legs, as a multiple of the law's
    /// ([`crate::dynamic_similarity::stride_frequency`]): a command faster, in its direction, than the
    /// legs can follow at that cadence with their stances inside the step regions is slowed to what
    /// they can ([`Rig::cadence_speeds`]). Where the step region is short for the law's strides (a
    /// narrow track, short legs), the character moves more slowly rather than patter. `None`: commands
    /// are limited only by the shortest swing (the datasets recorded before this setting). The default,
    /// 1.25, leaves room for the turns and sidesteps that a straight-ahead bound does not count: measured
    /// over whole datasets, the bundled and shared characters then step at 1.0–1.6× the law.
    pub cadence_limit: Option<f32>,
}

impl Default for LegConfig {
    fn default() -> Self {
        LegConfig {
            max_extension: 0.85,
            swing_height: 0.12,
            min_swing_frames: 4,
            walking_min_swing_frames: 5,
            walks_by_body_speed: true,
            bound_probability: 0.3,
            frequency_time_constant: 0.15,
            cadence_limit: Some(1.25),
        }
    }
}

/// A character the controllers cannot drive.
#[derive(Debug, Clone, Error, PartialEq)]
pub enum ControllerError {
    /// A leg that cannot step.
    #[error("leg ending in `{foot}`: {problem}")]
    Leg {
        /// Foot link name.
        foot: String,
        /// What is wrong.
        problem: String,
    },
    /// A legless creature that cannot crawl: what is missing.
    #[error("cannot crawl: {0}")]
    Crawl(String),
    /// A character without a joint that moves: no motion to generate or to learn.
    #[error("it has no movable joint (every joint is fixed), so there is no motion to generate or learn")]
    Rigid,
}

/// Counters that tell how clean an episode was.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct ControllerStats {
    /// Frames stepped.
    pub frames: usize,
    /// Stance feet that had to lift off early because they drifted beyond their step radius or IK
    /// could not hold them.
    pub early_liftoffs: usize,
    /// Largest IK error of a stance foot (m).
    pub max_stance_error: f32,
    /// Gait changes.
    pub gait_changes: usize,
    /// Reach targets drawn with a clear path.
    pub reach_targets: usize,
    /// Reaches sent back to the stowed configuration because no draw had a clear path.
    pub reach_fallbacks: usize,
}

/// Runs a character's kinematic controllers, one frame at a time (see the module docs).
#[derive(Clone, Debug)]
pub struct Controller<'a> {
    tree: &'a KinematicTree,
    rig: &'a Rig,
    cfg: ControllerConfig,
    dt: f32,
    commands: CommandGenerator,
    position: Vector2<f32>,
    yaw: f32,
    posture: [f32; 3],
    posture_target: [f32; 3],
    /// Gait bob amplitudes: vertical in two-beat gaits, vertical and pitch in bound/gallop (filtered).
    bob: [f32; 3],
    posture_hold: f32,
    q: Vec<f32>,
    legs: Vec<LegState>,
    force_lift: Vec<bool>,
    selector: GaitSelector,
    variant: usize,
    clock: f32,
    frequency: f32,
    stepping: bool,
    reach: Vec<ReachState>,
    scratch: ChainScratch,
    stats: ControllerStats,
    spine: spine::SpineState,
    /// Each leg's step-region centre (heading frame): its nominal foothold, moved with its hip where a
    /// bent spine carries the hip.
    centres: Vec<Vector2<f32>>,
    poses: Vec<Isometry3<f32>>,
    crawl: undulation::CrawlState,
    lift: undulation::LiftTarget,
    /// A crawling root's pose in the heading frame.
    crawl_root: Isometry3<f32>,
}

/// Solves `leg` for `target` (root frame) in `q`. A redundant leg (more than three DoFs, e.g. ball
/// joints) is solved from the nominal stance `nominal_q` every frame, so that its pose is a function
/// of the foot target alone — the pose the step-region calibration checked ([`calibrate`] solves from
/// the nominal stance too) — rather than drifting through the IK's null space over an episode (a knee
/// or shin sinking into the ground while the foot stays on it); the warm start is kept where the
/// nominal start does not reach the target. A leg with three DoFs or fewer has no such drift and is
/// warm-started.
fn solve_leg(
    tree: &KinematicTree,
    leg: &Leg,
    nominal_q: &[f32],
    q: &mut [f32],
    target: &Point3<f32>,
    scratch: &mut ChainScratch,
) -> IkResult {
    if leg.chain.active_dofs().nth(3).is_some() {
        let warm: Vec<f32> = leg.chain.active_dofs().map(|d| q[d]).collect();
        for d in leg.chain.active_dofs() {
            q[d] = nominal_q[d];
        }
        let r = leg.chain.solve(tree, q, target, FOOT_TOL, calibrate::ik_iterations(&leg.chain), scratch);
        if r.error <= STANCE_SLIP {
            return r;
        }
        for (d, &x) in leg.chain.active_dofs().zip(&warm) {
            q[d] = x;
        }
    }
    leg.chain.solve(tree, q, target, FOOT_TOL, 40, scratch)
}

/// Gait bob amplitude as a fraction of the leg length.
const BOB: f32 = 0.012;
/// How far ahead the gait looks at the command (s).
const LOOKAHEAD: f32 = 0.25;
/// IK tolerance for feet (m).
const FOOT_TOL: f32 = 1e-5;
/// Stance IK error above which a foot lifts off at the next frame (m).
const STANCE_SLIP: f32 = 2e-4;

impl<'a> Controller<'a> {
    /// A controller for `rig` (built from `tree`) stepping at `fps`; call [`Controller::reset`] first.
    pub fn new(tree: &'a KinematicTree, rig: &'a Rig, cfg: &ControllerConfig, fps: f32) -> Self {
        let commands = CommandGenerator::new(cfg.commands.clone(), rig.speed_scale, rig.max_speed, rig.foot_radius)
            .with_cadence_speeds(rig.cadence_speeds);
        Controller {
            tree,
            rig,
            cfg: cfg.clone(),
            dt: 1.0 / fps,
            commands,
            position: Vector2::zeros(),
            yaw: 0.0,
            posture: [rig.standing.root.translation.vector.z, 0.0, 0.0],
            posture_target: [rig.nominal_height, 0.0, 0.0],
            bob: [0.0; 3],
            posture_hold: 0.0,
            q: rig.standing.q.clone(),
            legs: Vec::new(),
            force_lift: vec![false; rig.legs.len()],
            selector: GaitSelector { current: 0 },
            variant: 0,
            clock: 0.0,
            frequency: 1.0,
            stepping: false,
            reach: Vec::new(),
            scratch: ChainScratch::default(),
            stats: ControllerStats::default(),
            spine: spine::SpineState::default(),
            centres: rig.legs.iter().map(|l| l.nominal).collect(),
            poses: Vec::new(),
            crawl: undulation::CrawlState::default(),
            lift: undulation::LiftTarget::default(),
            crawl_root: rig.standing.root,
        }
    }

    /// Starts an episode: the standing pose at the origin facing +x, standing still for a moment.
    pub fn reset<R: rand::Rng + ?Sized>(&mut self, rng: &mut R) {
        let rig = self.rig;
        self.position = Vector2::zeros();
        self.yaw = 0.0;
        self.q = rig.standing.q.clone();
        self.posture = [rig.standing.root.translation.vector.z, 0.0, 0.0];
        self.bob = [0.0; 3];
        self.posture_hold = 0.0;
        self.commands.reset(uniform(rng, 0.3, 1.0));
        self.legs = rig
            .legs
            .iter()
            .map(|l| LegState::standing(Point3::new(l.nominal.x, l.nominal.y, l.sole)))
            .collect();
        self.force_lift = vec![false; rig.legs.len()];
        self.selector = GaitSelector { current: 0 };
        self.variant = usize::from(rng.random::<f32>() < self.cfg.legs.bound_probability);
        self.clock = 0.0;
        self.frequency = dynamic_similarity::stride_frequency(0.0, rig.hip_height.max(1e-3));
        self.stepping = false;
        self.reach = rig
            .reach
            .iter()
            .map(|g| {
                let q = g.dofs.iter().map(|&d| self.q[d]).collect();
                ReachState::at(q, uniform(rng, 0.0, 1.0))
            })
            .collect();
        self.next_posture(rng);
        self.centres = rig.legs.iter().map(|l| l.nominal).collect();
        if !rig.spine.is_empty() {
            self.spine.reset(self.cfg.posture.hold_seconds, rng);
        }
        if let Some(c) = &rig.crawl {
            self.crawl = undulation::CrawlState::default();
            self.lift = undulation::LiftTarget::default();
            self.crawl_root = c.root_in_heading(self.tree, &self.q, rig.standing.root.translation.vector.z);
        }
        self.solve_legs();
    }

    /// The rig this controller drives.
    pub fn rig(&self) -> &Rig {
        self.rig
    }

    /// Root pose this frame.
    pub fn root(&self) -> Isometry3<f32> {
        if self.rig.mode == BaseMode::Crawling {
            let heading = Isometry3::from_parts(
                Translation3::new(self.position.x, self.position.y, 0.0),
                UnitQuaternion::from_euler_angles(0.0, 0.0, self.yaw),
            );
            return heading * self.crawl_root;
        }
        let [h, pitch, roll] = self.posture;
        let (dh, dp) = self.bob_offsets();
        let r = &self.rig;
        // The bob stays within the calibrated posture range (the legs are checked over it).
        let lo = r.height_range[0].min(h);
        let hi = r.height_range[1].max(h);
        let h = (h + dh).clamp(lo, hi);
        let pitch = (pitch + dp).clamp(-r.max_tilt[0].max(pitch.abs()), r.max_tilt[0].max(pitch.abs()));
        Isometry3::from_parts(
            Translation3::new(self.position.x, self.position.y, h),
            UnitQuaternion::from_euler_angles(roll, pitch, self.yaw),
        )
    }

    /// Joint vector this frame.
    pub fn q(&self) -> &[f32] {
        &self.q
    }

    /// Pose this frame.
    pub fn pose(&self) -> CharacterPose {
        CharacterPose {
            root: self.root(),
            q: self.q.clone(),
        }
    }

    /// The command target this frame (heading frame; zero for a fixed base, forward and turning only
    /// for a crawling one).
    pub fn command(&self) -> Command {
        match self.rig.mode {
            BaseMode::Fixed => Command::default(),
            BaseMode::Crawling => self.crawlable(self.commands.target()),
            _ => self.commands.target(),
        }
    }

    /// The filtered command the base follows this frame.
    pub fn followed(&self) -> Command {
        match self.rig.mode {
            BaseMode::Fixed => Command::default(),
            BaseMode::Crawling => self.crawlable(self.commands.current()),
            _ => self.commands.current(),
        }
    }

    /// What a crawling body follows of command `c`: forward no faster than its wave carries it, never
    /// backwards or sideways.
    fn crawlable(&self, c: Command) -> Command {
        let top = self.rig.crawl.as_ref().map_or(0.0, |u| u.max_speed);
        Command { vx: c.vx.clamp(0.0, top), vy: 0.0, wz: c.wz }
    }

    /// Whether each foot is in stance, in [`crate::morphology::Morphology::feet`] order.
    pub fn contacts(&self) -> impl Iterator<Item = bool> + '_ {
        self.legs.iter().map(LegState::in_stance)
    }

    /// The legs' states.
    pub fn legs(&self) -> &[LegState] {
        &self.legs
    }

    /// The current gait, if the character has legs.
    pub fn gait(&self) -> Option<&Gait> {
        self.rig.gaits.get(self.selector.current)
    }

    /// Counters since construction.
    pub fn stats(&self) -> &ControllerStats {
        &self.stats
    }

    /// Replaces the random command by `target` (character m/s, rad/s) for `hold` seconds.
    pub fn set_command(&mut self, target: Command, hold: f32) {
        self.commands.set_target(target, hold);
    }

    /// Advances one frame.
    pub fn step<R: rand::Rng + ?Sized>(&mut self, rng: &mut R) {
        let dt = self.dt;
        self.stats.frames += 1;
        let c = match self.rig.mode {
            BaseMode::Fixed => Command::default(),
            BaseMode::Crawling => {
                let c = self.commands.step(dt, rng);
                self.crawlable(c)
            }
            _ => self.commands.step(dt, rng),
        };
        // Base: integrate the followed twist (midpoint heading).
        let v = Vector2::new(c.vx, c.vy);
        self.position += legs::rot(self.yaw + 0.5 * c.wz * dt) * v * dt;
        self.yaw += c.wz * dt;
        if let Some(u) = &self.rig.crawl {
            let p = &self.cfg.posture;
            self.lift.step(&mut self.crawl.lift, u.max_lift, dt, p.hold_seconds, p.time_constant, rng);
            self.crawl.step(u, c.vx, c.wz, dt, &mut self.q);
            self.crawl_root = u.root_in_heading(self.tree, &self.q, self.rig.standing.root.translation.vector.z);
        }
        if self.rig.mode == BaseMode::Legged {
            self.step_posture(rng);
            if !self.rig.spine.is_empty() {
                let p = &self.cfg.posture;
                self.spine.step_posture(dt, p.hold_seconds, p.time_constant, rng);
            }
            let t = self.commands.target();
            self.step_legs(v, c.wz, Vector2::new(t.vx, t.vy), t.wz);
        }
        if self.rig.mode == BaseMode::Wheeled {
            wheels::roll(&self.rig.wheels, &mut self.q, v, c.wz, dt);
        }
        let ev = reach::step_reach(
            self.tree,
            self.rig,
            &self.cfg.reach,
            &mut self.reach,
            &mut self.q,
            dt,
            rng,
        );
        self.stats.reach_targets += ev.targets;
        self.stats.reach_fallbacks += ev.fallbacks;
    }

    fn next_posture<R: rand::Rng + ?Sized>(&mut self, rng: &mut R) {
        let rig = self.rig;
        let p = &self.cfg.posture;
        self.posture_target = [
            uniform(rng, rig.height_range[0], rig.height_range[1]),
            uniform(rng, -rig.max_tilt[0], rig.max_tilt[0]),
            uniform(rng, -rig.max_tilt[1], rig.max_tilt[1]),
        ];
        self.posture_hold = uniform(rng, p.hold_seconds[0], p.hold_seconds[1]);
    }

    fn step_posture<R: rand::Rng + ?Sized>(&mut self, rng: &mut R) {
        self.posture_hold -= self.dt;
        if self.posture_hold <= 0.0 {
            self.next_posture(rng);
        }
        let a = 1.0 - (-self.dt / self.cfg.posture.time_constant.max(1e-3)).exp();
        for (x, t) in self.posture.iter_mut().zip(self.posture_target) {
            *x += (t - *x) * a;
        }
    }

    /// Height and pitch offsets of the gait bob at the current clock phase: two dips per cycle in
    /// two-beat gaits (each stance of a diagonal pair), one rise-and-fall with a nod in bound/gallop.
    fn bob_offsets(&self) -> (f32, f32) {
        let tau = std::f32::consts::TAU;
        let [two_beat, leap, nod] = self.bob;
        let phi = self.clock;
        (
            -two_beat * (2.0 * tau * phi).cos() + leap * (tau * phi).cos(),
            nod * (tau * phi).sin(),
        )
    }

    fn step_legs(&mut self, v: Vector2<f32>, wz: f32, v_target: Vector2<f32>, wz_target: f32) {
        let rig = self.rig;
        if rig.legs.is_empty() {
            return;
        }
        let base = BaseMotion {
            position: self.position,
            yaw: self.yaw,
            v,
            wz,
            v_target,
            wz_target,
            tau: self.cfg.commands.time_constant,
        };
        // Step for where the command is going a little ahead, so that accelerating legs keep up.
        let (v_ahead, wz_ahead) = base.velocity_at(LOOKAHEAD);
        let foot_speed = (v.norm() + wz.abs() * rig.foot_radius).max(v_ahead.norm() + wz_ahead.abs() * rig.foot_radius);
        let speed = foot_speed / rig.speed_scale.max(1e-6);
        let h = rig.hip_height;
        let fr = dynamic_similarity::froude(foot_speed, h);
        // The shortest swing goes by the slower of the two speeds, so that a decelerating character
        // already takes walking swings.
        let slower = (v.norm() + wz.abs() * rig.foot_radius).min(v_ahead.norm() + wz_ahead.abs() * rig.foot_radius);
        let fr_slower = dynamic_similarity::froude(slower, h);
        let fr_walk = if self.cfg.legs.walks_by_body_speed {
            dynamic_similarity::froude(v.norm().min(v_ahead.norm()), h)
        } else {
            fr_slower
        };
        let drift = self
            .legs
            .iter()
            .zip(&rig.legs)
            .zip(&self.centres)
            .map(|((s, l), c)| l.reach_fraction(base.to_local(&s.foot) - c))
            .fold(0.0, f32::max);
        let swinging = self.legs.iter().any(|l| !l.in_stance());
        self.stepping = if self.stepping {
            speed > 0.05 || drift > 0.15 || swinging
        } else {
            speed > 0.08 || drift > 0.3
        };
        if self.selector.update(&rig.gaits, fr, self.variant) {
            self.stats.gait_changes += 1;
        }
        let gait = &rig.gaits[self.selector.current];
        let dir = if v_ahead.norm() > v.norm() { v_ahead } else { v };
        let r_min = rig
            .legs
            .iter()
            .map(|l| l.radius_toward(dir))
            .fold(f32::INFINITY, f32::min);
        // With a cadence limit, a stance that would overrun the step radius at that multiple of the
        // law's cadence spends less of the stride on the ground, within the gait's duty range.
        let duty = match self.cfg.legs.cadence_limit {
            Some(k) => gait.duty_fitting(
                fr,
                dynamic_similarity::stride_length(foot_speed, h) / k,
                2.0 * legs::STANCE_USE * r_min,
            ),
            None => gait.duty_at(fr),
        };
        // Alexander's stride frequency, raised where the stance would overrun the step radius, capped
        // by the shortest swing.
        let needed = foot_speed * duty / (2.0 * legs::STANCE_USE * r_min);
        let cap = rig::frequency_cap(&self.cfg, duty, fr_slower, 1.0 / self.dt);
        let target = dynamic_similarity::stride_frequency(foot_speed, h).max(needed).min(cap);
        let a = 1.0 - (-self.dt / self.cfg.legs.frequency_time_constant.max(1e-3)).exp();
        self.frequency += (target - self.frequency) * a;
        if self.stepping {
            self.clock = (self.clock + self.frequency * self.dt).rem_euclid(1.0);
        }
        // Bob amplitudes grow with speed while stepping and fade otherwise.
        let k = if self.stepping { (speed / 2.0).min(1.0) } else { 0.0 };
        let l = rig.leg_length;
        let target = match gait.kind {
            GaitKind::Alternating => [BOB * l * k, 0.0, 0.0],
            GaitKind::Bound | GaitKind::Gallop => [0.0, BOB * l * k, 0.5 * rig.max_tilt[0] * k],
            _ => [0.0; 3],
        };
        let b = 1.0 - (-self.dt / 0.3f32).exp();
        for (x, t) in self.bob.iter_mut().zip(target) {
            *x += (t - *x) * b;
        }
        if !rig.spine.is_empty() {
            self.spine.apply(&rig.spine, wz, rig.spine_turn_rate, self.clock, gait.kind, k, self.dt, &mut self.q);
            self.move_centres();
        }
        let params = StepParams {
            stepping: self.stepping,
            clock: self.clock,
            frequency: self.frequency,
            duty,
            lift: legs::swing_lift(fr),
            min_swing: rig::min_swing_frames(&self.cfg, fr_walk) as f32 * self.dt,
            stride_walk: self.cfg.legs.walks_by_body_speed.then(|| StrideWalk {
                below: dynamic_similarity::speed_at_froude(dynamic_similarity::WALK_TROT_FROUDE, h),
                min_swing: rig::min_swing_frames(&self.cfg, 0.0) as f32 * self.dt,
            }),
            clearance: rig.clearance,
        };
        for (i, (state, leg)) in self.legs.iter_mut().zip(&rig.legs).enumerate() {
            let force = std::mem::take(&mut self.force_lift[i]);
            if state.step(leg, self.centres[i], gait.offsets[i], &base, &params, self.dt, force) {
                self.stats.early_liftoffs += 1;
            }
        }
        self.solve_legs();
    }

    /// Moves the step-region centres of the legs whose hips the spine carries by as much as their hips
    /// moved from the nominal stance (heading frame, taken as the root's).
    fn move_centres(&mut self) {
        for (c, leg) in self.centres.iter_mut().zip(&self.rig.legs) {
            if !leg.on_spine {
                continue;
            }
            let Some(first) = leg.chain.first_moving() else { continue };
            leg.chain.poses_into(self.tree, &self.q, &mut self.poses);
            let hip = self.poses[first].translation.vector;
            *c = leg.nominal + (hip.xy() - leg.hip.xy());
        }
    }

    /// IK for every leg to its foot target; stance feet IK cannot hold lift off next frame.
    fn solve_legs(&mut self) {
        let root = self.root();
        for (i, (state, leg)) in self.legs.iter().zip(&self.rig.legs).enumerate() {
            let target = root.inverse_transform_point(&state.foot);
            let r = solve_leg(self.tree, leg, &self.rig.nominal_q, &mut self.q, &target, &mut self.scratch);
            if state.in_stance() {
                self.stats.max_stance_error = self.stats.max_stance_error.max(r.error);
                if r.error > STANCE_SLIP {
                    self.force_lift[i] = true;
                }
            }
        }
    }
}
