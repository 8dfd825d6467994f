//! Spine motion of legged creatures: the DoFs of [`Morphology::spine`] (the trunk, the neck) bend as a
//! body, smoothly and coupled to the gait, while leg IK holds them.
//!
//! Each spine DoF is classed at the nominal pose by its axis in the root frame: about the vertical it
//! bends the body **laterally**, about the lateral axis **vertically** (flexion and extension); a roll
//! stays at rest. Its sign is chosen so that a positive bend moves the bones beyond it (the centroid of
//! their origins and shapes) to the left, or up. A bend `u` is a fraction of the joint's range on that
//! side of its rest value, so every joint stays within its limits; joints in series bend alike, which
//! curves the body evenly. The bend is the sum of (constants below):
//! - **into the turn**: [`TURN_BEND`] × the followed yaw rate / the full-bend rate (clamped): a body
//!   turning left curves left, its front and rear ends toward the centre of the turn. The full-bend
//!   rate is [`TURN_RATE`], or the fastest the legs can turn on the spot if slower ([`full_turn_rate`]),
//!   so that a character whose legs turn slowly still bends its whole range;
//! - **with the stride**: a lateral sway of [`SWAY`] in the walks and trots and a flexion of [`FLEX`] in
//!   the bound and gallop (a flexing back), once per stride at the gait clock's phase, both growing
//!   with speed as the body's bob does and fading when the legs stop;
//! - **posture**: a slow random offset within ±[`POSTURE`] (lateral, vertical), drawn and filtered as
//!   the body's height and tilt are ([`super::PostureConfig`]), so that the prior also sees a spine held
//!   bent.
//!
//! A bent spine moves the hips that hang from it: their legs step around where the hips now are
//! ([`super::legs::LegState::step`]'s centre), not where they stood at rest, and the joints that carry
//! legs bend only so far that the hips stay within reach of planted feet ([`fit_legs`]). Reaching limbs
//! keep clear of the body wherever the spine bends it ([`swept`]).

use nalgebra::Point3;

use super::calibrate::fk_root;
use super::collide::Proxies;
use super::gait::GaitKind;
use super::rig::{Leg, Obstacle, finite_limits, subtree};
use crate::kinematics::KinematicTree;
use crate::morphology::Morphology;

/// Lateral bend (fraction of the range) at the full-bend yaw rate ([`full_turn_rate`]) or more.
pub const TURN_BEND: f32 = 0.6;
/// Yaw rate at which the bend into a turn is full (rad/s): the commands' largest (±1 rad/s).
pub const TURN_RATE: f32 = 1.0;
/// Lateral sway per stride at full speed in the walks and trots (fraction of the range).
pub const SWAY: f32 = 0.15;
/// Flexion per stride at full speed in the bound and the gallop (fraction of the range).
pub const FLEX: f32 = 0.35;
/// Largest random posture offset, lateral and vertical (fraction of the range).
pub const POSTURE: [f32; 2] = [0.15, 0.3];
/// The yaw rate at which the spine bends fully into a turn (rad/s): [`TURN_RATE`], or the fastest the
/// legs turn on the spot if slower — the commands' limit `|ω|·foot_radius ≤ side` (the sideways speed
/// of the cadence ellipse, else the top speed).
pub fn full_turn_rate(max_speed: f32, cadence_speeds: Option<[f32; 2]>, foot_radius: f32) -> f32 {
    let side = cadence_speeds.map_or(max_speed, |[_, side]| side.min(max_speed));
    if foot_radius > 1e-6 && side.is_finite() {
        (side / foot_radius).clamp(1e-3, TURN_RATE)
    } else {
        TURN_RATE
    }
}

/// Farthest a bent spine moves a hip sideways, as a fraction of its leg's step radius across the body.
pub const HIP_SHIFT: f32 = 1.5;
/// Farthest a bent spine moves a hip up or down, as a fraction of its leg's length.
pub const HIP_LIFT: f32 = 0.08;

/// The largest lateral and vertical bends the spine makes (fractions of the range).
pub const MAX_BEND: [f32; 2] = [TURN_BEND + SWAY + POSTURE[0], FLEX + POSTURE[1]];
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
    /// The fraction of its range a full bend takes (1, less where the joint carries legs:
    /// [`fit_legs`]).
    pub gain: f32,
}

impl SpineJoint {
    /// The joint value for bend `u` (a fraction in `[-1, 1]` of the range on the bend's side).
    pub fn value(&self, u: f32) -> f32 {
        let v = self.sign * self.gain * u.clamp(-1.0, 1.0);
        let q = if v >= 0.0 {
            self.rest + v * (self.upper - self.rest)
        } else {
            self.rest + v * (self.rest - self.lower)
        };
        q.clamp(self.lower, self.upper)
    }

    /// The bend `u` of joint value `q` (inverse of [`SpineJoint::value`] within the limits).
    pub fn bend_of(&self, q: f32) -> f32 {
        self.fraction_of(q) / self.gain.max(1e-9)
    }

    /// The fraction of the range on its side that joint value `q` takes (signed as the bend).
    pub fn fraction_of(&self, q: f32) -> f32 {
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
        // The bones beyond: their origins and the centres of their shapes (a tail's last bone has
        // only its own shape beyond its joint).
        let points: Vec<nalgebra::Vector3<f32>> = subtree(tree, l)
            .into_iter()
            .flat_map(|x| {
                let pose = poses[x];
                std::iter::once(pose.translation.vector)
                    .chain(tree.links[x].collisions.iter().map(move |g| (pose * g.origin).translation.vector))
            })
            .collect();
        let centroid = points.iter().sum::<nalgebra::Vector3<f32>>() / points.len().max(1) as f32;
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
            gain: 1.0,
        });
    }
    out
}

