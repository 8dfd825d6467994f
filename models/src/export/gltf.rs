//! A character motion as a glTF 2.0 binary (`.glb`).
//!
//! Layout of the file:
//! - **nodes**: node `i` is link `i` of the [`KinematicTree`] (same name), children as in the tree;
//!   its transform is the link's pose relative to its parent link (for the root: the root pose). Each
//!   visual of a link is a child node `<link>.visual<k>` placed at the visual's origin and carrying its
//!   mesh. The optional human skeleton is a second scene root `human` with a node per canonical joint
//!   (a sphere each) and a bone node per joint with a parent (a cylinder from the parent joint).
//! - **meshes**: URDF primitives triangulated ([`super::tessellate`]); mesh files (STL, OBJ, Collada)
//!   read ([`crate::mesh_file`]) with the URDF scale baked in; a mesh file that cannot be read is replaced
//!   by its bounding box when that is known, and left out otherwise; a link none of whose visuals can
//!   be shown gets its collision geometry instead (`<link>.collision<k>` nodes). All of these are
//!   noted in [`GlbOutput::warnings`]. One material per colour: the URDF material colour of the
//!   visual (read from the URDF file the tree came from), else the mesh file's material colour (OBJ
//!   MTL, Collada effect), else a neutral grey.
//! - **one animation**, one keyframe per pose at `k / fps` seconds, LINEAR: a translation and a
//!   rotation channel for the root link, a rotation channel for links on revolute and continuous
//!   joints, a translation channel for links on prismatic joints (mimic joints included); links on
//!   fixed joints keep their static transform. Human joints have translation channels (the pelvis a
//!   rotation channel too), bones rotation and scale channels. Rotations are kept in one
//!   hemisphere from key to key, so that LINEAR interpolation takes the short way.
//!
//! The crate's world is z up and glTF's is y up. The change of basis, (x, y, z) ↦ (x, z, −y) as in the
//! Bevy plugin, is applied in one place: it is pre-multiplied onto the transforms of the two scene
//! roots ([`z_up_to_y_up`]); everything below them stays in the z-up link frames.

use std::collections::HashMap;
use std::f32::consts::{FRAC_PI_2, PI};
use std::path::{Path, PathBuf};

use nalgebra::{Isometry3, Point3, Translation3, UnitQuaternion, Vector3};
use gltf_json as json;
use json::Index;
use json::animation::Property;

use super::tessellate::{box_mesh, cylinder_mesh, shape_mesh, sphere_mesh};
use super::writer::{Builder, glb, quat_values, vec3_values};
use super::{ExportError, ExportProblem, check_poses, write_model};
use crate::geometry::{Aabb, Geometry, Shape};
use crate::human::{HumanFrame, Joint};
use crate::kinematics::{CharacterPose, JointKind, KinematicTree, Link};
use crate::mesh_file::{MeshData, MeshError, MeshPart, read_mesh};
use crate::urdf::resolve_mesh_path;

/// Colour of visuals without a colour of their own (linear RGBA).
pub const DEFAULT_COLOR: [f32; 4] = [0.7, 0.7, 0.72, 1.0];
/// Colour of the human skeleton (linear RGBA).
pub const HUMAN_COLOR: [f32; 4] = [0.2, 0.45, 0.9, 1.0];

/// The rotation that takes this crate's z-up world to glTF's y-up world: −90° about x, i.e.
/// (x, y, z) ↦ (x, z, −y).
pub fn z_up_to_y_up() -> UnitQuaternion<f32> {
    UnitQuaternion::from_axis_angle(&Vector3::x_axis(), -FRAC_PI_2)
}

/// The human skeleton to show beside the character.
#[derive(Clone, Debug)]
pub struct HumanOverlay<'a> {
    /// One frame per character pose, at the same rate.
    pub frames: &'a [HumanFrame],
    /// Where the skeleton's world origin is placed (z-up metres), e.g. sideways so that it stands
    /// beside the character.
    pub offset: Vector3<f32>,
    /// Radius of the joint spheres (m).
    pub joint_radius: f32,
    /// Radius of the bone cylinders (m).
    pub bone_radius: f32,
}

