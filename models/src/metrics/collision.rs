//! Self-collision of a character from its URDF geometry: convex primitives, a narrow phase on them,
//! rigid bodies, and the set of body pairs worth checking.
//!
//! # Approximation of the URDF shapes ([`Primitive::from_geometry`])
//! - sphere → a sphere (exact); capsule → a capsule (exact); box → an oriented box (exact);
//! - cylinder at least as long as its diameter → the capsule with the same radius whose caps end at the
//!   cylinder's end faces (it lies inside the cylinder and misses only the rims);
//! - shorter cylinder (a disc, a wheel) → its bounding oriented box;
//! - mesh with known bounds → the oriented box of its vertex bounds (coarse: a convex box around the
//!   mesh); mesh without bounds → nothing (the link has no extent, as elsewhere in the crate).
//!
//! Each link's shapes come from [`crate::kinematics::Link::extent_geometry`] (collision shapes, else
//! visual shapes).
//!
//! # Which pairs are checked ([`SelfCollision::new`])
//! Links joined by fixed joints form one rigid body and never collide with each other. A body does not
//! collide with its *kinematic neighbour*: the nearest ancestor body that has geometry (bodies without
//! geometry in between — the dummy links of multi-axis joints — are skipped), because neighbouring
//! shapes meet at their joint by design. Pairs that already overlap at the neutral pose
//! ([`KinematicTree::neutral_q`]), or come within the collision tolerance of touching there, are left
//! out too: that contact is part of the model (nested telescope stages, shapes authored to intersect,
//! coarse boxes around meshes that nearly meet — PhantomX's thighs sit 1 mm from its body plate's box),
//! as in MoveIt's "default" collision matrix. The price: a part designed to rest against another (an
//! arm stowed on the body) is not checked against it. Pairs the tree declares in
//! [`KinematicTree::allowed_contacts`] are left out as well.
//!
//! # Narrow phase
//! [`penetration_depth`] is exact for capsule–capsule and capsule–box (closest distance minus radii;
//! inside-the-box counts as the capsule's radius) and uses the separating-axis test on the 15 axes for
//! box–box (the smallest overlap over the axes, which is the exact penetration depth of two boxes).
//! A pair collides when the depth exceeds a tolerance, so grazing contact within the tolerance is not
//! counted. The broad phase compares bounding spheres of bodies, then of primitives.

use nalgebra::{Isometry3, Matrix3, Point3, Vector3};

use crate::geometry::{Geometry, Shape};
use crate::kinematics::KinematicTree;

/// A convex primitive placed in some frame.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Primitive {
    /// Points within `radius` of the segment `a`–`b` (a sphere when `a == b`).
    Capsule {
        a: Point3<f32>,
        b: Point3<f32>,
        radius: f32,
    },
    /// Oriented box: centre, axes (columns of `axes`, orthonormal) and half extents along them.
    Obb {
        center: Point3<f32>,
        axes: Matrix3<f32>,
        half: Vector3<f32>,
    },
}

impl Primitive {
    /// The primitive standing for a URDF shape, in the frame the geometry is given in (its link frame);
    /// see the module docs. `None` for a mesh without known bounds.
    pub fn from_geometry(g: &Geometry) -> Option<Primitive> {
        let o = &g.origin;
        let centre = Point3::from(o.translation.vector);
        let axes = *o.rotation.to_rotation_matrix().matrix();
        let capsule = |half_len: f32, radius: f32| {
            let d = o.rotation * Vector3::new(0.0, 0.0, half_len);
            Primitive::Capsule {
                a: centre - d,
                b: centre + d,
                radius,
            }
        };
        Some(match &g.shape {
            Shape::Sphere { radius } => capsule(0.0, *radius),
            Shape::Capsule { radius, length } => capsule(0.5 * length, *radius),
            Shape::Cylinder { radius, length } if *length >= 2.0 * radius => capsule(0.5 * length - radius, *radius),
            Shape::Cylinder { radius, length } => Primitive::Obb {
                center: centre,
                axes,
                half: Vector3::new(*radius, *radius, 0.5 * length),
            },
            Shape::Box { size } => Primitive::Obb {
                center: centre,
                axes,
                half: size * 0.5,
            },
            Shape::Mesh { scale, bounds, .. } => {
                let b = bounds.as_ref()?;
                let lo = b.min.coords.component_mul(scale);
                let hi = b.max.coords.component_mul(scale);
                Primitive::Obb {
                    center: o * Point3::from((lo + hi) * 0.5),
                    axes,
                    half: ((hi - lo) * 0.5).abs(),
                }
            }
        })
    }

