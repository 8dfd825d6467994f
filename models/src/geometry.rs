//! Link geometry (URDF `<visual>` / `<collision>` shapes) and the bounding volumes that morphology
//! analysis and collision checks use.
//!
//! Shapes are kept as URDF describes them (cylinders and capsules along their local z). Meshes are not
//! loaded for rendering here; the URDF import reads the vertex bounding box of each mesh file (STL, OBJ
//! or Collada, [`crate::mesh_file::read_mesh_bounds`]) so that meshes have an extent too. A mesh whose
//! file is missing or unreadable has `bounds: None` and then counts as having no extent (callers fall
//! back to the link origin).

use nalgebra::{Isometry3, Point3, Vector3};

/// Axis-aligned bounding box.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Aabb {
    /// Minimum corner.
    pub min: Point3<f32>,
    /// Maximum corner.
    pub max: Point3<f32>,
}

impl Aabb {
    /// The empty box (min = +∞, max = −∞); [`Aabb::merge`] and [`Aabb::include`] grow it.
    pub fn empty() -> Self {
        Aabb {
            min: Point3::from(Vector3::repeat(f32::INFINITY)),
            max: Point3::from(Vector3::repeat(f32::NEG_INFINITY)),
        }
    }
    /// True when nothing was included yet.
    pub fn is_empty(&self) -> bool {
        self.min.x > self.max.x
    }
    /// Grows the box to contain `p`.
    pub fn include(&mut self, p: &Point3<f32>) {
        self.min = self.min.inf(p);
        self.max = self.max.sup(p);
    }
    /// Grows the box to contain `other`.
    pub fn merge(&mut self, other: &Aabb) {
        if !other.is_empty() {
            self.min = self.min.inf(&other.min);
            self.max = self.max.sup(&other.max);
        }
    }
    /// Centre of the box.
    pub fn center(&self) -> Point3<f32> {
        nalgebra::center(&self.min, &self.max)
    }
    /// Half extents.
    pub fn half_extents(&self) -> Vector3<f32> {
        (self.max - self.min) * 0.5
    }
    /// The eight corners.
    pub fn corners(&self) -> [Point3<f32>; 8] {
        let (a, b) = (self.min, self.max);
        [
            Point3::new(a.x, a.y, a.z),
            Point3::new(b.x, a.y, a.z),
            Point3::new(a.x, b.y, a.z),
            Point3::new(b.x, b.y, a.z),
            Point3::new(a.x, a.y, b.z),
            Point3::new(b.x, a.y, b.z),
            Point3::new(a.x, b.y, b.z),
            Point3::new(b.x, b.y, b.z),
        ]
    }
}

/// A geometric primitive as URDF describes it.
#[derive(Clone, Debug, PartialEq)]
pub enum Shape {
    /// Box with full side lengths `size`, centred on its origin.
    Box { size: Vector3<f32> },
    /// Cylinder along its local z axis, centred on its origin.
    Cylinder { radius: f32, length: f32 },
    /// Sphere centred on its origin.
    Sphere { radius: f32 },
    /// Capsule along local z: a cylinder of `length` with hemispherical caps of `radius` (URDF 1.2).
    Capsule { radius: f32, length: f32 },
    /// Mesh file as written in the URDF (`package://…`, relative or absolute), not loaded.
    /// `bounds` is the vertex bounding box in the file's own units before `scale`, when it was read
    /// (see [`crate::mesh_file::read_mesh_bounds`]).
    Mesh {
        filename: String,
        scale: Vector3<f32>,
        bounds: Option<Aabb>,
    },
}

/// One visual or collision element of a link: a shape placed at `origin` in the link frame.
#[derive(Clone, Debug, PartialEq)]
pub struct Geometry {
    /// Pose of the shape in the link frame.
    pub origin: Isometry3<f32>,
    /// The shape.
    pub shape: Shape,
}

impl Geometry {
    /// Bounding box in the frame in which the link has pose `link_pose` (pass the identity for the link
    /// frame, or the link's world pose for a world box). `None` for a mesh without known bounds.
    pub fn aabb(&self, link_pose: &Isometry3<f32>) -> Option<Aabb> {
        let pose = link_pose * self.origin;
        let c = Point3::from(pose.translation.vector);
        let r = pose.rotation.to_rotation_matrix();
        let m = r.matrix();
        let half = match &self.shape {
            Shape::Box { size } => m.abs() * (size * 0.5),
            Shape::Sphere { radius } => Vector3::repeat(*radius),
            Shape::Cylinder { radius, length } => {
                // Exact box of a cylinder with axis a: r·sqrt(1 − a_i²) + (l/2)·|a_i| per world axis
                // (1 − a_i² written as the sum of the other two squares, which keeps precision).
                let a = m.column(2);
                Vector3::from_fn(|i, _| {
                    let (j, k) = ((i + 1) % 3, (i + 2) % 3);
                    radius * (a[j] * a[j] + a[k] * a[k]).sqrt() + 0.5 * length * a[i].abs()
                })
            }
            Shape::Capsule { radius, length } => {
                let a = m.column(2);
                Vector3::from_fn(|i, _| radius + 0.5 * length * a[i].abs())
            }
            Shape::Mesh { scale, bounds, .. } => {
                let b = bounds.as_ref()?;
                let mut out = Aabb::empty();
                for p in b.corners() {
                    out.include(&pose.transform_point(&Point3::from(p.coords.component_mul(scale))));
                }
                return Some(out);
            }
        };
        Some(Aabb {
            min: c - half,
            max: c + half,
        })
    }

