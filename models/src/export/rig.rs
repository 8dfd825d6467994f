//! A retargeted clip written onto a rigged glTF creature's own skeleton: the artist's model comes out
//! as it went in (meshes, skins, materials, textures, images, samplers, every node) with the clip as a
//! new animation on its joint nodes, ready for Blender, three.js or Bevy.
//!
//! Decisions, documented once:
//! - **Pose → bone nodes.** The tree's poses become the bones' local transforms in the file's own frame
//!   and units through [`crate::character::rig_pose`] (the conversion the Bevy plugin uses too): see its
//!   docs for the inverse of the import and which nodes move. A rotation channel goes on every driven
//!   bone, a translation channel too on those that translate (root motion on the body root's node,
//!   deforming helpers); bones held at rest keep their node transform, unless the import moved them to
//!   the skin's bind pose, where a constant channel holds them. Every channel has one LINEAR key
//!   per pose at `k / fps` s; rotations stay in one hemisphere from key to key. A keyed node that the
//!   file places by a matrix gets the matrix's translation, rotation and scale instead, as glTF asks.
//! - **One buffer.** The file's buffers (a GLB's binary chunk, data URIs, `.bin` files beside a
//!   `.gltf`) and its external or data-URI images are laid end to end in the GLB's one binary chunk, so
//!   the output stands alone wherever it is written. The model's own animations are dropped unless
//!   [`RigClipOptions::keep_animations`], and with them the accessors, buffer views and bytes only they
//!   used (unless an extension such as mesh compression might point at those, then the data stays).
//! - **Animation only** ([`RigClipOptions::animation_only`]): the skin's joints and their ancestors
//!   with their rest transforms, the skin (joints and inverse bind matrices, so that a DCC tool builds
//!   an armature) and the clip; no meshes, materials or images.

use std::path::Path;

use gltf_json as json;
use json::Index;
use json::animation::Property;
use json::validation::USize64;
use nalgebra::{UnitQuaternion, Vector3};

use super::writer::{Builder, glb, quat_values, vec3_values};
use super::{ExportError, ExportProblem, check_poses, write_model};
use crate::character::Creature;
use crate::character::gltf::{decode_base64, open, percent_decode, read_beside};
use crate::character::rig_pose::{NodeTransform, RigMismatch, RigPose, RigScratch};
use crate::kinematics::CharacterPose;

/// Name of the clip's animation when [`RigClipOptions::name`] gives none.
pub const DEFAULT_CLIP_NAME: &str = "retargeted";

/// Options of [`rig_clip_glb`].
#[derive(Clone, Debug, Default)]
pub struct RigClipOptions {
    /// Name of the new animation; default [`DEFAULT_CLIP_NAME`].
    pub name: Option<String>,
    /// Keep the model's own animations beside the new one (the new one comes last).
    pub keep_animations: bool,
    /// Write only the skeleton, its skin and the clip (see the module docs); `keep_animations` is then
    /// moot.
    pub animation_only: bool,
}

/// A rig clip in memory.
#[derive(Clone, Debug)]
pub struct RigClipOutput {
    /// The `.glb` file's bytes.
    pub bytes: Vec<u8>,
    /// Nodes the clip animates.
    pub animated_nodes: usize,
}

/// Writes `poses` (one per frame, `fps` frames per second, in the tree of `creature`) as a new
/// animation on the creature's own model, read again from the file it was loaded from
/// ([`crate::kinematics::KinematicTree::source`]). See the module docs. Errors name `<rig clip of NAME
/// in memory>`.
pub fn rig_clip_glb(
    creature: &Creature,
    poses: &[CharacterPose],
    fps: f32,
    opts: &RigClipOptions,
) -> Result<RigClipOutput, ExportError> {
    build(creature, poses, fps, opts).map_err(|p| p.in_file(format!("<rig clip of {} in memory>", creature.tree.name)))
}