impl<'a> HumanOverlay<'a> {
    /// The skeleton of `frames` moved by `offset`, with 3 cm joints and 1.5 cm bones.
    pub fn new(frames: &'a [HumanFrame], offset: Vector3<f32>) -> Self {
        HumanOverlay {
            frames,
            offset,
            joint_radius: 0.03,
            bone_radius: 0.015,
        }
    }
}

/// Options of [`character_glb`].
#[derive(Clone, Debug)]
pub struct GltfOptions<'a> {
    /// Name of the scene and the animation; default the character's name.
    pub name: Option<String>,
    /// The human skeleton to include, if any.
    pub human: Option<HumanOverlay<'a>>,
    /// Segments around cylinders, spheres and capsules (at least 3).
    pub segments: u32,
    /// Directory against which mesh file names are resolved (see [`resolve_mesh_path`]); default the
    /// directory of the URDF the tree came from ([`KinematicTree::source`]).
    pub mesh_dir: Option<PathBuf>,
    /// Read the visuals' material colours from the URDF the tree came from.
    pub urdf_colors: bool,
}

impl Default for GltfOptions<'_> {
    fn default() -> Self {
        GltfOptions {
            name: None,
            human: None,
            segments: 24,
            mesh_dir: None,
            urdf_colors: true,
        }
    }
}

/// A GLB in memory and what the export had to work around.
#[derive(Clone, Debug)]
pub struct GlbOutput {
    /// The `.glb` file's bytes.
    pub bytes: Vec<u8>,
    /// Non-fatal problems: mesh files not found or not readable (and whether a bounding box stands in),
    /// an unreadable URDF for colours, dropped degenerate triangles.
    pub warnings: Vec<String>,
    /// How many distinct mesh files were read and included as triangles.
    pub mesh_files: usize,
}

/// Exports `poses` (one per frame, `fps` frames per second) of the character `tree` as a GLB. See the
/// module documentation for the file's layout. Errors name `<glTF of NAME in memory>`.
pub fn character_glb(
    tree: &KinematicTree,
    poses: &[CharacterPose],
    fps: f32,
    opts: &GltfOptions,
) -> Result<GlbOutput, ExportError> {
    let what = format!("<glTF of {} in memory>", tree.name);
    check_input(tree, poses, fps, opts).map_err(|p| p.in_file(&what))?;
    let name = opts.name.clone().unwrap_or_else(|| tree.name.clone());
    let mut b = Doc::default();
    let mut visuals = Visuals::new(tree, opts);

    let times: Vec<f32> = (0..poses.len()).map(|k| k as f32 / fps).collect();
    let input = b.w.floats(&times, 1, None, true);
    let to_y_up = Isometry3::from_parts(Translation3::identity(), z_up_to_y_up());

    link_nodes(&mut b, tree, poses, input, &to_y_up);
    for (i, link) in tree.links.iter().enumerate() {
        if let Some(p) = link.parent {
            b.nodes[p].children.push(i);
        }
        geometry_nodes(&mut b, &mut visuals, i, link);
    }
    let mut roots = vec![0];
    if let Some(h) = &opts.human {
        roots.push(human_nodes(&mut b, h, opts.segments, input, &to_y_up));
    }

    let scene = json::Scene {
        extensions: None,
        extras: Default::default(),
        name: Some(name.clone()),
        nodes: roots.iter().map(|&r| Index::new(r as u32)).collect(),
    };
    let Doc { mut w, nodes, .. } = b;
    w.root.asset.generator = Some(concat!("ace_models ", env!("CARGO_PKG_VERSION")).into());
    let scene = w.root.push(scene);
    w.root.scene = Some(scene);
    for n in &nodes {
        w.root.push(n.to_json());
    }
    let (root, bin) = w.finish(&name);
    let bytes = glb(&root, &bin).map_err(|p| p.in_file(&what))?;
    Ok(GlbOutput {
        bytes,
        warnings: visuals.warnings,
        mesh_files: visuals.files.values().filter(|r| r.is_ok()).count(),
    })
}

