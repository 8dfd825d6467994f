//! Clips written onto the shared rigged creatures' own models (`../shared/data/creatures`; set
//! `ACE_ALLOW_MISSING_DATA=1` to skip when absent): Khronos' validator accepts every variant, the model
//! comes out whole (from several buffers into one, without its own clips' data unless kept), the clip
//! keys only what the nodes do not already hold, the skeleton in the file moves as the tree does, the
//! creature's own clips come back through `clip_poses`, and bad inputs get errors that name the file.

mod common;
use common::{creatures, khronos_validate};

use std::path::{Path, PathBuf};

use ace_models::character::clips::clip_poses;
use ace_models::character::gltf::{Facing, open, polar_rotation, read};
use ace_models::character::{Creature, load_creature};
use ace_models::export::{ExportProblem, RigClipOptions, rig_clip_glb, write_rig_clip};
use ace_models::kinematics::CharacterPose;
use gltf::animation::util::ReadOutputs;
use nalgebra::{Isometry3, Matrix4, Quaternion, Translation3, UnitQuaternion, Vector3};

const FPS: f32 = 30.0;

/// The five shared creatures.
const SHARED: [&str; 5] = [
    "Fox/Fox.glb",
    "Quaternius_Wolf/Wolf.gltf",
    "Quaternius_Spider/Spider.glb",
    "Quaternius_TRex/t-rex.glb",
    "Quaternius_Snake/Snake.glb",
];

fn tmp(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("ace-rig-export-{}-{name}", std::process::id()));
    std::fs::create_dir_all(&d).unwrap();
    d
}

fn load(path: &Path) -> Creature {
    load_creature(path).unwrap_or_else(|e| panic!("{e}"))
}

/// The creature's largest extent at rest (m).
fn size(c: &Creature) -> f32 {
    let fk = c.tree.forward_kinematics(&c.tree.neutral_pose(Isometry3::identity()));
    c.tree.aabb(&fk).half_extents().max() * 2.0
}

/// The creature's first clip with root motion on top: it walks forward while turning, so that the
/// root's translation and rotation both change from frame to frame.
fn turning_clip(c: &Creature) -> Vec<CharacterPose> {
    let s = size(c);
    clip_poses(c, 0, FPS)
        .into_iter()
        .enumerate()
        .map(|(k, mut p)| {
            let t = k as f32 / FPS;
            let turn = Isometry3::from_parts(
                Translation3::new(0.5 * s * t, 0.2 * s * (2.0 * t).sin(), 0.0),
                UnitQuaternion::from_euler_angles(0.0, 0.0, 0.9 * t),
            );
            p.root = turn * p.root;
            p
        })
        .collect()
}

/// A GLB read back with the `gltf` crate, and every buffer's bytes (its binary chunk).
struct Readback {
    doc: gltf::Document,
    blob: Vec<u8>,
}

impl Readback {
    fn new(bytes: &[u8]) -> Self {
        let g = gltf::Gltf::from_slice(bytes).unwrap_or_else(|e| panic!("the gltf crate rejects the GLB: {e}"));
        assert_eq!(g.document.buffers().count(), 1, "one buffer, the binary chunk");
        Readback { doc: g.document, blob: g.blob.expect("a binary chunk") }
    }

    /// Animation `anim` keys only what the nodes do not already hold: one channel per node and
    /// property, and a translation or scale channel that keeps one value over the clip (a node held at
    /// a rest the import moved it to) holds one that differs from the node's own beyond float precision
    /// (1e-6 of its size). Returns the number of channels.
    fn assert_no_idle_channels(&self, anim: usize, file: &str) -> usize {
        let a = self.doc.animations().nth(anim).unwrap();
        let mut seen = std::collections::HashSet::new();
        for ch in a.channels() {
            let node = ch.target().node();
            let what = format!("{file}: node {:?} {:?}", node.name(), ch.target().property());
            assert!(seen.insert(what.clone()), "{what} is keyed twice");
            let (t, _, s) = node.transform().decomposed();
            let (values, own): (Vec<[f32; 3]>, _) = match ch.reader(|_| Some(&self.blob[..])).read_outputs().unwrap() {
                ReadOutputs::Translations(v) => (v.collect(), t),
                ReadOutputs::Scales(v) => (v.collect(), s),
                _ => continue,
            };
            if values.iter().all(|v| *v == values[0]) {
                let (v, own) = (Vector3::from(values[0]), Vector3::from(own));
                assert!((v - own).abs().max() > 1e-6 * (1.0 + v.abs().max()), "{what} holds {v:?}, which the node has already");
            }
        }
        seen.len()
    }

