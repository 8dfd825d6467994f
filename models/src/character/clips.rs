//! A creature's own animation clips as character poses: what an artist meant the creature to do, in
//! the tree's DoFs. Each bone's rotation relative to its rest pose is read in its axes (yaw, pitch,
//! roll) and kept on the axes the tree gives it, clamped to their limits; bones held at rest stay there,
//! so the poses are the clip projected onto the tree. The root follows the body root bone, translation
//! channels of the bones above it included (root motion).
//!
//! [`with_travel`] carries clips animated in place across the ground, as their feet say, so that they
//! can join a motion dataset ([`crate::dataset::OwnClipsConfig`]).
//!
//! [`bone_worlds`] and [`skinned_vertices`] give the file's own skeleton and mesh in a clip's frame, as
//! a player deforms them (IK and helper bones included), for checking the tree against them.

use nalgebra::{Isometry3, Matrix4, Point3, Rotation3, Translation3, UnitQuaternion, Vector2, Vector3};

use super::Creature;
use super::gltf::{Rig, TrackKind, polar_rotation};
use crate::controller::{Chain, ChainScratch};
use crate::kinematics::CharacterPose;

/// The number of frames of animation `clip` sampled at `fps` from its start to its end inclusive.
pub fn clip_frames(rig: &Rig, clip: usize, fps: f32) -> usize {
    (rig.animations[clip].duration_s.max(0.0) * fps).floor() as usize + 1
}

/// Every bone's world matrix (file frame and units) at time `t` of animation `clip`: the nodes' own
/// transforms with the clip's channels applied, as a player poses them. `rot` and `tra` are scratch.
fn pose_bones(
    rig: &Rig,
    clip: usize,
    t: f32,
    rot: &mut Vec<UnitQuaternion<f32>>,
    tra: &mut Vec<Vector3<f32>>,
    world: &mut Vec<Matrix4<f32>>,
) {
    let nb = rig.bones.len();
    rot.clear();
    tra.clear();
    rot.extend(rig.bones.iter().map(|b| b.file_local.rotation));
    tra.extend(rig.bones.iter().map(|b| b.file_local.translation));
    for tr in &rig.clips[clip] {
        let v = tr.sample(t);
        match tr.kind {
            TrackKind::Rotation => {
                rot[tr.bone] = UnitQuaternion::from_quaternion(nalgebra::Quaternion::new(v[3], v[0], v[1], v[2]))
            }
            TrackKind::Translation => tra[tr.bone] = Vector3::new(v[0], v[1], v[2]),
        }
    }
    world.resize(nb, Matrix4::identity());
    for (b, bone) in rig.bones.iter().enumerate() {
        let local = Matrix4::new_translation(&tra[b])
            * rot[b].to_homogeneous()
            * Matrix4::new_nonuniform_scaling(&bone.file_local.scale);
        world[b] = match bone.parent {
            Some(p) => world[p] * local,
            None => bone.parent_world * local,
        };
    }
}

/// Every bone's world matrix (file frame and units) in each frame of animation `clip` sampled at
/// `fps` (as [`clip_poses`] samples it), as a player poses the file's nodes.
pub fn bone_worlds(rig: &Rig, clip: usize, fps: f32) -> Vec<Vec<Matrix4<f32>>> {
    let (mut rot, mut tra) = (Vec::new(), Vec::new());
    (0..clip_frames(rig, clip, fps))
        .map(|f| {
            let mut world = Vec::new();
            pose_bones(rig, clip, f as f32 / fps, &mut rot, &mut tra, &mut world);
            world
        })
        .collect()
}

/// Every bone's world matrix at rest (the skin's bind pose; file frame and units).
pub fn rest_worlds(rig: &Rig) -> Vec<Matrix4<f32>> {
    let mut out: Vec<Matrix4<f32>> = Vec::with_capacity(rig.bones.len());
    for b in &rig.bones {
        let above = b.parent.map_or(b.parent_world, |p| out[p]);
        out.push(above * b.rest_local.matrix());
    }
    out
}

