//! A robot command trajectory from character poses: what a robot's API takes (paper §7.5: base
//! velocity command plus joint angles).
//!
//! Per frame `k` (time `t = k / fps`):
//! - `vx`, `vy` (m/s): the root link's horizontal velocity in its **heading frame** (x along the root's
//!   x axis projected on the ground, y to its left, see [`crate::frame`]);
//! - `wz` (rad/s): the heading's yaw rate, counter-clockwise seen from above;
//! - `height` (m): the root link origin's height above z = 0;
//! - one position per DoF (rad for revolute and continuous joints, m for prismatic ones), by URDF joint
//!   name in DoF order. Wheels are included; continuous joints are unwrapped so that they change
//!   continuously (no jumps of 2π), so a wheel's angle grows with the distance it rolled.
//!
//! Velocities are finite differences of the root positions and of the unwrapped heading yaw: central
//! differences `(x[k+1] − x[k−1]) / (2·dt)` inside the clip, one-sided at the first and last frame,
//! zero for a single frame. World velocities are turned into the heading frame of the same frame.
//!
//! **JSON schema** ([`CommandTrajectory::to_json`]):
//! ```json
//! {
//!   "format": "ace-command-trajectory", "version": 1,
//!   "robot": "spot", "fps": 30.0,
//!   "units": {"t": "s", "vx": "m/s", "vy": "m/s", "wz": "rad/s", "height": "m"},
//!   "joints": [{"name": "fl_hx", "type": "revolute", "unit": "rad"}, …],
//!   "frames": [{"t": 0.0, "vx": 0.5, "vy": 0.0, "wz": 0.1, "height": 0.52, "q": [0.1, …]}, …]
//! }
//! ```
//! `q` lists the joint positions in the order of `joints`; `type` is `revolute`, `continuous` or
//! `prismatic`. **CSV** ([`CommandTrajectory::to_csv`]): a header row `t,vx,vy,wz,height,<joint
//! names…>` and one row per frame, in the same units.

use std::path::Path;

use nalgebra::Vector3;
use serde::{Deserialize, Serialize};

use super::{ExportError, check_poses, write_atomic};
use crate::frame::{heading_yaw, unwrap_angles};
use crate::kinematics::{CharacterPose, JointKind, KinematicTree};

/// One joint column of a trajectory.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct CommandJoint {
    /// URDF joint name.
    pub name: String,
    /// `revolute`, `continuous` or `prismatic`.
    #[serde(rename = "type")]
    pub kind: String,
    /// `rad` or `m`.
    pub unit: String,
}

/// One frame of commands. See the module documentation for frames and units.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct CommandFrame {
    /// Time from the first frame (s).
    pub t: f32,
    /// Forward velocity in the heading frame (m/s).
    pub vx: f32,
    /// Leftward velocity in the heading frame (m/s).
    pub vy: f32,
    /// Yaw rate (rad/s).
    pub wz: f32,
    /// Height of the root link origin (m).
    pub height: f32,
    /// Joint positions in the order of [`CommandTrajectory::joints`] (rad or m).
    pub q: Vec<f32>,
}

/// Base velocity, base height and joint position commands over time.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct CommandTrajectory {
    /// Always `ace-command-trajectory`.
    pub format: String,
    /// Schema version, 1.
    pub version: u32,
    /// Robot name from the URDF.
    pub robot: String,
    /// Frames per second.
    pub fps: f32,
    /// Unit of each base column.
    pub units: BaseUnits,
    /// The joint columns, in DoF order.
    pub joints: Vec<CommandJoint>,
    /// One entry per pose.
    pub frames: Vec<CommandFrame>,
}

/// Units of the base columns (fixed; written out so that the files document themselves).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct BaseUnits {
    /// Unit of `t`: `s`.
    pub t: String,
    /// Unit of `vx`: `m/s`.
    pub vx: String,
    /// Unit of `vy`: `m/s`.
    pub vy: String,
    /// Unit of `wz`: `rad/s`.
    pub wz: String,
    /// Unit of `height`: `m`.
    pub height: String,
}

impl Default for BaseUnits {
    fn default() -> Self {
        BaseUnits {
            t: "s".into(),
            vx: "m/s".into(),
            vy: "m/s".into(),
            wz: "rad/s".into(),
            height: "m".into(),
        }
    }
}


/// Finite-difference rate of `x` sampled every `dt` seconds (central inside, one-sided at the ends).
fn rate<T>(x: &[T], dt: f32) -> Vec<T>
where
    T: Copy + std::ops::Sub<Output = T> + std::ops::Mul<f32, Output = T> + Default,
{
    let n = x.len();
    (0..n)
        .map(|k| match (k.checked_sub(1), (k + 1 < n).then_some(k + 1)) {
            (Some(a), Some(b)) => (x[b] - x[a]) * (0.5 / dt),
            (None, Some(b)) => (x[b] - x[k]) * (1.0 / dt),
            (Some(a), None) => (x[k] - x[a]) * (1.0 / dt),
            (None, None) => T::default(),
        })
        .collect()
}

