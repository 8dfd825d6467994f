//! From the networks' normalised states to poses, the same for both inference paths (the pure-Rust
//! [`super::Retargeter`] and, with `learn`, libtorch's): the standing start state, the rollout loop,
//! and `StateDecoder`, which integrates the root, clamps joints into their limits, rolls the wheels
//! from the base motion and applies the cleanup.

use std::path::Path;

use nalgebra::{Isometry3, Vector2};

use crate::character_state::{CharacterLayout, StateScratch, character_state, character_state_into, decode_pose};
use crate::checkpoint::{CharacterInfo, LearnError, Normaliser, StateBounds};
use crate::cleanup::{Cleanup, CleanupPass, CleanupState};
use crate::controller::wheels;
use crate::features::EndEffectorMapping;
use crate::human::HumanClip;
use crate::human_set::{HumanRow, PROJECT_FPS};
use crate::kinematics::{CharacterPose, KinematicTree};
use crate::morphology::Morphology;

/// Largest ratio between a character's body length and the one its checkpoint was trained with
/// (`check_character`).
pub const BODY_LENGTH_TOLERANCE: f32 = 1.25;

/// A retargeted motion: one state and one pose per human frame.
#[derive(Clone, Debug, PartialEq)]
pub struct RetargetedMotion {
    /// Frame rate (the project's, [`PROJECT_FPS`]).
    pub fps: f32,
    /// Denormalised x^r per frame (joint entries as in `poses`).
    pub states: Vec<Vec<f32>>,
    /// The character's pose per frame, starting from the standing pose at the origin facing +x.
    pub poses: Vec<CharacterPose>,
}

/// One frame of a character stream (`Retargeter::step` of either inference path).
#[derive(Clone, Debug, PartialEq)]
pub struct RetargetedFrame {
    /// Denormalised x^r (joint and end-effector entries as in `pose`).
    pub state: Vec<f32>,
    /// The character's pose.
    pub pose: CharacterPose,
}

/// The x^h rows of a human clip at [`PROJECT_FPS`] (resampled if it has another rate).
pub(crate) fn clip_rows(clip: &HumanClip) -> Vec<HumanRow> {
    let states = if (clip.fps - PROJECT_FPS).abs() > 1e-3 {
        clip.resampled(PROJECT_FPS).states()
    } else {
        clip.states()
    };
    states.into_iter().map(|s| s.0).collect()
}

/// Fails with [`LearnError::WrongCharacter`] unless `tree` and `morph` are `character`, the checkpoint
/// in `dir`'s. Also fails when the character's body length differs from `trained_body_length`, the one
/// recorded in training, by more than [`BODY_LENGTH_TOLERANCE`]: the same joints at another scale (a
/// URDF scaled ×10) are another character to the prior, whose states are in metres.
pub(crate) fn check_character(
    dir: &Path,
    character: &CharacterInfo,
    trained_body_length: f32,
    tree: &KinematicTree,
    morph: &Morphology,
) -> Result<(), LearnError> {
    character.check(dir, &CharacterInfo::of_character(tree, morph))?;
    let recorded = trained_body_length;
    let measured = crate::features::character_body_length(tree, morph);
    let ratio = measured / recorded;
    if !(ratio.is_finite() && (1.0 / BODY_LENGTH_TOLERANCE..=BODY_LENGTH_TOLERANCE).contains(&ratio)) {
        return Err(LearnError::WrongCharacter {
            path: dir.join(crate::checkpoint::ace::ACE_FILE),
            problem: format!(
                "it was trained for `{}` with a body length of {recorded:.3} m; this `{}` measures {measured:.3} m \
                 (×{ratio:.2}, more than ×{BODY_LENGTH_TOLERANCE} apart): the same joints at another size are \
                 another character to the prior; train a checkpoint for it",
                character.name, tree.name
            ),
        });
    }
    Ok(())
}

/// The normalised x^r of the character standing at rest (the standing pose, zero velocities), masked
/// as the prior's inputs are.
pub(crate) fn standing_state(stats: &Normaliser, mask: &[f32], tree: &KinematicTree, morph: &Morphology) -> Vec<f32> {
    let standing = tree.standing_pose();
    let x = character_state(tree, morph, &standing, &standing, 1.0 / PROJECT_FPS);
    x.iter()
        .zip(&stats.mean)
        .zip(&stats.std)
        .zip(mask)
        .map(|(((v, m), sd), k)| (v - m) / sd * k)
        .collect()
}

/// The root heights (m) the prior's dataset spans, when its bounds say: the bounds of the root-height
/// entry without their margin `bound_margin`, denormalised (`None` for a prior without finite bounds).
pub(crate) fn root_height_range(
    character: &CharacterInfo,
    stats: &Normaliser,
    bounds: &StateBounds,
    bound_margin: f64,
) -> Option<(f32, f32)> {
    let j = character.layout.root_height().start;
    let m = bound_margin as f32;
    let pad = (bounds.hi[j] - bounds.lo[j]) * m / (1.0 + 2.0 * m);
    let (lo, hi) = (bounds.lo[j] + pad, bounds.hi[j] - pad);
    let (mean, std) = (stats.mean[j], stats.std[j]);
    let (lo, hi) = (lo * std + mean, hi * std + mean);
    (lo.is_finite() && hi.is_finite() && lo <= hi).then_some((lo, hi))
}

