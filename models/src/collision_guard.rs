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
//! planted by foot locking); wheels keep their angles. When the root itself came down into the ground,
//! it is lifted out — the only case the guard moves the root. The guard is causal, so a live stream and
//! an offline clip agree frame for frame.

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
    /// Joint positions of the standing pose, where arms go when the last output's cannot clear the
    /// ground.
    standing: Vec<f32>,
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
        // Every DoF on a foot's path from the root, a spine's included: moving any of them moves a
        // foot the foot lock may hold planted, so they are the last resort.
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
            standing: tree.standing_pose().q,
        }
    }

    /// Whether `pose` collides with itself or the ground.
    pub fn collides(&self, tree: &KinematicTree, pose: &CharacterPose, scratch: &mut PoseScratch) -> bool {
        self.checks.place(tree, pose, scratch);
        self.checks.is_unrealistic(&self.morph, scratch)
    }

    fn self_collides(&self, tree: &KinematicTree, pose: &CharacterPose, scratch: &mut PoseScratch) -> bool {
        self.checks.place(tree, pose, scratch);
        self.checks.collisions(scratch, |_| {}) > 0
    }

    /// Guards one frame in place, advancing `state`:
    /// 1. a self-collision is undone by moving joints back towards the last output (legs only when the
    ///    others do not suffice; self-collision does not depend on the root, so this always succeeds
    ///    once there is a last output);
    /// 2. a ground penetration is undone the same way, towards the last output, else towards the
    ///    standing pose — with the arms and other non-leg joints first, with the legs too when that is
    ///    not enough — and when nothing is (the root itself came down) by lifting the root out of the
    ///    ground.
    pub fn apply(&self, tree: &KinematicTree, state: &mut GuardState, pose: &mut CharacterPose) {
        let scratch = &mut state.scratch;
        if !self.collides(tree, pose, scratch) {
            state.last_free = Some(pose.q.clone());
            return;
        }
        state.corrected += 1;
        if let Some(prev) = &state.last_free {
            if self.self_collides(tree, pose, scratch) {
                for dofs in [&self.upper, &self.all] {
                    if self.move_back(tree, pose, prev, dofs, scratch, &Self::self_collides) {
                        break;
                    }
                }
            }
            // Towards the last output, else towards the standing pose: an arm reaching into the ground
            // of a body that came down is pulled up rather than the whole body lifted.
            // Legs only when the rest cannot do it (a leg the network pushed through the floor).
            if self.collides(tree, pose, scratch) {
                for dofs in [&self.upper, &self.all] {
                    if self.move_back(tree, pose, prev, dofs, scratch, &Self::collides)
                        || self.move_back(tree, pose, &self.standing, dofs, scratch, &Self::collides)
                    {
                        break;
                    }
                }
            }
        }
        self.checks.place(tree, pose, scratch);
        if self.checks.penetrates(&self.morph, scratch) {
            pose.root.translation.z += self.checks.depth_below_ground(&self.morph, scratch);
        }
        if !self.collides(tree, pose, scratch) {
            state.last_free = Some(pose.q.clone());
        }
    }

    /// Moves `dofs` of `pose` back along the line towards `prev` to the last point where `bad` is
    /// false (bisection); false, leaving `pose` alone, when even `prev`'s values are bad.
    fn move_back(
        &self,
        tree: &KinematicTree,
        pose: &mut CharacterPose,
        prev: &[f32],
        dofs: &[usize],
        scratch: &mut PoseScratch,
        bad: &dyn Fn(&Self, &KinematicTree, &CharacterPose, &mut PoseScratch) -> bool,
    ) -> bool {
        let target = pose.q.clone();
        let mut probe = pose.clone();
        let at = |a: f32, q: &mut [f32]| {
            for &d in dofs {
                q[d] = prev[d] + a * (target[d] - prev[d]);
            }
        };
        at(0.0, &mut probe.q);
        if bad(self, tree, &probe, scratch) {
            return false;
        }
        let (mut lo, mut hi) = (0.0f32, 1.0f32);
        for _ in 0..BISECTION_STEPS {
            let mid = 0.5 * (lo + hi);
            at(mid, &mut probe.q);
            if bad(self, tree, &probe, scratch) {
                hi = mid;
            } else {
                lo = mid;
            }
        }
        at(lo, &mut pose.q);
        true
    }
}

#[cfg(test)]
mod tests {
    use std::path::Path;

    use super::*;
    use crate::metrics::ufr;
    use crate::morphology::load_character;