    /// Every node's world matrix at key `k` of animation `anim` (the other nodes at their node
    /// transforms).
    fn worlds_at(&self, anim: usize, k: usize) -> Vec<Matrix4<f32>> {
        let nodes: Vec<_> = self.doc.nodes().collect();
        let mut trs: Vec<_> = nodes.iter().map(|n| n.transform().decomposed()).collect();
        let a = self.doc.animations().nth(anim).unwrap();
        for ch in a.channels() {
            let r = ch.reader(|_| Some(&self.blob[..]));
            let i = ch.target().node().index();
            match r.read_outputs().unwrap() {
                ReadOutputs::Translations(mut t) => trs[i].0 = t.nth(k).unwrap(),
                ReadOutputs::Rotations(q) => trs[i].1 = q.into_f32().nth(k).unwrap(),
                ReadOutputs::Scales(mut s) => trs[i].2 = s.nth(k).unwrap(),
                ReadOutputs::MorphTargetWeights(_) => panic!("no morph target weights are written"),
            }
        }
        let mut parent = vec![None; nodes.len()];
        for n in &nodes {
            for ch in n.children() {
                parent[ch.index()] = Some(n.index());
            }
        }
        (0..nodes.len())
            .map(|mut i| {
                let local = |i: usize| {
                    let (t, q, s) = trs[i];
                    Matrix4::new_translation(&Vector3::from(t))
                        * UnitQuaternion::from_quaternion(Quaternion::new(q[3], q[0], q[1], q[2])).to_homogeneous()
                        * Matrix4::new_nonuniform_scaling(&Vector3::from(s))
                };
                let mut m = local(i);
                while let Some(p) = parent[i] {
                    m = local(p) * m;
                    i = p;
                }
                m
            })
            .collect()
    }

    /// The positions of every primitive of every mesh, in order.
    fn positions(doc: &gltf::Document, buffers: &[&[u8]]) -> Vec<Vec<[f32; 3]>> {
        doc.meshes()
            .flat_map(|m| m.primitives().collect::<Vec<_>>())
            .map(|p| p.reader(|b| Some(buffers[b.index()])).read_positions().unwrap().collect())
            .collect()
    }
}

/// Every bone that has a link in the tree sits, in the file at key `k` of animation `anim`, where forward
/// kinematics puts its link: position within `tol` (m), rotation within 1e-3 rad. Returns the largest
/// position error.
fn assert_bones_follow_the_tree(
    c: &Creature,
    rb: &Readback,
    anim: usize,
    k: usize,
    pose: &CharacterPose,
    tol: f32,
) -> f32 {
    let worlds = rb.worlds_at(anim, k);
    let fk = c.tree.forward_kinematics(pose);
    let to_char = c.rig.to_character;
    let mut worst = 0.0f32;
    let mut checked = 0;
    for node in rb.doc.nodes() {
        let Some(name) = node.name() else { continue };
        let Some(l) = c.tree.link_index(name) else { continue };
        if !c.rig.bones.iter().any(|b| b.name == name) {
            continue;
        }
        let m = &worlds[node.index()];
        let p = to_char * m.fixed_view::<3, 1>(0, 3).into_owned() * c.scale;
        let r = polar_rotation(&(to_char.matrix() * m.fixed_view::<3, 3>(0, 0))).unwrap();
        let err = (p - fk[l].translation.vector).norm();
        worst = worst.max(err);
        assert!(err <= tol, "{name} key {k}: at {p:?}, the tree puts it at {:?}", fk[l].translation.vector);
        let angle = r.angle_to(&fk[l].rotation);
        assert!(angle <= 1e-3, "{name} key {k}: turned {angle} rad away from the tree's pose");
        checked += 1;
    }
    assert!(checked >= 4, "{checked} bones checked");
    worst
}