/// [`character_glb`] written atomically to `path` (see [`write_model`]: JSON for a `.gltf` name); returns what it wrote and
/// its warnings. Errors name `path`.
pub fn write_glb(
    path: &Path,
    tree: &KinematicTree,
    poses: &[CharacterPose],
    fps: f32,
    opts: &GltfOptions,
) -> Result<GlbOutput, ExportError> {
    let out =
        character_glb(tree, poses, fps, opts).map_err(|e| e.problem.in_file(path.display().to_string()))?;
    write_model(path, &out.bytes)?;
    Ok(out)
}

fn check_input(
    tree: &KinematicTree,
    poses: &[CharacterPose],
    fps: f32,
    opts: &GltfOptions,
) -> Result<(), ExportProblem> {
    check_poses(tree, poses, fps)?;
    if let Some(h) = &opts.human {
        if h.frames.len() != poses.len() {
            return Err(ExportProblem::HumanFrameCount {
                human: h.frames.len(),
                character: poses.len(),
            });
        }
        for (frame, f) in h.frames.iter().enumerate() {
            let finite = f
                .positions
                .iter()
                .flat_map(|p| p.iter())
                .chain(f.root_rotation.coords.iter());
            if !finite.into_iter().all(|v| v.is_finite()) {
                return Err(ExportProblem::NonFinite {
                    frame,
                    what: "human joint position or pelvis rotation".into(),
                });
            }
        }
    }
    Ok(())
}

/// Adds node `i` for every link `i` (children are linked by the caller) with its animation channels:
/// translation and rotation for the root, rotation for revolute and continuous joints, translation
/// for prismatic ones.
fn link_nodes(
    b: &mut Doc,
    tree: &KinematicTree,
    poses: &[CharacterPose],
    input: Index<json::Accessor>,
    to_y_up: &Isometry3<f32>,
) {
    for (i, link) in tree.links.iter().enumerate() {
        let local = |p: &CharacterPose| match &link.joint {
            Some(j) => j.transform(j.position(&p.q)),
            None => to_y_up * p.root,
        };
        let track: Vec<Isometry3<f32>> = poses.iter().map(local).collect();
        let node = b.node(Node::new(&link.name, &track[0]));
        debug_assert_eq!(node, i);
        let (moves, turns) = match link
            .joint
            .as_ref()
            .map(|j| (j.kind, j.dof.is_some() || j.mimic.is_some()))
        {
            None => (true, true),
            Some((kind, true)) => (kind == JointKind::Prismatic, kind.is_rotational()),
            Some((_, false)) => (false, false),
        };
        if moves {
            let t: Vec<Vector3<f32>> = track.iter().map(|m| m.translation.vector).collect();
            b.channel(node, Property::Translation, input, &vec3_values(&t));
        }
        if turns {
            let r: Vec<UnitQuaternion<f32>> = track.iter().map(|m| m.rotation).collect();
            b.channel(node, Property::Rotation, input, &quat_values(&r));
        }
    }
}

/// Adds the visual nodes of link node `i` (or, when none of its visuals can be shown, its collision
/// geometry).
fn geometry_nodes(b: &mut Doc, visuals: &mut Visuals, i: usize, link: &Link) {
    let mut shown = 0;
    for (k, g) in link.visuals.iter().enumerate() {
        let what = format!("visual {k} of link `{}`", link.name);
        if let Some(mesh) = visuals.mesh(b, &what, visuals.color(&link.name, k), g) {
            let mut node = Node::new(&format!("{}.visual{k}", link.name), &g.origin);
            node.mesh = Some(mesh);
            let v = b.node(node);
            b.nodes[i].children.push(v);
            shown += 1;
        }
    }
    // A link whose visuals all failed (typically mesh files missing from a robot description) would
    // vanish; its collision geometry shows where it is instead.
    if shown == 0 && !link.visuals.is_empty() && !link.collisions.is_empty() {
        visuals.warnings.push(format!(
            "link `{}`: none of its visuals can be shown; its collision geometry stands in",
            link.name
        ));
        for (k, g) in link.collisions.iter().enumerate() {
            let what = format!("collision {k} of link `{}`", link.name);
            if let Some(mesh) = visuals.mesh(b, &what, visuals.color(&link.name, 0), g) {
                let mut node = Node::new(&format!("{}.collision{k}", link.name), &g.origin);
                node.mesh = Some(mesh);
                let c = b.node(node);
                b.nodes[i].children.push(c);
            }
        }
    }
}

