//! Coarse self-collision proxies: every link's geometry as oriented boxes (exact for boxes, the
//! enclosing box for cylinders, capsules, spheres and mesh bounds), tested pairwise by the separating
//! axis theorem.
//!
//! Contact within a small tolerance `tol` (1 % of the character's height) is allowed: pairs that
//! come within `tol` of each other at the neutral pose are not checked (coarse mesh boxes often nearly
//! meet), and a checked pair collides only when the boxes interpenetrate deeper than `tol / 2`.
//!
//! The controllers use this to keep motion sensible (arm targets whose path would pass through the body
//! or a leg are rejected, legs keep out of each other's way); it is conservative, not a metric. Pairs
//! that can never be separated are ignored: links rigidly fixed together, links joined by one joint,
//! and pairs that already overlap at the neutral pose (the URDF's own idea of "touching").

use nalgebra::{Isometry3, Matrix3, Point3, Vector3};

use crate::geometry::Shape;
use crate::kinematics::{CharacterPose, KinematicTree};

/// An oriented box.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Obb {
    /// Centre.
    pub center: Point3<f32>,
    /// Unit axes as columns.
    pub axes: Matrix3<f32>,
    /// Half extents along the axes.
    pub half: Vector3<f32>,
}

impl Obb {
    /// The box moved by `pose`.
    pub fn transformed(&self, pose: &Isometry3<f32>) -> Obb {
        Obb {
            center: pose.transform_point(&self.center),
            axes: pose.rotation.to_rotation_matrix().matrix() * self.axes,
            half: self.half,
        }
    }

    /// Radius of the bounding sphere.
    pub fn radius(&self) -> f32 {
        self.half.norm()
    }

    /// Lowest z of the box.
    pub fn min_z(&self) -> f32 {
        self.center.z - (0..3).map(|i| self.axes[(2, i)].abs() * self.half[i]).sum::<f32>()
    }

    /// True when the boxes, each grown by `margin` (shrunk when negative), overlap (separating axis
    /// test, 15 axes).
    pub fn overlaps(&self, other: &Obb, margin: f32) -> bool {
        let d = other.center - self.center;
        let rs = self.radius() + other.radius() + 2.0 * margin.max(0.0);
        if d.norm_squared() > rs * rs {
            return false;
        }
        let ha = self.half.add_scalar(margin).sup(&Vector3::zeros());
        let hb = other.half.add_scalar(margin).sup(&Vector3::zeros());
        // R[i][j] = a_i · b_j
        let r = self.axes.transpose() * other.axes;
        let abs_r = r.abs().add_scalar(1e-6);
        let t = self.axes.transpose() * d;
        for i in 0..3 {
            let rb = hb.dot(&abs_r.row(i).transpose());
            if t[i].abs() > ha[i] + rb {
                return false;
            }
        }
        for j in 0..3 {
            let ra = ha.dot(&abs_r.column(j).into_owned());
            if (r.column(j).dot(&t)).abs() > ra + hb[j] {
                return false;
            }
        }
        for i in 0..3 {
            for j in 0..3 {
                let (i1, i2) = ((i + 1) % 3, (i + 2) % 3);
                let (j1, j2) = ((j + 1) % 3, (j + 2) % 3);
                let ra = ha[i1] * abs_r[(i2, j)] + ha[i2] * abs_r[(i1, j)];
                let rb = hb[j1] * abs_r[(i, j2)] + hb[j2] * abs_r[(i, j1)];
                let dist = (t[i2] * r[(i1, j)] - t[i1] * r[(i2, j)]).abs();
                if dist > ra + rb {
                    return false;
                }
            }
        }
        true
    }
}

