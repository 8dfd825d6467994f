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
//! - it **lifts** when the network's foot rises above [`FootLockConfig::lift_height`] and has moved at
//!   least [`FootLockConfig::step_distance`] from the anchor, rises above
//!   [`FootLockConfig::raise_height`], or wanders more than [`FootLockConfig::max_drift`] from the
//!   anchor. A foot that only needs to move a little thus stays planted instead of popping. When the
//!   leg cannot hold it on its anchor (IK misses it by more than [`FootLockConfig::hold_tolerance`]:
//!   the body has moved beyond the leg's reach or joint limits), it steps at once, as the
//!   controllers' stance feet do, instead of being dragged along the ground: in that same frame it is
//!   lifted above the UFR's contact band and moved toward the network's foot as far as the leg needs
//!   to reach it (a swing foot the leg cannot reach is moved the same way). So does a planted leg
//!   that holding would cross into another body where the network's own pose keeps them clear (the
//!   body turned above close-set legs): held there, the collision guard that follows would pull it
//!   along the ground;
//! - a lifted foot **swings**: for at least the character's natural swing time at its current speed
//!   ([`crate::dynamic_similarity::swing_time`], never under [`FootLockConfig::min_swing_frames`]) it
//!   rises along `H·16 s²(1−s)²` (H = [`FootLockConfig::swing_height`] × the leg length, higher with
//!   speed as in the controllers, at least as high as the network's foot has risen, and high enough
//!   for its middle frame to clear the UFR's contact band), moves toward the network's foot along a
//!   minimum-jerk profile after the first fifth of the swing and before the last, and never between
//!   two frames within the contact band (a low arc's first and last frames are, on a small
//!   character), and comes down with zero vertical speed where the network's foot was when the descent began
//!   (the landing point is then frozen, so a low foot never slides). It never teleports.
//!   Before the descent it waits, hovering, while the network's foot is still high (at most another
//!   swing time; then it follows the network's foot); it plants where it lands;
//! - a foot that follows the network never skims the ground: it is kept at least
//!   [`FootLockConfig::swing_clearance`] above its standing height (a foot that comes down fast is held
//!   just above the ground until it slows enough to plant). When a swing ends in the air, the difference
//!   between the swing's and the network's foot fades out over [`FootLockConfig::blend_frames`]
//!   frames.
//!
//! Only leg joints move; the root and every other joint keep the network's values, the spine's too: it
//! carries the other legs, so bending it to hold one foot would drag the rest ([`Chain::limb`]). The cleanup is
//! causal — each frame depends on the past only — so a live stream and an offline clip give the same
//! result frame for frame. Thresholds are fractions of the character's body length.

use nalgebra::{Point3, Vector3};
use serde::{Deserialize, Serialize};

use crate::controller::LegConfig;
use crate::controller::chain::{Chain, ChainScratch};
use crate::controller::rig::subtree;
use crate::controller::legs::min_jerk;
use crate::dynamic_similarity::{froude, hip_height, swing_time};
use crate::features::character_body_length;
use crate::kinematics::{CharacterPose, KinematicTree};
use crate::metrics::{PoseChecks, PoseScratch, UfrConfig};
use crate::morphology::Morphology;

/// Thresholds of foot locking, in body lengths (L) and body lengths per second.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct FootLockConfig {
    /// A foot may plant within this height above its standing height (L).
    pub plant_height: f32,
    /// … and when its horizontal speed is below this (L/s).
    pub plant_speed: f32,
    /// A planted foot lifts when the network's foot rises above this (L) …
    pub lift_height: f32,
    /// … and is at least this far from the anchor horizontally (L),
    pub step_distance: f32,
    /// … or rises above this (L),
    pub raise_height: f32,
    /// … or strays this far from its anchor horizontally (L).
    pub max_drift: f32,
    /// Shortest swing (frames, lift-off to touchdown).
    pub min_swing_frames: usize,
    /// Peak swing height as a fraction of the leg length (scaled by 0.7…1 with the Froude number).
    pub swing_height: f32,
    /// Frames over which a foot whose swing ends in the air returns to the network's.
    pub blend_frames: usize,
    /// The lowest a foot that follows the network may be (L).
    pub swing_clearance: f32,
    /// A planted foot that IK misses by more than this lifts off (L).
    pub hold_tolerance: f32,
}

impl Default for FootLockConfig {
    fn default() -> Self {
        FootLockConfig {
            plant_height: 0.04,
            plant_speed: 1.0,
            lift_height: 0.06,
            step_distance: 0.1,
            raise_height: 0.15,
            max_drift: 0.25,
            min_swing_frames: 5,
            swing_height: LegConfig::default().swing_height,
            blend_frames: 4,
            swing_clearance: 0.04,
            hold_tolerance: 0.003,
        }
    }
}

/// One leg: the limb's chain from the root to the foot (spine DoFs held), the foot's standing height and the leg's length
/// (first moving joint to foot point, standing).
#[derive(Clone, Debug)]
struct Leg {
    chain: Chain,
    ground: f32,
    length: f32,
    /// The rigid bodies ([`PoseChecks::self_collision`]) from the hip down.
    bodies: Vec<usize>,
}

/// Foot locking set up for one character (see the module docs).
#[derive(Clone, Debug)]
pub struct FootLock {
    legs: Vec<Leg>,
    /// The UFR's self-collision check: a planted leg held into another body steps instead.
    checks: PoseChecks,
    config: FootLockConfig,
    body_length: f32,
    hip_height: f32,
    /// The top of the UFR's contact band (m): a swing foot moves horizontally only between frames
    /// one of which is above it.
    band: f32,
    dt: f32,
}

/// Per-foot memory of a running cleanup: one per character being driven.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct FootLockState {
    feet: Vec<FootMemory>,
    /// The root's last horizontal position and its filtered speed (m/s).
    root: Option<(f32, f32)>,
    speed: f32,
}

/// A swing of the cleaned foot.
#[derive(Clone, Copy, Debug, PartialEq)]
struct SwingState {
    /// Where it lifted off.
    from: Point3<f32>,
    /// Frames done and frames in all.
    frame: usize,
    frames: usize,
    /// Frames spent waiting before the descent.
    held: usize,
    /// Where it comes down, frozen when the descent starts.
    landing: Option<nalgebra::Point2<f32>>,
    /// Peak height above the ground (m).
    height: f32,
    /// Lifted above the contact band to keep up with the body ([`FootLock::reach_toward`]): it
    /// stays above it until the descent, rather than dip back into it and out again (a pop).
    raised: bool,
    /// Its horizontal progress (0 at `from`, 1 at `goal`) and goal on the last frame.
    progress: f32,
    goal: nalgebra::Point2<f32>,
}

impl SwingState {
    /// Goes on from `at`, where the foot was moved to: the rest of the way to the goal starts there.
    fn go_on_from(&mut self, at: Point3<f32>) {
        self.raised = true;
        if self.progress < 0.9 {
            let from = (at.xy() - self.goal * self.progress) / (1.0 - self.progress);
            self.from = Point3::new(from.x, from.y, self.from.z);
        }
    }
}

