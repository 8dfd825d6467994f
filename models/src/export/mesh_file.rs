//! Mesh files read as triangles for export: binary and ASCII STL, and Wavefront OBJ with the diffuse
//! colours of its MTL materials.
//!
//! STL triangles get flat normals computed from their vertices (the normals stored in STL files are
//! often zero or wrong). OBJ faces use their `vn` normals when every corner gives one, else flat
//! normals; polygons are split into fans. Triangles of zero area are dropped.

use std::collections::HashMap;
use std::path::Path;

use nalgebra::Vector3;
use thiserror::Error;

/// A mesh file that could not be read: which file and why.
#[derive(Debug, Clone, Error, PartialEq)]
#[error("{file}: {problem}")]
pub struct MeshError {
    /// The mesh file.
    pub file: String,
    /// What is wrong.
    pub problem: String,
}

/// Triangles that share one material.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct MeshPart {
    /// Vertex positions in the file's units and frame.
    pub positions: Vec<[f32; 3]>,
    /// Unit vertex normals, one per position.
    pub normals: Vec<[f32; 3]>,
    /// Three vertex indices per triangle, counter-clockwise seen from outside.
    pub indices: Vec<u32>,
    /// Linear RGBA colour from the file's material (OBJ `Kd` and `d`), if it names one.
    pub color: Option<[f32; 4]>,
}

impl MeshPart {
    /// Number of triangles.
    pub fn triangle_count(&self) -> usize {
        self.indices.len() / 3
    }

    /// Adds a triangle with its face normal on all three corners (not shared with other triangles).
    /// Returns false (and adds nothing) for a triangle of zero area.
    pub fn push_flat(&mut self, tri: [[f32; 3]; 3]) -> bool {
        let Some(n) = face_normal(&tri) else {
            return false;
        };
        let base = self.positions.len() as u32;
        self.positions.extend_from_slice(&tri);
        self.normals.extend_from_slice(&[n, n, n]);
        self.indices.extend_from_slice(&[base, base + 1, base + 2]);
        true
    }
}

/// The unit normal of a counter-clockwise triangle, `None` when its area is zero.
pub fn face_normal(tri: &[[f32; 3]; 3]) -> Option<[f32; 3]> {
    let [a, b, c] = tri.map(Vector3::from);
    let n = (b - a).cross(&(c - a));
    let len = n.norm();
    (len > 0.0 && len.is_finite()).then(|| (n / len).into())
}

/// A mesh file's triangles, one part per material.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct MeshData {
    /// Parts with at least one triangle.
    pub parts: Vec<MeshPart>,
    /// Non-fatal problems (a missing MTL file, an unknown material, dropped degenerate triangles).
    pub warnings: Vec<String>,
}

impl MeshData {
    /// Total number of triangles.
    pub fn triangle_count(&self) -> usize {
        self.parts.iter().map(MeshPart::triangle_count).sum()
    }
}

/// Reads an STL (`.stl`) or OBJ (`.obj`) file, chosen by extension (any case). OBJ material files
/// are looked for beside the OBJ.
pub fn read_mesh(path: &Path) -> Result<MeshData, MeshError> {
    let file = path.display().to_string();
    let err = |problem: String| MeshError {
        file: file.clone(),
        problem,
    };
    let ext = path
        .extension()
        .and_then(|e| e.to_str())
        .map(str::to_ascii_lowercase)
        .unwrap_or_default();
    if ext != "stl" && ext != "obj" {
        return Err(err(format!(
            "unsupported mesh format `.{ext}` (STL and OBJ are read)"
        )));
    }
    let bytes = std::fs::read(path).map_err(|e| err(format!("cannot read the file: {e}")))?;
    if ext == "stl" {
        parse_stl(&bytes, &file)
    } else {
        parse_obj(&String::from_utf8_lossy(&bytes), &file, path.parent())
    }
}