/// The rollout loop of both inference paths (and of the NKN baseline): `next(t, prev)` gives the
/// normalised state of frame `t` from the normalised previous one (the first is `start`, the standing
/// state) with its denormalised row, and `decoder` turns each row into a pose; `human` holds the x^h
/// row each frame follows (empty when no person drives the frames, as with random latents).
pub(crate) fn roll_out<S>(
    tree: &KinematicTree,
    morph: &Morphology,
    start: S,
    mut decoder: StateDecoder,
    frames: usize,
    human: &[HumanRow],
    next: &mut dyn FnMut(usize, &S) -> Result<(S, Vec<f32>), LearnError>,
) -> Result<RetargetedMotion, LearnError> {
    let mut prev = start;
    let (mut states, mut poses) = (Vec::with_capacity(frames), Vec::with_capacity(frames));
    for t in 0..frames {
        let (cur, mut state) = next(t, &prev)?;
        prev = cur;
        poses.push(decoder.decode(tree, morph, &mut state, human.get(t).map(|r| &r[..])));
        states.push(state);
    }
    Ok(RetargetedMotion {
        fps: PROJECT_FPS,
        states,
        poses,
    })
}

/// Turns a character's successive denormalised states into poses (see the module docs): the
/// integrated root (held while the person stands and steered onto the person's heading when the
/// cleanup says), joint limits, rolled wheels, the cleanup and its memory.
#[derive(Debug)]
pub(crate) struct StateDecoder {
    layout: CharacterLayout,
    wheels: Vec<crate::controller::Wheel>,
    root: Isometry3<f32>,
    wheel_q: Vec<f32>,
    cleanup: CleanupPass,
    cleanup_state: CleanupState,
    root_height_range: Option<(f32, f32)>,
    prev_pose: CharacterPose,
    recomputed: Vec<f32>,
    scratch: StateScratch,
}

impl StateDecoder {
    pub(crate) fn new(
        tree: &KinematicTree,
        morph: &Morphology,
        cleanup_config: &Cleanup,
        mapping: &EndEffectorMapping,
        root_height_range: Option<(f32, f32)>,
    ) -> StateDecoder {
        let layout = CharacterLayout::new(tree, morph);
        let standing = tree.standing_pose();
        let cleanup = CleanupPass::new(tree, morph, PROJECT_FPS, cleanup_config, mapping);
        StateDecoder {
            wheels: wheels::find(tree, morph, &standing),
            root: standing.root,
            wheel_q: standing.q.clone(),
            cleanup_state: cleanup.start(&standing.root),
            cleanup,
            root_height_range,
            recomputed: vec![0.0; layout.dim()],
            layout,
            prev_pose: standing,
            scratch: StateScratch::default(),
        }
    }

    /// The pose of the next state, retargeted from the x^h row `human` (`None` when no person drives
    /// it); `state` is updated to carry the pose's joints (and, after a cleanup, its end effectors and
    /// the heading steering's turn).
    pub(crate) fn decode(&mut self, tree: &KinematicTree, morph: &Morphology, state: &mut [f32], human: Option<&[f32]>) -> CharacterPose {
        let layout = &self.layout;
        let dt = 1.0 / PROJECT_FPS;
        self.cleanup.adjust_state(&self.cleanup_state, layout, state, &self.prev_pose.q, human);
        if let Some((lo, hi)) = self.root_height_range.filter(|_| self.cleanup.changes_poses()) {
            // The prior's clamp leaves a margin beyond the data; a low body can sink into the
            // ground inside it.
            let h = &mut state[layout.root_height()][0];
            *h = h.clamp(lo, hi);
        }
        let mut pose = decode_pose(layout, &self.root, state);
        tree.clamp(&mut pose.q);
        let v = &state[layout.root_linear_velocity()];
        let wz = state[layout.root_angular_velocity()][2];
        wheels::roll(&self.wheels, &mut self.wheel_q, Vector2::new(v[0], v[1]), wz, dt);
        for w in &self.wheels {
            pose.q[w.dof] = self.wheel_q[w.dof];
        }
        if self.cleanup.changes_poses() {
            self.cleanup.apply(tree, &mut self.cleanup_state, &mut pose);
            // The end-effector entries follow the cleaned-up joints.
            character_state_into(tree, morph, &self.prev_pose, &pose, dt, &mut self.scratch, &mut self.recomputed);
            for r in [layout.ee_positions(), layout.ee_velocities()] {
                state[r.clone()].copy_from_slice(&self.recomputed[r]);
            }
        }
        state[layout.joint_positions()].copy_from_slice(&pose.q);
        self.cleanup.observe(&mut self.cleanup_state, &pose.root, human);
        self.root = pose.root;
        self.prev_pose = pose.clone();
        pose
    }
}

/// Fails unless a batched step has one human state per character stream (both retargeters' `step`).
pub(crate) fn check_batch(streams: usize, rows: usize) -> Result<(), LearnError> {
    if streams != rows {
        return Err(LearnError::Data(format!("{rows} human states for {streams} characters: one per character")));
    }
    Ok(())
}
