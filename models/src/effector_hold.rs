//! End-effector hold: the cleanup step that keeps a character's arms (and head) still while the
//! person's matching hand (or head) rests.
//!
//! The networks move a character's arms together: where a person waves one hand and rests the other,
//! the crab's claw mapped to the resting hand still moved a median 0.10–0.12 body lengths over the
//! held-out clips (docs/following.md, "Resting hands"). For each manipulator and the head that the
//! correspondence maps to a human end effector, the hold reads that end effector's speed relative to
//! the pelvis (x^h's heading-frame positions, frame to frame), smoothed over `seconds`, and keeps a
//! share of the networks' joint motion, as the standing hold ([`crate::standing`]) does for the root:
//! 0 at and below `still`, 1 at and above `moving`, linear between. Joint q then moves from its shown
//! value by that share of the networks' step, so a held arm stays where it was and takes up the
//! networks' motion again as the hand moves off.
//!
//! The joints held are the end effector's chain up to the first joint that also carries a foot: legs,
//! and the trunk under them, stay the networks' and the foot lock's. A joint on two held chains moves
//! by the larger share. Like the standing hold, it holds from the first frame whose speed is known
//! (the second): a character whose person stands with a hand at rest keeps that arm where it stands.
//! Like the other cleanups it is causal.

use serde::{Deserialize, Serialize};

use crate::character_state::CharacterLayout;
use crate::features::EndEffectorMapping;
use crate::human::layout as human_layout;
use crate::human::skeleton::EndEffector;
use crate::kinematics::KinematicTree;
use crate::morphology::Morphology;
use crate::standing::{ramp, smoothing};

/// When the cleanup holds a character's arms and head while the person's matching end effector rests.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct EffectorHold {
    /// The person's smoothed end-effector speed relative to the pelvis (m/s) at and below which the
    /// chain holds still.
    pub still: f32,
    /// The speed (m/s) at and above which the chain moves as the networks say.
    pub moving: f32,
    /// Time constant (s) of the smoothing of the person's speed.
    pub seconds: f32,
}

impl Default for EffectorHold {
    fn default() -> Self {
        EffectorHold { still: 0.05, moving: 0.2, seconds: 0.25 }
    }
}

/// The chains one character's hold acts on: per held end effector, the human end effector it
/// follows and the DoFs that move it alone.
#[derive(Clone, Debug, PartialEq)]
pub struct HeldChains {
    chains: Vec<(EndEffector, Vec<usize>)>,
    /// Each held DoF with the chains it is on (indices into `chains`).
    dofs: Vec<(usize, Vec<usize>)>,
}

impl HeldChains {
    /// The chains of `tree`'s manipulators and head that `mapping` (one entry per end effector, in
    /// [`Morphology::end_effectors`] order) maps to a human end effector.
    pub fn new(tree: &KinematicTree, morph: &Morphology, mapping: &EndEffectorMapping) -> HeldChains {
        let dofs_above = |mut link: usize| {
            let mut dofs = Vec::new();
            loop {
                let l = &tree.links[link];
                if let Some(d) = l.joint.as_ref().and_then(|j| j.dof) {
                    dofs.push(d);
                }
                match l.parent {
                    Some(p) => link = p,
                    None => return dofs,
                }
            }
        };
        let under_feet: Vec<usize> = morph.feet.iter().flat_map(|&f| dofs_above(f)).collect();
        let chains = morph
            .end_effectors()
            .into_iter()
            .zip(&mapping.human)
            .skip(morph.feet.len())
            .filter_map(|(link, human)| {
                let chain: Vec<usize> = dofs_above(link).into_iter().take_while(|d| !under_feet.contains(d)).collect();
                human.filter(|_| !chain.is_empty()).map(|h| (h, chain))
            })
            .collect();
        HeldChains::from_chains(chains)
    }

