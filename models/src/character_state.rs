//! The character state x^r (paper §6.2) with a named layout.
//!
//! Frames: world is z-up. The *heading frame* of a pose ([`crate::frame::heading_frame`]) has its
//! origin at the root link and its x axis along the root's x axis (the URDF's forward) projected on
//! the ground. Each entry is documented on its [`CharacterLayout`] range. Quaternions are `[w, x, y, z]`
//! with `w ≥ 0` ([`crate::frame::quat_wxyz`]).
//!
//! The state of frame t needs frames t−1 and t (velocities and displacements are finite differences
//! over `dt`). [`integrate_root`] goes the other way: from the previous root pose and a state vector to
//! the new root pose, which is what an autoregressive rollout needs.

use std::ops::Range;

use nalgebra::{Isometry3, Point3, Quaternion, Translation3, UnitQuaternion, Vector3};

use crate::frame::{angular_velocity, heading_frame, quat_wxyz};
use crate::kinematics::{CharacterPose, KinematicTree};
use crate::morphology::Morphology;

/// Where each feature sits in x^r. All ranges are contiguous and in this order.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct CharacterLayout {
    /// Number of joint DoFs.
    pub dof: usize,
    /// Number of end effectors ([`Morphology::end_effectors`]: feet, manipulators, head).
    pub end_effectors: usize,
}

impl CharacterLayout {
    /// Layout for a tree and its morphology.
    pub fn new(tree: &KinematicTree, morph: &Morphology) -> Self {
        CharacterLayout {
            dof: tree.dof(),
            end_effectors: morph.n_end_effectors(),
        }
    }

    /// Root height above the ground (world z of the root link), 1 value.
    pub fn root_height(&self) -> Range<usize> {
        0..1
    }
    /// Root orientation relative to the current heading frame, `[w, x, y, z]` (pitch and roll only up
    /// to the heading's yaw), 4 values.
    pub fn root_orientation(&self) -> Range<usize> {
        1..5
    }
    /// Root displacement since the previous frame, `(x, y)` in the previous heading frame (m), 2 values.
    pub fn root_displacement(&self) -> Range<usize> {
        5..7
    }
    /// Rotation from the previous to the current root orientation, expressed in the previous heading
    /// frame (`H⁻¹·R_t·R_{t−1}⁻¹·H`), `[w, x, y, z]`, 4 values. Its yaw is the change of heading.
    pub fn root_delta_rotation(&self) -> Range<usize> {
        7..11
    }
    /// Root linear velocity in the current heading frame (m/s), 3 values.
    pub fn root_linear_velocity(&self) -> Range<usize> {
        11..14
    }
    /// Root angular velocity in the current heading frame (rad/s), 3 values.
    pub fn root_angular_velocity(&self) -> Range<usize> {
        14..17
    }
    /// Joint positions, one per DoF in DoF order (rad or m).
    pub fn joint_positions(&self) -> Range<usize> {
        17..17 + self.dof
    }
    /// End-effector points ([`Morphology::ee_point`]) in the current heading frame, 3 per end effector.
    pub fn ee_positions(&self) -> Range<usize> {
        let s = self.joint_positions().end;
        s..s + 3 * self.end_effectors
    }
    /// End-effector world velocities expressed in the current heading frame (m/s), 3 per end effector.
    pub fn ee_velocities(&self) -> Range<usize> {
        let s = self.ee_positions().end;
        s..s + 3 * self.end_effectors
    }
    /// Total length of x^r.
    pub fn dim(&self) -> usize {
        self.ee_velocities().end
    }

    /// A name for every entry, e.g. `root_height`, `q:fl_knee`, `ee_pos:fl_foot.z`.
    pub fn entry_names(&self, tree: &KinematicTree, morph: &Morphology) -> Vec<String> {
        let mut n: Vec<String> = vec!["root_height".into()];
        let xyz = ["x", "y", "z"];
        let wxyz = ["w", "x", "y", "z"];
        n.extend(wxyz.iter().map(|c| format!("root_orientation.{c}")));
        n.extend(["x", "y"].iter().map(|c| format!("root_displacement.{c}")));
        n.extend(wxyz.iter().map(|c| format!("root_delta_rotation.{c}")));
        n.extend(xyz.iter().map(|c| format!("root_linear_velocity.{c}")));
        n.extend(xyz.iter().map(|c| format!("root_angular_velocity.{c}")));
        n.extend(tree.dof_names().iter().map(|d| format!("q:{d}")));
        let ees = morph.end_effectors();
        for kind in ["ee_pos", "ee_vel"] {
            for &e in &ees {
                n.extend(xyz.iter().map(|c| format!("{kind}:{}.{c}", tree.links[e].name)));
            }
        }
        n
    }
}