#[test]
fn rig_clips_of_the_shared_creatures_validate_and_keep_the_model() {
    let Some(dir) = creatures() else { return };
    let out = tmp("validate");
    for file in SHARED {
        let path = dir.join(file);
        let c = load(&path);
        let poses = turning_clip(&c);
        let s = size(&c);
        let (src, src_buffers) = open(&path).unwrap();
        let src_buffers: Vec<&[u8]> = src_buffers.iter().map(Vec::as_slice).collect();
        let stem = Path::new(file).file_stem().unwrap().to_string_lossy().into_owned();
        for (tag, keep, only) in [("clip", false, false), ("keep", true, false), ("only", false, true)] {
            let opts = RigClipOptions { name: Some("turning".into()), keep_animations: keep, animation_only: only };
            let target = out.join(format!("{stem}_{tag}.glb"));
            let w = write_rig_clip(&target, &c, &poses, FPS, &opts).unwrap_or_else(|e| panic!("{e}"));
            assert_eq!(std::fs::read(&target).unwrap(), w.bytes);
            if let Some(issues) = khronos_validate(&target) {
                // Without the model's own animations, their accessors and buffer views are gone too.
                let unused: Vec<&str> = issues["messages"]
                    .as_array()
                    .unwrap()
                    .iter()
                    .filter(|m| m["code"] == "UNUSED_OBJECT")
                    .filter_map(|m| m["pointer"].as_str())
                    .filter(|p| p.starts_with("/accessors") || p.starts_with("/bufferViews"))
                    .collect();
                assert!(unused.is_empty(), "{file} {tag}: unused {unused:?}");
            }
            let rb = Readback::new(&w.bytes);
            let d = &rb.doc;
            let own = src.animations().count();
            let anims = if keep { own + 1 } else { 1 };
            assert_eq!(d.animations().count(), anims, "{file} {tag}");
            let new = d.animations().last().unwrap();
            assert_eq!(new.name(), Some("turning"));
            let keys = new.channels().next().unwrap().reader(|_| Some(&rb.blob[..])).read_inputs().unwrap().count();
            assert_eq!(keys, poses.len());
            if keep {
                let names: Vec<_> = d.animations().take(own).map(|a| a.name().map(str::to_owned)).collect();
                let src_names: Vec<_> = src.animations().map(|a| a.name().map(str::to_owned)).collect();
                assert_eq!(names, src_names, "{file}: the model's own clips are kept, in order");
            }
            if only {
                assert_eq!(d.meshes().count(), 0);
                assert_eq!(d.materials().count(), 0);
                assert_eq!(d.images().count(), 0);
                assert_eq!(d.skins().count(), 1, "{file}: the skin, for DCC tools to build an armature");
                let joints: Vec<_> = d.skins().next().unwrap().joints().map(|j| j.name().map(str::to_owned)).collect();
                let used = src.skins().nth(c.rig.skins.iter().position(|s| s.used).unwrap()).unwrap();
                let src_joints: Vec<_> = used.joints().map(|j| j.name().map(str::to_owned)).collect();
                assert_eq!(joints, src_joints, "{file}: the skin's joints, in order");
                assert!(d.nodes().count() >= c.rig.bones.len() && d.nodes().count() < src.nodes().count());
            } else {
                // The model comes out whole: every object of the source, the mesh data and the images
                // byte for byte.
                assert_eq!(d.meshes().count(), src.meshes().count(), "{file}");
                assert_eq!(d.skins().count(), src.skins().count(), "{file}");
                assert_eq!(d.materials().count(), src.materials().count(), "{file}");
                assert_eq!(d.textures().count(), src.textures().count(), "{file}");
                assert_eq!(d.images().count(), src.images().count(), "{file}");
                assert_eq!(d.samplers().count(), src.samplers().count(), "{file}");
                assert_eq!(d.nodes().count(), src.nodes().count(), "{file}");
                let names: Vec<_> = d.nodes().map(|n| n.name().map(str::to_owned)).collect();
                let src_names: Vec<_> = src.nodes().map(|n| n.name().map(str::to_owned)).collect();
                assert_eq!(names, src_names, "{file}");
                assert_eq!(
                    Readback::positions(d, &[&rb.blob]),
                    Readback::positions(&src, &src_buffers),
                    "{file}: mesh positions"
                );
                for (a, b) in d.images().zip(src.images()) {
                    let bytes = |img: &gltf::Image, bufs: &[&[u8]]| match img.source() {
                        gltf::image::Source::View { view, .. } => {
                            bufs[view.buffer().index()][view.offset()..view.offset() + view.length()].to_vec()
                        }
                        gltf::image::Source::Uri { .. } => panic!("images are embedded"),
                    };
                    assert_eq!(bytes(&a, &[&rb.blob]), bytes(&b, &src_buffers), "{file}: image {}", a.index());
                }
            }
            // The skeleton in the file moves as the tree does, root motion included.
            let mut worst = 0.0f32;
            for k in [0, poses.len() / 3, poses.len() - 1] {
                worst = worst.max(assert_bones_follow_the_tree(&c, &rb, anims - 1, k, &poses[k], 1e-4 * s));
            }
            let channels = rb.assert_no_idle_channels(anims - 1, file);
            let (animated, worst) = (w.animated_nodes, worst / s);
            eprintln!("{file} {tag}: {animated} bones animated ({channels} channels), worst bone position error {worst:.2e} of the size");
        }
    }
    let _ = std::fs::remove_dir_all(out);
}

