//! How fast a robot's leg joints let its feet swing, and so how fast it may walk in each gait: the
//! legged counterpart of a wheeled base's limit ([`super::Rig::max_speed`]), from the joints' velocity
//! limits (the URDF's `<limit velocity>`).
//!
//! In a steady gait of duty factor β and period T the swinging foot covers the stride `v·T` (world
//! frame) in the swing's `(1 − β)·T`, moving horizontally over the middle `1 − 2·edge` of it
//! ([`super::legs::edge`]) along a minimum-jerk profile, whose peak speed is [`MIN_JERK_PEAK`] times
//! its mean. Relative to the body, which moves on at `v`, the foot's peak speed is
//! `v · (1.875 / ((1 − 2·edge)(1 − β)) − 1)` ([`swing_speed_ratio`]), whatever the stride frequency.
//! A leg's joints let its foot move at most [`foot_speed_limit`] relative to the body; the body may
//! move no faster than that over the ratio. A wave gait, whose feet are on the ground five sixths of the
//! time, is therefore slow: the bundled crab's joints (6 rad/s) let it wave-walk at a few cm/s and
//! tripod-walk several times faster, as a servo-driven hexapod does.

use nalgebra::{DMatrix, Point3, Vector3};

use super::chain::{Chain, ChainScratch};
use crate::kinematics::KinematicTree;

/// Peak over mean speed of the minimum-jerk profile `10s³ − 15s⁴ + 6s⁵` (its slope at `s = ½`).
pub const MIN_JERK_PEAK: f32 = 1.875;

/// Horizontal directions checked by [`foot_speed_limit`].
const DIRECTIONS: usize = 16;

/// The swinging foot's peak speed relative to the body per unit of body speed, in a steady gait of duty
/// factor `duty` whose swings move horizontally over the middle `1 − 2·edge` of their time (module
/// docs). At least 1: the foot never moves more slowly than the ground passes under the body.
pub fn swing_speed_ratio(duty: f32, edge: f32) -> f32 {
    let moving = ((1.0 - 2.0 * edge) * (1.0 - duty)).max(1e-6);
    (MIN_JERK_PEAK / moving - 1.0).max(1.0)
}

/// The largest horizontal speed (m/s, relative to the root) at which the foot of `chain` can move in
/// every direction with the chain at `q` and none of its joints past its velocity limit: for each of
/// [`DIRECTIONS`] directions, the joint rates of a unit foot velocity (the least-norm ones, by the
/// pseudo-inverse of the numerical position Jacobian) against each joint's limit. Infinite when no
/// joint of the chain has a velocity limit, or where the chain cannot move its foot at all.
pub fn foot_speed_limit(tree: &KinematicTree, chain: &Chain, q: &[f32], scratch: &mut ChainScratch) -> f32 {
    let dofs: Vec<usize> = chain.active_dofs().collect();
    let limits: Vec<f32> = dofs
        .iter()
        .map(|&d| tree.limits(d).and_then(|l| l.velocity_bound()).unwrap_or(f32::INFINITY))
        .collect();
    if limits.iter().all(|l| l.is_infinite()) {
        return f32::INFINITY;
    }
    let jacobian = numerical_jacobian(tree, chain, q, &dofs, scratch);
    let Ok(pinv) = jacobian.pseudo_inverse(1e-6) else {
        return f32::INFINITY;
    };
    let mut slowest = f32::INFINITY;
    for k in 0..DIRECTIONS {
        let a = std::f32::consts::TAU * k as f32 / DIRECTIONS as f32;
        let rates = &pinv * DMatrix::from_column_slice(3, 1, &[a.cos(), a.sin(), 0.0]);
        // Joint rates per m/s of foot speed, over each joint's limit: the speed is 1 over the largest
        // (infinite where no joint moves).
        let load = rates
            .iter()
            .zip(&limits)
            .map(|(r, l)| r.abs() / l)
            .fold(0.0, f32::max);
        slowest = slowest.min(1.0 / load);
    }
    slowest
}

/// The foot's position Jacobian (3 × `dofs`, root frame) at `q`, by central differences (mimic joints
/// follow their DoF as in [`Chain::tip_point`]).
fn numerical_jacobian(
    tree: &KinematicTree,
    chain: &Chain,
    q: &[f32],
    dofs: &[usize],
    scratch: &mut ChainScratch,
) -> DMatrix<f32> {
    const STEP: f32 = 1e-3;
    let mut q = q.to_vec();
    let mut jacobian = DMatrix::zeros(3, dofs.len());
    for (c, &d) in dofs.iter().enumerate() {
        let x = q[d];
        q[d] = x + STEP;
        let plus = chain.tip_point(tree, &q, scratch);
        q[d] = x - STEP;
        let minus = chain.tip_point(tree, &q, scratch);
        q[d] = x;
        let column: Vector3<f32> = (plus - minus) / (2.0 * STEP);
        jacobian.set_column(c, &column);
    }
    jacobian
}

