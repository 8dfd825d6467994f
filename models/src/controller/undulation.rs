//! Crawling for legless creatures: lateral undulation along the body's axis ([`Morphology::body_axis`]).
//!
//! The bones of the axis that bend sideways (a DoF about the vertical, classed as
//! [`super::spine::classify`] does), head end first and the head itself left to reaching, are the
//! *segments* `i = 0 … n−1`. Each bends by `u_i = A·sin(φ − k·i) + b` (a fraction of its range on that
//! side, [`super::spine::SpineJoint::value`]): a wave of [`WAVES`] wavelengths along the body
//! (`k = 2π·WAVES/n`) that travels from the head to the tail as the phase `φ` advances, plus a bias `b`
//! that curves the body into a turn ([`super::spine::TURN_BEND`] × yaw rate / [`super::spine::TURN_RATE`]).
//! The bones' vertical bends (pitch) *lift* the body: all by the same slow random fraction of their
//! range, in `[0, max_lift]`, drawn and filtered as a legged body's posture ([`super::PostureConfig`]),
//! positive raising the parts beyond each joint. `max_lift` (at most [`LIFT`]) is calibrated so that no
//! part of the body dips below where it lies at rest over the wave's whole cycle and the turns; bends
//! about vertical axes move nothing up or down, so a body lying on the ground stays on it. Other DoFs
//! (roll) stay at rest.
//!
//! The base follows the commanded forward speed (never backwards; sideways commands are not followed)
//! and yaw rate. The wave is what carries it: the phase advances at `ω = v·k / (SLIP·s)` (`s` the mean
//! segment length), so that the wave runs back along the body at `v / SLIP`, as a snake's body slips a
//! little against the ground. The amplitude `A` ([`AMPLITUDE`]) grows as the body gets going and fades
//! when it stops. The top speed is where the wave would pass [`MAX_FREQUENCY`].
//!
//! The root link is placed so that the body's axis points (tail to head end) along the heading and
//! its centroid (of the axis bones' origins) stays where it is at rest in the heading frame: the body
//! swings about the path rather than the path about the root.

use nalgebra::{Isometry3, Point2, Translation3, UnitQuaternion, Vector2};

use super::calibrate::fk_root;
use super::spine::{Bend, SpineJoint, TURN_BEND, TURN_RATE, classify};
use crate::kinematics::KinematicTree;
use crate::morphology::Morphology;

/// Wavelengths along the body.
pub const WAVES: f32 = 1.0;
/// Wave amplitude while crawling (fraction of each segment's range).
pub const AMPLITUDE: f32 = 0.6;
/// Forward speed over the wave's speed back along the body.
pub const SLIP: f32 = 0.7;
/// Highest wave frequency (Hz): sets the top speed.
pub const MAX_FREQUENCY: f32 = 1.2;
/// Largest lift of the body (fraction of each vertical DoF's range).
pub const LIFT: f32 = 0.3;
/// Fewest segments that make a wave.
pub const MIN_SEGMENTS: usize = 4;
/// Time constant of the amplitude (s).
const AMPLITUDE_TIME_CONSTANT: f32 = 0.5;

/// A legless creature's crawl, derived from its body's axis.
#[derive(Clone, Debug)]
pub struct Undulation {
    /// Segments' lateral DoFs, head end first.
    pub segments: Vec<SpineJoint>,
    /// Vertical DoFs of the axis bones, which lift the body.
    pub lifts: Vec<SpineJoint>,
    /// The largest lift that keeps the body off the ground (fraction of the range, at most [`LIFT`]).
    pub max_lift: f32,
    /// Other DoFs of the axis bones, held at rest.
    pub held: Vec<usize>,
    /// Phase lag between neighbouring segments (rad).
    pub k: f32,
    /// Mean segment length (m).
    pub segment_length: f32,
    /// Links whose origins trace the axis (head end first) for placing the root.
    pub points: Vec<usize>,
    /// Top forward speed (m/s).
    pub max_speed: f32,
    /// Centroid of the axis at rest (root frame, x y).
    centroid: Vector2<f32>,
    /// Direction of the axis (tail end to head end) at rest, as an angle (rad).
    heading: f32,
}

