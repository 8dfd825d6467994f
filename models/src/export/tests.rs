//! Export tests on real inputs: GLBs of the bundled characters and of the real robots in
//! `../shared/data/robots` read back with the `gltf` crate, compared with forward kinematics and checked
//! by Khronos' glTF validator (installed by `scripts/setup.sh`); command trajectories of known root
//! motions. Set `ACE_ALLOW_MISSING_DATA=1` to skip what needs the shared data or the validator.

use std::collections::HashMap;
use std::f32::consts::{PI, TAU};
use std::path::{Path, PathBuf};
use std::process::Command;

use ::gltf::animation::util::ReadOutputs;
use nalgebra::{Isometry3, Point3, Translation3, UnitQuaternion, Vector3};
use serde_json::Value;

use super::gltf::z_up_to_y_up;
use super::*;
use crate::human::{HumanClip, ImportOptions, Joint};
use crate::kinematics::{JointKind, KinematicTree};
use crate::test_data::{allow_missing, bundled_character};

const EPS: f32 = 1e-4;
const FPS: f32 = 30.0;

fn project() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("..")
}

fn scratch(tag: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("ace_export_{tag}_{}", std::process::id()));
    std::fs::create_dir_all(&d).unwrap();
    d
}

fn wrap(a: f32) -> f32 {
    a - TAU * (a / TAU).round()
}

/// Varied motion: the root drifts, bobs, pitches, rolls and turns with its yaw wrapped into [−π, π]
/// (so consecutive raw quaternions change sign where the yaw crosses ±π); every DoF swings inside its
/// limits at its own rate; continuous joints spin with wrapped angles.
fn varied_poses(tree: &KinematicTree, frames: usize) -> Vec<CharacterPose> {
    let h = tree.standing_root_height();
    let neutral = tree.neutral_q();
    (0..frames)
        .map(|k| {
            let t = k as f32 / FPS;
            let root = Isometry3::from_parts(
                Translation3::new(0.4 * t, 0.3 * (0.7 * t).sin(), h + 0.03 * (3.0 * t).sin()),
                UnitQuaternion::from_euler_angles(
                    0.1 * (1.7 * t).sin(),
                    0.15 * (2.3 * t).sin(),
                    wrap(1.3 * t + 2.5),
                ),
            );
            let q = (0..tree.dof())
                .map(|d| {
                    let j = tree.dof_joint(d);
                    let (phase, w) = (0.7 * d as f32, 1.0 + 0.37 * d as f32);
                    let l = j.limits.expect("movable joints have limits");
                    match j.kind {
                        JointKind::Continuous => wrap(4.0 * t + phase),
                        _ if l.lower >= l.upper => neutral[d],
                        kind => {
                            let cap = if kind == JointKind::Prismatic { 0.1 } else { 0.8 };
                            let amp = (0.45 * (l.upper - l.lower)).min(cap);
                            0.5 * (l.lower + l.upper) + amp * (w * t + phase).sin()
                        }
                    }
                })
                .collect();
            CharacterPose { root, q }
        })
        .collect()
}

/// An animated node property (the `gltf` crate's enum is not `Hash`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
enum Prop {
    Translation,
    Rotation,
    Scale,
}

/// Keyframe values of every animated (node, property).
type Keys = HashMap<(usize, Prop), Vec<Vec<f32>>>;

/// A GLB read back with the `gltf` crate.
struct Readback {
    doc: ::gltf::Document,
    blob: Vec<u8>,
}

impl Readback {
    fn new(bytes: &[u8]) -> Self {
        let g =
            ::gltf::Gltf::from_slice(bytes).unwrap_or_else(|e| panic!("the gltf crate rejects the GLB: {e}"));
        Readback {
            doc: g.document,
            blob: g.blob.expect("a GLB with a binary chunk"),
        }
    }

    /// (node, property) → keyframe values, and the key times of every channel.
    fn channels(&self) -> (Keys, Vec<Vec<f32>>) {
        let anim = self.doc.animations().next().expect("one animation");
        assert_eq!(self.doc.animations().count(), 1);
        let mut out = HashMap::new();
        let mut times = Vec::new();
        for ch in anim.channels() {
            assert_eq!(
                ch.sampler().interpolation(),
                ::gltf::animation::Interpolation::Linear
            );
            let r = ch.reader(|_| Some(&self.blob[..]));
            times.push(r.read_inputs().unwrap().collect());
            let values: Vec<Vec<f32>> = match r.read_outputs().unwrap() {
                ReadOutputs::Translations(it) | ReadOutputs::Scales(it) => it.map(|v| v.to_vec()).collect(),
                ReadOutputs::Rotations(rot) => rot.into_f32().map(|v| v.to_vec()).collect(),
                ReadOutputs::MorphTargetWeights(_) => panic!("no morph targets are written"),
            };
            let prop = match ch.target().property() {
                ::gltf::animation::Property::Translation => Prop::Translation,
                ::gltf::animation::Property::Rotation => Prop::Rotation,
                ::gltf::animation::Property::Scale => Prop::Scale,
                ::gltf::animation::Property::MorphTargetWeights => panic!("no morph targets are written"),
            };
            out.insert((ch.target().node().index(), prop), values);
        }
        (out, times)
    }