    /// Spot, and its arm's DoF `name` swept over its range and back in 120 frames from the standing pose,
    /// with the DoFs of `fixed` held at the given fraction of their ranges.
    fn sweep(name: &str, fixed: &[(&str, f32)]) -> (KinematicTree, Morphology, Vec<CharacterPose>) {
        let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../assets/characters/spot.urdf");
        let (tree, morph) = load_character(&path).unwrap();
        let dof = |name: &str| tree.dof_names().iter().position(|n| *n == name).unwrap();
        let d = dof(name);
        let l = tree.limits(d).unwrap();
        let mut standing = tree.standing_pose();
        for &(n, f) in fixed {
            let l = tree.limits(dof(n)).unwrap();
            standing.q[dof(n)] = l.lower + f * (l.upper - l.lower);
        }
        let raw = (0..120)
            .map(|t| {
                let mut p = standing.clone();
                let s = 0.5 - 0.5 * (t as f32 * std::f32::consts::TAU / 120.0).cos();
                p.q[d] = l.lower + s * (l.upper - l.lower);
                p
            })
            .collect();
        (tree, morph, raw)
    }

    /// Every frame the guard changed stops at the surface it ran into: on the line from the last
    /// output towards the raw pose, free, with a point 3/256 of that line further on colliding (the
    /// bisection's resolution is 1/256), unless it is the line's end. Returns the frames changed.
    fn assert_stopped_at_the_surface(tree: &KinematicTree, guard: &CollisionGuard, raw: &[CharacterPose], out: &[CharacterPose]) -> usize {
        let mut scratch = PoseScratch::default();
        let mut changed = 0;
        for t in 1..raw.len() {
            if raw[t] == out[t] {
                continue;
            }
            changed += 1;
            let (prev, (a, b)) = (&out[t - 1].q, (&raw[t].q, &out[t].q));
            assert!(!guard.collides(tree, &out[t], &mut scratch), "frame {t} still collides");
            // On the line: the same fraction of the way for every joint that moved.
            let fractions: Vec<f32> = (0..a.len())
                .filter(|&d| (a[d] - prev[d]).abs() > 1e-4)
                .map(|d| (b[d] - prev[d]) / (a[d] - prev[d]))
                .collect();
            let f = fractions[0];
            assert!(fractions.iter().all(|g| (g - f).abs() < 1e-3), "frame {t}: off the line {fractions:?}");
            assert!((0.0..1.0).contains(&f), "frame {t}: {f} of the way");
            let mut further = out[t].clone();
            for d in 0..a.len() {
                further.q[d] += 3.0 / 256.0 * (a[d] - prev[d]);
            }
            assert!(f + 3.0 / 256.0 >= 1.0 || guard.collides(tree, &further, &mut scratch), "frame {t}: stopped short at {f}");
        }
        changed
    }

    #[test]
    fn an_arm_swung_into_the_ground_stops_at_its_surface() {
        // The shoulder swept over its range with the elbow half bent drives the arm into the floor in
        // front of the body (and through the body on the way).
        let (tree, morph, raw) = sweep("arm_sh1", &[("arm_el0", 0.5)]);
        let cfg = UfrConfig::for_character(&tree, &morph);
        let before = ufr(&tree, &morph, &raw, 30.0, &cfg).summary().rates;
        assert!(before.penetration > 0.1, "the sweep goes into the ground: {before:?}");
        let guard = CollisionGuard::new(&tree, &morph);
        let mut state = GuardState::default();
        let mut out = raw.clone();
        for p in &mut out {
            guard.apply(&tree, &mut state, p);
        }
        let after = ufr(&tree, &morph, &out, 30.0, &cfg).summary().rates;
        assert_eq!((after.penetration, after.self_collision), (0.0, 0.0));
        assert!(assert_stopped_at_the_surface(&tree, &guard, &raw, &out) > 10);
        // The body stays where it was: the arm, not the root, was moved.
        assert!(raw.iter().zip(&out).all(|(a, b)| a.root == b.root));
    }

    #[test]
    fn an_arm_swung_through_the_body_stops_at_its_surface() {
        // The arm's shoulder swept across its whole range and back: somewhere it passes the body.
        let (tree, morph, raw) = sweep("arm_sh1", &[]);
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
        // Frames that were free are untouched; roots are not moved for a self-collision.
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
        assert!(assert_stopped_at_the_surface(&tree, &guard, &raw, &out) > 10);
    }

    #[test]
    fn a_root_sunk_into_the_ground_is_lifted_out() {
        let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../assets/characters/spot.urdf");
        let (tree, morph) = load_character(&path).unwrap();
        let guard = CollisionGuard::new(&tree, &morph);
        let mut state = GuardState::default();
        let standing = tree.standing_pose();
        let mut first = standing.clone();
        guard.apply(&tree, &mut state, &mut first);
        assert_eq!(first, standing, "a free pose is left alone");
        // The whole body 5 cm down: no joint motion can fix that, the root is lifted back.
        let mut sunk = standing.clone();
        sunk.root.translation.z -= 0.05;
        guard.apply(&tree, &mut state, &mut sunk);
        let mut scratch = PoseScratch::default();
        assert!(!guard.collides(&tree, &sunk, &mut scratch));
        assert!((sunk.root.translation.z - standing.root.translation.z).abs() < 0.01, "{}", sunk.root.translation.z);
        assert_eq!(state.corrected, 1);
    }
}
