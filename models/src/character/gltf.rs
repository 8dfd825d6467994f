//! Skinned glTF 2.0 (`.glb`, `.gltf` with embedded or external buffers) →
//! [`KinematicTree`](crate::kinematics::KinematicTree): the rigged creatures that game developers and
//! artists bring become the same tree a URDF becomes, so morphology, controllers, datasets, training,
//! metrics and cleanup see no difference.
//!
//! Decisions, documented once:
//! - **Frame.** glTF is y up with the model facing +z; the character frame is z up facing +x. A point
//!   `(x, y, z)` of the file becomes `(z, x, y)` (a proper rotation). The profile's `up` and
//!   `forward` name other axes of the file ([`Facing`]); a creature that stands on fewer than two feet
//!   as the file says, but on more with another axis up, is read with a warning naming that axis.
//! - **Units.** glTF says metres, but files are authored at many scales: after the armature's own
//!   transforms, a creature whose largest extent exceeds [`MAX_PLAUSIBLE_SIZE`] is read as centimetres
//!   (then millimetres), with a warning. The profile's `scale` (metres per file unit) overrides this.
//! - **Skin.** The skin that deforms the most vertices; when there are several, a warning says which.
//! - **Bones.** The *body root* is found by walking down from the skin's top joint past joints whose
//!   other children are small (at most two joints: IK targets, pole targets, foot controls). Bones
//!   outside the body root's subtree are *helpers* and never DoFs: non-deforming helpers are dropped;
//!   deforming ones (a foot bone driven by IK, hanging off the root) become fixed links under the end of
//!   the body chain nearest to them, where the file's clips hold them, and the vertices they deform most
//!   count as that bone's (see [`super::helpers`]).
//!   Ancestors of the body root fold into the root pose. Bones below which no vertex deforms (prop
//!   sockets, an exporter's `_end` leaf bones) are helpers too: they would end a limb where it has no
//!   flesh to stand on.
//! - **Joints.** A moving bone becomes up to three revolute DoFs about axes fixed in its rest frame and
//!   applied in the order yaw, pitch, roll: links `bone:yaw`, `bone:pitch` and finally `bone` (the link
//!   carrying the geometry), joints `bone:yaw`, `bone:pitch`, `bone:roll` (only the axes it keeps).
//!   For legs the axes are vertical, the knee's hinge axis and the leg's outward direction; elsewhere
//!   the character frame's z, y and x at rest. Which bones move and their limits: see [`super::body_plan`].
//! - **Rest pose** (all q = 0) is the skin's bind pose, the pose the mesh was modelled in: joint `j`
//!   stands at `M · IBM_j⁻¹`, with `M` the world matrix of the skinned mesh's node (three.js's
//!   convention too), so the skinned vertices are the mesh's own. Exporters often leave the nodes in
//!   another pose (a frame of a clip); then a warning says how many joints were moved to their bind
//!   pose. Joints whose nodes already stand there keep their node transforms exactly. A clip's
//!   channels still start from the nodes' own transforms ([`Bone::file_local`]), as a player's do.
//! - **Invalid values.** A node rotation that is not of unit length is normalised (a zero one is an
//!   error). A clip's keyframes without a rotation (zero or not finite) or a finite translation are
//!   left out, keyframe times out of order are read sorted, and a channel with fewer values than
//!   times is left out, each with a warning naming the animation and the bone.
//! - **Geometry.** Each body bone gets a capsule for the core of the vertices it deforms most (see
//!   [`fit_capsule`]); a foot gets the sphere of its contact instead. UFR, the cleanup and the
//!   controllers use them as they use URDF geometry.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use ::gltf::animation::util::ReadOutputs;
use nalgebra::{
    Isometry3, Matrix3, Matrix4, Point3, Rotation3, Translation3, UnitQuaternion, Vector3,
};
use thiserror::Error;

use crate::geometry::{Geometry, Shape};

/// How much larger than the next the largest variance of a bone's points must be for their principal
/// direction to set the axis of its capsule ([`fit_capsule`]).
pub const DISTINCT_AXIS: f32 = 1.5;
/// Largest plausible extent of a creature in metres; larger files are read as centimetres.
pub const MAX_PLAUSIBLE_SIZE: f32 = 20.0;
/// Smallest extent of a creature (metres) read without a warning: an insect's.
pub const MIN_PLAUSIBLE_SIZE: f32 = 0.01;
/// Most joints a skin may have.
pub const MAX_JOINTS: usize = 256;
/// Most bytes a glTF file may have, and its buffers together.
pub const MAX_FILE_BYTES: u64 = crate::input::MAX_MESH_BYTES;
/// Most skinned vertices a creature may have, counted over every node that carries its skin and every
/// primitive of that node's mesh (a file may reuse one accessor many times, so its size does not bound
/// this).
pub const MAX_SKINNED_VERTICES: usize = 2_000_000;
/// Longest animation a creature may have, in seconds: as long as a mocap clip
/// ([`crate::human::bvh::MAX_CLIP_SECONDS`]). Clips are sampled frame by frame, so their length sizes memory.
pub const MAX_ANIMATION_SECONDS: f32 = 7200.0;

/// An error importing a glTF creature: which file, and what is wrong with it.
#[derive(Debug, Clone, Error, PartialEq)]
#[error("{file}: {problem}")]
pub struct GltfError {
    /// The file.
    pub file: String,
    /// What is wrong.
    pub problem: GltfProblem,
}

/// The problems [`GltfError`] reports.
#[derive(Debug, Clone, Error, PartialEq)]
pub enum GltfProblem {
    #[error("cannot read the file: {0}")]
    Io(String),
    #[error("not a regular file")]
    NotAFile,
    #[error("the file is {0} bytes, more than the {MAX_FILE_BYTES} a creature may have")]
    TooLarge(u64),
    #[error("malformed glTF: {0}")]
    Parse(String),
    #[error("buffer {index} ({uri}) cannot be read: {reason}")]
    Buffer {
        index: usize,
        uri: String,
        reason: String,
    },
    #[error("the model has no skin: a creature needs a rigged (skinned) mesh")]
    NoSkin,
    #[error("skin {skin} has {joints} joint(s); a creature needs at least two")]
    TooFewJoints { skin: usize, joints: usize },
    #[error("skin {skin} has {joints} joints, more than the {MAX_JOINTS} supported")]
    TooManyJoints { skin: usize, joints: usize },
    #[error(
        "skin {skin} deforms {vertices} vertices (over every node and primitive that uses it), more than the \
         {MAX_SKINNED_VERTICES} supported"
    )]
    TooManyVertices { skin: usize, vertices: usize },
    #[error("buffers {first} and {index} both read `{uri}`; each file may be listed once")]
    RepeatedBuffer { first: usize, index: usize, uri: String },
    #[error("the buffers hold more than {MAX_FILE_BYTES} bytes together")]
    BuffersTooLarge,
    #[error("skin {skin} lists node {node} (`{name}`) more than once among its joints")]
    DuplicateJoint {
        skin: usize,
        node: usize,
        name: String,
    },
    #[error("node {node} (`{name}`) is its own child")]
    SelfParent { node: usize, name: String },
    #[error("node {node} (`{name}`) is the child of several nodes")]
    SeveralParents { node: usize, name: String },
    #[error("the node hierarchy has a cycle through {}", .0.join(" → "))]
    Cycle(Vec<String>),
    #[error("mesh {mesh} primitive {primitive}, vertex {vertex}: {what}")]
    BadVertex {
        mesh: usize,
        primitive: usize,
        vertex: usize,
        what: String,
    },
    #[error("skin {skin} deforms no vertex: no mesh that uses it has JOINTS_0 and WEIGHTS_0")]
    NoSkinnedMesh { skin: usize },
    #[error("non-finite or degenerate transform: {0}")]
    BadTransform(String),
    #[error(
        "animation {index} (`{name}`) has a keyframe at {time} s; keyframe times must be finite and \
         at most {MAX_ANIMATION_SECONDS} s (2 hours)"
    )]
    AnimationTooLong { index: usize, name: String, time: f32 },
    #[error("the file requires the glTF extension `{name}`: {what}; export the model again without it")]
    RequiredExtension { name: String, what: &'static str },
}

impl GltfProblem {
    /// Attaches the file name.
    pub fn in_file(self, file: &Path) -> GltfError {
        GltfError {
            file: file.display().to_string(),
            problem: self,
        }
    }
}

/// One skin of the file, as `ace inspect` reports it.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct SkinInfo {
    pub name: String,
    pub joints: usize,
    /// Vertices of the meshes that use it.
    pub vertices: usize,
    /// Whether it is the one the creature was built from.
    pub used: bool,
}

/// One animation clip of the file.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct AnimationInfo {
    pub name: String,
    pub duration_s: f32,
    pub channels: usize,
}

/// A bone of the chosen skin as read from the file, in the character frame (z up, metres).
#[derive(Clone, Debug)]
pub struct Bone {
    /// Node name (or `node<i>`).
    pub name: String,
    /// glTF node index.
    pub node: usize,
    /// Parent bone (index into [`Rig::bones`]); `None` for top-level joints.
    pub parent: Option<usize>,
    /// World pose at rest (rotation and translation; scale stripped).
    pub rest: Isometry3<f32>,
    /// Its local transform at rest (the bind pose; file frame and units).
    pub rest_local: NodeTransform,
    /// The node's own local transform in the file, which a clip's missing channels keep.
    pub file_local: NodeTransform,
    /// World matrix of the node's parent at rest (file frame), for top-level bones.
    pub parent_world: Matrix4<f32>,
    /// Vertices it deforms (any weight > 0).
    pub deforms: usize,
}

/// A node's local translation, rotation and scale (glTF's TRS, file frame and units).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct NodeTransform {
    pub translation: Vector3<f32>,
    pub rotation: UnitQuaternion<f32>,
    pub scale: Vector3<f32>,
}

impl NodeTransform {
    /// The node's own transform as the file gives it.
    pub fn of(node: &::gltf::Node) -> NodeTransform {
        let (t, r, s) = node.transform().decomposed();
        NodeTransform {
            translation: Vector3::from(t),
            rotation: UnitQuaternion::from_quaternion(nalgebra::Quaternion::new(r[3], r[0], r[1], r[2])),
            scale: Vector3::from(s),
        }
    }

    /// `T · R · S`.
    pub fn matrix(&self) -> Matrix4<f32> {
        Translation3::from(self.translation).to_homogeneous()
            * self.rotation.to_homogeneous()
            * Matrix4::new_nonuniform_scaling(&self.scale)
    }

