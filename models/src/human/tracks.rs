//! Per-frame positions of the canonical joints and the feet in the file's axes and units, and the
//! measurements the importer takes on them.

use nalgebra::Vector3;

use super::bvh::Bvh;
use super::fk::{Pose, Translation};
use super::matching::SkeletonMap;
use super::skeleton::{JOINT_COUNT, Joint};

/// Per-frame positions in file axes and units: the canonical joints, and the box that bounds the feet
/// (ankles, toes, their end sites), for the floor.
pub(super) struct Tracks {
    pub joints: Vec<[Vector3<f32>; JOINT_COUNT]>,
    /// Per frame, the coordinate-wise least and greatest of both feet's points: two vectors whatever
    /// the number of points, and enough for the lowest point along an axis ([`lowest_foot`]).
    pub feet: Vec<[Vector3<f32>; 2]>,
}

impl Tracks {
    pub fn frame_count(&self) -> usize {
        self.joints.len()
    }
}

/// Points (joint, local offset) that bound a subtree: each joint and each end site below `root`.
fn subtree_points(bvh: &Bvh, root: usize) -> Vec<(usize, Vector3<f32>)> {
    let mut inside = vec![false; bvh.joints.len()];
    let mut out = Vec::new();
    for (j, joint) in bvh.joints.iter().enumerate() {
        inside[j] = j == root || joint.parent.is_some_and(|p| inside[p]);
        if inside[j] {
            out.push((j, Vector3::zeros()));
            out.extend(joint.end_sites.iter().map(|o| (j, *o)));
        }
    }
    out
}

/// Positions at `frames`, with `modes` translation semantics per joint.
pub(super) fn track(
    bvh: &Bvh,
    map: &SkeletonMap,
    frames: &[usize],
    modes: &[Translation],
) -> Tracks {
    let mut feet = subtree_points(bvh, map.index(Joint::LeftFoot));
    feet.extend(subtree_points(bvh, map.index(Joint::RightFoot)));
    let mut wanted: Vec<usize> = feet.iter().map(|(j, _)| *j).collect();
    wanted.extend(Joint::ALL.iter().flat_map(|&j| map.indices(j)));
    let mut pose = Pose::for_joints(bvh, &wanted);
    let mut tracks = Tracks {
        joints: Vec::with_capacity(frames.len()),
        feet: Vec::with_capacity(frames.len()),
    };
    for &f in frames {
        pose.compute(bvh, f, modes);
        tracks
            .joints
            .push(std::array::from_fn(|k| map.position(&pose, Joint::ALL[k])));
        let bounds = feet.iter().map(|(j, o)| pose.point(*j, o)).fold(
            [Vector3::repeat(f32::INFINITY), Vector3::repeat(f32::NEG_INFINITY)],
            |[lo, hi], p| [lo.inf(&p), hi.sup(&p)],
        );
        tracks.feet.push(bounds);
    }
    tracks
}

/// Median (upper median for even lengths); 0 for no values.
pub(super) fn median(mut v: Vec<f32>) -> f32 {
    if v.is_empty() {
        return 0.0;
    }
    v.sort_by(f32::total_cmp);
    v[v.len() / 2]
}

/// The `q` quantile (nearest rank); 0 for no values.
pub(super) fn percentile(mut v: Vec<f32>, q: f32) -> f32 {
    if v.is_empty() {
        return 0.0;
    }
    v.sort_by(f32::total_cmp);
    v[((v.len() - 1) as f32 * q).round() as usize]
}

/// Per-frame height of the lowest foot point along `up`, a signed coordinate axis (as [`UpAxis`]
/// gives): along an axis the lowest point of the feet is the lowest corner of their box.
///
/// [`UpAxis`]: super::units::UpAxis
pub(super) fn lowest_foot(tracks: &Tracks, up: &Vector3<f32>) -> Vec<f32> {
    tracks
        .feet
        .iter()
        .map(|[lo, hi]| (0..3).map(|i| up[i] * if up[i] >= 0.0 { lo[i] } else { hi[i] }).sum())
        .collect()
}

/// Leg length (hip to ankle, mean of both sides) in file units, from the posed bones.
pub(super) fn leg_length(tracks: &Tracks) -> f32 {
    use Joint::*;
    let lens: Vec<f32> = tracks
        .joints
        .iter()
        .map(|p| {
            let side = |a: Joint, b: Joint, c: Joint| {
                (p[a.index()] - p[b.index()]).norm() + (p[b.index()] - p[c.index()]).norm()
            };
            0.5 * (side(LeftThigh, LeftShin, LeftFoot) + side(RightThigh, RightShin, RightFoot))
        })
        .collect();
    median(lens)
}