    /// The primitive moved by `iso`.
    pub fn transformed(&self, iso: &Isometry3<f32>) -> Primitive {
        self.transformed_with(iso, iso.rotation.to_rotation_matrix().matrix())
    }

    /// [`Primitive::transformed`] with the rotation matrix of `iso` already computed.
    fn transformed_with(&self, iso: &Isometry3<f32>, rot: &Matrix3<f32>) -> Primitive {
        match self {
            Primitive::Capsule { a, b, radius } => Primitive::Capsule {
                a: iso * a,
                b: iso * b,
                radius: *radius,
            },
            Primitive::Obb { center, axes, half } => Primitive::Obb {
                center: iso * center,
                axes: rot * axes,
                half: *half,
            },
        }
    }

    /// Bounding sphere `(centre, radius)`.
    pub fn bounding_sphere(&self) -> (Point3<f32>, f32) {
        match self {
            Primitive::Capsule { a, b, radius } => (nalgebra::center(a, b), 0.5 * (b - a).norm() + radius),
            Primitive::Obb { center, half, .. } => (*center, half.norm()),
        }
    }

    /// Lowest world z of the primitive.
    pub fn lowest_z(&self) -> f32 {
        match self {
            Primitive::Capsule { a, b, radius } => a.z.min(b.z) - radius,
            Primitive::Obb { center, axes, half } => {
                center.z - (axes[(2, 0)].abs() * half.x + axes[(2, 1)].abs() * half.y + axes[(2, 2)].abs() * half.z)
            }
        }
    }
}

/// How deep two primitives interpenetrate (m): positive when they overlap; zero or negative when
/// they do not (for two boxes the negative value is not a distance). See the module docs.
pub fn penetration_depth(p: &Primitive, q: &Primitive) -> f32 {
    use Primitive::*;
    match (p, q) {
        (Capsule { a, b, radius: r }, Capsule { a: c, b: d, radius: s }) => r + s - segment_distance(a, b, c, d),
        (Capsule { a, b, radius }, Obb { center, axes, half })
        | (Obb { center, axes, half }, Capsule { a, b, radius }) => {
            radius - segment_box_distance(a, b, center, axes, half)
        }
        (
            Obb { center, axes, half },
            Obb {
                center: c2,
                axes: a2,
                half: h2,
            },
        ) => box_box_overlap(center, axes, half, c2, a2, h2),
    }
}

/// Distance between segments `p1`–`q1` and `p2`–`q2` (Ericson, Real-Time Collision Detection, 5.1.9).
pub fn segment_distance(p1: &Point3<f32>, q1: &Point3<f32>, p2: &Point3<f32>, q2: &Point3<f32>) -> f32 {
    const EPS: f32 = 1e-12;
    let d1 = q1 - p1;
    let d2 = q2 - p2;
    let r = p1 - p2;
    let a = d1.norm_squared();
    let e = d2.norm_squared();
    let f = d2.dot(&r);
    let (s, t);
    if a <= EPS && e <= EPS {
        return r.norm();
    }
    if a <= EPS {
        s = 0.0;
        t = (f / e).clamp(0.0, 1.0);
    } else {
        let c = d1.dot(&r);
        if e <= EPS {
            t = 0.0;
            s = (-c / a).clamp(0.0, 1.0);
        } else {
            let b = d1.dot(&d2);
            let denom = a * e - b * b;
            let s0 = if denom > EPS {
                ((b * f - c * e) / denom).clamp(0.0, 1.0)
            } else {
                0.0
            };
            let t0 = (b * s0 + f) / e;
            if t0 < 0.0 {
                t = 0.0;
                s = (-c / a).clamp(0.0, 1.0);
            } else if t0 > 1.0 {
                t = 1.0;
                s = ((b - c) / a).clamp(0.0, 1.0);
            } else {
                t = t0;
                s = s0;
            }
        }
    }
    ((p1 + d1 * s) - (p2 + d2 * t)).norm()
}

