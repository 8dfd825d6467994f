//! Velocity limit: no joint of the output moves faster than the velocity limit its file gives it
//! (URDF `<limit velocity>`).
//!
//! A robot sent a joint faster than its limit slows it or faults, and what it executes is no longer the
//! motion retargeted. The networks can ask for it: the prior learned from datasets within the limits,
//! but a generator chasing a fast hand pushes it past them (the shipped Stretch moves its lift at up to
//! 5.6 times its 0.3 m/s on the bundled `wave`; [`mod@crate::metrics::joint_limits`] measures it). Each
//! limited joint moves from the previous frame's output towards the pose asked for by at most its limit
//! times the frame's duration; a joint held back catches up on the frames that follow, as a robot's
//! joint controller at its speed limit would. Wheels are left out (their angles follow the base's
//! travel), and so are other continuous joints (their angles wrap at ±π, where a clamp would turn
//! them the long way round) and joints without a limit (every bone of a rigged creature). Causal: a live stream
//! and an offline clip agree frame for frame.
//!
//! Off by default ([`crate::cleanup::Cleanup::velocity_limit`], `ace retarget --limit-velocity`): the
//! shipped Stretch's generator asks its lift for up to 11.7 times its speed on held-out clips, and held
//! to it the gripper follows the hand far less (held out: vertical correlation 0.82 → 0.46, following
//! 0.252 → 0.124); Spot's following moves 0.390 → 0.388. A generator trained with a penalty on joint
//! speed past the limits did worse: its lift lagged the hand more than this clamp's and still
//! exceeded its limit (docs/metrics.md, "Joint limits").

use crate::kinematics::{CharacterPose, JointKind, KinematicTree};
use crate::morphology::Morphology;

/// The velocity limit of one character: per limited DoF, the most it may move in one frame.
#[derive(Clone, Debug)]
pub struct VelocityLimit {
    steps: Vec<(usize, f32)>,
}

/// Its memory for one character being driven: the last output's joint positions.
#[derive(Clone, Debug, Default)]
pub struct VelocityLimitState {
    last: Option<Vec<f32>>,
}

impl VelocityLimit {
    /// The limit of `tree`'s joints at `fps` frames per second (`None` when no joint but wheels has a
    /// velocity limit).
    pub fn new(tree: &KinematicTree, morph: &Morphology, fps: f32) -> Option<VelocityLimit> {
        let wheels = morph.wheel_dofs(tree);
        let steps: Vec<(usize, f32)> = (0..tree.dof())
            .filter(|d| !wheels.contains(d))
            .filter_map(|d| {
                let j = tree.dof_joint(d);
                let v = j.limits?.velocity_bound()?;
                (j.kind != JointKind::Continuous).then_some((d, v / fps))
            })
            .collect();
        (!steps.is_empty()).then_some(VelocityLimit { steps })
    }

    /// Moves each limited joint of `pose` at most one frame's step from the last output.
    pub fn apply(&self, state: &VelocityLimitState, pose: &mut CharacterPose) {
        let Some(last) = &state.last else { return };
        for &(d, step) in &self.steps {
            let from = last[d];
            pose.q[d] = pose.q[d].clamp(from - step, from + step);
        }
    }

    /// Records the frame's output (after every other step), which the next frame moves from.
    pub fn observe(&self, state: &mut VelocityLimitState, pose: &CharacterPose) {
        match &mut state.last {
            Some(last) => last.copy_from_slice(&pose.q),
            None => state.last = Some(pose.q.clone()),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::morphology::load_character;
    use nalgebra::Isometry3;

    fn stretch() -> (KinematicTree, Morphology) {
        let p = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../assets/characters/stretch.urdf");
        load_character(&p).unwrap()
    }

    #[test]
    fn a_joint_asked_to_jump_moves_at_its_limit_and_catches_up() {
        let (tree, morph) = stretch();
        let limit = VelocityLimit::new(&tree, &morph, 30.0).unwrap();
        let lift = tree.dof_index("joint_lift").unwrap();
        let wheel = tree.dof_index("joint_left_wheel").unwrap();
        assert!(limit.steps.iter().all(|&(d, _)| d != wheel), "wheels are left out");
        let step = 0.3 / 30.0;
        let mut state = VelocityLimitState::default();
        let mut pose = tree.neutral_pose(Isometry3::identity());
        pose.q[lift] = 0.1;
        let mut out = Vec::new();
        let mut limited = 0;
        for k in 0..60 {
            // Asked: 0.1 m, then 0.6 m from frame 1 on; the wheel spins half a turn a frame.
            let mut p = pose.clone();
            if k > 0 {
                p.q[lift] = 0.6;
            }
            p.q[wheel] = k as f32 * 3.0;
            let asked = p.q.clone();
            limit.apply(&state, &mut p);
            limited += usize::from(p.q != asked);
            limit.observe(&mut state, &p);
            out.push((p.q[lift], p.q[wheel]));
        }
        assert_eq!(out[0].0, 0.1, "the first frame has nothing to move from");
        for k in 1..60 {
            let moved = out[k].0 - out[k - 1].0;
            assert!(moved <= step + 1e-6, "frame {k}: {moved}");
            assert_eq!(out[k].1, k as f32 * 3.0, "the wheel is not held");
        }
        assert!((out[10].0 - (0.1 + 10.0 * step)).abs() < 1e-5, "{}", out[10].0);
        // 0.5 m at 0.01 m a frame: there by frame 50, and held there.
        assert!((out[50].0 - 0.6).abs() < 1e-5 && (out[59].0 - 0.6).abs() < 1e-6, "{} {}", out[50].0, out[59].0);
        assert!((49..=51).contains(&limited), "{limited}");
        // Down as up.
        let mut p = pose.clone();
        p.q[lift] = 0.0;
        limit.apply(&state, &mut p);
        assert!((p.q[lift] - (0.6 - step)).abs() < 1e-6);
    }

    #[test]
    fn a_character_without_velocity_limits_has_no_limit() {
        let hound = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../assets/creatures/hound.glb");
        let (tree, morph) = load_character(&hound).unwrap();
        assert!(VelocityLimit::new(&tree, &morph, 30.0).is_none());
    }
}
