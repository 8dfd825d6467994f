//! The kinematic tree of a character and its forward kinematics.
//!
//! The tree is flat and topologically ordered — `links[0]` is the root and every link comes after its
//! parent — so forward kinematics is one loop over an array (like rapier's multibody arrays). Each
//! non-root link carries the joint that attaches it to its parent. Movable joints own one DoF each
//! (an index into `q`), except mimic joints, which follow another DoF.

use std::path::{Path, PathBuf};

use nalgebra::{Isometry3, Translation3, Unit, UnitQuaternion, Vector3};
use serde::{Deserialize, Serialize};

use crate::geometry::{Aabb, Geometry, geometries_aabb};
use crate::urdf::{STRING_SOURCE, UrdfError, parse_urdf, read_urdf_file};

/// How a joint moves.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum JointKind {
    /// No motion (also used for URDF `floating` and `planar` joints, see [`crate::urdf`]).
    Fixed,
    /// Rotation about the axis within limits.
    Revolute,
    /// Rotation about the axis without limits (wheels).
    Continuous,
    /// Translation along the axis within limits.
    Prismatic,
}

impl JointKind {
    /// True for the kinds that have a position variable.
    pub fn is_movable(self) -> bool {
        self != JointKind::Fixed
    }
    /// True for rotational kinds.
    pub fn is_rotational(self) -> bool {
        matches!(self, JointKind::Revolute | JointKind::Continuous)
    }
}

/// Joint limits. Position bounds are infinite for continuous joints; velocity and effort are +∞ when
/// the URDF does not give them.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Limits {
    /// Lower position bound (rad or m).
    pub lower: f32,
    /// Upper position bound (rad or m).
    pub upper: f32,
    /// Velocity bound (rad/s or m/s).
    pub velocity: f32,
    /// Effort bound (N·m or N).
    pub effort: f32,
}

impl Limits {
    /// The velocity bound when there is one: finite and positive (URDF's 0 means none, as does +∞).
    pub fn velocity_bound(&self) -> Option<f32> {
        (self.velocity.is_finite() && self.velocity > 0.0).then_some(self.velocity)
    }
}

/// A mimic joint's rule: position = `multiplier · q[dof] + offset`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Mimic {
    /// The DoF followed.
    pub dof: usize,
    /// Scale.
    pub multiplier: f32,
    /// Offset (rad or m).
    pub offset: f32,
}

/// The joint that attaches a link to its parent.
#[derive(Clone, Debug, PartialEq)]
pub struct JointSpec {
    /// URDF joint name.
    pub name: String,
    /// How it moves.
    pub kind: JointKind,
    /// Pose of the joint frame (= child link frame at zero position) in the parent link frame.
    pub origin: Isometry3<f32>,
    /// Unit axis in the joint frame (x for fixed joints).
    pub axis: Unit<Vector3<f32>>,
    /// Limits; `None` only for fixed joints.
    pub limits: Option<Limits>,
    /// Index into `q` for movable joints that are not mimic joints.
    pub dof: Option<usize>,
    /// For mimic joints: which DoF they follow and how.
    pub mimic: Option<Mimic>,
}

impl JointSpec {
    /// Position of this joint for the joint vector `q` (0 for fixed joints).
    #[inline]
    pub fn position(&self, q: &[f32]) -> f32 {
        match (self.dof, &self.mimic) {
            (Some(d), _) => q[d],
            (None, Some(m)) => m.multiplier * q[m.dof] + m.offset,
            _ => 0.0,
        }
    }

    /// Transform from the parent link frame to the child link frame at joint position `x`.
    #[inline]
    pub fn transform(&self, x: f32) -> Isometry3<f32> {
        match self.kind {
            JointKind::Fixed => self.origin,
            JointKind::Revolute | JointKind::Continuous => self.origin * UnitQuaternion::from_axis_angle(&self.axis, x),
            JointKind::Prismatic => self.origin * Translation3::from(self.axis.into_inner() * x),
        }
    }
}

/// A rigid body of the character.
#[derive(Clone, Debug, PartialEq)]
pub struct Link {
    /// URDF link name.
    pub name: String,
    /// Index of the parent link; `None` for the root.
    pub parent: Option<usize>,
    /// Joint to the parent; `None` for the root.
    pub joint: Option<JointSpec>,
    /// Visual shapes in the link frame.
    pub visuals: Vec<Geometry>,
    /// Collision shapes in the link frame.
    pub collisions: Vec<Geometry>,
    /// Mass (kg; 0 when the URDF gives no inertial).
    pub mass: f32,
}

