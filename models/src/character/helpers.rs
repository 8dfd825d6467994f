//! Deforming helper bones: bones outside the body (an IK foot hanging off the armature's root) that
//! deform vertices, which the tree fixes to a *host*, the body bone at whose end the helper sits.
//!
//! An IK rig holds its target where the leg's chain ends, with an orientation of its own: the Quaternius
//! files' paws stay level while the shin above them tilts. Where the target sits relative to the chain
//! is what the rig's clips show, not necessarily the bind pose: the Spider was bound with its foot
//! targets 3.5 cm beyond the ends of its legs, which its clips pull in to the ends. So a helper hangs
//! off its host where the file's clips hold it ([`held_offsets`]), its vertices move with it, and a foot
//! whose paw a helper holds touches the ground under the helper's origin, the paw's pivot, rather than at
//! the paw's lowest vertex, which a paw tilting about its pivot (as the tree's paw does when the shin
//! tilts) would lift or sink ([`under_pivot`]).

use std::collections::BTreeMap;

use nalgebra::{Isometry3, Matrix4, Point3, Translation3, Vector3};

use super::clips::bone_worlds;
use super::gltf::{Rig, polar_rotation};

/// Frames per second at which the clips are sampled for [`held_offsets`].
pub const SAMPLE_FPS: f32 = 30.0;

/// Per helper (bone index, with its host in `host`): its origin in the host's rest frame (m), where
/// the file's clips hold it. Each coordinate is the median over every frame of every clip (sampled at
/// [`SAMPLE_FPS`]), so a clip that lets go of its targets (a death) does not move it; without clips it
/// is the bind pose's.
pub fn held_offsets(rig: &Rig, host: &BTreeMap<usize, usize>) -> BTreeMap<usize, Vector3<f32>> {
    let bind = |h: usize, b: usize| rig.bones[b].rest.inverse_transform_point(&Point3::from(rig.bones[h].rest.translation.vector)).coords;
    let mut samples: BTreeMap<usize, Vec<Vector3<f32>>> = host.keys().map(|&h| (h, Vec::new())).collect();
    if host.is_empty() {
        // Nothing to sample: the clips are not posed (their length sizes the sampling).
        return BTreeMap::new();
    }
    for clip in 0..rig.clips.len() {
        for world in bone_worlds(rig, clip, SAMPLE_FPS) {
            for (&h, &b) in host {
                if let (Some(ph), Some(pb)) = (character_pose(rig, &world[h]), character_pose(rig, &world[b])) {
                    samples.get_mut(&h).expect("every helper").push(pb.inverse_transform_point(&Point3::from(ph.translation.vector)).coords);
                }
            }
        }
    }
    samples
        .into_iter()
        .map(|(h, s)| {
            let at = if s.is_empty() { bind(h, host[&h]) } else { Vector3::from_fn(|i, _| median(s.iter().map(|v| v[i]).collect())) };
            (h, at)
        })
        .collect()
}

/// A bone's world matrix (file frame and units) as a pose in the character frame (m), scale stripped.
pub fn character_pose(rig: &Rig, m: &Matrix4<f32>) -> Option<Isometry3<f32>> {
    let r = polar_rotation(&(rig.to_character.matrix() * m.fixed_view::<3, 3>(0, 0)))?;
    let t = rig.to_character * m.fixed_view::<3, 1>(0, 3).into_owned() * rig.scale;
    Some(Isometry3::from_parts(Translation3::from(t), r))
}

/// The contact point of a foot whose paw pivots about `pivot` (a point at rest, character frame): the
/// point under the pivot at the height of the paw's lowest vertex `lowest`.
pub fn under_pivot(pivot: &Point3<f32>, lowest: &Point3<f32>) -> Point3<f32> {
    Point3::new(pivot.x, pivot.y, lowest.z)
}

fn median(mut v: Vec<f32>) -> f32 {
    v.sort_by(f32::total_cmp);
    v[v.len() / 2]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_median_ignores_a_minority_of_outliers() {
        assert_eq!(median(vec![1.0, 5.0, 1.1, 0.9, 100.0]), 1.1);
    }

    #[test]
    fn the_contact_point_is_under_the_pivot_at_the_soles_height() {
        let c = under_pivot(&Point3::new(0.3, -0.1, 0.2), &Point3::new(0.45, -0.12, -0.01));
        assert_eq!(c, Point3::new(0.3, -0.1, -0.01));
    }
}
