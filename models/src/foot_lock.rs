//! Foot locking: the contact cleanup applied to generated motion before anyone sees it.
//!
//! A kinematic motion prior predicts joint angles and root motion as separate numbers; nothing ties a
//! planted foot to the ground, so feet in contact drift by millimetres to centimetres a frame and dip
//! under the ground. Animation tools clean this up with foot locking, and so does ACE's output:
//!
//! - a foot **plants** when the network's foot point comes within [`FootLockConfig::plant_height`]
//!   of the foot's standing height and moves slower than [`FootLockConfig::plant_speed`]; it is
//!   anchored there, on the ground;
//! - while planted, the leg is solved by inverse kinematics ([`Chain::solve`]) so the foot point stays
//!   on the anchor;
//! - it **lifts** when the network's foot rises above [`FootLockConfig::lift_height`] or wanders more
//!   than [`FootLockConfig::max_drift`] from the anchor; the difference between the anchored and the
//!   network's foot then fades out over [`FootLockConfig::blend_frames`] frames;
//! - a foot that is not planted never skims the ground: it is kept at least
//!   [`FootLockConfig::swing_clearance`] above its standing height (a foot that comes down fast is held
//!   just above the ground until it slows enough to plant, and one that lifts off leaves the ground at
//!   once).
//!
//! Only leg joints move; the root and every other joint keep the network's values. The cleanup is
//! causal — each frame depends on the past only — so a live stream and an offline clip give the same
//! result frame for frame. Thresholds are fractions of the character's body length.

use nalgebra::{Point3, Vector3};
use serde::{Deserialize, Serialize};

use crate::controller::chain::{Chain, ChainScratch};
use crate::features::character_body_length;
use crate::kinematics::{CharacterPose, KinematicTree};
use crate::morphology::Morphology;

/// Thresholds of foot locking, in body lengths (L) and body lengths per second.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct FootLockConfig {
    /// A foot may plant within this height above its standing height (L).
    pub plant_height: f32,
    /// … and when its horizontal speed is below this (L/s).
    pub plant_speed: f32,
    /// A planted foot lifts when the network's foot rises above this (L).
    pub lift_height: f32,
    /// … or strays this far from its anchor horizontally (L).
    pub max_drift: f32,
    /// Frames over which a lifted foot returns to the network's.
    pub blend_frames: usize,
    /// The lowest a foot that is not planted may be (L).
    pub swing_clearance: f32,
}

impl Default for FootLockConfig {
    fn default() -> Self {
        FootLockConfig {
            plant_height: 0.04,
            plant_speed: 1.0,
            lift_height: 0.06,
            max_drift: 0.25,
            blend_frames: 4,
            swing_clearance: 0.04,
        }
    }
}

/// One leg: the chain from the root to the foot and the foot's standing height.
#[derive(Clone, Debug)]
struct Leg {
    chain: Chain,
    ground: f32,
}

/// Foot locking set up for one character (see the module docs).
#[derive(Clone, Debug)]
pub struct FootLock {
    legs: Vec<Leg>,
    config: FootLockConfig,
    body_length: f32,
    dt: f32,
}

/// Per-foot memory of a running cleanup: one per character being driven.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct FootLockState {
    feet: Vec<FootMemory>,
}

#[derive(Clone, Debug, Default, PartialEq)]
struct FootMemory {
    anchor: Option<Point3<f32>>,
    /// Anchored minus network foot at the last lift, fading out.
    offset: Vector3<f32>,
    blend_left: usize,
    prev: Option<Point3<f32>>,
}

impl FootLockState {
    /// Feet planted now.
    pub fn planted(&self) -> usize {
        self.feet.iter().filter(|f| f.anchor.is_some()).count()
    }
}

impl FootLock {
    /// Foot locking for a character's feet at `fps` frames per second (no legs: a no-op).
    pub fn new(tree: &KinematicTree, morph: &Morphology, fps: f32, config: FootLockConfig) -> FootLock {
        let standing = tree.standing_pose();
        let links = tree.forward_kinematics(&standing);
        let legs = morph
            .feet
            .iter()
            .map(|&f| Leg {
                chain: Chain::new(tree, morph, f),
                ground: morph.ee_point(f, &links).z.max(0.0),
            })
            .collect();
        FootLock {
            legs,
            config,
            body_length: character_body_length(tree, morph),
            dt: 1.0 / fps,
        }
    }

    /// A fresh state: no foot planted.
    pub fn start(&self) -> FootLockState {
        FootLockState {
            feet: vec![FootMemory::default(); self.legs.len()],
        }
    }

