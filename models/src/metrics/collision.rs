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
    let (mut x1, mut x2) = (1.0 - INV_PHI, INV_PHI);
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

#[cfg(test)]
mod tests {
    //! The narrow phase against references computed another way (in f64, from first principles), the
    //! primitives against the shapes they stand for, and the pair checks on the bundled characters
    //! against a brute force over every primitive pair.
    use nalgebra::{Quaternion, Translation3, UnitQuaternion, Vector3 as V3};
    use rand::{RngExt, SeedableRng};
    use rand_pcg::Pcg64;

    use super::*;
    use crate::geometry::Aabb;
    use crate::kinematics::CharacterPose;
    use crate::test_data::bundled_character;

    type P64 = nalgebra::Point3<f64>;
    type V64 = nalgebra::Vector3<f64>;

    fn p64(p: &Point3<f32>) -> P64 {
        p.cast()
    }

    fn random_rotation(rng: &mut Pcg64) -> UnitQuaternion<f32> {
        let mut c = || rng.random_range(-1.0f32..1.0);
        UnitQuaternion::from_quaternion(Quaternion::new(c(), c(), c(), c()))
    }

    fn random_point(rng: &mut Pcg64, r: f32) -> Point3<f32> {
        Point3::new(rng.random_range(-r..r), rng.random_range(-r..r), rng.random_range(-r..r))
    }

    fn random_box(rng: &mut Pcg64) -> Primitive {
        let centre = random_point(rng, 0.8);
        let half = V3::new(rng.random_range(0.05f32..0.6), rng.random_range(0.05f32..0.6), rng.random_range(0.05f32..0.6));
        Primitive::Obb {
            center: centre,
            axes: *random_rotation(rng).to_rotation_matrix().matrix(),
            half,
        }
    }

    /// A random segment: one in ten is a point, one in ten is parallel to `along` when given.
    fn random_segment(rng: &mut Pcg64, along: Option<V3<f32>>) -> (Point3<f32>, Point3<f32>) {
        let a = random_point(rng, 1.0);
        let kind = rng.random_range(0..10);
        let b = match (kind, along) {
            (0, _) => a,
            (1, Some(d)) => a + d * rng.random_range(-1.5f32..1.5),
            _ => random_point(rng, 1.0),
        };
        (a, b)
    }

    fn point_segment_distance(p: &P64, a: &P64, b: &P64) -> f64 {
        let d = b - a;
        let t = if d.norm_squared() > 0.0 { ((p - a).dot(&d) / d.norm_squared()).clamp(0.0, 1.0) } else { 0.0 };
        (a + d * t - p).norm()
    }

    /// The squared distance |r + s·d1 − t·d2|² over the unit square is a convex quadratic: its least
    /// value is at its stationary point when that lies inside, else on an edge of the square, where
    /// it is an endpoint's distance to the other segment.
    fn reference_segment_distance(p1: &Point3<f32>, q1: &Point3<f32>, p2: &Point3<f32>, q2: &Point3<f32>) -> f64 {
        let (p1, q1, p2, q2) = (p64(p1), p64(q1), p64(p2), p64(q2));
        let mut best = point_segment_distance(&p1, &p2, &q2)
            .min(point_segment_distance(&q1, &p2, &q2))
            .min(point_segment_distance(&p2, &p1, &q1))
            .min(point_segment_distance(&q2, &p1, &q1));
        let (d1, d2, r) = (q1 - p1, q2 - p2, p1 - p2);
        let (a, b, e) = (d1.dot(&d1), d1.dot(&d2), d2.dot(&d2));
        let det = b * b - a * e;
        if det.abs() > 1e-9 * (a * e).max(1e-30) {
            // a·s − b·t = −d1·r and b·s − e·t = −d2·r.
            let (u, v) = (-d1.dot(&r), -d2.dot(&r));
            let s = (-e * u + b * v) / det;
            let t = (-b * u + a * v) / det;
            if (0.0..=1.0).contains(&s) && (0.0..=1.0).contains(&t) {
                best = best.min((r + d1 * s - d2 * t).norm());
            }
        }
        best
    }