/// The shared Wolf's glTF document as JSON, to be edited into files the shared creatures are not.
/// An output named `.gltf` (any case) is glTF's JSON form, one file with its data embedded, for the
/// creature's own model and for a robot alike; it once held the GLB container under that name. Read
/// back, it is the same document and data as the `.glb`, and Khronos' validator accepts it.
#[test]
fn an_output_named_gltf_is_the_json_form_with_the_same_model() {
    use ace_models::export::{GltfOptions, write_glb};
    use ace_models::kinematics::KinematicTree;
    let out = tmp("json-form");
    let same = |glb: &Path, text: &Path| {
        let bytes = std::fs::read(text).unwrap();
        assert!(bytes.starts_with(b"{") && serde_json::from_slice::<serde_json::Value>(&bytes).is_ok(), "{} is JSON", text.display());
        let ((a, abuf), (b, bbuf)) = (open(glb).unwrap(), open(text).unwrap());
        let mut b_json = b.as_json().clone();
        assert!(b_json.buffers[0].uri.as_deref().is_some_and(|u| u.starts_with("data:application/octet-stream;base64,")));
        b_json.buffers[0].uri = None;
        assert_eq!(serde_json::to_value(a.as_json()).unwrap(), serde_json::to_value(&b_json).unwrap());
        assert_eq!(abuf, bbuf);
        khronos_validate(text);
    };
    if let Some(dir) = creatures() {
        let c = load(&dir.join("Fox/Fox.glb"));
        let poses = turning_clip(&c);
        for name in ["fox.glb", "fox.GLTF"] {
            write_rig_clip(&out.join(name), &c, &poses, FPS, &RigClipOptions::default()).unwrap_or_else(|e| panic!("{e}"));
        }
        same(&out.join("fox.glb"), &out.join("fox.GLTF"));
    }
    let spot = KinematicTree::from_urdf_file(&Path::new(env!("CARGO_MANIFEST_DIR")).join("../assets/characters/spot.urdf")).unwrap();
    let poses = vec![spot.standing_pose(); 3];
    for name in ["spot.glb", "spot.gltf"] {
        write_glb(&out.join(name), &spot, &poses, FPS, &GltfOptions::default()).unwrap_or_else(|e| panic!("{e}"));
    }
    same(&out.join("spot.glb"), &out.join("spot.gltf"));
}

fn wolf_json(dir: &Path) -> serde_json::Value {
    serde_json::from_slice(&std::fs::read(dir.join("Quaternius_Wolf/Wolf.gltf")).unwrap()).unwrap()
}