/// Parses a binary or ASCII STL; `file` names it in errors. A file whose size is exactly
/// 84 + 50·n bytes for the triangle count n in its header is binary, anything else is read as text.
pub fn parse_stl(bytes: &[u8], file: &str) -> Result<MeshData, MeshError> {
    let err = |problem: String| MeshError {
        file: file.to_string(),
        problem,
    };
    let mut part = MeshPart::default();
    let mut dropped = 0usize;
    let binary_count =
        (bytes.len() >= 84).then(|| u32::from_le_bytes([bytes[80], bytes[81], bytes[82], bytes[83]]));
    if binary_count.is_some_and(|n| 84 + 50 * n as usize == bytes.len()) {
        for tri in bytes[84..].chunks_exact(50) {
            let f = |o: usize| f32::from_le_bytes([tri[o], tri[o + 1], tri[o + 2], tri[o + 3]]);
            let v = |k: usize| [f(12 + 12 * k), f(16 + 12 * k), f(20 + 12 * k)];
            dropped += usize::from(!part.push_flat([v(0), v(1), v(2)]));
        }
    } else {
        let text = String::from_utf8_lossy(bytes);
        if !text.trim_start().starts_with("solid") {
            return Err(err(format!(
                "neither a binary STL ({} bytes, not 84 + 50 × the header's triangle count) nor an ASCII STL \
                 (it does not start with `solid`)",
                bytes.len()
            )));
        }
        let mut corners = Vec::with_capacity(3);
        for (n, line) in text.lines().enumerate() {
            let mut it = line.split_whitespace();
            if it.next() != Some("vertex") {
                continue;
            }
            let v: Vec<f32> = it.map(str::parse).collect::<Result<_, _>>().map_err(|_| {
                err(format!(
                    "line {}: a vertex needs three numbers: `{}`",
                    n + 1,
                    line.trim()
                ))
            })?;
            if v.len() != 3 {
                return Err(err(format!(
                    "line {}: a vertex needs three numbers: `{}`",
                    n + 1,
                    line.trim()
                )));
            }
            corners.push([v[0], v[1], v[2]]);
            if corners.len() == 3 {
                dropped += usize::from(!part.push_flat([corners[0], corners[1], corners[2]]));
                corners.clear();
            }
        }
        if !corners.is_empty() {
            return Err(err("the vertex count is not a multiple of three".into()));
        }
    }
    finish(vec![part], dropped, Vec::new(), file)
}

/// Parses a Wavefront OBJ; `file` names it in errors and `dir` is where `mtllib` files are looked for.
/// Supports `v`, `vn`, `f` (with `v`, `v/vt`, `v//vn`, `v/vt/vn` corners and negative indices),
/// `usemtl` and `mtllib`; everything else is ignored.
pub fn parse_obj(text: &str, file: &str, dir: Option<&Path>) -> Result<MeshData, MeshError> {
    let err = |line: usize, problem: String| MeshError {
        file: file.to_string(),
        problem: format!("line {line}: {problem}"),
    };
    let mut positions: Vec<[f32; 3]> = Vec::new();
    let mut normals: Vec<[f32; 3]> = Vec::new();
    let mut materials: HashMap<String, [f32; 4]> = HashMap::new();
    let mut warnings = Vec::new();
    // One part per material name, in order of first use; "" is the part before any `usemtl`.
    let mut part_names: Vec<String> = vec![String::new()];
    let mut parts: Vec<MeshPart> = vec![MeshPart::default()];
    // Smooth vertices are shared per (position, normal) pair within a part.
    let mut shared: Vec<HashMap<(usize, usize), u32>> = vec![HashMap::new()];
    let mut current = 0usize;
    let mut dropped = 0usize;

    for (n, raw) in text.lines().enumerate() {
        let line = n + 1;
        let mut it = raw.split_whitespace();
        let Some(key) = it.next() else { continue };
        match key {
            "v" | "vn" => {
                let v: Vec<f32> = it
                    .take(3)
                    .map(str::parse)
                    .collect::<Result<_, _>>()
                    .map_err(|_| err(line, format!("`{key}` needs three numbers")))?;
                if v.len() != 3 || v.iter().any(|x| !x.is_finite()) {
                    return Err(err(line, format!("`{key}` needs three finite numbers")));
                }
                let v = [v[0], v[1], v[2]];
                if key == "v" {
                    positions.push(v);
                } else {
                    normals.push(v);
                }
            }
            "f" => {
                let corners: Vec<(usize, Option<usize>)> = it
                    .map(|c| obj_corner(c, positions.len(), normals.len()))
                    .collect::<Result<_, _>>()
                    .map_err(|p| err(line, p))?;
                if corners.len() < 3 {
                    return Err(err(line, "a face needs at least three corners".into()));
                }
                for k in 1..corners.len() - 1 {
                    let tri = [corners[0], corners[k], corners[k + 1]];
                    let pos = tri.map(|(p, _)| positions[p]);
                    let Some(flat) = face_normal(&pos) else {
                        dropped += 1;
                        continue;
                    };
                    let part = &mut parts[current];
                    for (p, vn) in tri {
                        let smooth = vn.and_then(|i| unit(normals[i]));
                        let index = match (smooth, vn) {
                            (Some(nrm), Some(i)) => *shared[current].entry((p, i)).or_insert_with(|| {
                                part.positions.push(positions[p]);
                                part.normals.push(nrm);
                                part.positions.len() as u32 - 1
                            }),
                            _ => {
                                part.positions.push(positions[p]);
                                part.normals.push(flat);
                                part.positions.len() as u32 - 1
                            }
                        };
                        part.indices.push(index);
                    }
                }
            }
            "usemtl" => {
                let name = it.collect::<Vec<_>>().join(" ");
                current = match part_names.iter().position(|p| *p == name) {
                    Some(i) => i,
                    None => {
                        let color = materials.get(&name).copied();
                        if color.is_none() {
                            warnings.push(format!(
                                "{file}: material `{name}` is not defined in its MTL files"
                            ));
                        }
                        part_names.push(name);
                        parts.push(MeshPart {
                            color,
                            ..MeshPart::default()
                        });
                        shared.push(HashMap::new());
                        parts.len() - 1
                    }
                };
            }
            "mtllib" => {
                for lib in it {
                    let path = dir.map_or_else(|| Path::new(lib).to_path_buf(), |d| d.join(lib));
                    match std::fs::read_to_string(&path) {
                        Ok(mtl) => materials.extend(parse_mtl_colors(&mtl)),
                        Err(e) => warnings.push(format!(
                            "{file}: material file {} cannot be read ({e}); its colours are not used",
                            path.display()
                        )),
                    }
                }
            }
            _ => {}
        }
    }
    finish(parts, dropped, warnings, file)
}

