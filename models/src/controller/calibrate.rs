//! Leg calibration for [`super::Rig`]: what each leg can do, found by IK and collision tests rather
//! than assumed.
//!
//! - **Reach**: the maximal hip–foot distance, by sampling the leg's joint space.
//! - **Nominal height**: the standing root height, lowered until no leg is stretched beyond
//!   [`super::LegConfig::max_extension`] of its reach, so that legs are bent and can step. The nominal
//!   joint vector is the IK solution with every foot under its standing position.
//! - **Step radius** `r_max` per leg: the largest horizontal distance from the nominal foothold at which
//!   IK still reaches the ground point within 0.3 mm, with joints in limits, the leg clear of the body
//!   and the other legs, and nothing of the leg below the ground, for the lowest and highest body height
//!   and the extreme pitch and roll (bisection over 8 directions); times 0.9, and at most 0.35 × the
//!   distance to the nearest foot on the same side (neighbours swinging past each other at full stride
//!   keep apart) and 0.45 × the distance to the nearest foot across the body. Along the body the region
//!   reaches further: `r_fore`, the fore-and-aft semi-axis of the largest ellipse with `r_max` across
//!   that passes the same checks (8 points on it), capped at 0.4 × the distance to the nearest foot on the
//!   same side only (a front and a hind foot at full stride keep a fifth of their distance apart).
//!   The body is an obstacle for the step regions, but the **appendages** are not ([`appendages`]: links
//!   on DoFs no leg owns that carry no leg — a tail, a neck and head, an arm): they move, so they are
//!   stowed clear of the legs' workspace instead ([`stow_appendages`]); an appendage that cannot be
//!   stowed clear stays where it is and the legs are calibrated again to step around it. Redundant legs
//!   (ball joints) get more IK iterations in these checks ([`ik_iterations`]).
//! - **Posture range**: if some leg cannot step at least 12 % of its length at the configured body
//!   height and tilt extremes, the range is halved (up to three times, then none) and the best kept.
//!   A range that passes is halved once more when that lengthens the weakest leg's fore-and-aft step
//!   by half (`POSTURE_TRADE`): just past 12 % a leg may step too short for an animal's stride.
//! - **Sole**: a foot whose geometry would dip more than half the allowed slack ([`dip_tolerance`])
//!   below the ground at some posture with its foot point on the ground keeps the foot point that much
//!   above the ground in stance (e.g. a sphere foot whose point was found at a straight-legged neutral
//!   pose).
//! - **Swing height**: [`super::LegConfig::swing_height`] × the leg length, lowered until the lifted foot
//!   is reachable with the body at its lowest.

use std::collections::BTreeMap;

use nalgebra::{Isometry3, Point3, Vector2};
use rand::SeedableRng;

use super::chain::{Chain, ChainScratch};
use super::collide::{Obb, Proxies};
use super::rig::{Leg, Obstacle, finite_limits, subtree, tilted_root};
use super::{ControllerError, uniform};
use crate::geometry::Shape;
use crate::kinematics::{CharacterPose, KinematicTree};
use crate::morphology::Morphology;

/// IK tolerance in calibration (m).
const IK_TOL: f32 = 1e-5;
/// Largest IK error at which a calibration pose counts as reached (m).
const REACHED: f32 = 3e-4;
/// Smallest step radius, as a fraction of the leg's length, that the weakest leg must keep at the
/// posture range's extremes before the range is halved.
const MIN_STEP: f32 = 0.12;
/// A range that passes is still halved once more when that lengthens the weakest leg's fore-and-aft
/// step by this factor: the step region sets the stride (and so the cadence), the posture range only
/// how far the body heaves and tilts.
const POSTURE_TRADE: f32 = 1.5;
/// Joint-space samples for a leg's reach.
const REACH_SAMPLES: usize = 512;

/// IK iterations of a step-region check: damped least squares converges slowly near the edge of
/// the workspace of a redundant leg (ball joints), which would otherwise pass for out of reach.
pub fn ik_iterations(chain: &Chain) -> usize {
    if chain.active_dofs().nth(3).is_some() {
        200
    } else {
        60
    }
}

/// Body heights and tilts a leg must cope with: `(root height, pitch, roll)`.
pub type Posture = (f32, f32, f32);

