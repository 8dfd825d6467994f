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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::human::fk::Translation;
    use crate::human::test_rig::{bvh, leg, rig, torso};

    /// The tracks of a rig at rest whose left foot has a toe (ahead, below the ankle) and whose right
    /// shin is 50 long, the left 40; the feet's end sites stand 1 above their last joint. Position
    /// channels are added to the OFFSET: the root (whose channels are zero) stands at its OFFSET
    /// (0, 90, 0).
    fn rig_with_toe() -> Tracks {
        let mut right = leg(["RightUpLeg", "RightLeg", "RightFoot"], -8.0);
        right[2].2 = [0.0, -50.0, 0.0];
        let toe = vec![("LeftToe", Some("LeftFoot"), [0.0, -2.0, 10.0])];
        let joints = rig(&[torso("Head"), leg(["LeftUpLeg", "LeftLeg", "LeftFoot"], 8.0), toe, right]);
        let b = bvh(&joints);
        let map = SkeletonMap::build(&b, None, "t.bvh").unwrap();
        track(&b, &map, &[0], &vec![Translation::AddToOffset; b.joints.len()])
    }

    #[test]
    fn the_feet_box_bounds_both_feet_their_toes_and_end_sites_and_nothing_else() {
        let t = rig_with_toe();
        assert_eq!(t.frame_count(), 1);
        // Left ankle (8, 5, 0), its toe (8, 3, 10) and the toe's end site (8, 4, 10); right ankle
        // (-8, -5, 0) and its end site (-8, -4, 0). The hips (0, 90, 0) and the hands are outside.
        assert_eq!(t.feet[0], [Vector3::new(-8.0, -5.0, 0.0), Vector3::new(8.0, 5.0, 10.0)]);
        assert_eq!(t.joints[0][Joint::LeftFoot.index()], Vector3::new(8.0, 5.0, 0.0));
        assert_eq!(t.joints[0][Joint::Head.index()], Vector3::new(0.0, 143.0, 0.0));
    }

    #[test]
    fn the_lowest_foot_point_is_the_boxs_corner_along_a_signed_axis() {
        let t = rig_with_toe();
        let lowest = |up: [f32; 3]| lowest_foot(&t, &Vector3::from(up))[0];
        assert_eq!(lowest([0.0, 1.0, 0.0]), -5.0);
        assert_eq!(lowest([0.0, -1.0, 0.0]), -5.0);
        assert_eq!(lowest([0.0, 0.0, 1.0]), 0.0);
        assert_eq!(lowest([0.0, 0.0, -1.0]), -10.0);
        assert_eq!(lowest([1.0, 0.0, 0.0]), -8.0);
    }

    #[test]
    fn the_leg_length_is_hip_to_ankle_averaged_over_both_sides() {
        let t = rig_with_toe();
        // Left 40 + 40, right 40 + 50.
        assert_eq!(leg_length(&t), 85.0);
    }

    #[test]
    fn median_and_percentile_take_a_value_of_the_list() {
        assert_eq!(median(vec![]), 0.0);
        assert_eq!(median(vec![3.0, 1.0, 2.0]), 2.0);
        assert_eq!(median(vec![4.0, 1.0, 3.0, 2.0]), 3.0);
        assert_eq!(percentile(vec![], 0.5), 0.0);
        let v: Vec<f32> = (0..11).rev().map(|i| i as f32).collect();
        assert_eq!(percentile(v.clone(), 0.0), 0.0);
        assert_eq!(percentile(v.clone(), 0.04), 0.0);
        assert_eq!(percentile(v.clone(), 0.06), 1.0);
        assert_eq!(percentile(v.clone(), 0.5), 5.0);
        assert_eq!(percentile(v, 1.0), 10.0);
    }
}