/// The rig's vertices ([`Rig::vertices`], character frame, metres) skinned by the bones' world
/// matrices `world` (file frame and units, e.g. one frame of [`bone_worlds`]); `rest` from
/// [`rest_worlds`].
pub fn skinned_vertices(rig: &Rig, rest: &[Matrix4<f32>], world: &[Matrix4<f32>]) -> Vec<Point3<f32>> {
    let c = rig.to_character.to_homogeneous();
    let to_file = Matrix4::new_scaling(1.0 / rig.scale) * c.transpose();
    let to_char = c * Matrix4::new_scaling(rig.scale);
    // Per bone, rest vertex (character frame) → posed vertex (character frame).
    let moves: Vec<Matrix4<f32>> = world
        .iter()
        .zip(rest)
        .map(|(w, r)| to_char * w * r.try_inverse().unwrap_or_else(Matrix4::identity) * to_file)
        .collect();
    rig.vertices
        .iter()
        .map(|(p, w)| {
            let m = w.iter().fold(Matrix4::zeros(), |m, &(b, wb)| m + moves[b] * wb);
            m.transform_point(p)
        })
        .collect()
}

/// The poses of animation `clip` (index into the rig's [`super::gltf::Rig::animations`]) sampled at `fps` from its start
/// to its end inclusive.
pub fn clip_poses(c: &Creature, clip: usize, fps: f32) -> Vec<CharacterPose> {
    let rig = &c.rig;
    let frames = clip_frames(rig, clip, fps);
    let to_char = rig.to_character;
    let root = c.plan.root_bone;
    let root_rest = rig.bones[root].rest.rotation;
    let rest = rest_worlds(rig);
    let mut out = Vec::with_capacity(frames);
    let (mut rot, mut tra, mut world) = (Vec::new(), Vec::new(), Vec::new());
    for f in 0..frames {
        pose_bones(rig, clip, f as f32 / fps, &mut rot, &mut tra, &mut world);
        let m = &world[root];
        let r = polar_rotation(&(to_char.matrix() * m.fixed_view::<3, 3>(0, 0))).unwrap_or(root_rest);
        let p = to_char * m.fixed_view::<3, 1>(0, 3).into_owned() * rig.scale;
        let mut q = c.tree.neutral_q();
        for j in &c.plan.joints {
            let bone = &rig.bones[j.bone];
            let Some(parent) = bone.parent else { continue };
            if j.slides.iter().any(Option::is_some) {
                // The bone's offset from its bind offset, in the parent's axes at rest, then in its own.
                let moved = rest[parent].fixed_view::<3, 3>(0, 0) * (tra[j.bone] - bone.rest_local.translation);
                let s = bone.rest.rotation.inverse() * (to_char * moved) * rig.scale;
                for (k, d) in j.slides.iter().enumerate() {
                    if let Some(d) = d {
                        q[*d] = s[k];
                    }
                }
            }
            if j.dofs.iter().all(Option::is_none) {
                continue;
            }
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

/// The poses of animation `clip` as [`clip_poses`] gives them, with each leg then solved (by IK on its
/// own DoFs, [`Chain::limb`]) so that its foot stands where the file puts it: `exact` is the same file
/// under [`exact_profile`], on whose tree the clip plays as the file does. The character keeps fewer
/// axes than a file turns (a knee is a hinge), and what a clip turns about the axes left out is lost
/// in the projection; on the shared Spider, whose clips turn its knees about axes its hinges do not
/// have, that put feet up to 1.3 m from where the file has them and 0.66 m under the ground. Feet the
/// exact tree does not have (by link name) stay as projected.
pub fn clip_poses_on_feet(c: &Creature, exact: &Creature, clip: usize, fps: f32) -> Vec<CharacterPose> {
    let mut poses = clip_poses(c, clip, fps);
    let played = clip_poses(exact, clip, fps);
    let legs: Vec<(Chain, usize)> = c
        .morphology
        .feet
        .iter()
        .filter_map(|&f| {
            let name = &c.tree.links[f].name;
            let e = exact.tree.links.iter().position(|l| &l.name == name)?;
            Some((Chain::limb(&c.tree, &c.morphology, f).0, e))
        })
        .collect();
    let tol = 1e-3 * c.tree.standing_root_height().max(0.01);
    let mut scratch = ChainScratch::default();
    for (pose, file) in poses.iter_mut().zip(&played) {
        let links = exact.tree.forward_kinematics(file);
        for (chain, e) in &legs {
            // In the character's root frame (the two trees' roots follow the same bone).
            let target = pose.root.inverse_transform_point(&exact.morphology.ee_point(*e, &links));
            chain.solve(&c.tree, &mut pose.q, &target, tol, 50, &mut scratch);
        }
    }
    poses
}

/// `poses` (of one clip of `c`, in order) with the root carried across the ground by the feet that
/// stand. Artists animate walk and run cycles in place: the body stays over the origin while the feet
/// slide back under it. A foot whose point is within `contact_height` of the ground (z = 0) in two
/// consecutive frames is planted, and from each frame on the root is moved horizontally by the mean
/// of the planted feet's slide, so that they stay where they stood. A frame without a planted foot (a
/// gallop's flight) moves on as the last frame did. A clip that already travels with its feet planted
/// is left as it is (its planted feet do not slide). Heights and headings are the clip's own.
pub fn with_travel(c: &Creature, mut poses: Vec<CharacterPose>, contact_height: f32) -> Vec<CharacterPose> {
    let feet = &c.morphology.feet;
    let (mut offset, mut slide) = (Vector2::zeros(), Vector2::<f32>::zeros());
    let mut prev: Option<Vec<Point3<f32>>> = None;
    for pose in &mut poses {
        let links = c.tree.forward_kinematics(pose);
        // Measured before the offset: a slide is the clip's own, from one frame to the next.
        let points: Vec<Point3<f32>> = feet.iter().map(|&f| c.morphology.ee_point(f, &links)).collect();
        if let Some(before) = &prev {
            let planted: Vec<Vector2<f32>> = points
                .iter()
                .zip(before)
                .filter(|(p, q)| p.z < contact_height && q.z < contact_height)
                .map(|(p, q)| Vector2::new(q.x - p.x, q.y - p.y))
                .collect();
            if !planted.is_empty() {
                slide = planted.iter().sum::<Vector2<f32>>() / planted.len() as f32;
            }
            offset += slide;
        }
        prev = Some(points);
        pose.root.translation.x += offset.x;
        pose.root.translation.y += offset.y;
    }
    poses
}

/// A profile under which every body bone of `c` turns about all three axes over ±π, and every body bone
/// that a clip (or the file's node transforms, which a player keeps where a clip has no channel) moves off
/// its bind offset also slides: the tree on which the file's clips play exactly (no bone held at rest,
/// no axis dropped, nothing clamped), for checking the clips themselves, e.g. with the UFR detectors.
pub fn exact_profile(c: &Creature) -> crate::morphology::Profile {
    let pi = std::f32::consts::PI;
    let bones: Vec<String> = c
        .plan
        .joints
        .iter()
        .map(|j| c.rig.bones[j.bone].name.clone())
        .chain(c.plan.at_rest.iter().cloned())
        .collect();
    let rig = &c.rig;
    let moves = |b: usize| {
        let bone = &rig.bones[b];
        let off = |t: &Vector3<f32>| (t - bone.rest_local.translation).norm() > 1e-6 * (1.0 + bone.rest_local.translation.norm());
        off(&bone.file_local.translation)
            || rig.clips.iter().flatten().any(|t| {
                t.bone == b && t.kind == TrackKind::Translation && t.values.iter().any(|v| off(&Vector3::new(v[0], v[1], v[2])))
            })
    };
    let translate = (0..rig.bones.len())
        .filter(|&b| b != c.plan.root_bone && bones.contains(&rig.bones[b].name) && moves(b))
        .map(|b| rig.bones[b].name.clone())
        .collect();
    let mut p = crate::morphology::Profile {
        scale: Some(c.scale),
        animated: Some(bones.clone()),
        translate,
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