    /// `m` split into translation, rotation and per-axis scale; `None` when it shears, mirrors or
    /// degenerates beyond what TRS can say.
    pub fn from_matrix(m: &Matrix4<f32>) -> Option<NodeTransform> {
        let a = m.fixed_view::<3, 3>(0, 0).into_owned();
        let scale = Vector3::from_fn(|i, _| a.column(i).norm());
        if !(scale.min() > 0.0 && scale.iter().all(|v| v.is_finite())) {
            return None;
        }
        let rotation = polar_rotation(&(a * Matrix3::from_diagonal(&scale.map(|v| 1.0 / v))))?;
        let back = rotation.to_rotation_matrix().matrix() * Matrix3::from_diagonal(&scale);
        if (back - a).abs().max() > 1e-3 * scale.max() {
            return None;
        }
        Some(NodeTransform { translation: m.fixed_view::<3, 1>(0, 3).into_owned(), rotation, scale })
    }
}

/// What a [`Track`] animates.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum TrackKind {
    Rotation,
    Translation,
}

/// One animation channel on a bone (file frame and units): keyframe times and values (`[x, y, z, w]`
/// quaternions, or translations with w = 0). Cubic-spline keyframes keep their values, not tangents.
#[derive(Clone, Debug)]
pub struct Track {
    pub bone: usize,
    pub kind: TrackKind,
    /// Step interpolation (else linear: slerp for rotations).
    pub step: bool,
    pub times: Vec<f32>,
    pub values: Vec<[f32; 4]>,
}

impl Track {
    /// The value at time `t` (clamped to the keyframes).
    pub fn sample(&self, t: f32) -> [f32; 4] {
        let n = self.times.len();
        let k = self.times.partition_point(|&x| x <= t);
        if k == 0 {
            return self.values[0];
        }
        if k >= n || self.step {
            return self.values[k.min(n) - 1];
        }
        let (t0, t1) = (self.times[k - 1], self.times[k]);
        let u = if t1 > t0 { ((t - t0) / (t1 - t0)).clamp(0.0, 1.0) } else { 0.0 };
        let (a, b) = (self.values[k - 1], self.values[k]);
        match self.kind {
            TrackKind::Translation => std::array::from_fn(|i| a[i] + (b[i] - a[i]) * u),
            TrackKind::Rotation => {
                let qa = UnitQuaternion::from_quaternion(nalgebra::Quaternion::new(a[3], a[0], a[1], a[2]));
                let qb = UnitQuaternion::from_quaternion(nalgebra::Quaternion::new(b[3], b[0], b[1], b[2]));
                let q = qa.slerp(&qb, u);
                [q.coords.x, q.coords.y, q.coords.z, q.coords.w]
            }
        }
    }
}

/// What [`read`] gets from a file: bones, their skinned vertices and their clips' rotations.
#[derive(Clone, Debug)]
pub struct Rig {
    /// Bones in parent-first order.
    pub bones: Vec<Bone>,
    /// Skinned rest vertices in the character frame (m), with each vertex's bone weights.
    pub vertices: Vec<(Point3<f32>, Vec<(usize, f32)>)>,
    /// Per bone, local rotations sampled from the clips (file frame), one per keyframe.
    pub clip_rotations: Vec<Vec<UnitQuaternion<f32>>>,
    /// Per animation (in [`Rig::animations`] order), its tracks on bones.
    pub clips: Vec<Vec<Track>>,
    /// Metres per file unit applied.
    pub scale: f32,
    /// File frame → character frame rotation.
    pub to_character: Rotation3<f32>,
    pub skins: Vec<SkinInfo>,
    pub animations: Vec<AnimationInfo>,
    pub warnings: Vec<String>,
}

/// An axis of the file, with its sign: the profile's `forward` and `up`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub enum Axis {
    #[serde(rename = "+x")]
    PlusX,
    #[serde(rename = "-x")]
    MinusX,
    #[serde(rename = "+y")]
    PlusY,
    #[serde(rename = "-y")]
    MinusY,
    #[serde(rename = "+z")]
    PlusZ,
    #[serde(rename = "-z")]
    MinusZ,
}

impl Axis {
    /// All six, in the order a search for a lying creature's up tries them.
    pub const ALL: [Axis; 6] = [Axis::PlusY, Axis::PlusZ, Axis::MinusZ, Axis::PlusX, Axis::MinusX, Axis::MinusY];

    /// The unit vector of the axis in file coordinates.
    pub fn vector(self) -> Vector3<f32> {
        match self {
            Axis::PlusX => Vector3::x(),
            Axis::MinusX => -Vector3::x(),
            Axis::PlusY => Vector3::y(),
            Axis::MinusY => -Vector3::y(),
            Axis::PlusZ => Vector3::z(),
            Axis::MinusZ => -Vector3::z(),
        }
    }

    /// As a profile writes it (`"+z"`).
    pub fn label(self) -> &'static str {
        match self {
            Axis::PlusX => "+x",
            Axis::MinusX => "-x",
            Axis::PlusY => "+y",
            Axis::MinusY => "-y",
            Axis::PlusZ => "+z",
            Axis::MinusZ => "-z",
        }
    }
}

/// How the file's axes map to the character frame: which file axes point up and the way the creature
/// faces. glTF says +y up, facing +z ([`Facing::default`]); a file exported with z up (Blender's own
/// axes) lies on its back or side unless its profile says `up = "+z"`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Facing {
    pub forward: Axis,
    pub up: Axis,
}

impl Default for Facing {
    fn default() -> Facing {
        Facing { forward: Axis::PlusZ, up: Axis::PlusY }
    }
}

impl Facing {
    /// `up` (glTF's +y when `None`) with `forward`, which defaults to glTF's +z, or to -y (Blender's
    /// front) when up is along z. Fails when the two are parallel.
    pub fn new(forward: Option<Axis>, up: Option<Axis>) -> Result<Facing, String> {
        let up = up.unwrap_or(Axis::PlusY);
        let forward = forward.unwrap_or(if matches!(up, Axis::PlusZ | Axis::MinusZ) { Axis::MinusY } else { Axis::PlusZ });
        if forward.vector().dot(&up.vector()) != 0.0 {
            return Err(format!(
                "`up` = \"{}\" is along the same axis; the creature faces along an axis perpendicular to up",
                up.label()
            ));
        }
        Ok(Facing { forward, up })
    }

    /// Rotation from the file frame to the character frame (z up, facing +x).
    pub fn to_character(self) -> Rotation3<f32> {
        // Rows: character x, y, z in file coordinates; left = up × forward.
        let (f, up) = (self.forward.vector(), self.up.vector());
        Rotation3::from_matrix_unchecked(Matrix3::from_rows(&[
            f.transpose(),
            up.cross(&f).transpose(),
            up.transpose(),
        ]))
    }
}

/// Whether the quaternion `[x, y, z, w]` can stand for a rotation once normalised: finite and not
/// (nearly) zero. glTF asks for unit quaternions; files quantised or written with few digits are
/// normalised.
fn usable_rotation(q: [f32; 4]) -> bool {
    let norm = q.iter().map(|v| v * v).sum::<f32>().sqrt();
    norm.is_finite() && norm > 1e-6
}

fn name_of(node: &::gltf::Node) -> String {
    node.name()
        .map(str::to_owned)
        .unwrap_or_else(|| format!("node{}", node.index()))
}

/// The nodes' names, each unique: glTF allows two nodes of one name (Blender does not for bones,
/// other tools do), but the tree, the trajectory's columns and the profile's keys name bones by it.
/// Every node of a shared name gets its index after it (`Leg (node 18)`), with a warning.
fn unique_names(doc: &::gltf::Document, warnings: &mut Vec<String>) -> Vec<String> {
    let mut names: Vec<String> = doc.nodes().map(|nd| name_of(&nd)).collect();
    let mut by_name: BTreeMap<String, Vec<usize>> = BTreeMap::new();
    for (i, n) in names.iter().enumerate() {
        by_name.entry(n.clone()).or_default().push(i);
    }
    for (name, nodes) in by_name.into_iter().filter(|(_, v)| v.len() > 1) {
        let renamed: Vec<String> = nodes.iter().map(|&i| format!("{name} (node {i})")).collect();
        warnings.push(format!("{} nodes are named `{name}`: they are read as {}", nodes.len(), renamed.join(", ")));
        for (&i, r) in nodes.iter().zip(renamed) {
            names[i] = r;
        }
    }
    names
}

/// Reads the file and the bones of its main skin. `scale` (metres per file unit) overrides the
/// unit detection; `facing` says which file axes point up and forward.
pub fn read(path: &Path, scale: Option<f32>, facing: Facing) -> Result<Rig, GltfError> {
    let (document, buffers) = open(path)?;
    read_document(&document, &buffers, path, scale, facing)
}

