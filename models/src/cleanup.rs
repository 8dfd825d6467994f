//! The cleanup every generated pose passes through before anyone sees it: the standing hold
//! ([`crate::standing`]) and heading steering ([`crate::heading`]), on the state before its root is
//! integrated, so they run in the retargeters' state decoder; then foot locking ([`crate::foot_lock`]), then the collision guard
//! ([`crate::collision_guard`]), which has the last word so that no output pose collides with itself
//! or the ground. All are causal, so the offline retargeter and a live stream give the same poses; all
//! can be switched off to see the networks' raw output.

use serde::{Deserialize, Serialize};

use crate::collision_guard::{CollisionGuard, GuardState};
use crate::foot_lock::{FootLock, FootLockConfig, FootLockScratch, FootLockState};
use crate::heading::HeadingSteering;
use crate::standing::StandingHold;
use crate::kinematics::{CharacterPose, KinematicTree};
use crate::morphology::Morphology;

/// Which cleanups run (all by default).
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
}

impl Default for Cleanup {
    fn default() -> Self {
        Cleanup {
            collision_guard: true,
            foot_lock: Some(FootLockConfig::default()),
            heading: Some(HeadingSteering::default()),
            standing: Some(StandingHold::default()),
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
    };
}

/// The cleanups set up for one character.
#[derive(Clone, Debug)]
pub struct CleanupPass {
    guard: Option<CollisionGuard>,
    lock: Option<FootLock>,
}

/// The memory of a cleanup pass for one character being driven.
#[derive(Clone, Debug, Default)]
pub struct CleanupState {
    guard: GuardState,
    lock: Option<FootLockState>,
    scratch: FootLockScratch,
}

impl CleanupState {
    /// Frames the collision guard has changed so far.
    pub fn guarded_frames(&self) -> usize {
        self.guard.corrected
    }
}

impl CleanupPass {
    /// The cleanups of `cleanup` for a character at `fps` frames per second.
    pub fn new(tree: &KinematicTree, morph: &Morphology, fps: f32, cleanup: &Cleanup) -> CleanupPass {
        CleanupPass {
            guard: cleanup.collision_guard.then(|| CollisionGuard::new(tree, morph)),
            lock: cleanup.foot_lock.map(|c| FootLock::new(tree, morph, fps, c)),
        }
    }

    /// Whether it changes anything at all.
    pub fn is_active(&self) -> bool {
        self.guard.is_some() || self.lock.is_some()
    }

    /// A fresh state (nothing planted, no previous pose).
    pub fn start(&self) -> CleanupState {
        CleanupState {
            guard: GuardState::default(),
            lock: self.lock.as_ref().map(FootLock::start),
            scratch: FootLockScratch::default(),
        }
    }

    /// Cleans up one frame in place, advancing `state`.
    pub fn apply(&self, tree: &KinematicTree, state: &mut CleanupState, pose: &mut CharacterPose) {
        if let (Some(l), Some(s)) = (&self.lock, &mut state.lock) {
            l.apply(tree, s, pose, &mut state.scratch);
        }
        if let Some(g) = &self.guard {
            g.apply(tree, &mut state.guard, pose);
        }
    }
}
