//! Spine motion of legged creatures: the DoFs of [`Morphology::spine`] (the trunk, the neck) bend as a
//! body, smoothly and coupled to the gait, while leg IK holds them.
//!
//! Each spine DoF is classed at the nominal pose by its axis in the root frame: about the vertical it
//! bends the body **laterally**, about the lateral axis **vertically** (flexion and extension); a roll
//! stays at rest. Its sign is chosen so that a positive bend moves the bones beyond it (their centroid)
//! to the left, or up. A bend `u` is a fraction of the joint's range on that side of its rest value, so
//! every joint stays within its limits; joints in series bend alike, which curves the body evenly. The
//! bend is the sum of (constants below):
//! - **into the turn**: [`TURN_BEND`] × the followed yaw rate / [`TURN_RATE`] (clamped): a body turning
//!   left curves left, its front and rear ends toward the centre of the turn;
//! - **with the stride**: a lateral sway of [`SWAY`] in the walks and trots and a flexion of [`FLEX`] in
//!   the bound and gallop (a flexing back), once per stride at the gait clock's phase, both growing
//!   with speed as the body's bob does and fading when the legs stop;
//! - **posture**: a slow random offset within ±[`POSTURE`] (lateral, vertical), drawn and filtered as
//!   the body's height and tilt are ([`super::PostureConfig`]), so that the prior also sees a spine held
//!   bent.
//!
//! A bent spine moves the hips that hang from it: their legs step around where the hips now are
//! ([`super::legs::LegState::step`]'s centre), not where they stood at rest.

use nalgebra::Point3;

use super::calibrate::fk_root;
use super::gait::GaitKind;
use super::rig::{finite_limits, subtree};
use crate::kinematics::KinematicTree;
use crate::morphology::Morphology;

/// Lateral bend (fraction of the range) at a yaw rate of [`TURN_RATE`] or more.
pub const TURN_BEND: f32 = 0.6;
/// Yaw rate at which the bend into a turn is full (rad/s): the commands' largest (±1 rad/s).
pub const TURN_RATE: f32 = 1.0;
/// Lateral sway per stride at full speed in the walks and trots (fraction of the range).
pub const SWAY: f32 = 0.15;
/// Flexion per stride at full speed in the bound and the gallop (fraction of the range).
pub const FLEX: f32 = 0.35;
/// Largest random posture offset, lateral and vertical (fraction of the range).
pub const POSTURE: [f32; 2] = [0.15, 0.3];
/// Time constant with which the stride's sway and flexion follow the gait and speed (s), as the bob.
const STRIDE_TIME_CONSTANT: f32 = 0.3;

/// How a spine DoF bends the body.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Bend {
    /// About the vertical: sideways.
    Lateral,
    /// About the lateral axis: up and down.
    Vertical,
}

/// One spine DoF.
#[derive(Clone, Debug, PartialEq)]
pub struct SpineJoint {
    /// The DoF.
    pub dof: usize,
    /// What it bends.
    pub bend: Bend,
    /// +1 when a positive joint value bends the bones beyond it left (lateral) or up (vertical), else −1.
    pub sign: f32,
    /// Rest value (the nominal stance's).
    pub rest: f32,
    /// Limits.
    pub lower: f32,
    /// Limits.
    pub upper: f32,
}

impl SpineJoint {
    /// The joint value for bend `u` (a fraction in `[-1, 1]` of the range on the bend's side).
    pub fn value(&self, u: f32) -> f32 {
        let v = self.sign * u.clamp(-1.0, 1.0);
        let q = if v >= 0.0 {
            self.rest + v * (self.upper - self.rest)
        } else {
            self.rest + v * (self.rest - self.lower)
        };
        q.clamp(self.lower, self.upper)
    }

    /// The bend `u` of joint value `q` (inverse of [`SpineJoint::value`] within the limits).
    pub fn bend_of(&self, q: f32) -> f32 {
        let d = q - self.rest;
        let side = if d * self.sign >= 0.0 {
            if self.sign > 0.0 { self.upper - self.rest } else { self.rest - self.lower }
        } else if self.sign > 0.0 {
            self.rest - self.lower
        } else {
            self.upper - self.rest
        };
        self.sign * d / side.max(1e-9)
    }
}