    /// Bounding sphere `(centre, radius)` in the link frame (a sphere around the local box, so
    /// approximate for boxes and meshes). `None` for a mesh without known bounds.
    pub fn bounding_sphere(&self) -> Option<(Point3<f32>, f32)> {
        match &self.shape {
            Shape::Sphere { radius } => Some((Point3::from(self.origin.translation.vector), *radius)),
            Shape::Cylinder { radius, length } => {
                Some((Point3::from(self.origin.translation.vector), radius.hypot(0.5 * length)))
            }
            Shape::Capsule { radius, length } => {
                Some((Point3::from(self.origin.translation.vector), radius + 0.5 * length))
            }
            Shape::Box { size } => Some((Point3::from(self.origin.translation.vector), 0.5 * size.norm())),
            Shape::Mesh { scale, bounds, .. } => {
                let b = bounds.as_ref()?;
                let lo = b.min.coords.component_mul(scale);
                let hi = b.max.coords.component_mul(scale);
                let centre = self.origin.transform_point(&Point3::from((lo + hi) * 0.5));
                Some((centre, 0.5 * (hi - lo).norm()))
            }
        }
    }
}

/// Bounding box of several geometries of one link placed at `link_pose`; `None` when none has a known
/// extent.
pub fn geometries_aabb(geoms: &[Geometry], link_pose: &Isometry3<f32>) -> Option<Aabb> {
    let mut out = Aabb::empty();
    for g in geoms {
        if let Some(b) = g.aabb(link_pose) {
            out.merge(&b);
        }
    }
    (!out.is_empty()).then_some(out)
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::{Translation3, UnitQuaternion};
    use std::f32::consts::FRAC_PI_2;

    #[test]
    fn cylinder_lying_on_its_side() {
        // A wheel: cylinder axis turned from z to y.
        let g = Geometry {
            origin: Isometry3::from_parts(
                Translation3::new(0.0, 0.0, 0.1),
                UnitQuaternion::from_euler_angles(FRAC_PI_2, 0.0, 0.0),
            ),
            shape: Shape::Cylinder {
                radius: 0.1,
                length: 0.04,
            },
        };
        let b = g.aabb(&Isometry3::identity()).unwrap();
        assert!((b.min - Point3::new(-0.1, -0.02, 0.0)).norm() < 1e-5, "{b:?}");
        assert!((b.max - Point3::new(0.1, 0.02, 0.2)).norm() < 1e-5, "{b:?}");
    }

    #[test]
    fn rotated_box_and_sphere() {
        let g = Geometry {
            origin: Isometry3::rotation(Vector3::z() * FRAC_PI_2),
            shape: Shape::Box {
                size: Vector3::new(2.0, 1.0, 0.5),
            },
        };
        let b = g.aabb(&Isometry3::translation(1.0, 0.0, 0.0)).unwrap();
        assert!((b.half_extents() - Vector3::new(0.5, 1.0, 0.25)).norm() < 1e-5);
        assert!((b.center() - Point3::new(1.0, 0.0, 0.0)).norm() < 1e-5);
        let s = Geometry {
            origin: Isometry3::translation(0.0, 0.0, -1.0),
            shape: Shape::Sphere { radius: 0.2 },
        };
        assert_eq!(s.bounding_sphere(), Some((Point3::new(0.0, 0.0, -1.0), 0.2)));
        assert!((s.aabb(&Isometry3::identity()).unwrap().min.z + 1.2).abs() < 1e-6);
    }

    #[test]
    fn mesh_without_bounds_has_no_extent() {
        let g = Geometry {
            origin: Isometry3::identity(),
            shape: Shape::Mesh {
                filename: "x.dae".into(),
                scale: Vector3::repeat(1.0),
                bounds: None,
            },
        };
        assert!(g.aabb(&Isometry3::identity()).is_none());
        assert!(geometries_aabb(&[g], &Isometry3::identity()).is_none());
    }

    /// The hand-written Collada pyramid (decimetres, base ±1, apex at 2) under a URDF scale of (2, 1, 0.5)
    /// and a collision origin 0.3 m up: the link's collision extent is the scaled mesh's.
    #[test]
    fn collada_collision_mesh_has_its_extent() {
        let urdf = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/urdf/pyramid.urdf");
        let tree = crate::kinematics::KinematicTree::from_urdf_file(&urdf).unwrap();
        assert!(tree.warnings.is_empty(), "{:?}", tree.warnings);
        let base = tree.links.iter().find(|l| l.name == "base").unwrap();
        let b = geometries_aabb(&base.collisions, &Isometry3::identity()).unwrap();
        assert!((b.min - Point3::new(-0.2, -0.1, 0.3)).norm() < 1e-6, "{b:?}");
        assert!((b.max - Point3::new(0.2, 0.1, 0.4)).norm() < 1e-6, "{b:?}");
    }
}