impl Link {
    /// The geometry that stands for the link's extent: the collision shapes if any has a known
    /// extent, else the visual shapes.
    pub fn extent_geometry(&self) -> &[Geometry] {
        if self.collisions.iter().any(|g| g.aabb(&Isometry3::identity()).is_some()) {
            &self.collisions
        } else {
            &self.visuals
        }
    }

    /// Bounding box of [`Link::extent_geometry`] with the link at `pose`; `None` if it has no known extent.
    pub fn aabb(&self, pose: &Isometry3<f32>) -> Option<Aabb> {
        geometries_aabb(self.extent_geometry(), pose)
    }
}

/// A character's pose: the root link's world pose and one position per DoF.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct CharacterPose {
    /// World pose of the root link.
    pub root: Isometry3<f32>,
    /// Joint positions, indexed by DoF (rad or m).
    pub q: Vec<f32>,
}

impl CharacterPose {
    /// The pose's ground travel: its root's horizontal position and its heading (the yaw of the root's
    /// rotation away from `rest`, the root's rotation standing), a rigid motion `M` about the vertical.
    /// The pose with its root premultiplied by `M⁻¹` stays over the origin, facing +x as at rest. Game
    /// engines carry this part of a motion on the entity ("root motion") and the rest on the skeleton.
    pub fn ground_travel(&self, rest: &UnitQuaternion<f32>) -> Isometry3<f32> {
        let forward = (self.root.rotation * rest.inverse()) * Vector3::x();
        let yaw = if forward.x.abs() + forward.y.abs() > 1e-6 { forward.y.atan2(forward.x) } else { 0.0 };
        let t = self.root.translation.vector;
        Isometry3::from_parts(Translation3::new(t.x, t.y, 0.0), UnitQuaternion::from_axis_angle(&Vector3::z_axis(), yaw))
    }
}

/// The kinematic tree of a character.
#[derive(Clone, Debug)]
pub struct KinematicTree {
    /// Robot name from the URDF.
    pub name: String,
    /// Links, root first, every link after its parent.
    pub links: Vec<Link>,
    /// Non-fatal import notes (floating joints treated as fixed, missing mesh files, …).
    pub warnings: Vec<String>,
    /// The URDF file the tree was read from, if any (for resolving mesh paths later).
    pub source: Option<PathBuf>,
    /// Link pairs whose contact is part of the model and never counts as a self-collision (like an
    /// SRDF's disabled collisions): a rigged creature's bones that deform the same skin.
    pub allowed_contacts: Vec<(usize, usize)>,
    dof_links: Vec<usize>,
    rest_q: Option<Vec<f32>>,
}

impl KinematicTree {
    /// Assembles a tree from links that are already topologically ordered with DoFs assigned in link
    /// order (what [`crate::urdf::robot_to_tree`] produces).
    pub fn from_parts(name: String, links: Vec<Link>, warnings: Vec<String>) -> Self {
        let mut dof_links: Vec<(usize, usize)> = links
            .iter()
            .enumerate()
            .filter_map(|(i, l)| l.joint.as_ref().and_then(|j| j.dof).map(|d| (d, i)))
            .collect();
        dof_links.sort_unstable();
        debug_assert!(
            dof_links.iter().enumerate().all(|(k, (d, _))| k == *d),
            "DoFs must be 0..n"
        );
        debug_assert!(links.iter().enumerate().all(|(i, l)| l.parent.is_none_or(|p| p < i)));
        KinematicTree {
            name,
            links,
            warnings,
            source: None,
            allowed_contacts: Vec::new(),
            dof_links: dof_links.into_iter().map(|(_, i)| i).collect(),
            rest_q: None,
        }
    }

    /// Reads a URDF file. Errors name the file. STL/OBJ mesh bounds are read when the files are found.
    pub fn from_urdf_file(path: &Path) -> Result<Self, UrdfError> {
        read_urdf_file(path)
    }

    /// Parses URDF text (mesh files are not looked for). Errors name the source `<string>`.
    pub fn from_urdf_str(xml: &str) -> Result<Self, UrdfError> {
        parse_urdf(xml, STRING_SOURCE, None)
    }

