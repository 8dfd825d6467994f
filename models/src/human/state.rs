//! The human state x^h (paper §6.1): 92 values per frame. Everything except the root height is
//! expressed in the heading frame of [`crate::frame`] (origin at the pelvis, x along the facing direction
//! projected on the ground, z up); velocities are world velocities expressed in the current frame's
//! heading axes.

use nalgebra::{Isometry3, UnitQuaternion, Vector3};

use super::clip::{HumanClip, HumanFrame};
use super::skeleton::{EndEffector, Joint};
use crate::frame::{angular_velocity, heading_frame, quat_wxyz};

/// Index ranges of the blocks of [`HumanState`]. The blocks are contiguous and in this order.
pub mod layout {
    use std::ops::Range;

    use crate::human::skeleton::{EndEffector, Joint};

    /// Pelvis height above the floor, metres (world z).
    pub const ROOT_HEIGHT: Range<usize> = 0..1;
    /// Pelvis rotation relative to the heading frame, quaternion `w, x, y, z` with `w ≥ 0`.
    pub const ROOT_ORIENTATION: Range<usize> = 1..5;
    /// Pelvis linear velocity, m/s, heading axes.
    pub const ROOT_LINEAR_VELOCITY: Range<usize> = 5..8;
    /// Pelvis angular velocity, rad/s, heading axes.
    pub const ROOT_ANGULAR_VELOCITY: Range<usize> = 8..11;
    /// Positions of the 17 canonical joints (x, y, z each, in [`Joint::ALL`] order), heading frame.
    pub const JOINT_POSITIONS: Range<usize> = 11..62;
    /// Positions of the 5 end effectors ([`EndEffector::ALL`] order), heading frame.
    pub const EE_POSITIONS: Range<usize> = 62..77;
    /// Velocities of the 5 end effectors, m/s, heading axes.
    pub const EE_VELOCITIES: Range<usize> = 77..92;
    /// Length of the state vector.
    pub const DIM: usize = 92;

    /// All blocks with their names, in order.
    pub const BLOCKS: [(&str, Range<usize>); 7] = [
        ("root_height", ROOT_HEIGHT),
        ("root_orientation", ROOT_ORIENTATION),
        ("root_linear_velocity", ROOT_LINEAR_VELOCITY),
        ("root_angular_velocity", ROOT_ANGULAR_VELOCITY),
        ("joint_positions", JOINT_POSITIONS),
        ("ee_positions", EE_POSITIONS),
        ("ee_velocities", EE_VELOCITIES),
    ];

    /// The 3 values of joint `j`'s position.
    pub fn joint_position(j: Joint) -> Range<usize> {
        let s = JOINT_POSITIONS.start + 3 * j.index();
        s..s + 3
    }

    /// The 3 values of end effector `e`'s position.
    pub fn ee_position(e: EndEffector) -> Range<usize> {
        let s = EE_POSITIONS.start + 3 * e as usize;
        s..s + 3
    }

    /// The 3 values of end effector `e`'s velocity.
    pub fn ee_velocity(e: EndEffector) -> Range<usize> {
        let s = EE_VELOCITIES.start + 3 * e as usize;
        s..s + 3
    }
}

/// x^h: 92 values, laid out as in [`layout`].
#[derive(Clone, Debug, PartialEq)]
pub struct HumanState(pub [f32; layout::DIM]);

impl HumanState {
    /// The heading frame of a human frame: at the pelvis, yawed to the facing direction.
    pub fn heading(frame: &HumanFrame) -> Isometry3<f32> {
        heading_frame(&frame.positions[Joint::Pelvis.index()], &frame.forward())
    }

