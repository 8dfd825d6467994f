//! The cleanup every generated pose passes through before anyone sees it. Three steps act on the next
//! frame's state before its root is integrated and its pose read ([`CleanupPass::adjust_state`]), and
//! follow the person: heading steering ([`crate::heading`]), the standing hold ([`crate::standing`])
//! and the end-effector hold ([`crate::effector_hold`]).
//! Three act on the pose ([`CleanupPass::apply`]): foot locking ([`crate::foot_lock`]), the velocity
//! limit ([`crate::velocity_limit`]), which moves no joint faster than its file's limit, then the
//! collision guard ([`crate::collision_guard`]), which has the last word so that no output pose
//! collides with itself or the ground (it only moves joints back towards the previous output, so
//! they stay within their velocity limits). All are causal, so the offline retargeter and a live stream
//! give the same poses; all can be switched off to see the networks' raw output.

use nalgebra::Isometry3;
use serde::{Deserialize, Serialize};

use crate::character_state::CharacterLayout;
use crate::collision_guard::{CollisionGuard, GuardState};
use crate::effector_hold::{EffectorHold, EffectorHoldState, HeldChains};
use crate::features::EndEffectorMapping;
use crate::foot_lock::{FootLock, FootLockConfig, FootLockScratch, FootLockState};
use crate::heading::{HeadingSteering, SteeringState};
use crate::kinematics::{CharacterPose, KinematicTree};
use crate::morphology::Morphology;
use crate::standing::{HoldState, StandingHold};
use crate::velocity_limit::{VelocityLimit, VelocityLimitState};

/// Which cleanups run (all but the velocity limit by default).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct Cleanup {
    /// Move poses that collide with themselves or the ground back to the last free pose.
    pub collision_guard: bool,
    /// Foot locking and its thresholds (`None`: off).
    pub foot_lock: Option<FootLockConfig>,
    /// Steering the character's root back onto the person's heading (`None`: off).
    pub heading: Option<HeadingSteering>,
    /// Holding the character's root in place while the person stands (`None`: off).
    pub standing: Option<StandingHold>,
    /// Holding the character's arms and head while the person's matching end effector rests (`None`:
    /// off).
    pub effector_hold: Option<EffectorHold>,
    /// Moving no joint faster than its velocity limit (off by default: it costs the shipped
    /// Stretch half its following, [`crate::velocity_limit`]).
    pub velocity_limit: bool,
}

impl Default for Cleanup {
    fn default() -> Self {
        Cleanup {
            collision_guard: true,
            foot_lock: Some(FootLockConfig::default()),
            heading: Some(HeadingSteering::default()),
            standing: Some(StandingHold::default()),
            effector_hold: Some(EffectorHold::default()),
            velocity_limit: false,
        }
    }
}

impl Cleanup {
    /// No cleanup: the networks' raw output.
    pub const NONE: Cleanup = Cleanup {
        collision_guard: false,
        foot_lock: None,
        heading: None,
        standing: None,
        effector_hold: None,
        velocity_limit: false,
    };
}

/// The cleanups set up for one character.
#[derive(Clone, Debug)]
pub struct CleanupPass {
    fps: f32,
    steering: Option<HeadingSteering>,
    standing: Option<StandingHold>,
    effector_hold: Option<(EffectorHold, HeldChains)>,
    guard: Option<CollisionGuard>,
    lock: Option<FootLock>,
    velocity: Option<VelocityLimit>,
}

/// The memory of a cleanup pass for one character being driven.
#[derive(Clone, Debug)]
pub struct CleanupState {
    steering: Option<SteeringState>,
    hold: Option<HoldState>,
    effector_hold: Option<EffectorHoldState>,
    guard: GuardState,
    lock: Option<FootLockState>,
    scratch: FootLockScratch,
    velocity: VelocityLimitState,
}