/// Adds the human skeleton under a root node `human`; returns that node.
fn human_nodes(
    b: &mut Doc,
    h: &HumanOverlay,
    segments: u32,
    input: Index<json::Accessor>,
    to_y_up: &Isometry3<f32>,
) -> usize {
    let material = b.material(HUMAN_COLOR);
    let sphere = b.mesh(
        "human_joint",
        &[(&sphere_mesh(h.joint_radius, segments), material)],
    );
    // A unit-length bone along z from its base; nodes scale it to each bone's length.
    let mut bone = cylinder_mesh(h.bone_radius, 1.0, segments.div_ceil(2).max(6));
    for p in &mut bone.positions {
        p[2] += 0.5;
    }
    let bone = b.mesh("human_bone", &[(&bone, material)]);
    let root = b.node(Node::new("human", &(to_y_up * Translation3::from(h.offset))));
    let mut joint_nodes = [0usize; Joint::ALL.len()];
    for j in Joint::ALL {
        // Only the pelvis turns; every other joint node is offset in the pelvis' frame.
        let local = |f: &HumanFrame| match j.parent() {
            None => Isometry3::from_parts(f.position(j).into(), f.root_rotation),
            Some(p) => Isometry3::from_parts(
                Translation3::from(f.root_rotation.inverse() * (f.position(j) - f.position(p))),
                UnitQuaternion::identity(),
            ),
        };
        let track: Vec<Isometry3<f32>> = h.frames.iter().map(local).collect();
        let mut node = Node::new(j.name(), &track[0]);
        node.mesh = Some(sphere);
        let n = b.node(node);
        joint_nodes[j.index()] = n;
        let t: Vec<Vector3<f32>> = track.iter().map(|m| m.translation.vector).collect();
        b.channel(n, Property::Translation, input, &vec3_values(&t));
        let parent = match j.parent() {
            None => {
                let r: Vec<UnitQuaternion<f32>> = track.iter().map(|m| m.rotation).collect();
                b.channel(n, Property::Rotation, input, &quat_values(&r));
                root
            }
            Some(p) => {
                // The bone hangs under the parent joint and points at this joint (offset `t`).
                let r: Vec<UnitQuaternion<f32>> = t.iter().map(z_towards).collect();
                let s: Vec<Vector3<f32>> = t
                    .iter()
                    .map(|v| Vector3::new(1.0, 1.0, v.norm().max(1e-6)))
                    .collect();
                let mut node = Node::new(
                    &format!("{}_bone", j.name()),
                    &Isometry3::from_parts(Translation3::identity(), r[0]),
                );
                node.scale = Some(s[0]);
                node.mesh = Some(bone);
                let bn = b.node(node);
                b.channel(bn, Property::Rotation, input, &quat_values(&r));
                b.channel(bn, Property::Scale, input, &vec3_values(&s));
                let pn = joint_nodes[p.index()];
                b.nodes[pn].children.push(bn);
                pn
            }
        };
        b.nodes[parent].children.push(n);
    }
    root
}

/// The rotation that takes +z to the direction of `v` (the identity for a zero vector).
fn z_towards(v: &Vector3<f32>) -> UnitQuaternion<f32> {
    if v.norm() < 1e-9 {
        return UnitQuaternion::identity();
    }
    UnitQuaternion::rotation_between(&Vector3::z(), v)
        .unwrap_or_else(|| UnitQuaternion::from_axis_angle(&Vector3::x_axis(), PI))
}