/// Accessors of `doc` that nothing refers to (meshes, skins, animations).
fn unused_accessors(doc: &gltf::Document) -> usize {
    let mut used = vec![false; doc.accessors().count()];
    for p in doc.meshes().flat_map(|m| m.primitives().collect::<Vec<_>>()) {
        p.attributes().for_each(|(_, a)| used[a.index()] = true);
        p.indices().into_iter().for_each(|a| used[a.index()] = true);
        for t in p.morph_targets() {
            t.positions().into_iter().chain(t.normals()).chain(t.tangents()).for_each(|a| used[a.index()] = true);
        }
    }
    doc.skins().filter_map(|s| s.inverse_bind_matrices()).for_each(|a| used[a.index()] = true);
    for s in doc.animations().flat_map(|a| a.samplers().collect::<Vec<_>>()) {
        used[s.input().index()] = true;
        used[s.output().index()] = true;
    }
    used.iter().filter(|u| !**u).count()
}

#[test]
fn a_model_in_several_buffers_comes_out_in_one_without_the_data_it_no_longer_uses() {
    let Some(dir) = creatures() else { return };
    let out = tmp("buffers");
    // The Wolf with its data in two buffers (the second a copy of the first, odd buffer views in it).
    let mut json = wolf_json(&dir);
    let first = json["buffers"][0].clone();
    json["buffers"].as_array_mut().unwrap().push(first);
    for v in json["bufferViews"].as_array_mut().unwrap().iter_mut().skip(1).step_by(2) {
        v["buffer"] = 1.into();
    }
    let animations = json["animations"].as_array().map_or(0, Vec::len);
    assert!(animations > 0, "the Wolf has clips of its own");
    // An extension that names no accessor or buffer view lets the export drop the Wolf's own clips'
    // data; one that might (instancing) keeps every accessor where it was.
    for (extension, renumbered) in [("KHR_materials_emissive_strength", true), ("EXT_mesh_gpu_instancing", false)] {
        json["extensionsUsed"] = serde_json::json!([extension]);
        let path = out.join(format!("{extension}.gltf"));
        std::fs::write(&path, serde_json::to_vec(&json).unwrap()).unwrap();
        let c = load(&path);
        let (src, src_buffers) = open(&path).unwrap();
        assert_eq!(src_buffers.len(), 2);
        let src_buffers: Vec<&[u8]> = src_buffers.iter().map(Vec::as_slice).collect();
        let poses = turning_clip(&c);
        let w = rig_clip_glb(&c, &poses, FPS, &RigClipOptions::default()).unwrap_or_else(|e| panic!("{e}"));
        let rb = Readback::new(&w.bytes);
        assert_eq!(Readback::positions(&rb.doc, &[&rb.blob]), Readback::positions(&src, &src_buffers), "{extension}");
        assert_bones_follow_the_tree(&c, &rb, 0, poses.len() / 2, &poses[poses.len() / 2], 1e-4 * size(&c));
        let unused = unused_accessors(&rb.doc);
        if renumbered {
            assert_eq!(unused, 0, "{extension}");
        } else {
            // The Wolf's own clips' accessors stay, now unused, beside those the file left unused.
            let samplers = src.animations().flat_map(|a| a.samplers().collect::<Vec<_>>());
            let own_clips: std::collections::HashSet<_> =
                samplers.flat_map(|s| [s.input().index(), s.output().index()]).collect();
            assert!(rb.doc.accessors().count() > src.accessors().count(), "{extension}");
            assert_eq!(unused, unused_accessors(&src) + own_clips.len(), "{extension}");
        }
    }
    let _ = std::fs::remove_dir_all(out);
}