    /// State of `cur`, with velocities from `from` → `to` over `dt` seconds (normally `from` = the
    /// previous frame and `to` = `cur`; for a clip's first frame, `cur` → the next frame).
    pub fn from_frames(
        cur: &HumanFrame,
        from: &HumanFrame,
        to: &HumanFrame,
        dt: f32,
    ) -> HumanState {
        let mut x = [0.0f32; layout::DIM];
        let h = Self::heading(cur);
        let to_local = |v: Vector3<f32>| h.rotation.inverse_transform_vector(&v);
        let pelvis = Joint::Pelvis.index();
        x[layout::ROOT_HEIGHT.start] = cur.positions[pelvis].z;
        x[layout::ROOT_ORIENTATION]
            .copy_from_slice(&quat_wxyz(&(h.rotation.inverse() * cur.root_rotation)));
        let (lin, ang) = if dt > 0.0 {
            (
                (to.positions[pelvis] - from.positions[pelvis]) / dt,
                angular_velocity(&from.root_rotation, &to.root_rotation, dt),
            )
        } else {
            (Vector3::zeros(), Vector3::zeros())
        };
        x[layout::ROOT_LINEAR_VELOCITY].copy_from_slice(to_local(lin).as_slice());
        x[layout::ROOT_ANGULAR_VELOCITY].copy_from_slice(to_local(ang).as_slice());
        for j in Joint::ALL {
            let p = h.inverse_transform_point(&cur.positions[j.index()].into());
            x[layout::joint_position(j)].copy_from_slice(p.coords.as_slice());
        }
        for e in EndEffector::ALL {
            let k = e.joint().index();
            let p = h.inverse_transform_point(&cur.positions[k].into());
            x[layout::ee_position(e)].copy_from_slice(p.coords.as_slice());
            let v = if dt > 0.0 {
                (to.positions[k] - from.positions[k]) / dt
            } else {
                Vector3::zeros()
            };
            x[layout::ee_velocity(e)].copy_from_slice(to_local(v).as_slice());
        }
        HumanState(x)
    }

    /// x^h at time `t` of a motion sampled by `frame_at` (seconds → frame), with velocities over
    /// `dt`: the backward difference from `t − dt`, or for the first state of a sequence (`first`)
    /// the forward difference to `t + dt`. This is the rule of [`HumanClip::states`], for motion
    /// that is sampled or arrives frame by frame; a sampler that clamps at its latest frame gives
    /// a first state without velocities.
    pub fn sampled(frame_at: impl Fn(f32) -> HumanFrame, t: f32, dt: f32, first: bool) -> HumanState {
        let cur = frame_at(t);
        if first {
            HumanState::from_frames(&cur, &cur, &frame_at(t + dt), dt)
        } else {
            HumanState::from_frames(&cur, &frame_at(t - dt), &cur, dt)
        }
    }

    /// All values.
    pub fn as_slice(&self) -> &[f32] {
        &self.0
    }

    /// Pelvis height, metres.
    pub fn root_height(&self) -> f32 {
        self.0[layout::ROOT_HEIGHT.start]
    }

    /// Pelvis rotation relative to the heading frame.
    pub fn root_orientation(&self) -> UnitQuaternion<f32> {
        let q = &self.0[layout::ROOT_ORIENTATION];
        UnitQuaternion::from_quaternion(nalgebra::Quaternion::new(q[0], q[1], q[2], q[3]))
    }

    /// Pelvis linear velocity in heading axes (x forward, y left, z up), m/s.
    pub fn root_linear_velocity(&self) -> Vector3<f32> {
        Vector3::from_column_slice(&self.0[layout::ROOT_LINEAR_VELOCITY])
    }

    /// Pelvis angular velocity in heading axes, rad/s.
    pub fn root_angular_velocity(&self) -> Vector3<f32> {
        Vector3::from_column_slice(&self.0[layout::ROOT_ANGULAR_VELOCITY])
    }

    /// Joint position in the heading frame.
    pub fn joint_position(&self, j: Joint) -> Vector3<f32> {
        Vector3::from_column_slice(&self.0[layout::joint_position(j)])
    }

    /// End-effector position in the heading frame.
    pub fn ee_position(&self, e: EndEffector) -> Vector3<f32> {
        Vector3::from_column_slice(&self.0[layout::ee_position(e)])
    }

    /// End-effector velocity in heading axes.
    pub fn ee_velocity(&self, e: EndEffector) -> Vector3<f32> {
        Vector3::from_column_slice(&self.0[layout::ee_velocity(e)])
    }
}