    /// The chains `chains` (human end effector and DoFs of each), with each DoF's chains listed.
    fn from_chains(chains: Vec<(EndEffector, Vec<usize>)>) -> HeldChains {
        let mut dofs: Vec<(usize, Vec<usize>)> = Vec::new();
        for (c, (_, chain)) in chains.iter().enumerate() {
            for &d in chain {
                match dofs.iter_mut().find(|(e, _)| *e == d) {
                    Some((_, on)) => on.push(c),
                    None => dofs.push((d, vec![c])),
                }
            }
        }
        HeldChains { chains, dofs }
    }

    /// Per held end effector, the human end effector it follows and its DoFs (end effector first).
    pub fn chains(&self) -> &[(EndEffector, Vec<usize>)] {
        &self.chains
    }

    /// Whether there is nothing to hold (no mapped manipulator or head with joints of its own).
    pub fn is_empty(&self) -> bool {
        self.chains.is_empty()
    }
}

/// One character's memory of the person's end effectors: per held chain, the last position seen and
/// the smoothed speed (`None` until two positions are seen).
#[derive(Clone, Debug, PartialEq)]
pub struct EffectorHoldState {
    last: Vec<Option<[f32; 3]>>,
    speed: Vec<Option<f32>>,
}

impl EffectorHoldState {
    /// A stream's start: nothing seen (until a speed is known, the networks move the arms freely).
    pub fn new(chains: &HeldChains) -> EffectorHoldState {
        let n = chains.chains.len();
        EffectorHoldState { last: vec![None; n], speed: vec![None; n] }
    }

    /// Moves the held joints of the next frame's denormalised state `state` from the shown joints
    /// `shown` (the previous frame's pose) by their share of the networks' step.
    pub fn hold(&self, hold: &EffectorHold, chains: &HeldChains, layout: &CharacterLayout, state: &mut [f32], shown: &[f32]) {
        let share = |c: usize| self.speed[c].map_or(1.0, |v| ramp(hold.still, hold.moving, v));
        let q = &mut state[layout.joint_positions()];
        for (d, on) in &chains.dofs {
            let s = on.iter().map(|&c| share(c)).fold(0.0, f32::max);
            if s < 1.0 {
                q[*d] = shown[*d] + s * (q[*d] - shown[*d]);
            }
        }
    }