/// Distance from a point given in box coordinates to a box of half extents `half` centred at the origin.
fn point_box_distance_local(p: &Vector3<f32>, half: &Vector3<f32>) -> f32 {
    Vector3::from_fn(|i, _| (p[i].abs() - half[i]).max(0.0)).norm()
}

/// Distance between segment `a`–`b` and an oriented box (0 when they intersect). The distance along
/// the segment is convex, so a golden-section search finds its minimum (to ~1e-6 of the segment).
pub fn segment_box_distance(
    a: &Point3<f32>,
    b: &Point3<f32>,
    center: &Point3<f32>,
    axes: &Matrix3<f32>,
    half: &Vector3<f32>,
) -> f32 {
    let la = axes.tr_mul(&(a - center));
    let lb = axes.tr_mul(&(b - center));
    let d = lb - la;
    let f = |t: f32| point_box_distance_local(&(la + d * t), half);
    if d.norm_squared() < 1e-12 {
        return f(0.0);
    }
    const INV_PHI: f32 = 0.618_034;
    let (mut lo, mut hi) = (0.0f32, 1.0f32);
    let mut x1 = hi - INV_PHI * (hi - lo);
    let mut x2 = lo + INV_PHI * (hi - lo);
    let (mut f1, mut f2) = (f(x1), f(x2));
    for _ in 0..30 {
        if f1 == 0.0 || f2 == 0.0 {
            return 0.0;
        }
        if f1 < f2 {
            hi = x2;
            x2 = x1;
            f2 = f1;
            x1 = hi - INV_PHI * (hi - lo);
            f1 = f(x1);
        } else {
            lo = x1;
            x1 = x2;
            f1 = f2;
            x2 = lo + INV_PHI * (hi - lo);
            f2 = f(x2);
        }
    }
    f1.min(f2).min(f(0.0)).min(f(1.0))
}

/// Separating-axis test of two oriented boxes: the smallest overlap of their projections over the 15
/// candidate axes (negative when an axis separates them).
fn box_box_overlap(
    c1: &Point3<f32>,
    a1: &Matrix3<f32>,
    h1: &Vector3<f32>,
    c2: &Point3<f32>,
    a2: &Matrix3<f32>,
    h2: &Vector3<f32>,
) -> f32 {
    let t = c2 - c1;
    let mut best = f32::INFINITY;
    let mut test = |l: Vector3<f32>| {
        let n2 = l.norm_squared();
        if n2 < 1e-10 {
            return; // parallel edges: the face axes cover this case
        }
        let l = l / n2.sqrt();
        let r1: f32 = (0..3).map(|i| h1[i] * a1.column(i).dot(&l).abs()).sum();
        let r2: f32 = (0..3).map(|i| h2[i] * a2.column(i).dot(&l).abs()).sum();
        best = best.min(r1 + r2 - t.dot(&l).abs());
    };
    for i in 0..3 {
        test(a1.column(i).into_owned());
        test(a2.column(i).into_owned());
    }
    for i in 0..3 {
        for j in 0..3 {
            test(a1.column(i).cross(&a2.column(j)));
        }
    }
    best
}

/// A rigid body: links joined by fixed joints, with their primitives in the frame of its first link.
#[derive(Clone, Debug)]
pub struct RigidBody {
    /// The body's first link (the root or a link with a movable joint); its frame is the body frame.
    pub link: usize,
    /// Every link of the body.
    pub links: Vec<usize>,
    /// Primitives in the body frame.
    pub primitives: Vec<Primitive>,
    /// Per primitive: true when it is a box around a mesh (a coarse stand-in).
    pub from_mesh: Vec<bool>,
    /// Bounding sphere of all primitives in the body frame (radius −∞ when there are none).
    pub sphere: (Point3<f32>, f32),
    /// The nearest ancestor body that has primitives.
    pub neighbour: Option<usize>,
}

impl RigidBody {
    /// True when the body has geometry.
    pub fn has_geometry(&self) -> bool {
        !self.primitives.is_empty()
    }
}

