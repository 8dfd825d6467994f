//! Crawling for legless creatures: lateral undulation along the body's axis ([`Morphology::body_axis`]).
//!
//! The bones of the axis that bend sideways (a DoF about the vertical, classed as
//! [`super::spine::classify`] does), head end first and the head itself left to reaching, are the
//! *segments* `i = 0 … n−1`. Each bends by `u_i = A·sin(φ − k·i) + b` (a fraction of its range on that
//! side, [`super::spine::SpineJoint::value`]): a wave of [`WAVES`] wavelengths along the body
//! (`k = 2π·WAVES/n`) that travels from the head to the tail as the phase `φ` advances, plus a bias `b`
//! that curves the body into a turn ([`super::spine::TURN_BEND`] × yaw rate / [`super::spine::TURN_RATE`]).
//! The other DoFs of the axis bones (pitch) stay at rest, so the body keeps its height: bends about
//! vertical axes move nothing up or down, and a body lying on the ground stays on it.
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
/// Fewest segments that make a wave.
pub const MIN_SEGMENTS: usize = 4;
/// Time constant of the amplitude (s).
const AMPLITUDE_TIME_CONSTANT: f32 = 0.5;

/// A legless creature's crawl, derived from its body's axis.
#[derive(Clone, Debug)]
pub struct Undulation {
    /// Segments' lateral DoFs, head end first.
    pub segments: Vec<SpineJoint>,
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
        let mut held = Vec::new();
        let mut points = Vec::new();
        for dofs in &morph.body_axis {
            let Some(&last) = dofs.last() else { continue };
            let link = tree.dof_link(last);
            points.push(link);
            if Some(link) == morph.head {
                continue; // the head looks around (reaching)
            }
            let lateral = classify(tree, dofs, nominal_q)
                .into_iter()
                .find(|j| j.bend == Bend::Lateral);
            held.extend(dofs.iter().copied().filter(|&d| lateral.as_ref().is_none_or(|j| j.dof != d)));
            segments.extend(lateral);
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
        Ok(Undulation {
            max_speed: MAX_FREQUENCY * std::f32::consts::TAU * SLIP * segment_length / k,
            segments,
            held,
            k,
            segment_length,
            points,
            centroid,
            heading,
        })
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
}

impl CrawlState {
    /// Advances by `dt` at forward speed `v` and yaw rate `wz`, and bends the segments in `q`.
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
    }
}