/// [`read`] for a document already opened (see [`open`], [`open_bytes`]); `path` names the file in
/// errors.
pub fn read_document(
    doc: &::gltf::Document,
    buffers: &[Vec<u8>],
    path: &Path,
    scale: Option<f32>,
    facing: Facing,
) -> Result<Rig, GltfError> {
    let fail = |p: GltfProblem| p.in_file(path);
    let get = |b: ::gltf::Buffer| buffers.get(b.index()).map(|d| d.as_slice());

    // Hierarchy: one parent per node, no cycles; world transforms in parent-first order.
    let n = doc.nodes().count();
    let mut warnings = Vec::new();
    let names = unique_names(doc, &mut warnings);
    let mut parent = vec![None; n];
    for nd in doc.nodes() {
        for c in nd.children() {
            let ci = c.index();
            if ci == nd.index() {
                return Err(fail(GltfProblem::SelfParent {
                    node: ci,
                    name: names[ci].clone(),
                }));
            }
            if parent[ci].is_some() {
                return Err(fail(GltfProblem::SeveralParents {
                    node: ci,
                    name: names[ci].clone(),
                }));
            }
            parent[ci] = Some(nd.index());
        }
    }
    let mut order = Vec::with_capacity(n);
    let mut stack: Vec<usize> = (0..n).filter(|&i| parent[i].is_none()).collect();
    let children: Vec<Vec<usize>> = doc
        .nodes()
        .map(|nd| nd.children().map(|c| c.index()).collect())
        .collect();
    while let Some(i) = stack.pop() {
        order.push(i);
        stack.extend(children[i].iter().rev());
    }
    if order.len() < n {
        // Every node not reached from a root hangs in a cycle (each has exactly one parent).
        let mut reached = vec![false; n];
        order.iter().for_each(|&i| reached[i] = true);
        let start = (0..n).find(|&i| !reached[i]).unwrap_or(0);
        let mut cycle = vec![names[start].clone()];
        let mut i = parent[start].unwrap_or(start);
        while i != start && cycle.len() <= n {
            cycle.push(names[i].clone());
            i = parent[i].unwrap_or(start);
        }
        cycle.push(names[start].clone());
        return Err(fail(GltfProblem::Cycle(cycle)));
    }
    // A node's local matrix as [`NodeTransform::of`] reads it (the `gltf` crate's `matrix()` would
    // take a rotation that is not of unit length as a scale and shear).
    let mut locals: Vec<Matrix4<f32>> = Vec::with_capacity(n);
    for nd in doc.nodes() {
        locals.push(match nd.transform() {
            ::gltf::scene::Transform::Matrix { matrix } => Matrix4::from(matrix),
            ::gltf::scene::Transform::Decomposed { rotation: r, .. } => {
                if !usable_rotation(r) {
                    return Err(fail(GltfProblem::BadTransform(format!(
                        "node {} (`{}`) has the rotation {r:?}, which is no rotation (glTF asks for a unit quaternion [x, y, z, w])",
                        nd.index(),
                        names[nd.index()]
                    ))));
                }
                NodeTransform::of(&nd).matrix()
            }
        });
    }
    let mut world = vec![Matrix4::identity(); n];
    for &i in &order {
        world[i] = match parent[i] {
            Some(p) => world[p] * locals[i],
            None => locals[i],
        };
        if !world[i].iter().all(|v| v.is_finite()) {
            return Err(fail(GltfProblem::BadTransform(format!(
                "node {i} (`{}`)",
                names[i]
            ))));
        }
    }

    // Skins: vertices each deforms, with the weights checked on the way.
    let mut skin_vertices = vec![0usize; doc.skins().count()];
    for nd in doc.nodes() {
        if let (Some(skin), Some(mesh)) = (nd.skin(), nd.mesh()) {
            for p in mesh.primitives() {
                let r = p.reader(get);
                if r.read_joints(0).is_some() && r.read_weights(0).is_some() {
                    skin_vertices[skin.index()] += r.read_positions().map_or(0, |it| it.len());
                }
            }
        }
    }
    let Some(skin_index) =
        (0..skin_vertices.len()).max_by_key(|&s| (skin_vertices[s], std::cmp::Reverse(s)))
    else {
        return Err(fail(GltfProblem::NoSkin));
    };
    let skin = doc.skins().nth(skin_index).expect("index in range");
    let skins: Vec<SkinInfo> = doc
        .skins()
        .map(|s| SkinInfo {
            name: s
                .name()
                .map(str::to_owned)
                .unwrap_or_else(|| format!("skin{}", s.index())),
            joints: s.joints().count(),
            vertices: skin_vertices[s.index()],
            used: s.index() == skin_index,
        })
        .collect();
    if skins.len() > 1 {
        warnings.push(format!(
            "{} skins; the creature is built from `{}` ({} joints), which deforms the most vertices ({})",
            skins.len(),
            skins[skin_index].name,
            skins[skin_index].joints,
            skins[skin_index].vertices
        ));
    }
    let joints: Vec<usize> = skin.joints().map(|j| j.index()).collect();
    if joints.len() < 2 {
        return Err(fail(GltfProblem::TooFewJoints {
            skin: skin_index,
            joints: joints.len(),
        }));
    }
    if joints.len() > MAX_JOINTS {
        return Err(fail(GltfProblem::TooManyJoints {
            skin: skin_index,
            joints: joints.len(),
        }));
    }
    if skin_vertices[skin_index] > MAX_SKINNED_VERTICES {
        return Err(fail(GltfProblem::TooManyVertices { skin: skin_index, vertices: skin_vertices[skin_index] }));
    }
    let mut slot = vec![None; n];
    for (k, &j) in joints.iter().enumerate() {
        if slot[j].is_some() {
            return Err(fail(GltfProblem::DuplicateJoint {
                skin: skin_index,
                node: j,
                name: names[j].clone(),
            }));
        }
        slot[j] = Some(k);
    }
    if skin_vertices[skin_index] == 0 {
        return Err(fail(GltfProblem::NoSkinnedMesh { skin: skin_index }));
    }
    let ibms: Vec<Matrix4<f32>> = match skin.reader(get).read_inverse_bind_matrices() {
        Some(it) => it.map(Matrix4::from).collect(),
        None => vec![Matrix4::identity(); joints.len()],
    };
    if ibms.len() < joints.len() {
        return Err(fail(GltfProblem::Parse(format!(
            "skin {skin_index} has {} inverse bind matrices for {} joints",
            ibms.len(),
            joints.len()
        ))));
    }

    // Morph targets weighted by default change the shape a player shows; the import reads the base mesh.
    let morphed: Vec<String> = doc
        .nodes()
        .filter(|nd| nd.skin().map(|s| s.index()) == Some(skin_index))
        .filter_map(|nd| {
            let weights = nd.weights().or_else(|| nd.mesh()?.weights())?;
            weights.iter().any(|w| *w != 0.0).then(|| names[nd.index()].clone())
        })
        .collect();
    if !morphed.is_empty() {
        warnings.push(format!(
            "the skinned mesh of {} is shown with morph targets weighted by default; the creature's geometry is \
             read from the base mesh, without them",
            morphed.join(", ")
        ));
    }
    // Rest pose: the bind pose (module docs). `rebound[i]`: node i's rest world matrix is not its
    // node transforms' (a joint moved to its bind pose, or a node below one).
    let skinned = doc.nodes().find(|nd| nd.mesh().is_some() && nd.skin().map(|s| s.index()) == Some(skin_index));
    let mesh_world = skinned.as_ref().map_or_else(Matrix4::identity, |nd| world[nd.index()]);
    let mut rest_world = world.clone();
    let mut rebound = vec![false; n];
    for &i in &order {
        let above = parent[i].map_or_else(Matrix4::identity, |p| rest_world[p]);
        let moved_above = parent[i].is_some_and(|p| rebound[p]);
        match slot[i] {
            Some(k) => {
                let bind = ibms[k]
                    .try_inverse()
                    .map(|inv| mesh_world * inv)
                    .filter(|m| m.iter().all(|v| v.is_finite()))
                    .ok_or_else(|| {
                        fail(GltfProblem::BadTransform(format!(
                            "the inverse bind matrix of joint `{}` cannot be inverted",
                            names[i]
                        )))
                    })?;
                if !same_placement(&world[i], &bind) {
                    rest_world[i] = bind;
                    rebound[i] = true;
                }
            }
            None if moved_above => {
                rest_world[i] = above * locals[i];
                rebound[i] = true;
            }
            None => {}
        }
    }
    let rest_local = |i: usize| -> Result<NodeTransform, GltfError> {
        let node = doc.nodes().nth(i).expect("node");
        if !rebound[i] && !parent[i].is_some_and(|p| rebound[p]) {
            return Ok(NodeTransform::of(&node));
        }
        let above = parent[i].map_or_else(Matrix4::identity, |p| rest_world[p]);
        above
            .try_inverse()
            .and_then(|inv| NodeTransform::from_matrix(&(inv * rest_world[i])))
            .ok_or_else(|| {
                fail(GltfProblem::BadTransform(format!(
                    "the bind pose of joint `{}` is no translation, rotation and scale of its parent's",
                    names[i]
                )))
            })
    };
    let moved = slot.iter().zip(&rebound).filter(|(s, r)| s.is_some() && **r).count();
    if moved > 0 {
        warnings.push(format!(
            "the nodes' transforms are not the skin's bind pose: {moved} of {} joints stand elsewhere; \
             the rest pose is the bind pose",
            joints.len()
        ));
    }

    // Skinned rest vertices in file world coordinates.
    let joint_mats: Vec<Matrix4<f32>> = joints
        .iter()
        .zip(&ibms)
        .map(|(&j, ibm)| rest_world[j] * ibm)
        .collect();
    let mut raw: Vec<(Point3<f32>, Vec<(usize, f32)>)> = Vec::new();
    let mut deforms = vec![0usize; joints.len()];
    for nd in doc.nodes() {
        let (Some(s), Some(mesh)) = (nd.skin(), nd.mesh()) else {
            continue;
        };
        if s.index() != skin_index {
            continue;
        }
        for (pi, p) in mesh.primitives().enumerate() {
            let r = p.reader(get);
            let Some(pos) = r.read_positions() else {
                continue;
            };
            // Every set of four influences (`JOINTS_n`, `WEIGHTS_n`): exporters write a second set for
            // vertices of more than four, where the heaviest may be.
            let mut sets: Vec<(Vec<[u16; 4]>, Vec<[f32; 4]>)> = Vec::new();
            while let (Some(j), Some(w)) = (r.read_joints(sets.len() as u32), r.read_weights(sets.len() as u32)) {
                sets.push((j.into_u16().collect(), w.into_f32().collect()));
            }
            if sets.is_empty() {
                continue;
            }
            let bad = |vertex: usize, what: String| {
                fail(GltfProblem::BadVertex {
                    mesh: mesh.index(),
                    primitive: pi,
                    vertex,
                    what,
                })
            };
            for (vi, v) in pos.enumerate() {
                let mut inf = Vec::with_capacity(4 * sets.len());
                let mut total = 0.0;
                let influences = sets.iter().filter_map(|(j, w)| Some((j.get(vi)?, w.get(vi)?)));
                for (jk, wk) in influences.flat_map(|(j, w)| (0..4).map(move |k| (j[k] as usize, w[k]))) {
                    if !wk.is_finite() || wk < 0.0 {
                        return Err(bad(
                            vi,
                            format!("skin weight {wk} (weights must be finite and ≥ 0)"),
                        ));
                    }
                    if wk == 0.0 {
                        continue;
                    }
                    if jk >= joints.len() {
                        return Err(bad(
                            vi,
                            format!("joint index {jk}, but the skin has {} joints", joints.len()),
                        ));
                    }
                    if inf.iter().any(|&(o, _)| o == jk) {
                        return Err(bad(
                            vi,
                            format!("joint index {jk} appears twice among its weights"),
                        ));
                    }
                    inf.push((jk, wk));
                    total += wk;
                }
                if !v.iter().all(|x| x.is_finite()) {
                    return Err(bad(vi, "non-finite position".into()));
                }
                if total <= 0.0 {
                    continue;
                }
                let mut m = Matrix4::zeros();
                for &(jk, wk) in &inf {
                    m += joint_mats[jk] * (wk / total);
                    deforms[jk] += 1;
                }
                let p = m.transform_point(&Point3::from(v));
                raw.push((p, inf.iter().map(|&(jk, wk)| (jk, wk / total)).collect()));
            }
        }
    }

    // Bones: the skin's joints in parent-first order, parents = nearest ancestor joint.
    let mut bone_of = vec![None; n];
    let mut bones_nodes = Vec::new();
    for &i in &order {
        if slot[i].is_some() {
            bone_of[i] = Some(bones_nodes.len());
            bones_nodes.push(i);
        }
    }
    // A skeleton below an unevenly scaled node: the tree turns its bones rigidly, but the file scales
    // their turns unevenly, so the clip exported onto the model would not be the motion retargeted
    // (a Fox under a scale of [1, 2, 1] kept its feet 12 cm in the air in every frame).
    // The nearest ancestor of a node that is a bone (its parent bone), if any.
    let bone_above = |node: usize| {
        let mut up = parent[node];
        while let Some(a) = up.filter(|&a| bone_of[a].is_none()) {
            up = parent[a];
        }
        up
    };
    let uneven = |m: &Matrix4<f32>| {
        let s = m.fixed_view::<3, 3>(0, 0).into_owned().svd(false, false).singular_values;
        // (A zero scale is no rotation at all, which the bones' check below reports.)
        (s.max() - s.min() > 1e-3 * s.max() && s.min() > 1e-6 * s.max()).then_some(s)
    };
    let apply = "the bones would not turn as they do in the file: apply the scale in the modelling tool (in Blender, \
                 Apply › Scale) and export again";
    for &node in &bones_nodes {
        let (None, Some(q)) = (bone_above(node), parent[node]) else { continue };
        if let Some(s) = uneven(&rest_world[q]) {
            return Err(fail(GltfProblem::BadTransform(format!(
                "node {q} (`{}`), above the skeleton, scales unevenly (by {:.3}, {:.3} and {:.3} along its axes); {apply}",
                names[q], s[0], s[1], s[2]
            ))));
        }
    }
    // The same for the skinned mesh's node and within the skeleton: a bone whose bind pose scales
    // unevenly (the hound's hips by [1.1, 0.9, 1.25] stretched its shins by 23 % as they swung).
    if let Some((nd, s)) = skinned.and_then(|nd| Some((nd.index(), uneven(&mesh_world)?))) {
        return Err(fail(GltfProblem::BadTransform(format!(
            "node {nd} (`{}`), the skinned mesh's, scales unevenly (by {:.3}, {:.3} and {:.3} along its axes); {apply}",
            names[nd], s[0], s[1], s[2]
        ))));
    }
    for &node in &bones_nodes {
        if let Some(s) = uneven(&rest_world[node]) {
            return Err(fail(GltfProblem::BadTransform(format!(
                "joint `{}` scales unevenly in its bind pose (by {:.3}, {:.3} and {:.3} along its axes); {apply}",
                names[node], s[0], s[1], s[2]
            ))));
        }
    }
    let to_character = facing.to_character();
    // Units.
    let mut bb_min = Vector3::repeat(f32::INFINITY);
    let mut bb_max = Vector3::repeat(f32::NEG_INFINITY);
    for (p, _) in &raw {
        let q = to_character * p.coords;
        bb_min = bb_min.inf(&q);
        bb_max = bb_max.sup(&q);
    }
    let extent = (bb_max - bb_min).max();
    let scale = match scale {
        Some(s) => s,
        None => {
            let mut s = 1.0f32;
            let mut unit = "metres";
            for (f, u) in [(0.01, "centimetres"), (0.001, "millimetres")] {
                if extent * s > MAX_PLAUSIBLE_SIZE {
                    s = f;
                    unit = u;
                }
            }
            if s != 1.0 {
                warnings.push(format!(
                    "the model is {extent:.1} units across, implausible in metres; read as {unit} ({:.2} m). \
                     Set `scale` (metres per file unit) in the profile to give its real size",
                    extent * s
                ));
            }
            // Read as millimetres and still too big, or too small in metres: no unit helps.
            if extent * s > MAX_PLAUSIBLE_SIZE || extent * s < MIN_PLAUSIBLE_SIZE {
                warnings.push(format!(
                    "the model is {:.3e} m across as read, implausible for a creature ({MIN_PLAUSIBLE_SIZE} to \
                     {MAX_PLAUSIBLE_SIZE} m): its steps, reach and speeds follow that size; set `scale` (metres per \
                     file unit) in the profile to give its real size",
                    extent * s
                ));
            }
            s
        }
    };
    if !(scale.is_finite() && scale > 0.0) {
        return Err(fail(GltfProblem::BadTransform(format!(
            "scale {scale} (must be finite and > 0)"
        ))));
    }
    let to_char_iso = |m: &Matrix4<f32>| -> Option<Isometry3<f32>> {
        let r = to_character.matrix() * m.fixed_view::<3, 3>(0, 0);
        let t = to_character * m.fixed_view::<3, 1>(0, 3).into_owned() * scale;
        let rot = polar_rotation(&r)?;
        Some(Isometry3::from_parts(Translation3::from(t), rot))
    };
    let mut bones = Vec::with_capacity(bones_nodes.len());
    for &node in &bones_nodes {
        let p = bone_above(node);
        let rest = to_char_iso(&rest_world[node]).ok_or_else(|| {
            let det = rest_world[node].fixed_view::<3, 3>(0, 0).determinant();
            fail(GltfProblem::BadTransform(if det < 0.0 {
                format!(
                    "node {node} (`{}`) stands mirrored (a negative scale on it or above it); mirrored armatures \
                     are not read: apply the scale in the modelling tool (in Blender, Apply › Scale) and export again",
                    names[node]
                )
            } else {
                format!("node {node} (`{}`) has a degenerate rotation (a zero scale on it or above it)", names[node])
            }))
        })?;
        bones.push(Bone {
            name: names[node].clone(),
            node,
            parent: p.and_then(|a| bone_of[a]),
            rest,
            rest_local: rest_local(node)?,
            file_local: NodeTransform::of(&doc.nodes().nth(node).expect("node")),
            deforms: deforms[slot[node].expect("joint")],
            parent_world: parent[node].map_or_else(Matrix4::identity, |q| rest_world[q]),
        });
    }
    let bone_index: Vec<usize> = (0..joints.len())
        .map(|k| bone_of[joints[k]].expect("joint"))
        .collect();
    let vertices = raw
        .into_iter()
        .map(|(p, w)| {
            (
                Point3::from(to_character * p.coords * scale),
                w.into_iter().map(|(k, wk)| (bone_index[k], wk)).collect(),
            )
        })
        .collect();

    // Nodes that are no joint of the skin but carry some of its bones (a control above a bone, an
    // armature object): their channels move the skeleton, and the import reads joints' channels only.
    let mut carries_bones = vec![false; n];
    for &b in &bones_nodes {
        let mut up = parent[b];
        while let Some(a) = up {
            if bone_of[a].is_none() {
                carries_bones[a] = true;
            }
            up = parent[a];
        }
    }
    // Clips: every rotation keyframe of every bone.
    let mut clip_rotations = vec![Vec::new(); bones.len()];
    let mut animations = Vec::new();
    let mut clips = Vec::new();
    for a in doc.animations() {
        let name = a.name().map(str::to_owned).unwrap_or_else(|| format!("animation{}", a.index()));
        let mut duration = 0.0f32;
        let mut channels = 0;
        let mut tracks = Vec::new();
        let mut unread: Vec<&str> = Vec::new();
        for ch in a.channels() {
            channels += 1;
            let target = ch.target().node().index();
            if carries_bones[target]
                && ch.target().property() != ::gltf::animation::Property::MorphTargetWeights
                && !unread.contains(&names[target].as_str())
            {
                unread.push(&names[target]);
            }
            let r = ch.reader(get);
            if let Some(t) = r.read_inputs() {
                for time in t {
                    // The duration sizes every sampling of the clip (`clips::clip_frames`).
                    if !(time.is_finite() && time <= MAX_ANIMATION_SECONDS) {
                        return Err(fail(GltfProblem::AnimationTooLong { index: a.index(), name, time }));
                    }
                    duration = duration.max(time);
                }
            }
            let Some(b) = bone_of[ch.target().node().index()] else {
                continue;
            };
            let interpolation = ch.sampler().interpolation();
            let cubic = interpolation == ::gltf::animation::Interpolation::CubicSpline;
            let mut times: Vec<f32> = r.read_inputs().map(|t| t.collect()).unwrap_or_default();
            // Keyframe values (a cubic spline's tangents skipped).
            let (kind, mut values): (TrackKind, Vec<[f32; 4]>) = match r.read_outputs() {
                Some(ReadOutputs::Rotations(rot)) => (TrackKind::Rotation, rot.into_f32().collect()),
                Some(ReadOutputs::Translations(tr)) => {
                    (TrackKind::Translation, tr.map(|[x, y, z]| [x, y, z, 0.0]).collect())
                }
                _ => continue,
            };
            if cubic {
                values = values.into_iter().skip(1).step_by(3).collect();
            }
            let what = if kind == TrackKind::Rotation { "rotation" } else { "translation" };
            let at = format!("animation {} (`{name}`), the {what} of `{}`", a.index(), names[ch.target().node().index()]);
            if times.len() != values.len() {
                warnings.push(format!(
                    "{at}: {} keyframe times for {} values; the channel is left out",
                    times.len(),
                    values.len()
                ));
                continue;
            }
            // glTF asks for unit quaternions and finite values: keyframes without them are left out
            // (the neighbours' interpolation spans them), never turned into NaN poses.
            let usable = |v: &[f32; 4]| match kind {
                TrackKind::Rotation => usable_rotation(*v),
                TrackKind::Translation => v.iter().all(|x| x.is_finite()),
            };
            let bad = values.iter().filter(|v| !usable(v)).count();
            if bad > 0 {
                warnings.push(format!(
                    "{at}: {bad} of {} keyframes are {}; they are left out",
                    values.len(),
                    if kind == TrackKind::Rotation { "no rotation (zero or not finite)" } else { "not finite" }
                ));
                (times, values) = times.into_iter().zip(values).filter(|(_, v)| usable(v)).unzip();
            }
            if times.is_empty() {
                continue;
            }
            if times.windows(2).any(|w| w[1] < w[0]) {
                // Sampling searches the times, so they must be in order (glTF asks for it).
                warnings.push(format!("{at}: its keyframe times are out of order; they are read sorted"));
                let mut keys: Vec<(f32, [f32; 4])> = times.into_iter().zip(values).collect();
                keys.sort_by(|x, y| x.0.total_cmp(&y.0));
                (times, values) = keys.into_iter().unzip();
            }
            if kind == TrackKind::Rotation {
                clip_rotations[b].extend(
                    values.iter().map(|q| UnitQuaternion::from_quaternion(nalgebra::Quaternion::new(q[3], q[0], q[1], q[2]))),
                );
            }
            tracks.push(Track {
                bone: b,
                kind,
                step: interpolation == ::gltf::animation::Interpolation::Step,
                times,
                values,
            });
        }
        if !unread.is_empty() {
            warnings.push(format!(
                "animation {} (`{name}`) moves {} node(s) that carry bones but are no joints of the skin ({}): only \
                 joints' channels are read, so the clip's joint ranges and `--include-clips` miss that motion; make \
                 them joints of the skin, or bake their motion onto the bones",
                a.index(),
                unread.len(),
                unread.join(", ")
            ));
        }
        animations.push(AnimationInfo {
            name,
            duration_s: duration,
            channels,
        });
        clips.push(tracks);
    }
    Ok(Rig {
        bones,
        vertices,
        clip_rotations,
        clips,
        scale,
        to_character,
        skins,
        animations,
        warnings,
    })
}