    /// Cleans up one frame in place (leg joints of `pose.q` only), advancing `state`.
    ///
    /// # Panics
    /// If `state` was not made by this lock's [`FootLock::start`].
    pub fn apply(&self, tree: &KinematicTree, state: &mut FootLockState, pose: &mut CharacterPose, scratch: &mut ChainScratch) {
        assert_eq!(state.feet.len(), self.legs.len(), "a state from another character");
        if self.legs.is_empty() {
            return;
        }
        let c = &self.config;
        let l = self.body_length;
        let links = tree.forward_kinematics(pose);
        let to_root = pose.root.inverse();
        for (leg, mem) in self.legs.iter().zip(&mut state.feet) {
            let tip = links[leg.chain.tip].transform_point(&Point3::from(leg.chain.tip_offset));
            let speed = mem.prev.map_or(0.0, |p| (tip - p).xy().norm() / self.dt);
            mem.prev = Some(tip);
            let height = tip.z - leg.ground;
            match mem.anchor {
                Some(a) if height > c.lift_height * l || (tip - a).xy().norm() > c.max_drift * l => {
                    mem.anchor = None;
                    mem.offset = a - tip;
                    mem.blend_left = c.blend_frames;
                }
                None if height < c.plant_height * l && speed < c.plant_speed * l => {
                    // Plant where the foot is now, after any fading offset, on the ground.
                    let fade = mem.blend_left as f32 / c.blend_frames.max(1) as f32;
                    let at = tip + mem.offset * fade;
                    mem.anchor = Some(Point3::new(at.x, at.y, leg.ground));
                    mem.blend_left = 0;
                }
                _ => {}
            }
            let mut target = match mem.anchor {
                Some(a) => a,
                None if mem.blend_left > 0 => {
                    let fade = mem.blend_left as f32 / (c.blend_frames + 1) as f32;
                    mem.blend_left -= 1;
                    tip + mem.offset * fade
                }
                None => tip,
            };
            let floor = if mem.anchor.is_some() { 0.0 } else { c.swing_clearance * l };
            target.z = target.z.max(leg.ground + floor);
            if (target - tip).norm() > 1e-4 {
                let local = to_root.transform_point(&target);
                leg.chain.solve(tree, &mut pose.q, &local, 2e-4, 30, scratch);
            }
        }
    }

    /// Cleans up a whole motion (one episode, in order) from a fresh state.
    pub fn apply_all(&self, tree: &KinematicTree, poses: &mut [CharacterPose]) {
        let mut state = self.start();
        let mut scratch = ChainScratch::default();
        for p in poses {
            self.apply(tree, &mut state, p, &mut scratch);
        }
    }
}

#[cfg(test)]
mod tests {
    use std::path::Path;

    use nalgebra::{Isometry3, Translation3};

    use super::*;
    use crate::metrics::{UfrConfig, ufr};
    use crate::morphology::load_character;

    fn spot() -> (KinematicTree, Morphology) {
        load_character(&Path::new(env!("CARGO_MANIFEST_DIR")).join("../assets/characters/spot.urdf")).unwrap()
    }

    /// Spot standing while its body sways sideways and its legs jitter: feet that should stay planted
    /// slide and dip.
    fn swaying(tree: &KinematicTree, frames: usize) -> Vec<CharacterPose> {
        let standing = tree.standing_pose();
        (0..frames)
            .map(|t| {
                let s = (t as f32 * 0.21).sin();
                let mut p = standing.clone();
                p.root = Isometry3::from_parts(
                    Translation3::new(0.0, 0.03 * s, standing.root.translation.z - 0.01 * s.abs()),
                    standing.root.rotation,
                );
                for (d, q) in p.q.iter_mut().enumerate() {
                    *q += 0.02 * ((t + 3 * d) as f32 * 0.37).sin();
                }
                p
            })
            .collect()
    }

    #[test]
    fn planted_feet_stop_sliding_and_stay_above_the_ground() {
        let (tree, morph) = spot();
        let raw = swaying(&tree, 300);
        let cfg = UfrConfig::for_character(&tree, &morph);
        let before = ufr(&tree, &morph, &raw, 30.0, &cfg).summary().rates;
        assert!(before.sliding > 0.5, "the raw motion slides: {before:?}");
        let mut clean = raw.clone();
        let lock = FootLock::new(&tree, &morph, 30.0, FootLockConfig::default());
        lock.apply_all(&tree, &mut clean);
        let after = ufr(&tree, &morph, &clean, 30.0, &cfg).summary().rates;
        assert!(after.sliding < 0.01 && after.penetration < 0.01, "{after:?}");
        // Only leg joints move, and the root never does.
        let arm: Vec<usize> = (12..tree.dof()).collect();
        for (a, b) in raw.iter().zip(&clean) {
            assert_eq!(a.root, b.root);
            for &d in &arm {
                assert_eq!(a.q[d], b.q[d]);
            }
        }
    }

    #[test]
    fn frame_by_frame_equals_the_whole_clip_and_lifted_feet_follow_the_network() {
        let (tree, morph) = spot();
        let lock = FootLock::new(&tree, &morph, 30.0, FootLockConfig::default());
        let raw = swaying(&tree, 120);
        let mut whole = raw.clone();
        lock.apply_all(&tree, &mut whole);
        let mut state = lock.start();
        let mut scratch = ChainScratch::default();
        for (t, p) in raw.iter().enumerate() {
            let mut p = p.clone();
            lock.apply(&tree, &mut state, &mut p, &mut scratch);
            assert_eq!(p, whole[t], "frame {t}");
        }
        assert_eq!(state.planted(), 4);

        // A foot raised high above the ground is left to the network.
        let mut high = tree.standing_pose();
        high.root.translation.z += 0.3;
        let before = high.clone();
        let mut state = lock.start();
        lock.apply(&tree, &mut state, &mut high, &mut scratch);
        assert_eq!(high, before);
        assert_eq!(state.planted(), 0);
    }
}
