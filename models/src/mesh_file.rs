//! Mesh files that URDF visuals and collisions name, read through `mesh-loader`: binary and ASCII STL,
//! Wavefront OBJ with the diffuse colours of its MTL materials, and Collada (`.dae`) with the diffuse
//! colours of its effects, its `<unit>` and node transforms applied and its `<up_axis>` ignored (as
//! ROS tools read it). This module adapts the crate's scene to the triangles the glTF export writes
//! ([`read_mesh`]) and gives the vertex bounds that link geometry uses ([`read_mesh_bounds`]).
//!
//! STL triangles get flat normals computed from their vertices (the normals stored in STL files are
//! often zero or wrong); OBJ and Collada corners keep the file's normal where they have a non-zero one.
//! Triangles of zero area are dropped. Corners with the same position and normal are shared.

use std::collections::HashMap;
use std::panic::{AssertUnwindSafe, catch_unwind};
use std::path::Path;

use mesh_loader::{Loader, Material, Scene};
use nalgebra::{Point3, Vector3};
use thiserror::Error;

use crate::geometry::Aabb;

/// A mesh file that could not be read: which file and why.
#[derive(Debug, Clone, Error, PartialEq)]
#[error("{file}: {problem}")]
pub struct MeshError {
    /// The mesh file.
    pub file: String,
    /// What is wrong.
    pub problem: String,
}

/// Triangles that share one colour.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct MeshPart {
    /// Vertex positions in the file's units and frame.
    pub positions: Vec<[f32; 3]>,
    /// Unit vertex normals, one per position.
    pub normals: Vec<[f32; 3]>,
    /// Three vertex indices per triangle, counter-clockwise seen from outside.
    pub indices: Vec<u32>,
    /// Linear RGBA colour from the file's material (OBJ `Kd` and `d`, Collada `<diffuse>` and
    /// transparency), if it gives one.
    pub color: Option<[f32; 4]>,
}

impl MeshPart {
    /// Number of triangles.
    pub fn triangle_count(&self) -> usize {
        self.indices.len() / 3
    }
}

/// A mesh file's triangles, one part per colour.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct MeshData {
    /// Parts with at least one triangle.
    pub parts: Vec<MeshPart>,
    /// Non-fatal problems (an unreadable MTL file, dropped degenerate triangles).
    pub warnings: Vec<String>,
}

impl MeshData {
    /// Total number of triangles.
    pub fn triangle_count(&self) -> usize {
        self.parts.iter().map(MeshPart::triangle_count).sum()
    }
}

/// Reads an STL (`.stl`), OBJ (`.obj`) or Collada (`.dae`) file, chosen by extension (any case). OBJ
/// material files are looked for beside the OBJ.
pub fn read_mesh(path: &Path) -> Result<MeshData, MeshError> {
    let (scene, mut warnings) = load(path)?;
    let file = path.display().to_string();
    let file_normals = extension(path) != "stl";
    let mut parts: Vec<SharedPart> = Vec::new();
    let mut dropped = 0usize;
    for (mesh, material) in scene.meshes.iter().zip(&scene.materials) {
        let color = material_color(material);
        let k = match parts.iter().position(|p| p.part.color == color) {
            Some(k) => k,
            None => {
                parts.push(SharedPart::new(color));
                parts.len() - 1
            }
        };
        for face in &mesh.faces {
            let [Some(a), Some(b), Some(c)] = face.map(|v| mesh.vertices.get(v as usize).copied()) else {
                return Err(MeshError {
                    file,
                    problem: "a triangle refers to a vertex the file does not have".into(),
                });
            };
            let Some(flat) = face_normal(&[a, b, c]) else {
                dropped += 1;
                continue;
            };
            for (v, p) in face.iter().zip([a, b, c]) {
                let smooth = file_normals
                    .then(|| mesh.normals.get(*v as usize).and_then(|n| unit(*n)))
                    .flatten();
                parts[k].corner(p, smooth.unwrap_or(flat));
            }
        }
    }
    let parts: Vec<MeshPart> = parts
        .into_iter()
        .map(|p| p.part)
        .filter(|p| !p.indices.is_empty())
        .collect();
    if parts.is_empty() {
        return Err(MeshError {
            file,
            problem: "the mesh has no triangles of non-zero area".into(),
        });
    }
    if dropped > 0 {
        warnings.push(format!("{file}: {dropped} triangle(s) of zero area dropped"));
    }
    Ok(MeshData { parts, warnings })
}