    /// World transform (z up again) of every node at keyframe `k`: static node transforms with the
    /// animated ones replaced by their keyframe values, composed down the hierarchy. Scale is left out
    /// (only leaf bone nodes are scaled).
    fn world_at(&self, k: usize) -> Vec<Isometry3<f32>> {
        let (channels, _) = self.channels();
        let n = self.doc.nodes().count();
        let mut local = vec![Isometry3::identity(); n];
        for node in self.doc.nodes() {
            let (t, r, _) = node.transform().decomposed();
            let mut t = Vector3::from(t);
            let mut r = r;
            if let Some(v) = channels.get(&(node.index(), Prop::Translation)) {
                t = Vector3::new(v[k][0], v[k][1], v[k][2]);
            }
            if let Some(v) = channels.get(&(node.index(), Prop::Rotation)) {
                r = [v[k][0], v[k][1], v[k][2], v[k][3]];
            }
            let q = UnitQuaternion::from_quaternion(nalgebra::Quaternion::new(r[3], r[0], r[1], r[2]));
            local[node.index()] = Isometry3::from_parts(t.into(), q);
        }
        let mut world = vec![None; n];
        let back = Isometry3::from_parts(Translation3::identity(), z_up_to_y_up().inverse());
        let mut stack: Vec<(usize, Isometry3<f32>)> = self
            .doc
            .default_scene()
            .unwrap()
            .nodes()
            .map(|r| (r.index(), back))
            .collect();
        while let Some((i, parent)) = stack.pop() {
            let w = parent * local[i];
            assert!(world[i].is_none(), "node {i} reached twice");
            world[i] = Some(w);
            stack.extend(
                self.doc
                    .nodes()
                    .nth(i)
                    .unwrap()
                    .children()
                    .map(|c| (c.index(), w)),
            );
        }
        world
            .into_iter()
            .map(|w| w.expect("every node is in the scene"))
            .collect()
    }

    /// Length of the binary chunk.
    fn bin_len(&self) -> usize {
        self.blob.len()
    }
}

/// Runs Khronos' validator on `path` through `scripts/validate-gltf.mjs`; panics on any error.
/// Returns the report, or `None` when the validator is missing and `ACE_ALLOW_MISSING_DATA=1`.
fn khronos_validate(path: &Path) -> Option<Value> {
    let root = project();
    let missing = |why: String| -> Option<Value> {
        if allow_missing() {
            eprintln!("SKIPPED glTF validation: {why} (ACE_ALLOW_MISSING_DATA=1)");
            return None;
        }
        panic!(
            "{why}: run scripts/setup.sh to install Khronos' glTF validator (or set ACE_ALLOW_MISSING_DATA=1)"
        );
    };
    let installed = root.join(".local/node/node_modules/gltf-validator");
    if !installed.is_dir() {
        return missing(format!("{} not found", installed.display()));
    }
    let out = match Command::new("node")
        .arg(root.join("scripts/validate-gltf.mjs"))
        .arg(path)
        .output()
    {
        Ok(o) => o,
        Err(e) => return missing(format!("cannot run `node`: {e}")),
    };
    let report: Value = serde_json::from_slice(&out.stdout).unwrap_or_else(|e| {
        panic!(
            "the validator printed no JSON report ({e}); stderr: {}",
            String::from_utf8_lossy(&out.stderr)
        )
    });
    let issues = &report["issues"];
    assert_eq!(
        issues["numErrors"],
        0,
        "{} has glTF errors: {}",
        path.display(),
        serde_json::to_string_pretty(issues).unwrap()
    );
    assert!(out.status.success(), "the validator exited with {}", out.status);
    let codes: Vec<&str> = issues["messages"]
        .as_array()
        .unwrap()
        .iter()
        .filter_map(|m| m["code"].as_str())
        .collect();
    let mut counts: Vec<(&str, usize)> = Vec::new();
    for c in codes {
        match counts.iter_mut().find(|(k, _)| *k == c) {
            Some(e) => e.1 += 1,
            None => counts.push((c, 1)),
        }
    }
    eprintln!(
        "validator {}: {} — {} errors, {} warnings, {} infos, {} hints {:?}",
        report["validatorVersion"],
        path.display(),
        issues["numErrors"],
        issues["numWarnings"],
        issues["numInfos"],
        issues["numHints"],
        counts
    );
    Some(report)
}

/// Keyframe rotations of every rotation channel stay in one hemisphere.
fn assert_one_hemisphere(rb: &Readback) {
    let (channels, _) = rb.channels();
    for ((node, prop), values) in &channels {
        if *prop != Prop::Rotation {
            continue;
        }
        for w in values.windows(2) {
            let dot: f32 = w[0].iter().zip(&w[1]).map(|(a, b)| a * b).sum();
            assert!(dot >= 0.0, "node {node}: consecutive keys {:?} {:?}", w[0], w[1]);
        }
    }
}

/// Every link's world transform read back from the GLB equals forward kinematics at frame `k`.
fn assert_matches_fk(rb: &Readback, tree: &KinematicTree, pose: &CharacterPose, k: usize) {
    let world = rb.world_at(k);
    for (i, fk) in tree.forward_kinematics(pose).iter().enumerate() {
        let g = &world[i];
        let name = &tree.links[i].name;
        assert!(
            g.rotation.angle_to(&fk.rotation) < EPS,
            "link {name} frame {k}: rotation"
        );
        assert!(
            (g.translation.vector - fk.translation.vector).norm() < EPS,
            "link {name} frame {k}: {} vs {}",
            g.translation.vector,
            fk.translation.vector
        );
    }
}

fn walk_clip() -> HumanClip {
    let opts = ImportOptions {
        fps: Some(FPS),
        ..ImportOptions::default()
    };
    HumanClip::from_bvh_file(&project().join("assets/motions/walk.bvh"), &opts)
        .unwrap_or_else(|e| panic!("{e}"))
}

// ---------------------------------------------------------------------------------------------
// GLB