/// Collision proxies of a whole character and the pairs that are checked.
#[derive(Clone, Debug)]
pub struct Proxies {
    /// Boxes of each link in its own frame (empty for links without geometry of known extent).
    pub local: Vec<Vec<Obb>>,
    /// Rigid body of each link: the nearest ancestor-or-self attached by a movable joint (or the root).
    pub body: Vec<usize>,
    /// `checked[a][b]`: whether the pair of links is tested.
    checked: Vec<Vec<bool>>,
    /// Contact tolerance (m; see the module docs).
    pub tol: f32,
}

impl Proxies {
    /// Builds the proxies and decides which pairs to check, using `neutral` to find pairs that
    /// already touch.
    pub fn new(tree: &KinematicTree, neutral: &CharacterPose) -> Proxies {
        let n = tree.links.len();
        let local: Vec<Vec<Obb>> = tree
            .links
            .iter()
            .map(|l| l.extent_geometry().iter().filter_map(geometry_obb).collect())
            .collect();
        let mut body = vec![0; n];
        for (i, l) in tree.links.iter().enumerate() {
            body[i] = match (&l.joint, l.parent) {
                (Some(j), Some(p)) if !j.kind.is_movable() => body[p],
                _ => i,
            };
        }
        let parent_body = |b: usize| tree.links[b].parent.map(|p| body[p]);
        let poses = tree.forward_kinematics(neutral);
        let tol = {
            let b = tree.aabb(&poses);
            0.01 * (b.max.z - b.min.z).max(1e-3)
        };
        let mut checked = vec![vec![false; n]; n];
        for a in 0..n {
            for b in a + 1..n {
                let (ba, bb) = (body[a], body[b]);
                let adjacent = ba == bb || parent_body(ba) == Some(bb) || parent_body(bb) == Some(ba);
                if adjacent || local[a].is_empty() || local[b].is_empty() {
                    continue;
                }
                let touching = tree.allowed_contacts.contains(&(a, b))
                    || tree.allowed_contacts.contains(&(b, a))
                    || boxes(&local[a], poses[a]).any(|x| boxes(&local[b], poses[b]).any(|y| x.overlaps(&y, 0.5 * tol)));
                checked[a][b] = !touching;
                checked[b][a] = !touching;
            }
        }
        Proxies {
            local,
            body,
            checked,
            tol,
        }
    }

    /// Stops checking the pairs that overlap at link poses `poses` (e.g. a stance the controllers
    /// always pass through).
    pub fn ignore_touching(&mut self, poses: &[Isometry3<f32>]) {
        for (a, b) in self.colliding_pairs(poses, 0.5 * self.tol) {
            self.checked[a][b] = false;
            self.checked[b][a] = false;
        }
    }

    /// Tests again the pairs that `rest` tests and that involve a link marked in `links`, except those
    /// that overlap at link poses `poses` (as [`Proxies::ignore_touching`]): for parts moved away from a
    /// pose where they touched.
    pub fn recheck(&mut self, rest: &Proxies, poses: &[Isometry3<f32>], links: &[bool]) {
        let n = self.checked.len();
        for a in 0..n {
            for b in 0..n {
                if (links[a] || links[b]) && rest.checked[a][b] {
                    let touching = self
                        .world(a, &poses[a])
                        .any(|x| self.world(b, &poses[b]).any(|y| x.overlaps(&y, 0.5 * self.tol)));
                    self.checked[a][b] = !touching;
                }
            }
        }
    }

    /// Whether links `a` and `b` are tested against each other.
    pub fn is_checked(&self, a: usize, b: usize) -> bool {
        self.checked[a][b]
    }