/// The bounding box of a mesh file's finite vertices, in the file's units before any URDF scale (for
/// Collada: after its `<unit>` and node transforms). The formats are those of [`read_mesh`].
pub fn read_mesh_bounds(path: &Path) -> Result<Aabb, MeshError> {
    let (scene, _) = load(path)?;
    let mut b = Aabb::empty();
    for v in scene.meshes.iter().flat_map(|m| &m.vertices) {
        if v.iter().all(|x| x.is_finite()) {
            b.include(&Point3::from(*v));
        }
    }
    if b.is_empty() {
        return Err(MeshError {
            file: path.display().to_string(),
            problem: "the mesh has no vertices".into(),
        });
    }
    Ok(b)
}

/// The file's scene as `mesh-loader` reads it, and warnings about MTL files that cannot be read.
fn load(path: &Path) -> Result<(Scene, Vec<String>), MeshError> {
    let file = path.display().to_string();
    let err = |problem: String| MeshError {
        file: file.clone(),
        problem,
    };
    let ext = extension(path);
    if !matches!(ext.as_str(), "stl" | "obj" | "dae") {
        return Err(err(format!(
            "unsupported mesh format `.{ext}` (STL, OBJ and Collada `.dae` are read)"
        )));
    }
    let bytes = crate::input::read_regular(path, crate::input::MAX_MESH_BYTES).map_err(|e| err(format!("cannot read the file: {e}")))?;
    if ext == "dae" {
        check_collada_unit(&bytes).map_err(err)?;
    }
    let mut warnings = Vec::new();
    if ext == "stl" {
        warnings.extend(binary_stl_count_mismatch(&bytes).map(|w| format!("{file}: {w}")));
    }
    let loader = Loader::default();
    // The Collada reader panics on some malformed files (an index past its array): caught, so that
    // such a file is reported like any other unreadable one.
    let scene = catch_unwind(AssertUnwindSafe(|| match ext.as_str() {
        "stl" => loader.load_stl_from_slice(&bytes, path),
        "dae" => loader.load_collada_from_slice(&bytes, path),
        _ => loader.load_obj_from_slice_with_reader(&bytes, path, |mtl: &Path| {
            // The crate skips an MTL file it cannot read without a word.
            crate::input::read_regular(mtl, crate::input::MAX_TEXT_BYTES).map_err(std::io::Error::other).inspect_err(|e| {
                warnings.push(format!(
                    "{file}: material file {} cannot be read ({e}); its colours are not used",
                    mtl.display()
                ))
            })
        }),
    }))
    .map_err(|_| err("malformed: the mesh reader gave up on it".into()))?
    // Parse errors end in `(FILE:LINE:COLUMN)`; the file is named already.
    .map_err(|e| err(e.to_string().replace(&format!("({file}:"), "(line ")))?;
    Ok((scene, warnings))
}

/// For a binary STL whose header's triangle count disagrees with its length (a truncated download, a
/// writer's bug), what it says: the reader goes by the length, so triangles may be missing.
fn binary_stl_count_mismatch(bytes: &[u8]) -> Option<String> {
    // An ASCII STL begins with `solid` and holds no NUL; a binary one's 80-byte header may begin so too.
    let ascii = bytes.starts_with(b"solid") && !bytes.iter().take(1024).any(|&b| b == 0);
    if ascii || bytes.len() < 84 {
        return None;
    }
    // (A length that is no whole number of triangles the reader refuses.)
    let count = u32::from_le_bytes(bytes[80..84].try_into().expect("4 bytes")) as usize;
    let held = (bytes.len() - 84) / 50;
    (count != held && (bytes.len() - 84) % 50 == 0).then(|| {
        format!("its header counts {count} triangles and the file holds {held}: it may be truncated; the {held} are read")
    })
}