/// Classes the DoFs `dofs` at the nominal joint vector `nominal_q` (see the module docs); DoFs that
/// turn about the body's long axis, or move nothing sideways or up, are left out.
pub fn classify(tree: &KinematicTree, dofs: &[usize], nominal_q: &[f32]) -> Vec<SpineJoint> {
    let poses = fk_root(tree, nominal_q);
    let mut out = Vec::new();
    for &d in dofs {
        let l = tree.dof_link(d);
        let j = tree.dof_joint(d);
        let Some(parent) = tree.links[l].parent else { continue };
        let frame = poses[parent] * j.origin;
        let axis = frame.rotation * j.axis.into_inner();
        let at = Point3::from(frame.translation.vector);
        let beyond = subtree(tree, l);
        let centroid = beyond
            .iter()
            .map(|&x| poses[x].translation.vector)
            .sum::<nalgebra::Vector3<f32>>()
            / beyond.len().max(1) as f32;
        let motion = axis.cross(&(Point3::from(centroid) - at));
        let (bend, effect) = if axis.z.abs() >= axis.x.abs().max(axis.y.abs()) {
            (Bend::Lateral, motion.y)
        } else if axis.y.abs() >= axis.x.abs() {
            (Bend::Vertical, motion.z)
        } else {
            continue;
        };
        if effect.abs() < 1e-6 {
            continue;
        }
        let (lower, upper) = finite_limits(tree, d, nominal_q[d]);
        out.push(SpineJoint {
            dof: d,
            bend,
            sign: effect.signum(),
            rest: nominal_q[d].clamp(lower, upper),
            lower,
            upper,
        });
    }
    out
}

/// The spine's DoFs of a legged character: [`Morphology::spine`] classed at the nominal stance.
pub fn joints(tree: &KinematicTree, morph: &Morphology, nominal_q: &[f32]) -> Vec<SpineJoint> {
    classify(tree, &morph.spine, nominal_q)
}

/// The spine's motion state over an episode.
#[derive(Clone, Debug, Default)]
pub struct SpineState {
    /// Current random posture offset (lateral, vertical).
    posture: [f32; 2],
    /// Its target.
    target: [f32; 2],
    /// Seconds the target is held yet.
    hold: f32,
    /// Filtered stride amplitudes (lateral sway, flexion).
    stride: [f32; 2],
}

impl SpineState {
    /// At rest, with a first posture target drawn from `rng`.
    pub fn reset<R: rand::Rng + ?Sized>(&mut self, hold: [f32; 2], rng: &mut R) {
        *self = SpineState::default();
        self.next_target(hold, rng);
    }

    fn next_target<R: rand::Rng + ?Sized>(&mut self, hold: [f32; 2], rng: &mut R) {
        self.target = [
            super::uniform(rng, -POSTURE[0], POSTURE[0]),
            super::uniform(rng, -POSTURE[1], POSTURE[1]),
        ];
        self.hold = super::uniform(rng, hold[0], hold[1]);
    }

    /// Advances the random posture by `dt` (targets held for `hold` seconds, filtered with time
    /// constant `tau`).
    pub fn step_posture<R: rand::Rng + ?Sized>(&mut self, dt: f32, hold: [f32; 2], tau: f32, rng: &mut R) {
        self.hold -= dt;
        if self.hold <= 0.0 {
            self.next_target(hold, rng);
        }
        let a = 1.0 - (-dt / tau.max(1e-3)).exp();
        for (x, t) in self.posture.iter_mut().zip(self.target) {
            *x += (t - *x) * a;
        }
    }

    /// Bends `joints` in `q` for this frame: yaw rate `wz` (rad/s), the gait clock's phase `clock`, the
    /// gait `kind` and `pace` in `[0, 1]` (how much the body bobs: 0 when the legs do not step).
    pub fn apply(&mut self, joints: &[SpineJoint], wz: f32, clock: f32, kind: GaitKind, pace: f32, dt: f32, q: &mut [f32]) {
        let target = match kind {
            GaitKind::Bound | GaitKind::Gallop => [0.0, FLEX * pace],
            _ => [SWAY * pace, 0.0],
        };
        let a = 1.0 - (-dt / STRIDE_TIME_CONSTANT).exp();
        for (x, t) in self.stride.iter_mut().zip(target) {
            *x += (t - *x) * a;
        }
        let wave = (std::f32::consts::TAU * clock).sin();
        let lateral = TURN_BEND * (wz / TURN_RATE).clamp(-1.0, 1.0) + self.stride[0] * wave + self.posture[0];
        let vertical = self.stride[1] * wave + self.posture[1];
        for j in joints {
            let u = match j.bend {
                Bend::Lateral => lateral,
                Bend::Vertical => vertical,
            };
            q[j.dof] = j.value(u);
        }
    }
}