    /// World boxes of link `l` at `pose`.
    pub fn world<'s>(&'s self, l: usize, pose: &Isometry3<f32>) -> impl Iterator<Item = Obb> + use<'s> {
        boxes(&self.local[l], *pose)
    }

    /// Margin for [`Obb::overlaps`] that counts a collision: penetration deeper than `tol / 2`.
    pub fn collision_margin(&self) -> f32 {
        -0.25 * self.tol
    }

    /// Whether links `a` and `b`, at `pa` and `pb`, collide (checked pair, [`Proxies::collision_margin`]).
    pub fn collide(&self, a: usize, pa: &Isometry3<f32>, b: usize, pb: &Isometry3<f32>) -> bool {
        self.checked[a][b]
            && self
                .world(a, pa)
                .any(|x| self.world(b, pb).any(|y| x.overlaps(&y, self.collision_margin())))
    }

    /// The checked link pairs that overlap (grown by `margin`) for link poses `poses`.
    pub fn colliding_pairs(&self, poses: &[Isometry3<f32>], margin: f32) -> Vec<(usize, usize)> {
        let world: Vec<Vec<Obb>> = (0..self.local.len())
            .map(|l| self.world(l, &poses[l]).collect())
            .collect();
        let mut out = Vec::new();
        for a in 0..world.len() {
            for b in a + 1..world.len() {
                if self.checked[a][b] && world[a].iter().any(|x| world[b].iter().any(|y| x.overlaps(y, margin))) {
                    out.push((a, b));
                }
            }
        }
        out
    }
}

fn boxes(local: &[Obb], pose: Isometry3<f32>) -> impl Iterator<Item = Obb> + '_ {
    local.iter().map(move |b| b.transformed(&pose))
}

/// The box enclosing one geometry, in its link's frame.
fn geometry_obb(g: &crate::geometry::Geometry) -> Option<Obb> {
    let (center, half) = match &g.shape {
        Shape::Box { size } => (Point3::origin(), size * 0.5),
        Shape::Sphere { radius } => (Point3::origin(), Vector3::repeat(*radius)),
        Shape::Cylinder { radius, length } => (Point3::origin(), Vector3::new(*radius, *radius, 0.5 * length)),
        Shape::Capsule { radius, length } => (Point3::origin(), Vector3::new(*radius, *radius, 0.5 * length + radius)),
        Shape::Mesh { scale, bounds, .. } => {
            let b = bounds.as_ref()?;
            let lo = b.min.coords.component_mul(scale);
            let hi = b.max.coords.component_mul(scale);
            (Point3::from((lo + hi) * 0.5), ((hi - lo) * 0.5).abs())
        }
    };
    let local = Obb {
        center,
        axes: Matrix3::identity(),
        half,
    };
    Some(local.transformed(&g.origin))
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::UnitQuaternion;

    fn cube(c: [f32; 3], h: f32, yaw: f32) -> Obb {
        Obb {
            center: Point3::from(c),
            axes: UnitQuaternion::from_euler_angles(0.0, 0.0, yaw)
                .to_rotation_matrix()
                .into_inner(),
            half: Vector3::repeat(h),
        }
    }

    #[test]
    fn separating_axes() {
        let a = cube([0.0, 0.0, 0.0], 0.5, 0.0);
        assert!(a.overlaps(&cube([0.9, 0.0, 0.0], 0.5, 0.0), 0.0));
        assert!(!a.overlaps(&cube([1.1, 0.0, 0.0], 0.5, 0.0), 0.0));
        assert!(a.overlaps(&cube([1.1, 0.0, 0.0], 0.5, 0.0), 0.06));
        // A cube turned 45° reaches √2/2 ≈ 0.707 along x.
        assert!(a.overlaps(&cube([1.15, 0.0, 0.0], 0.5, std::f32::consts::FRAC_PI_4), 0.0));
        assert!(!a.overlaps(&cube([1.25, 0.0, 0.0], 0.5, std::f32::consts::FRAC_PI_4), 0.0));
        // Diagonal placement separated only by an edge–edge axis.
        let b = Obb {
            center: Point3::new(1.05, 1.05, 0.0),
            axes: UnitQuaternion::from_euler_angles(0.3, 0.2, 0.785)
                .to_rotation_matrix()
                .into_inner(),
            half: Vector3::new(0.5, 0.05, 0.05),
        };
        assert!(!a.overlaps(&b, 0.0));
        assert!((a.min_z() + 0.5).abs() < 1e-6);
    }
}
