//! Triangle meshes of the URDF primitives (box, cylinder, sphere, capsule) for export, in the shape's
//! own frame: centred on the origin, cylinders and capsules along z, as [`crate::geometry::Shape`]
//! describes them. Normals are unit length; triangles are counter-clockwise seen from outside.

use std::f32::consts::{FRAC_PI_2, PI};

use nalgebra::Vector3;

use crate::geometry::Shape;
use crate::mesh_file::MeshPart;

/// The mesh of a primitive `shape` with `segments` segments around round shapes (at least 3);
/// `None` for [`Shape::Mesh`], which is read from its file instead.
pub fn shape_mesh(shape: &Shape, segments: u32) -> Option<MeshPart> {
    let n = segments.max(3);
    Some(match shape {
        Shape::Box { size } => box_mesh(size),
        Shape::Cylinder { radius, length } => cylinder_mesh(*radius, *length, n),
        Shape::Sphere { radius } => sphere_mesh(*radius, n),
        Shape::Capsule { radius, length } => capsule_mesh(*radius, *length, n),
        Shape::Mesh { .. } => return None,
    })
}

/// A box with full side lengths `size`: 24 vertices (four per face, flat normals), 12 triangles.
pub fn box_mesh(size: &Vector3<f32>) -> MeshPart {
    let h = size * 0.5;
    let mut m = MeshPart::default();
    for axis in 0..3 {
        for sign in [-1.0f32, 1.0] {
            // Face normal n with in-face axes u, v such that u × v = n: the corners below run
            // counter-clockwise seen from outside.
            let n = Vector3::ith(axis, sign);
            let u = Vector3::ith((axis + 1) % 3, sign);
            let v = Vector3::ith((axis + 2) % 3, 1.0);
            let base = m.positions.len() as u32;
            for (a, b) in [(-1.0, -1.0), (1.0, -1.0), (1.0, 1.0), (-1.0, 1.0)] {
                let p = (n + u * a + v * b).component_mul(&h);
                m.positions.push(p.into());
                m.normals.push(n.into());
            }
            m.indices
                .extend_from_slice(&[base, base + 1, base + 2, base, base + 2, base + 3]);
        }
    }
    m
}

/// A cylinder along z, centred: side with smooth normals, flat caps.
pub fn cylinder_mesh(radius: f32, length: f32, segments: u32) -> MeshPart {
    let (r, h) = (radius, 0.5 * length);
    lathe(
        &[
            vec![pt(0.0, -h, 0.0, -1.0), pt(r, -h, 0.0, -1.0)],
            vec![pt(r, -h, 1.0, 0.0), pt(r, h, 1.0, 0.0)],
            vec![pt(r, h, 0.0, 1.0), pt(0.0, h, 0.0, 1.0)],
        ],
        segments,
    )
}

/// A sphere centred on the origin, `segments` around and `segments / 2` from pole to pole.
pub fn sphere_mesh(radius: f32, segments: u32) -> MeshPart {
    capsule_mesh(radius, 0.0, segments)
}

/// A capsule along z: a cylinder of `length` between two hemispheres of `radius`.
pub fn capsule_mesh(radius: f32, length: f32, segments: u32) -> MeshPart {
    // Each hemisphere has segments/4 bands (at least 2) from pole to equator.
    let quarter = (segments / 4).max(2);
    let h = 0.5 * length;
    let mut profile = Vec::new();
    for k in 0..=quarter {
        let a = -FRAC_PI_2 + FRAC_PI_2 * k as f32 / quarter as f32;
        let (s, c) = a.sin_cos();
        profile.push(pt(radius * c, radius * s - h, c, s));
    }
    // The equator is repeated at +h only for a capsule; a sphere's two hemispheres meet there.
    let start = u32::from(length <= 0.0);
    for k in start..=quarter {
        let a = FRAC_PI_2 * k as f32 / quarter as f32;
        let (s, c) = a.sin_cos();
        profile.push(pt(radius * c, radius * s + h, c, s));
    }
    // Exact zeros at the poles so that they become single vertices.
    profile[0].r = 0.0;
    profile.last_mut().expect("profile has points").r = 0.0;
    lathe(&[profile], segments)
}

/// A point of a surface-of-revolution profile: radius from the z axis, height, and the normal's
/// (radial, z) components.
#[derive(Clone, Copy, Debug)]
struct ProfilePoint {
    r: f32,
    z: f32,
    nr: f32,
    nz: f32,
}

fn pt(r: f32, z: f32, nr: f32, nz: f32) -> ProfilePoint {
    ProfilePoint { r, z, nr, nz }
}