/// The spine's DoFs of a legged character: [`Morphology::spine`] classed at the nominal stance, their
/// bends limited for the legs they carry ([`fit_legs`]).
pub fn joints(tree: &KinematicTree, morph: &Morphology, legs: &[Leg], nominal_q: &[f32]) -> Vec<SpineJoint> {
    let mut joints = classify(tree, &morph.spine, nominal_q);
    fit_legs(tree, &mut joints, legs, nominal_q);
    joints
}

/// Lowers the gain of the joints that carry legs so that, bent to [`MAX_BEND`] together, they move no
/// hip more than [`HIP_SHIFT`] of its step region's radius sideways or [`HIP_LIFT`] of its leg's length
/// up or down: the step regions follow the hips, but a stance foot stays where it is while the body
/// bends above it, and the legs were calibrated for the body's own height range.
pub fn fit_legs(tree: &KinematicTree, joints: &mut [SpineJoint], legs: &[Leg], nominal_q: &[f32]) {
    let hips: Vec<(usize, &Leg)> = legs
        .iter()
        .filter(|l| l.on_spine)
        .filter_map(|l| l.chain.first_moving().map(|f| (l.chain.links[f], l)))
        .collect();
    for (bend, k) in [(Bend::Lateral, 0), (Bend::Vertical, 1)] {
        let carrying: Vec<usize> = (0..joints.len())
            .filter(|&i| joints[i].bend == bend)
            .filter(|&i| {
                let l = tree.dof_link(joints[i].dof);
                hips.iter().any(|&(h, _)| tree.is_descendant(h, l))
            })
            .collect();
        if carrying.is_empty() {
            continue;
        }
        let mut worst = 0.0f32;
        for side in [1.0, -1.0] {
            let mut q = nominal_q.to_vec();
            for &i in &carrying {
                q[joints[i].dof] = joints[i].value(side * MAX_BEND[k]);
            }
            let poses = fk_root(tree, &q);
            for &(h, leg) in &hips {
                let d = poses[h].translation.vector - leg.hip;
                let ratio = match bend {
                    Bend::Lateral => d.xy().norm() / (HIP_SHIFT * leg.r_max).max(1e-6),
                    Bend::Vertical => d.z.abs() / (HIP_LIFT * leg.length).max(1e-6),
                };
                worst = worst.max(ratio);
            }
        }
        if worst > 1.0 {
            for &i in &carrying {
                joints[i].gain = 1.0 / worst;
            }
        }
    }
}

/// Boxes of the links the spine carries for which `keep` holds, with the spine bent to its extremes
/// ([`MAX_BEND`], lateral and vertical and both), in the frame of the root: obstacles that reaching
/// limbs keep clear of wherever the body bends.
pub fn swept(
    tree: &KinematicTree,
    proxies: &Proxies,
    joints: &[SpineJoint],
    nominal_q: &[f32],
    keep: impl Fn(usize) -> bool,
) -> Vec<Obstacle> {
    let mut carried = vec![false; tree.links.len()];
    for j in joints {
        for l in subtree(tree, tree.dof_link(j.dof)) {
            carried[l] = keep(l);
        }
    }
    let mut out = Vec::new();
    for (a, b) in [(1.0, 0.0), (-1.0, 0.0), (0.0, 1.0), (0.0, -1.0), (1.0, 1.0), (1.0, -1.0), (-1.0, 1.0), (-1.0, -1.0)] {
        let mut q = nominal_q.to_vec();
        for j in joints {
            let u = match j.bend {
                Bend::Lateral => a * MAX_BEND[0],
                Bend::Vertical => b * MAX_BEND[1],
            };
            q[j.dof] = j.value(u);
        }
        let poses = fk_root(tree, &q);
        for (l, pose) in poses.iter().enumerate().filter(|&(l, _)| carried[l]) {
            out.extend(proxies.world(l, pose).map(|obb| Obstacle { link: l, obb }));
        }
    }
    out
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

    /// Bends `joints` in `q` for this frame: yaw rate `wz` (rad/s) of which `turn_rate` bends fully
    /// ([`full_turn_rate`]), the gait clock's phase `clock`, the gait `kind` and `pace` in `[0, 1]` (how
    /// much the body bobs: 0 when the legs do not step).
    #[allow(clippy::too_many_arguments)]
    pub fn apply(
        &mut self,
        joints: &[SpineJoint],
        wz: f32,
        turn_rate: f32,
        clock: f32,
        kind: GaitKind,
        pace: f32,
        dt: f32,
        q: &mut [f32],
    ) {
        let target = match kind {
            GaitKind::Bound | GaitKind::Gallop => [0.0, FLEX * pace],
            _ => [SWAY * pace, 0.0],
        };
        let a = 1.0 - (-dt / STRIDE_TIME_CONSTANT).exp();
        for (x, t) in self.stride.iter_mut().zip(target) {
            *x += (t - *x) * a;
        }
        let wave = (std::f32::consts::TAU * clock).sin();
        let lateral = TURN_BEND * (wz / turn_rate).clamp(-1.0, 1.0) + self.stride[0] * wave + self.posture[0];
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
