//! Joint limits: does a motion keep within the joint limits of the character's file (URDF `<limit>`:
//! position bounds and velocity)? A robot that is sent the motion must: a joint commanded faster than
//! its velocity limit is slowed or faulted by the robot's own controller, and the motion it executes is
//! no longer the one retargeted. None of UFR's detectors sees it: a lift that jumps at five times its
//! speed neither slides, collides nor goes into the ground.
//!
//! - **Velocity**: each DoF's velocity between consecutive frames of an episode (`|Δq|·fps`; for a
//!   continuous joint, such as a wheel, the step wrapped into [−π, π]) against its velocity limit.
//!   A frame is over when some DoF's velocity into it exceeds its limit by more than
//!   [`VELOCITY_TOLERANCE`] of the limit; the first frame of an episode has no velocity.
//! - **Position**: a frame is outside when some DoF lies more than [`POSITION_TOLERANCE`] beyond its
//!   lower or upper bound.
//!
//! Only DoFs with a finite limit count: a URDF joint without a velocity limit (or with 0, which the
//! format uses for "none"), a continuous joint's position and a rigged glTF creature's bones (whose
//! files carry no velocity) are not checked. [`joint_limits`] returns `None` for a character with no
//! limit to check.

use std::ops::Range;

use serde::{Deserialize, Serialize};

use crate::frame::wrap_pi;
use crate::kinematics::{CharacterPose, JointKind, KinematicTree};

/// Fraction of a velocity limit a velocity may exceed it by before the frame counts as over (float
/// rounding of a motion that moves at its limit exactly).
pub const VELOCITY_TOLERANCE: f32 = 0.01;

/// How far past a position bound a DoF may lie before the frame counts as outside (rad or m).
pub const POSITION_TOLERANCE: f32 = 1e-3;

/// How one DoF kept to its limits over a motion.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct JointLimitUse {
    /// The joint's name in the character's file.
    pub joint: String,
    /// Velocity limit (rad/s or m/s; `None`: not given).
    pub velocity_limit: Option<f32>,
    /// Largest velocity between two frames (rad/s or m/s).
    pub peak_velocity: f32,
    /// Frames into which the joint moved faster than its limit.
    pub frames_over: usize,
    /// Frames in which the joint lay outside its position limits.
    pub frames_outside: usize,
}

impl JointLimitUse {
    /// The peak velocity as a multiple of the limit (`None` without a limit).
    pub fn peak_ratio(&self) -> Option<f32> {
        self.velocity_limit.map(|l| self.peak_velocity / l)
    }
}

/// How a motion kept to its character's joint limits.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct JointLimitsReport {
    /// Frames evaluated.
    pub frames: usize,
    /// Share of the frames (0…1) into which some joint moved faster than its velocity limit.
    pub over_velocity: f32,
    /// Share of the frames (0…1) in which some joint lay outside its position limits.
    pub outside_position: f32,
    /// Every DoF with a finite limit, in DoF order.
    pub joints: Vec<JointLimitUse>,
}

impl JointLimitsReport {
    /// The joints that went over their velocity limit, the fastest (against its limit) first.
    pub fn over(&self) -> Vec<&JointLimitUse> {
        let mut v: Vec<&JointLimitUse> = self.joints.iter().filter(|j| j.frames_over > 0).collect();
        v.sort_by(|a, b| b.peak_ratio().unwrap_or(0.0).total_cmp(&a.peak_ratio().unwrap_or(0.0)));
        v
    }

    /// Whether some joint has a velocity limit (a robot's file gives them; a rigged creature's does not).
    pub fn has_velocity_limits(&self) -> bool {
        self.joints.iter().any(|j| j.velocity_limit.is_some())
    }

    /// The largest peak velocity against its limit over the joints (0 without velocity limits).
    pub fn worst_ratio(&self) -> f32 {
        self.joints.iter().filter_map(JointLimitUse::peak_ratio).fold(0.0, f32::max)
    }
}

impl std::fmt::Display for JointLimitsReport {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        if self.has_velocity_limits() {
            write!(f, "joint limits: {} of frames over a velocity limit, ", super::percent(self.over_velocity))?;
        } else {
            write!(f, "joint limits: no velocity limits given, ")?;
        }
        write!(f, "{} outside a position limit", super::percent(self.outside_position))?;
        for j in self.over() {
            write!(
                f,
                "\n        {}: {:.3} at most, {:.2} times its limit of {:.3}, over it in {} frames",
                j.joint,
                j.peak_velocity,
                j.peak_ratio().unwrap_or(0.0),
                j.velocity_limit.unwrap_or(f32::INFINITY),
                j.frames_over
            )?;
        }
        Ok(())
    }
}

/// How `poses` (frames at `fps`, holding `episodes` back to back; velocities never span two episodes)
/// keep to the joint limits of `tree`. `None` when no DoF of the character has a finite limit.
///
/// # Panics
/// If a pose does not have `tree`'s DoF count or an episode lies outside `poses`.
pub fn joint_limits(
    tree: &KinematicTree,
    poses: &[CharacterPose],
    fps: f32,
    episodes: &[Range<usize>],
) -> Option<JointLimitsReport> {
    struct Checked {
        dof: usize,
        continuous: bool,
        velocity: Option<f32>,
        bounds: Option<(f32, f32)>,
    }
    let checked: Vec<Checked> = (0..tree.dof())
        .filter_map(|d| {
            let j = tree.dof_joint(d);
            let l = j.limits?;
            let continuous = j.kind == JointKind::Continuous;
            let velocity = l.velocity_bound();
            // A continuous joint's bounds are infinite.
            let bounds = (l.lower.is_finite() && l.upper.is_finite()).then_some((l.lower, l.upper));
            (velocity.is_some() || bounds.is_some()).then_some(Checked {
                dof: d,
                continuous,
                velocity,
                bounds,
            })
        })
        .collect();
    if checked.is_empty() {
        return None;
    }
    let mut joints: Vec<JointLimitUse> = checked
        .iter()
        .map(|c| JointLimitUse {
            joint: tree.dof_joint(c.dof).name.clone(),
            velocity_limit: c.velocity,
            peak_velocity: 0.0,
            frames_over: 0,
            frames_outside: 0,
        })
        .collect();
    let (mut over, mut outside) = (0usize, 0usize);
    for e in episodes {
        for k in e.clone() {
            let (mut any_over, mut any_outside) = (false, false);
            for (c, u) in checked.iter().zip(joints.iter_mut()) {
                let q = poses[k].q[c.dof];
                if let Some((lo, hi)) = c.bounds
                    && (q < lo - POSITION_TOLERANCE || q > hi + POSITION_TOLERANCE)
                {
                    u.frames_outside += 1;
                    any_outside = true;
                }
                if k == e.start {
                    continue;
                }
                let step = q - poses[k - 1].q[c.dof];
                let v = if c.continuous { wrap_pi(step) } else { step }.abs() * fps;
                u.peak_velocity = u.peak_velocity.max(v);
                if let Some(limit) = c.velocity
                    && v > limit * (1.0 + VELOCITY_TOLERANCE)
                {
                    u.frames_over += 1;
                    any_over = true;
                }
            }
            over += usize::from(any_over);
            outside += usize::from(any_outside);
        }
    }
    let frames: usize = episodes.iter().map(|e| e.len()).sum();
    let share = |n: usize| if frames == 0 { 0.0 } else { n as f32 / frames as f32 };
    Some(JointLimitsReport {
        frames,
        over_velocity: share(over),
        outside_position: share(outside),
        joints,
    })
}