/// [`rig_clip_glb`] written atomically to `path` (see [`write_model`]: JSON for a `.gltf` name). Errors name `path`.
pub fn write_rig_clip(
    path: &Path,
    creature: &Creature,
    poses: &[CharacterPose],
    fps: f32,
    opts: &RigClipOptions,
) -> Result<RigClipOutput, ExportError> {
    let out = build(creature, poses, fps, opts).map_err(|p| p.in_file(path.display().to_string()))?;
    write_model(path, &out.bytes)?;
    Ok(out)
}

/// The file's node hierarchy (parents), for the skeleton-only output.
struct Hierarchy {
    parent: Vec<Option<usize>>,
}

fn build(
    c: &Creature,
    poses: &[CharacterPose],
    fps: f32,
    opts: &RigClipOptions,
) -> Result<RigClipOutput, ExportProblem> {
    check_poses(&c.tree, poses, fps)?;
    let source = c.tree.source.as_deref().ok_or(ExportProblem::NoSource)?;
    let model = source.display().to_string();
    let (doc, buffers) = open(source)?;
    if doc.skins().len() == 0 {
        return Err(ExportProblem::NoSkin { model });
    }
    let not_it = |e: RigMismatch| ExportProblem::NotTheCreature { model: model.clone(), why: e.0 };
    let rig_pose = RigPose::new(c, &doc).map_err(not_it)?;
    let h = hierarchy(&doc);
    let driven = rig_pose.driven();
    let tracks = tracks(c, &rig_pose, poses).map_err(not_it)?;

    let (mut b, map) = if opts.animation_only {
        skeleton(&doc, &buffers, c, &h)
    } else {
        let b = whole_model(&doc, buffers, source, opts.keep_animations, &model)?;
        (b, (0..h.parent.len()).map(Some).collect())
    };
    let times: Vec<f32> = (0..poses.len()).map(|k| k as f32 / fps).collect();
    let input = b.floats(&times, 1, None, true);
    for (d, (t, r)) in driven.iter().zip(&tracks) {
        let node = map[d.node].expect("the skeleton keeps every bone");
        if d.translates {
            b.channel(node, Property::Translation, input, &vec3_values(t));
        }
        b.channel(node, Property::Rotation, input, &quat_values(r));
    }
    // Nodes whose rest is not the transform the file gives them (joints the import moved to the
    // skin's bind pose): the clip holds them there, on each property it does not animate already.
    let held = rig_pose.held().iter().map(|(i, _)| (*i, None));
    for (i, d) in driven.iter().map(|d| (d.node, Some(d))).chain(held) {
        let (Some(node), Some(file)) = (map[i], doc.nodes().nth(i)) else { continue };
        let (rest, file) = (rig_pose.rest(i), NodeTransform::of(&file));
        let frames = poses.len();
        if !d.is_some_and(|d| d.translates) && !near(&rest.translation, &file.translation) {
            b.channel(node, Property::Translation, input, &vec3_values(&vec![rest.translation; frames]));
        }
        if d.is_none() && rest.rotation.angle_to(&file.rotation) > 1e-6 {
            b.channel(node, Property::Rotation, input, &quat_values(&vec![rest.rotation; frames]));
        }
        if !near(&rest.scale, &file.scale) {
            b.channel(node, Property::Scale, input, &vec3_values(&vec![rest.scale; frames]));
        }
    }
    let (mut root, bin) = b.finish(opts.name.as_deref().unwrap_or(DEFAULT_CLIP_NAME));
    trs_for_animated(&mut root);
    root.asset.generator = Some(concat!("ace_models ", env!("CARGO_PKG_VERSION")).into());
    Ok(RigClipOutput {
        bytes: glb(&root, &bin)?,
        animated_nodes: driven.len(),
    })
}

/// glTF keys only nodes placed by a translation, a rotation and a scale: a node the file places by a
/// matrix gets the matrix's decomposition instead (the one the import read it with) when a channel
/// targets it.
fn trs_for_animated(root: &mut json::Root) {
    let targets: Vec<usize> = root.animations.iter().flat_map(|a| &a.channels).map(|c| c.target.node.value()).collect();
    for i in targets {
        let node = &mut root.nodes[i];
        if let Some(m) = node.matrix.take() {
            let columns = std::array::from_fn(|c| std::array::from_fn(|r| m[4 * c + r]));
            let (t, r, s) = ::gltf::scene::Transform::Matrix { matrix: columns }.decomposed();
            node.translation = Some(t);
            node.rotation = Some(json::scene::UnitQuaternion(r));
            node.scale = Some(s);
        }
    }
}