#[derive(Clone, Debug, Default, PartialEq)]
struct FootMemory {
    anchor: Option<Point3<f32>>,
    swing: Option<SwingState>,
    /// Cleaned minus network foot when a swing ended in the air, fading out.
    offset: Vector3<f32>,
    blend_left: usize,
    prev: Option<Point3<f32>>,
}

/// What a foot stepping at once ([`FootLock::step_toward_network`]) moves toward and swings for: the
/// network's joints and foot this frame, the natural swing's frames and the Froude number.
struct Reach<'a> {
    raw_q: &'a [f32],
    tip: Point3<f32>,
    swing_frames: usize,
    fr: f32,
}

/// Reusable buffers of [`FootLock::apply`] (no allocation per frame once sized).
#[derive(Clone, Debug, Default)]
pub struct FootLockScratch {
    chain: ChainScratch,
    pose: PoseScratch,
    /// The pairs of bodies colliding in the network's pose.
    raw_pairs: Vec<usize>,
    /// The network's joints this frame.
    raw_q: Vec<f32>,
    /// The network's foot points this frame.
    raw_tips: Vec<Point3<f32>>,
}

/// Fraction of a swing at each end without horizontal motion (as in the controllers).
const EDGE: f32 = 0.2;
/// A swing frame counts as above the contact band when it is this many times the band's height up
/// (the IK's tolerance and the foot's tilt).
const BAND_MARGIN: f32 = 1.1;
/// A foot moved to keep up with the body is lifted this many times the contact band's height.
const REACH_MARGIN: f32 = 1.3;
/// Time constant of the root speed filter (s).
const SPEED_TIME_CONSTANT: f32 = 0.2;

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
        let ufr = UfrConfig::for_character(tree, morph);
        let checks = PoseChecks::new(tree, morph, &ufr);
        let legs: Vec<Leg> = morph
            .feet
            .iter()
            .map(|&f| {
                let (chain, _) = Chain::limb(tree, morph, f);
                let foot = morph.ee_point(f, &links);
                let length = chain
                    .first_moving()
                    .map_or(0.0, |i| (links[chain.links[i]].translation.vector - foot.coords).norm());
                let mut bodies: Vec<usize> = chain
                    .first_moving()
                    .map(|i| subtree(tree, chain.links[i]))
                    .unwrap_or_default()
                    .into_iter()
                    .map(|l| checks.self_collision().body_of(l))
                    .collect();
                bodies.sort_unstable();
                bodies.dedup();
                Leg {
                    chain,
                    ground: foot.z.max(0.0),
                    length,
                    bodies,
                }
            })
            .collect();
        let mean_leg = legs.iter().map(|l| l.length).sum::<f32>() / legs.len().max(1) as f32;
        FootLock {
            legs,
            checks,
            config,
            body_length: character_body_length(tree, morph),
            hip_height: hip_height(tree, morph).unwrap_or(mean_leg).max(1e-3),
            band: ufr.ground_z + ufr.contact_height,
            dt: 1.0 / fps,
        }
    }

    /// A fresh state: no foot planted.
    pub fn start(&self) -> FootLockState {
        FootLockState {
            feet: vec![FootMemory::default(); self.legs.len()],
            root: None,
            speed: 0.0,
        }
    }

    /// Cleans up one frame in place (leg joints of `pose.q` only), advancing `state`.
    ///
    /// # Panics
    /// If `state` was not made by this lock's [`FootLock::start`].
    pub fn apply(
        &self,
        tree: &KinematicTree,
        state: &mut FootLockState,
        pose: &mut CharacterPose,
        scratch: &mut FootLockScratch,
    ) {
        assert_eq!(state.feet.len(), self.legs.len(), "a state from another character");
        if self.legs.is_empty() {
            return;
        }
        let FootLockScratch { chain: scratch, pose: checked, raw_pairs, raw_q, raw_tips } = scratch;
        raw_q.clone_from(&pose.q);
        raw_tips.clear();
        self.checks.place(tree, pose, checked);
        raw_pairs.clear();
        self.checks.collisions(checked, |i| raw_pairs.push(i));
        let c = &self.config;
        let l = self.body_length;
        // The root's horizontal speed, filtered: the speed the natural swing time is taken at.
        let r = pose.root.translation.vector;
        if let Some((x, y)) = state.root {
            let v = (r.x - x).hypot(r.y - y) / self.dt;
            state.speed += (v - state.speed) * (1.0 - (-self.dt / SPEED_TIME_CONSTANT).exp());
        }
        state.root = Some((r.x, r.y));
        let fr = froude(state.speed, self.hip_height);
        let swing_frames =
            ((swing_time(state.speed, self.hip_height) / self.dt).round() as usize).max(c.min_swing_frames);
        let links = tree.forward_kinematics(pose);
        let to_root = pose.root.inverse();
        for (leg, mem) in self.legs.iter().zip(&mut state.feet) {
            let tip = links[leg.chain.tip].transform_point(&Point3::from(leg.chain.tip_offset));
            raw_tips.push(tip);
            let speed = mem.prev.map_or(0.0, |p| (tip - p).xy().norm() / self.dt);
            mem.prev = Some(tip);
            let height = tip.z - leg.ground;
            let low = height < c.plant_height * l;
            match mem.anchor {
                Some(a) => {
                    let away = (tip - a).xy().norm();
                    if (height > c.lift_height * l && away > c.step_distance * l)
                        || height > c.raise_height * l
                        || away > c.max_drift * l
                    {
                        mem.anchor = None;
                        mem.swing = Some(self.swing(a, swing_frames, leg, fr));
                    }
                }
                None if mem.swing.is_none() && low && speed < c.plant_speed * l => {
                    // Plant where the foot is now, after any fading offset, on the ground.
                    let fade = mem.blend_left as f32 / c.blend_frames.max(1) as f32;
                    let at = tip + mem.offset * fade;
                    mem.anchor = Some(Point3::new(at.x, at.y, leg.ground));
                    mem.blend_left = 0;
                }
                None => {}
            }
            let mut target = match (mem.anchor, &mut mem.swing) {
                (Some(a), _) => a,
                (None, Some(sw)) => {
                    // The arc rises at least as high as the network's foot has.
                    sw.height = sw.height.max(height);
                    let (k0, k1, hold_at) = self.moving_frames(sw, leg);
                    // Before coming down, wait (at most another swing time) for the network's foot to
                    // come low, hovering clear of the ground.
                    let hold = sw.frame >= hold_at && !low && sw.held < sw.frames;
                    if hold {
                        sw.held += 1;
                    } else {
                        sw.frame += 1;
                    }
                    let s = sw.frame as f32 / sw.frames as f32;
                    let u = min_jerk((sw.frame as f32 - k0) / (k1 - k0));
                    // The landing point is frozen for the descent, so that a low foot never slides.
                    if sw.frame as f32 >= k1 && !hold && sw.landing.is_none() {
                        sw.landing = Some(tip.xy());
                    }
                    let goal = sw.landing.unwrap_or(tip.xy());
                    (sw.progress, sw.goal) = (u, goal);
                    let xy = sw.from.xy() + (goal - sw.from.xy()) * u;
                    let s2 = s * (1.0 - s);
                    let mut z = sw.height * 16.0 * s2 * s2;
                    if hold {
                        z = z.max(c.swing_clearance * l);
                    }
                    if sw.raised && (sw.frame as f32) < k1 {
                        z = z.max(REACH_MARGIN * self.band - leg.ground);
                    }
                    let p = Point3::new(xy.x, xy.y, leg.ground + z);
                    if sw.frame >= sw.frames {
                        mem.swing = None;
                        if low {
                            mem.anchor = Some(Point3::new(p.x, p.y, leg.ground));
                        } else {
                            mem.offset = p - tip;
                            mem.blend_left = c.blend_frames;
                        }
                    }
                    p
                }
                (None, None) if mem.blend_left > 0 => {
                    let fade = mem.blend_left as f32 / (c.blend_frames + 1) as f32;
                    mem.blend_left -= 1;
                    tip + mem.offset * fade
                }
                (None, None) => tip,
            };
            if mem.anchor.is_none() && mem.swing.is_none() {
                target.z = target.z.max(leg.ground + c.swing_clearance * l);
            }
            target.z = target.z.max(leg.ground);
            if (target - tip).norm() > 1e-4 {
                let local = to_root.transform_point(&target);
                let missed = leg.chain.solve(tree, &mut pose.q, &local, 2e-4, 30, scratch).error;
                let tolerance = c.hold_tolerance * l;
                // Out of the leg's reach (the body has moved on): the foot steps at once, rather than
                // be dragged along the ground.
                if missed > tolerance {
                    let reach = Reach { raw_q, tip, swing_frames, fr };
                    self.step_toward_network(tree, leg, mem, pose, target, &reach, scratch, |_, m| m <= tolerance);
                }
            }
        }
        // A leg the lock holds into another body (a pair the network's own pose keeps clear: the body
        // turned above crossed front legs, a hind leg into the tail, the body moving on over a foot
        // still lifting off) steps toward the network's foot at once, as the animal would, rather
        // than stay there for the collision guard to pull along the ground.
        if state.feet.iter().any(|m| m.anchor.is_some() || m.swing.is_some()) {
            // The pairs colliding in `pose` that the network's own pose keeps clear.
            let crossed_pairs = |checked: &mut PoseScratch, pose: &CharacterPose| {
                self.checks.place(tree, pose, checked);
                let pairs = self.checks.self_collision().pairs();
                let mut crossed: Vec<(usize, usize)> = Vec::new();
                self.checks.collisions(checked, |i| {
                    if !raw_pairs.contains(&i) {
                        crossed.push(pairs[i]);
                    }
                });
                crossed
            };
            let involves = |leg: &Leg, pairs: &[(usize, usize)]| {
                pairs.iter().any(|(x, y)| leg.bodies.contains(x) || leg.bodies.contains(y))
            };
            let crossed = crossed_pairs(checked, pose);
            for ((leg, mem), &tip) in self.legs.iter().zip(&mut state.feet).zip(raw_tips.iter()) {
                if mem.anchor.is_none() && mem.swing.is_none() || !involves(leg, &crossed) {
                    continue;
                }
                // A swinging foot moves on from where it is now.
                let now = pose.root * leg.chain.tip_point(tree, &pose.q, scratch);
                let reach = Reach { raw_q, tip, swing_frames, fr };
                self.step_toward_network(tree, leg, mem, pose, now, &reach, scratch, |p, _| {
                    !involves(leg, &crossed_pairs(checked, p))
                });
            }
        }
    }

    /// Moves a foot the lock holds toward the network's foot at once, in the air, until `done`
    /// ([`FootLock::reach_toward`]): a planted foot starts a swing from its anchor (its first frame
    /// now), a swinging one is moved from `swinging_from` and its swing goes on from there.
    #[allow(clippy::too_many_arguments)]
    fn step_toward_network(
        &self,
        tree: &KinematicTree,
        leg: &Leg,
        mem: &mut FootMemory,
        pose: &mut CharacterPose,
        swinging_from: Point3<f32>,
        reach: &Reach<'_>,
        scratch: &mut ChainScratch,
        done: impl FnMut(&CharacterPose, f32) -> bool,
    ) {
        match (mem.anchor, &mut mem.swing) {
            (Some(a), _) => {
                mem.anchor = None;
                let mut sw = self.swing(a, reach.swing_frames, leg, reach.fr);
                sw.frame = 1;
                let lift = self.lift(&sw, a, leg);
                let at = self.reach_toward(tree, leg, pose, reach.raw_q, lift, reach.tip, scratch, done);
                sw.go_on_from(at);
                mem.swing = Some(sw);
            }
            (None, Some(sw)) => {
                let at = self.reach_toward(tree, leg, pose, reach.raw_q, swinging_from, reach.tip, scratch, done);
                sw.go_on_from(at);
            }
            (None, None) => {}
        }
    }

    /// Solves a leg from the network's joints `raw_q` for points a quarter, half, three quarters and
    /// all of the way from `target` toward the network's foot `toward`, raised above the contact
    /// band, until `done(pose, IK miss)`: a foot that must move to keep up with the body moves in
    /// the air, not along the ground. Returns where the foot is.
    #[allow(clippy::too_many_arguments)]
    fn reach_toward(
        &self,
        tree: &KinematicTree,
        leg: &Leg,
        pose: &mut CharacterPose,
        raw_q: &[f32],
        target: Point3<f32>,
        toward: Point3<f32>,
        scratch: &mut ChainScratch,
        mut done: impl FnMut(&CharacterPose, f32) -> bool,
    ) -> Point3<f32> {
        let z = target.z.max(REACH_MARGIN * self.band);
        let to_root = pose.root.inverse();
        for k in 1..=4 {
            let xy = target.xy() + (toward.xy() - target.xy()) * (k as f32 / 4.0);
            for d in leg.chain.active_dofs() {
                pose.q[d] = raw_q[d];
            }
            let local = to_root.transform_point(&Point3::new(xy.x, xy.y, z));
            let missed = leg.chain.solve(tree, &mut pose.q, &local, 2e-4, 30, scratch).error;
            if done(pose, missed) {
                break;
            }
        }
        pose.root * leg.chain.tip_point(tree, &pose.q, scratch)
    }

    /// Where swing `sw` lifting off from `from` is on its frame.
    fn lift(&self, sw: &SwingState, from: Point3<f32>, leg: &Leg) -> Point3<f32> {
        let s = sw.frame as f32 / sw.frames as f32;
        Point3::new(from.x, from.y, leg.ground + sw.height * 16.0 * (s * (1.0 - s)).powi(2))
    }

    /// A swing of `frames` frames lifting off from `from`, at Froude number `fr`: at least high
    /// enough for its middle frame to clear the contact band.
    fn swing(&self, from: Point3<f32>, frames: usize, leg: &Leg, fr: f32) -> SwingState {
        let middle = (frames / 2) as f32 / frames as f32;
        let clear = (BAND_MARGIN * self.band - leg.ground) / (16.0 * (middle * (1.0 - middle)).powi(2));
        SwingState {
            from,
            frame: 0,
            frames,
            held: 0,
            landing: None,
            raised: false,
            progress: 0.0,
            goal: from.xy(),
            height: (self.config.swing_height * leg.length * (0.7 + 0.3 * fr.min(1.0))).max(1.01 * clear),
        }
    }

    /// The frames `(k0, k1)` between which a swing's foot moves horizontally, and the frame from
    /// which it waits for the network's foot to come low. Not in its first and last fifth (it lifts
    /// and comes down), and never between two frames of its arc within the contact band, where the
    /// UFR would see a foot sliding on the ground (a short swing of a small character skims through
    /// the band on its first and last frames): the descent then waits above the band.
    fn moving_frames(&self, sw: &SwingState, leg: &Leg) -> (f32, f32, usize) {
        let n = sw.frames;
        let (edge0, edge1) = (EDGE * n as f32, (1.0 - EDGE) * n as f32);
        let above = |k: usize| {
            let s = k as f32 / n as f32;
            leg.ground + sw.height * 16.0 * (s * (1.0 - s)).powi(2) >= BAND_MARGIN * self.band
        };
        // The arc is symmetric: the last frame above the band mirrors the first, so the band binds at
        // both ends or at neither. A swing is made high enough for its middle frame to clear it
        // ([`FootLock::swing`]), so `first ≤ n / 2` and `k0 < k1`.
        let first = (1..n).find(|&k| above(k)).unwrap_or(n / 2).max(1);
        let (last_in, first_out) = ((first - 1) as f32, (n - first + 1) as f32);
        if last_in <= edge0 {
            (edge0, edge1, edge1.floor() as usize)
        } else {
            let k1 = edge1.min(first_out);
            (last_in, k1, k1 as usize - 1)
        }
    }

    /// Cleans up a whole motion (one episode, in order) from a fresh state.
    pub fn apply_all(&self, tree: &KinematicTree, poses: &mut [CharacterPose]) {
        let mut state = self.start();
        let mut scratch = FootLockScratch::default();
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
    use crate::metrics::{FootTracks, GaitConfig, gait_quality, ufr};
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

    /// The root's horizontal speed, which sets the natural swing time, is the frame-to-frame speed
    /// filtered with its time constant: from rest, each frame moves it the fraction
    /// 1 − exp(−dt/τ) of the way to the speed of that frame (here along a diagonal away from the origin).
    #[test]
    fn the_root_speed_is_filtered_with_its_time_constant() {
        let (tree, morph) = spot();
        let lock = FootLock::new(&tree, &morph, 30.0, FootLockConfig::default());
        let mut state = lock.start();
        let mut scratch = FootLockScratch::default();
        let standing = tree.standing_pose();
        let (vx, vy, dt) = (0.6_f32, -0.8_f32, 1.0 / 30.0);
        let gain = 1.0 - (-dt / SPEED_TIME_CONSTANT).exp();
        let mut want = 0.0_f32;
        for t in 0..40 {
            let mut pose = standing.clone();
            let k = if t < 20 { t as f32 } else { 20.0 };
            pose.root.translation.vector.x = 2.0 + vx * dt * k;
            pose.root.translation.vector.y = 1.0 + vy * dt * k;
            lock.apply(&tree, &mut state, &mut pose, &mut scratch);
            if t > 0 {
                // 1 m/s for 20 frames, then standing still.
                let v = if t <= 20 { 1.0 } else { 0.0 };
                want += (v - want) * gain;
            }
            assert!((state.speed - want).abs() < 1e-4, "frame {t}: {} against {want}", state.speed);
        }
        assert!(want < 0.1, "the filter has come back down: {want}");
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

    /// The shared Fox (`None`, where `ACE_ALLOW_MISSING_DATA` allows, without `../shared`).
    fn shared_fox() -> Option<(KinematicTree, Morphology)> {
        let path = crate::test_data::require(
            Path::new(env!("CARGO_MANIFEST_DIR")).join("../../shared/data/creatures/Fox/Fox.glb"),
            "the shared Fox",
        )?;
        Some(load_character(&path).unwrap())
    }

    /// A creature whose spine carries its legs (the shared Fox: spine DoFs between the root and every
    /// hip) standing while its trunk bends and sways and every joint jitters: planted feet stay put and
    /// the spine keeps the network's values. Solving each leg through the spine instead moved the hips
    /// of the legs already planted, and the Fox's held-out retargets slid in 36 % of their frames.
    #[test]
    fn planted_feet_hold_while_the_spine_that_carries_them_bends() {
        let Some((tree, morph)) = shared_fox() else { return };
        assert!(morph.spine.len() >= 4, "the Fox's spine moves: {:?}", morph.spine);
        let legs: Vec<usize> = morph.feet.iter().flat_map(|&f| Chain::limb(&tree, &morph, f).0.active_dofs().collect::<Vec<_>>()).collect();
        assert!(legs.iter().all(|d| !morph.spine.contains(d)));
        let l = character_body_length(&tree, &morph);
        let standing = tree.standing_pose();
        let raw: Vec<CharacterPose> = (0..300)
            .map(|t| {
                let s = (t as f32 * 0.21).sin();
                let mut p = standing.clone();
                p.root.translation.y += 0.02 * l * s;
                for (d, q) in p.q.iter_mut().enumerate() {
                    let bend = if morph.spine.contains(&d) { 0.06 * (t as f32 * 0.13 + d as f32).sin() } else { 0.0 };
                    *q += bend + 0.02 * ((t + 3 * d) as f32 * 0.37).sin();
                }
                p
            })
            .collect();
        let cfg = UfrConfig::for_character(&tree, &morph);
        let before = ufr(&tree, &morph, &raw, 30.0, &cfg).summary().rates;
        assert!(before.sliding > 0.5, "the raw motion slides: {before:?}");
        let mut clean = raw.clone();
        FootLock::new(&tree, &morph, 30.0, FootLockConfig::default()).apply_all(&tree, &mut clean);
        let after = ufr(&tree, &morph, &clean, 30.0, &cfg).summary().rates;
        assert!(after.sliding < 0.01 && after.penetration < 0.01, "{after:?}");
        for (a, b) in raw.iter().zip(&clean) {
            assert_eq!(a.root, b.root);
            for d in (0..tree.dof()).filter(|d| !legs.contains(d)) {
                assert_eq!(a.q[d], b.q[d], "DoF {d} is not a leg's");
            }
        }
    }

    fn hound() -> (KinematicTree, Morphology) {
        load_character(&Path::new(env!("CARGO_MANIFEST_DIR")).join("../assets/creatures/hound.glb")).unwrap()
    }

    /// The longest run of frames over which one foot slides by the UFR's rule: within its contact band
    /// in consecutive frames and faster than its sliding speed.
    fn longest_slide(tree: &KinematicTree, morph: &Morphology, poses: &[CharacterPose]) -> usize {
        let cfg = UfrConfig::for_character(tree, morph);
        let feet: Vec<Vec<Point3<f32>>> = poses
            .iter()
            .map(|p| {
                let links = tree.forward_kinematics(p);
                morph.feet.iter().map(|&f| morph.ee_point(f, &links)).collect()
            })
            .collect();
        (0..morph.feet.len())
            .map(|k| {
                let (mut run, mut longest) = (0, 0);
                for w in feet.windows(2) {
                    let (a, b) = (w[0][k], w[1][k]);
                    let slides = a.z < cfg.contact_height
                        && b.z < cfg.contact_height
                        && (b - a).xy().norm() * 30.0 > cfg.sliding_speed;
                    run = if slides { run + 1 } else { 0 };
                    longest = longest.max(run);
                }
                longest
            })
            .max()
            .unwrap_or(0)
    }

    #[test]
    fn a_planted_foot_the_leg_cannot_hold_steps_instead_of_being_dragged() {
        // The hound's body drifts sideways at 0.2 L/s while the network holds its legs still, so that
        // the network's feet slide along with it. Its hips cannot splay far: planted feet leave the
        // legs' reach long before they stray `max_drift` from their anchors.
        let (tree, morph) = hound();
        let l = character_body_length(&tree, &morph);
        let standing = tree.standing_pose();
        let raw: Vec<CharacterPose> = (0..90)
            .map(|t| {
                let mut p = standing.clone();
                p.root.translation.y += 0.2 * l * t as f32 / 30.0;
                p
            })
            .collect();
        // Feet never stray far enough from their anchors to lift for that reason.
        let c = FootLockConfig {
            max_drift: 1.0,
            ..FootLockConfig::default()
        };
        let mut clean = raw.clone();
        FootLock::new(&tree, &morph, 30.0, c).apply_all(&tree, &mut clean);
        // Feet are held, then step as soon as the legs cannot hold them, through the air: none is
        // dragged along the ground, not even in the frame it is released in.
        assert_eq!(longest_slide(&tree, &morph, &raw), 89);
        let longest = longest_slide(&tree, &morph, &clean);
        assert_eq!(longest, 0, "a foot was dragged for {longest} frames");
        // They do step to keep up: each foot ends near the network's, not left behind.
        let last = |p: &CharacterPose| {
            let links = tree.forward_kinematics(p);
            morph.feet.iter().map(|&f| morph.ee_point(f, &links)).collect::<Vec<_>>()
        };
        for (a, b) in last(&clean[89]).iter().zip(last(&raw[89])) {
            assert!((a - b).xy().norm() < c.max_drift * l, "left {} m behind", (a - b).xy().norm());
        }
    }

    /// Frames of `clean` with a self-collision that the same frame of `raw` does not have.
    fn collisions_added(tree: &KinematicTree, morph: &Morphology, raw: &[CharacterPose], clean: &[CharacterPose]) -> usize {
        let checks = PoseChecks::new(tree, morph, &UfrConfig::for_character(tree, morph));
        let mut scratch = PoseScratch::default();
        let mut pairs = |p: &CharacterPose| {
            checks.place(tree, p, &mut scratch);
            let mut v = Vec::new();
            checks.collisions(&scratch, |i| v.push(i));
            v
        };
        raw.iter()
            .zip(clean)
            .filter(|(r, c)| {
                let before = pairs(r);
                pairs(c).iter().any(|i| !before.contains(i))
            })
            .count()
    }

    #[test]
    fn a_planted_leg_the_body_would_cross_steps_instead_of_being_held_there() {
        // The Fox's body drifts sideways and turns while the network keeps its legs' angles, so that
        // its feet go along and never cross. Held planted, its close-set legs end up crossed as the
        // body passes over them (37 frames of 90); they step out instead, crossed only in the first
        // frames of their swings.
        let Some((tree, morph)) = shared_fox() else { return };
        let l = character_body_length(&tree, &morph);
        let standing = tree.standing_pose();
        let raw: Vec<CharacterPose> = (0..90)
            .map(|t| {
                let mut p = standing.clone();
                p.root.translation.y += 0.3 * l * t as f32 / 30.0;
                p.root.rotation =
                    nalgebra::UnitQuaternion::from_euler_angles(0.0, 0.0, 0.8 * t as f32 / 30.0) * p.root.rotation;
                p
            })
            .collect();
        assert_eq!(collisions_added(&tree, &morph, &raw, &raw), 0);
        // Feet neither drift nor leave the legs' reach far enough to step for those reasons.
        let c = FootLockConfig {
            max_drift: 1.0,
            hold_tolerance: 1.0,
            ..FootLockConfig::default()
        };
        let mut clean = raw.clone();
        FootLock::new(&tree, &morph, 30.0, c).apply_all(&tree, &mut clean);
        let added = collisions_added(&tree, &morph, &raw, &clean);
        assert!(added <= 8, "the lock held legs crossed in {added} frames");
    }

    /// Spot standing still while the network moves its first foot: up to `lift` (L) for frames 10 and
    /// 11, then down again `forward` (L) ahead for good.
    fn quick_step(tree: &KinematicTree, morph: &Morphology, lift: f32, forward: f32) -> Vec<CharacterPose> {
        sliding_step(tree, morph, lift, forward, 0.0)
    }

    /// [`quick_step`] with the network's foot sliding on forward by `slide` (L) a frame once down.
    fn sliding_step(
        tree: &KinematicTree,
        morph: &Morphology,
        lift: f32,
        forward: f32,
        slide: f32,
    ) -> Vec<CharacterPose> {
        let l = character_body_length(tree, morph);
        let standing = tree.standing_pose();
        let chain = Chain::new(tree, morph, morph.feet[0]);
        let mut scratch = ChainScratch::default();
        let start = chain.tip_point(tree, &standing.q, &mut scratch);
        (0..40)
            .map(|t| {
                let mut p = standing.clone();
                let (dx, dz) = match t {
                    0..10 => (0.0, 0.0),
                    10 | 11 => (0.5 * forward, lift),
                    _ => (forward + slide * (t - 12) as f32, 0.0),
                };
                let target = start + Vector3::new(dx * l, 0.0, dz * l);
                chain.solve(tree, &mut p.q, &target, 1e-5, 60, &mut scratch);
                p
            })
            .collect()
    }

    fn first_foot(tree: &KinematicTree, morph: &Morphology, poses: &[CharacterPose]) -> Vec<Point3<f32>> {
        poses
            .iter()
            .map(|p| morph.ee_point(morph.feet[0], &tree.forward_kinematics(p)))
            .collect()
    }

    #[test]
    fn a_released_foot_swings_for_its_natural_time_and_lands_where_the_network_put_it() {
        let (tree, morph) = spot();
        let l = character_body_length(&tree, &morph);
        let raw = quick_step(&tree, &morph, 0.1, 0.3);
        let mut clean = raw.clone();
        let lock = FootLock::new(&tree, &morph, 30.0, FootLockConfig::default());
        lock.apply_all(&tree, &mut clean);
        let band = UfrConfig::for_character(&tree, &morph).contact_height;
        let gait = |poses: &[CharacterPose]| {
            let cfg = GaitConfig::for_character(&tree, &morph, 30.0, None).unwrap();
            gait_quality(
                &FootTracks::from_poses(&tree, &morph, poses, band),
                &[0..poses.len()],
                &cfg,
            )
        };
        // The network's foot pops: a 2-frame swing.
        let raw_swings: Vec<usize> = gait(&raw)
            .swings
            .iter()
            .filter(|s| s.foot == 0)
            .map(|s| s.frames)
            .collect();
        assert_eq!(raw_swings, [2]);
        // The cleaned foot takes one swing of at least the natural swing time standing (less the first
        // and last frames, still within the contact band), and lands where the network's foot is.
        let natural = (swing_time(0.0, lock.hip_height) * 30.0).round() as usize;
        assert!(natural >= 8, "natural swing {natural} frames");
        let swings: Vec<usize> = gait(&clean)
            .swings
            .iter()
            .filter(|s| s.foot == 0)
            .map(|s| s.frames)
            .collect();
        assert_eq!(swings.len(), 1, "{swings:?}");
        assert!(swings[0] + 4 >= natural, "{swings:?} vs {natural}");
        let feet = first_foot(&tree, &morph, &clean);
        let goal = first_foot(&tree, &morph, &raw)[39];
        assert!((feet[39] - goal).norm() < 1e-3, "{:?} vs {goal:?}", feet[39]);
        // It never jumps: no frame moves it more than a third of the step, and it rises at least
        // half the swing height.
        let step = 0.3 * l;
        let most = feet.windows(2).map(|w| (w[1] - w[0]).norm()).fold(0.0, f32::max);
        assert!(most < step / 3.0, "{most} m in one frame for a {step} m step");
        // A low foot never slides: the landing point is frozen for the descent.
        let ufr_cfg = UfrConfig::for_character(&tree, &morph);
        assert_eq!(ufr(&tree, &morph, &clean, 30.0, &ufr_cfg).rates.sliding, 0.0);
        let top = feet.iter().map(|p| p.z).fold(f32::MIN, f32::max) - feet[0].z;
        assert!(
            top > 0.5 * FootLockConfig::default().swing_height * lock.legs[0].length * 0.7,
            "{top}"
        );
    }

    /// [`sliding_step`] (which must slide by the UFR's rule) cleaned with `config`, and the UFR's
    /// thresholds.
    fn cleaned_sliding_step(
        tree: &KinematicTree,
        morph: &Morphology,
        (lift, forward, slide): (f32, f32, f32),
        config: FootLockConfig,
    ) -> (Vec<CharacterPose>, UfrConfig) {
        let raw = sliding_step(tree, morph, lift, forward, slide);
        let cfg = UfrConfig::for_character(tree, morph);
        assert!(ufr(tree, morph, &raw, 30.0, &cfg).rates.sliding > 0.5);
        let mut clean = raw;
        FootLock::new(tree, morph, 30.0, config).apply_all(tree, &mut clean);
        (clean, cfg)
    }

    #[test]
    fn a_swinging_foot_comes_down_without_sliding_where_the_network_foot_slides() {
        let (tree, morph) = spot();
        // The network's foot slides at 0.15 L/s once down: 1.5 times the UFR's sliding speed.
        let (clean, cfg) = cleaned_sliding_step(&tree, &morph, (0.1, 0.3, 0.005), FootLockConfig::default());
        assert_eq!(ufr(&tree, &morph, &clean, 30.0, &cfg).rates.sliding, 0.0);
    }

    #[test]
    fn a_small_characters_low_swing_moves_only_above_the_contact_band() {
        // The hound's swing arc (3.4 cm) is twice its contact band (1.7 cm): its second and
        // second-to-last frames are within the band. The network's foot barely lifts and slides on
        // once down, and the lock releases it when it has strayed (so the arc is not raised to the
        // network's foot).
        let (tree, morph) = hound();
        let c = FootLockConfig { max_drift: 0.1, ..FootLockConfig::default() };
        let (clean, cfg) = cleaned_sliding_step(&tree, &morph, (0.05, 0.08, 0.005), c);
        let feet = first_foot(&tree, &morph, &clean);
        let band = cfg.ground_z + cfg.contact_height;
        let top = feet.iter().map(|p| p.z).fold(f32::MIN, f32::max);
        assert!(top > band && top < 3.0 * band, "the swing's top: {top} m");
        let moving = feet.windows(2).filter(|w| (w[1] - w[0]).xy().norm() > 1e-4).count();
        assert!(moving >= 3, "the foot hardly moved: {moving} frames");
        assert_eq!(ufr(&tree, &morph, &clean, 30.0, &cfg).rates.sliding, 0.0, "{feet:?}");
    }

    #[test]
    fn a_swing_never_moves_between_two_frames_within_the_contact_band() {
        // Every swing length and height the hound's legs can take, from the lowest a swing is made,
        // with its own swing height and one far below the band.
        let (tree, morph) = hound();
        for swing_height in [FootLockConfig::default().swing_height, 0.01] {
            let lock = FootLock::new(&tree, &morph, 30.0, FootLockConfig { swing_height, ..FootLockConfig::default() });
            for leg in &lock.legs {
                for frames in 4..=16 {
                    let lowest = lock.swing(Point3::origin(), frames, leg, 0.0);
                    for scale in [1.0, 1.2, 1.5, 2.0, 4.0] {
                        let sw = SwingState { height: lowest.height * scale, ..lowest };
                        let (k0, k1, hold_at) = lock.moving_frames(&sw, leg);
                        assert!(hold_at < frames && k0 < k1, "{frames} frames: {k0} {k1} {hold_at}");
                        // The first and last fifths lift and come down without moving on.
                        let n = frames as f32;
                        assert!(k0 >= EDGE * n - 1e-4 && k1 <= (1.0 - EDGE) * n + 1e-4, "{frames} frames: {k0} {k1}");
                        // As `apply` moves it: progress along the minimum-jerk profile, frozen from `k1`.
                        let u = |k: usize| if k as f32 >= k1 { 1.0 } else { min_jerk((k as f32 - k0) / (k1 - k0)) };
                        let z = |k: usize| {
                            let s = k as f32 / frames as f32;
                            leg.ground + sw.height * 16.0 * (s * (1.0 - s)).powi(2)
                        };
                        assert!((1..frames).any(|k| z(k) >= lock.band), "{frames} frames: never above the band");
                        let band = BAND_MARGIN * lock.band;
                        for k in 1..=frames {
                            let (a, b) = (z(k - 1), z(k));
                            if a < lock.band && b < lock.band {
                                assert_eq!(u(k), u(k - 1), "{frames} frames, ×{scale}: moves from frame {} to {k} within the band", k - 1);
                            }
                            // It uses every frame it may: out of the first and last fifths, one end clear of the band.
                            if (a >= band || b >= band) && (k - 1) as f32 >= EDGE * n && k as f32 <= (1.0 - EDGE) * n {
                                assert!(u(k) > u(k - 1), "{frames} frames, ×{scale}: waits from frame {} to {k}", k - 1);
                            }
                        }
                    }
                }
            }
        }
    }

    #[test]
    fn a_swing_high_above_the_band_moves_between_its_first_and_last_fifth() {
        // Spot's swings clear its contact band (1.5 cm) by far: the band does not bind, and the foot
        // moves on from a fifth of the way through to four fifths, waiting (if it must) from there.
        let (tree, morph) = spot();
        let lock = FootLock::new(&tree, &morph, 30.0, FootLockConfig::default());
        for frames in [5, 8, 10, 13] {
            let sw = lock.swing(Point3::origin(), frames, &lock.legs[0], 0.0);
            let n = frames as f32;
            let (k0, k1, hold_at) = lock.moving_frames(&sw, &lock.legs[0]);
            assert_eq!((k0, k1, hold_at), (EDGE * n, (1.0 - EDGE) * n, ((1.0 - EDGE) * n).floor() as usize));
        }
    }

    #[test]
    fn a_swing_moved_to_keep_up_goes_on_from_where_the_foot_got_to() {
        let sw = SwingState {
            from: Point3::new(0.0, 0.0, 0.0),
            frame: 3,
            frames: 10,
            held: 0,
            landing: None,
            height: 0.05,
            raised: false,
            progress: 0.5,
            goal: nalgebra::Point2::new(1.0, 0.0),
        };
        // Half-way: the rest of the way to the goal now starts so that this frame is where the foot is.
        let at = Point3::new(0.7, 0.2, 0.03);
        let mut moved = sw;
        moved.go_on_from(at);
        assert!(moved.raised);
        let here = moved.from.xy() + (moved.goal - moved.from.xy()) * moved.progress;
        assert!((here - at.xy()).norm() < 1e-6, "{here:?}");
        // Nearly there (from 90 %): the start is left alone, the landing close.
        let mut late = SwingState { progress: 0.9, ..sw };
        late.go_on_from(at);
        assert!(late.raised && late.from == sw.from);
    }

    #[test]
    fn a_foot_the_network_drags_fast_along_the_ground_is_held_at_the_swing_clearance() {
        let (tree, morph) = spot();
        let l = character_body_length(&tree, &morph);
        let c = FootLockConfig::default();
        // The network's first foot is up in the air, then skims the ground, 1 mm up, at 1.5 L/s: too
        // fast to plant.
        let standing = tree.standing_pose();
        let chain = Chain::new(&tree, &morph, morph.feet[0]);
        let mut scratch = ChainScratch::default();
        let start = chain.tip_point(&tree, &standing.q, &mut scratch);
        let raw: Vec<CharacterPose> = (0..12)
            .map(|t| {
                let mut p = standing.clone();
                let up = if t < 4 { 0.2 * l } else { 0.001 };
                let target = start + Vector3::new((-0.3 + 0.05 * t as f32) * l, 0.0, up);
                chain.solve(&tree, &mut p.q, &target, 1e-5, 60, &mut scratch);
                p
            })
            .collect();
        let mut clean = raw.clone();
        FootLock::new(&tree, &morph, 30.0, c).apply_all(&tree, &mut clean);
        let ground = first_foot(&tree, &morph, &[standing])[0].z;
        for (t, p) in first_foot(&tree, &morph, &clean).iter().enumerate().skip(4) {
            assert!(p.z > ground + 0.9 * c.swing_clearance * l, "frame {t}: foot {} m above its standing height", p.z - ground);
        }
    }

    /// Whether the lock holds Spot's first foot planted after each frame of `path` ([`first_foot_along`]
    /// with the default configuration).
    fn planted_along(stand: usize, path: &[(f32, f32)]) -> Vec<bool> {
        planted_along_with(0.0, stand, path)
    }

    /// [`planted_along`] with the first foot's point `raised` metres above its standing geometry, so
    /// that the foot stands above the ground: its heights count from there.
    fn planted_along_with(raised: f32, stand: usize, path: &[(f32, f32)]) -> Vec<bool> {
        let (_, _, memory) = first_foot_along(FootLockConfig::default(), raised, stand, path);
        memory.iter().map(|m| m.anchor.is_some()).collect()
    }

    /// Each rule that lifts a planted foot, alone (defaults: lift 0.06 L with a step of 0.1 L, or a raise
    /// of 0.15 L, or a drift of 0.25 L), and the foot held where no rule applies.
    #[test]
    fn each_lift_off_rule_releases_a_planted_foot_and_nothing_else_does() {
        let held = |forward: f32, up: f32| planted_along(3, &[(forward, up)])[0];
        assert!(held(0.0, 0.0), "standing, planted");
        // Up past the lift height: released only once also a step away.
        assert!(held(0.05, 0.10));
        assert!(!held(0.15, 0.10));
        // A step away but low: held (drift below the limit).
        assert!(held(0.15, 0.03));
        // Raised high: released without moving away; below that, held.
        assert!(held(0.0, 0.12));
        assert!(!held(0.0, 0.20));
        // Drifting along the ground: held up to the drift limit, released past it.
        assert!(held(0.20, 0.0));
        assert!(!held(0.30, 0.0));
        // A foot that stands 3 cm up (its point above its geometry): heights count from there.
        let raised = |forward: f32, up: f32| planted_along_with(0.03, 3, &[(forward, up)])[0];
        assert!(raised(0.0, 0.0) && raised(0.0, 0.12) && !raised(0.0, 0.20));
    }

    /// A foot comes down and plants once it is low (below 0.04 L) and slow (below 1 L/s): hovering
    /// above that height, or skimming the ground faster, it does not.
    #[test]
    fn a_foot_plants_once_low_and_slow() {
        let hover = |up: f32| planted_along(0, &[(0.0, 0.3), (0.0, up), (0.0, up), (0.0, up)]);
        assert_eq!(hover(0.03), [false, true, true, true]);
        assert_eq!(hover(0.05), [false, false, false, false]);
        // Along the ground at 0.5 and 1.5 L/s (1/60 and 1/20 L a frame) after coming down.
        let skim = |per_frame: f32| {
            let path: Vec<(f32, f32)> =
                std::iter::once((0.0, 0.3)).chain((1..6).map(|k| (k as f32 * per_frame, 0.0))).collect();
            planted_along(0, &path)
        };
        assert!(skim(1.0 / 60.0)[2..].iter().all(|&p| p), "{:?}", skim(1.0 / 60.0));
        assert!(skim(1.0 / 20.0)[2..].iter().all(|&p| !p), "{:?}", skim(1.0 / 20.0));
    }

    /// Spot's first foot put by the network at each `(forward, up)` of `path` (body lengths from where
    /// it stands), one per frame, after `stand` standing frames, cleaned by a lock of `config`; with the
    /// foot's point `raised` metres above its standing geometry. Returns the cleaned foot point, the
    /// network's, and the lock's memory of that foot after each frame.
    fn first_foot_along(
        config: FootLockConfig,
        raised: f32,
        stand: usize,
        path: &[(f32, f32)],
    ) -> (Vec<Point3<f32>>, Vec<Point3<f32>>, Vec<FootMemory>) {
        let (tree, mut morph) = spot();
        let first = morph.feet[0];
        let up = tree.forward_kinematics(&tree.standing_pose())[first].rotation.inverse() * Vector3::z() * raised;
        *morph.tip_offsets.entry(first).or_insert_with(Vector3::zeros) += up;
        let l = character_body_length(&tree, &morph);
        let lock = FootLock::new(&tree, &morph, 30.0, config);
        let standing = tree.standing_pose();
        let chain = Chain::new(&tree, &morph, first);
        let mut cs = ChainScratch::default();
        let start = chain.tip_point(&tree, &standing.q, &mut cs);
        let (mut state, mut scratch) = (lock.start(), FootLockScratch::default());
        for _ in 0..stand {
            lock.apply(&tree, &mut state, &mut standing.clone(), &mut scratch);
        }
        let foot = |p: &CharacterPose| morph.ee_point(first, &tree.forward_kinematics(p));
        let (mut clean, mut net, mut memory) = (Vec::new(), Vec::new(), Vec::new());
        for &(forward, up) in path {
            let mut p = standing.clone();
            let target = start + Vector3::new(forward * l, 0.0, up * l);
            let missed = chain.solve(&tree, &mut p.q, &target, 1e-5, 60, &mut cs).error;
            assert!(missed < 1e-3, "({forward}, {up}) is out of reach by {missed} m");
            net.push(foot(&p));
            lock.apply(&tree, &mut state, &mut p, &mut scratch);
            clean.push(foot(&p));
            memory.push(state.feet[0].clone());
        }
        (clean, net, memory)
    }

    /// A foot the network keeps in the air after stepping: the cleaned swing waits before its descent,
    /// hovering at least the swing clearance up, for at most another swing time; the swing then ends
    /// in the air and the foot returns to the network's over the blend frames, the gap shrinking by the
    /// same step each frame; when the network's foot then comes down during the blend, it plants where
    /// the cleaned foot is, without a jump.
    #[test]
    fn a_swing_waits_for_a_foot_kept_up_then_blends_back_and_plants_where_it_is() {
        let (tree, morph) = spot();
        let l = character_body_length(&tree, &morph);
        // A clearance above the swing's arc where it waits (0.08 L against about 0.05 L), so that both
        // show.
        let c = FootLockConfig { swing_clearance: 0.08, ..FootLockConfig::default() };
        let ground = first_foot(&tree, &morph, &[tree.standing_pose()])[0].z;
        let up = vec![(0.15, 0.10); 60];
        let (clean, net, memory) = first_foot_along(c, 0.0, 3, &up);
        // Lifted off at the first frame.
        let frames = memory[0].swing.expect("released").frames;
        // Standing (Froude number 0), a swing rises 0.7 of the swing height times the leg's length, or
        // as high as the network's foot has when that is higher (0.10 L here, not 0.07 L).
        let leg = FootLock::new(&tree, &morph, 30.0, c).legs[0].length;
        let own = c.swing_height * leg * 0.7;
        let lifted = |up: f32| first_foot_along(c, 0.0, 3, &[(0.15, up)]).2[0].swing.expect("released").height;
        assert!((0.07 * l) < own && own < 0.10 * l, "{own} m");
        assert!((lifted(0.07) - own).abs() < 1e-5, "{} against {own}", lifted(0.07));
        assert!((lifted(0.10) - net[0].z + ground).abs() < 1e-4, "{} against the network's", lifted(0.10));
        assert!(frames >= c.min_swing_frames);
        // Waiting: the swing's own frames stop while `held` counts up to another swing, the foot hovering.
        let waiting: Vec<usize> = (1..memory.len())
            .filter(|&t| {
                let (a, b) = (memory[t - 1].swing, memory[t].swing);
                matches!((a, b), (Some(a), Some(b)) if b.held == a.held + 1 && b.frame == a.frame)
            })
            .collect();
        assert_eq!(waiting.len(), frames, "{memory:?}");
        assert!(waiting.windows(2).all(|w| w[1] == w[0] + 1), "one wait, not several: {waiting:?}");
        // Hovering on the swing's arc, or at the swing clearance where the arc is lower.
        for &t in &waiting {
            let sw = memory[t].swing.unwrap();
            let s = sw.frame as f32 / sw.frames as f32;
            let arc = sw.height * 16.0 * (s * (1.0 - s)).powi(2);
            let want = arc.max(c.swing_clearance * l);
            let z = clean[t].z - ground;
            assert!((z - want).abs() < 1e-3, "frame {t}: {z} m up against {want} (arc {arc})");
        }
        assert!(
            waiting.iter().any(|&t| clean[t].z - ground < c.swing_clearance * l + 1e-3),
            "the clearance never held the foot up: the test would not see it"
        );
        // The swing ends in the air (2 × frames after lift-off); then the blend: the cleaned foot is
        // the network's plus b/(b+1), (b−1)/(b+1), … 1/(b+1) of the offset it ended at, no lower than
        // the swing clearance, then the network's. With the default clearance, which the last frames
        // of the blend are above (the larger one would hide them).
        let end = memory.iter().position(|m| m.swing.is_none()).expect("the swing ends");
        assert_eq!(end + 1, 2 * frames, "{memory:?}");
        let d = FootLockConfig::default();
        let (clean, net, memory) = first_foot_along(d, 0.0, 3, &up);
        assert_eq!(memory.iter().position(|m| m.swing.is_none()), Some(end), "the same swing");
        let b = d.blend_frames;
        let offset = memory[end].offset;
        assert!(offset.norm() > 0.01, "the swing ended away from the network's foot: {offset:?}");
        let mut shown = 0;
        for k in 0..=b {
            let t = end + 1 + k;
            let mut want = net[t] + offset * (b - k) as f32 / (b + 1) as f32;
            let floor = ground + d.swing_clearance * l;
            shown += usize::from(want.z > floor + 1e-3 && k < b);
            want.z = want.z.max(floor);
            let miss = (clean[t] - want).norm();
            assert!(miss < 1e-3, "blend frame {k}: {:?} against {want:?}", clean[t]);
        }
        assert!(shown >= 2, "only {shown} blend frames above the clearance: the test would not see the blend");

        // Again, the network's foot moving on by 0.05 L once the wait is over and the landing point
        // frozen (so the swing ends behind it), and coming down one frame into the blend: it
        // plants where the cleaned foot is, the network's plus the part of the offset left.
        let last_wait = *waiting.last().unwrap();
        let mut path = up[..=last_wait + 1].to_vec();
        path.extend(vec![(0.20, 0.10); end - last_wait]);
        path.extend([(0.20, 0.0); 5]);
        let (clean, net, memory) = first_foot_along(c, 0.0, 3, &path);
        let t = end + 2;
        assert!(memory[t - 1].anchor.is_none() && memory[t - 1].blend_left == b - 1, "{:?}", memory[t - 1]);
        let offset = memory[t - 1].offset;
        assert!(offset.xy().norm() > 0.02, "the swing ended behind the network's foot: {offset:?}");
        let anchor = memory[t].anchor.expect("planted once down");
        let want = net[t].xy() + offset.xy() * (b - 1) as f32 / b as f32;
        assert!((anchor.xy() - want).norm() < 1e-3, "planted at {anchor:?}, not {want:?}");
        assert!((clean[t + 4] - anchor).norm() < 2e-3, "held where it planted");
    }

    #[test]
    fn a_foot_that_only_needs_to_move_a_little_stays_planted() {
        let (tree, morph) = spot();
        let raw = quick_step(&tree, &morph, 0.08, 0.04);
        let mut clean = raw.clone();
        FootLock::new(&tree, &morph, 30.0, FootLockConfig::default()).apply_all(&tree, &mut clean);
        let feet = first_foot(&tree, &morph, &clean);
        let moved = feet.iter().map(|p| (p - feet[0]).norm()).fold(0.0, f32::max);
        assert!(moved < 1e-3, "the planted foot moved {moved} m");
    }

    #[test]
    fn frame_by_frame_equals_the_whole_clip_and_lifted_feet_follow_the_network() {
        let (tree, morph) = spot();
        let lock = FootLock::new(&tree, &morph, 30.0, FootLockConfig::default());
        let raw = swaying(&tree, 120);
        let mut whole = raw.clone();
        lock.apply_all(&tree, &mut whole);
        let mut state = lock.start();
        let mut scratch = FootLockScratch::default();
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