/// The bytes of the glTF file at `path`: a regular file of at most [`MAX_FILE_BYTES`].
fn read_file(path: &Path) -> Result<Vec<u8>, GltfError> {
    let fail = |p: GltfProblem| p.in_file(path);
    let meta = std::fs::metadata(path).map_err(|e| fail(GltfProblem::Io(e.to_string())))?;
    if !meta.is_file() {
        return Err(fail(GltfProblem::NotAFile));
    }
    if meta.len() > MAX_FILE_BYTES {
        return Err(fail(GltfProblem::TooLarge(meta.len())));
    }
    std::fs::read(path).map_err(|e| fail(GltfProblem::Io(e.to_string())))
}

/// The document of the glTF file at `path` (at most [`MAX_FILE_BYTES`]) and the bytes of each of its
/// buffers (the GLB binary chunk, data URIs, files beside it).
pub fn open(path: &Path) -> Result<(::gltf::Document, Vec<Vec<u8>>), GltfError> {
    let bytes = read_file(path)?;
    open_bytes(&bytes, path, &|uri| read_beside(path, uri))
}

/// The bytes of the file that the glTF at `gltf` names by `uri` (already percent-decoded, relative to
/// the glTF's folder): a regular file of at most [`MAX_FILE_BYTES`], or why not, naming the file.
/// Buffers ([`open`]) and the rig export's images are read through it.
pub(crate) fn read_beside(gltf: &Path, uri: &str) -> Result<Vec<u8>, String> {
    let file = gltf.parent().unwrap_or(Path::new(".")).join(uri);
    let meta = std::fs::metadata(&file).map_err(|e| format!("{}: {e}", file.display()))?;
    if !meta.is_file() || meta.len() > MAX_FILE_BYTES {
        return Err(format!(
            "{}: not a regular file of at most {MAX_FILE_BYTES} bytes",
            file.display()
        ));
    }
    std::fs::read(&file).map_err(|e| format!("{}: {e}", file.display()))
}