#[test]
fn images_beside_the_model_or_in_data_uris_are_embedded_with_their_format() {
    let Some(dir) = creatures() else { return };
    let out = tmp("images");
    let wolf = load(&dir.join("Quaternius_Wolf/Wolf.gltf"));
    let poses = clip_poses(&wolf, 0, FPS);
    let json = wolf_json(&dir);
    let bytes = |head: &[u8]| [head, b"-the rest of the image".as_slice()].concat();
    let png = bytes(b"\x89PNG\r\n\x1a\n");
    let data_uri = |head: &str| format!("data:{head};base64,{}", base64::Engine::encode(&base64::engine::general_purpose::STANDARD, &png));
    // (what the image gives, bytes of the file beside, the format expected in the export)
    let images = [
        (serde_json::json!({"uri": data_uri("")}), None, "image/png"),
        // The type a data URI declares, or the image its own MIME type, wins over what its bytes look like.
        (serde_json::json!({"uri": data_uri("image/jpeg")}), None, "image/jpeg"),
        (serde_json::json!({"uri": "tex%20ture.jpg"}), Some(("tex ture.jpg", bytes(&[0xFF, 0xD8, 0xFF]))), "image/jpeg"),
        (serde_json::json!({"uri": "skin.webp"}), Some(("skin.webp", bytes(b"RIFF\0\0\0\0WEBP"))), "image/webp"),
        (serde_json::json!({"uri": "skin.ktx2"}), Some(("skin.ktx2", bytes(b"\xABKTX 20\xBB"))), "image/ktx2"),
        (serde_json::json!({"uri": "named.png", "mimeType": "image/jpeg"}), Some(("named.png", png.clone())), "image/jpeg"),
    ];
    let model = |images: Vec<serde_json::Value>, name: &str| {
        let mut json = json.clone();
        json["images"] = images.into();
        let path = out.join(name);
        std::fs::write(&path, serde_json::to_vec(&json).unwrap()).unwrap();
        let mut c = wolf.clone();
        c.tree.source = Some(path);
        c
    };
    for (_, file, _) in &images {
        if let Some((name, b)) = file {
            std::fs::write(out.join(name), b).unwrap();
        }
    }
    let c = model(images.iter().map(|i| i.0.clone()).collect(), "images.gltf");
    let w = rig_clip_glb(&c, &poses, FPS, &RigClipOptions::default()).unwrap_or_else(|e| panic!("{e}"));
    let rb = Readback::new(&w.bytes);
    assert_eq!(rb.doc.images().count(), images.len());
    for (img, (_, file, mime)) in rb.doc.images().zip(&images) {
        let gltf::image::Source::View { view, mime_type } = img.source() else { panic!("image {} is not embedded", img.index()) };
        assert_eq!(mime_type, *mime, "image {}", img.index());
        let embedded = &rb.blob[view.offset()..view.offset() + view.length()];
        assert_eq!(embedded, file.as_ref().map_or(&png, |f| &f.1).as_slice(), "image {}", img.index());
    }

    // A missing file, a folder, a file over the size cap (sparse: refused before it is read) and bytes
    // of no known format without a MIME type: errors that name the model, the image and why.
    std::fs::write(out.join("unknown.img"), b"not an image").unwrap();
    std::fs::create_dir_all(out.join("folder.png")).unwrap();
    let cap = ace_models::character::gltf::MAX_FILE_BYTES;
    std::fs::File::create(out.join("huge.png")).unwrap().set_len(cap + 1).unwrap();
    let not_a_file = format!("not a regular file of at most {cap} bytes");
    for (image, why) in [
        ("absent.png", "absent.png"),
        ("folder.png", not_a_file.as_str()),
        ("huge.png", not_a_file.as_str()),
        ("unknown.img", "neither its URI nor its bytes"),
    ] {
        let c = model(vec![serde_json::json!({"uri": "skin.webp"}), serde_json::json!({"uri": image})], "bad.gltf");
        let e = rig_clip_glb(&c, &poses, FPS, &RigClipOptions::default()).unwrap_err();
        assert!(matches!(e.problem, ExportProblem::Image { index: 1, .. }), "{e}");
        assert!(e.to_string().contains("bad.gltf") && e.to_string().contains(why), "{e}");
    }
    let _ = std::fs::remove_dir_all(out);
}

