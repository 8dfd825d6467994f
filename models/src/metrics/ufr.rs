//! UFR, the unrealistic frame ratio (paper §7.3): the fraction of frames with a self-collision, a
//! penetration of the ground, or a foot sliding while in contact.
//!
//! # Detectors (thresholds in [`UfrConfig`], all proportional to the body length `L`)
//! - **Self-collision**: a checked pair of rigid bodies interpenetrates deeper than 1 % L (≈ 6 mm on
//!   Spot). Adjacent bodies and pairs that touch (within the tolerance) at the neutral pose are not checked; see
//!   [`super::collision`] for the shape approximations. The tolerance absorbs grazing contact and the
//!   approximations' few millimetres.
//! - **Penetration**: a foot point ([`Morphology::ee_point`]) or any part of the geometry lies more
//!   than 1 % L below the ground (`ground_z`). On bodies that carry a foot, boxes around meshes are
//!   left out (their corners dip when a foot tilts although the mesh does not); the foot point stands
//!   for them. Wheels are checked as if they did not spin (a wheel is round, its box is not).
//! - **Sliding**: a foot in contact — its point within 2.5 % L of the ground in both this and the
//!   previous frame — moves horizontally faster than 10 % L per second between the two frames
//!   (≈ 1.5 cm and 6 cm/s on Spot, 4.6 mm and 1.8 cm/s on the crab, 4 cm and 17 cm/s for a 1.7 m
//!   human, whose usual foot-contact band is ≈ 5 cm). The band lies well under a swing foot's
//!   clearance, so only feet skimming the ground count; the speed is a small fraction of a swing
//!   foot's (≈ 2 L/s when walking) yet far above the numeric noise of a planted foot (µm per frame).
//!   Velocities never span an episode boundary. Wheels roll and are not checked (the paper treats
//!   wheeled bases as moving in any direction).
//!
//! A frame is unrealistic when any detector fires. The per-frame flags feed the editor's timeline.

use std::ops::Range;

use nalgebra::{Isometry3, Point3};
use serde::{Deserialize, Serialize};

use super::collision::{PosedBodies, SelfCollision};
use crate::features::character_body_length;
use crate::kinematics::{CharacterPose, KinematicTree};
use crate::morphology::Morphology;

/// Thresholds of the UFR detectors (metres, seconds). See the module docs for the defaults.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct UfrConfig {
    /// The body length the defaults derive from (m).
    pub body_length: f32,
    /// Height of the ground plane (world z, m).
    pub ground_z: f32,
    /// Self-collision: the penetration depth a pair of bodies must exceed (m).
    pub collision_tolerance: f32,
    /// Ground penetration: how far below the ground a point must be (m).
    pub penetration_depth: f32,
    /// Contact: a foot point is in contact within this height above the ground (m).
    pub contact_height: f32,
    /// Sliding: the horizontal speed above which a foot in contact slides (m/s).
    pub sliding_speed: f32,
}

impl UfrConfig {
    /// Self-collision tolerance as a fraction of the body length.
    pub const COLLISION_TOLERANCE: f32 = 0.01;
    /// Penetration depth as a fraction of the body length.
    pub const PENETRATION_DEPTH: f32 = 0.01;
    /// Contact height as a fraction of the body length.
    pub const CONTACT_HEIGHT: f32 = 0.025;
    /// Sliding speed in body lengths per second.
    pub const SLIDING_SPEED: f32 = 0.10;

    /// The default thresholds for a body `body_length` metres long, ground at z = 0.
    pub fn from_body_length(body_length: f32) -> Self {
        UfrConfig {
            body_length,
            ground_z: 0.0,
            collision_tolerance: Self::COLLISION_TOLERANCE * body_length,
            penetration_depth: Self::PENETRATION_DEPTH * body_length,
            contact_height: Self::CONTACT_HEIGHT * body_length,
            sliding_speed: Self::SLIDING_SPEED * body_length,
        }
    }

    /// The default thresholds for a character ([`character_body_length`]).
    pub fn for_character(tree: &KinematicTree, morph: &Morphology) -> Self {
        Self::from_body_length(character_body_length(tree, morph))
    }
}

/// Fractions of frames (0…1) flagged by each detector and by any.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct UfrRates {
    /// Frames with any detector firing: the UFR.
    pub ufr: f32,
    pub self_collision: f32,
    pub penetration: f32,
    pub sliding: f32,
}

/// How often a pair of bodies collided (named by their first links).
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct PairCount {
    pub a: String,
    pub b: String,
    pub frames: usize,
}