/// The files a glTF file's buffers name (their URIs percent-decoded, relative to the file), in buffer
/// order: what [`open_bytes`] will ask for. Data URIs and the GLB chunk are not files.
pub fn external_buffers(bytes: &[u8], path: &Path) -> Result<Vec<String>, GltfError> {
    let (document, _) = parse(bytes, path)?;
    Ok(document
        .buffers()
        .filter_map(|b| match b.source() {
            ::gltf::buffer::Source::Uri(uri) if !uri.starts_with("data:") => Some(percent_decode(uri)),
            _ => None,
        })
        .collect())
}

/// Every other file the glTF file at `path` reads: its buffers' and its images' URIs that are not
/// data URIs, percent-decoded and relative to the file's folder (what [`open`] and the rig export read
/// beside it). Empty for a self-contained file. Commands register them as inputs, never to be written
/// over.
pub fn external_files(path: &Path) -> Result<Vec<PathBuf>, GltfError> {
    let (document, _) = parse(&read_file(path)?, path)?;
    let base = path.parent().unwrap_or(Path::new("."));
    let buffers = document.buffers().filter_map(|b| match b.source() {
        ::gltf::buffer::Source::Uri(uri) => Some(uri),
        ::gltf::buffer::Source::Bin => None,
    });
    let images = document.images().filter_map(|i| match i.source() {
        ::gltf::image::Source::Uri { uri, .. } => Some(uri),
        ::gltf::image::Source::View { .. } => None,
    });
    Ok(buffers
        .chain(images)
        .filter(|uri| !uri.starts_with("data:"))
        .map(|uri| base.join(percent_decode(uri)))
        .collect())
}

/// [`open`] for a file's bytes (at most [`MAX_FILE_BYTES`]): `file(uri)` gives the bytes of a buffer
/// stored in another file (its URI percent-decoded, relative to the glTF file) or why it cannot.
/// `path` names the file in errors.
pub fn open_bytes(
    bytes: &[u8],
    path: &Path,
    file: &dyn Fn(&str) -> Result<Vec<u8>, String>,
) -> Result<(::gltf::Document, Vec<Vec<u8>>), GltfError> {
    let (document, blob) = parse(bytes, path)?;
    let buffers = read_buffers(&document, path, blob, file)?;
    Ok((document, buffers))
}

/// The document of a glTF file's bytes (JSON or GLB), checked, and the GLB's binary chunk: every
/// reading of a file ([`open_bytes`], [`external_buffers`], [`external_files`]) goes through it.
fn parse(bytes: &[u8], path: &Path) -> Result<(::gltf::Document, Option<Vec<u8>>), GltfError> {
    let fail = |p: GltfProblem| p.in_file(path);
    if bytes.len() as u64 > MAX_FILE_BYTES {
        return Err(fail(GltfProblem::TooLarge(bytes.len() as u64)));
    }
    // The `gltf` crate subtracts the header's 12 bytes from the length a GLB declares before it checks
    // it (a panic in a debug build).
    if let Some(declared) = bytes.strip_prefix(b"glTF").and_then(|b| b.get(4..8)) {
        let declared = u32::from_le_bytes(declared.try_into().expect("four bytes"));
        if declared < 12 {
            return Err(fail(GltfProblem::Parse(format!(
                "the GLB header declares a length of {declared} bytes, less than its own 12"
            ))));
        }
    }
    let parse = |e: ::gltf::Error| fail(GltfProblem::Parse(e.to_string()));
    let unchecked = ::gltf::Gltf::from_slice_without_validation(bytes).map_err(parse)?;
    let json = unchecked.document.into_json();
    check_required_extensions(&json.extensions_required).map_err(fail)?;
    check_what_validation_misses(&json).map_err(fail)?;
    // The crate's validation refuses every required extension it was not built for (which depends
    // on the features other crates enable); those left are ones the import reads through. The
    // document keeps them, so that a model exported from it still requires them.
    let mut checked = json.clone();
    checked.extensions_required.clear();
    ::gltf::Document::from_json(checked).map_err(parse)?;
    let document = ::gltf::Document::from_json_without_validation(json);
    check_accessor_types(&document).map_err(fail)?;
    Ok((document, unchecked.blob))
}

/// Refuses a file that requires an extension the import cannot read through: one that may change
/// the skeleton, the skin, the clips or how their data is stored (compressed or quantized
/// geometry). Extensions of materials, textures and lights are read through: the import reads none
/// of those.
fn check_required_extensions(required: &[String]) -> Result<(), GltfProblem> {
    const LOOKS_ONLY: [&str; 4] = ["KHR_materials_", "KHR_texture_", "EXT_texture_", "MSFT_texture_"];
    let Some(name) = required
        .iter()
        .find(|e| !(LOOKS_ONLY.iter().any(|p| e.starts_with(p)) || matches!(e.as_str(), "KHR_lights_punctual" | "KHR_xmp_json_ld")))
    else {
        return Ok(());
    };
    let what = match name.as_str() {
        "KHR_draco_mesh_compression" | "EXT_meshopt_compression" | "KHR_meshopt_compression" => "compressed geometry, which the import does not decode",
        "KHR_mesh_quantization" => "quantized vertex data, which the import does not read",
        _ => "an extension the import does not know; it may change the skeleton, the skin or the clips",
    };
    Err(GltfProblem::RequiredExtension { name: name.clone(), what })
}

/// The accessors a creature is read from have the types the glTF specification gives them (a vertex
/// position three floats, a joint set four small integers, an animation's times scalar floats, …),
/// and their buffer views' strides hold a whole element: the `gltf` crate reads them as those types,
/// asserting it in debug builds and reading garbage otherwise.
fn check_accessor_types(doc: &::gltf::Document) -> Result<(), GltfProblem> {
    use ::gltf::Semantic;
    use ::gltf::accessor::{DataType, DataType::*, Dimensions, Dimensions::*};
    use ::gltf::animation::Property;
    let check = |a: ::gltf::Accessor, what: &dyn Fn() -> String, dims: Dimensions, types: &[DataType]| {
        if a.dimensions() != dims || !types.contains(&a.data_type()) {
            return Err(GltfProblem::Parse(format!(
                "{}: accessor {} holds {:?} of {:?}; expected {dims:?} of {}",
                what(),
                a.index(),
                a.dimensions(),
                a.data_type(),
                types.iter().map(|t| format!("{t:?}")).collect::<Vec<_>>().join(" or ")
            )));
        }
        match a.view().and_then(|v| v.stride()) {
            Some(stride) if stride < a.size() => Err(GltfProblem::Parse(format!(
                "{}: accessor {}'s buffer view strides {stride} bytes, less than its {}-byte elements",
                what(),
                a.index(),
                a.size()
            ))),
            _ => Ok(()),
        }
    };
    for mesh in doc.meshes() {
        for p in mesh.primitives() {
            for (semantic, a) in p.attributes() {
                let what = || format!("meshes[{}].primitives[{}].attributes.{}", mesh.index(), p.index(), semantic.to_string());
                match semantic {
                    Semantic::Positions => check(a, &what, Vec3, &[F32])?,
                    Semantic::Joints(_) => check(a, &what, Vec4, &[U8, U16])?,
                    Semantic::Weights(_) => check(a, &what, Vec4, &[F32, U8, U16])?,
                    _ => {}
                }
            }
        }
    }
    for skin in doc.skins() {
        if let Some(a) = skin.inverse_bind_matrices() {
            check(a, &|| format!("skins[{}].inverseBindMatrices", skin.index()), Mat4, &[F32])?;
        }
    }
    for anim in doc.animations() {
        for ch in anim.channels() {
            let sampler = ch.sampler();
            let what = |end: &str| format!("animations[{}].samplers[{}].{end}", anim.index(), sampler.index());
            check(sampler.input(), &|| what("input"), Scalar, &[F32])?;
            let (dims, types): (Dimensions, &[DataType]) = match ch.target().property() {
                Property::Translation | Property::Scale => (Vec3, &[F32]),
                Property::Rotation => (Vec4, &[F32, I8, U8, I16, U16]),
                Property::MorphTargetWeights => (Scalar, &[F32, I8, U8, I16, U16]),
            };
            check(sampler.output(), &|| what("output"), dims, types)?;
        }
    }
    Ok(())
}