/// A Collada file's `<unit meter="…">` (metres per unit) must be a positive number: the reader scales
/// by it as it is, so a negative one mirrored the mesh and zero flattened it, without a word.
fn check_collada_unit(bytes: &[u8]) -> Result<(), String> {
    let text = String::from_utf8_lossy(&bytes[..bytes.len().min(1 << 16)]);
    let Some(tag) = text.find("<unit").map(|i| &text[i..]).and_then(|t| t.split('>').next()) else {
        return Ok(());
    };
    let Some(value) = tag.split("meter=").nth(1).and_then(|v| v.trim_start().get(1..)).and_then(|v| v.split(['"', '\'']).next()) else {
        return Ok(());
    };
    match value.trim().parse::<f32>() {
        Ok(m) if m.is_finite() && m > 0.0 => Ok(()),
        _ => Err(format!("`<unit meter=\"{value}\">`: a unit is a positive number of metres")),
    }
}

fn extension(path: &Path) -> String {
    path.extension()
        .and_then(|e| e.to_str())
        .map(str::to_ascii_lowercase)
        .unwrap_or_default()
}

/// A material's diffuse colour with its opacity, clamped to [0, 1]; `None` when it has none.
fn material_color(m: &Material) -> Option<[f32; 4]> {
    let [r, g, b, a] = m.color.diffuse?;
    let c = [r, g, b, m.opacity.unwrap_or(a)];
    c.iter().all(|v| v.is_finite()).then(|| c.map(|v| v.clamp(0.0, 1.0)))
}

/// A part under construction, sharing corners by (position, normal).
struct SharedPart {
    part: MeshPart,
    corners: HashMap<[u32; 6], u32>,
}

impl SharedPart {
    fn new(color: Option<[f32; 4]>) -> Self {
        SharedPart {
            part: MeshPart {
                color,
                ..MeshPart::default()
            },
            corners: HashMap::new(),
        }
    }

    /// Adds a triangle corner.
    fn corner(&mut self, p: [f32; 3], n: [f32; 3]) {
        let [a, b, c] = p.map(f32::to_bits);
        let [d, e, f] = n.map(f32::to_bits);
        let part = &mut self.part;
        let i = *self.corners.entry([a, b, c, d, e, f]).or_insert_with(|| {
            part.positions.push(p);
            part.normals.push(n);
            part.positions.len() as u32 - 1
        });
        part.indices.push(i);
    }
}

/// The unit normal of a counter-clockwise triangle, `None` when its area is zero.
fn face_normal(tri: &[[f32; 3]; 3]) -> Option<[f32; 3]> {
    let [a, b, c] = tri.map(Vector3::from);
    unit((b - a).cross(&(c - a)).into())
}