/// Heading frame of a root pose: origin at the root, x along the root's x projected on the ground.
pub fn root_heading(root: &Isometry3<f32>) -> Isometry3<f32> {
    heading_frame(&root.translation.vector, &(root.rotation * Vector3::x()))
}

/// Reusable buffers for [`character_state_into`].
#[derive(Clone, Debug, Default)]
pub struct StateScratch {
    prev_links: Vec<Isometry3<f32>>,
    cur_links: Vec<Isometry3<f32>>,
}

/// x^r of frame `cur` given the previous frame `prev`, `dt` seconds earlier.
pub fn character_state(
    tree: &KinematicTree,
    morph: &Morphology,
    prev: &CharacterPose,
    cur: &CharacterPose,
    dt: f32,
) -> Vec<f32> {
    let layout = CharacterLayout::new(tree, morph);
    let mut out = vec![0.0; layout.dim()];
    character_state_into(tree, morph, prev, cur, dt, &mut StateScratch::default(), &mut out);
    out
}

/// [`character_state`] into `out` (length [`CharacterLayout::dim`]); allocation-free once `scratch`
/// has been used for this tree.
pub fn character_state_into(
    tree: &KinematicTree,
    morph: &Morphology,
    prev: &CharacterPose,
    cur: &CharacterPose,
    dt: f32,
    scratch: &mut StateScratch,
    out: &mut [f32],
) {
    tree.forward_kinematics_into(prev, &mut scratch.prev_links);
    tree.forward_kinematics_into(cur, &mut scratch.cur_links);
    let layout = CharacterLayout::new(tree, morph);
    write_state(
        &layout,
        morph,
        prev,
        cur,
        &scratch.prev_links,
        &scratch.cur_links,
        dt,
        out,
    );
}

/// Fills x^r from poses whose forward kinematics (`prev_links`, `cur_links`) is already known.
///
/// # Panics
/// If `out.len() != layout.dim()` or `dt` is not positive.
#[allow(clippy::too_many_arguments)]
pub fn write_state(
    layout: &CharacterLayout,
    morph: &Morphology,
    prev: &CharacterPose,
    cur: &CharacterPose,
    prev_links: &[Isometry3<f32>],
    cur_links: &[Isometry3<f32>],
    dt: f32,
    out: &mut [f32],
) {
    assert_eq!(out.len(), layout.dim(), "state buffer has the wrong length");
    assert!(dt > 0.0, "dt must be positive");
    let hp = root_heading(&prev.root);
    let hc = root_heading(&cur.root);
    let (rp, rc) = (prev.root.rotation, cur.root.rotation);
    let (pp, pc) = (prev.root.translation.vector, cur.root.translation.vector);

    out[layout.root_height()].copy_from_slice(&[pc.z]);
    out[layout.root_orientation()].copy_from_slice(&quat_wxyz(&(hc.rotation.inverse() * rc)));
    let disp = hp.rotation.inverse() * (pc - pp);
    out[layout.root_displacement()].copy_from_slice(&[disp.x, disp.y]);
    let delta = hp.rotation.inverse() * (rc * rp.inverse()) * hp.rotation;
    out[layout.root_delta_rotation()].copy_from_slice(&quat_wxyz(&delta));
    let v = hc.rotation.inverse() * ((pc - pp) / dt);
    out[layout.root_linear_velocity()].copy_from_slice(v.as_slice());
    let w = hc.rotation.inverse() * angular_velocity(&rp, &rc, dt);
    out[layout.root_angular_velocity()].copy_from_slice(w.as_slice());
    out[layout.joint_positions()].copy_from_slice(&cur.q[..layout.dof]);

    let pos = layout.ee_positions().start;
    let vel = layout.ee_velocities().start;
    let ees = morph.feet.iter().chain(&morph.manipulators).chain(&morph.head);
    for (k, &e) in ees.enumerate() {
        let now = morph.ee_point(e, cur_links);
        let before = morph.ee_point(e, prev_links);
        let local = hc.inverse_transform_point(&now);
        out[pos + 3 * k..pos + 3 * k + 3].copy_from_slice(local.coords.as_slice());
        let v = hc.rotation.inverse() * ((now - before) / dt);
        out[vel + 3 * k..vel + 3 * k + 3].copy_from_slice(v.as_slice());
    }
}