/// Resolves one OBJ face corner `v[/vt[/vn]]` to 0-based (position, normal) indices.
fn obj_corner(corner: &str, n_pos: usize, n_nrm: usize) -> Result<(usize, Option<usize>), String> {
    let resolve = |s: &str, len: usize, what: &str| -> Result<usize, String> {
        let i: i64 = s
            .parse()
            .map_err(|_| format!("face corner `{corner}` has a bad {what} index"))?;
        let k = if i > 0 { i - 1 } else { len as i64 + i };
        if i == 0 || k < 0 || k >= len as i64 {
            return Err(format!(
                "face corner `{corner}` refers to {what} {i}, but {len} are defined so far"
            ));
        }
        Ok(k as usize)
    };
    let mut fields = corner.split('/');
    let p = resolve(fields.next().unwrap_or(""), n_pos, "vertex")?;
    let _texcoord = fields.next();
    let vn = match fields.next() {
        Some(s) if !s.is_empty() => Some(resolve(s, n_nrm, "normal")?),
        _ => None,
    };
    Ok((p, vn))
}

/// Diffuse colours of the materials in an MTL file: `Kd` with opacity from `d` (or `1 − Tr`).
fn parse_mtl_colors(text: &str) -> HashMap<String, [f32; 4]> {
    let mut out = HashMap::new();
    let mut name: Option<String> = None;
    for line in text.lines() {
        let mut it = line.split_whitespace();
        let key = it.next();
        let nums: Vec<f32> = it.clone().filter_map(|s| s.parse().ok()).collect();
        match key {
            Some("newmtl") => {
                let n = it.collect::<Vec<_>>().join(" ");
                out.insert(n.clone(), [0.8, 0.8, 0.8, 1.0]);
                name = Some(n);
            }
            Some("Kd") if nums.len() >= 3 => {
                if let Some(c) = name.as_ref().and_then(|n| out.get_mut(n)) {
                    c[..3].copy_from_slice(&nums[..3].iter().map(|v| v.clamp(0.0, 1.0)).collect::<Vec<_>>());
                }
            }
            Some(k @ ("d" | "Tr")) if !nums.is_empty() => {
                if let Some(c) = name.as_ref().and_then(|n| out.get_mut(n)) {
                    let d = if k == "d" { nums[0] } else { 1.0 - nums[0] };
                    c[3] = d.clamp(0.0, 1.0);
                }
            }
            _ => {}
        }
    }
    out
}

fn unit(v: [f32; 3]) -> Option<[f32; 3]> {
    let v = Vector3::from(v);
    let len = v.norm();
    (len > 1e-6 && len.is_finite()).then(|| (v / len).into())
}