/// The extremes of a height range and tilt.
pub fn postures(height: [f32; 2], tilt: [f32; 2]) -> [Posture; 6] {
    [
        (height[0], 0.0, 0.0),
        (height[1], 0.0, 0.0),
        (height[0], tilt[0], tilt[1]),
        (height[0], -tilt[0], -tilt[1]),
        (height[1], tilt[0], -tilt[1]),
        (height[1], -tilt[0], tilt[1]),
    ]
}

/// How far a foot's own geometry may dip below the ground while its foot point stays on it (a sphere
/// rolling about its sole point): 0.5 % of the standing height, at least 1 mm.
pub fn dip_tolerance(tree: &KinematicTree, standing: &CharacterPose) -> f32 {
    let b = tree.aabb(&tree.forward_kinematics(standing));
    (0.005 * (b.max.z - b.min.z)).max(1e-3)
}

/// The legs of a character with their chains, hips, standing footholds and reach (`length` holds the
/// reach until [`nominal_stance`] sets the nominal length).
pub fn legs(tree: &KinematicTree, morph: &Morphology, standing: &CharacterPose) -> Result<Vec<Leg>, ControllerError> {
    let links = tree.forward_kinematics(&CharacterPose {
        root: Isometry3::identity(),
        q: standing.q.clone(),
    });
    let mut scratch = ChainScratch::default();
    let mut rng = rand_pcg::Pcg64::seed_from_u64(0x1e65);
    let mut legs = Vec::new();
    for &foot in &morph.feet {
        let (chain, on_spine) = Chain::limb(tree, morph, foot);
        let Some(first) = chain.first_moving() else {
            return Err(leg_error(
                tree,
                foot,
                "no movable joint between the root and the foot".into(),
            ));
        };
        let hip = links[chain.links[first]].translation.vector;
        let sole = morph.ee_point(foot, &links).coords;
        let mut q = standing.q.clone();
        let mut reach = (chain.tip_point(tree, &q, &mut scratch).coords - hip).norm();
        for _ in 0..REACH_SAMPLES {
            for d in chain.active_dofs() {
                let (lo, hi) = finite_limits(tree, d, standing.q[d]);
                q[d] = uniform(&mut rng, lo, hi);
            }
            reach = reach.max((chain.tip_point(tree, &q, &mut scratch).coords - hip).norm());
        }
        legs.push(Leg {
            links: subtree(tree, chain.links[first]),
            chain,
            foot,
            hip,
            nominal: Vector2::new(sole.x, sole.y),
            length: reach,
            r_max: 0.0,
            r_fore: 0.0,
            swing_height: 0.0,
            sole: 0.0,
            on_spine,
        });
    }
    Ok(legs)
}

fn leg_error(tree: &KinematicTree, foot: usize, problem: String) -> ControllerError {
    ControllerError::Leg {
        foot: tree.links[foot].name.clone(),
        problem,
    }
}

/// The nominal root height (see the module docs) and the joint vector with every foot under its
/// standing position; sets each leg's nominal `length`.
pub fn nominal_stance(
    tree: &KinematicTree,
    legs: &mut [Leg],
    standing: &CharacterPose,
    max_extension: f32,
) -> Result<(f32, Vec<f32>), ControllerError> {
    let mut h0 = standing.root.translation.vector.z;
    for leg in legs.iter() {
        let dxy = (leg.hip.xy() - leg.nominal).norm();
        let dmax = max_extension * leg.length;
        if dmax > dxy {
            // |hip − foot| at root height h is √(dxy² + (h + hip.z)²).
            h0 = h0.min((dmax * dmax - dxy * dxy).sqrt() - leg.hip.z);
        }
    }
    let mut q = standing.q.clone();
    let root = tilted_root(h0, 0.0, 0.0);
    let mut scratch = ChainScratch::default();
    for leg in legs.iter_mut() {
        let target = root.inverse_transform_point(&Point3::new(leg.nominal.x, leg.nominal.y, 0.0));
        let r = leg.chain.solve(tree, &mut q, &target, IK_TOL, 300, &mut scratch);
        if r.error > 1e-3 {
            // Most often the leg's joints are limited too narrowly to bend that far: name those at a limit.
            let stuck: Vec<String> = leg
                .chain
                .active_dofs()
                .filter(|&d| {
                    tree.limits(d).is_some_and(|l| (q[d] - l.lower).abs() < 1e-3 || (q[d] - l.upper).abs() < 1e-3)
                })
                .map(|d| tree.dof_joint(d).name.clone())
                .collect();
            let at_limits = if stuck.is_empty() {
                String::new()
            } else {
                format!("; at their limits: {} (widen them to let the leg bend further)", stuck.join(", "))
            };
            return Err(leg_error(
                tree,
                leg.foot,
                format!(
                    "cannot place the foot under its standing position at body height {h0:.3} m (IK error {:.1} mm){at_limits}",
                    r.error * 1e3
                ),
            ));
        }
        leg.length = (target.coords - leg.hip).norm();
    }
    Ok((h0, q))
}