/// The UFR of a motion without the per-frame flags (what `ace metrics` prints).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct UfrSummary {
    /// Frames evaluated.
    pub frames: usize,
    /// Fractions of frames flagged.
    pub rates: UfrRates,
    /// The most frequently colliding pairs, most frequent first (at most 10).
    pub collision_pairs: Vec<PairCount>,
    /// The thresholds used.
    pub config: UfrConfig,
}

/// The UFR of a motion with per-frame flags (index = frame).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct UfrReport {
    /// Frames evaluated.
    pub frames: usize,
    pub self_collision: Vec<bool>,
    pub penetration: Vec<bool>,
    pub sliding: Vec<bool>,
    /// Any of the three.
    pub any: Vec<bool>,
    /// Fractions of frames flagged.
    pub rates: UfrRates,
    /// The most frequently colliding pairs, most frequent first (at most 10).
    pub collision_pairs: Vec<PairCount>,
    /// The thresholds used.
    pub config: UfrConfig,
}

impl UfrReport {
    /// The report without the per-frame flags.
    pub fn summary(&self) -> UfrSummary {
        UfrSummary {
            frames: self.frames,
            rates: self.rates,
            collision_pairs: self.collision_pairs.clone(),
            config: self.config,
        }
    }

    /// Indices of the frames any detector flagged.
    pub fn flagged_frames(&self) -> impl Iterator<Item = usize> + '_ {
        self.any.iter().enumerate().filter(|(_, a)| **a).map(|(t, _)| t)
    }
}

/// The UFR of one continuous motion sampled at `fps` frames per second.
pub fn ufr(
    tree: &KinematicTree,
    morph: &Morphology,
    poses: &[CharacterPose],
    fps: f32,
    config: &UfrConfig,
) -> UfrReport {
    let all = 0..poses.len();
    UfrDetector::new(tree, morph, *config).evaluate(poses, std::slice::from_ref(&all), fps)
}

/// The UFR of several episodes stored back to back in `poses` (see [`UfrDetector::evaluate`]).
pub fn ufr_episodes(
    tree: &KinematicTree,
    morph: &Morphology,
    poses: &[CharacterPose],
    episodes: &[Range<usize>],
    fps: f32,
    config: &UfrConfig,
) -> UfrReport {
    UfrDetector::new(tree, morph, *config).evaluate(poses, episodes, fps)
}

/// The per-pose half of the UFR — self-collision and ground penetration — for one character, owning
/// what it needs; the UFR's detector uses it, and so does the collision guard that keeps generated poses
/// clear of both ([`crate::collision_guard`]).
#[derive(Clone, Debug)]
pub struct PoseChecks {
    collision: SelfCollision,
    /// Per rigid body: whether it carries a foot.
    foot_body: Vec<bool>,
    /// Wheel links with every link of their subtree.
    wheels: Vec<(usize, Vec<usize>)>,
    /// The ground's height (m).
    ground: f32,
    /// Penetration: below this height (m).
    below: f32,
}

/// Buffers of [`PoseChecks`]: the link poses and bodies of the last placed pose.
#[derive(Clone, Debug, Default)]
pub struct PoseScratch {
    /// World poses of the links (wheels turned back to their zero position).
    pub links: Vec<Isometry3<f32>>,
    posed: PosedBodies,
}

impl PoseChecks {
    /// The checks of a character with the thresholds of `config`.
    pub fn new(tree: &KinematicTree, morph: &Morphology, config: &UfrConfig) -> Self {
        let collision = SelfCollision::new(tree, config.collision_tolerance);
        let mut foot_body = vec![false; collision.bodies().len()];
        for &f in &morph.feet {
            foot_body[collision.body_of(f)] = true;
        }
        let wheels = morph
            .wheels
            .iter()
            .filter(|&&w| tree.links[w].parent.is_some() && tree.links[w].joint.is_some())
            .map(|&w| (w, (0..tree.links.len()).filter(|&l| tree.is_descendant(l, w)).collect()))
            .collect();
        PoseChecks {
            collision,
            foot_body,
            wheels,
            ground: config.ground_z,
            below: config.ground_z - config.penetration_depth,
        }
    }

    /// The self-collision checker (bodies and checked pairs).
    pub fn self_collision(&self) -> &SelfCollision {
        &self.collision
    }

