//! A creature's own animation clips as character poses: what an artist meant the creature to do, in
//! the tree's DoFs. Each bone's rotation relative to its rest pose is read in its axes (yaw, pitch,
//! roll) and kept on the axes the tree gives it, clamped to their limits; bones held at rest stay there,
//! so the poses are the clip projected onto the tree. The root follows the body root bone, translation
//! channels of the bones above it included (root motion).

use nalgebra::{Isometry3, Matrix4, Rotation3, Translation3, UnitQuaternion, Vector3};

use super::Creature;
use super::gltf::{TrackKind, polar_rotation};
use crate::kinematics::CharacterPose;

/// The poses of animation `clip` (index into the rig's [`super::gltf::Rig::animations`]) sampled at `fps` from its start
/// to its end inclusive.
pub fn clip_poses(c: &Creature, clip: usize, fps: f32) -> Vec<CharacterPose> {
    let rig = &c.rig;
    let tracks = &rig.clips[clip];
    let duration = rig.animations[clip].duration_s.max(0.0);
    let frames = (duration * fps).floor() as usize + 1;
    let nb = rig.bones.len();
    let to_char = rig.to_character;
    let root = c.plan.root_bone;
    let root_rest = rig.bones[root].rest.rotation;
    let mut out = Vec::with_capacity(frames);
    let mut rot = vec![UnitQuaternion::identity(); nb];
    let mut tra = vec![Vector3::zeros(); nb];
    let mut world = vec![Matrix4::identity(); nb];
    for f in 0..frames {
        let t = f as f32 / fps;
        for (b, bone) in rig.bones.iter().enumerate() {
            rot[b] = bone.file_local.rotation;
            tra[b] = bone.file_local.translation;
        }
        for tr in tracks {
            let v = tr.sample(t);
            match tr.kind {
                TrackKind::Rotation => {
                    rot[tr.bone] = UnitQuaternion::from_quaternion(nalgebra::Quaternion::new(v[3], v[0], v[1], v[2]))
                }
                TrackKind::Translation => tra[tr.bone] = Vector3::new(v[0], v[1], v[2]),
            }
        }
        for (b, bone) in rig.bones.iter().enumerate() {
            let local = Matrix4::new_translation(&tra[b])
                * rot[b].to_homogeneous()
                * Matrix4::new_nonuniform_scaling(&bone.file_local.scale);
            world[b] = match bone.parent {
                Some(p) => world[p] * local,
                None => bone.parent_world * local,
            };
        }
        let m = &world[root];
        let r = polar_rotation(&(to_char.matrix() * m.fixed_view::<3, 3>(0, 0))).unwrap_or(root_rest);
        let p = to_char * m.fixed_view::<3, 1>(0, 3).into_owned() * rig.scale;
        let mut q = c.tree.neutral_q();
        for j in &c.plan.joints {
            if j.dofs.iter().all(Option::is_none) {
                continue;
            }
            let bone = &rig.bones[j.bone];
            let Some(parent) = bone.parent else { continue };
            let rp = rig.bones[parent].rest.rotation;
            let d = rp * (rot[j.bone] * bone.rest_local.rotation.inverse()) * rp.inverse();
            let bq = UnitQuaternion::from_rotation_matrix(&Rotation3::from_matrix_unchecked(j.basis));
            let (roll, pitch, yaw) = (bq.inverse() * d * bq).euler_angles();
            for (k, a) in [yaw, pitch, roll].into_iter().enumerate() {
                if let Some(dof) = j.dofs[k] {
                    q[dof] = a;
                }
            }
        }
        c.tree.clamp(&mut q);
        out.push(CharacterPose { root: Isometry3::from_parts(Translation3::from(p), r * root_rest.inverse()), q });
    }
    out
}

/// A profile under which every body bone of `c` turns about all three axes over ±π: the tree on which
/// the file's clips play exactly (no bone held at rest, no axis dropped, nothing clamped), for checking
/// the clips themselves, e.g. with the UFR detectors.
pub fn exact_profile(c: &Creature) -> crate::morphology::Profile {
    let pi = std::f32::consts::PI;
    let bones: Vec<String> = c
        .plan
        .joints
        .iter()
        .map(|j| c.rig.bones[j.bone].name.clone())
        .chain(c.plan.at_rest.iter().cloned())
        .collect();
    let mut p = crate::morphology::Profile {
        scale: Some(c.scale),
        animated: Some(bones.clone()),
        ..Default::default()
    };
    for b in &bones {
        p.dofs.insert(b.clone(), super::body_plan::AXES.iter().map(|a| a.to_string()).collect());
        for a in super::body_plan::AXES {
            p.limits.insert(format!("{b}:{a}"), [-pi, pi]);
        }
    }
    p
}