/// The foot speed limit of a leg over the middle of its swing: at its nominal foothold (`foot`, root
/// frame) on the ground and raised by `swing_height`, where a swing is fastest, each solved by IK from
/// the nominal stance `nominal_q`; the smaller of the two.
pub fn swing_foot_speed_limit(
    tree: &KinematicTree,
    chain: &Chain,
    nominal_q: &[f32],
    foot: Point3<f32>,
    swing_height: f32,
    scratch: &mut ChainScratch,
) -> f32 {
    [0.0, swing_height]
        .into_iter()
        .map(|dz| {
            let mut q = nominal_q.to_vec();
            let target = foot + Vector3::z() * dz;
            chain.solve(tree, &mut q, &target, 1e-5, 100, scratch);
            foot_speed_limit(tree, chain, &q, scratch)
        })
        .fold(f32::INFINITY, f32::min)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::morphology::Morphology;

    /// The bundled crab (6 rad/s joints) standing, with IK scratch space.
    fn crab() -> (KinematicTree, Morphology, Vec<f32>, ChainScratch) {
        let file = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../assets/characters/crab.urdf");
        let (tree, morph) = crate::morphology::load_character(&file).unwrap();
        let q = tree.standing_pose().q;
        (tree, morph, q, ChainScratch::default())
    }

    #[test]
    fn the_swing_ratio_follows_the_duty_factor() {
        // A trot (β ½) with no edge: the foot covers the stride in half the period at 1.875 times the mean,
        // 2·1.875·v in the world, 2.75·v relative to the body.
        assert!((swing_speed_ratio(0.5, 0.0) - 2.75).abs() < 1e-5);
        // A hexapod's wave gait (β ⅚) with the default edge of 0.2.
        let wave = swing_speed_ratio(5.0 / 6.0, 0.2);
        assert!((wave - (1.875 / (0.6 / 6.0) - 1.0)).abs() < 1e-3, "{wave}");
        assert!(swing_speed_ratio(0.4, 0.2) < swing_speed_ratio(0.6, 0.2));
    }

    #[test]
    fn a_leg_is_as_fast_as_its_slowest_joint_allows() {
        let (tree, morph, q, mut scratch) = crab();
        // Moving a foot at its limit speed in its worst direction takes one joint to its limit (6 rad/s)
        // and none past it: checked by IK on the real chain, not the function's own Jacobian, on every
        // leg (the left and right legs' worst directions mirror each other).
        for &foot in &morph.feet {
            let chain = Chain::new(&tree, &morph, foot);
            let v = foot_speed_limit(&tree, &chain, &q, &mut scratch);
            assert!(v.is_finite() && v > 0.0, "{v}");
            let dofs: Vec<usize> = chain.active_dofs().collect();
            let worst = (0..DIRECTIONS)
                .map(|k| {
                    let a = std::f32::consts::TAU * k as f32 / DIRECTIONS as f32;
                    let u = Vector3::new(a.cos(), a.sin(), 0.0) * v;
                    // IK to a target 1 ms ahead at speed v: the joints' travel over 1 ms.
                    let here = chain.tip_point(&tree, &q, &mut scratch);
                    let mut q1 = q.clone();
                    chain.solve(&tree, &mut q1, &(here + u * 1e-3), 1e-8, 200, &mut scratch);
                    dofs.iter().map(|&d| (q1[d] - q[d]).abs() / 1e-3).fold(0.0, f32::max)
                })
                .fold(0.0, f32::max);
            assert!((worst - 6.0).abs() < 0.1, "foot {foot}: fastest joint at the limit speed: {worst} rad/s");
        }
        let chain = Chain::new(&tree, &morph, morph.feet[0]);
        let dofs: Vec<usize> = chain.active_dofs().collect();
        let v = foot_speed_limit(&tree, &chain, &q, &mut scratch);
        // Twice the velocity limits, twice the speed.
        let mut fast = tree.clone();
        let set_limits = |tree: &mut KinematicTree, f: &dyn Fn(f32) -> f32| {
            for &d in &dofs {
                let l = tree.dof_link(d);
                let limits = tree.links[l].joint.as_mut().and_then(|j| j.limits.as_mut()).unwrap();
                limits.velocity = f(limits.velocity);
            }
        };
        set_limits(&mut fast, &|v| 2.0 * v);
        let v2 = foot_speed_limit(&fast, &chain, &q, &mut scratch);
        assert!((v2 / v - 2.0).abs() < 1e-3, "{v} {v2}");
        // No velocity limits (URDF's 0): no bound.
        set_limits(&mut fast, &|_| 0.0);
        assert!(foot_speed_limit(&fast, &chain, &q, &mut scratch).is_infinite());
    }

    #[test]
    fn a_swing_is_as_fast_as_its_slower_end_of_the_middle_allows() {
        // The swing's limit is the smaller of the foot's on the ground and raised by the swing height.
        let (tree, morph, q, mut scratch) = crab();
        let chain = Chain::new(&tree, &morph, morph.feet[0]);
        let foot = chain.tip_point(&tree, &q, &mut scratch);
        let at = |dz: f32, scratch: &mut ChainScratch| {
            let mut q1 = q.clone();
            let r = chain.solve(&tree, &mut q1, &(foot + Vector3::z() * dz), 1e-5, 100, scratch);
            assert!(r.error < 1e-4);
            foot_speed_limit(&tree, &chain, &q1, scratch)
        };
        let height = 0.03;
        let (ground, raised, lowered) = (at(0.0, &mut scratch), at(height, &mut scratch), at(-height, &mut scratch));
        assert!((raised - lowered).abs() > 0.01 * raised, "raising and lowering differ: {raised} {lowered}");
        let swing = swing_foot_speed_limit(&tree, &chain, &q, foot, height, &mut scratch);
        assert!((swing - ground.min(raised)).abs() < 1e-3 * swing, "{swing} {ground} {raised} {lowered}");
    }
}