/// Splits a tree into rigid bodies (in link order of their first links) and returns them with the
/// body index of every link.
pub fn rigid_bodies(tree: &KinematicTree) -> (Vec<RigidBody>, Vec<usize>) {
    let n = tree.links.len();
    let rest = tree.forward_kinematics(&tree.neutral_pose(Isometry3::identity()));
    let mut body_of = vec![0usize; n];
    let mut bodies: Vec<RigidBody> = Vec::new();
    for (i, l) in tree.links.iter().enumerate() {
        let movable = l.joint.as_ref().is_some_and(|j| j.kind.is_movable());
        match l.parent {
            Some(p) if !movable => body_of[i] = body_of[p],
            _ => {
                body_of[i] = bodies.len();
                bodies.push(RigidBody {
                    link: i,
                    links: Vec::new(),
                    primitives: Vec::new(),
                    from_mesh: Vec::new(),
                    sphere: (Point3::origin(), f32::NEG_INFINITY),
                    neighbour: None,
                });
            }
        }
        let b = &mut bodies[body_of[i]];
        b.links.push(i);
        // Fixed offset of this link in the body frame (constant, so read at the rest pose).
        let in_body = rest[b.link].inv_mul(&rest[i]);
        for g in l.extent_geometry() {
            if let Some(p) = Primitive::from_geometry(g) {
                b.primitives.push(p.transformed(&in_body));
                b.from_mesh.push(matches!(g.shape, Shape::Mesh { .. }));
            }
        }
    }
    for k in 0..bodies.len() {
        bodies[k].sphere = enclosing_sphere(&bodies[k].primitives);
        let mut up = tree.links[bodies[k].link].parent.map(|p| body_of[p]);
        while let Some(u) = up {
            if bodies[u].has_geometry() {
                break;
            }
            up = tree.links[bodies[u].link].parent.map(|p| body_of[p]);
        }
        bodies[k].neighbour = up;
    }
    (bodies, body_of)
}

/// A sphere around all primitives (centre of their spheres' bounding box; radius to the farthest).
fn enclosing_sphere(prims: &[Primitive]) -> (Point3<f32>, f32) {
    if prims.is_empty() {
        return (Point3::origin(), f32::NEG_INFINITY);
    }
    let spheres: Vec<_> = prims.iter().map(Primitive::bounding_sphere).collect();
    let mut lo = Vector3::repeat(f32::INFINITY);
    let mut hi = Vector3::repeat(f32::NEG_INFINITY);
    for (c, r) in &spheres {
        lo = lo.inf(&(c.coords - Vector3::repeat(*r)));
        hi = hi.sup(&(c.coords + Vector3::repeat(*r)));
    }
    let centre = Point3::from((lo + hi) * 0.5);
    let radius = spheres.iter().map(|(c, r)| (c - centre).norm() + r).fold(0.0, f32::max);
    (centre, radius)
}

/// The world primitives and bounding spheres of every body for one pose (reused between frames).
#[derive(Clone, Debug, Default)]
pub struct PosedBodies {
    /// World primitives per body.
    pub primitives: Vec<Vec<Primitive>>,
    /// World bounding sphere per body.
    pub spheres: Vec<(Point3<f32>, f32)>,
}

impl PosedBodies {
    /// Places `bodies` at the link poses `links` (e.g. from forward kinematics).
    pub fn update(&mut self, bodies: &[RigidBody], links: &[Isometry3<f32>]) {
        self.primitives.resize_with(bodies.len(), Vec::new);
        self.spheres.resize(bodies.len(), (Point3::origin(), 0.0));
        for (k, b) in bodies.iter().enumerate() {
            let iso = &links[b.link];
            let rot = *iso.rotation.to_rotation_matrix().matrix();
            let out = &mut self.primitives[k];
            out.clear();
            out.extend(b.primitives.iter().map(|p| p.transformed_with(iso, &rot)));
            self.spheres[k] = (iso * b.sphere.0, b.sphere.1);
        }
    }
}

/// Self-collision checks of one character: its rigid bodies and the body pairs to check (module docs).
#[derive(Clone, Debug)]
pub struct SelfCollision {
    bodies: Vec<RigidBody>,
    body_of: Vec<usize>,
    pairs: Vec<(usize, usize)>,
    tolerance: f32,
}