impl Undulation {
    /// The crawl of a creature with body axis [`Morphology::body_axis`] at `nominal_q`, or what is
    /// missing.
    pub fn new(tree: &KinematicTree, morph: &Morphology, nominal_q: &[f32]) -> Result<Undulation, String> {
        let mut segments = Vec::new();
        let mut lifts = Vec::new();
        let mut held = Vec::new();
        let mut points = Vec::new();
        for dofs in &morph.body_axis {
            let Some(&last) = dofs.last() else { continue };
            let link = tree.dof_link(last);
            points.push(link);
            if Some(link) == morph.head {
                continue; // the head looks around (reaching)
            }
            let joints = classify(tree, dofs, nominal_q);
            let lateral = joints.iter().find(|j| j.bend == Bend::Lateral).cloned();
            let vertical: Vec<SpineJoint> = joints.into_iter().filter(|j| j.bend == Bend::Vertical).collect();
            held.extend(dofs.iter().copied().filter(|&d| {
                lateral.as_ref().is_none_or(|j| j.dof != d) && vertical.iter().all(|j| j.dof != d)
            }));
            segments.extend(lateral);
            lifts.extend(vertical);
        }
        if segments.len() < MIN_SEGMENTS {
            return Err(format!(
                "no legs, and {} bone(s) along its body (head to tail tip) that bend sideways: a legless creature \
                 crawls by bending at least {MIN_SEGMENTS}; name its feet in a profile, or give its body bones DoFs",
                segments.len()
            ));
        }
        let poses = fk_root(tree, nominal_q);
        let xy = |l: usize| poses[l].translation.vector.xy();
        let length: f32 = points.windows(2).map(|w| (xy(w[0]) - xy(w[1])).norm()).sum();
        let n = segments.len() as f32;
        let k = std::f32::consts::TAU * WAVES / n;
        let segment_length = (length / n).max(1e-3);
        let (centroid, heading) = axis_frame(&points.iter().map(|&l| xy(l)).collect::<Vec<_>>());
        let mut u = Undulation {
            max_speed: MAX_FREQUENCY * std::f32::consts::TAU * SLIP * segment_length / k,
            segments,
            lifts,
            max_lift: 0.0,
            held,
            k,
            segment_length,
            points,
            centroid,
            heading,
        };
        u.max_lift = u.safe_lift(tree, nominal_q, length);
        Ok(u)
    }

    /// The largest lift (of [`LIFT`] and fractions of it) at which, over 8 phases of the wave at full
    /// amplitude, straight and bent into either turn, nothing of the body lies lower than at rest (by
    /// 0.1 % of the axis' length `length`).
    fn safe_lift(&self, tree: &KinematicTree, nominal_q: &[f32], length: f32) -> f32 {
        if self.lifts.is_empty() {
            return 0.0;
        }
        let lowest = |q: &[f32]| tree.lowest_z(&fk_root(tree, q));
        let floor = lowest(nominal_q).min(0.0) - 1e-3 * length;
        let mut q = nominal_q.to_vec();
        for lift in [1.0, 0.75, 0.5, 0.35, 0.25, 0.15, 0.1, 0.05].map(|f| f * LIFT) {
            let state = CrawlState { phase: 0.0, amplitude: AMPLITUDE, lift };
            let clear = (0..8).all(|p| {
                [-TURN_RATE, 0.0, TURN_RATE].iter().all(|&wz| {
                    let s = CrawlState { phase: p as f32 * std::f32::consts::FRAC_PI_4, ..state.clone() };
                    s.bend(self, wz, &mut q);
                    lowest(&q) >= floor
                })
            });
            if clear {
                return lift;
            }
        }
        0.0
    }

    /// Wave phase rate (rad/s) at forward speed `v`.
    pub fn phase_rate(&self, v: f32) -> f32 {
        v * self.k / (SLIP * self.segment_length)
    }