/// Reads a `[w, x, y, z]` quaternion from a state slice (normalised; identity if degenerate).
pub fn read_quat(s: &[f32]) -> UnitQuaternion<f32> {
    let q = Quaternion::new(s[0], s[1], s[2], s[3]);
    if q.norm() < 1e-6 {
        UnitQuaternion::identity()
    } else {
        UnitQuaternion::from_quaternion(q)
    }
}

/// The root pose of a frame from the previous root pose and that frame's state: position from the
/// displacement and height; heading (yaw) from the delta rotation, integrated; pitch and roll from the
/// state's root orientation relative to that heading, which is absolute, so that no tilt accumulates
/// over a long rollout (the inverse of [`write_state`] for the root).
pub fn integrate_root(layout: &CharacterLayout, prev_root: &Isometry3<f32>, state: &[f32]) -> Isometry3<f32> {
    let hp = root_heading(prev_root);
    let d = &state[layout.root_displacement()];
    let step = hp.rotation * Vector3::new(d[0], d[1], 0.0);
    let p = prev_root.translation.vector + step;
    let delta = read_quat(&state[layout.root_delta_rotation()]);
    let integrated = hp.rotation * delta * hp.rotation.inverse() * prev_root.rotation;
    let heading = root_heading(&Isometry3::from_parts(Translation3::identity(), integrated)).rotation;
    let rot = heading * read_quat(&state[layout.root_orientation()]);
    Isometry3::from_parts(Translation3::new(p.x, p.y, state[layout.root_height()][0]), rot)
}

/// The pose of a frame from the previous root pose and that frame's state ([`integrate_root`] plus the
/// joint positions).
pub fn decode_pose(layout: &CharacterLayout, prev_root: &Isometry3<f32>, state: &[f32]) -> CharacterPose {
    CharacterPose {
        root: integrate_root(layout, prev_root, state),
        q: state[layout.joint_positions()].to_vec(),
    }
}

