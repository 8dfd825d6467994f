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
//! planted by foot locking), and when it does not, only the legs that move a body in the collision are
//! moved (moving every leg back while the root goes on drags the planted feet of the others along the
//! ground: all of Spot's sliding frames came from that); wheels keep their angles. When the root itself came down into the ground,
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
    /// Per foot: the DoFs on its path from the root, and per link whether they move it.
    legs: Vec<(Vec<usize>, Vec<bool>)>,
    /// DoFs tried when those do not suffice: all but wheels.
    all: Vec<usize>,
    /// Joint positions of the standing pose, where arms go when the last output's cannot clear the
    /// ground.
    standing: Vec<f32>,
    /// The UFR's contact band (m): a penetration no deeper is undone by lifting the root.
    contact_height: f32,
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
        let config = UfrConfig::for_character(tree, morph);
        let checks = PoseChecks::new(tree, morph, &config);
        let dof_of = |l: usize| tree.links[l].joint.as_ref().and_then(|j| j.dof);
        let wheels = morph.wheel_dofs(tree);
        // Every DoF on a foot's path from the root, a spine's included: moving any of them moves a
        // foot the foot lock may hold planted, so they are the last resort.
        let per_leg: Vec<(Vec<usize>, Vec<bool>)> = morph
            .feet
            .iter()
            .map(|&f| {
                let dofs: Vec<usize> = Chain::new(tree, morph, f).active_dofs().filter(|d| !wheels.contains(d)).collect();
                let moves = (0..tree.links.len())
                    .map(|l| {
                        let mut at = Some(l);
                        while let Some(k) = at {
                            if dof_of(k).is_some_and(|d| dofs.contains(&d)) {
                                return true;
                            }
                            at = tree.links[k].parent;
                        }
                        false
                    })
                    .collect();
                (dofs, moves)
            })
            .collect();
        let legs: Vec<usize> = per_leg.iter().flat_map(|(d, _)| d.iter().copied()).collect();
        let all: Vec<usize> = (0..tree.dof()).filter(|d| !wheels.contains(d)).collect();
        CollisionGuard {
            checks,
            morph: morph.clone(),
            upper: all.iter().copied().filter(|d| !legs.contains(d)).collect(),
            legs: per_leg,
            all,
            standing: tree.standing_pose().q,
            contact_height: config.contact_height,
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

    /// The DoFs of `upper` and of the legs that move a link [`PoseChecks::offending_links`] names in
    /// the placed pose (with the ground's when `ground`).
    fn upper_and_involved_legs(&self, scratch: &PoseScratch, ground: bool) -> Vec<usize> {
        let mut involved = vec![false; self.legs.len()];
        self.checks.offending_links(&self.morph, scratch, ground, |l| {
            for (i, (_, moves)) in self.legs.iter().enumerate() {
                involved[i] |= moves[l];
            }
        });
        let mut dofs = self.upper.clone();
        for ((leg, _), _) in self.legs.iter().zip(&involved).filter(|(_, i)| **i) {
            dofs.extend(leg.iter().filter(|d| !dofs.contains(d)).copied().collect::<Vec<_>>());
        }
        dofs
    }

    /// Whether `pose` collides with itself, or reaches below the ground deeper than the contact band
    /// (what lifting the root out would leave planted feet above the ground).
    fn too_deep_for_the_root(&self, tree: &KinematicTree, pose: &CharacterPose, scratch: &mut PoseScratch) -> bool {
        self.self_collides(tree, pose, scratch) || self.checks.depth_below_ground(&self.morph, scratch) > self.contact_height
    }

    /// Guards one frame in place, advancing `state`:
    /// 1. a self-collision is undone by moving joints back towards the last output: the legs' only
    ///    when the others do not suffice, first only the legs that move a body in the collision, then
    ///    all (self-collision does not depend on the root, so this always succeeds once there is a
    ///    last output);
    /// 2. a ground penetration is undone the same way, towards the last output, else towards the
    ///    standing pose — with the arms and other non-leg joints first, then with the legs in the
    ///    penetration, then with all legs — and when nothing is (the root itself came down) by lifting
    ///    the root out of the ground.
    pub fn apply(&self, tree: &KinematicTree, state: &mut GuardState, pose: &mut CharacterPose) {
        let scratch = &mut state.scratch;
        if !self.collides(tree, pose, scratch) {
            state.last_free = Some(pose.q.clone());
            return;
        }
        state.corrected += 1;
        if let Some(prev) = &state.last_free {
            if self.self_collides(tree, pose, scratch) {
                let involved = self.upper_and_involved_legs(scratch, false);
                for dofs in [&self.upper, &involved, &self.all] {
                    if self.move_back(tree, pose, prev, dofs, scratch, &Self::self_collides) {
                        break;
                    }
                }
            }
            // Towards the last output, else towards the standing pose: an arm reaching into the ground
            // of a body that came down is pulled up rather than the whole body lifted.
            // Legs only when the rest cannot do it (a leg the network pushed through the floor).
            // The legs only for a penetration deeper than the contact band: a shallower one is lifted
            // out with the root below, leaving planted feet at most that far above their anchors
            // rather than dragging them.
            if self.collides(tree, pose, scratch) {
                let involved = self.upper_and_involved_legs(scratch, true);
                for (stage, dofs) in [&self.upper, &involved, &self.all].into_iter().enumerate() {
                    if stage > 0 && !self.too_deep_for_the_root(tree, pose, scratch) {
                        break;
                    }
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

    /// The bundled Spot.
    fn spot() -> (KinematicTree, Morphology) {
        load_character(&Path::new(env!("CARGO_MANIFEST_DIR")).join("../assets/characters/spot.urdf")).unwrap()
    }

    /// Spot, and its arm's DoF `name` swept over its range and back in 120 frames from the standing pose,
    /// with the DoFs of `fixed` held at the given fraction of their ranges.
    fn sweep(name: &str, fixed: &[(&str, f32)]) -> (KinematicTree, Morphology, Vec<CharacterPose>) {
        let (tree, morph) = spot();
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
        let (tree, morph) = spot();
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

    /// Spot, standing, then moved 5 cm forward with `dof` at `value` of its range and every other leg
    /// joint 0.03 rad on (the legs move, as a network's do): the guard's output and the raw pose.
    fn step_with(tree: &KinematicTree, guard: &CollisionGuard, dof: &str, value: f32) -> (CharacterPose, CharacterPose) {
        let mut state = GuardState::default();
        let mut first = tree.standing_pose();
        guard.apply(tree, &mut state, &mut first);
        let d = tree.dof_names().iter().position(|n| *n == dof).unwrap();
        let mut raw = tree.standing_pose();
        raw.root.translation.x += 0.05;
        for (k, name) in tree.dof_names().iter().enumerate() {
            if k != d && ["fl_", "fr_", "rl_", "rr_"].iter().any(|leg| name.starts_with(leg)) {
                raw.q[k] += 0.03;
            }
        }
        let l = tree.limits(d).unwrap();
        raw.q[d] = l.lower + value * (l.upper - l.lower);
        let mut out = raw.clone();
        guard.apply(tree, &mut state, &mut out);
        (raw, out)
    }

    /// A hind leg swung into the body is moved back alone: the other legs, whose feet foot locking may
    /// hold planted while the root moves on, keep the network's joint values (moving them back too
    /// made every one of Spot's held-out sliding frames).
    #[test]
    fn a_leg_in_a_collision_is_moved_back_alone() {
        let (tree, morph) = spot();
        let guard = CollisionGuard::new(&tree, &morph);
        let mut scratch = PoseScratch::default();
        // The first abduction of the hind right hip (over its range) that puts its leg into the body.
        let value = (0..=100)
            .map(|k| k as f32 / 100.0)
            .find(|&v| {
                let (raw, _) = step_with(&tree, &guard, "rr_hip_x", v);
                guard.self_collides(&tree, &raw, &mut scratch)
            })
            .expect("the hind right leg reaches the body");
        let (raw, out) = step_with(&tree, &guard, "rr_hip_x", value);
        assert!(!guard.collides(&tree, &out, &mut scratch), "the output is free");
        let names = tree.dof_names();
        for (d, name) in names.iter().enumerate() {
            if name.starts_with("rr_") {
                continue;
            }
            assert_eq!(out.q[d], raw.q[d], "{name} moved");
        }
        assert_ne!(out.q, raw.q, "the hind right leg moved back");
        // (The root may be lifted out of a shallow penetration of the moved legs, never moved on the
        // ground.)
        assert_eq!((out.root.rotation, out.root.translation.x, out.root.translation.y), (raw.root.rotation, raw.root.translation.x, raw.root.translation.y));
    }

    /// A penetration no deeper than the contact band is undone by lifting the root, leaving the legs
    /// (and so planted feet) as they are; a deeper one moves the leg in it back.
    #[test]
    fn a_shallow_penetration_lifts_the_root_and_a_deep_one_moves_the_leg() {
        let (tree, morph) = spot();
        let guard = CollisionGuard::new(&tree, &morph);
        let mut scratch = PoseScratch::default();
        let standing = tree.standing_pose();
        // The front left knee straightened or bent over its range: the foot goes below the ground.
        let depth = |pose: &CharacterPose, scratch: &mut PoseScratch| {
            guard.checks.place(&tree, pose, scratch);
            guard.checks.depth_below_ground(&morph, scratch)
        };
        let mut found = (None, None);
        for k in 0..=200 {
            let (raw, _) = step_with(&tree, &guard, "fl_knee", k as f32 / 200.0);
            let d = depth(&raw, &mut scratch);
            let pen = guard.collides(&tree, &raw, &mut scratch) && !guard.self_collides(&tree, &raw, &mut scratch);
            if pen && d < 0.8 * guard.contact_height && found.0.is_none() {
                found.0 = Some(k as f32 / 200.0);
            }
            if pen && d > 2.0 * guard.contact_height && found.1.is_none() {
                found.1 = Some(k as f32 / 200.0);
            }
        }
        let (shallow, deep) = (found.0.expect("a shallow penetration"), found.1.expect("a deep penetration"));
        let (raw, out) = step_with(&tree, &guard, "fl_knee", shallow);
        assert!(!guard.collides(&tree, &out, &mut scratch));
        assert_eq!(out.q, raw.q, "the joints are the network's");
        let lift = out.root.translation.z - raw.root.translation.z;
        assert!(lift > 0.0 && lift <= guard.contact_height, "lifted {lift} m");
        let (raw, out) = step_with(&tree, &guard, "fl_knee", deep);
        assert!(!guard.collides(&tree, &out, &mut scratch));
        assert!((out.root.translation.z - standing.root.translation.z).abs() < 1e-6, "the root stays");
        let knee = tree.dof_names().iter().position(|n| *n == "fl_knee").unwrap();
        assert_ne!(out.q[knee], raw.q[knee], "the knee moved back");
    }
}
