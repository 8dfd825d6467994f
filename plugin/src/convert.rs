//! The one place where `models`' z-up nalgebra world meets Bevy's y-up glam world.
//!
//! `models` is right-handed with z up and x forward; Bevy is right-handed with y up. The change of
//! basis is the proper rotation (x, y, z) ↦ (x, z, −y): a −90° turn about x, never a reflection.
//! Shapes follow the same map, so a URDF cylinder along its local z is a Bevy cylinder along y.
//! A rigged creature's node transforms are the exception: they stay in the glTF file's frame
//! ([`node_transform`]).

use ace_models::character::rig_pose::NodeTransform;
use ace_models::nalgebra::{Isometry3, Quaternion, UnitQuaternion, Vector3};
use bevy::math::{Quat, Vec3};
use bevy::transform::components::Transform;

/// A `models` point or vector (z up) in Bevy coordinates (y up).
pub fn vec3(v: &Vector3<f32>) -> Vec3 {
    Vec3::new(v.x, v.z, -v.y)
}

/// A Bevy vector (y up) in `models` coordinates (z up). Inverse of [`vec3`].
pub fn vector3(v: Vec3) -> Vector3<f32> {
    Vector3::new(v.x, -v.z, v.y)
}

/// A `models` rotation in Bevy coordinates (the rotation conjugated by the change of basis).
pub fn quat(q: &UnitQuaternion<f32>) -> Quat {
    let q = q.quaternion();
    Quat::from_xyzw(q.i, q.k, -q.j, q.w)
}

/// A Bevy rotation in `models` coordinates. Inverse of [`quat`].
pub fn unit_quaternion(q: Quat) -> UnitQuaternion<f32> {
    UnitQuaternion::from_quaternion(Quaternion::new(q.w, q.x, -q.z, q.y))
}

/// A `models` rigid transform as a Bevy [`Transform`] (unit scale).
pub fn transform(iso: &Isometry3<f32>) -> Transform {
    Transform { translation: vec3(&iso.translation.vector), rotation: quat(&iso.rotation), scale: Vec3::ONE }
}

/// A Bevy [`Transform`] as a `models` rigid transform (scale dropped).
pub fn isometry(t: &Transform) -> Isometry3<f32> {
    Isometry3::from_parts(vector3(t.translation).into(), unit_quaternion(t.rotation))
}

/// A rigged creature's node transform as a [`Transform`], with no change of basis: node transforms are
/// in the glTF file's own frame, which is the scene's (Bevy loads glTF as it is).
pub fn node_transform(n: &NodeTransform) -> Transform {
    let q = n.rotation.quaternion();
    Transform {
        translation: Vec3::new(n.translation.x, n.translation.y, n.translation.z),
        rotation: Quat::from_xyzw(q.i, q.j, q.k, q.w),
        scale: Vec3::new(n.scale.x, n.scale.y, n.scale.z),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn up_maps_to_up_and_handedness_is_kept() {
        assert_eq!(vec3(&Vector3::z()), Vec3::Y);
        assert_eq!(vec3(&Vector3::x()), Vec3::X);
        // x × y = z must survive the map.
        assert!((vec3(&Vector3::x()).cross(vec3(&Vector3::y())) - vec3(&Vector3::z())).length() < 1e-6);
    }

    #[test]
    fn rotations_commute_with_the_change_of_basis() {
        let q = UnitQuaternion::from_euler_angles(0.4, -1.1, 2.3);
        let v = Vector3::new(0.3, -0.7, 1.9);
        let rotated_then_mapped = vec3(&(q * v));
        let mapped_then_rotated = quat(&q) * vec3(&v);
        assert!((rotated_then_mapped - mapped_then_rotated).length() < 1e-5);
        assert!(unit_quaternion(quat(&q)).angle_to(&q) < 1e-5);
        assert!((vector3(vec3(&v)) - v).norm() < 1e-6);
    }
}