/// End-effector points of a state in its heading frame, one per end effector.
pub fn ee_positions(layout: &CharacterLayout, state: &[f32]) -> Vec<Point3<f32>> {
    state[layout.ee_positions()]
        .chunks_exact(3)
        .map(|c| Point3::new(c[0], c[1], c[2]))
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::test_data::{bundled_character, close};

    /// The bundled Spot: four feet and an arm.
    fn spot() -> (KinematicTree, Morphology) {
        bundled_character("spot")
    }

    fn yawed(x: f32, y: f32, z: f32, yaw: f32) -> Isometry3<f32> {
        Isometry3::from_parts(Translation3::new(x, y, z), UnitQuaternion::from_axis_angle(&Vector3::z_axis(), yaw))
    }

    #[test]
    fn every_entry_is_named_where_the_layout_puts_it() {
        let (tree, morph) = spot();
        let l = CharacterLayout::new(&tree, &morph);
        let names = l.entry_names(&tree, &morph);
        assert_eq!(names.len(), l.dim());
        assert_eq!(l.dim(), 17 + tree.dof() + 6 * morph.n_end_effectors());
        let (dofs, ees) = (tree.dof_names(), morph.end_effector_links(&tree));
        assert_eq!(ees.len(), 5, "four feet and the gripper: {ees:?}");
        let expect = [
            (0, "root_height".to_string()),
            (l.root_orientation().start, "root_orientation.w".into()),
            (l.root_orientation().end - 1, "root_orientation.z".into()),
            (l.root_displacement().start, "root_displacement.x".into()),
            (l.root_displacement().end - 1, "root_displacement.y".into()),
            (l.root_delta_rotation().start + 1, "root_delta_rotation.x".into()),
            (l.root_linear_velocity().start + 2, "root_linear_velocity.z".into()),
            (l.root_angular_velocity().start, "root_angular_velocity.x".into()),
            (l.joint_positions().start, format!("q:{}", dofs[0])),
            (l.joint_positions().end - 1, format!("q:{}", dofs[dofs.len() - 1])),
            (l.ee_positions().start, format!("ee_pos:{}.x", ees[0])),
            (l.ee_positions().start + 3 * 4 + 2, format!("ee_pos:{}.z", ees[4])),
            (l.ee_velocities().start + 3 + 1, format!("ee_vel:{}.y", ees[1])),
            (l.dim() - 1, format!("ee_vel:{}.z", ees[4])),
        ];
        for (i, name) in expect {
            assert_eq!(names[i], name, "entry {i}");
        }
    }

    #[test]
    fn a_turning_walking_root_reads_in_its_heading_frames() {
        let (tree, morph) = spot();
        let l = CharacterLayout::new(&tree, &morph);
        let dt = 0.1;
        // Heading 0.5 rad, then 0.8: 3 cm up and 0.2 m along world x, the body pitched 0.2 rad at the end.
        let q = tree.neutral_q();
        let prev = CharacterPose { root: yawed(1.0, 2.0, 0.5, 0.5), q: q.clone() };
        let pitch = UnitQuaternion::from_axis_angle(&Vector3::y_axis(), 0.2);
        let mut cur = CharacterPose { root: yawed(1.2, 2.0, 0.53, 0.8), q: q.clone() };
        cur.root.rotation *= pitch;
        cur.q[3] += 0.1;
        let x = character_state(&tree, &morph, &prev, &cur, dt);
        assert_eq!(x[l.root_height()], [0.53]);
        // Orientation: the pitch alone, the yaw taken out by the heading.
        assert!(close(&x[l.root_orientation()], &[0.1f32.cos(), 0.0, 0.1f32.sin(), 0.0], 1e-5), "{:?}", &x[l.root_orientation()]);
        // The 0.2 m along world x, in the previous heading (0.5 rad): forward and to the right.
        assert!(close(&x[l.root_displacement()], &[0.2 * 0.5f32.cos(), -0.2 * 0.5f32.sin()], 1e-5));
        // The change of heading, 0.3 rad, is the delta rotation's yaw (with the pitch, in the previous
        // heading frame); the velocity is in the current heading (0.8 rad).
        let delta = read_quat(&x[l.root_delta_rotation()]);
        let turn = UnitQuaternion::from_axis_angle(&Vector3::z_axis(), 0.3) * pitch;
        assert!(delta.angle_to(&turn) < 1e-5, "{:?}", delta.euler_angles());
        assert!(close(&x[l.root_linear_velocity()], &[2.0 * 0.8f32.cos(), -2.0 * 0.8f32.sin(), 0.3], 1e-4));
        let w = &x[l.root_angular_velocity()];
        assert!(w[2] > 2.5 && w[2] < 3.5, "{w:?}");
        assert_eq!(x[l.joint_positions()], cur.q[..]);
        // End effectors: where forward kinematics puts them, in the current heading frame, and their
        // world velocity turned into it.
        let (before, now) = (tree.forward_kinematics(&prev), tree.forward_kinematics(&cur));
        let heading = yawed(1.2, 2.0, 0.53, 0.8);
        for (k, &e) in morph.end_effectors().iter().enumerate() {
            let (a, b) = (morph.ee_point(e, &before), morph.ee_point(e, &now));
            let at = heading.inverse_transform_point(&b);
            let v = heading.rotation.inverse() * ((b - a) / dt);
            let r = l.ee_positions().start + 3 * k;
            assert!(close(&x[r..r + 3], at.coords.as_slice(), 1e-5), "end effector {k} at {:?}", &x[r..r + 3]);
            let r = l.ee_velocities().start + 3 * k;
            assert!(close(&x[r..r + 3], v.as_slice(), 1e-3), "end effector {k} moving {:?}", &x[r..r + 3]);
            assert!((ee_positions(&l, &x)[k] - at).norm() < 1e-5);
        }
    }

    #[test]
    fn quaternions_read_back_normalised_and_a_degenerate_one_as_the_identity() {
        assert_eq!(read_quat(&[0.0, 0.0, 0.0, 0.0]), UnitQuaternion::identity());
        assert_eq!(read_quat(&[1e-7, 0.0, 0.0, 0.0]), UnitQuaternion::identity());
        assert!(read_quat(&[2.0, 0.0, 0.0, 0.0]).angle() < 1e-6);
        let half_turn = read_quat(&[0.0, 0.0, 0.0, 3.0]);
        assert!((half_turn.angle() - std::f32::consts::PI).abs() < 1e-5);
        assert!((half_turn.axis().unwrap().z - 1.0).abs() < 1e-6);
        let q = read_quat(&[0.6, 0.0, 0.8, 0.0]);
        assert!((q.angle() - 2.0 * 0.8f32.atan2(0.6)).abs() < 1e-5 && q.axis().unwrap().y > 0.999);
    }

    #[test]
    #[should_panic(expected = "state buffer has the wrong length")]
    fn a_state_buffer_of_the_wrong_length_is_refused() {
        let (tree, morph) = spot();
        let p = tree.neutral_pose(yawed(0.0, 0.0, 0.5, 0.0));
        let mut out = vec![0.0; CharacterLayout::new(&tree, &morph).dim() - 1];
        character_state_into(&tree, &morph, &p, &p, 0.1, &mut StateScratch::default(), &mut out);
    }

    #[test]
    #[should_panic(expected = "dt must be positive")]
    fn a_state_over_no_time_is_refused() {
        let (tree, morph) = spot();
        let p = tree.neutral_pose(yawed(0.0, 0.0, 0.5, 0.0));
        character_state(&tree, &morph, &p, &p, 0.0);
    }

    #[test]
    fn a_rollout_integrates_the_heading_and_takes_the_tilt_as_it_is_each_frame() {
        let (tree, morph) = spot();
        let l = CharacterLayout::new(&tree, &morph);
        // Each frame: 0.1 m forward, a tenth of a radian left, 0.4 m high, pitched 0.2 rad.
        let mut x = vec![0.0; l.dim()];
        x[l.root_height()][0] = 0.4;
        let pitch = UnitQuaternion::from_axis_angle(&Vector3::y_axis(), 0.2);
        x[l.root_orientation()].copy_from_slice(&quat_wxyz(&pitch));
        x[l.root_displacement()].copy_from_slice(&[0.1, 0.0]);
        x[l.root_delta_rotation()].copy_from_slice(&quat_wxyz(&UnitQuaternion::from_axis_angle(&Vector3::z_axis(), 0.1)));
        x[l.joint_positions()][0] = 0.25;
        // From a root rolled 0.3 rad at heading 1.0: after ten frames heading 2.0, pitched 0.2, no roll.
        let mut root = yawed(0.0, 0.0, 0.5, 1.0);
        root.rotation *= UnitQuaternion::from_axis_angle(&Vector3::x_axis(), 0.3);
        let mut path = Vector3::zeros();
        for k in 0..10 {
            path += UnitQuaternion::from_axis_angle(&Vector3::z_axis(), 1.0 + 0.1 * k as f32) * Vector3::new(0.1, 0.0, 0.0);
            let pose = decode_pose(&l, &root, &x);
            assert_eq!(pose.q, x[l.joint_positions()]);
            root = pose.root;
        }
        let expected = yawed(path.x, path.y, 0.4, 2.0).rotation * pitch;
        assert!(root.rotation.angle_to(&expected) < 1e-4, "{:?}", root.rotation.euler_angles());
        assert!((root.translation.vector - Vector3::new(path.x, path.y, 0.4)).norm() < 1e-5);
        // The heading frame of the tilted root: at the root, x along its forward on the ground.
        let h = root_heading(&root);
        assert!(h.rotation.angle_to(&UnitQuaternion::from_axis_angle(&Vector3::z_axis(), 2.0)) < 1e-4);
        assert_eq!(h.translation.vector, root.translation.vector);
    }
}