#[test]
fn bundled_characters_round_trip_and_validate() {
    let clip = walk_clip();
    let frames = 121; // 4 s
    let human = &clip.frames[..frames];
    let offset = Vector3::new(0.0, 1.2, 0.0);
    let dir = scratch("bundled");
    for name in ["spot", "crab", "stretch"] {
        let (tree, _) = bundled_character(name);
        let poses = varied_poses(&tree, frames);
        // The raw root rotations do change sign somewhere (the yaw is wrapped), so the export must fix it.
        let raw_flips = poses
            .windows(2)
            .filter(|w| w[0].root.rotation.coords.dot(&w[1].root.rotation.coords) < 0.0)
            .count();
        assert!(raw_flips > 0);
        let opts = GltfOptions {
            human: Some(HumanOverlay::new(human, offset)),
            ..GltfOptions::default()
        };
        let path = dir.join(format!("{name}.glb"));
        let out = write_glb(&path, &tree, &poses, FPS, &opts).unwrap();
        assert!(out.warnings.is_empty(), "{name}: {:?}", out.warnings);
        assert_eq!(std::fs::read(&path).unwrap(), out.bytes);
        let rb = Readback::new(&out.bytes);

        // Nodes: the links in order, one per visual, and 1 + 17 joints + 16 bones for the human.
        let visuals: usize = tree.links.iter().map(|l| l.visuals.len()).sum();
        let nodes: Vec<_> = rb.doc.nodes().collect();
        assert_eq!(nodes.len(), tree.links.len() + visuals + 34, "{name}");
        for (i, link) in tree.links.iter().enumerate() {
            assert_eq!(nodes[i].name(), Some(link.name.as_str()));
            let child_links: Vec<usize> = nodes[i]
                .children()
                .map(|c| c.index())
                .filter(|&c| c < tree.links.len())
                .collect();
            assert_eq!(
                child_links,
                tree.children(i).collect::<Vec<_>>(),
                "{name}: children of {}",
                link.name
            );
            let visual_nodes = nodes[i].children().filter(|c| c.mesh().is_some()).count();
            assert_eq!(visual_nodes, link.visuals.len());
        }
        let roots: Vec<usize> = rb
            .doc
            .default_scene()
            .unwrap()
            .nodes()
            .map(|n| n.index())
            .collect();
        assert_eq!(roots.len(), 2);
        assert_eq!(roots[0], 0);
        assert_eq!(nodes[roots[1]].name(), Some("human"));

        // Time keys: one per frame, min/max given.
        let (_, times) = rb.channels();
        let last = (frames - 1) as f32 / FPS;
        assert!(
            times
                .iter()
                .all(|t| t.len() == frames && t[0] == 0.0 && (t[frames - 1] - last).abs() < 1e-6)
        );
        let input = rb
            .doc
            .animations()
            .next()
            .unwrap()
            .samplers()
            .next()
            .unwrap()
            .input();
        assert_eq!(input.min().unwrap()[0].as_f64(), Some(0.0));
        assert_eq!(
            input.max().unwrap()[0].as_f64(),
            Some(f64::from(times[0][frames - 1]))
        );

        assert_one_hemisphere(&rb);
        for k in [0, 37, 61, frames - 1] {
            assert_matches_fk(&rb, &tree, &poses[k], k);
            // Human joints: world positions offset sideways, pelvis turned like the clip's pelvis.
            let world = rb.world_at(k);
            for j in Joint::ALL {
                let n = nodes.iter().position(|n| n.name() == Some(j.name())).unwrap();
                let want = offset + human[k].position(j);
                assert!(
                    (world[n].translation.vector - want).norm() < EPS,
                    "{name} {j:?} frame {k}"
                );
            }
            let pelvis = nodes.iter().position(|n| n.name() == Some("pelvis")).unwrap();
            assert!(world[pelvis].rotation.angle_to(&human[k].root_rotation) < EPS);
        }
        khronos_validate(&path);
    }
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn animation_holds_one_key_per_frame_per_channel() {
    // A 10 s clip against a 5 s one: the binary chunks differ by exactly the 150 extra keys of the
    // time accessor and of every channel (meshes are identical, all data is 4-byte aligned).
    let mut sizes = Vec::new();
    for name in ["spot", "crab", "stretch"] {
        let (tree, _) = bundled_character(name);
        let ten = character_glb(&tree, &varied_poses(&tree, 301), FPS, &GltfOptions::default()).unwrap();
        let five = character_glb(&tree, &varied_poses(&tree, 151), FPS, &GltfOptions::default()).unwrap();
        let (a, b) = (Readback::new(&ten.bytes), Readback::new(&five.bytes));
        let (channels, _) = a.channels();
        let floats_per_key: usize = 1 + channels
            .keys()
            .map(|(_, p)| if *p == Prop::Rotation { 4 } else { 3 })
            .sum::<usize>();
        assert_eq!(a.bin_len() - b.bin_len(), 150 * 4 * floats_per_key, "{name}");
        sizes.push(format!("{name}: {} bytes", ten.bytes.len()));
    }
    eprintln!(
        "GLB sizes for a 10 s clip at 30 fps (no human): {}",
        sizes.join(", ")
    );
}

#[test]
fn each_link_is_animated_on_the_properties_its_joint_moves() {
    // The root moves and turns; a revolute or continuous joint's link only turns, a prismatic one's
    // (Stretch's lift and arm stages) only moves, a fixed one's is not animated. Link i is node i.
    for name in ["spot", "crab", "stretch"] {
        let (tree, _) = bundled_character(name);
        let glb = character_glb(&tree, &varied_poses(&tree, 5), FPS, &GltfOptions::default()).unwrap();
        let (channels, _) = Readback::new(&glb.bytes).channels();
        let mut expected = Vec::new();
        for (i, link) in tree.links.iter().enumerate() {
            match link.joint.as_ref().map(|j| (j.kind, j.dof.is_some() || j.mimic.is_some())) {
                None => expected.extend([(i, Prop::Translation), (i, Prop::Rotation)]),
                Some((JointKind::Prismatic, true)) => expected.push((i, Prop::Translation)),
                Some((JointKind::Revolute | JointKind::Continuous, true)) => expected.push((i, Prop::Rotation)),
                Some(_) => {}
            }
        }
        let mut animated: Vec<(usize, Prop)> = channels.into_keys().collect();
        animated.sort_by_key(|&(n, p)| (n, p as u8));
        assert_eq!(animated, expected, "{name}");
        if name == "stretch" {
            let prismatic = expected.iter().filter(|(i, _)| {
                tree.links[*i].joint.as_ref().is_some_and(|j| j.kind == JointKind::Prismatic)
            });
            assert!(prismatic.count() >= 5, "Stretch's lift and four arm stages slide");
        }
    }
}

/// The real robot URDFs with their mesh files.
const REAL_ROBOTS: [&str; 3] = [
    "spot_arm/spot_with_arm.urdf",
    "stretch_re1/stretch_description_RE1V0_tool_stretch_gripper.urdf",
    "phantomx_hexapod/phantomx_description/urdf/phantomx.urdf",
];

#[test]
fn real_robots_export_with_their_meshes_and_validate() {
    let data = project().join("../shared/data/robots");
    if !data.is_dir() {
        assert!(
            allow_missing(),
            "shared robot data not found at {} (set ACE_ALLOW_MISSING_DATA=1 to skip tests that need it)",
            data.display()
        );
        eprintln!("SKIPPED: shared robot data not found at {}", data.display());
        return;
    }
    let dir = scratch("robots");
    for rel in REAL_ROBOTS {
        let urdf = data.join(rel);
        let tree = KinematicTree::from_urdf_file(&urdf).unwrap_or_else(|e| panic!("{e}"));
        let poses = varied_poses(&tree, 31);
        let path = dir.join(format!("{}.glb", tree.name));
        let out = write_glb(&path, &tree, &poses, FPS, &GltfOptions::default()).unwrap();
        // Every visual mesh file present in the data is read; the absent ones are reported.
        let mut present = std::collections::HashSet::new();
        let mut absent = std::collections::HashSet::new();
        for g in tree.links.iter().flat_map(|l| &l.visuals) {
            if let crate::geometry::Shape::Mesh { filename, .. } = &g.shape {
                match crate::urdf::resolve_mesh_path(filename, urdf.parent().unwrap()) {
                    Some(p) => present.insert(p),
                    None => absent.insert(filename.clone()),
                };
            }
        }
        eprintln!(
            "{rel}: {} links, {} visual mesh files present and {} absent, {} mesh files read, {} bytes, \
             {} warnings:\n  {}",
            tree.links.len(),
            present.len(),
            absent.len(),
            out.mesh_files,
            out.bytes.len(),
            out.warnings.len(),
            out.warnings.join("\n  ")
        );
        assert!(!present.is_empty(), "{rel}: no visual mesh file found");
        assert!(
            out.mesh_files >= present.len(),
            "{rel}: every visual mesh file present is read"
        );
        for f in &absent {
            assert!(
                out.warnings.iter().any(|w| w.contains(f.as_str())),
                "{rel}: no warning about {f}"
            );
        }
        // Every link with visuals shows something when it has a visual that can be drawn or collision
        // geometry to stand in.
        let rb = Readback::new(&out.bytes);
        let nodes: Vec<_> = rb.doc.nodes().collect();
        for (i, l) in tree.links.iter().enumerate() {
            let drawable = l.visuals.iter().any(|g| match &g.shape {
                crate::geometry::Shape::Mesh { filename, .. } => !absent.contains(filename),
                _ => true,
            });
            if drawable || (!l.visuals.is_empty() && !l.collisions.is_empty()) {
                assert!(
                    nodes[i].children().any(|c| c.mesh().is_some()),
                    "{rel}: link {} shows nothing",
                    l.name
                );
            }
        }
        assert!(rb.doc.meshes().count() > 0);
        assert_one_hemisphere(&rb);
        assert_matches_fk(&rb, &tree, &poses[20], 20);
        khronos_validate(&path);
    }
    let _ = std::fs::remove_dir_all(&dir);
}

/// A closed tetrahedron as a binary STL (counter-clockwise seen from outside).
fn tetra_stl() -> Vec<u8> {
    let p = [
        [0.0, 0.0, 0.0],
        [1.0, 0.0, 0.0],
        [0.0, 1.0, 0.0],
        [0.0, 0.0, 1.0f32],
    ];
    let tris = [[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]];
    let mut b = vec![0u8; 80];
    b.extend_from_slice(&(tris.len() as u32).to_le_bytes());
    for t in tris {
        b.extend_from_slice(&[0u8; 12]);
        for i in t {
            for x in p[i] {
                b.extend_from_slice(&x.to_le_bytes());
            }
        }
        b.extend_from_slice(&[0, 0]);
    }
    b
}

const MESH_URDF: &str = r#"<robot name="meshy">
  <material name="red"><color rgba="1 0 0 1"/></material>
  <link name="base">
    <visual>
      <geometry><mesh filename="meshes/tetra.stl" scale="1 -2 0.5"/></geometry><material name="red"/>
    </visual>
    <visual><origin xyz="0 0 1"/><geometry><mesh filename="meshes/gone.stl"/></geometry></visual>
  </link>
  <link name="tip">
    <visual>
      <geometry><sphere radius="0.1"/></geometry>
      <material name="blue"><color rgba="0 0 1 0.5"/></material>
    </visual>
  </link>
  <joint name="j" type="revolute"><parent link="base"/><child link="tip"/><axis xyz="0 0 1"/>
    <limit lower="-1" upper="1" velocity="1" effort="1"/></joint>
</robot>"#;

/// Positions, normals and triangles of the first primitive of `mesh`.
fn primitive(rb: &Readback, mesh: usize) -> (Vec<Vector3<f32>>, Vec<Vector3<f32>>, Vec<u32>) {
    let m = rb.doc.meshes().nth(mesh).unwrap();
    let p = m.primitives().next().unwrap();
    let r = p.reader(|_| Some(&rb.blob[..]));
    (
        r.read_positions().unwrap().map(Vector3::from).collect(),
        r.read_normals().unwrap().map(Vector3::from).collect(),
        r.read_indices().unwrap().into_u32().collect(),
    )
}

#[test]
fn the_world_turns_from_z_up_to_gltfs_y_up() {
    // (x, y, z) ↦ (x, z, −y): up stays up, forward stays x, the character's left goes to −z.
    let r = z_up_to_y_up();
    assert!((r * Vector3::z() - Vector3::y()).norm() < 1e-6);
    assert!((r * Vector3::x() - Vector3::x()).norm() < 1e-6);
    assert!((r * Vector3::y() + Vector3::z()).norm() < 1e-6);
}

#[test]
fn the_humans_bones_run_from_each_joint_to_the_next() {
    let tree = stretch();
    let clip = walk_clip();
    let human = &clip.frames[..2];
    let poses = vec![tree.neutral_pose(Isometry3::identity()); 2];
    let opts = GltfOptions {
        human: Some(HumanOverlay::new(human, Vector3::zeros())),
        ..GltfOptions::default()
    };
    let rb = Readback::new(&character_glb(&tree, &poses, FPS, &opts).unwrap().bytes);
    // The shared bone mesh: a cylinder of the bone radius from z = 0 to 1, scaled along z per bone.
    let bone = rb.doc.meshes().find(|m| m.name() == Some("human_bone")).unwrap();
    let (pos, _, _) = primitive(&rb, bone.index());
    let (lo, hi) = pos.iter().fold((f32::INFINITY, f32::NEG_INFINITY), |(lo, hi), p| (lo.min(p.z), hi.max(p.z)));
    assert!(lo.abs() < 1e-6 && (hi - 1.0).abs() < 1e-6, "the bone mesh spans z {lo}..{hi}");
    let radial = pos.iter().map(|p| p.xy().norm()).fold(0.0, f32::max);
    assert!((radial - 0.015).abs() < 1e-6, "{radial}");
    // Each bone node hangs under its parent joint and points at its joint, as long as the bone.
    for j in Joint::ALL {
        let Some(parent) = j.parent() else { continue };
        let name = format!("{}_bone", j.name());
        let node = rb.doc.nodes().find(|n| n.name() == Some(name.as_str())).unwrap();
        let holder = rb.doc.nodes().find(|n| n.children().any(|c| c.index() == node.index())).unwrap();
        assert_eq!(holder.name(), Some(parent.name()));
        let (_, [x, y, z, w], [sx, sy, sz]) = node.transform().decomposed();
        let tip = UnitQuaternion::from_quaternion(nalgebra::Quaternion::new(w, x, y, z)) * Vector3::new(0.0, 0.0, sz);
        let f = &human[0];
        let want = f.root_rotation.inverse() * (f.position(j) - f.position(parent));
        assert!((tip - want).norm() < 1e-5 && sx == 1.0 && sy == 1.0, "{name}: {tip} against {want}");
    }
}

/// Every triangle of a closed mesh faces away from `centroid` with its vertices' normals along its
/// face, and the mesh encloses `volume` (to 10⁻⁴ of it).
fn assert_faces_outwards(pos: &[Vector3<f32>], nrm: &[Vector3<f32>], idx: &[u32], centroid: Vector3<f32>, volume: f32) {
    let mut enclosed = 0.0;
    for t in idx.chunks_exact(3) {
        let [a, b, c] = [0, 1, 2].map(|i| pos[t[i] as usize]);
        enclosed += a.dot(&b.cross(&c)) / 6.0;
        let face = (b - a).cross(&(c - a)).normalize();
        assert!(face.dot(&((a + b + c) / 3.0 - centroid)) > 0.0, "a triangle faces inwards");
        for &i in t {
            assert!((nrm[i as usize] - face).norm() < 1e-5, "normal {} vs face {face}", nrm[i as usize]);
        }
    }
    assert!((enclosed - volume).abs() < 1e-4 * volume, "volume {enclosed}");
}

/// A unit tetrahedron as an OBJ file with a normal per face.
const TETRA_OBJ: &str = "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\n\
vn 0 0 -1\nvn 0 -1 0\nvn -1 0 0\nvn 0.57735027 0.57735027 0.57735027\n\
f 1//1 3//1 2//1\nf 1//2 2//2 4//2\nf 1//3 4//3 3//3\nf 2//4 3//4 4//4\n";

#[test]
fn a_mesh_files_own_normals_follow_its_scale_and_primitives_are_named_for_their_shape() {
    let dir = scratch("normals");
    std::fs::create_dir_all(&dir).unwrap();
    std::fs::write(dir.join("tetra.obj"), TETRA_OBJ).unwrap();
    // Mirrored in y and stretched unevenly: the slanted face's normal turns, the winding flips.
    let urdf = dir.join("obj.urdf");
    std::fs::write(
        &urdf,
        r#"<robot name="obj">
  <link name="base">
    <visual><geometry><mesh filename="tetra.obj" scale="1 -0.5 2"/></geometry></visual>
    <visual><geometry><box size="0.1 0.1 0.1"/></geometry></visual>
    <visual><geometry><cylinder radius="0.1" length="0.2"/></geometry></visual>
    <visual><geometry><sphere radius="0.1"/></geometry></visual>
  </link>
</robot>"#,
    )
    .unwrap();
    let tree = KinematicTree::from_urdf_file(&urdf).unwrap();
    let poses = vec![tree.neutral_pose(Isometry3::identity()); 2];
    let out = character_glb(&tree, &poses, FPS, &GltfOptions::default()).unwrap();
    assert!(out.warnings.is_empty(), "{:?}", out.warnings);
    let rb = Readback::new(&out.bytes);
    let names: Vec<&str> = rb.doc.meshes().filter_map(|m| m.name()).collect();
    assert_eq!(names, ["tetra", "box", "cylinder", "sphere"]);
    // Without a colour: the default grey, opaque, dielectric and fairly rough.
    let material = rb.doc.meshes().nth(1).unwrap().primitives().next().unwrap().material();
    let pbr = material.pbr_metallic_roughness();
    assert_eq!(pbr.base_color_factor(), gltf::DEFAULT_COLOR);
    assert_eq!((pbr.metallic_factor(), pbr.roughness_factor()), (0.0, 0.6));
    assert_eq!(material.alpha_mode(), ::gltf::material::AlphaMode::Opaque);
    assert_eq!(material.name(), Some("rgba(0.7 0.7 0.72 1)"));
    let (pos, nrm, idx) = primitive(&rb, 0);
    assert!(pos.contains(&Vector3::new(0.0, -0.5, 0.0)) && pos.contains(&Vector3::new(0.0, 0.0, 2.0)));
    assert_faces_outwards(&pos, &nrm, &idx, Vector3::new(0.25, -0.125, 0.5), 1.0 / 6.0);
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn mesh_files_scale_colours_and_stand_ins() {
    let dir = scratch("meshes");
    std::fs::create_dir_all(dir.join("meshes")).unwrap();
    std::fs::write(dir.join("meshes/tetra.stl"), tetra_stl()).unwrap();
    // `gone.stl` exists while the URDF is read (so its bounds are known) and is deleted before export.
    std::fs::write(dir.join("meshes/gone.stl"), tetra_stl()).unwrap();
    let urdf = dir.join("meshy.urdf");
    std::fs::write(&urdf, MESH_URDF).unwrap();
    let tree = KinematicTree::from_urdf_file(&urdf).unwrap();
    std::fs::remove_file(dir.join("meshes/gone.stl")).unwrap();
    let poses = vec![tree.neutral_pose(Isometry3::identity()); 2];
    let out = character_glb(&tree, &poses, FPS, &GltfOptions::default()).unwrap();
    assert_eq!(out.mesh_files, 1);
    assert_eq!(out.warnings.len(), 1, "{:?}", out.warnings);
    assert!(
        out.warnings[0]
            .contains("meshes/gone.stl` not found; its bounding box stands in (visual 1 of link `base`)"),
        "{:?}",
        out.warnings
    );
    let rb = Readback::new(&out.bytes);
    let node_mesh = |name: &str| {
        rb.doc
            .nodes()
            .find(|n| n.name() == Some(name))
            .unwrap()
            .mesh()
            .unwrap()
    };

    // The mirrored, stretched tetrahedron: scaled vertices, triangles still facing outwards.
    let tetra = node_mesh("base.visual0");
    let (pos, nrm, idx) = primitive(&rb, tetra.index());
    let corners: Vec<Vector3<f32>> = pos.clone();
    assert!(
        corners.contains(&Vector3::new(0.0, -2.0, 0.0)) && corners.contains(&Vector3::new(0.0, 0.0, 0.5))
    );
    assert_faces_outwards(&pos, &nrm, &idx, Vector3::new(0.25, -0.5, 0.125), 1.0 / 6.0);
    let acc = tetra
        .primitives()
        .next()
        .unwrap()
        .get(&::gltf::Semantic::Positions)
        .unwrap();
    assert_eq!(acc.min().unwrap(), serde_json::json!([0.0, -2.0, 0.0]));
    assert_eq!(acc.max().unwrap(), serde_json::json!([1.0, 0.0, 0.5]));
    // Colour by material name from the top level; the other visual's colour defined inline.
    let color = |m: ::gltf::Mesh| {
        m.primitives()
            .next()
            .unwrap()
            .material()
            .pbr_metallic_roughness()
            .base_color_factor()
    };
    assert_eq!(color(tetra), [1.0, 0.0, 0.0, 1.0]);
    let tip = node_mesh("tip.visual0");
    assert_eq!(color(tip.clone()), [0.0, 0.0, 1.0, 0.5]);
    assert_eq!(
        tip.primitives().next().unwrap().material().alpha_mode(),
        ::gltf::material::AlphaMode::Blend
    );
    // The stand-in: a box over the deleted file's bounds.
    let (pos, _, idx) = primitive(&rb, node_mesh("base.visual1").index());
    assert_eq!((pos.len(), idx.len()), (24, 36));
    let lo = pos
        .iter()
        .fold(Point3::from(Vector3::repeat(f32::INFINITY)), |m, p| {
            m.inf(&Point3::from(*p))
        });
    let hi = pos
        .iter()
        .fold(Point3::from(Vector3::repeat(f32::NEG_INFINITY)), |m, p| {
            m.sup(&Point3::from(*p))
        });
    assert_eq!((lo, hi), (Point3::origin(), Point3::new(1.0, 1.0, 1.0)));

    let path = dir.join("meshy.glb");
    write_atomic(&path, &out.bytes).unwrap();
    khronos_validate(&path);

    // A mesh file that was never found has no bounds: it is left out, with a warning.
    std::fs::remove_file(dir.join("meshes/tetra.stl")).unwrap();
    let tree = KinematicTree::from_urdf_file(&urdf).unwrap();
    let out = character_glb(&tree, &poses, FPS, &GltfOptions::default()).unwrap();
    assert_eq!(out.mesh_files, 0);
    assert!(
        out.warnings
            .iter()
            .any(|w| w.contains("tetra.stl` not found; it is left out (visual 0 of link `base`)")),
        "{:?}",
        out.warnings
    );
    assert!(
        Readback::new(&out.bytes)
            .doc
            .nodes()
            .all(|n| n.name() != Some("base.visual0"))
    );
    let _ = std::fs::remove_dir_all(&dir);
}

/// The hand-written Collada pyramid (`models/tests/data/urdf/meshes/pyramid.dae`: decimetres, base
/// ±1, apex at 2, a green effect) under the URDF scale (2, 1, 0.5): its own six triangles are written, in
/// metres and scaled, facing outwards, in the file's colour, and the GLB validates.
#[test]
fn collada_mesh_exports_its_triangles_scaled_and_coloured() {
    let urdf = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("tests/data/urdf/pyramid.urdf");
    let tree = KinematicTree::from_urdf_file(&urdf).unwrap();
    let poses = vec![tree.neutral_pose(Isometry3::identity()); 2];
    let out = character_glb(&tree, &poses, FPS, &GltfOptions::default()).unwrap();
    assert!(out.warnings.is_empty(), "{:?}", out.warnings);
    assert_eq!(out.mesh_files, 1);
    let rb = Readback::new(&out.bytes);
    let mesh = rb
        .doc
        .nodes()
        .find(|n| n.name() == Some("base.visual0"))
        .and_then(|n| n.mesh())
        .expect("the pyramid has a mesh");
    let (pos, nrm, idx) = primitive(&rb, mesh.index());
    // Six triangles (a stand-in box has twelve), with the apex and the base corners in metres, scaled.
    assert_eq!(idx.len(), 18);
    let near = |p: Vector3<f32>| pos.iter().any(|q| (q - p).norm() < 1e-6);
    for p in [
        Vector3::new(0.0, 0.0, 0.1),
        Vector3::new(-0.2, -0.1, 0.0),
        Vector3::new(0.2, -0.1, 0.0),
        Vector3::new(0.2, 0.1, 0.0),
        Vector3::new(-0.2, 0.1, 0.0),
    ] {
        assert!(near(p), "no vertex at {p}: {pos:?}");
    }
    // Base 0.4 × 0.2 m, height 0.1 m.
    assert_faces_outwards(&pos, &nrm, &idx, Vector3::new(0.0, 0.0, 0.02), 0.4 * 0.2 * 0.1 / 3.0);
    let material = mesh.primitives().next().unwrap().material();
    let [r, g, b, a] = material.pbr_metallic_roughness().base_color_factor();
    assert!(
        (Vector3::new(r, g, b) - Vector3::new(0.1, 0.6, 0.3)).norm() < 1e-6 && a == 1.0,
        "colour {:?}",
        [r, g, b, a]
    );
    let dir = scratch("collada");
    let path = dir.join("pyramid.glb");
    write_atomic(&path, &out.bytes).unwrap();
    khronos_validate(&path);
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn bad_input_is_refused_with_the_file_named() {
    let (tree, _) = bundled_character("crab");
    let dir = scratch("bad");
    let path = dir.join("out.glb");
    let file = path.display().to_string();
    let poses = varied_poses(&tree, 3);
    let opts = GltfOptions::default();
    let msg = |r: Result<GlbOutput, ExportError>| r.unwrap_err().to_string();
    assert_eq!(
        msg(write_glb(&path, &tree, &[], FPS, &opts)),
        format!("{file}: there are no frames to export")
    );
    assert!(msg(write_glb(&path, &tree, &poses, 0.0, &opts)).contains("frame rate must be positive"));
    let mut short = poses.clone();
    short[1].q.pop();
    assert_eq!(
        msg(write_glb(&path, &tree, &short, FPS, &opts)),
        format!(
            "{file}: frame 1 has {} joint values, the character has {} DoFs",
            tree.dof() - 1,
            tree.dof()
        )
    );
    let mut nan = poses.clone();
    nan[2].q[0] = f32::NAN;
    let e = msg(write_glb(&path, &tree, &nan, FPS, &opts));
    assert!(
        e.contains(&format!(
            "frame 2 has a non-finite value of joint `{}`",
            tree.dof_names()[0]
        )),
        "{e}"
    );
    let clip = walk_clip();
    let opts = GltfOptions {
        human: Some(HumanOverlay::new(&clip.frames[..2], Vector3::zeros())),
        ..GltfOptions::default()
    };
    assert!(msg(write_glb(&path, &tree, &poses, FPS, &opts)).contains("human skeleton has 2 frames"));
    // In memory the error names the export.
    let e = character_glb(&tree, &[], FPS, &GltfOptions::default()).unwrap_err();
    assert_eq!(e.file, "<glTF of crab in memory>");
    assert!(!path.exists(), "nothing was written");
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn atomic_write_replaces_and_leaves_nothing_behind() {
    let dir = scratch("atomic");
    let path = dir.join("out.txt");
    write_atomic(&path, b"first").unwrap();
    write_atomic(&path, b"second").unwrap();
    assert_eq!(std::fs::read(&path).unwrap(), b"second");
    let names: Vec<_> = std::fs::read_dir(&dir)
        .unwrap()
        .map(|e| e.unwrap().file_name())
        .collect();
    assert_eq!(names, vec![std::ffi::OsString::from("out.txt")]);
    // A directory that does not exist: the error names the file, nothing is created.
    let bad = dir.join("missing/out.txt");
    let e = write_atomic(&bad, b"x").unwrap_err();
    assert!(e.to_string().starts_with(&bad.display().to_string()), "{e}");
    assert!(!dir.join("missing").exists());
    let _ = std::fs::remove_dir_all(&dir);
}

// ---------------------------------------------------------------------------------------------
// Command trajectories

fn stretch() -> KinematicTree {
    bundled_character("stretch").0
}

#[test]
fn csv_header_lists_every_dof_and_json_round_trips() {
    let tree = stretch();
    let poses = varied_poses(&tree, 40);
    let traj = CommandTrajectory::from_poses(&tree, &poses, FPS).unwrap();
    let csv = traj.to_csv();
    let mut lines = csv.lines();
    let header: Vec<&str> = lines.next().unwrap().split(',').collect();
    let mut want = vec!["t", "vx", "vy", "wz", "height"];
    want.extend(tree.dof_names());
    assert_eq!(header, want);
    assert!(tree.dof_names().contains(&"joint_left_wheel"));
    let rows: Vec<Vec<f32>> = lines
        .map(|l| l.split(',').map(|v| v.parse().unwrap()).collect())
        .collect();
    assert_eq!(rows.len(), poses.len());
    assert!(rows.iter().all(|r| r.len() == header.len()));
    assert_eq!(rows[3][0], traj.frames[3].t);
    assert_eq!(rows[3][4], poses[3].root.translation.vector.z);

    let json: Value = serde_json::from_str(&traj.to_json()).unwrap();
    assert_eq!(json["format"], "ace-command-trajectory");
    assert_eq!(json["units"]["wz"], "rad/s");
    assert_eq!(json["joints"][0]["name"], tree.dof_names()[0]);
    let lift = tree.dof_index("joint_lift").unwrap();
    assert_eq!(json["joints"][lift]["unit"], "m");
    let back: CommandTrajectory = serde_json::from_str(&traj.to_json()).unwrap();
    assert_eq!(back, traj);

    let dir = scratch("traj");
    traj.write_csv(&dir.join("t.csv")).unwrap();
    traj.write_json(&dir.join("t.json")).unwrap();
    assert_eq!(std::fs::read_to_string(dir.join("t.csv")).unwrap(), csv);
    assert_eq!(
        std::fs::read_to_string(dir.join("t.json")).unwrap(),
        traj.to_json()
    );
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn base_velocities_of_known_root_motions() {
    let tree = stretch();
    let q = tree.neutral_q();
    let pose = |x: f32, y: f32, z: f32, yaw: f32| CharacterPose {
        root: Isometry3::from_parts(
            Translation3::new(x, y, z),
            UnitQuaternion::from_axis_angle(&Vector3::z_axis(), wrap(yaw)),
        ),
        q: q.clone(),
    };
    // Straight line at (1.0, 0.5) m/s with the body turned 0.5 rad: constant heading-frame velocity.
    let poses: Vec<_> = (0..60)
        .map(|k| {
            let t = k as f32 / FPS;
            pose(2.0 + 1.0 * t, -1.0 + 0.5 * t, 0.3, 0.5)
        })
        .collect();
    let traj = CommandTrajectory::from_poses(&tree, &poses, FPS).unwrap();
    let (s, c) = 0.5f32.sin_cos();
    for f in &traj.frames {
        assert!((f.vx - (c * 1.0 + s * 0.5)).abs() < 1e-3, "{f:?}");
        assert!((f.vy - (-s * 1.0 + c * 0.5)).abs() < 1e-3, "{f:?}");
        assert!(f.wz.abs() < 1e-4 && (f.height - 0.3).abs() < 1e-6);
    }
    // A circle driven forwards at 0.8 m/s turning at 0.6 rad/s for 8 s: the yaw passes ±π, the heading
    // velocity stays (0.8, 0) and the yaw rate 0.6 (central differences of a chord: error O(dt²)).
    let (v, w) = (0.8, 0.6);
    let poses: Vec<_> = (0..241)
        .map(|k| {
            let t = k as f32 / FPS;
            let a = w * t;
            pose(v / w * a.sin(), v / w * (1.0 - a.cos()), 0.25, a)
        })
        .collect();
    let traj = CommandTrajectory::from_poses(&tree, &poses, FPS).unwrap();
    for f in &traj.frames[1..traj.frames.len() - 1] {
        assert!((f.vx - v).abs() < 1e-3 && f.vy.abs() < 1e-3, "{f:?}");
        assert!((f.wz - w).abs() < 1e-3, "{f:?}");
    }
    // One-sided ends are a half-step off in direction only.
    assert!((traj.frames[0].wz - w).abs() < 1e-3);
}

#[test]
fn wheel_angles_are_unwrapped_across_pi() {
    let tree = stretch();
    let wheel = tree.dof_index("joint_left_wheel").unwrap();
    assert_eq!(tree.dof_joint(wheel).kind, JointKind::Continuous);
    let lift = tree.dof_index("joint_lift").unwrap();
    let rate = 7.0; // rad/s: more than a turn in a second
    let poses: Vec<_> = (0..45)
        .map(|k| {
            let mut p = tree.standing_pose();
            let t = k as f32 / FPS;
            p.q[wheel] = wrap(3.0 + rate * t);
            p.q[lift] = 0.3 + 0.1 * t;
            p
        })
        .collect();
    assert!(
        poses
            .windows(2)
            .any(|w| (w[1].q[wheel] - w[0].q[wheel]).abs() > PI),
        "the input jumps at ±π"
    );
    let traj = CommandTrajectory::from_poses(&tree, &poses, FPS).unwrap();
    for (k, f) in traj.frames.iter().enumerate() {
        let t = k as f32 / FPS;
        assert!(
            (f.q[wheel] - (3.0 + rate * t)).abs() < 1e-4,
            "frame {k}: {}",
            f.q[wheel]
        );
        assert!(
            (f.q[lift] - (0.3 + 0.1 * t)).abs() < 1e-6,
            "prismatic joints are kept as they are"
        );
    }
}