/// Whether two translations or scales are the same to float precision.
fn near(a: &Vector3<f32>, b: &Vector3<f32>) -> bool {
    (a - b).abs().max() <= 1e-6 * (1.0 + a.abs().max())
}

/// The parent of each of the file's nodes (checked for one parent each and no cycle by [`RigPose::new`]).
fn hierarchy(doc: &::gltf::Document) -> Hierarchy {
    let mut parent = vec![None; doc.nodes().len()];
    for nd in doc.nodes() {
        for ch in nd.children() {
            parent[ch.index()] = Some(nd.index());
        }
    }
    Hierarchy { parent }
}

/// Per driven bone, its local translation and rotation in every frame (file frame and units).
#[allow(clippy::type_complexity)]
fn tracks(
    c: &Creature,
    rig_pose: &RigPose,
    poses: &[CharacterPose],
) -> Result<Vec<(Vec<Vector3<f32>>, Vec<UnitQuaternion<f32>>)>, RigMismatch> {
    let n = rig_pose.driven().len();
    let mut out: Vec<_> = (0..n).map(|_| (Vec::with_capacity(poses.len()), Vec::with_capacity(poses.len()))).collect();
    let (mut scratch, mut locals) = (RigScratch::default(), Vec::new());
    for pose in poses {
        rig_pose.write(&c.tree, pose, &mut scratch, &mut locals)?;
        for (o, l) in out.iter_mut().zip(&locals) {
            o.0.push(l.translation);
            o.1.push(l.rotation);
        }
    }
    Ok(out)
}

/// The whole model: the file's document with its buffers and images in one binary buffer, and its own
/// animations unless `keep_animations` is false.
fn whole_model(
    doc: &::gltf::Document,
    buffers: Vec<Vec<u8>>,
    source: &Path,
    keep_animations: bool,
    model: &str,
) -> Result<Builder, ExportProblem> {
    let mut root = doc.as_json().clone();
    let mut bin = Vec::new();
    let mut base = Vec::with_capacity(buffers.len());
    for data in buffers {
        bin.resize(bin.len().next_multiple_of(4), 0);
        base.push(bin.len() as u64);
        bin.extend_from_slice(&data);
    }
    for v in &mut root.buffer_views {
        let offset = v.byte_offset.map_or(0, |o| o.0) + base[v.buffer.value()];
        v.byte_offset = Some(USize64(offset));
        v.buffer = Index::new(0);
    }
    root.buffers.truncate(1);
    if !keep_animations {
        root.animations.clear();
        bin = drop_unused_data(&mut root, bin);
    }
    let images = std::mem::take(&mut root.images);
    let mut b = Builder::new(root, bin);
    for (index, mut image) in images.into_iter().enumerate() {
        if let Some(uri) = image.uri.take() {
            let fail = |reason: String| ExportProblem::Image { model: model.to_owned(), index, reason };
            let (bytes, declared) = image_bytes(&uri, source).map_err(fail)?;
            let mime = image
                .mime_type
                .as_ref()
                .map(|m| m.0.clone())
                .or(declared)
                .or_else(|| sniff_image(&bytes).map(str::to_owned))
                .ok_or_else(|| fail("neither its URI nor its bytes say which image format it is".into()))?;
            image.buffer_view = Some(b.view(&bytes, None));
            image.mime_type = Some(json::image::MimeType(mime));
        }
        b.root.push(image);
    }
    Ok(b)
}

/// Extensions (by prefix) that point at no accessor or buffer view: a document using only these can
/// have its accessors and buffer views renumbered.
const RENUMBERABLE: [&str; 7] = [
    "KHR_materials_",
    "KHR_texture_transform",
    "KHR_lights_punctual",
    "KHR_mesh_quantization",
    "KHR_texture_basisu",
    "EXT_texture_webp",
    "EXT_texture_avif",
];

