//! A small software renderer for `ace demo`: wireframes of characters and human skeletons,
//! projected orthographically onto a PNG. No GPU or window needed.

use std::path::Path;

use ace::models::geometry::Shape;
use ace::models::human::{HumanFrame, Joint};
use ace::models::kinematics::{CharacterPose, KinematicTree};
use ace::models::nalgebra::{Isometry3, Point3, Vector3};
use anyhow::{Context, Result};
use image::{Rgb, RgbImage};

/// A coloured 3-D line segment (metres, z up).
pub type Segment = (Vector3<f32>, Vector3<f32>, [u8; 3]);

/// Segments outlining the visual geometry of a posed character (meshes as their bounding boxes; a
/// link without visuals, such as a creature's bone, by its collision shapes), plus a line from each
/// link to its parent.
pub fn character_segments(tree: &KinematicTree, pose: &CharacterPose, color: [u8; 3]) -> Vec<Segment> {
    let world = tree.forward_kinematics(pose);
    let mut out = Vec::new();
    for (i, link) in tree.links.iter().enumerate() {
        if let Some(p) = link.parent {
            out.push((world[p].translation.vector, world[i].translation.vector, [120, 120, 120]));
        }
        let shapes = if link.visuals.is_empty() { &link.collisions } else { &link.visuals };
        for g in shapes {
            shape_segments(&(world[i] * g.origin), &g.shape, color, &mut out);
        }
    }
    out
}

fn circle(frame: &Isometry3<f32>, center: Vector3<f32>, u: Vector3<f32>, v: Vector3<f32>, r: f32, color: [u8; 3], out: &mut Vec<Segment>) {
    const N: usize = 24;
    let at = |k: usize| {
        let a = k as f32 / N as f32 * std::f32::consts::TAU;
        frame * Point3::from(center + (u * a.cos() + v * a.sin()) * r)
    };
    for k in 0..N {
        out.push((at(k).coords, at(k + 1).coords, color));
    }
}

fn shape_segments(frame: &Isometry3<f32>, shape: &Shape, color: [u8; 3], out: &mut Vec<Segment>) {
    let (x, y, z): (Vector3<f32>, Vector3<f32>, Vector3<f32>) = (Vector3::x(), Vector3::y(), Vector3::z());
    match shape {
        Shape::Box { size } => {
            let h = size / 2.0;
            let corner = |i: usize| frame * Point3::new(if i & 1 == 0 { -h.x } else { h.x }, if i & 2 == 0 { -h.y } else { h.y }, if i & 4 == 0 { -h.z } else { h.z });
            for i in 0..8 {
                for bit in [1, 2, 4] {
                    if i & bit == 0 {
                        out.push((corner(i).coords, corner(i | bit).coords, color));
                    }
                }
            }
        }
        &Shape::Cylinder { radius, length } | &Shape::Capsule { radius, length } => {
            for s in [-0.5, 0.5] {
                circle(frame, z * length * s, x, y, radius, color, out);
            }
            for (a, b) in [(x, 1.0), (x, -1.0), (y, 1.0), (y, -1.0)] {
                let p = a * radius * b;
                out.push(((frame * Point3::from(p - z * length / 2.0)).coords, (frame * Point3::from(p + z * length / 2.0)).coords, color));
            }
        }
        &Shape::Sphere { radius } => {
            for (u, v) in [(x, y), (y, z), (z, x)] {
                circle(frame, Vector3::zeros(), u, v, radius, color, out);
            }
        }
        // Mesh files are drawn as their bounding box when it could be read.
        Shape::Mesh { bounds: Some(b), scale, .. } => {
            let size = (b.max - b.min).component_mul(scale);
            let center = frame * Isometry3::translation(b.center().x * scale.x, b.center().y * scale.y, b.center().z * scale.z);
            shape_segments(&center, &Shape::Box { size }, color, out);
        }
        Shape::Mesh { bounds: None, .. } => {}
    }
}

/// Segments of a human skeleton: one bone per canonical joint and its parent.
pub fn human_segments(frame: &HumanFrame, offset: Vector3<f32>, color: [u8; 3]) -> Vec<Segment> {
    Joint::ALL
        .iter()
        .filter_map(|j| j.parent().map(|p| (frame.positions[p.index()] + offset, frame.positions[j.index()] + offset, color)))
        .collect()
}