/// The outcome of [`step_radii`].
pub struct StepRadii {
    /// Height range kept (m).
    pub height: [f32; 2],
    /// Tilt kept (pitch, roll; rad).
    pub tilt: [f32; 2],
}

/// One posture range tried by [`step_radii`]: each leg's step radius and sole there.
struct Range {
    /// The weakest leg's step radius relative to its length.
    worst: f32,
    radii: Vec<f32>,
    soles: Vec<f32>,
    height: [f32; 2],
    tilt: [f32; 2],
}

/// What every posture range of [`step_radii`] is checked against: the character, its collision
/// proxies, the nominal height `h0`, the foot's dip tolerance and the links the checks ignore.
struct Stepping<'a> {
    tree: &'a KinematicTree,
    proxies: &'a Proxies,
    h0: f32,
    dip_tol: f32,
    ignore: &'a [bool],
}

impl Stepping<'_> {
    /// The legs' soles and step radii over `shrink` × the configured posture range (`height`,
    /// `tilt`); sets each leg's sole and moves `nominal_q` onto them.
    fn try_range(
        &self,
        legs: &mut [Leg],
        nominal_q: &mut [f32],
        (height, tilt, shrink): ([f32; 2], [f32; 2], f32),
        scratch: &mut ChainScratch,
    ) -> Range {
        let (tree, proxies, h0) = (self.tree, self.proxies, self.h0);
        let root0 = tilted_root(h0, 0.0, 0.0);
        let hr = [h0 + (height[0] - h0) * shrink, h0 + (height[1] - h0) * shrink];
        let tl = [tilt[0] * shrink, tilt[1] * shrink];
        let poses = postures(hr, tl);
        for leg in legs.iter_mut() {
            leg.sole = sole(tree, proxies, leg, nominal_q, &poses, self.dip_tol, scratch);
            let target = root0.inverse_transform_point(&Point3::new(leg.nominal.x, leg.nominal.y, leg.sole));
            leg.chain.solve(tree, nominal_q, &target, IK_TOL, 100, scratch);
        }
        let scene = Scene::new(proxies, fk_root(tree, nominal_q), self.ignore);
        let radii: Vec<f32> = (0..legs.len())
            .map(|i| 0.9 * radius(tree, proxies, &scene, legs, i, nominal_q, &poses, self.dip_tol, None, scratch))
            .collect();
        let worst = legs.iter().zip(&radii).map(|(l, r)| r / l.length).fold(f32::INFINITY, f32::min);
        Range { worst, radii, soles: legs.iter().map(|l| l.sole).collect(), height: hr, tilt: tl }
    }

    /// Puts the legs on range `r`: their soles (moving `nominal_q` onto them where they changed), step
    /// radii and fore-and-aft semi-axes, the latter from the same checks over the ellipse with the
    /// lateral semi-axis kept. Returns the weakest leg's fore-and-aft semi-axis relative to its length.
    fn settle(&self, legs: &mut [Leg], nominal_q: &mut [f32], r: &Range, scratch: &mut ChainScratch) -> f32 {
        let (tree, proxies) = (self.tree, self.proxies);
        let root0 = tilted_root(self.h0, 0.0, 0.0);
        for ((leg, &radius), &s) in legs.iter_mut().zip(&r.radii).zip(&r.soles) {
            leg.r_max = radius;
            leg.r_fore = radius;
            if leg.sole != s {
                leg.sole = s;
                let target = root0.inverse_transform_point(&Point3::new(leg.nominal.x, leg.nominal.y, s));
                leg.chain.solve(tree, nominal_q, &target, IK_TOL, 100, scratch);
            }
        }
        let poses = postures(r.height, r.tilt);
        let scene = Scene::new(proxies, fk_root(tree, nominal_q), self.ignore);
        let fore: Vec<f32> = (0..legs.len())
            .map(|i| {
                let lateral = legs[i].r_max / 0.9;
                0.9 * radius(tree, proxies, &scene, legs, i, nominal_q, &poses, self.dip_tol, Some(lateral), scratch)
            })
            .collect();
        for (leg, f) in legs.iter_mut().zip(fore) {
            leg.r_fore = f.max(leg.r_max);
        }
        legs.iter().map(|l| l.r_fore / l.length).fold(f32::INFINITY, f32::min)
    }
}