    /// Places `pose` into `scratch` for the checks below.
    pub fn place(&self, tree: &KinematicTree, pose: &CharacterPose, scratch: &mut PoseScratch) {
        tree.forward_kinematics_into(pose, &mut scratch.links);
        self.unspin_wheels(tree, &mut scratch.links);
        scratch.posed.update(self.collision.bodies(), &scratch.links);
    }

    /// Calls `hit(pair_index)` for every colliding checked pair of the placed pose; returns how many.
    pub fn collisions(&self, scratch: &PoseScratch, hit: impl FnMut(usize)) -> usize {
        self.collision.for_each_collision(&scratch.posed, hit)
    }

    /// Whether a foot point or any geometry of the placed pose is below the ground (mesh boxes on
    /// foot bodies excepted).
    pub fn penetrates(&self, morph: &Morphology, scratch: &PoseScratch) -> bool {
        morph.feet.iter().any(|&f| morph.ee_point(f, &scratch.links).z < self.below) || self.geometry_penetrates(scratch)
    }

    /// Whether the placed pose collides with itself or the ground.
    pub fn is_unrealistic(&self, morph: &Morphology, scratch: &PoseScratch) -> bool {
        self.collisions(scratch, |_| {}) > 0 || self.penetrates(morph, scratch)
    }

    /// How far the placed pose reaches below the ground (m, 0 when it does not): the lowest foot point
    /// or geometry that [`PoseChecks::penetrates`] looks at.
    pub fn depth_below_ground(&self, morph: &Morphology, scratch: &PoseScratch) -> f32 {
        let bodies = self.collision.bodies();
        let feet = morph.feet.iter().map(|&f| morph.ee_point(f, &scratch.links).z);
        let geometry = (0..bodies.len()).flat_map(|k| {
            scratch.posed.primitives[k]
                .iter()
                .zip(&bodies[k].from_mesh)
                .filter(move |(_, mesh)| !(**mesh && self.foot_body[k]))
                .map(|(p, _)| p.lowest_z())
        });
        let lowest = feet.chain(geometry).fold(f32::INFINITY, f32::min);
        (self.ground - lowest).max(0.0)
    }

    /// Whether any geometry of the placed pose lies below the penetration depth (mesh boxes on foot
    /// bodies excepted): [`PoseChecks::penetrates`] without the foot points.
    pub fn geometry_penetrates(&self, scratch: &PoseScratch) -> bool {
        (0..self.collision.bodies().len()).any(|k| self.body_penetrates(k, scratch))
    }

    /// Whether body `k`'s geometry in the placed pose lies below the penetration depth.
    fn body_penetrates(&self, k: usize, scratch: &PoseScratch) -> bool {
        let posed = &scratch.posed;
        let (c, r) = posed.spheres[k];
        c.z - r < self.below
            && posed.primitives[k]
                .iter()
                .zip(&self.collision.bodies()[k].from_mesh)
                .any(|(p, &mesh)| !(mesh && self.foot_body[k]) && p.lowest_z() < self.below)
    }

    /// Calls `hit(link)` with the link of every body in a colliding pair of the placed pose, and when
    /// `ground`, of every body and foot point below the ground too (a link may come more than once):
    /// what [`PoseChecks::is_unrealistic`] objects to, by link.
    pub fn offending_links(&self, morph: &Morphology, scratch: &PoseScratch, ground: bool, mut hit: impl FnMut(usize)) {
        let bodies = self.collision.bodies();
        let pairs = self.collision.pairs();
        self.collisions(scratch, |k| {
            let (a, b) = pairs[k];
            hit(bodies[a].link);
            hit(bodies[b].link);
        });
        if ground {
            for &f in &morph.feet {
                if morph.ee_point(f, &scratch.links).z < self.below {
                    hit(f);
                }
            }
            for k in 0..bodies.len() {
                if self.body_penetrates(k, scratch) {
                    hit(bodies[k].link);
                }
            }
        }
    }

    /// Turns each wheel (and what hangs below it) back to its joint's zero position.
    fn unspin_wheels(&self, tree: &KinematicTree, links: &mut [Isometry3<f32>]) {
        for (w, sub) in &self.wheels {
            let link = &tree.links[*w];
            let (Some(p), Some(j)) = (link.parent, &link.joint) else {
                continue;
            };
            let fix = links[p] * j.origin * links[*w].inverse();
            for &l in sub {
                links[l] = fix * links[l];
            }
        }
    }
}

/// The UFR detectors of one character, set up once (bodies, checked pairs) for any number of motions.
#[derive(Clone, Debug)]
pub struct UfrDetector<'a> {
    tree: &'a KinematicTree,
    morph: &'a Morphology,
    config: UfrConfig,
    checks: PoseChecks,
}