/// A ground grid of 0.5 m cells under everything in `segments`, with a cell of margin.
pub fn ground_segments(segments: &[Segment]) -> Vec<Segment> {
    const CELL: f32 = 0.5;
    let (mut lo, mut hi) = ((0.0f32, 0.0f32), (0.0f32, 0.0f32));
    for p in segments.iter().flat_map(|(a, b, _)| [a, b]) {
        lo = (lo.0.min(p.x), lo.1.min(p.y));
        hi = (hi.0.max(p.x), hi.1.max(p.y));
    }
    let cell = |v: f32, up: bool| if up { (v / CELL).ceil() as i32 + 1 } else { (v / CELL).floor() as i32 - 1 };
    let (x0, x1, y0, y1) = (cell(lo.0, false), cell(hi.0, true), cell(lo.1, false), cell(hi.1, true));
    let color = [205, 205, 205];
    let xs = (x0..=x1).map(|i| {
        let x = i as f32 * CELL;
        (Vector3::new(x, y0 as f32 * CELL, 0.0), Vector3::new(x, y1 as f32 * CELL, 0.0), color)
    });
    let ys = (y0..=y1).map(|j| {
        let y = j as f32 * CELL;
        (Vector3::new(x0 as f32 * CELL, y, 0.0), Vector3::new(x1 as f32 * CELL, y, 0.0), color)
    });
    xs.chain(ys).collect()
}

/// Renders segments orthographically, seen from azimuth `yaw` and elevation `pitch` (radians),
/// scaled to fit a `width`×`height` image, and writes it as PNG.
pub fn render(segments: &[Segment], width: u32, height: u32, yaw: f32, pitch: f32, path: &Path) -> Result<()> {
    let (sy, cy, sp, cp) = (yaw.sin(), yaw.cos(), pitch.sin(), pitch.cos());
    // Camera right and up vectors for a camera looking at the origin from (yaw, pitch).
    let right = Vector3::new(-sy, cy, 0.0);
    let up = Vector3::new(-cy * sp, -sy * sp, cp);
    let project = |p: &Vector3<f32>| (p.dot(&right), p.dot(&up));
    let (mut lo, mut hi) = ((f32::MAX, f32::MAX), (f32::MIN, f32::MIN));
    for (a, b, _) in segments {
        for (u, v) in [project(a), project(b)] {
            lo = (lo.0.min(u), lo.1.min(v));
            hi = (hi.0.max(u), hi.1.max(v));
        }
    }
    let margin = 20.0;
    let scale = ((width as f32 - 2.0 * margin) / (hi.0 - lo.0).max(1e-3)).min((height as f32 - 2.0 * margin) / (hi.1 - lo.1).max(1e-3));
    let cx = width as f32 / 2.0 - (lo.0 + hi.0) / 2.0 * scale;
    let cyy = height as f32 / 2.0 + (lo.1 + hi.1) / 2.0 * scale;
    let mut img = RgbImage::from_pixel(width, height, Rgb([250, 250, 248]));
    for (a, b, color) in segments {
        let (pa, pb) = (project(a), project(b));
        let to_px = |(u, v): (f32, f32)| (cx + u * scale, cyy - v * scale);
        line(&mut img, to_px(pa), to_px(pb), Rgb(*color));
    }
    if let Some(dir) = path.parent() {
        std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
    }
    img.save(path).with_context(|| format!("writing {}", path.display()))
}

/// A two-pixel-wide line.
fn line(img: &mut RgbImage, (x0, y0): (f32, f32), (x1, y1): (f32, f32), color: Rgb<u8>) {
    let steps = ((x1 - x0).abs().max((y1 - y0).abs()).ceil() as usize).max(1);
    for s in 0..=steps {
        let t = s as f32 / steps as f32;
        let (x, y) = (x0 + (x1 - x0) * t, y0 + (y1 - y0) * t);
        for (dx, dy) in [(0.0, 0.0), (1.0, 0.0), (0.0, 1.0), (1.0, 1.0)] {
            let (px, py) = ((x + dx - 0.5).floor(), (y + dy - 0.5).floor());
            if px >= 0.0 && py >= 0.0 && (px as u32) < img.width() && (py as u32) < img.height() {
                img.put_pixel(px as u32, py as u32, color);
            }
        }
    }
}