/// What the `gltf` crate's validation reads before checking, or does not check, and its accessors
/// then unwrap (a panic on a bad file): every primitive's attributes are ones glTF knows and its
/// `POSITION` accessor exists, and every animation channel targets a node that exists with a
/// property glTF knows.
fn check_what_validation_misses(root: &::gltf::json::Root) -> Result<(), GltfProblem> {
    use ::gltf::json::mesh::Semantic;
    use ::gltf::json::validation::Checked;
    for (a, anim) in root.animations.iter().enumerate() {
        for (c, ch) in anim.channels.iter().enumerate() {
            let at = format!("animations[{a}].channels[{c}].target");
            if ch.target.node.value() >= root.nodes.len() {
                return Err(GltfProblem::Parse(format!(
                    "{at}.node names node {}, but the file has {}",
                    ch.target.node.value(),
                    root.nodes.len()
                )));
            }
            if let Checked::Invalid = ch.target.path {
                return Err(GltfProblem::Parse(format!(
                    "{at}.path is not translation, rotation, scale or weights"
                )));
            }
        }
    }
    for (m, mesh) in root.meshes.iter().enumerate() {
        for (p, primitive) in mesh.primitives.iter().enumerate() {
            if primitive.attributes.keys().any(|k| matches!(k, Checked::Invalid)) {
                return Err(GltfProblem::Parse(format!("meshes[{m}].primitives[{p}].attributes names an attribute glTF does not know")));
            }
            if let Some(i) = primitive.attributes.get(&Checked::Valid(Semantic::Positions))
                && i.value() >= root.accessors.len()
            {
                return Err(GltfProblem::Parse(format!(
                    "meshes[{m}].primitives[{p}].attributes.POSITION names accessor {}, but the file has {}",
                    i.value(),
                    root.accessors.len()
                )));
            }
        }
    }
    Ok(())
}

/// Every buffer's bytes, with errors that name the buffer and its URI.
fn read_buffers(
    doc: &::gltf::Document,
    path: &Path,
    mut blob: Option<Vec<u8>>,
    file: &dyn Fn(&str) -> Result<Vec<u8>, String>,
) -> Result<Vec<Vec<u8>>, GltfError> {
    // A file listed by several buffers would be read (and held) once per listing.
    let mut listed: std::collections::HashMap<&str, usize> = std::collections::HashMap::new();
    for b in doc.buffers() {
        if let ::gltf::buffer::Source::Uri(uri) = b.source()
            && !uri.starts_with("data:")
            && let Some(first) = listed.insert(uri, b.index())
        {
            return Err(GltfProblem::RepeatedBuffer { first, index: b.index(), uri: uri.to_owned() }.in_file(path));
        }
    }
    let mut out = Vec::new();
    let mut total = 0u64;
    for b in doc.buffers() {
        let index = b.index();
        let (uri, data) = match b.source() {
            ::gltf::buffer::Source::Bin => (
                "the GLB binary chunk".to_owned(),
                blob.take().unwrap_or_default(),
            ),
            ::gltf::buffer::Source::Uri(uri) if uri.starts_with("data:") => {
                let data = uri
                    .split_once(";base64,")
                    .map(|(_, d)| d)
                    .ok_or_else(|| "only base64 data URIs are read".to_owned())
                    .and_then(|d| decode_base64(d).ok_or_else(|| "invalid base64".to_owned()))
                    .map_err(|reason| {
                        GltfProblem::Buffer {
                            index,
                            uri: "a data URI".into(),
                            reason,
                        }
                        .in_file(path)
                    })?;
                ("a data URI".to_owned(), data)
            }
            ::gltf::buffer::Source::Uri(uri) => {
                let data = file(&percent_decode(uri)).map_err(|reason| {
                    GltfProblem::Buffer {
                        index,
                        uri: uri.to_owned(),
                        reason,
                    }
                    .in_file(path)
                })?;
                (uri.to_owned(), data)
            }
        };
        if data.len() < b.length() {
            return Err(GltfProblem::Buffer {
                index,
                uri,
                reason: format!("{} bytes, but the file declares {}", data.len(), b.length()),
            }
            .in_file(path));
        }
        total += data.len() as u64;
        if total > MAX_FILE_BYTES {
            return Err(GltfProblem::BuffersTooLarge.in_file(path));
        }
        out.push(data);
    }
    Ok(out)
}

/// `s` with its `%XX` escapes decoded (bytes that are not UTF-8 replaced), as URIs of files beside a
/// glTF carry them. Anything that is not a whole escape is kept as it is.
pub fn percent_decode(s: &str) -> String {
    percent_encoding::percent_decode_str(s).decode_utf8_lossy().into_owned()
}

/// Decodes base64 as data URIs carry it: the standard alphabet or the URL-safe one, padding optional,
/// whitespace and the unused bits of the last digit ignored. `None` for anything else.
pub fn decode_base64(s: &str) -> Option<Vec<u8>> {
    use base64::engine::{DecodePaddingMode, GeneralPurpose, GeneralPurposeConfig};
    const LENIENT: GeneralPurpose = GeneralPurpose::new(
        &base64::alphabet::STANDARD,
        GeneralPurposeConfig::new()
            .with_decode_padding_mode(DecodePaddingMode::Indifferent)
            .with_decode_allow_trailing_bits(true),
    );
    let standard = |c: u8| match c {
        b'-' => b'+',
        b'_' => b'/',
        c => c,
    };
    let digits: Vec<u8> = s.bytes().filter(|c| !c.is_ascii_whitespace()).map(standard).collect();
    base64::Engine::decode(&LENIENT, digits).ok()
}

/// Whether two world matrices place a node the same to float precision: their linear parts within
/// 1e-4 of their scale, their translations within 1e-4 of their distance from the origin (plus one
/// file unit).
fn same_placement(a: &Matrix4<f32>, b: &Matrix4<f32>) -> bool {
    let (la, lb) = (a.fixed_view::<3, 3>(0, 0), b.fixed_view::<3, 3>(0, 0));
    let (ta, tb) = (a.fixed_view::<3, 1>(0, 3), b.fixed_view::<3, 1>(0, 3));
    (la - lb).abs().max() <= 1e-4 * lb.abs().max() && (ta - tb).norm() <= 1e-4 * (1.0 + tb.norm())
}

/// The rotation nearest to `m` (its polar factor); `None` when `m` is degenerate or mirrors.
pub fn polar_rotation(m: &Matrix3<f32>) -> Option<UnitQuaternion<f32>> {
    if !m.iter().all(|v| v.is_finite()) {
        return None;
    }
    let svd = m.svd(true, true);
    let (u, vt) = (svd.u?, svd.v_t?);
    if svd.singular_values.min() <= 1e-9 * svd.singular_values.max().max(1e-30) {
        return None;
    }
    let r = u * vt;
    if r.determinant() <= 0.0 {
        return None;
    }
    Some(UnitQuaternion::from_rotation_matrix(
        &Rotation3::from_matrix_unchecked(r),
    ))
}

