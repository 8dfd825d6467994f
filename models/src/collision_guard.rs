//! Collision guard: generated poses never put one part of the character through another or through
//! the ground.
//!
//! The motion prior has never seen a self-colliding pose, but a generator chasing a human hand can
//! still lead it into one (Spot's arm folding into its body, the gripper pushed into the floor). A robot
//! must never be sent such a pose and an animator does not want one, so generated motion passes through
//! this guard: when a frame's pose collides — by the same checks and tolerances as the UFR
//! ([`PoseChecks`]) — its joint positions are moved back along the straight line towards the previous
//! frame's output (collision-free by induction) to the last collision-free point, found by bisection.
//! The joints of the legs are left alone when moving the others suffices (the legs have just been
//! planted by foot locking); wheels keep their angles and the root is never moved. The guard is causal,
//! so a live stream and an offline clip agree frame for frame.

use crate::controller::chain::Chain;
use crate::kinematics::{CharacterPose, KinematicTree};
use crate::metrics::{PoseChecks, PoseScratch, UfrConfig};
use crate::morphology::Morphology;

/// Bisection steps: the remaining step is at most 1/2⁸ of the frame's joint motion.
const BISECTION_STEPS: usize = 8;

/// The guard of one character (see the module docs).
#[derive(Clone, Debug)]
pub struct CollisionGuard {
    checks: PoseChecks,
    morph: Morphology,
    /// DoFs tried first: neither legs nor wheels.
    upper: Vec<usize>,
    /// DoFs tried when those do not suffice: all but wheels.
    all: Vec<usize>,
}

/// The guard's memory for one character being driven: its last output's joint positions.
#[derive(Clone, Debug, Default)]
pub struct GuardState {
    last_free: Option<Vec<f32>>,
    scratch: PoseScratch,
    /// Frames the guard changed so far.
    pub corrected: usize,
}

impl CollisionGuard {
    /// The guard for a character, with the UFR's tolerances.
    pub fn new(tree: &KinematicTree, morph: &Morphology) -> CollisionGuard {
        let checks = PoseChecks::new(tree, morph, &UfrConfig::for_character(tree, morph));
        let dof_of = |l: usize| tree.links[l].joint.as_ref().and_then(|j| j.dof);
        let wheels: Vec<usize> = morph.wheels.iter().filter_map(|&l| dof_of(l)).collect();
        let legs: Vec<usize> = morph
            .feet
            .iter()
            .flat_map(|&f| Chain::new(tree, morph, f).active_dofs().collect::<Vec<_>>())
            .collect();
        let all: Vec<usize> = (0..tree.dof()).filter(|d| !wheels.contains(d)).collect();
        CollisionGuard {
            checks,
            morph: morph.clone(),
            upper: all.iter().copied().filter(|d| !legs.contains(d)).collect(),
            all,
        }
    }

    /// Whether `pose` collides with itself or the ground.
    pub fn collides(&self, tree: &KinematicTree, pose: &CharacterPose, scratch: &mut PoseScratch) -> bool {
        self.checks.place(tree, pose, scratch);
        self.checks.is_unrealistic(&self.morph, scratch)
    }

    /// Guards one frame in place, advancing `state`. A pose that collides while the previous output
    /// also did (the first frame, say) is left as it is.
    pub fn apply(&self, tree: &KinematicTree, state: &mut GuardState, pose: &mut CharacterPose) {
        let scratch = &mut state.scratch;
        if self.collides(tree, pose, scratch) {
            if let Some(prev) = &state.last_free {
                let target = pose.q.clone();
                let mut probe = pose.clone();
                for dofs in [&self.upper, &self.all] {
                    let at = |a: f32, q: &mut Vec<f32>| {
                        q.copy_from_slice(&target);
                        for &d in dofs {
                            q[d] = prev[d] + a * (target[d] - prev[d]);
                        }
                    };
                    at(0.0, &mut probe.q);
                    if self.collides(tree, &probe, scratch) {
                        continue; // moving these DoFs back is not enough
                    }
                    // The largest a in [0, 1) with a free pose.
                    let (mut lo, mut hi) = (0.0f32, 1.0f32);
                    for _ in 0..BISECTION_STEPS {
                        let mid = 0.5 * (lo + hi);
                        at(mid, &mut probe.q);
                        if self.collides(tree, &probe, scratch) {
                            hi = mid;
                        } else {
                            lo = mid;
                        }
                    }
                    at(lo, &mut pose.q);
                    state.corrected += 1;
                    break;
                }
            }
        }
        if !self.collides(tree, pose, scratch) {
            state.last_free = Some(pose.q.clone());
        }
    }
}

#[cfg(test)]
mod tests {
    use std::path::Path;

    use super::*;
    use crate::metrics::ufr;
    use crate::morphology::load_character;

    #[test]
    fn an_arm_swung_through_the_body_stops_at_its_surface() {
        let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../assets/characters/spot.urdf");
        let (tree, morph) = load_character(&path).unwrap();
        let sh1 = tree.dof_names().iter().position(|n| *n == "arm_sh1").unwrap();
        let l = tree.limits(sh1).unwrap();
        let (lo, hi) = (l.lower, l.upper);
        // The arm's shoulder swept across its whole range and back: somewhere it passes the body.
        let raw: Vec<CharacterPose> = (0..120)
            .map(|t| {
                let mut p = tree.standing_pose();
                let s = 0.5 - 0.5 * (t as f32 * std::f32::consts::TAU / 120.0).cos();
                p.q[sh1] = lo + s * (hi - lo);
                p
            })
            .collect();
        let cfg = UfrConfig::for_character(&tree, &morph);
        let before = ufr(&tree, &morph, &raw, 30.0, &cfg).summary().rates.self_collision;
        assert!(before > 0.1, "the sweep collides: {before}");
        let guard = CollisionGuard::new(&tree, &morph);
        let mut state = GuardState::default();
        let mut out = raw.clone();
        for p in &mut out {
            guard.apply(&tree, &mut state, p);
        }
        let after = ufr(&tree, &morph, &out, 30.0, &cfg).summary().rates.self_collision;
        assert_eq!(after, 0.0);
        assert!(state.corrected > 0);
        // Frames that were free are untouched, roots are never moved.
        let mut scratch = PoseScratch::default();
        for (a, b) in raw.iter().zip(&out) {
            assert_eq!(a.root, b.root);
            assert!(!guard.collides(&tree, b, &mut scratch));
            if !guard.collides(&tree, a, &mut scratch) {
                assert_eq!(a, b, "a free frame is left alone");
            }
            // Legs were not needed to clear the arm.
            assert_eq!(a.q[..12], b.q[..12]);
        }
        assert_eq!(raw[0], out[0]);
    }
}