    /// World corners of a box.
    fn corners(center: &Point3<f32>, axes: &Matrix3<f32>, half: &V3<f32>) -> Vec<P64> {
        (0..8)
            .map(|k| {
                let s = V64::new(
                    if k & 1 == 0 { -1.0 } else { 1.0 },
                    if k & 2 == 0 { -1.0 } else { 1.0 },
                    if k & 4 == 0 { -1.0 } else { 1.0 },
                );
                p64(center) + axes.cast::<f64>() * s.component_mul(&half.cast())
            })
            .collect()
    }

    /// Distance from `p` to a box: to its closest point, the point clamped onto the box along each axis.
    fn point_box_distance(p: &P64, center: &Point3<f32>, axes: &Matrix3<f32>, half: &V3<f32>) -> f64 {
        let (c, m, h) = (p64(center), axes.cast::<f64>(), half.cast::<f64>());
        let mut closest = c;
        for i in 0..3 {
            let axis = m.column(i).into_owned();
            closest += axis * (p - c).dot(&axis).clamp(-h[i], h[i]);
        }
        (p - closest).norm()
    }

    /// The distance along a segment is convex: a ternary search finds its least value.
    fn reference_segment_box_distance(a: &Point3<f32>, b: &Point3<f32>, center: &Point3<f32>, axes: &Matrix3<f32>, half: &V3<f32>) -> f64 {
        let (a, b) = (p64(a), p64(b));
        let f = |t: f64| point_box_distance(&(a + (b - a) * t), center, axes, half);
        let (mut lo, mut hi) = (0.0f64, 1.0f64);
        for _ in 0..200 {
            let (m1, m2) = (lo + (hi - lo) / 3.0, hi - (hi - lo) / 3.0);
            if f(m1) <= f(m2) { hi = m2 } else { lo = m1 }
        }
        f(0.5 * (lo + hi)).min(f(0.0)).min(f(1.0))
    }