impl CommandTrajectory {
    /// The trajectory of `poses` (one per frame, `fps` frames per second) of the character `tree`.
    /// Errors name `<command trajectory of NAME in memory>`.
    pub fn from_poses(tree: &KinematicTree, poses: &[CharacterPose], fps: f32) -> Result<Self, ExportError> {
        check_poses(tree, poses, fps)
            .map_err(|p| p.in_file(format!("<command trajectory of {} in memory>", tree.name)))?;
        let dt = 1.0 / fps;
        let positions: Vec<Vector3<f32>> = poses.iter().map(|p| p.root.translation.vector).collect();
        let mut yaw: Vec<f32> = poses
            .iter()
            .map(|p| heading_yaw(&(p.root.rotation * Vector3::x())))
            .collect();
        unwrap_angles(&mut yaw);
        let velocity = rate(&positions, dt);
        let yaw_rate = rate(&yaw, dt);

        let joints: Vec<CommandJoint> = (0..tree.dof())
            .map(|d| {
                let j = tree.dof_joint(d);
                let (kind, unit) = match j.kind {
                    JointKind::Revolute => ("revolute", "rad"),
                    JointKind::Continuous => ("continuous", "rad"),
                    JointKind::Prismatic => ("prismatic", "m"),
                    JointKind::Fixed => unreachable!("DoFs are movable joints"),
                };
                CommandJoint {
                    name: j.name.clone(),
                    kind: kind.into(),
                    unit: unit.into(),
                }
            })
            .collect();
        // Joint tracks, continuous ones unwrapped.
        let mut tracks: Vec<Vec<f32>> = (0..tree.dof())
            .map(|d| poses.iter().map(|p| p.q[d]).collect())
            .collect();
        for (d, track) in tracks.iter_mut().enumerate() {
            if tree.dof_joint(d).kind == JointKind::Continuous {
                unwrap_angles(track);
            }
        }
        let frames = (0..poses.len())
            .map(|k| {
                let (s, c) = yaw[k].sin_cos();
                let v = velocity[k];
                CommandFrame {
                    t: k as f32 * dt,
                    vx: c * v.x + s * v.y,
                    vy: -s * v.x + c * v.y,
                    wz: yaw_rate[k],
                    height: positions[k].z,
                    q: tracks.iter().map(|t| t[k]).collect(),
                }
            })
            .collect();
        Ok(CommandTrajectory {
            format: "ace-command-trajectory".into(),
            version: 1,
            robot: tree.name.clone(),
            fps,
            units: BaseUnits::default(),
            joints,
            frames,
        })
    }

    /// The trajectory as JSON (schema in the module documentation).
    pub fn to_json(&self) -> String {
        serde_json::to_string_pretty(self).expect("a trajectory serialises")
    }

    /// The trajectory as CSV: header `t,vx,vy,wz,height,<joint names…>`, one row per frame. Joint
    /// names that contain a comma, quote or line break are quoted.
    pub fn to_csv(&self) -> String {
        let mut out = String::from("t,vx,vy,wz,height");
        for j in &self.joints {
            out.push(',');
            if j.name.contains([',', '"', '\n', '\r']) {
                out.push_str(&format!("\"{}\"", j.name.replace('"', "\"\"")));
            } else {
                out.push_str(&j.name);
            }
        }
        out.push('\n');
        for f in &self.frames {
            let row: Vec<String> = [f.t, f.vx, f.vy, f.wz, f.height]
                .iter()
                .chain(&f.q)
                .map(|v| v.to_string())
                .collect();
            out.push_str(&row.join(","));
            out.push('\n');
        }
        out
    }

    /// Writes [`CommandTrajectory::to_json`] atomically to `path`; errors name `path`.
    pub fn write_json(&self, path: &Path) -> Result<(), ExportError> {
        write_atomic(path, self.to_json().as_bytes())
    }

    /// Writes [`CommandTrajectory::to_csv`] atomically to `path`; errors name `path`.
    pub fn write_csv(&self, path: &Path) -> Result<(), ExportError> {
        write_atomic(path, self.to_csv().as_bytes())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rates_are_central_inside_and_one_sided_at_the_ends() {
        let x = [0.0f32, 1.0, 4.0, 9.0];
        assert_eq!(rate(&x, 0.5), vec![2.0, 4.0, 8.0, 10.0]);
        assert_eq!(rate(&[5.0f32], 0.1), vec![0.0]);
    }
}