impl CleanupPass {
    /// The cleanups of `cleanup` for a character at `fps` frames per second whose end effectors follow
    /// the human's as `mapping` says (the checkpoint's correspondence).
    pub fn new(tree: &KinematicTree, morph: &Morphology, fps: f32, cleanup: &Cleanup, mapping: &EndEffectorMapping) -> CleanupPass {
        CleanupPass {
            fps,
            steering: cleanup.heading,
            standing: cleanup.standing,
            effector_hold: cleanup
                .effector_hold
                .map(|h| (h, HeldChains::new(tree, morph, mapping)))
                .filter(|(_, chains)| !chains.is_empty()),
            guard: cleanup.collision_guard.then(|| CollisionGuard::new(tree, morph)),
            lock: cleanup.foot_lock.map(|c| FootLock::new(tree, morph, fps, c)),
            velocity: cleanup.velocity_limit.then(|| VelocityLimit::new(tree, morph, fps)).flatten(),
        }
    }

    /// Whether it changes the networks' joints: foot locking or the collision guard ([`Self::apply`]),
    /// or the end-effector hold. Only then is the root height clamped into the dataset's range, and
    /// are the state's end effectors recomputed from the cleaned-up joints.
    pub fn changes_poses(&self) -> bool {
        self.guard.is_some() || self.lock.is_some() || self.effector_hold.is_some() || self.velocity.is_some()
    }

    /// A fresh state for a stream starting from the root `start` (nothing planted, no previous pose,
    /// no turn yet).
    pub fn start(&self, start: &Isometry3<f32>) -> CleanupState {
        CleanupState {
            steering: self.steering.map(|_| SteeringState::new(start)),
            hold: self.standing.map(|_| HoldState::default()),
            effector_hold: self.effector_hold.as_ref().map(|(_, chains)| EffectorHoldState::new(chains)),
            guard: GuardState::default(),
            lock: self.lock.as_ref().map(FootLock::start),
            scratch: FootLockScratch::default(),
            velocity: VelocityLimitState::default(),
        }
    }

    /// Steers and holds the root, and holds the resting arms, of the next frame's denormalised state
    /// `x` (laid out as `layout`) before its root is integrated and its pose read; `shown` is the
    /// previous frame's joints as shown. Only when a person drives the frame (`human`, the frame's x^h
    /// row; `None` for random latents, which have nobody to follow).
    pub fn adjust_state(&self, state: &CleanupState, layout: &CharacterLayout, x: &mut [f32], shown: &[f32], human: Option<&[f32]>) {
        if human.is_none() {
            return;
        }
        if let (Some(config), Some(memory)) = (&self.steering, &state.steering) {
            memory.steer(config, layout, x, 1.0 / self.fps);
        }
        if let (Some(config), Some(memory)) = (&self.standing, &state.hold) {
            memory.hold(config, layout, x);
        }
        if let (Some((config, chains)), Some(memory)) = (&self.effector_hold, &state.effector_hold) {
            memory.hold(config, chains, layout, x, shown);
        }
    }

    /// Cleans up one frame's pose in place, advancing `state`.
    pub fn apply(&self, tree: &KinematicTree, state: &mut CleanupState, pose: &mut CharacterPose) {
        if let (Some(l), Some(s)) = (&self.lock, &mut state.lock) {
            l.apply(tree, s, pose, &mut state.scratch);
        }
        if let Some(v) = &self.velocity {
            v.apply(&state.velocity, pose);
        }
        if let Some(g) = &self.guard {
            g.apply(tree, &mut state.guard, pose);
        }
        if let Some(v) = &self.velocity {
            v.observe(&mut state.velocity, pose);
        }
    }

    /// Records the frame shown, with its root `root`, and the person's x^h row `human` it followed
    /// (nothing to record without one), for the next frame's [`Self::adjust_state`].
    pub fn observe(&self, state: &mut CleanupState, root: &Isometry3<f32>, human: Option<&[f32]>) {
        let Some(x_h) = human else { return };
        if let Some(memory) = &mut state.steering {
            memory.observe(root, x_h, self.fps);
        }
        if let (Some(config), Some(memory)) = (&self.standing, &mut state.hold) {
            memory.observe(config, x_h, self.fps);
        }
        if let (Some((config, chains)), Some(memory)) = (&self.effector_hold, &mut state.effector_hold) {
            memory.observe(config, chains, x_h, self.fps);
        }
    }
}