/// Revolves `bands` about z with `segments` segments. Each band is a profile polyline traversed from
/// bottom to top along the outer surface; consecutive points of a band are joined, bands are not (so a
/// hard edge is two bands meeting at the same radius and height). A point with `r == 0` is a pole: one
/// vertex joined by a triangle fan.
fn lathe(bands: &[Vec<ProfilePoint>], segments: u32) -> MeshPart {
    let n = segments.max(3);
    let angles: Vec<(f32, f32)> = (0..n)
        .map(|j| (2.0 * PI * j as f32 / n as f32).sin_cos())
        .collect();
    let mut m = MeshPart::default();
    for band in bands {
        // First vertex of each profile point's ring (a pole has one vertex).
        let mut rings: Vec<(u32, bool)> = Vec::with_capacity(band.len());
        for p in band {
            rings.push((m.positions.len() as u32, p.r == 0.0));
            if p.r == 0.0 {
                let nz = if p.nz < 0.0 { -1.0 } else { 1.0 };
                m.positions.push([0.0, 0.0, p.z]);
                m.normals.push([0.0, 0.0, nz]);
            } else {
                let len = p.nr.hypot(p.nz);
                for &(s, c) in &angles {
                    m.positions.push([p.r * c, p.r * s, p.z]);
                    m.normals.push([p.nr * c / len, p.nr * s / len, p.nz / len]);
                }
            }
        }
        for w in rings.windows(2) {
            let ((a, a_pole), (b, b_pole)) = (w[0], w[1]);
            for j in 0..n {
                let k = (j + 1) % n;
                let (aj, ak) = if a_pole { (a, a) } else { (a + j, a + k) };
                let (bj, bk) = if b_pole { (b, b) } else { (b + j, b + k) };
                if !a_pole {
                    m.indices.extend_from_slice(&[aj, ak, bk]);
                }
                if !b_pole {
                    m.indices.extend_from_slice(&[aj, bk, bj]);
                }
            }
        }
    }
    m
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Enclosed volume by the divergence theorem; positive when triangles face outwards.
    fn volume(m: &MeshPart) -> f32 {
        m.indices
            .chunks_exact(3)
            .map(|t| {
                let [a, b, c] = [0, 1, 2].map(|i| Vector3::from(m.positions[t[i] as usize]));
                a.dot(&b.cross(&c)) / 6.0
            })
            .sum()
    }

    /// Every edge is used exactly twice, once in each direction: a closed, consistently wound surface.
    fn is_closed(m: &MeshPart) -> bool {
        let mut edges = std::collections::HashMap::new();
        for t in m.indices.chunks_exact(3) {
            for (a, b) in [(t[0], t[1]), (t[1], t[2]), (t[2], t[0])] {
                // Identify vertices by position: hard edges duplicate vertices.
                let key = |i: u32| m.positions[i as usize].map(f32::to_bits);
                *edges.entry((key(a), key(b))).or_insert(0) += 1;
            }
        }
        edges
            .iter()
            .all(|(&(a, b), &c)| c == 1 && edges.get(&(b, a)) == Some(&1))
    }

    fn check(m: &MeshPart, expected_volume: f32, tol: f32) {
        assert!(is_closed(m));
        assert_eq!(m.positions.len(), m.normals.len());
        for n in &m.normals {
            assert!((Vector3::from(*n).norm() - 1.0).abs() < 1e-5, "{n:?}");
        }
        // Vertex normals point away from the centre on these convex shapes.
        for (p, n) in m.positions.iter().zip(&m.normals) {
            assert!(Vector3::from(*p).dot(&Vector3::from(*n)) > 0.0, "{p:?} {n:?}");
        }
        let v = volume(m);
        assert!(
            (v - expected_volume).abs() < tol * expected_volume,
            "{v} vs {expected_volume}"
        );
    }

    #[test]
    fn primitives_are_closed_outward_and_have_their_volume() {
        let b = box_mesh(&Vector3::new(0.2, 0.4, 1.0));
        assert_eq!((b.positions.len(), b.triangle_count()), (24, 12));
        check(&b, 0.08, 1e-5);
        // An n-gon prism has volume ½·n·r²·sin(2π/n)·L exactly.
        let n = 24;
        let c = cylinder_mesh(0.1, 0.5, n);
        check(
            &c,
            0.5 * n as f32 * 0.01 * (2.0 * PI / n as f32).sin() * 0.5,
            1e-5,
        );
        // Round shapes approach the analytic volume as the segment count grows.
        let s = sphere_mesh(0.3, 64);
        check(&s, 4.0 / 3.0 * PI * 0.027, 0.01);
        let k = capsule_mesh(0.1, 0.4, 64);
        check(&k, PI * 0.01 * 0.4 + 4.0 / 3.0 * PI * 0.001, 0.01);
        assert!(
            shape_mesh(
                &Shape::Mesh {
                    filename: "a.stl".into(),
                    scale: Vector3::repeat(1.0),
                    bounds: None
                },
                8
            )
            .is_none()
        );
    }

    #[test]
    fn cylinder_extent_matches_its_shape() {
        let c = cylinder_mesh(0.25, 2.0, 16);
        let z: Vec<f32> = c.positions.iter().map(|p| p[2]).collect();
        assert_eq!(z.iter().cloned().fold(f32::INFINITY, f32::min), -1.0);
        assert_eq!(z.iter().cloned().fold(f32::NEG_INFINITY, f32::max), 1.0);
        let r = c
            .positions
            .iter()
            .map(|p| p[0].hypot(p[1]))
            .fold(0.0f32, f32::max);
        assert!((r - 0.25).abs() < 1e-6);
    }
}
