//! Wheeled bases: the base moves holonomically in the plane (the paper's simplification: a low-level
//! controller can drive it in any direction), and each wheel's angle is integrated from the velocity of
//! its contact point along its rolling direction, so that wheels roll without slipping forwards (the
//! sideways component of a holonomic motion slips, as on omni or caster wheels).

use nalgebra::{Isometry3, Vector2, Vector3};

use super::rig::Wheel;
use crate::kinematics::{CharacterPose, KinematicTree};
use crate::morphology::Morphology;

/// The wheels of a character: each [`Morphology::wheels`] link with its own DoF, its axis and centre in
/// the root frame, and its radius — the height of its axle above the ground when standing (links whose
/// axle is not above the ground are left out).
pub fn find(tree: &KinematicTree, morph: &Morphology, standing: &CharacterPose) -> Vec<Wheel> {
    let world = tree.forward_kinematics(standing);
    let local = tree.forward_kinematics(&CharacterPose {
        root: Isometry3::identity(),
        q: standing.q.clone(),
    });
    morph
        .wheels
        .iter()
        .filter_map(|&w| {
            let j = tree.links[w].joint.as_ref()?;
            let radius = world[w].translation.vector.z;
            (radius >= 1e-3).then_some(Wheel {
                dof: j.dof?,
                axis: local[w].rotation * j.axis.into_inner(),
                center: local[w].translation.vector,
                radius,
            })
        })
        .collect()
}

/// Advances the wheel angles in `q` by one frame of base velocity `v` (heading frame, m/s) and yaw rate
/// `wz` (rad/s). Angles are wrapped into `[−π, π)` so they stay bounded over long episodes.
pub fn roll(wheels: &[Wheel], q: &mut [f32], v: Vector2<f32>, wz: f32, dt: f32) {
    for w in wheels {
        q[w.dof] = wrap(q[w.dof] + spin_rate(w, v, wz) * dt);
    }
}

/// Angular velocity of a wheel (rad/s) for base velocity `v` and yaw rate `wz`: the contact point's
/// velocity along the rolling direction `axis × z`, over the radius.
pub fn spin_rate(w: &Wheel, v: Vector2<f32>, wz: f32) -> f32 {
    let contact = Vector3::new(v.x - wz * w.center.y, v.y + wz * w.center.x, 0.0);
    let rolling = w.axis.cross(&Vector3::z());
    contact.dot(&rolling) / w.radius
}

/// Wraps an angle into `[−π, π)`.
pub fn wrap(a: f32) -> f32 {
    use std::f32::consts::{PI, TAU};
    (a + PI).rem_euclid(TAU) - PI
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_wheel_on_the_y_axis_rolls_forward_positively() {
        let w = Wheel {
            dof: 0,
            axis: Vector3::y(),
            center: Vector3::new(0.0, 0.2, 0.05),
            radius: 0.05,
        };
        assert!((spin_rate(&w, Vector2::new(0.1, 0.0), 0.0) - 2.0).abs() < 1e-5);
        // Turning left on the spot: the left wheel moves backwards.
        assert!(spin_rate(&w, Vector2::zeros(), 1.0) < 0.0);
        assert!((wrap(3.5) - (3.5 - std::f32::consts::TAU)).abs() < 1e-6);
    }
}