impl<'a> UfrDetector<'a> {
    /// Sets up the detectors for a character.
    pub fn new(tree: &'a KinematicTree, morph: &'a Morphology, config: UfrConfig) -> Self {
        UfrDetector {
            tree,
            morph,
            config,
            checks: PoseChecks::new(tree, morph, &config),
        }
    }

    /// The thresholds.
    pub fn config(&self) -> &UfrConfig {
        &self.config
    }

    /// The self-collision checker (bodies and checked pairs).
    pub fn self_collision(&self) -> &SelfCollision {
        self.checks.self_collision()
    }

    /// Flags every frame of `poses`. `episodes` are ranges of frames that are continuous in time;
    /// sliding (a velocity) is only measured between consecutive frames of the same episode. Frames in
    /// no episode are checked for self-collision and penetration only.
    ///
    /// # Panics
    /// If an episode reaches past the end of `poses` or `fps` is not positive.
    pub fn evaluate(&self, poses: &[CharacterPose], episodes: &[Range<usize>], fps: f32) -> UfrReport {
        assert!(fps > 0.0, "fps must be positive");
        let n = poses.len();
        let mut continues = vec![false; n];
        for e in episodes {
            assert!(e.end <= n, "episode {e:?} reaches past the {n} frames");
            for c in continues.iter_mut().take(e.end).skip(e.start + 1) {
                *c = true;
            }
        }
        let c = &self.config;
        let (below, band) = (c.ground_z - c.penetration_depth, c.ground_z + c.contact_height);
        let step_limit = c.sliding_speed / fps;

        let mut scratch = PoseScratch::default();
        let mut pair_frames = vec![0usize; self.self_collision().pairs().len()];
        let mut feet = vec![Point3::origin(); self.morph.feet.len()];
        let mut prev_feet = feet.clone();
        let (mut sc, mut pen, mut sl) = (vec![false; n], vec![false; n], vec![false; n]);
        for t in 0..n {
            self.checks.place(self.tree, &poses[t], &mut scratch);
            sc[t] = self.checks.collisions(&scratch, |k| pair_frames[k] += 1) > 0;
            for (p, &f) in feet.iter_mut().zip(&self.morph.feet) {
                *p = self.morph.ee_point(f, &scratch.links);
            }
            // The foot points are at hand: `penetrates` without computing them again.
            pen[t] = feet.iter().any(|p| p.z < below) || self.checks.geometry_penetrates(&scratch);
            if continues[t] {
                sl[t] = feet
                    .iter()
                    .zip(&prev_feet)
                    .any(|(p, q)| p.z < band && q.z < band && (p.x - q.x).hypot(p.y - q.y) > step_limit);
            }
            std::mem::swap(&mut feet, &mut prev_feet);
        }
        self.report(sc, pen, sl, &pair_frames)
    }

    fn report(&self, sc: Vec<bool>, pen: Vec<bool>, sl: Vec<bool>, pair_frames: &[usize]) -> UfrReport {
        let n = sc.len();
        let any: Vec<bool> = (0..n).map(|t| sc[t] || pen[t] || sl[t]).collect();
        let rate = |v: &[bool]| {
            if n == 0 {
                0.0
            } else {
                v.iter().filter(|&&b| b).count() as f32 / n as f32
            }
        };
        let mut pairs: Vec<(usize, usize)> = pair_frames
            .iter()
            .enumerate()
            .filter(|(_, c)| **c > 0)
            .map(|(k, c)| (k, *c))
            .collect();
        pairs.sort_by(|a, b| b.1.cmp(&a.1).then(a.0.cmp(&b.0)));
        let bodies = self.self_collision().bodies();
        let name = |b: usize| self.tree.links[bodies[b].link].name.clone();
        let collision_pairs = pairs
            .into_iter()
            .take(10)
            .map(|(k, frames)| {
                let (a, b) = self.self_collision().pairs()[k];
                PairCount {
                    a: name(a),
                    b: name(b),
                    frames,
                }
            })
            .collect();
        UfrReport {
            frames: n,
            rates: UfrRates {
                ufr: rate(&any),
                self_collision: rate(&sc),
                penetration: rate(&pen),
                sliding: rate(&sl),
            },
            self_collision: sc,
            penetration: pen,
            sliding: sl,
            any,
            collision_pairs,
            config: self.config,
        }
    }
}