/// Finds each leg's sole and step radius, shrinking the posture range if needed (module docs); updates
/// `nominal_q` for the soles. `h0` is the nominal height, `height` and `tilt` the configured range.
#[allow(clippy::too_many_arguments)]
pub fn step_radii(
    tree: &KinematicTree,
    proxies: &Proxies,
    legs: &mut [Leg],
    nominal_q: &mut [f32],
    h0: f32,
    height: [f32; 2],
    tilt: [f32; 2],
    dip_tol: f32,
    ignore: &[bool],
) -> Result<StepRadii, ControllerError> {
    let mut scratch = ChainScratch::default();
    let stepping = Stepping { tree, proxies, h0, dip_tol, ignore };
    const SHRINKS: [f32; 4] = [1.0, 0.5, 0.25, 0.0];
    let mut best: Option<Range> = None;
    let mut next = None;
    for (k, shrink) in SHRINKS.into_iter().enumerate() {
        let r = stepping.try_range(legs, nominal_q, (height, tilt, shrink), &mut scratch);
        let passed = r.worst >= MIN_STEP;
        if best.as_ref().is_none_or(|b| r.worst > b.worst) {
            best = Some(r);
        }
        if passed {
            next = SHRINKS.get(k + 1).copied();
            break;
        }
    }
    let mut best = best.expect("at least one posture range is tried");
    let fore = stepping.settle(legs, nominal_q, &best, &mut scratch);
    // A passing range is halved once more when that lengthens the weakest leg's stride enough
    // (module docs); otherwise the legs go back exactly as they were.
    if let Some(shrink) = next {
        let (kept_q, kept_legs) = (nominal_q.to_vec(), legs.to_vec());
        let r = stepping.try_range(legs, nominal_q, (height, tilt, shrink), &mut scratch);
        if stepping.settle(legs, nominal_q, &r, &mut scratch) >= POSTURE_TRADE * fore {
            best = r;
        } else {
            nominal_q.copy_from_slice(&kept_q);
            legs.clone_from_slice(&kept_legs);
        }
    }
    if best.worst < 0.03 {
        let leg = legs
            .iter()
            .min_by(|a, b| (a.r_max / a.length).total_cmp(&(b.r_max / b.length)))
            .expect("legs");
        // What stops it: the obstacles just beyond its step radius, over the footholds and postures tried.
        let scene = Scene::new(proxies, fk_root(tree, nominal_q), ignore);
        let poses = postures(best.height, best.tilt);
        let mut seen: BTreeMap<Blocker, usize> = BTreeMap::new();
        for foot in footholds(leg, leg.r_max / 0.9 + 0.02 * leg.length, None) {
            for &(h, pitch, roll) in &poses {
                let root = tilted_root(h, pitch, roll);
                if let Some(o) = leg_pose_blocker(tree, proxies, &scene, nominal_q, leg, &root, &foot, dip_tol, &mut scratch) {
                    *seen.entry(o).or_default() += 1;
                }
            }
        }
        let tries = 8 * poses.len();
        let most = seen.into_iter().max_by_key(|&(_, n)| n);
        let stopped = most.map_or(String::new(), |(o, n)| {
            format!(": most often {} ({n} of {tries} footholds just beyond it)", o.describe(tree))
        });
        return Err(leg_error(
            tree,
            leg.foot,
            format!(
                "the foot can hardly move from its nominal foothold (step radius {:.1} mm) without leaving its \
                 joint limits, colliding with the body or another leg, or sinking into the ground{stopped}",
                leg.r_max * 1e3
            ),
        ));
    }
    Ok(StepRadii {
        height: best.height,
        tilt: best.tilt,
    })
}

/// The sole height of a leg over `poses` (module docs).
fn sole(
    tree: &KinematicTree,
    proxies: &Proxies,
    leg: &Leg,
    nominal_q: &[f32],
    poses: &[Posture],
    dip_tol: f32,
    scratch: &mut ChainScratch,
) -> f32 {
    let mut dip = 0.0f32;
    for &(h, pitch, roll) in poses {
        let root = tilted_root(h, pitch, roll);
        let mut q = nominal_q.to_vec();
        let target = root.inverse_transform_point(&Point3::new(leg.nominal.x, leg.nominal.y, 0.0));
        leg.chain.solve(tree, &mut q, &target, IK_TOL, 100, scratch);
        dip = dip.max(-foot_lowest(tree, proxies, leg, &root, &q));
    }
    (dip - 0.5 * dip_tol).max(0.0)
}