impl SelfCollision {
    /// Builds the bodies and the pairs to check; `tolerance` (m) is the penetration depth a pair must
    /// exceed to count as colliding.
    pub fn new(tree: &KinematicTree, tolerance: f32) -> Self {
        let (bodies, body_of) = rigid_bodies(tree);
        let rest = tree.forward_kinematics(&tree.neutral_pose(Isometry3::identity()));
        let mut posed = PosedBodies::default();
        posed.update(&bodies, &rest);
        let allowed: Vec<(usize, usize)> = tree
            .allowed_contacts
            .iter()
            .map(|&(a, b)| (body_of[a].min(body_of[b]), body_of[a].max(body_of[b])))
            .collect();
        let mut pairs = Vec::new();
        for i in 0..bodies.len() {
            for j in i + 1..bodies.len() {
                let (a, b) = (&bodies[i], &bodies[j]);
                if !a.has_geometry() || !b.has_geometry() || a.neighbour == Some(j) || b.neighbour == Some(i) {
                    continue;
                }
                // Touching (within the tolerance) or overlapping at rest, or declared by the model.
                if pair_depth(&posed, i, j, -tolerance) > -tolerance || allowed.contains(&(i, j)) {
                    continue;
                }
                pairs.push((i, j));
            }
        }
        SelfCollision {
            bodies,
            body_of,
            pairs,
            tolerance,
        }
    }

    /// The rigid bodies.
    pub fn bodies(&self) -> &[RigidBody] {
        &self.bodies
    }

    /// The index of the body that link `link` belongs to.
    pub fn body_of(&self, link: usize) -> usize {
        self.body_of[link]
    }

    /// The checked pairs as body indices.
    pub fn pairs(&self) -> &[(usize, usize)] {
        &self.pairs
    }

    /// The checked pairs as the first link of each body.
    pub fn link_pairs(&self) -> Vec<(usize, usize)> {
        self.pairs
            .iter()
            .map(|&(a, b)| (self.bodies[a].link, self.bodies[b].link))
            .collect()
    }

    /// The penetration depth a pair must exceed to collide (m).
    pub fn tolerance(&self) -> f32 {
        self.tolerance
    }

    /// Calls `hit(pair_index)` for every checked pair that collides with the bodies placed in `posed`
    /// (indices into [`SelfCollision::pairs`]); returns how many collide.
    pub fn for_each_collision(&self, posed: &PosedBodies, mut hit: impl FnMut(usize)) -> usize {
        let mut n = 0;
        for (k, &(i, j)) in self.pairs.iter().enumerate() {
            if pair_depth(posed, i, j, self.tolerance) > self.tolerance {
                hit(k);
                n += 1;
            }
        }
        n
    }

    /// The colliding pairs (as first links of the bodies) for link poses `links`.
    pub fn colliding_pairs(&self, links: &[Isometry3<f32>]) -> Vec<(usize, usize)> {
        let mut posed = PosedBodies::default();
        posed.update(&self.bodies, links);
        let mut out = Vec::new();
        self.for_each_collision(&posed, |k| {
            let (a, b) = self.pairs[k];
            out.push((self.bodies[a].link, self.bodies[b].link));
        });
        out
    }
}

/// True when two bounding spheres overlap by more than `margin`.
fn spheres_overlap(a: &(Point3<f32>, f32), b: &(Point3<f32>, f32), margin: f32) -> bool {
    let r = a.1 + b.1 - margin;
    r > 0.0 && (a.0 - b.0).norm_squared() < r * r
}

/// The largest penetration depth between the primitives of bodies `i` and `j`, over primitive pairs
/// whose bounding spheres overlap by more than `margin` (−∞ when there are none). Skipping the others
/// loses nothing above `margin`: two shapes cannot interpenetrate deeper than their bounding spheres.
fn pair_depth(posed: &PosedBodies, i: usize, j: usize, margin: f32) -> f32 {
    if !spheres_overlap(&posed.spheres[i], &posed.spheres[j], margin) {
        return f32::NEG_INFINITY;
    }
    let mut best = f32::NEG_INFINITY;
    for p in &posed.primitives[i] {
        let ps = p.bounding_sphere();
        for q in &posed.primitives[j] {
            if spheres_overlap(&ps, &q.bounding_sphere(), margin) {
                best = best.max(penetration_depth(p, q));
            }
        }
    }
    best
}