/// URDF colour of each visual (linear RGBA, `None` when it has none) by link name and visual index.
type VisualColors = HashMap<String, Vec<Option<[f32; 4]>>>;

/// The meshes of link visuals, with the caches that let identical visuals share one glTF mesh.
struct Visuals {
    segments: u32,
    mesh_dir: Option<PathBuf>,
    colors: VisualColors,
    /// Mesh files read, by resolved path.
    files: HashMap<PathBuf, Result<MeshData, MeshError>>,
    /// glTF mesh by a key of shape (with scale) and colour.
    meshes: HashMap<String, Option<usize>>,
    warnings: Vec<String>,
}

impl Visuals {
    fn new(tree: &KinematicTree, opts: &GltfOptions) -> Self {
        let mut warnings = Vec::new();
        let colors = match (&tree.source, opts.urdf_colors) {
            (Some(urdf), true) => urdf_visual_colors(urdf).unwrap_or_else(|e| {
                warnings.push(format!("{e}; visuals get the default colour"));
                HashMap::new()
            }),
            _ => HashMap::new(),
        };
        Visuals {
            segments: opts.segments,
            mesh_dir: opts.mesh_dir.clone().or_else(|| {
                tree.source
                    .as_ref()
                    .and_then(|s| s.parent())
                    .map(Path::to_path_buf)
            }),
            colors,
            files: HashMap::new(),
            meshes: HashMap::new(),
            warnings,
        }
    }

    /// The URDF colour of visual `k` of link `link`, if it has one.
    fn color(&self, link: &str, k: usize) -> Option<[f32; 4]> {
        self.colors.get(link).and_then(|c| c.get(k).copied().flatten())
    }

    /// The glTF mesh of geometry `g` (`what` names it in warnings) in `color` (else the mesh file's
    /// colours, else [`DEFAULT_COLOR`]); `None` when it has nothing to show.
    fn mesh(&mut self, b: &mut Doc, what: &str, color: Option<[f32; 4]>, g: &Geometry) -> Option<usize> {
        let Shape::Mesh {
            filename,
            scale,
            bounds,
        } = &g.shape
        else {
            let key = format!("{:?}|{color:?}", g.shape);
            if let Some(m) = self.meshes.get(&key) {
                return *m;
            }
            let part = shape_mesh(&g.shape, self.segments).expect("primitives have meshes");
            let material = b.material(color.unwrap_or(DEFAULT_COLOR));
            let m = Some(b.mesh(&shape_name(&g.shape), &[(&part, material)]));
            self.meshes.insert(key, m);
            return m;
        };
        let path = self
            .mesh_dir
            .as_deref()
            .and_then(|d| resolve_mesh_path(filename, d));
        let key = format!("{path:?}|{filename}|{scale:?}|{color:?}");
        if let Some(m) = self.meshes.get(&key) {
            return *m;
        }
        if let Some(p) = &path
            && !self.files.contains_key(p)
        {
            let r = read_mesh(p);
            if let Ok(d) = &r {
                self.warnings.extend(d.warnings.iter().cloned());
            }
            self.files.insert(p.clone(), r);
        }
        let mut notes = Vec::new();
        let mut stand_in = |why: String| match bounds {
            Some(bb) => {
                notes.push(format!("{why}; its bounding box stands in ({what})"));
                vec![box_part(bb, scale)]
            }
            None => {
                notes.push(format!("{why}; it is left out ({what})"));
                Vec::new()
            }
        };
        let parts: Vec<MeshPart> = match path.as_ref().map(|p| &self.files[p]) {
            Some(Ok(data)) => data.parts.iter().map(|p| scaled(p, scale)).collect(),
            Some(Err(e)) => stand_in(e.to_string()),
            None => stand_in(format!("mesh file `{filename}` not found")),
        };
        self.warnings.extend(notes);
        let m = (!parts.is_empty()).then(|| {
            let with_materials: Vec<(&MeshPart, usize)> = parts
                .iter()
                .map(|p| (p, b.material(color.or(p.color).unwrap_or(DEFAULT_COLOR))))
                .collect();
            let stem = Path::new(filename)
                .file_stem()
                .map_or(filename.clone(), |s| s.to_string_lossy().into_owned());
            b.mesh(&stem, &with_materials)
        });
        self.meshes.insert(key, m);
        m
    }
}