/// Drops empty parts, notes dropped triangles, and fails when no triangle is left.
fn finish(
    parts: Vec<MeshPart>,
    dropped: usize,
    mut warnings: Vec<String>,
    file: &str,
) -> Result<MeshData, MeshError> {
    let parts: Vec<MeshPart> = parts.into_iter().filter(|p| !p.indices.is_empty()).collect();
    if parts.is_empty() {
        return Err(MeshError {
            file: file.to_string(),
            problem: "the mesh has no triangles of non-zero area".into(),
        });
    }
    if dropped > 0 {
        warnings.push(format!("{file}: {dropped} triangle(s) of zero area dropped"));
    }
    Ok(MeshData { parts, warnings })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn tmp_dir(tag: &str) -> std::path::PathBuf {
        let d = std::env::temp_dir().join(format!("ace_mesh_{tag}_{}", std::process::id()));
        std::fs::create_dir_all(&d).unwrap();
        d
    }

    /// A binary STL of the given triangles.
    fn binary_stl(tris: &[[[f32; 3]; 3]]) -> Vec<u8> {
        let mut b = vec![0u8; 80];
        b.extend_from_slice(&(tris.len() as u32).to_le_bytes());
        for t in tris {
            b.extend_from_slice(&[0u8; 12]);
            for v in t {
                for x in v {
                    b.extend_from_slice(&x.to_le_bytes());
                }
            }
            b.extend_from_slice(&[0, 0]);
        }
        b
    }

    #[test]
    fn binary_and_ascii_stl_give_the_same_triangles() {
        let tris = [
            [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]],
            [[0.0, 0.0, 0.0], [0.0, 0.0, 1.0], [1.0, 0.0, 0.0]],
            // Zero area: dropped with a warning.
            [[0.0, 0.0, 0.0], [1.0, 1.0, 1.0], [2.0, 2.0, 2.0]],
        ];
        let bin = parse_stl(&binary_stl(&tris), "b.stl").unwrap();
        let mut ascii = String::from("solid t\n");
        for t in &tris {
            ascii.push_str("facet normal 0 0 0\nouter loop\n");
            for v in t {
                ascii.push_str(&format!("vertex {} {} {}\n", v[0], v[1], v[2]));
            }
            ascii.push_str("endloop\nendfacet\n");
        }
        ascii.push_str("endsolid t\n");
        let txt = parse_stl(ascii.as_bytes(), "a.stl").unwrap();
        assert_eq!(bin.parts, txt.parts);
        assert_eq!(bin.triangle_count(), 2);
        assert_eq!(bin.parts[0].normals[0], [0.0, 0.0, 1.0]);
        assert_eq!(bin.parts[0].normals[3], [0.0, 1.0, 0.0]);
        assert!(
            bin.warnings[0].contains("1 triangle(s) of zero area"),
            "{:?}",
            bin.warnings
        );
        let e = parse_stl(b"not a mesh at all", "x.stl").unwrap_err();
        assert!(e.to_string().starts_with("x.stl: neither a binary STL"), "{e}");
    }

    #[test]
    fn obj_faces_normals_and_materials() {
        let dir = tmp_dir("obj");
        std::fs::write(dir.join("m.mtl"), "newmtl red\nKd 1 0 0\nd 0.5\nnewmtl plain\n").unwrap();
        let obj = "mtllib m.mtl\nv 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nvn 0 0 2\n\
                   usemtl red\nf 1//1 2//1 3//1 4//1\nusemtl plain\nf -4 -3 -2\n";
        let path = dir.join("quad.obj");
        std::fs::write(&path, obj).unwrap();
        let m = read_mesh(&path).unwrap();
        assert!(m.warnings.is_empty(), "{:?}", m.warnings);
        assert_eq!(m.parts.len(), 2);
        let red = &m.parts[0];
        assert_eq!(red.color, Some([1.0, 0.0, 0.0, 0.5]));
        // The quad is a fan of two triangles sharing the four smooth vertices (normal renormalised).
        assert_eq!(red.indices, vec![0, 1, 2, 0, 2, 3]);
        assert_eq!(red.positions.len(), 4);
        assert!(red.normals.iter().all(|n| *n == [0.0, 0.0, 1.0]));
        // Without `vn` the triangle is flat-shaded with its own vertices; `plain` has the MTL default.
        let plain = &m.parts[1];
        assert_eq!(plain.color, Some([0.8, 0.8, 0.8, 1.0]));
        assert_eq!(
            plain.positions,
            vec![[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [1.0, 1.0, 0.0]]
        );
        let bad = dir.join("bad.obj");
        std::fs::write(&bad, "v 0 0 0\nf 1 2 3\n").unwrap();
        let e = read_mesh(&bad).unwrap_err();
        assert_eq!(e.file, bad.display().to_string());
        assert!(
            e.problem
                .starts_with("line 2: face corner `2` refers to vertex 2"),
            "{e}"
        );
        let e = read_mesh(&dir.join("x.dae")).unwrap_err();
        assert!(e.problem.contains("unsupported mesh format `.dae`"), "{e}");
        let _ = std::fs::remove_dir_all(&dir);
    }
}