/// The step radius of leg `i` (before the 0.9 margin), by bisection: of a circle, or with `lateral`
/// given, the fore-and-aft semi-axis of an ellipse with that lateral semi-axis (no cap from the feet
/// across the body, which move alongside).
#[allow(clippy::too_many_arguments)]
fn radius(
    tree: &KinematicTree,
    proxies: &Proxies,
    scene: &Scene,
    legs: &[Leg],
    i: usize,
    nominal_q: &[f32],
    poses: &[Posture],
    dip_tol: f32,
    lateral: Option<f32>,
    scratch: &mut ChainScratch,
) -> f32 {
    let leg = &legs[i];
    let cap = legs
        .iter()
        .enumerate()
        .filter(|&(j, _)| j != i)
        .filter_map(|(_, o)| {
            let d = (o.nominal - leg.nominal).norm();
            let same_side = (o.nominal.y > 0.0) == (leg.nominal.y > 0.0);
            match (same_side, lateral) {
                (true, None) => Some(0.35 * d),
                (true, Some(_)) => Some(0.4 * d),
                (false, None) => Some(0.45 * d),
                (false, Some(_)) => None,
            }
        })
        .fold(0.6 * leg.length, f32::min);
    let ok = |r: f32, scratch: &mut ChainScratch| {
        footholds(leg, r, lateral).all(|foot| {
            poses.iter().all(|&(h, pitch, roll)| {
                let root = tilted_root(h, pitch, roll);
                leg_pose_blocker(tree, proxies, scene, nominal_q, leg, &root, &foot, dip_tol, scratch).is_none()
            })
        })
    };
    if !ok(0.0, scratch) {
        return 0.0;
    }
    if ok(cap, scratch) {
        return cap;
    }
    let (mut lo, mut hi) = (0.0f32, cap);
    for _ in 0..10 {
        let mid = 0.5 * (lo + hi);
        if ok(mid, scratch) {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    lo
}

/// The eight footholds around the leg's nominal one that [`radius`] tries: at `r` fore and aft and
/// `lateral` (or `r`) to the sides, on the leg's sole.
fn footholds(leg: &Leg, r: f32, lateral: Option<f32>) -> impl Iterator<Item = Point3<f32>> + '_ {
    (0..8).map(move |k| {
        let a = k as f32 * std::f32::consts::FRAC_PI_4;
        let p = leg.nominal + Vector2::new(a.cos() * r, a.sin() * lateral.unwrap_or(r));
        Point3::new(p.x, p.y, leg.sole)
    })
}

/// Sets each leg's swing height (module docs).
pub fn swing_heights(tree: &KinematicTree, legs: &mut [Leg], nominal_q: &[f32], lowest: f32, fraction: f32) {
    let mut scratch = ChainScratch::default();
    let root = tilted_root(lowest, 0.0, 0.0);
    for leg in legs {
        let mut h = fraction * leg.length;
        for _ in 0..8 {
            let target = root.inverse_transform_point(&Point3::new(leg.nominal.x, leg.nominal.y, leg.sole + h));
            let mut q = nominal_q.to_vec();
            if leg.chain.solve(tree, &mut q, &target, IK_TOL, 100, &mut scratch).error < 1e-3 {
                break;
            }
            h *= 0.7;
        }
        leg.swing_height = h;
    }
}

/// Obstacles for the parts that move on their own (an appendage being stowed, a reach group), in the
/// frame of the root at the nominal height: the links on no leg for which `still` holds, at the nominal
/// pose, and the legs over their workspace ([`swept_legs`]).
pub fn obstacles(
    tree: &KinematicTree,
    proxies: &Proxies,
    legs: &[Leg],
    nominal_q: &[f32],
    h0: f32,
    height: [f32; 2],
    still: impl Fn(usize) -> bool,
) -> Vec<Obstacle> {
    let mut out: Vec<Obstacle> = fk_root(tree, nominal_q)
        .iter()
        .enumerate()
        .filter(|&(l, _)| !legs.iter().any(|g| g.links.contains(&l)) && still(l))
        .flat_map(|(l, pose)| proxies.world(l, pose).map(move |obb| Obstacle { link: l, obb }))
        .collect();
    out.extend(swept_legs(tree, proxies, legs, nominal_q, h0, height));
    out
}

/// Boxes of every leg over its workspace — standing at the nominal foothold and at the step radius in
/// 8 directions, lifted at mid-swing — at both ends of the height range, in the frame of the root at
/// the nominal height.
pub fn swept_legs(
    tree: &KinematicTree,
    proxies: &Proxies,
    legs: &[Leg],
    nominal_q: &[f32],
    h0: f32,
    height: [f32; 2],
) -> Vec<Obstacle> {
    let mut scratch = ChainScratch::default();
    let root0 = tilted_root(h0, 0.0, 0.0);
    let mut out = Vec::new();
    for leg in legs {
        let mut targets = vec![
            Point3::new(leg.nominal.x, leg.nominal.y, leg.sole),
            Point3::new(leg.nominal.x, leg.nominal.y, leg.sole + leg.swing_height),
        ];
        for k in 0..8 {
            let a = k as f32 * std::f32::consts::FRAC_PI_4;
            let p = leg.region_point(a, 1.0);
            targets.push(Point3::new(p.x, p.y, leg.sole));
            let p = leg.region_point(a, 0.6);
            targets.push(Point3::new(p.x, p.y, leg.sole + 0.8 * leg.swing_height));
        }
        for &h in &height {
            let root = tilted_root(h, 0.0, 0.0);
            for t in &targets {
                let mut q = nominal_q.to_vec();
                leg.chain.solve(
                    tree,
                    &mut q,
                    &root.inverse_transform_point(t),
                    IK_TOL,
                    100,
                    &mut scratch,
                );
                let links = tree.forward_kinematics(&CharacterPose {
                    root: root0.inverse() * root,
                    q,
                });
                for &l in &leg.links {
                    out.extend(proxies.world(l, &links[l]).map(|obb| Obstacle { link: l, obb }));
                }
            }
        }
    }
    out
}

/// Lowest z (relative to the root) of the boxes of `links` at root-frame poses `poses` when the body
/// is tilted by up to `tilt` (pitch, roll) either way.
pub fn lowest_tilted(proxies: &Proxies, poses: &[Isometry3<f32>], links: &[usize], tilt: [f32; 2]) -> f32 {
    let mut low = f32::INFINITY;
    for &(p, r) in &[(1.0, 1.0), (1.0, -1.0), (-1.0, 1.0), (-1.0, -1.0)] {
        let rot = tilted_root(0.0, p * tilt[0], r * tilt[1]);
        for &l in links {
            for b in proxies.world(l, &(rot * poses[l])) {
                low = low.min(b.min_z());
            }
        }
    }
    low
}

/// Link poses in the root frame for joint vector `q`.
pub fn fk_root(tree: &KinematicTree, q: &[f32]) -> Vec<Isometry3<f32>> {
    tree.forward_kinematics(&CharacterPose {
        root: Isometry3::identity(),
        q: q.to_vec(),
    })
}

/// The nominal pose in the root frame with the collision boxes of every link that is an obstacle for
/// the legs (all but the `ignore`d ones), for leg checks.
struct Scene {
    links: Vec<Isometry3<f32>>,
    boxes: Vec<Vec<Obb>>,
}

impl Scene {
    fn new(proxies: &Proxies, links: Vec<Isometry3<f32>>, ignore: &[bool]) -> Scene {
        let boxes = links
            .iter()
            .enumerate()
            .map(|(l, p)| {
                if ignore.get(l).copied().unwrap_or(false) {
                    Vec::new()
                } else {
                    proxies.world(l, p).collect()
                }
            })
            .collect();
        Scene { links, boxes }
    }
}

/// Poses (root frame) of the links of `leg` for joint vector `q`, the rest from `scene`, into `out`.
fn leg_poses(tree: &KinematicTree, scene: &Scene, leg: &Leg, q: &[f32], out: &mut Vec<Isometry3<f32>>) {
    out.clear();
    out.extend_from_slice(&scene.links);
    for &l in &leg.links {
        let link = &tree.links[l];
        if let (Some(p), Some(j)) = (link.parent, &link.joint) {
            out[l] = out[p] * j.transform(j.position(q));
        }
    }
}

/// What keeps a leg from a foothold in a posture ([`leg_pose_blocker`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord)]
enum Blocker {
    /// The foot cannot reach it within the leg's joint limits.
    Reach,
    /// Link `.0` of the leg collides with link `.1`.
    Collision(usize, usize),
    /// Link `.0` of the leg goes below the ground.
    Ground(usize),
}

impl Blocker {
    fn describe(self, tree: &KinematicTree) -> String {
        let name = |l: usize| &tree.links[l].name;
        match self {
            Blocker::Reach => "the foot cannot reach it within the leg's joint limits".into(),
            Blocker::Collision(a, b) => format!("`{}` collides with `{}`", name(a), name(b)),
            Blocker::Ground(l) => format!("`{}` goes below the ground", name(l)),
        }
    }
}

/// Why the leg cannot put its foot at the world point `foot` with the root at `root` (within joint
/// limits, clear of the rest of the body at the nominal pose and above the ground), or `None` when it
/// can.
#[allow(clippy::too_many_arguments)]
fn leg_pose_blocker(
    tree: &KinematicTree,
    proxies: &Proxies,
    scene: &Scene,
    nominal_q: &[f32],
    leg: &Leg,
    root: &Isometry3<f32>,
    foot: &Point3<f32>,
    dip_tol: f32,
    scratch: &mut ChainScratch,
) -> Option<Blocker> {
    let mut q = nominal_q.to_vec();
    if leg
        .chain
        .solve(tree, &mut q, &root.inverse_transform_point(foot), IK_TOL, ik_iterations(&leg.chain), scratch)
        .error
        > REACHED
    {
        return Some(Blocker::Reach);
    }
    let mut links = Vec::new();
    leg_poses(tree, scene, leg, &q, &mut links);
    let on_leg = |b: usize| leg.links.binary_search(&b).is_ok();
    for &a in &leg.links {
        let boxes: Vec<Obb> = proxies.world(a, &links[a]).collect();
        for b in 0..tree.links.len() {
            if on_leg(b) || !proxies.is_checked(a, b) {
                continue;
            }
            if boxes.iter().any(|x| scene.boxes[b].iter().any(|y| x.overlaps(y, 0.0))) {
                return Some(Blocker::Collision(a, b));
            }
        }
    }
    // Nothing below the ground: `dip_tol` of slack for the foot's own geometry, none for the rest of the
    // leg. Boxes of meshes on the foot's body are left out (their corners dip although the mesh does
    // not); the foot point stands for them.
    leg.links
        .iter()
        .copied()
        .find(|&l| {
            let foot_body = proxies.body[l] == proxies.body[leg.foot];
            let pose = root * links[l];
            !tree.links[l].extent_geometry().iter().all(|g| {
                if foot_body && matches!(g.shape, Shape::Mesh { .. }) {
                    return true;
                }
                g.aabb(&pose)
                    .is_none_or(|b| b.min.z > if foot_body { -dip_tol } else { 0.0 })
            })
        })
        .map(Blocker::Ground)
}

/// Lowest z of the geometry on the foot's rigid body (boxes of meshes left out) with the root at `root`.
fn foot_lowest(tree: &KinematicTree, proxies: &Proxies, leg: &Leg, root: &Isometry3<f32>, q: &[f32]) -> f32 {
    let links = tree.forward_kinematics(&CharacterPose {
        root: *root,
        q: q.to_vec(),
    });
    leg.links
        .iter()
        .filter(|&&l| proxies.body[l] == proxies.body[leg.foot])
        .flat_map(|&l| tree.links[l].extent_geometry().iter().map(move |g| (l, g)))
        .filter(|(_, g)| !matches!(g.shape, Shape::Mesh { .. }))
        .filter_map(|(l, g)| g.aabb(&links[l]))
        .map(|b| b.min.z)
        .fold(f32::INFINITY, f32::min)
}

/// Appendages: per link, whether it hangs off the body on DoFs that no leg owns and carries no leg — a
/// tail, a neck and head, an arm. They are not obstacles for the step regions ([`step_radii`]'s
/// `ignore`): they move, and [`stow_appendages`] keeps them clear of the legs instead. `skip` marks DoFs
/// that are not posed (wheels).
pub fn appendages(tree: &KinematicTree, legs: &[Leg], skip: &[bool]) -> Vec<bool> {
    let n = tree.links.len();
    let on_leg: Vec<bool> = (0..n).map(|l| legs.iter().any(|g| g.links.contains(&l))).collect();
    let mut leg_dof = vec![false; tree.dof()];
    for d in legs.iter().flat_map(|g| g.chain.active_dofs()) {
        leg_dof[d] = true;
    }
    let mut out = vec![false; n];
    for d in (0..tree.dof()).filter(|&d| !leg_dof[d] && !skip.get(d).copied().unwrap_or(false)) {
        let sub = subtree(tree, tree.dof_link(d));
        if sub.iter().all(|&l| !on_leg[l]) {
            for l in sub {
                out[l] = true;
            }
        }
    }
    out
}

/// Stows the appendages clear of the legs' workspace. Each appendage (the subtree of an appendage link
/// whose parent is not one, with its DoFs) whose boxes at the nominal configuration overlap `obstacles`
/// (root frame: the legs over their workspace and the rest of the body) by more than `margin` moves to
/// the nearest clear configuration among deterministic random draws around the nominal one, within
/// the joint limits, over growing spreads; its boxes must also stay above `floor` (root frame) or no
/// lower than they were. `proxies` decide which pairs count: pass those of the standing pose, so that
/// pairs let go because they touch at the nominal stance still count. Updates `nominal_q`; returns the
/// appendages that found no clear configuration (left as they were), by their top link.
pub fn stow_appendages(
    tree: &KinematicTree,
    proxies: &Proxies,
    appendage: &[bool],
    nominal_q: &mut [f32],
    obstacles: &[Obstacle],
    floor: f32,
    margin: f32,
) -> Vec<usize> {
    let tops: Vec<usize> = (0..tree.links.len())
        .filter(|&l| appendage[l] && tree.links[l].parent.is_none_or(|p| !appendage[p]))
        .collect();
    let mut rng = rand_pcg::Pcg64::seed_from_u64(0x57a1);
    let mut stuck = Vec::new();
    for top in tops {
        let links = subtree(tree, top);
        let dofs: Vec<usize> = (0..tree.dof())
            .filter(|&d| links.binary_search(&tree.dof_link(d)).is_ok())
            .collect();
        if dofs.is_empty() {
            continue;
        }
        let boxes_at = |q: &[f32]| -> Vec<(usize, Obb)> {
            let poses = fk_root(tree, q);
            links.iter().flat_map(|&l| proxies.world(l, &poses[l]).map(move |b| (l, b))).collect()
        };
        let lowest = |boxes: &[(usize, Obb)]| boxes.iter().map(|(_, b)| b.min_z()).fold(f32::INFINITY, f32::min);
        let nominal = boxes_at(nominal_q);
        let floor = floor.min(lowest(&nominal));
        let clear = |boxes: &[(usize, Obb)]| {
            lowest(boxes) >= floor
                && boxes.iter().all(|(a, x)| {
                    obstacles.iter().all(|o| {
                        links.binary_search(&o.link).is_ok()
                            || !proxies.is_checked(*a, o.link)
                            || !x.overlaps(&o.obb, margin)
                    }) && boxes
                        .iter()
                        .all(|(b, y)| b <= a || !proxies.is_checked(*a, *b) || !x.overlaps(y, margin))
                })
        };
        if clear(&nominal) {
            continue;
        }
        let ranges: Vec<(f32, f32)> = dofs.iter().map(|&d| finite_limits(tree, d, nominal_q[d])).collect();
        let mut best: Option<(f32, Vec<f32>)> = None;
        for spread in [0.05f32, 0.1, 0.2, 0.3, 0.5] {
            for _ in 0..64 {
                let mut q = nominal_q.to_vec();
                let mut cost = 0.0;
                for (&d, &(lo, hi)) in dofs.iter().zip(&ranges) {
                    let r = spread * (hi - lo);
                    q[d] = uniform(&mut rng, (nominal_q[d] - r).max(lo), (nominal_q[d] + r).min(hi));
                    cost += ((q[d] - nominal_q[d]) / (hi - lo).max(1e-6)).powi(2);
                }
                if best.as_ref().is_none_or(|(c, _)| cost < *c) && clear(&boxes_at(&q)) {
                    best = Some((cost, dofs.iter().map(|&d| q[d]).collect()));
                }
            }
            if best.is_some() {
                break;
            }
        }
        match best {
            Some((_, q)) => {
                for (&d, x) in dofs.iter().zip(q) {
                    nominal_q[d] = x;
                }
            }
            None => stuck.push(top),
        }
    }
    stuck
}