/// Drops the accessors nothing refers to any more (those of the dropped animations) and the buffer
/// views and bytes only they used, renumbering the rest; `bin` is buffer 0, the only one. Documents
/// using an extension that might point at accessors or buffer views (mesh compression, instancing)
/// are left as they are.
fn drop_unused_data(root: &mut json::Root, bin: Vec<u8>) -> Vec<u8> {
    if root.extensions_used.iter().any(|e| !RENUMBERABLE.iter().any(|p| e.starts_with(p))) {
        return bin;
    }
    let mut used = vec![false; root.accessors.len()];
    accessor_refs(root, &mut |a| used[a.value()] = true);
    let map = renumber(&used);
    let accessors = std::mem::take(&mut root.accessors);
    root.accessors = accessors.into_iter().zip(&used).filter(|(_, u)| **u).map(|(a, _)| a).collect();
    accessor_refs(root, &mut |a| *a = Index::new(map[a.value()]));

    let mut used = vec![false; root.buffer_views.len()];
    view_refs(root, &mut |v| used[v.value()] = true);
    let map = renumber(&used);
    let views = std::mem::take(&mut root.buffer_views);
    let mut out = Vec::with_capacity(bin.len());
    for (mut v, _) in views.into_iter().zip(&used).filter(|(_, u)| **u) {
        let start = v.byte_offset.map_or(0, |o| o.0) as usize;
        let end = (start + v.byte_length.0 as usize).min(bin.len());
        // The same offset modulo 4 as before, so that every accessor stays aligned to its components.
        while out.len() % 4 != start % 4 {
            out.push(0);
        }
        v.byte_offset = Some(USize64::from(out.len()));
        out.extend_from_slice(&bin[start.min(end)..end]);
        root.buffer_views.push(v);
    }
    view_refs(root, &mut |v| *v = Index::new(map[v.value()]));
    out
}

/// New index of each kept object (`used`), counting kept objects only.
fn renumber(used: &[bool]) -> Vec<u32> {
    let mut next = 0;
    used.iter()
        .map(|&u| {
            let i = next;
            next += u32::from(u);
            i
        })
        .collect()
}

/// Visits every reference to an accessor: mesh attributes, indices and morph targets, inverse bind
/// matrices, animation samplers.
fn accessor_refs(root: &mut json::Root, f: &mut dyn FnMut(&mut Index<json::Accessor>)) {
    for p in root.meshes.iter_mut().flat_map(|m| m.primitives.iter_mut()) {
        p.attributes.values_mut().for_each(&mut *f);
        p.indices.iter_mut().for_each(&mut *f);
        for t in p.targets.iter_mut().flatten() {
            t.positions.iter_mut().chain(t.normals.iter_mut()).chain(t.tangents.iter_mut()).for_each(&mut *f);
        }
    }
    root.skins.iter_mut().filter_map(|s| s.inverse_bind_matrices.as_mut()).for_each(&mut *f);
    for s in root.animations.iter_mut().flat_map(|a| a.samplers.iter_mut()) {
        f(&mut s.input);
        f(&mut s.output);
    }
}

/// Visits every reference to a buffer view: accessors (sparse ones included) and images.
fn view_refs(root: &mut json::Root, f: &mut dyn FnMut(&mut Index<json::buffer::View>)) {
    for a in &mut root.accessors {
        a.buffer_view.iter_mut().for_each(&mut *f);
        if let Some(s) = &mut a.sparse {
            f(&mut s.indices.buffer_view);
            f(&mut s.values.buffer_view);
        }
    }
    root.images.iter_mut().filter_map(|i| i.buffer_view.as_mut()).for_each(&mut *f);
}