fn unit(v: [f32; 3]) -> Option<[f32; 3]> {
    let v = Vector3::from(v);
    let len = v.norm();
    (len > 0.0 && len.is_finite()).then(|| (v / len).into())
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

    /// A binary STL whose header counts other triangles than it holds (a download cut at a triangle's
    /// end) was read without a word; the reader goes by the file's length, and a warning says so.
    #[test]
    fn a_binary_stl_holding_fewer_triangles_than_its_header_counts_is_warned_of() {
        let dir = tmp_dir("stl-count");
        let tris = [[[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]], [[0.0, 0.0, 0.0], [0.0, 0.0, 1.0], [1.0, 0.0, 0.0]]];
        let whole = binary_stl(&tris);
        let path = dir.join("part.stl");
        std::fs::write(&path, &whole).unwrap();
        assert!(read_mesh(&path).unwrap().warnings.is_empty());
        let mut counted = whole.clone();
        counted[80..84].copy_from_slice(&10u32.to_le_bytes());
        std::fs::write(&path, &counted).unwrap();
        let m = read_mesh(&path).unwrap();
        assert_eq!(m.warnings, [format!("{}: its header counts 10 triangles and the file holds 2: it may be truncated; the 2 are read", path.display())]);
        // Cut in the middle of the second triangle: refused, naming the file.
        std::fs::write(&path, &whole[..84 + 50 + 20]).unwrap();
        assert_eq!(read_mesh(&path).unwrap_err().file, path.display().to_string());
        let _ = std::fs::remove_dir_all(&dir);
    }

    #[test]
    fn binary_and_ascii_stl_give_the_same_triangles() {
        let dir = tmp_dir("stl");
        let tris = [
            [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]],
            [[0.0, 0.0, 0.0], [0.0, 0.0, 1.0], [1.0, 0.0, 0.0]],
            // Zero area: dropped with a warning.
            [[0.0, 0.0, 0.0], [1.0, 1.0, 1.0], [2.0, 2.0, 2.0]],
        ];
        std::fs::write(dir.join("b.stl"), binary_stl(&tris)).unwrap();
        let mut ascii = String::from("solid t\n");
        for t in &tris {
            // A wrong stored normal: the flat normal is computed from the vertices.
            ascii.push_str("facet normal 0 0 0\nouter loop\n");
            for v in t {
                ascii.push_str(&format!("vertex {} {} {}\n", v[0], v[1], v[2]));
            }
            ascii.push_str("endloop\nendfacet\n");
        }
        ascii.push_str("endsolid t\n");
        std::fs::write(dir.join("a.STL"), ascii).unwrap();
        let bin = read_mesh(&dir.join("b.stl")).unwrap();
        let txt = read_mesh(&dir.join("a.STL")).unwrap();
        assert_eq!(bin.parts, txt.parts);
        assert_eq!(bin.triangle_count(), 2);
        let p = &bin.parts[0];
        assert_eq!(p.color, None);
        // The origin and (1, 0, 0) have different normals in the two triangles: six corners.
        assert_eq!(p.positions.len(), 6);
        assert_eq!(p.normals[0], [0.0, 0.0, 1.0]);
        assert_eq!(p.normals[3], [0.0, 1.0, 0.0]);
        let b = read_mesh_bounds(&dir.join("a.STL")).unwrap();
        assert_eq!((b.min, b.max), (Point3::origin(), Point3::new(2.0, 2.0, 2.0)));
        let file = dir.join("b.stl").display().to_string();
        assert_eq!(bin.warnings, vec![format!("{file}: 1 triangle(s) of zero area dropped")]);
        let bad = dir.join("x.stl");
        std::fs::write(&bad, "not a mesh at all").unwrap();
        let e = read_mesh(&bad).unwrap_err();
        assert_eq!(e.file, bad.display().to_string());
        assert!(read_mesh_bounds(&bad).is_err());
        let _ = std::fs::remove_dir_all(&dir);
    }

    #[test]
    fn obj_faces_normals_and_materials() {
        let dir = tmp_dir("obj");
        std::fs::write(dir.join("m.mtl"), "newmtl red\nKd 1 0 0\nd 0.5\nnewmtl blue\nKd 0 0 2\n").unwrap();
        let obj = "mtllib m.mtl\nmtllib gone.mtl\nv 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nvn 0 0 2\n\
                   usemtl red\nf 1//1 2//1 3//1 4//1\nusemtl blue\nf -4 -3 -2\nusemtl red\nf 1 3 4\n";
        let path = dir.join("quad.obj");
        std::fs::write(&path, obj).unwrap();
        let m = read_mesh(&path).unwrap();
        let gone = dir.join("gone.mtl");
        assert_eq!(m.warnings.len(), 1, "{:?}", m.warnings);
        assert!(
            m.warnings[0].starts_with(&format!(
                "{}: material file {} cannot be read",
                path.display(),
                gone.display()
            )),
            "{:?}",
            m.warnings
        );
        // One part per colour: both `red` groups in one part.
        assert_eq!(m.parts.len(), 2);
        let red = &m.parts[0];
        assert_eq!(red.color, Some([1.0, 0.0, 0.0, 0.5]));
        // The quad is a fan of two triangles sharing the four smooth vertices (normal renormalised);
        // the later triangle without `vn` is flat-shaded, here with the same normal, so it shares them too.
        assert_eq!(red.indices, vec![0, 1, 2, 0, 2, 3, 0, 2, 3]);
        assert_eq!(red.positions.len(), 4);
        assert!(red.normals.iter().all(|n| *n == [0.0, 0.0, 1.0]));
        let blue = &m.parts[1];
        assert_eq!(blue.color, Some([0.0, 0.0, 1.0, 1.0]));
        assert_eq!(
            blue.positions,
            vec![[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [1.0, 1.0, 0.0]]
        );
        let bad = dir.join("bad.obj");
        std::fs::write(&bad, "v 0 0 0\nf 1 2 3\n").unwrap();
        let e = read_mesh(&bad).unwrap_err();
        assert_eq!(e.file, bad.display().to_string());
        assert!(e.problem.starts_with("face index out of bounds"), "{e}");
        let e = read_mesh(&dir.join("x.ply")).unwrap_err();
        assert!(e.problem.contains("unsupported mesh format `.ply`"), "{e}");
        let e = read_mesh(&dir.join("missing.dae")).unwrap_err();
        assert!(e.problem.starts_with("cannot read the file"), "{e}");
        let _ = std::fs::remove_dir_all(&dir);
    }

    /// The hand-written Collada fixture (`models/tests/data/urdf/meshes/pyramid.dae`): a square pyramid
    /// in decimetres, base ±1 and apex at z = 2, with one normal per face and a green effect.
    #[test]
    fn collada_pyramid_in_its_units_with_its_colour() {
        let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/urdf/meshes/pyramid.dae");
        let m = read_mesh(&path).unwrap();
        assert!(m.warnings.is_empty(), "{:?}", m.warnings);
        assert_eq!(m.parts.len(), 1);
        let p = &m.parts[0];
        assert_eq!(p.color, Some([0.1, 0.6, 0.3, 1.0]));
        assert_eq!(p.triangle_count(), 6);
        let b = read_mesh_bounds(&path).unwrap();
        assert!((b.min - Point3::new(-0.1, -0.1, 0.0)).norm() < 1e-6, "{b:?}");
        assert!((b.max - Point3::new(0.1, 0.1, 0.2)).norm() < 1e-6, "{b:?}");
        for t in p.indices.chunks_exact(3) {
            let tri = [0, 1, 2].map(|i| p.positions[t[i] as usize]);
            let face = face_normal(&tri).unwrap();
            for i in t {
                let n = Vector3::from(p.normals[*i as usize]);
                assert!((n - Vector3::from(face)).norm() < 1e-5, "file normal {n} vs face {face:?}");
            }
        }
        // A malformed Collada file (an index past its arrays) is an error naming it, not a panic.
        let dir = tmp_dir("dae");
        let bad = dir.join("bad.dae");
        let text = std::fs::read_to_string(&path).unwrap();
        std::fs::write(&bad, text.replace("<p>0 0 3 0", "<p>0 0 9 0")).unwrap();
        let e = read_mesh(&bad).unwrap_err();
        assert_eq!(e.file, bad.display().to_string());
        // A unit that is not a positive length mirrored or flattened the mesh without a word.
        for unit in ["-1", "0", "nan", "ten"] {
            std::fs::write(&bad, text.replace("meter=\"0.1\"", &format!("meter=\"{unit}\""))).unwrap();
            let e = read_mesh(&bad).unwrap_err();
            assert_eq!(e.problem, format!("`<unit meter=\"{unit}\">`: a unit is a positive number of metres"), "{unit}");
        }
        let _ = std::fs::remove_dir_all(&dir);
    }
}
