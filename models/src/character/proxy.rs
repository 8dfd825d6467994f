//! Adjustments of the capsules fitted to a creature's bones ([`super::gltf::fit_capsule`]).

use nalgebra::{Isometry3, Point3, Vector3};

use super::gltf::Bone;
use crate::geometry::{Geometry, Shape};

/// `points` (character frame, at rest) that `bone` deforms, at the size a player shows the bone: its
/// node's scale over its bind scale along its own axes, about its origin. A player keeps a node's scale
/// where a clip has no scale channel, and the clips' scale channels are not read, so a bone the nodes
/// keep at another size than it was bound (the Spider's abdomen at 0.88) is that size in every clip.
pub fn at_played_size(points: &mut [Point3<f32>], bone: &Bone) {
    let ratio = bone.file_local.scale.component_div(&bone.rest_local.scale);
    if (ratio - Vector3::repeat(1.0)).abs().max() <= 1e-3 || !ratio.iter().all(|r| r.is_finite()) {
        return;
    }
    for p in points {
        *p = bone.rest * Point3::from(bone.rest.inverse_transform_point(p).coords.component_mul(&ratio));
    }
}

/// `g` (a capsule in the frame whose world pose is `pose`) thinned about its axis, which it keeps, so
/// that it reaches no lower than `floor` (world z): the core of a flat section lying on the ground (the
/// Snake's coiled tail tip) is wider than it is thick, and a round capsule of its median radius pokes out
/// below the mesh into the ground. The thinned capsule lies inside `g`. Capsules above the floor, other
/// shapes, and capsules whose axis itself reaches below the floor are returned unchanged.
pub fn above_floor(g: &Geometry, pose: &Isometry3<f32>, floor: f32) -> Geometry {
    let Shape::Capsule { radius, length } = g.shape else {
        return g.clone();
    };
    let world = pose * g.origin;
    let tilt = (world.rotation * Vector3::z()).z.abs();
    // The axis' lowest point, and the capsule's: a radius below it.
    let axis_low = world.translation.vector.z - 0.5 * length * tilt;
    if axis_low - radius >= floor || axis_low <= floor {
        return g.clone();
    }
    Geometry {
        origin: g.origin,
        shape: Shape::Capsule { radius: (axis_low - floor).max(1e-4), length },
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::{Translation3, UnitQuaternion};

    fn capsule(radius: f32, length: f32, tilt_rad: f32, z: f32) -> (Geometry, Isometry3<f32>) {
        let g = Geometry {
            origin: Isometry3::from_parts(Translation3::new(0.0, 0.0, z), UnitQuaternion::from_euler_angles(0.0, std::f32::consts::FRAC_PI_2 - tilt_rad, 0.0)),
            shape: Shape::Capsule { radius, length },
        };
        (g, Isometry3::identity())
    }

    fn lowest(g: &Geometry, pose: &Isometry3<f32>) -> f32 {
        let Shape::Capsule { radius, length } = g.shape else { unreachable!() };
        let w = pose * g.origin;
        let a = w.rotation * Vector3::z();
        w.translation.vector.z - 0.5 * length * a.z.abs() - radius
    }

    #[test]
    fn a_capsule_reaching_below_the_floor_is_thinned_to_it_about_its_axis() {
        // Lying (axis horizontal), centre 0.1 above the floor, radius 0.16: it pokes 0.06 below.
        let (g, pose) = capsule(0.16, 0.1, 0.0, 0.1);
        let out = above_floor(&g, &pose, 0.0);
        assert_eq!(out.shape, Shape::Capsule { radius: 0.1, length: 0.1 });
        assert_eq!(out.origin, g.origin);
        // Tilted by 0.3 rad, it reaches the floor exactly.
        let (g, pose) = capsule(0.16, 0.3, 0.3, 0.15);
        let out = above_floor(&g, &pose, 0.0);
        assert!(lowest(&out, &pose).abs() < 1e-5, "{}", lowest(&out, &pose));
    }

    #[test]
    fn capsules_above_the_floor_or_with_their_axis_below_it_are_unchanged() {
        let (g, pose) = capsule(0.05, 0.3, 0.2, 0.2);
        assert_eq!(above_floor(&g, &pose, 0.0), g);
        let (g, pose) = capsule(0.05, 0.3, 0.2, 0.02);
        assert_eq!(above_floor(&g, &pose, 0.0), g);
    }
}