    /// How far the projections of two corner sets onto `l` overlap: the least shift along `l` that
    /// parts them (negative: the gap between them).
    fn interval_overlap(x: &[P64], y: &[P64], l: &V64) -> f64 {
        let span = |c: &[P64]| c.iter().map(|p| p.coords.dot(l)).fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), v| (lo.min(v), hi.max(v)));
        let ((lx, hx), (ly, hy)) = (span(x), span(y));
        // The shorter of the two pushes that part them along `l`.
        (hx - ly).min(hy - lx)
    }

    /// Two boxes' penetration depth from their corners: the least overlap of their projections over
    /// the face normals and the edge pairs' cross products, the edges read from the corners.
    fn reference_box_box(x: &[P64], y: &[P64]) -> f64 {
        let edges = |c: &[P64]| [c[1] - c[0], c[2] - c[0], c[4] - c[0]];
        let (ex, ey) = (edges(x), edges(y));
        let mut axes: Vec<V64> = ex.iter().chain(&ey).copied().collect();
        for u in &ex {
            for v in &ey {
                axes.push(u.cross(v));
            }
        }
        axes.iter()
            .filter(|l| l.norm() > 1e-6 * ex[0].norm().max(ey[0].norm()).powi(2))
            .map(|l| interval_overlap(x, y, &l.normalize()))
            .fold(f64::INFINITY, f64::min)
    }

    #[test]
    fn segment_distance_is_the_least_distance_between_the_segments() {
        let mut rng = Pcg64::seed_from_u64(7);
        for k in 0..2000 {
            let (p1, q1) = random_segment(&mut rng, None);
            let along = Some(q1 - p1).filter(|d| d.norm() > 0.0);
            let (p2, q2) = random_segment(&mut rng, along);
            let got = segment_distance(&p1, &q1, &p2, &q2) as f64;
            let want = reference_segment_distance(&p1, &q1, &p2, &q2);
            assert!((got - want).abs() < 2e-5, "case {k}: {got} against {want} ({p1} {q1} / {p2} {q2})");
            // The order of the segments and of their ends does not matter.
            let swapped = segment_distance(&q2, &p2, &q1, &p1) as f64;
            assert!((swapped - want).abs() < 2e-5, "case {k} swapped: {swapped} against {want}");
        }
    }

    #[test]
    fn segment_box_distance_is_the_least_distance_from_the_segment_to_the_box() {
        let mut rng = Pcg64::seed_from_u64(8);
        let mut inside = 0;
        for k in 0..1000 {
            let Primitive::Obb { center, axes, half } = random_box(&mut rng) else { unreachable!() };
            let axis = axes.column(rng.random_range(0..3)).into_owned();
            let (a, b) = random_segment(&mut rng, Some(axis));
            let got = segment_box_distance(&a, &b, &center, &axes, &half) as f64;
            let want = reference_segment_box_distance(&a, &b, &center, &axes, &half);
            assert!((got - want).abs() < 2e-5, "case {k}: {got} against {want}");
            inside += usize::from(want < 1e-6);
        }
        assert!(inside > 100 && inside < 900, "both sides are tried: {inside} of 1000 segments touch their box");
    }

    #[test]
    fn a_segment_pointing_away_from_a_box_is_as_far_as_its_nearer_end() {
        // Along the segment's line, beyond either end, lies the box: only points of the segment
        // itself may be searched (the line's points past an end are inside the box).
        let axes = *UnitQuaternion::from_euler_angles(0.4, -0.2, 0.9).to_rotation_matrix().matrix();
        let (center, half) = (Point3::new(0.2, -0.1, 0.3), V3::new(1.0, 0.7, 0.5));
        for (axis, extent) in [(0, 1.0f32), (1, 0.7), (2, 0.5)] {
            let dir = axes.column(axis).into_owned();
            for gap in [0.05f32, 0.3, 0.5] {
                for length in [0.5f32, 1.0, 2.0] {
                    let near = center + dir * (extent + gap);
                    let far = near + dir * length;
                    for (a, b) in [(near, far), (far, near)] {
                        let d = segment_box_distance(&a, &b, &center, &axes, &half);
                        assert!((d - gap).abs() < 1e-4, "axis {axis}, gap {gap}, length {length}: {d}");
                    }
                }
            }
        }
    }

    #[test]
    fn penetration_depth_is_the_overlap_of_the_shapes_in_either_order() {
        let mut rng = Pcg64::seed_from_u64(9);
        let mut overlapping = [0usize; 3];
        for k in 0..1500 {
            let capsule = |rng: &mut Pcg64| {
                let (a, b) = random_segment(rng, None);
                Primitive::Capsule { a, b, radius: rng.random_range(0.02f32..0.3) }
            };
            let (p, q) = match k % 3 {
                0 => (capsule(&mut rng), capsule(&mut rng)),
                1 => (capsule(&mut rng), random_box(&mut rng)),
                _ => (random_box(&mut rng), random_box(&mut rng)),
            };
            let want = match (&p, &q) {
                (Primitive::Capsule { a, b, radius: r }, Primitive::Capsule { a: c, b: d, radius: s }) => {
                    (r + s) as f64 - reference_segment_distance(a, b, c, d)
                }
                (Primitive::Capsule { a, b, radius }, Primitive::Obb { center, axes, half }) => {
                    *radius as f64 - reference_segment_box_distance(a, b, center, axes, half)
                }
                (Primitive::Obb { center, axes, half }, Primitive::Obb { center: c2, axes: a2, half: h2 }) => {
                    reference_box_box(&corners(center, axes, half), &corners(c2, a2, h2))
                }
                _ => unreachable!(),
            };
            for (x, y) in [(&p, &q), (&q, &p)] {
                let got = penetration_depth(x, y) as f64;
                assert!((got - want).abs() < 1e-4, "case {k}: {got} against {want} ({x:?} / {y:?})");
            }
            overlapping[k % 3] += usize::from(want > 0.0);
        }
        for (kind, n) in ["capsules", "capsule and box", "boxes"].iter().zip(overlapping) {
            assert!(n > 50 && n < 450, "{kind}: {n} of 500 overlap; both sides are tried");
        }
    }

    #[test]
    fn box_penetration_is_no_deeper_than_along_any_direction() {
        // The separating-axis theorem: no direction parts two overlapping boxes with a shorter push
        // than the best of the 15 axes.
        let mut rng = Pcg64::seed_from_u64(10);
        let n = 4000;
        let dirs: Vec<V64> = (0..n)
            .map(|i| {
                let z = 1.0 - 2.0 * (i as f64 + 0.5) / n as f64;
                let phi = i as f64 * std::f64::consts::PI * (3.0 - 5f64.sqrt());
                let r = (1.0 - z * z).sqrt();
                V64::new(r * phi.cos(), r * phi.sin(), z)
            })
            .collect();
        let mut overlapping = 0;
        for k in 0..100 {
            let (Primitive::Obb { center, axes, half }, Primitive::Obb { center: c2, axes: a2, half: h2 }) =
                (random_box(&mut rng), random_box(&mut rng))
            else {
                unreachable!()
            };
            let (x, y) = (corners(&center, &axes, &half), corners(&c2, &a2, &h2));
            let sat = box_box_overlap(&center, &axes, &half, &c2, &a2, &h2) as f64;
            let sampled = dirs.iter().map(|l| interval_overlap(&x, &y, l)).fold(f64::INFINITY, f64::min);
            // Apart, some axis parts them as some direction does (the depth is then no distance).
            assert_eq!(sat > 0.0, sampled > 0.0, "case {k}: {sat} against {sampled}");
            if sampled > 0.0 {
                assert!(sat <= sampled + 1e-5, "case {k}: {sat} > {sampled}");
                assert!(sat >= sampled - 0.05, "case {k}: {sat} far below {sampled}");
                overlapping += 1;
            }
        }
        assert!(overlapping > 10 && overlapping < 90, "{overlapping} of 100 pairs overlap");
    }

    /// The world box of a primitive.
    fn primitive_aabb(p: &Primitive) -> Aabb {
        let mut out = Aabb::empty();
        match p {
            Primitive::Capsule { a, b, radius } => {
                for e in [a, b] {
                    out.include(&(e - V3::repeat(*radius)));
                    out.include(&(e + V3::repeat(*radius)));
                }
            }
            Primitive::Obb { center, axes, half } => {
                for c in corners(center, axes, half) {
                    out.include(&c.cast());
                }
            }
        }
        out
    }

    fn assert_boxes_match(a: &Aabb, b: &Aabb, what: &str) {
        assert!((a.min - b.min).norm() < 1e-5 && (a.max - b.max).norm() < 1e-5, "{what}: {a:?} against {b:?}");
    }

    #[test]
    fn primitives_stand_for_their_shapes() {
        let shapes = [
            Shape::Sphere { radius: 0.1 },
            Shape::Capsule { radius: 0.05, length: 0.3 },
            Shape::Cylinder { radius: 0.04, length: 0.5 },
            Shape::Cylinder { radius: 0.2, length: 0.1 },
            Shape::Box { size: V3::new(0.1, 0.2, 0.3) },
            Shape::Mesh {
                filename: "m.stl".into(),
                scale: V3::new(2.0, -1.0, 0.5),
                bounds: Some(Aabb { min: Point3::new(-0.1, 0.0, 0.2), max: Point3::new(0.3, 0.1, 0.4) }),
            },
        ];
        let shifted = Isometry3::from_parts(Translation3::new(0.3, -0.2, 0.7), UnitQuaternion::identity());
        let turned = Isometry3::from_parts(
            Translation3::new(-0.1, 0.4, 0.2),
            UnitQuaternion::from_euler_angles(0.3, -0.7, 1.1),
        );
        for shape in shapes {
            let at = |origin: Isometry3<f32>| Geometry { origin, shape: shape.clone() };
            // Placed without a turn, every primitive spans its shape's box exactly (a long cylinder's
            // capsule ends at its end faces).
            let p = Primitive::from_geometry(&at(shifted)).unwrap();
            assert_boxes_match(&primitive_aabb(&p), &at(shifted).aabb(&Isometry3::identity()).unwrap(), &format!("{shape:?}"));
            assert!((p.lowest_z() - at(shifted).aabb(&Isometry3::identity()).unwrap().min.z).abs() < 1e-6);
            // Turned, it is the shape's primitive at its own origin carried by the turn.
            let turned_p = Primitive::from_geometry(&at(turned)).unwrap();
            let carried = Primitive::from_geometry(&at(Isometry3::identity())).unwrap().transformed(&turned);
            assert_boxes_match(&primitive_aabb(&turned_p), &primitive_aabb(&carried), &format!("{shape:?} turned"));
            assert!((penetration_depth(&turned_p, &carried) - penetration_depth(&carried, &carried)).abs() < 1e-5);
        }
        let long = Primitive::from_geometry(&Geometry { origin: Isometry3::identity(), shape: Shape::Cylinder { radius: 0.04, length: 0.5 } });
        assert!(matches!(long, Some(Primitive::Capsule { radius, .. }) if radius == 0.04), "a long cylinder is a capsule");
        let disc = Primitive::from_geometry(&Geometry { origin: Isometry3::identity(), shape: Shape::Cylinder { radius: 0.2, length: 0.1 } });
        assert!(matches!(disc, Some(Primitive::Obb { .. })), "a disc is a box");
        let unread = Geometry {
            origin: Isometry3::identity(),
            shape: Shape::Mesh { filename: "m.stl".into(), scale: V3::repeat(1.0), bounds: None },
        };
        assert_eq!(Primitive::from_geometry(&unread), None);
    }

    #[test]
    fn lowest_points_and_bounding_spheres_are_exact() {
        let mut rng = Pcg64::seed_from_u64(11);
        for _ in 0..200 {
            let b = random_box(&mut rng);
            let Primitive::Obb { center, axes, half } = b else { unreachable!() };
            let cs = corners(&center, &axes, &half);
            let lowest = cs.iter().map(|c| c.z).fold(f64::INFINITY, f64::min);
            assert!((b.lowest_z() as f64 - lowest).abs() < 1e-5);
            let (c, r) = b.bounding_sphere();
            let far = cs.iter().map(|x| (x - p64(&c)).norm()).fold(0.0, f64::max);
            assert!((far - r as f64).abs() < 1e-5, "the farthest corner lies on the sphere");

            let (a, e) = random_segment(&mut rng, None);
            let radius = rng.random_range(0.02f32..0.3);
            let cap = Primitive::Capsule { a, b: e, radius };
            assert!((cap.lowest_z() - (a.z.min(e.z) - radius)).abs() < 1e-6);
            let (c, r) = cap.bounding_sphere();
            let dir = (e - a).try_normalize(1e-9).unwrap_or(V3::x());
            for tip in [a - dir * radius, e + dir * radius] {
                assert!(((tip - c).norm() - r).abs() < 1e-5, "the capsule's tips lie on its sphere");
            }
        }
    }

    /// A pose with every joint somewhere random within its limits (±π for continuous joints).
    fn random_pose(tree: &KinematicTree, rng: &mut Pcg64) -> CharacterPose {
        let q = (0..tree.dof())
            .map(|d| match tree.limits(d) {
                Some(l) if l.lower.is_finite() && l.upper > l.lower => rng.random_range(l.lower..l.upper),
                _ => rng.random_range(-3.0f32..3.0),
            })
            .collect();
        CharacterPose { root: Isometry3::from_parts(Translation3::new(0.2, -0.1, 0.5), random_rotation(rng)), q }
    }

    #[test]
    fn bodies_carry_their_links_shapes_and_enclose_them_tightly() {
        let mut rng = Pcg64::seed_from_u64(12);
        for name in ["spot", "crab", "stretch"] {
            let tree = bundled_character(name).0;
            let (bodies, body_of) = rigid_bodies(&tree);
            for (i, link) in tree.links.iter().enumerate() {
                let fixed = link.joint.as_ref().is_some_and(|j| !j.kind.is_movable());
                match link.parent {
                    Some(p) if fixed => assert_eq!(body_of[i], body_of[p], "{name}: {} is fixed to its parent", link.name),
                    _ => assert_eq!(bodies[body_of[i]].link, i, "{name}: {} starts a body", link.name),
                }
                assert!(bodies[body_of[i]].links.contains(&i));
            }
            // Each body's nearest ancestor with geometry.
            for b in &bodies {
                let mut up = tree.links[b.link].parent;
                while let Some(l) = up.filter(|&l| bodies[body_of[l]].primitives.is_empty()) {
                    up = tree.links[l].parent;
                }
                assert_eq!(b.neighbour, up.map(|l| body_of[l]), "{name}: {}", tree.links[b.link].name);
            }
            let pose = random_pose(&tree, &mut rng);
            let links = tree.forward_kinematics(&pose);
            let mut posed = PosedBodies::default();
            posed.update(&bodies, &links);
            for (i, link) in tree.links.iter().enumerate() {
                for g in link.extent_geometry() {
                    let Some(p) = Primitive::from_geometry(g) else { continue };
                    let want = primitive_aabb(&p.transformed(&links[i]));
                    let found = posed.primitives[body_of[i]].iter().any(|q| {
                        let got = primitive_aabb(q);
                        (got.min - want.min).norm() < 1e-4 && (got.max - want.max).norm() < 1e-4
                    });
                    assert!(found, "{name}: {}'s shape is where forward kinematics puts it", link.name);
                }
            }
            for (k, b) in bodies.iter().enumerate().filter(|(_, b)| !b.primitives.is_empty()) {
                let (c, r) = posed.spheres[k];
                let spheres: Vec<_> = posed.primitives[k].iter().map(Primitive::bounding_sphere).collect();
                for (pc, pr) in &spheres {
                    assert!((pc - c).norm() + pr <= r + 1e-4, "{name}: body {} encloses its shapes", b.link);
                }
                // Tight: centred in the box of its shapes' spheres in the body frame, so no farther
                // out than that box's half diagonal.
                let mut bx = Aabb::empty();
                for (pc, pr) in b.primitives.iter().map(Primitive::bounding_sphere) {
                    bx.include(&(pc - V3::repeat(pr)));
                    bx.include(&(pc + V3::repeat(pr)));
                }
                let (c, r) = b.sphere;
                assert!((c - bx.center()).norm() < 1e-4 && r <= bx.half_extents().norm() + 1e-4, "{name}: body {}", b.link);
            }
        }
    }

    #[test]
    fn neighbours_and_pairs_within_the_tolerance_at_rest_are_not_checked() {
        // Spheres around a base sphere of radius 0.1 (tolerance 6 mm): `upper` hangs off the base 15 cm
        // from it through `turn`, a link without geometry (a neighbour all the same, as the second
        // axis of a two-axis joint is, apart at rest), `lower` hangs off `upper` 3 mm from the base (within
        // the tolerance: touching by design), `tip` hangs off `lower` 10 cm from the base and far from
        // `upper`. The bounding spheres of the base and `lower` are 3 mm apart, so only a broad phase
        // widened by the tolerance sees that they touch.
        //
        // The same robot a hundred times larger (25 m across, with a tolerance of 60 cm) is checked
        // alike: the broad phase compares squared distances with squared radii at any size. Turned
        // a quarter turn at `j3`, `tip` swings into `upper` (5 cm into it at the small size).
        for k in [1.0f32, 100.0] {
            let sphere = |name: &str, xyz: [f32; 3], r: f32| {
                let [x, y, z] = xyz.map(|v| v * k);
                let r = r * k;
                format!(r#"<link name="{name}"><collision><origin xyz="{x} {y} {z}"/><geometry><sphere radius="{r}"/></geometry></collision></link>"#)
            };
            let joint = |name: &str, parent: &str, child: &str| {
                format!(
                    r#"<joint name="{name}" type="revolute"><parent link="{parent}"/><child link="{child}"/><axis xyz="0 0 1"/><limit lower="-2" upper="2" effort="1" velocity="1"/></joint>"#
                )
            };
            let urdf = format!(
                r#"<robot name="apart"><link name="turn"/>{}{}{}{}{}{}{}{}</robot>"#,
                sphere("base", [0.0, 0.0, 0.0], 0.1),
                sphere("upper", [0.3, 0.0, 0.0], 0.05),
                sphere("lower", [0.0, 0.153, 0.0], 0.05),
                sphere("tip", [0.0, 0.25, 0.0], 0.05),
                joint("j0", "base", "turn"),
                joint("j1", "turn", "upper"),
                joint("j2", "upper", "lower"),
                joint("j3", "lower", "tip"),
            );
            let tree = KinematicTree::from_urdf_str(&urdf).unwrap();
            let check = SelfCollision::new(&tree, 0.006 * k);
            let named = |pairs: Vec<(usize, usize)>| -> Vec<(String, String)> {
                pairs.into_iter().map(|(a, b)| (tree.links[a].name.clone(), tree.links[b].name.clone())).collect()
            };
            let pair = |a: &str, b: &str| (a.to_string(), b.to_string());
            assert_eq!(named(check.link_pairs()), [pair("base", "tip"), pair("upper", "tip")], "×{k}");
            let mut pose = tree.neutral_pose(Isometry3::identity());
            assert_eq!(check.colliding_pairs(&tree.forward_kinematics(&pose)), [], "×{k}");
            pose.q[tree.dof_index("j3").unwrap()] = -std::f32::consts::FRAC_PI_2;
            assert_eq!(named(check.colliding_pairs(&tree.forward_kinematics(&pose))), [pair("upper", "tip")], "×{k}");
        }
    }

    /// The deepest overlap of two bodies over all their primitive pairs, without the broad phase.
    fn brute_depth(posed: &PosedBodies, i: usize, j: usize) -> f32 {
        let mut best = f32::NEG_INFINITY;
        for p in &posed.primitives[i] {
            for q in &posed.primitives[j] {
                best = best.max(penetration_depth(p, q));
            }
        }
        best
    }

    #[test]
    fn checked_pairs_and_collisions_match_a_brute_force_over_every_shape_pair() {
        let mut rng = Pcg64::seed_from_u64(13);
        for name in ["spot", "crab", "stretch"] {
            let tree = bundled_character(name).0;
            let tolerance = 0.006;
            let check = SelfCollision::new(&tree, tolerance);
            let bodies = check.bodies();
            let rest = tree.forward_kinematics(&tree.neutral_pose(Isometry3::identity()));
            let mut posed = PosedBodies::default();
            posed.update(bodies, &rest);
            let mut want = Vec::new();
            for i in 0..bodies.len() {
                for j in i + 1..bodies.len() {
                    let (a, b) = (&bodies[i], &bodies[j]);
                    let neighbours = a.neighbour == Some(j) || b.neighbour == Some(i);
                    let shaped = !a.primitives.is_empty() && !b.primitives.is_empty();
                    if shaped && !neighbours && brute_depth(&posed, i, j) <= -tolerance {
                        want.push((i, j));
                    }
                }
            }
            assert_eq!(check.pairs(), &want[..], "{name}: the pairs apart at rest, neighbours left out");
            assert!(want.len() > 5, "{name}: {} pairs", want.len());
            assert_eq!(check.tolerance(), tolerance);
            let links: Vec<(usize, usize)> = want.iter().map(|&(i, j)| (bodies[i].link, bodies[j].link)).collect();
            assert_eq!(check.link_pairs(), links);

            let mut hits = 0;
            for _ in 0..300 {
                let links = tree.forward_kinematics(&random_pose(&tree, &mut rng));
                posed.update(bodies, &links);
                let mut reported = Vec::new();
                let n = check.for_each_collision(&posed, |k| reported.push(k));
                let brute: Vec<usize> = (0..want.len())
                    .filter(|&k| brute_depth(&posed, want[k].0, want[k].1) > tolerance)
                    .collect();
                assert_eq!(reported, brute, "{name}");
                assert_eq!(n, brute.len());
                let pairs: Vec<(usize, usize)> = brute.iter().map(|&k| (bodies[want[k].0].link, bodies[want[k].1].link)).collect();
                assert_eq!(check.colliding_pairs(&links), pairs);
                for (&k, &(a, b)) in brute.iter().zip(&pairs) {
                    assert_eq!((check.body_of(a), check.body_of(b)), want[k], "{name}: a body's first link is in it");
                }
                hits += brute.len();
            }
            if name != "stretch" {
                // Stretch's checked pairs do not meet in random poses; the other two's legs do.
                assert!(hits > 0, "{name}: random poses collide somewhere");
            }
        }
    }
}