/// A capsule for the core of a bone's flesh around `points` (in the frame they are given in): axis along
/// their principal direction, radius the median of their distances from the axis, caps reaching the 5th
/// and 95th percentiles along it. A skinned mesh bulges and creases at the joints, so a proxy that
/// covered every vertex would overlap its neighbours whenever a joint bends. When the points have no
/// distinct principal direction (the largest variance under [`DISTINCT_AXIS`] times the next: a blob,
/// such as a chest, whose axis would fall by chance and could make a mirror-symmetric body asymmetric),
/// the axis is `along` instead, the bone's own direction, if given. `None` for fewer than 4 points.
pub fn fit_capsule(points: &[Point3<f32>], along: Option<Vector3<f32>>) -> Option<Geometry> {
    if points.len() < 4 {
        return None;
    }
    let n = points.len() as f32;
    let c = points.iter().fold(Vector3::zeros(), |a, p| a + p.coords) / n;
    let mut cov = Matrix3::zeros();
    for p in points {
        let d = p.coords - c;
        cov += d * d.transpose();
    }
    let eig = (cov / n).symmetric_eigen();
    let k = eig.eigenvalues.imax();
    let second = (0..3).filter(|&i| i != k).map(|i| eig.eigenvalues[i]).fold(f32::NEG_INFINITY, f32::max);
    let axis = match along.and_then(|a| a.try_normalize(1e-9)) {
        Some(a) if eig.eigenvalues[k] < DISTINCT_AXIS * second => a,
        _ => eig.eigenvectors.column(k).into_owned().normalize(),
    };
    let mut along: Vec<f32> = Vec::with_capacity(points.len());
    let mut radial: Vec<f32> = Vec::with_capacity(points.len());
    for p in points {
        let d = p.coords - c;
        let t = d.dot(&axis);
        along.push(t);
        radial.push((d - axis * t).norm());
    }
    let quantile = |v: &mut Vec<f32>, q: f32| {
        v.sort_by(f32::total_cmp);
        v[((v.len() - 1) as f32 * q).round() as usize]
    };
    let radius = quantile(&mut radial, 0.5).max(1e-4);
    let (lo, hi) = (quantile(&mut along, 0.05), quantile(&mut along, 0.95));
    let length = ((hi - lo) - 2.0 * radius).max(0.0);
    let centre = c + axis * (0.5 * (lo + hi));
    let rot = UnitQuaternion::rotation_between(&Vector3::z(), &axis).unwrap_or_else(|| {
        UnitQuaternion::from_axis_angle(&Vector3::x_axis(), std::f32::consts::PI)
    });
    Some(Geometry {
        origin: Isometry3::from_parts(Translation3::from(centre), rot),
        shape: Shape::Capsule { radius, length },
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every facing of a file turns its forward axis to the character's +x and its up axis to +z, as a
    /// proper rotation; parallel ones are refused.
    #[test]
    fn each_facing_turns_forward_to_x_and_up_to_z() {
        for up in Axis::ALL {
            for forward in Axis::ALL {
                let Ok(f) = Facing::new(Some(forward), Some(up)) else {
                    assert_eq!(forward.vector().dot(&up.vector()).abs(), 1.0, "{forward:?} {up:?} refused");
                    continue;
                };
                let r = f.to_character();
                assert!((r * forward.vector() - Vector3::x()).norm() < 1e-6, "{forward:?} {up:?}");
                assert!((r * up.vector() - Vector3::z()).norm() < 1e-6, "{forward:?} {up:?}");
                assert!((r.matrix().determinant() - 1.0).abs() < 1e-6);
            }
        }
        // The defaults: glTF's, and Blender's front when up is along z.
        assert_eq!(Facing::new(None, None), Ok(Facing { forward: Axis::PlusZ, up: Axis::PlusY }));
        assert_eq!(Facing::new(None, Some(Axis::MinusZ)).map(|f| f.forward), Ok(Axis::MinusY));
        assert_eq!(Facing::new(None, Some(Axis::PlusX)).map(|f| f.forward), Ok(Axis::PlusZ));
        let labels: Vec<&str> = Axis::ALL.iter().map(|a| a.label()).collect();
        assert_eq!(labels, ["+y", "+z", "-z", "+x", "-x", "-y"]);
        // Each axis is the one its label names (the checks above hold for any consistent relabelling).
        for a in Axis::ALL {
            let (sign, letter) = a.label().split_at(1);
            let unit = match letter {
                "x" => Vector3::x(),
                "y" => Vector3::y(),
                _ => Vector3::z(),
            };
            assert_eq!(a.vector(), if sign == "-" { -unit } else { unit }, "{a:?}");
        }
    }

    /// The bundled hound with its JSON edited by `edit`, as a `.glb`'s bytes.
    fn edited_hound(edit: impl Fn(&mut serde_json::Value)) -> Vec<u8> {
        let glb = std::fs::read(Path::new(env!("CARGO_MANIFEST_DIR")).join("../assets/creatures/hound.glb")).unwrap();
        let n = u32::from_le_bytes(glb[12..16].try_into().unwrap()) as usize;
        let mut json: serde_json::Value = serde_json::from_slice(&glb[20..20 + n]).unwrap();
        edit(&mut json);
        let mut text = serde_json::to_vec(&json).unwrap();
        while text.len() % 4 != 0 {
            text.push(b' ');
        }
        let bin = &glb[20 + n..];
        let mut out = b"glTF".to_vec();
        out.extend(2u32.to_le_bytes());
        out.extend(((12 + 8 + text.len() + bin.len()) as u32).to_le_bytes());
        out.extend((text.len() as u32).to_le_bytes());
        out.extend(b"JSON");
        out.extend(text);
        out.extend(bin);
        out
    }

    #[test]
    fn accessors_of_the_wrong_type_are_refused_naming_them() {
        // Found by fuzzing: the `gltf` crate asserts the element size when it reads (debug builds).
        let open = |bytes: &[u8]| open_bytes(bytes, Path::new("hound.glb"), &|_| Err("no files".into())).map(|_| ());
        assert!(open(&edited_hound(|_| {})).is_ok());
        // Vertex joints read from the inverse bind matrices' accessor (5: MAT4).
        let e = open(&edited_hound(|j| j["meshes"][0]["primitives"][0]["attributes"]["JOINTS_0"] = 5.into())).unwrap_err().to_string();
        assert_eq!(
            e,
            "hound.glb: malformed glTF: meshes[0].primitives[0].attributes.JOINTS_0: accessor 5 holds Mat4 of F32; expected Vec4 of U8 or U16"
        );
        // An animation whose times are the vertex positions (accessor 0: VEC3).
        let e = open(&edited_hound(|j| {
            j["animations"] = serde_json::json!([{
                "channels": [{"sampler": 0, "target": {"node": 0, "path": "translation"}}],
                "samplers": [{"input": 0, "output": 1}]
            }]);
        }))
        .unwrap_err()
        .to_string();
        assert_eq!(e, "hound.glb: malformed glTF: animations[0].samplers[0].input: accessor 0 holds Vec3 of F32; expected Scalar of F32");
    }

    #[test]
    fn an_animation_channel_with_a_bad_target_is_refused() {
        // Found by fuzzing: the `gltf` crate does not validate channel targets and unwraps them.
        let open = |bytes: &[u8]| open_bytes(bytes, Path::new("hound.glb"), &|_| Err("no files".into())).map(|_| ()).unwrap_err().to_string();
        let animation = |target: serde_json::Value| {
            edited_hound(move |j| {
                j["accessors"].as_array_mut().unwrap().push(serde_json::json!({"componentType": 5126, "count": 1, "type": "SCALAR"}));
                j["animations"] = serde_json::json!([{
                    "channels": [{"sampler": 0, "target": target}],
                    "samplers": [{"input": 6, "output": 6}]
                }]);
            })
        };
        assert_eq!(
            open(&animation(serde_json::json!({"node": 0, "path": "wobble"}))),
            "hound.glb: malformed glTF: animations[0].channels[0].target.path is not translation, rotation, scale or weights"
        );
        assert_eq!(
            open(&animation(serde_json::json!({"node": 99, "path": "rotation"}))),
            "hound.glb: malformed glTF: animations[0].channels[0].target.node names node 99, but the file has 22"
        );
    }

    /// Every reading of a file's bytes: [`open_bytes`], [`external_buffers`] (which the plugin's loader
    /// calls first) and [`external_files`] (through a file written in the test's folder); the errors,
    /// each naming the file, must agree.
    fn every_reading(bytes: &[u8], name: &str) -> String {
        let e = open_bytes(bytes, Path::new(name), &|_| Err("no files".into())).unwrap_err().to_string();
        assert_eq!(external_buffers(bytes, Path::new(name)).unwrap_err().to_string(), e);
        let dir = std::env::temp_dir().join(format!("ace-gltf-reading-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let file = dir.join(name);
        std::fs::write(&file, bytes).unwrap();
        let from_file = external_files(&file).unwrap_err().to_string();
        assert_eq!(from_file.replacen(&file.display().to_string(), name, 1), e);
        e
    }

    #[test]
    fn malformed_files_the_gltf_crate_would_panic_on_are_refused() {
        // Found by fuzzing: the `gltf` crate's validation indexed the accessor and panicked.
        let text = br#"{"asset":{"version":"2.0"},"meshes":[{"primitives":[{"attributes":{"POSITION":3}}]}]}"#;
        let e = every_reading(text, "bad.gltf");
        assert!(
            e.starts_with("bad.gltf: ") && e.contains("meshes[0].primitives[0].attributes.POSITION names accessor 3, but the file has 0"),
            "{e}"
        );
        // The plugin's loader once handed such a GLB to the crate as it was (a panic in a debug build).
        let glb = [b"glTF".as_slice(), &2u32.to_le_bytes(), &4u32.to_le_bytes()].concat();
        let e = every_reading(&glb, "bad.glb");
        assert!(e.contains("the GLB header declares a length of 4 bytes, less than its own 12"), "{e}");
        let text = br#"{"asset":{"version":"2.0"},"meshes":[{"primitives":[{"attributes":{"WOBBLE":0}}]}]}"#;
        let e = every_reading(text, "bad.gltf");
        assert!(e.contains("meshes[0].primitives[0].attributes names an attribute glTF does not know"), "{e}");
    }

    /// A file that requires compressed or quantized geometry, or an extension nobody knows, is refused
    /// naming it (the crate's "malformed glTF: … Unsupported extension" called a valid file broken);
    /// one that requires extensions of materials, textures or lights reads as without them, and keeps
    /// requiring them.
    #[test]
    fn required_extensions_are_refused_by_name_or_read_through() {
        let with = |required: &[&str]| {
            let text = format!(r#"{{"asset":{{"version":"2.0"}},"extensionsUsed":{0:?},"extensionsRequired":{0:?},"buffers":[{{"byteLength":4,"uri":"b.bin"}}]}}"#, required);
            text.into_bytes()
        };
        for (ext, what) in [
            ("KHR_draco_mesh_compression", "compressed geometry, which the import does not decode"),
            ("EXT_meshopt_compression", "compressed geometry, which the import does not decode"),
            ("KHR_mesh_quantization", "quantized vertex data, which the import does not read"),
            ("EXT_mesh_gpu_instancing", "an extension the import does not know"),
        ] {
            let e = every_reading(&with(&["KHR_texture_basisu", ext]), "packed.gltf");
            assert!(
                e.starts_with(&format!("packed.gltf: the file requires the glTF extension `{ext}`: {what}"))
                    && e.ends_with("; export the model again without it"),
                "{e}"
            );
        }
        let looks = ["KHR_texture_basisu", "KHR_materials_variants", "EXT_texture_webp", "MSFT_texture_dds", "KHR_lights_punctual", "KHR_xmp_json_ld"];
        assert_eq!(external_buffers(&with(&looks), Path::new("looks.gltf")).unwrap(), ["b.bin"]);
        let (doc, buffers) = open_bytes(&with(&looks), Path::new("looks.gltf"), &|uri| {
            assert_eq!(uri, "b.bin");
            Ok(vec![1, 2, 3, 4])
        })
        .unwrap();
        assert_eq!((buffers, &doc.as_json().extensions_required[..]), (vec![vec![1, 2, 3, 4]], &looks.map(String::from)[..]));
    }

    /// The capsule's axis in the frame of the points.
    fn axis(g: &Geometry) -> Vector3<f32> {
        g.origin.rotation * Vector3::z()
    }

    #[test]
    fn a_blob_takes_the_bones_direction_and_a_limb_its_own() {
        // A blob: a slightly squashed box of points (sides 1 : 0.95 : 0.9) tilted about x, as a chest
        // can be. PCA alone picks the tilted axis; the bone's direction (along x) is taken instead.
        let tilt = UnitQuaternion::from_euler_angles(0.4, 0.0, 0.0);
        let mut blob = Vec::new();
        for i in 0..10 {
            for j in 0..10 {
                for k in 0..10 {
                    let c = |n: i32, s: f32| s * (n as f32 / 9.0 - 0.5);
                    blob.push(Point3::from(tilt * Vector3::new(c(i, 0.95), c(j, 0.9), c(k, 1.0))));
                }
            }
        }
        let free = fit_capsule(&blob, None).expect("capsule");
        assert!(axis(&free).y.abs() > 0.3, "{:?}", axis(&free));
        let along = fit_capsule(&blob, Some(Vector3::new(2.0, 0.0, 0.0))).expect("capsule");
        assert!((axis(&along).x.abs() - 1.0).abs() < 1e-5, "{:?}", axis(&along));
        // A limb: points spread along z keep their own axis whatever the bone's direction.
        let limb: Vec<Point3<f32>> =
            (0..50).map(|k| Point3::new(0.02 * (k as f32).sin(), 0.02 * (k as f32).cos(), 0.01 * k as f32)).collect();
        let g = fit_capsule(&limb, Some(Vector3::new(1.0, 0.0, 0.0))).expect("capsule");
        assert!(axis(&g).z.abs() > 0.99, "{:?}", axis(&g));
    }

    #[test]
    fn percent_escapes_in_uris_are_decoded_and_anything_else_kept() {
        assert_eq!(percent_decode("Fox%20Body%2Ebin"), "Fox Body.bin");
        assert_eq!(percent_decode("%41"), "A");
        // Multi-byte UTF-8, and a byte that is not UTF-8 (replaced, not an error).
        assert_eq!(percent_decode("caf%C3%A9.bin"), "café.bin");
        assert_eq!(percent_decode("%FF"), "\u{FFFD}");
        // Not an escape: a percent sign at the end, one hex digit short, or not hex.
        assert_eq!(percent_decode("100%"), "100%");
        assert_eq!(percent_decode("x%4"), "x%4");
        assert_eq!(percent_decode("%zz%4g"), "%zz%4g");
        // An escape cut short inside a character of several bytes.
        assert_eq!(percent_decode("%a\u{e9}.bin"), "%a\u{e9}.bin");
        assert_eq!(percent_decode("%\u{e9}"), "%\u{e9}");
    }

    #[test]
    fn base64_decodes_either_alphabet_with_or_without_padding() {
        // RFC 4648's test vectors.
        for (text, b64) in [("", ""), ("f", "Zg=="), ("fo", "Zm8="), ("foo", "Zm9v"), ("foob", "Zm9vYg=="), ("fooba", "Zm9vYmE="), ("foobar", "Zm9vYmFy")] {
            assert_eq!(decode_base64(b64).as_deref(), Some(text.as_bytes()), "{b64}");
        }
        // Both alphabets' last two digits (62, 63), the other letters and digits, whitespace and no padding.
        assert_eq!(decode_base64("+/8").unwrap(), [0xFB, 0xFF]);
        assert_eq!(decode_base64("-_8").unwrap(), [0xFB, 0xFF]);
        assert_eq!(decode_base64("AZaz\n09").unwrap(), [0x01, 0x96, 0xB3, 0xD3]);
        assert_eq!(decode_base64("Zm9v\r\n YmFy").unwrap(), b"foobar");
        assert_eq!(decode_base64("Zm9*"), None);
        // A lone digit after whole groups holds no byte.
        assert_eq!(decode_base64("Zm9vY"), None);
    }

    #[test]
    fn the_rotation_of_a_scaled_matrix_is_its_polar_factor() {
        let r = UnitQuaternion::from_euler_angles(0.3, -1.1, 2.0);
        let m = r.to_rotation_matrix().matrix() * Matrix3::from_diagonal(&Vector3::new(300.0, 2.0, 0.5));
        let p = polar_rotation(&m).expect("a rotation");
        assert!(p.angle_to(&r) < 1e-4, "{}", p.angle_to(&r));
        // A tiny uniform scale is still a rotation; a flattened, mirrored or non-finite matrix is not.
        assert!(polar_rotation(&(r.to_rotation_matrix().matrix() * 1e-3)).unwrap().angle_to(&r) < 1e-4);
        assert!(polar_rotation(&Matrix3::from_diagonal(&Vector3::new(1.0, 1.0, 1e-8))).is_some());
        assert_eq!(polar_rotation(&Matrix3::from_diagonal(&Vector3::new(1.0, 1.0, 1e-10))), None);
        // Flat relative to its own size: a smallest scale under 1e-9 of the largest, however large.
        assert_eq!(polar_rotation(&Matrix3::from_diagonal(&Vector3::new(1e6, 1e6, 1e-4))), None);
        assert!(polar_rotation(&Matrix3::from_diagonal(&Vector3::new(1e6, 1e6, 1e-2))).is_some());
        assert_eq!(polar_rotation(&Matrix3::from_diagonal(&Vector3::new(1.0, 1.0, 0.0))), None);
        assert_eq!(polar_rotation(&Matrix3::from_diagonal(&Vector3::new(1.0, -1.0, 1.0))), None);
        assert_eq!(polar_rotation(&Matrix3::from_diagonal(&Vector3::new(1.0, f32::NAN, 1.0))), None);
    }

    #[test]
    fn placements_are_the_same_within_a_ten_thousandth_of_their_scale_and_distance() {
        let at = |scale: f32, x: f32| {
            let mut m = Matrix4::identity() * scale;
            m[(3, 3)] = 1.0;
            m[(0, 3)] = x;
            m
        };
        assert!(same_placement(&at(300.0, 0.0), &at(300.0, 0.0)));
        // The linear part: 300 ± 0.02 is within 1e-4 of 300, ± 0.04 is not.
        assert!(same_placement(&at(300.02, 0.0), &at(300.0, 0.0)));
        assert!(!same_placement(&at(300.04, 0.0), &at(300.0, 0.0)));
        // The translation: 1000 ± 0.09 is within 1e-4 of 1 + 1000, ± 0.12 is not; near the origin 1e-4
        // of one unit.
        assert!(same_placement(&at(1.0, 1000.09), &at(1.0, 1000.0)));
        assert!(!same_placement(&at(1.0, 1000.12), &at(1.0, 1000.0)));
        assert!(same_placement(&at(1.0, 0.00009), &at(1.0, 0.0)));
        assert!(!same_placement(&at(1.0, 0.00012), &at(1.0, 0.0)));
    }

    #[test]
    fn a_capsule_covers_the_core_of_its_points_from_the_5th_to_the_95th_percentile() {
        // A tube of radius 0.1 from z = 1 to 2: 101 rings of 8 points.
        let tube: Vec<Point3<f32>> = (0..=100)
            .flat_map(|k| {
                (0..8).map(move |a| {
                    let t = a as f32 * std::f32::consts::FRAC_PI_4;
                    Point3::new(0.1 * t.cos(), 0.1 * t.sin(), 1.0 + k as f32 / 100.0)
                })
            })
            .collect();
        let g = fit_capsule(&tube, None).expect("capsule");
        let Shape::Capsule { radius, length } = g.shape else { panic!("{:?}", g.shape) };
        // Rings 5 and 95 (of 0..=100) end the caps: 0.9 long, less two radii of 0.1.
        assert!((radius - 0.1).abs() < 1e-5, "{radius}");
        assert!((length - 0.7).abs() < 1e-4, "{length}");
        assert!((g.origin.translation.vector - Vector3::new(0.0, 0.0, 1.5)).norm() < 1e-4, "{}", g.origin.translation.vector);
        assert!(axis(&g).z.abs() > 1.0 - 1e-5, "{:?}", axis(&g));
        // Moved across its axis and along it, the capsule moves with the points.
        let shift = Vector3::new(2.0, -1.0, 0.5);
        let moved: Vec<Point3<f32>> = tube.iter().map(|p| p + shift).collect();
        let m = fit_capsule(&moved, None).expect("capsule");
        let Shape::Capsule { radius, length } = m.shape else { panic!("{:?}", m.shape) };
        assert!((radius - 0.1).abs() < 1e-4 && (length - 0.7).abs() < 1e-4, "{radius} {length}");
        assert!((m.origin.translation.vector - Vector3::new(2.0, -1.0, 2.0)).norm() < 1e-4, "{}", m.origin.translation.vector);
        assert!(axis(&m).z.abs() > 1.0 - 1e-5, "{:?}", axis(&m));
        // As many points again at its top end: the caps end at the new 5th and 95th percentiles (z 1.1
        // and 2), not around the points' mean (z 1.75).
        let mut top_heavy = tube.clone();
        top_heavy.extend(tube.iter().map(|p| Point3::new(p.x, p.y, 2.0)));
        let t = fit_capsule(&top_heavy, None).expect("capsule");
        let Shape::Capsule { length, .. } = t.shape else { panic!("{:?}", t.shape) };
        assert!((length - 0.7).abs() < 1e-4, "{length}");
        assert!((t.origin.translation.vector - Vector3::new(0.0, 0.0, 1.55)).norm() < 1e-4, "{}", t.origin.translation.vector);
        // More points on one side: the radius is their median distance from the axis, not the largest.
        let mut lopsided = tube.clone();
        lopsided.extend((0..=100).map(|k| Point3::new(0.3, 0.0, 1.0 + k as f32 / 100.0)));
        let Shape::Capsule { radius, .. } = fit_capsule(&lopsided, None).unwrap().shape else { unreachable!() };
        assert!(radius < 0.15, "{radius}");
        // A ring around its given axis is a flat capsule: as wide as the ring, of no length.
        let ring: Vec<Point3<f32>> = (0..16)
            .map(|a| {
                let t = a as f32 * std::f32::consts::PI / 8.0;
                Point3::new(t.cos(), t.sin(), 0.0)
            })
            .collect();
        let Shape::Capsule { radius, length } = fit_capsule(&ring, Some(Vector3::z())).unwrap().shape else { unreachable!() };
        assert!((radius - 1.0).abs() < 1e-5 && length == 0.0, "{radius} {length}");
        // A largest variance of exactly DISTINCT_AXIS times the next is distinct: the axis is the
        // principal one (x), not the one given.
        let cross: Vec<Point3<f32>> = [(1.0, 0.0, 3), (-1.0, 0.0, 3), (0.0, 1.0, 2), (0.0, -1.0, 2)]
            .into_iter()
            .flat_map(|(x, y, k)| std::iter::repeat_n(Point3::new(x, y, 0.0), k))
            .collect();
        assert_eq!(DISTINCT_AXIS, 1.5);
        assert!(axis(&fit_capsule(&cross, Some(Vector3::z())).unwrap()).x.abs() > 0.99);
        // Fewer than four points have no capsule.
        assert_eq!(fit_capsule(&tube[..3], None), None);
        assert!(fit_capsule(&tube[..4], None).is_some());
    }
}
