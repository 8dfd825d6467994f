//! The local ("heading") frame shared by the human and character state vectors (paper §6.1–6.2):
//! origin at the root, x along the facing direction projected on the ground, z along world up.
//!
//! All of `models` works in a right-handed, z-up world measured in metres.

use nalgebra::{Isometry3, UnitQuaternion, Vector3};

/// World up.
pub const UP: Vector3<f32> = Vector3::new(0.0, 0.0, 1.0);

/// Yaw (rotation about world z) of the facing direction `forward` projected on the ground.
/// Falls back to 0 when `forward` is (nearly) vertical.
pub fn heading_yaw(forward: &Vector3<f32>) -> f32 {
    if forward.x.abs() + forward.y.abs() < 1e-6 {
        0.0
    } else {
        forward.y.atan2(forward.x)
    }
}

/// The heading frame of a root at `position` whose facing direction is `forward`:
/// translation `position`, rotation by the yaw of `forward` only.
pub fn heading_frame(position: &Vector3<f32>, forward: &Vector3<f32>) -> Isometry3<f32> {
    Isometry3::from_parts(
        (*position).into(),
        UnitQuaternion::from_axis_angle(&Vector3::z_axis(), heading_yaw(forward)),
    )
}

/// Quaternion as `[w, x, y, z]` with `w >= 0`, so that q and −q (the same rotation) encode alike.
pub fn quat_wxyz(q: &UnitQuaternion<f32>) -> [f32; 4] {
    let q = q.quaternion();
    let s = if q.w < 0.0 { -1.0 } else { 1.0 };
    [s * q.w, s * q.i, s * q.j, s * q.k]
}

/// Angular velocity (rad/s, in the frame the rotations are expressed in) that takes `from` to `to` in `dt`.
pub fn angular_velocity(from: &UnitQuaternion<f32>, to: &UnitQuaternion<f32>, dt: f32) -> Vector3<f32> {
    (to * from.inverse()).scaled_axis() / dt
}

/// `a` wrapped into [−π, π].
pub fn wrap_pi(a: f32) -> f32 {
    use std::f32::consts::TAU;
    a - TAU * (a / TAU).round()
}

/// `values` with every step wrapped into [−π, π]: the continuous version of a sequence of angles.
pub fn unwrap_angles(values: &mut [f32]) {
    for k in 1..values.len() {
        values[k] = values[k - 1] + wrap_pi(values[k] - values[k - 1]);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::f32::consts::{FRAC_PI_2, PI};

    #[test]
    fn heading_frame_ignores_pitch_and_keeps_position() {
        let f = heading_frame(&Vector3::new(1.0, 2.0, 0.9), &Vector3::new(0.0, 1.0, -0.7));
        assert!((f.rotation.angle() - FRAC_PI_2).abs() < 1e-5);
        let local_forward = f.inverse_transform_vector(&Vector3::new(0.0, 1.0, 0.0));
        assert!((local_forward - Vector3::x()).norm() < 1e-5);
        assert_eq!(f.translation.vector, Vector3::new(1.0, 2.0, 0.9));
    }

    #[test]
    fn quaternion_sign_is_canonical() {
        let q = UnitQuaternion::from_euler_angles(0.3, -0.2, 2.9);
        let neg = UnitQuaternion::new_unchecked(-q.into_inner());
        assert_eq!(quat_wxyz(&q), quat_wxyz(&neg));
        assert!(quat_wxyz(&q)[0] >= 0.0);
    }

    #[test]
    fn angular_velocity_of_a_yaw_step() {
        let a = UnitQuaternion::from_axis_angle(&Vector3::z_axis(), 0.1);
        let b = UnitQuaternion::from_axis_angle(&Vector3::z_axis(), 0.2);
        let w = angular_velocity(&a, &b, 0.5);
        assert!((w - Vector3::new(0.0, 0.0, 0.2)).norm() < 1e-5);
    }

    #[test]
    fn angles_unwrap_across_pi() {
        let mut a = vec![3.0, 3.1, -3.1, -3.0, 3.1, 2.9];
        unwrap_angles(&mut a);
        let want = [3.0, 3.1, 2.0 * PI - 3.1, 2.0 * PI - 3.0, 3.1, 2.9];
        for (x, y) in a.iter().zip(want) {
            assert!((x - y).abs() < 1e-5, "{a:?}");
        }
        assert!((wrap_pi(3.0 * PI + 0.1) - (-PI + 0.1)).abs() < 1e-5);
    }
}