impl HumanClip {
    /// x^h for every frame. Velocities are backward differences; the first frame uses the forward
    /// difference to the second (a one-frame clip has zero velocities).
    pub fn states(&self) -> Vec<HumanState> {
        let dt = 1.0 / self.fps;
        let f = &self.frames;
        (0..f.len())
            .map(|t| match t {
                0 if f.len() > 1 => HumanState::from_frames(&f[0], &f[0], &f[1], dt),
                0 => HumanState::from_frames(&f[0], &f[0], &f[0], 0.0),
                _ => HumanState::from_frames(&f[t], &f[t - 1], &f[t], dt),
            })
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::human::skeleton::JOINT_COUNT;

    #[test]
    fn layout_blocks_are_contiguous_and_sum_to_dim() {
        let mut next = 0;
        for (name, r) in layout::BLOCKS {
            assert_eq!(r.start, next, "{name}");
            next = r.end;
        }
        assert_eq!(next, layout::DIM);
        assert_eq!(layout::DIM, 92);
        assert_eq!(layout::JOINT_POSITIONS.len(), 3 * JOINT_COUNT);
        assert_eq!(layout::EE_POSITIONS.len(), 3 * EndEffector::ALL.len());
        assert_eq!(layout::ee_velocity(EndEffector::Head).end, layout::DIM);
        assert_eq!(
            layout::joint_position(Joint::RightFoot).end,
            layout::JOINT_POSITIONS.end
        );
    }

    #[test]
    fn sampling_a_clip_tick_by_tick_gives_its_states() {
        let clip = crate::test_data::bundled_clip("walk");
        let at30 = clip.resampled(30.0);
        let states = at30.states();
        for (k, want) in states.iter().enumerate().take(60) {
            let got = HumanState::sampled(|t| clip.frame_at(t), k as f32 / 30.0, 1.0 / 30.0, k == 0);
            let gap = got.0.iter().zip(&want.0).map(|(a, b)| (a - b).abs()).fold(0.0, f32::max);
            assert!(gap < 1e-4, "tick {k}: {gap}");
        }
    }

    #[test]
    fn a_one_frame_clip_has_its_pose_and_no_velocities() {
        let mut clip = crate::test_data::bundled_clip("walk");
        let moving = clip.states()[0].clone();
        assert!(moving.root_linear_velocity().norm() > 0.1, "the walk's first frame moves");
        clip.frames.truncate(1);
        let [still] = &clip.states()[..] else { panic!("one state") };
        for (name, r) in layout::BLOCKS {
            let velocity = name.ends_with("velocity") || name.ends_with("velocities");
            for i in r {
                let want = if velocity { 0.0 } else { moving.0[i] };
                assert_eq!(still.0[i], want, "{name}, entry {i}");
            }
        }
    }

    #[test]
    fn state_is_invariant_to_ground_translation_and_yaw() {
        // A pelvis walking along world y (facing +y) at 1 m/s.
        let frame = |t: f32| {
            let yaw =
                UnitQuaternion::from_axis_angle(&Vector3::z_axis(), std::f32::consts::FRAC_PI_2);
            let mut positions = [Vector3::zeros(); JOINT_COUNT];
            for (k, p) in positions.iter_mut().enumerate() {
                *p = Vector3::new(0.0, t, 1.0)
                    + yaw * Vector3::new(0.01 * k as f32, 0.0, 0.1 * k as f32);
            }
            HumanFrame {
                positions,
                root_rotation: yaw,
            }
        };
        let a = HumanState::from_frames(&frame(0.1), &frame(0.0), &frame(0.1), 0.1);
        assert!((a.root_height() - 1.0).abs() < 1e-6);
        assert!((a.root_linear_velocity() - Vector3::new(1.0, 0.0, 0.0)).norm() < 1e-4);
        assert!(a.root_orientation().angle() < 1e-4);
        assert!((a.joint_position(Joint::Head) - Vector3::new(0.04, 0.0, 0.4)).norm() < 1e-5);
        assert!((a.ee_velocity(EndEffector::LeftFoot) - Vector3::new(1.0, 0.0, 0.0)).norm() < 1e-4);
    }
}