    /// Number of DoFs (length of `q`).
    pub fn dof(&self) -> usize {
        self.dof_links.len()
    }

    /// Joint name of each DoF.
    pub fn dof_names(&self) -> Vec<&str> {
        self.dof_links.iter().map(|&l| self.joint(l).name.as_str()).collect()
    }

    /// The link moved by DoF `dof`.
    pub fn dof_link(&self, dof: usize) -> usize {
        self.dof_links[dof]
    }

    /// The joint of DoF `dof`.
    pub fn dof_joint(&self, dof: usize) -> &JointSpec {
        self.joint(self.dof_links[dof])
    }

    /// DoF index of the joint named `name`.
    pub fn dof_index(&self, name: &str) -> Option<usize> {
        self.dof_links.iter().position(|&l| self.joint(l).name == name)
    }

    fn joint(&self, link: usize) -> &JointSpec {
        self.links[link].joint.as_ref().expect("DoF links have joints")
    }

    /// Index of the link named `name`.
    pub fn link_index(&self, name: &str) -> Option<usize> {
        self.links.iter().position(|l| l.name == name)
    }

    /// Indices of the children of `link`, in order.
    pub fn children(&self, link: usize) -> impl Iterator<Item = usize> + '_ {
        self.links
            .iter()
            .enumerate()
            .filter(move |(_, l)| l.parent == Some(link))
            .map(|(i, _)| i)
    }

    /// True when `link` is `ancestor` or lies below it.
    pub fn is_descendant(&self, link: usize, ancestor: usize) -> bool {
        let mut l = Some(link);
        while let Some(i) = l {
            if i == ancestor {
                return true;
            }
            l = self.links[i].parent;
        }
        false
    }

    /// Limits of DoF `dof`.
    pub fn limits(&self, dof: usize) -> Option<Limits> {
        self.dof_joint(dof).limits
    }

    /// Clamps every DoF of `q` into its position limits.
    pub fn clamp(&self, q: &mut [f32]) {
        for (d, x) in q.iter_mut().enumerate().take(self.dof()) {
            if let Some(l) = self.limits(d) {
                *x = x.max(l.lower).min(l.upper);
            }
        }
    }

    /// The neutral joint vector: the rest pose if one was set (e.g. from a profile), else zeros clamped
    /// into the limits.
    pub fn neutral_q(&self) -> Vec<f32> {
        if let Some(q) = &self.rest_q {
            return q.clone();
        }
        let mut q = vec![0.0; self.dof()];
        self.clamp(&mut q);
        q
    }

    /// Sets the rest pose that [`KinematicTree::neutral_q`] returns (clamped into limits).
    ///
    /// # Panics
    /// If `q.len() != self.dof()`.
    pub fn set_rest_q(&mut self, mut q: Vec<f32>) {
        assert_eq!(q.len(), self.dof(), "rest pose needs one value per DoF");
        self.clamp(&mut q);
        self.rest_q = Some(q);
    }

    /// The neutral pose with the root at `root`.
    pub fn neutral_pose(&self, root: Isometry3<f32>) -> CharacterPose {
        CharacterPose {
            root,
            q: self.neutral_q(),
        }
    }

    /// World pose of every link, in link order.
    pub fn forward_kinematics(&self, pose: &CharacterPose) -> Vec<Isometry3<f32>> {
        let mut out = Vec::with_capacity(self.links.len());
        self.forward_kinematics_into(pose, &mut out);
        out
    }

    /// [`KinematicTree::forward_kinematics`] into `out`; does not allocate when `out` has capacity for
    /// every link.
    ///
    /// # Panics
    /// If `pose.q` is shorter than [`KinematicTree::dof`].
    pub fn forward_kinematics_into(&self, pose: &CharacterPose, out: &mut Vec<Isometry3<f32>>) {
        assert!(
            pose.q.len() >= self.dof(),
            "pose has {} joint values, tree has {} DoFs",
            pose.q.len(),
            self.dof()
        );
        out.clear();
        out.reserve(self.links.len());
        for link in &self.links {
            let world = match (&link.joint, link.parent) {
                (Some(j), Some(p)) => out[p] * j.transform(j.position(&pose.q)),
                _ => pose.root,
            };
            out.push(world);
        }
    }

    /// Lowest z over the geometry of all links at `link_poses` (collision shapes, else visual shapes;
    /// the origin stands in for links without known extent).
    pub fn lowest_z(&self, link_poses: &[Isometry3<f32>]) -> f32 {
        self.links
            .iter()
            .zip(link_poses)
            .map(|(l, p)| l.aabb(p).map_or(p.translation.vector.z, |b| b.min.z))
            .fold(f32::INFINITY, f32::min)
    }

    /// World bounding box of the whole character at `link_poses` (as in [`KinematicTree::lowest_z`]).
    pub fn aabb(&self, link_poses: &[Isometry3<f32>]) -> Aabb {
        let mut out = Aabb::empty();
        for (l, p) in self.links.iter().zip(link_poses) {
            match l.aabb(p) {
                Some(b) => out.merge(&b),
                None => out.include(&p.translation.vector.into()),
            }
        }
        out
    }

    /// Root height such that, at the neutral pose with an upright root, the lowest point of the
    /// geometry touches z = 0.
    pub fn standing_root_height(&self) -> f32 {
        let poses = self.forward_kinematics(&self.neutral_pose(Isometry3::identity()));
        -self.lowest_z(&poses)
    }

    /// The neutral pose standing on the ground at the origin, facing +x.
    pub fn standing_pose(&self) -> CharacterPose {
        self.neutral_pose(Isometry3::translation(0.0, 0.0, self.standing_root_height()))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn revolute_and_prismatic_transforms() {
        let j = JointSpec {
            name: "j".into(),
            kind: JointKind::Revolute,
            origin: Isometry3::translation(1.0, 0.0, 0.0),
            axis: Vector3::z_axis(),
            limits: None,
            dof: Some(0),
            mimic: None,
        };
        let t = j.transform(std::f32::consts::FRAC_PI_2);
        let p = t.transform_point(&nalgebra::Point3::new(1.0, 0.0, 0.0));
        assert!((p - nalgebra::Point3::new(1.0, 1.0, 0.0)).norm() < 1e-6);
        let pj = JointSpec {
            kind: JointKind::Prismatic,
            axis: Vector3::y_axis(),
            ..j.clone()
        };
        assert!((pj.transform(0.5).translation.vector - Vector3::new(1.0, 0.5, 0.0)).norm() < 1e-6);
        let mj = JointSpec {
            dof: None,
            mimic: Some(Mimic {
                dof: 1,
                multiplier: -2.0,
                offset: 0.1,
            }),
            ..j
        };
        assert!((mj.position(&[0.0, 0.5]) + 0.9).abs() < 1e-6);
    }

    #[test]
    fn ground_travel_is_the_roots_place_and_heading_away_from_its_rest() {
        // A root whose rest is not upright (a rigged creature's armature turned −90° about x and 0.6 rad
        // about z), turned about the vertical, pitched a little and lifted: the travel is the
        // turn about z and the horizontal place, and taking it away leaves the root at rest over the
        // origin; a quarter turn too, where the heading's x is zero.
        let rest = UnitQuaternion::from_euler_angles(-std::f32::consts::FRAC_PI_2, 0.0, 0.6);
        let pitch = UnitQuaternion::from_axis_angle(&Vector3::y_axis(), 0.1);
        for heading in [0.8, std::f32::consts::FRAC_PI_2, -2.5] {
            let yaw = UnitQuaternion::from_axis_angle(&Vector3::z_axis(), heading);
            let pose = CharacterPose {
                root: Isometry3::from_parts(Translation3::new(1.5, -2.0, 0.4), yaw * pitch * rest),
                q: Vec::new(),
            };
            let m = pose.ground_travel(&rest);
            assert!((m.translation.vector - Vector3::new(1.5, -2.0, 0.0)).norm() < 1e-6);
            assert!(m.rotation.angle_to(&yaw) < 1e-5, "heading {heading}: {} rad", m.rotation.scaled_axis().z);
            let back = m.inverse() * pose.root;
            assert!(back.translation.vector.xy().norm() < 1e-6);
            assert!(back.rotation.angle_to(&(pitch * rest)) < 1e-5);
        }
        // Facing straight up or down there is no heading.
        let up = CharacterPose {
            root: Isometry3::from_parts(Translation3::new(0.3, 0.0, 1.0), UnitQuaternion::from_axis_angle(&Vector3::y_axis(), -std::f32::consts::FRAC_PI_2) * rest),
            q: Vec::new(),
        };
        assert!(up.ground_travel(&rest).rotation.angle() < 1e-6);
    }
}