fn shape_name(s: &Shape) -> String {
    match s {
        Shape::Box { .. } => "box",
        Shape::Cylinder { .. } => "cylinder",
        Shape::Sphere { .. } => "sphere",
        Shape::Capsule { .. } => "capsule",
        Shape::Mesh { .. } => "mesh",
    }
    .into()
}

/// `part` with `scale` baked in: positions scaled, normals by the inverse transpose, and the winding
/// reversed when the scale mirrors (so that triangles still face outwards).
fn scaled(part: &MeshPart, scale: &Vector3<f32>) -> MeshPart {
    if *scale == Vector3::repeat(1.0) {
        return part.clone();
    }
    let det = scale.x * scale.y * scale.z;
    // The cofactor vector is det · scale⁻¹ and also works for a zero scale component.
    let cof = Vector3::new(scale.y * scale.z, scale.x * scale.z, scale.x * scale.y) * det.signum();
    let mut out = MeshPart {
        positions: part
            .positions
            .iter()
            .map(|p| Vector3::from(*p).component_mul(scale).into())
            .collect(),
        normals: part
            .normals
            .iter()
            .map(|n| {
                let m = Vector3::from(*n).component_mul(&cof);
                let len = m.norm();
                if len > 0.0 { (m / len).into() } else { *n }
            })
            .collect(),
        indices: part.indices.clone(),
        color: part.color,
    };
    if det < 0.0 {
        for t in out.indices.chunks_exact_mut(3) {
            t.swap(1, 2);
        }
    }
    out
}

/// The box of mesh bounds `b` (file units) with `scale` applied.
fn box_part(b: &Aabb, scale: &Vector3<f32>) -> MeshPart {
    let p = Point3::from(b.min.coords.component_mul(scale));
    let q = Point3::from(b.max.coords.component_mul(scale));
    let (lo, hi) = (p.inf(&q), p.sup(&q));
    let mut part = box_mesh(&(hi - lo));
    let c = nalgebra::center(&lo, &hi);
    for v in &mut part.positions {
        *v = (Vector3::from(*v) + c.coords).into();
    }
    part
}

/// URDF colour of every visual, by link name and visual index. The tree keeps no colours, so the URDF
/// is read again. A visual's material gives its colour directly or names a material defined at the
/// top level or in another visual.
fn urdf_visual_colors(path: &Path) -> Result<VisualColors, String> {
    let file = path.display();
    let xml = crate::input::read_text(path).map_err(|e| format!("{file}: cannot read the URDF for colours: {e}"))?;
    let robot = urdf_rs::read_from_string(&xml)
        .map_err(|e| format!("{file}: cannot parse the URDF for colours: {e}"))?;
    let rgba = |c: &urdf_rs::Color| {
        c.rgba.map(|v| {
            if v.is_finite() {
                v.clamp(0.0, 1.0) as f32
            } else {
                1.0
            }
        })
    };
    let mut named: HashMap<&str, [f32; 4]> = HashMap::new();
    let defined = robot.materials.iter().chain(
        robot
            .links
            .iter()
            .flat_map(|l| l.visual.iter().filter_map(|v| v.material.as_ref())),
    );
    for m in defined {
        if let (Some(c), false) = (&m.color, m.name.is_empty()) {
            named.entry(m.name.as_str()).or_insert_with(|| rgba(c));
        }
    }
    Ok(robot
        .links
        .iter()
        .map(|l| {
            let colors = l
                .visual
                .iter()
                .map(|v| {
                    let m = v.material.as_ref()?;
                    m.color
                        .as_ref()
                        .map(rgba)
                        .or_else(|| named.get(m.name.as_str()).copied())
                })
                .collect();
            (l.name.clone(), colors)
        })
        .collect())
}