    /// Root pose in the heading frame for joint vector `q` at root height `h` (see the module docs).
    pub fn root_in_heading(&self, tree: &KinematicTree, q: &[f32], h: f32) -> Isometry3<f32> {
        let poses = fk_root(tree, q);
        let pts: Vec<Vector2<f32>> = self.points.iter().map(|&l| poses[l].translation.vector.xy()).collect();
        let (c, a) = axis_frame(&pts);
        let turn = self.heading - a;
        let r = nalgebra::Rotation2::new(turn);
        let t = self.centroid - r * c;
        Isometry3::from_parts(Translation3::new(t.x, t.y, h), UnitQuaternion::from_euler_angles(0.0, 0.0, turn))
    }
}

/// Centroid and direction (tail end to head end, rad) of axis points given head end first.
fn axis_frame(points: &[Vector2<f32>]) -> (Vector2<f32>, f32) {
    let c = points.iter().sum::<Vector2<f32>>() / points.len().max(1) as f32;
    let (Some(front), Some(back)) = (points.first(), points.last()) else {
        return (c, 0.0);
    };
    // The mean direction of the two halves' centroids is steadier than the end points alone.
    let half = points.len() / 2;
    let mean = |p: &[Vector2<f32>]| Point2::from(p.iter().sum::<Vector2<f32>>() / p.len().max(1) as f32);
    let d = if half >= 1 && points.len() - half >= 1 {
        mean(&points[..half]) - mean(&points[points.len() - half..])
    } else {
        front - back
    };
    (c, d.y.atan2(d.x))
}

/// The crawl's state over an episode.
#[derive(Clone, Debug, Default)]
pub struct CrawlState {
    /// Wave phase (rad).
    pub phase: f32,
    /// Current amplitude (fraction of the range).
    pub amplitude: f32,
    /// Current lift (fraction of the range).
    pub lift: f32,
}

/// The random lift's target and how long it is held yet (s).
#[derive(Clone, Debug, Default)]
pub struct LiftTarget {
    target: f32,
    hold: f32,
}

impl LiftTarget {
    /// Advances by `dt`: a new target in `[0, max_lift]` held for `hold` seconds when the last one is
    /// over; `lift` follows with time constant `tau`.
    pub fn step<R: rand::Rng + ?Sized>(&mut self, lift: &mut f32, max_lift: f32, dt: f32, hold: [f32; 2], tau: f32, rng: &mut R) {
        self.hold -= dt;
        if self.hold <= 0.0 {
            self.target = super::uniform(rng, 0.0, max_lift);
            self.hold = super::uniform(rng, hold[0], hold[1]);
        }
        *lift += (self.target - *lift) * (1.0 - (-dt / tau.max(1e-3)).exp());
    }
}

impl CrawlState {
    /// Advances by `dt` at forward speed `v` and yaw rate `wz`, and bends the body in `q`.
    pub fn step(&mut self, u: &Undulation, v: f32, wz: f32, dt: f32, q: &mut [f32]) {
        self.phase = (self.phase + u.phase_rate(v) * dt).rem_euclid(std::f32::consts::TAU);
        let going = (v / (0.2 * u.max_speed).max(1e-6)).min(1.0);
        let a = 1.0 - (-dt / AMPLITUDE_TIME_CONSTANT).exp();
        self.amplitude += (AMPLITUDE * going - self.amplitude) * a;
        self.bend(u, wz, q);
    }

    /// Bends the segments in `q` for the current phase and amplitude and yaw rate `wz`.
    pub fn bend(&self, u: &Undulation, wz: f32, q: &mut [f32]) {
        let bias = TURN_BEND * (wz / TURN_RATE).clamp(-1.0, 1.0);
        let amplitude = self.amplitude.min(1.0 - bias.abs());
        for (i, j) in u.segments.iter().enumerate() {
            q[j.dof] = j.value(amplitude * (self.phase - u.k * i as f32).sin() + bias);
        }
        for j in &u.lifts {
            q[j.dof] = j.value(self.lift.min(u.max_lift));
        }
    }
}