    /// Records a frame of the person, x^h row `x_h`, at `fps` frames per second.
    pub fn observe(&mut self, hold: &EffectorHold, chains: &HeldChains, x_h: &[f32], fps: f32) {
        let a = smoothing(hold.seconds, fps);
        for (((end, _), last), speed) in chains.chains.iter().zip(&mut self.last).zip(&mut self.speed) {
            let at = human_layout::EE_POSITIONS.start + 3 * *end as usize;
            let now: [f32; 3] = std::array::from_fn(|i| x_h[at + i]);
            if let Some(before) = last.replace(now) {
                let v = (0..3).map(|i| (now[i] - before[i]).powi(2)).sum::<f32>().sqrt() * fps;
                *speed = Some(speed.map_or(v, |s| s + a * (v - s)));
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use std::path::{Path, PathBuf};

    use super::*;
    use crate::cleanup::Cleanup;
    use crate::morphology::load_character;
    use crate::runtime::Retargeter;

    fn assets() -> PathBuf {
        Path::new(env!("CARGO_MANIFEST_DIR")).join("../assets")
    }

    fn character(file: &str) -> (KinematicTree, Morphology) {
        load_character(&assets().join(file)).unwrap()
    }

    /// The DoF names of each held chain, with the human end effector it follows.
    fn held(file: &str) -> Vec<(EndEffector, Vec<String>)> {
        let (tree, morph) = character(file);
        let chains = HeldChains::new(&tree, &morph, &EndEffectorMapping::by_side(&tree, &morph));
        let names = tree.dof_names();
        chains.chains().iter().map(|(e, dofs)| (*e, dofs.iter().map(|&d| names[d].to_string()).collect())).collect()
    }

    #[test]
    fn the_held_chains_are_the_arms_and_the_neck_never_a_leg() {
        let names = |v: &[&str]| v.iter().map(|s| s.to_string()).collect::<Vec<_>>();
        assert_eq!(
            held("characters/crab.urdf"),
            vec![
                (EndEffector::LeftHand, names(&["arm_l_elbow", "arm_l_pitch", "arm_l_yaw"])),
                (EndEffector::RightHand, names(&["arm_r_elbow", "arm_r_pitch", "arm_r_yaw"])),
            ]
        );
        let spot = held("characters/spot.urdf");
        assert_eq!(spot.len(), 1);
        assert_eq!(spot[0].0, EndEffector::RightHand);
        assert!(spot[0].1.len() >= 6 && spot[0].1.iter().all(|n| n.starts_with("arm_")), "{spot:?}");
        let stretch = held("characters/stretch.urdf");
        assert!(stretch[0].1.iter().any(|n| n == "joint_lift"), "{stretch:?}");
        // The hound's head: its neck, not the spine that carries the front legs.
        let (tree, morph) = character("creatures/hound.glb");
        let hound = HeldChains::new(&tree, &morph, &EndEffectorMapping::by_side(&tree, &morph));
        let (end, neck) = &hound.chains()[0];
        assert_eq!((*end, hound.chains().len()), (EndEffector::Head, 1));
        assert!(!neck.is_empty());
        for &foot in &morph.feet {
            let mut link = Some(foot);
            while let Some(l) = link {
                let dof = tree.links[l].joint.as_ref().and_then(|j| j.dof);
                assert!(dof.is_none_or(|d| !neck.contains(&d)), "the head's chain moves a leg: {}", tree.links[l].name);
                link = tree.links[l].parent;
            }
        }
        // An end effector mapped to nothing is not held.
        let (tree, morph) = character("characters/crab.urdf");
        let mut mapping = EndEffectorMapping::by_side(&tree, &morph);
        mapping.human[morph.feet.len()] = None;
        assert_eq!(HeldChains::new(&tree, &morph, &mapping).chains().len(), 1);
    }

    /// An x^h row with the left hand at `left` and the right hand at `right` (heading frame, m).
    fn person(left: [f32; 3], right: [f32; 3]) -> Vec<f32> {
        let mut x = vec![0.0; human_layout::DIM];
        for (e, p) in [(EndEffector::LeftHand, left), (EndEffector::RightHand, right)] {
            let at = human_layout::EE_POSITIONS.start + 3 * e as usize;
            x[at..at + 3].copy_from_slice(&p);
        }
        x
    }

    #[test]
    fn a_resting_hand_holds_its_arm_and_a_moving_hand_releases_it() {
        let layout = CharacterLayout { dof: 4, end_effectors: 0 };
        // Joint 1 is on both chains.
        let chains = HeldChains::from_chains(vec![(EndEffector::LeftHand, vec![0, 1]), (EndEffector::RightHand, vec![1, 2])]);
        let hold = EffectorHold::default();
        let fps = 30.0;
        let shown = [0.1, 0.2, 0.3, 0.4];
        // Values where `shown + 1·(network − shown)` is not `network` in f32: a free joint passes the
        // networks' value exactly.
        let network = || {
            let mut s = vec![0.0; layout.dim()];
            s[layout.joint_positions()].copy_from_slice(&[0.001, 0.003, 0.007, 0.8]);
            s
        };
        let joints = |memory: &EffectorHoldState| {
            let mut s = network();
            memory.hold(&hold, &chains, &layout, &mut s, &shown);
            s[layout.joint_positions()].to_vec()
        };
        let mut memory = EffectorHoldState::new(&chains);
        // Nothing seen, then one position (no speed yet): the networks move every joint.
        assert_eq!(joints(&memory), [0.001, 0.003, 0.007, 0.8]);
        memory.observe(&hold, &chains, &person([0.0; 3], [0.0; 3]), fps);
        assert_eq!(joints(&memory), [0.001, 0.003, 0.007, 0.8]);
        // Both hands rest: both chains hold, the joint on neither moves.
        memory.observe(&hold, &chains, &person([0.0; 3], [0.0; 3]), fps);
        assert_eq!(joints(&memory), [0.1, 0.2, 0.3, 0.8]);
        // The right hand moves off at 0.6 m/s (2 cm a frame): within a few frames (the smoothing) its
        // chain and the shared joint move freely, not at once; the left chain's own joint still holds.
        let mut z = 0.0;
        let released = (1..=30).find(|_| {
            z += 0.02;
            memory.observe(&hold, &chains, &person([0.0; 3], [0.0, 0.0, z]), fps);
            let q = joints(&memory);
            assert_eq!(q[0], 0.1, "the resting hand's arm moved");
            assert!((0.007..=0.3).contains(&q[2]), "a share of the step: {q:?}");
            q[2] == 0.007
        });
        // 1 − e^(−1/7.5) of the way each frame from 0 to 0.6 m/s passes 0.2 m/s on the fourth frame.
        assert_eq!(released, Some(4));
        assert_eq!(joints(&memory), [0.1, 0.003, 0.007, 0.8]);
        // Half way up the ramp the joint moves half the step.
        let mut half = EffectorHoldState::new(&chains);
        let speed = (hold.still + hold.moving) / 2.0;
        half.observe(&hold, &chains, &person([0.0; 3], [0.0; 3]), fps);
        half.observe(&hold, &chains, &person([speed / fps, 0.0, 0.0], [0.0; 3]), fps);
        let q = joints(&half);
        assert!((q[0] - 0.0505).abs() < 1e-5 && (q[1] - 0.1015).abs() < 1e-5 && q[2] == 0.3, "{q:?}");
    }

    #[test]
    fn a_character_with_nothing_to_hold_leaves_its_joints_and_states_alone() {
        use crate::cleanup::CleanupPass;
        let (tree, morph) = character("characters/crab.urdf");
        let only_hold = Cleanup { effector_hold: Some(EffectorHold::default()), ..Cleanup::NONE };
        let by_side = EndEffectorMapping::by_side(&tree, &morph);
        assert!(CleanupPass::new(&tree, &morph, 30.0, &only_hold, &by_side).changes_poses());
        // No end effector mapped: no chain, so the hold is off and the decoder neither clamps the root
        // height nor recomputes the end effectors for it.
        let unmapped = EndEffectorMapping::new(vec![None; by_side.human.len()]);
        assert!(HeldChains::new(&tree, &morph, &unmapped).is_empty());
        assert!(!CleanupPass::new(&tree, &morph, 30.0, &only_hold, &unmapped).changes_poses());
        assert!(!CleanupPass::new(&tree, &morph, 30.0, &Cleanup::NONE, &by_side).changes_poses());
    }

    #[test]
    fn the_crab_keeps_the_claw_of_the_resting_hand_still_on_the_bundled_wave() {
        let (tree, morph) = character("characters/crab.urdf");
        let mut r = Retargeter::load(&assets().join("checkpoints/crab")).unwrap();
        let clip = crate::test_data::bundled_clip("wave");
        let chains = HeldChains::new(&tree, &morph, &r.record().correspondence.mapping);
        // The person waves the right hand; the left hand rests.
        let (left, right) = (&chains.chains()[0].1, &chains.chains()[1].1);
        let range = |poses: &[crate::kinematics::CharacterPose], dofs: &[usize]| {
            dofs.iter()
                .map(|&d| {
                    let q = poses.iter().map(|p| p.q[d]);
                    q.clone().fold(f32::MIN, f32::max) - q.fold(f32::MAX, f32::min)
                })
                .fold(0.0, f32::max)
        };
        let held = r.retarget_clip(&tree, &morph, &clip).unwrap().poses;
        r.set_cleanup(Cleanup { effector_hold: None, ..Cleanup::default() });
        let free = r.retarget_clip(&tree, &morph, &clip).unwrap().poses;
        // After the first second the networks alone swing the left claw by 0.14 rad; held, it moves
        // half as much, where the left hand sways with the wave (0.07 rad; the checkpoint shipped until
        // 2026-12-06: 0.2 and 0.03).
        let (held_left, free_left) = (range(&held[30..], left), range(&free[30..], left));
        assert!(free_left > 0.1 && held_left < 0.5 * free_left, "left claw: {held_left} held, {free_left} free");
        // The waving hand's claw still moves as the networks say.
        assert!(range(&held, right) > 0.2 && range(&held, right) == range(&free, right), "right claw");
    }
}