/// The bytes of an image URI (a data URI, or a file beside `source`) and the MIME type a data URI
/// declares.
fn image_bytes(uri: &str, source: &Path) -> Result<(Vec<u8>, Option<String>), String> {
    if let Some(rest) = uri.strip_prefix("data:") {
        let (head, data) = rest.split_once(";base64,").ok_or("only base64 data URIs are read")?;
        let bytes = decode_base64(data).ok_or("invalid base64")?;
        return Ok((bytes, (!head.is_empty()).then(|| head.to_owned())));
    }
    Ok((read_beside(source, &percent_decode(uri))?, None))
}

/// The MIME type of image bytes by their signature (the formats glTF and its extensions embed).
fn sniff_image(b: &[u8]) -> Option<&'static str> {
    if b.starts_with(b"\x89PNG\r\n\x1a\n") {
        Some("image/png")
    } else if b.starts_with(&[0xFF, 0xD8, 0xFF]) {
        Some("image/jpeg")
    } else if b.len() >= 12 && &b[0..4] == b"RIFF" && &b[8..12] == b"WEBP" {
        Some("image/webp")
    } else if b.starts_with(b"\xABKTX 20\xBB") {
        Some("image/ktx2")
    } else {
        None
    }
}

/// The skeleton alone: the skin's joints and their ancestors (rest transforms, names, extras), the
/// skin the creature was built from, one scene. Returns the builder and the new index of each kept node.
fn skeleton(doc: &::gltf::Document, buffers: &[Vec<u8>], c: &Creature, h: &Hierarchy) -> (Builder, Vec<Option<usize>>) {
    let src = doc.as_json();
    let n = h.parent.len();
    let mut keep = vec![false; n];
    for bone in &c.rig.bones {
        let mut i = Some(bone.node);
        while let Some(k) = i.filter(|&k| !keep[k]) {
            keep[k] = true;
            i = h.parent[k];
        }
    }
    let mut map = vec![None; n];
    let mut count = 0;
    for i in 0..n {
        if keep[i] {
            map[i] = Some(count);
            count += 1;
        }
    }
    let remap = |i: Index<json::Node>| map[i.value()].map(|k| Index::new(k as u32));
    let mut root = json::Root {
        asset: src.asset.clone(),
        ..Default::default()
    };
    for nd in src.nodes.iter().enumerate().filter(|(i, _)| keep[*i]).map(|(_, nd)| nd) {
        let children: Vec<Index<json::Node>> = nd.children.iter().flatten().filter_map(|&ch| remap(ch)).collect();
        root.push(json::Node {
            name: nd.name.clone(),
            matrix: nd.matrix,
            translation: nd.translation,
            rotation: nd.rotation,
            scale: nd.scale,
            children: (!children.is_empty()).then_some(children),
            extras: nd.extras.clone(),
            ..Default::default()
        });
    }
    let roots = (0..n).filter(|&i| keep[i] && h.parent[i].is_none_or(|p| !keep[p]));
    let scene_name = doc.default_scene().or_else(|| doc.scenes().next()).and_then(|s| s.name().map(str::to_owned));
    let scene = root.push(json::Scene {
        extensions: None,
        extras: Default::default(),
        name: scene_name,
        nodes: roots.map(|i| Index::new(map[i].expect("kept") as u32)).collect(),
    });
    root.scene = Some(scene);
    let mut b = Builder::new(root, Vec::new());
    let used = c.rig.skins.iter().position(|s| s.used).unwrap_or(0);
    if let Some(skin) = doc.skins().nth(used) {
        let ibm: Option<Vec<f32>> = skin
            .reader(|buf| buffers.get(buf.index()).map(Vec::as_slice))
            .read_inverse_bind_matrices()
            .map(|it| it.flat_map(|m| m.into_iter().flatten()).collect());
        let inverse_bind_matrices = ibm.map(|m| b.floats(&m, 16, None, false));
        let joints = skin.joints().filter_map(|j| map[j.index()].map(|k| Index::new(k as u32))).collect();
        b.root.push(json::Skin {
            extensions: None,
            extras: Default::default(),
            inverse_bind_matrices,
            joints,
            name: skin.name().map(str::to_owned),
            skeleton: skin.skeleton().and_then(|s| map[s.index()]).map(|k| Index::new(k as u32)),
        });
    }
    (b, map)
}