/// A node under construction.
struct Node {
    name: String,
    translation: Vector3<f32>,
    rotation: UnitQuaternion<f32>,
    scale: Option<Vector3<f32>>,
    mesh: Option<usize>,
    children: Vec<usize>,
}

impl Node {
    fn new(name: &str, transform: &Isometry3<f32>) -> Self {
        Node {
            name: name.to_string(),
            translation: transform.translation.vector,
            rotation: transform.rotation,
            scale: None,
            mesh: None,
            children: Vec::new(),
        }
    }

    fn to_json(&self) -> json::Node {
        let q = self.rotation.normalize();
        json::Node {
            name: Some(self.name.clone()),
            translation: Some(self.translation.into()),
            rotation: Some(json::scene::UnitQuaternion([q.i, q.j, q.k, q.w])),
            scale: self.scale.map(Into::into),
            mesh: self.mesh.map(|m| Index::new(m as u32)),
            children: (!self.children.is_empty())
                .then(|| self.children.iter().map(|&c| Index::new(c as u32)).collect()),
            ..Default::default()
        }
    }
}

/// The document of a character export: the writer, the nodes (whose children grow while links,
/// visuals and human joints are added) and one material per colour.
#[derive(Default)]
struct Doc {
    w: Builder,
    nodes: Vec<Node>,
    material_index: HashMap<[u32; 4], usize>,
}

impl Doc {
    /// The material of colour `rgba` (linear RGBA), shared by every mesh of that colour.
    fn material(&mut self, rgba: [f32; 4]) -> usize {
        let key = rgba.map(f32::to_bits);
        if let Some(&m) = self.material_index.get(&key) {
            return m;
        }
        let [r, g, b, a] = rgba;
        let m = self.w.root.push(json::Material {
            name: Some(format!("rgba({r} {g} {b} {a})")),
            pbr_metallic_roughness: json::material::PbrMetallicRoughness {
                base_color_factor: json::material::PbrBaseColorFactor(rgba),
                metallic_factor: json::material::StrengthFactor(0.0),
                roughness_factor: json::material::StrengthFactor(0.6),
                ..Default::default()
            },
            alpha_mode: json::validation::Checked::Valid(if a < 1.0 {
                json::material::AlphaMode::Blend
            } else {
                json::material::AlphaMode::Opaque
            }),
            ..Default::default()
        });
        self.material_index.insert(key, m.value());
        m.value()
    }

    /// A mesh with one triangle primitive per part.
    fn mesh(&mut self, name: &str, parts: &[(&MeshPart, usize)]) -> usize {
        use json::mesh::{Mode, Semantic};
        use json::validation::Checked::Valid;
        let primitives = parts
            .iter()
            .map(|(p, material)| {
                let flat = |v: &[[f32; 3]]| v.iter().flatten().copied().collect::<Vec<f32>>();
                let vertices = Some(json::buffer::Target::ArrayBuffer);
                let position = self.w.floats(&flat(&p.positions), 3, vertices, true);
                let normal = self.w.floats(&flat(&p.normals), 3, vertices, false);
                let indices = self.w.indices(&p.indices, p.positions.len());
                json::mesh::Primitive {
                    attributes: [(Valid(Semantic::Positions), position), (Valid(Semantic::Normals), normal)].into(),
                    extensions: None,
                    extras: Default::default(),
                    indices: Some(indices),
                    material: Some(Index::new(*material as u32)),
                    mode: Valid(Mode::Triangles),
                    targets: None,
                }
            })
            .collect();
        let m = self.w.root.push(json::Mesh {
            extensions: None,
            extras: Default::default(),
            name: Some(name.to_owned()),
            primitives,
            weights: None,
        });
        m.value()
    }

    fn node(&mut self, node: Node) -> usize {
        self.nodes.push(node);
        self.nodes.len() - 1
    }

    fn channel(&mut self, node: usize, path: Property, input: Index<json::Accessor>, values: &[f32]) {
        self.w.channel(node, path, input, values);
    }
}