#[test]
fn a_bone_placed_by_a_matrix_is_keyed_as_translation_rotation_scale_and_the_skeleton_keeps_asset_and_extras() {
    let Some(dir) = creatures() else { return };
    let out = tmp("matrix");
    let wolf = load(&dir.join("Quaternius_Wolf/Wolf.gltf"));
    let poses = turning_clip(&wolf);
    let mut json = wolf_json(&dir);
    json["asset"]["copyright"] = "the artist".into();
    // The Wolf's head as a matrix (column-major) instead of its translation, rotation and scale.
    let head = json["nodes"].as_array().unwrap().iter().position(|n| n["name"] == "Head").expect("a Head bone");
    let node = &mut json["nodes"][head];
    let f = |v: &serde_json::Value, d: [f32; 4]| -> Vec<f32> {
        v.as_array().map_or(d.to_vec(), |a| a.iter().map(|x| x.as_f64().unwrap() as f32).collect())
    };
    let (t, r, sc) = (f(&node["translation"], [0.0; 4]), f(&node["rotation"], [0.0, 0.0, 0.0, 1.0]), f(&node["scale"], [1.0; 4]));
    let m = Matrix4::new_translation(&Vector3::new(t[0], t[1], t[2]))
        * UnitQuaternion::from_quaternion(Quaternion::new(r[3], r[0], r[1], r[2])).to_homogeneous()
        * Matrix4::new_nonuniform_scaling(&Vector3::new(sc[0], sc[1], sc[2]));
    for key in ["translation", "rotation", "scale"] {
        node.as_object_mut().unwrap().remove(key);
    }
    node["matrix"] = m.as_slice().to_vec().into();
    node["extras"] = serde_json::json!({"rigging": "keep me"});
    let path = out.join("Wolf.gltf");
    std::fs::write(&path, serde_json::to_vec(&json).unwrap()).unwrap();
    let mut c = wolf.clone();
    c.tree.source = Some(path);
    for only in [false, true] {
        let opts = RigClipOptions { animation_only: only, ..Default::default() };
        let target = out.join(format!("only_{only}.glb"));
        let w = write_rig_clip(&target, &c, &poses, FPS, &opts).unwrap_or_else(|e| panic!("{e}"));
        khronos_validate(&target);
        let rb = Readback::new(&w.bytes);
        let head = rb.doc.nodes().find(|n| n.name() == Some("Head")).unwrap();
        let json = head.extras().as_ref().map(|e| e.get().to_owned());
        assert_eq!(json.as_deref(), Some(r#"{"rigging":"keep me"}"#), "only {only}");
        assert_eq!(rb.doc.as_json().asset.copyright.as_deref(), Some("the artist"), "only {only}");
        assert_bones_follow_the_tree(&c, &rb, rb.doc.animations().count() - 1, 0, &poses[0], 1e-4 * size(&c));
        assert_bones_follow_the_tree(&c, &rb, rb.doc.animations().count() - 1, poses.len() - 1, &poses[poses.len() - 1], 1e-4 * size(&c));
    }
    let _ = std::fs::remove_dir_all(out);
}

/// The creature's own clip → poses → exported as a new animation → poses again with `clip_poses`
/// (on the same tree): the same poses.
fn round_trip(c: &Creature, path: &Path, clip: usize, out: &Path) -> (f32, f32) {
    let poses = clip_poses(c, clip, FPS);
    let target = out.join(format!("clip{clip}.glb"));
    write_rig_clip(&target, c, &poses, FPS, &RigClipOptions::default()).unwrap_or_else(|e| panic!("{e}"));
    let rig = read(&target, Some(c.scale), Facing::default()).unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(rig.to_character, c.rig.to_character);
    assert_eq!(rig.bones.len(), c.rig.bones.len());
    assert_eq!(rig.animations.len(), 1);
    let mut back = c.clone();
    back.rig.clips = rig.clips;
    back.rig.animations = rig.animations;
    let again = clip_poses(&back, 0, FPS);
    assert_eq!(again.len(), poses.len(), "{}: clip {clip}", path.display());
    let s = size(c);
    let (mut worst_pos, mut worst_q) = (0.0f32, 0.0f32);
    for (k, (a, b)) in poses.iter().zip(&again).enumerate() {
        for (l, (x, y)) in c.tree.forward_kinematics(a).iter().zip(c.tree.forward_kinematics(b)).enumerate() {
            let e = (x.translation.vector - y.translation.vector).norm() / s;
            worst_pos = worst_pos.max(e);
            let link = &c.tree.links[l].name;
            assert!(e <= 1e-4, "{} clip {clip} frame {k}: link {link} off by {e} of the size", path.display());
        }
        for (d, (x, y)) in a.q.iter().zip(&b.q).enumerate() {
            worst_q = worst_q.max((x - y).abs());
            let dof = c.tree.dof_names()[d];
            assert!((x - y).abs() <= 1e-3, "{} clip {clip} frame {k}: {dof} {x} became {y}", path.display());
        }
    }
    (worst_pos, worst_q)
}

#[test]
fn the_creatures_own_clips_come_back_through_clip_poses() {
    let Some(dir) = creatures() else { return };
    let cases = [("Fox/Fox.glb", 0..3), ("Quaternius_Wolf/Wolf.gltf", 0..12), ("Quaternius_Spider/Spider.glb", 4..5)];
    for (file, clips) in cases {
        let path = dir.join(file);
        let c = load(&path);
        let out = tmp(&format!("round-trip-{}", file.replace('/', "-")));
        for clip in clips {
            let (pos, q) = round_trip(&c, &path, clip, &out);
            let name = &c.rig.animations[clip].name;
            eprintln!("{file} clip {clip} ({name}): worst link position {pos:.2e} of the size, worst DoF {q:.2e} rad");
        }
        let _ = std::fs::remove_dir_all(out);
    }
}

#[test]
fn bad_inputs_get_errors_that_name_the_file() {
    let Some(dir) = creatures() else { return };
    let fox = load(&dir.join("Fox/Fox.glb"));
    let poses = clip_poses(&fox, 1, FPS);
    let out = tmp("bad");
    let opts = RigClipOptions::default();

    // A glTF without a skin.
    let skinless = out.join("skinless.gltf");
    let json = r#"{"asset":{"version":"2.0"},"nodes":[{"name":"b_Hip_01"}],"scenes":[{"nodes":[0]}],"scene":0}"#;
    std::fs::write(&skinless, json).unwrap();
    let mut c = fox.clone();
    c.tree.source = Some(skinless.clone());
    let target = out.join("fox.glb");
    std::fs::write(&target, b"the previous export").unwrap();
    let e = write_rig_clip(&target, &c, &poses, FPS, &opts).unwrap_err();
    assert!(matches!(&e.problem, ExportProblem::NoSkin { model } if model == &skinless.display().to_string()), "{e}");
    let msg = e.to_string();
    assert!(msg.contains("fox.glb") && msg.contains("skinless.gltf") && msg.contains("no skin"), "{msg}");
    assert_eq!(std::fs::read(&target).unwrap(), b"the previous export", "nothing written over the old file");
    let leftovers: Vec<_> = std::fs::read_dir(&out).unwrap().flatten().map(|e| e.file_name()).collect();
    assert_eq!(leftovers.len(), 2, "no temporary left behind: {leftovers:?}");

    // Another creature's model.
    let mut c = fox.clone();
    c.tree.source = Some(dir.join("Quaternius_Wolf/Wolf.gltf"));
    let e = rig_clip_glb(&c, &poses, FPS, &opts).unwrap_err();
    assert!(matches!(e.problem, ExportProblem::NotTheCreature { .. }), "{e}");
    assert!(e.to_string().contains("Wolf.gltf"), "{e}");

    // No model at all, a missing one, and poses of another tree.
    let mut c = fox.clone();
    c.tree.source = None;
    let e = rig_clip_glb(&c, &poses, FPS, &opts).unwrap_err();
    assert!(matches!(e.problem, ExportProblem::NoSource), "{e}");
    c.tree.source = Some(out.join("gone.glb"));
    let e = rig_clip_glb(&c, &poses, FPS, &opts).unwrap_err();
    assert!(matches!(e.problem, ExportProblem::Source(_)) && e.to_string().contains("gone.glb"), "{e}");
    let mut short = poses.clone();
    short[3].q.pop();
    let e = rig_clip_glb(&fox, &short, FPS, &opts).unwrap_err();
    assert!(matches!(e.problem, ExportProblem::PoseLength { frame: 3, .. }), "{e}");
    let _ = std::fs::remove_dir_all(out);
}
