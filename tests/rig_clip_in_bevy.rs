//! The artist's path end to end (issue 14 item 3): `ace retarget` (its library calls) writes the walk
//! onto the bundled hound's own model as a rig clip, and Bevy plays that file with nothing of ours in
//! the way: Bevy's glTF loader, its `AnimationPlayer` and an `AnimationGraph` of the clip named after
//! the walk, time stepped by hand one frame (1/30 s) per update. On each of the clip's 150 keyframes
//! (the player's clock within 2e-5 s of the key's time) each bone's local `Transform` is the
//! local TRS the project's own pose → bone conversion (`ace_models::character::rig_pose`) gives for the
//! retargeted pose of that frame, and each bone's world transform is the tree's pose of its link
//! (`C⁻¹ · W_b · R_b⁻¹ · C · F_b`, written out here without `rig_pose`), within 1e-3 of the creature's
//! size and 1e-3 rad. Root motion is on the body root's node (its world position is its link's);
//! the armature root and every other node the pose does not move stay at rest.

use std::collections::HashMap;
use std::path::{Path, PathBuf};
use std::time::Duration;

use ace::models::character::gltf::open;
use ace::models::character::rig_pose::{NodeTransform, RigScratch};
use ace::models::character::{Creature, RigPose, load_creature};
use ace::models::kinematics::CharacterPose;
use ace::models::nalgebra::{Matrix4, Vector3};
use ace::output::Outputs;
use ace::plugin::convert::node_transform;
use ace::plugin::prelude::*;
use ace::retarget::{Backend, Networks, Written, import_options, retarget_and_score, write};
use ace::scoring::Scorer;
use bevy::animation::graph::{AnimationGraph, AnimationGraphHandle};
use bevy::animation::{AnimationClip, AnimationPlayer, AnimationTargetId};
use bevy::asset::LoadState;
use bevy::gltf::{Gltf, GltfAssetLabel, GltfPlugin};
use bevy::prelude::*;
use bevy::time::TimeUpdateStrategy;
use bevy::world_serialization::{WorldAssetRoot, WorldInstance, WorldInstanceSpawner, WorldSerializationPlugin};

mod common;
use common::{root, update_until};

const FPS: f32 = 30.0;
const DT: f32 = 1.0 / FPS;

/// What `ace retarget assets/motions/walk.bvh --character hound --out DIR/hound_walk.glb` does
/// (`ace::retarget::run`, with its defaults: the Rust backend, cleanup on, the model whole), keeping the
/// poses it wrote.
fn retarget_walk_onto_hound(dir: &Path) -> (Written, String) {
    let (_, tree, morph) = ace::characters::load("hound").unwrap();
    let checkpoint = ace::retarget::default_checkpoint("hound").unwrap();
    let networks = Networks::load(&checkpoint, Backend::Rust).unwrap();
    let clip = ace::models::human::HumanClip::from_bvh_file(
        &root().join("assets/motions/walk.bvh"),
        &import_options(None).unwrap(),
    )
    .unwrap();
    let scorer = Scorer::new(networks.record(), networks.character(), &checkpoint).unwrap();
    let r = retarget_and_score(&networks, &scorer, &tree, &morph, &clip).unwrap();
    assert!((r.motion.fps - FPS).abs() < 1e-6, "retargeted at {} fps", r.motion.fps);
    let mut outputs = Outputs::new();
    let w = write(&r, &tree, &clip, &dir.join("hound_walk.glb"), false, &mut outputs).unwrap();
    outputs.commit().unwrap();
    (w, clip.name)
}

/// A headless app loading assets from `assets` with Bevy's glTF loader and animation (and the plugin,
/// as an artist's game has it: it must not get in the way of a scene nothing retargets).
fn app(assets: &Path) -> App {
    let mut app = App::new();
    app.add_plugins((
        MinimalPlugins,
        AssetPlugin { file_path: assets.to_str().unwrap().into(), ..default() },
        TransformPlugin,
        WorldSerializationPlugin,
        bevy::mesh::MeshPlugin,
        bevy::image::ImagePlugin::default(),
        bevy::animation::AnimationPlugin,
        GltfPlugin::default(),
        AcePlugin,
    ))
    .insert_resource(TimeUpdateStrategy::ManualDuration(Duration::from_secs_f32(DT)));
    // Bevy's glTF loader is registered when the plugins finish (`App::run` does this).
    app.finish();
    app.cleanup();
    app
}

/// The angle (rad) between two rotations, without the rounding `angle_between` suffers near zero
/// (`|a − b| = 2 sin(θ/4)` for unit quaternions, with `b`'s sign the nearer).
fn angle(a: Quat, b: Quat) -> f32 {
    let d = (a - b).length().min((a + b).length());
    4.0 * (d / 2.0).min(1.0).asin()
}

/// The world matrix (file frame and units) of each rig bone with a link in `pose`, from the tree and the
/// file alone: `C⁻¹ · W_b · R_b⁻¹ · C · F_b`.
fn bone_worlds(c: &Creature, rest_world: &[Matrix4<f32>], pose: &CharacterPose) -> Vec<(String, Matrix4<f32>)> {
    let fk = c.tree.forward_kinematics(pose);
    let rot = c.rig.to_character.matrix();
    let mut to_char = Matrix4::identity();
    to_char.fixed_view_mut::<3, 3>(0, 0).copy_from(&(rot * c.rig.scale));
    let mut from_char = Matrix4::identity();
    from_char.fixed_view_mut::<3, 3>(0, 0).copy_from(&(rot.transpose() / c.rig.scale));
    c.rig
        .bones
        .iter()
        .filter_map(|b| {
            let link = c.tree.link_index(&b.name)?;
            let m = from_char * fk[link].to_homogeneous() * b.rest.inverse().to_homogeneous() * to_char * rest_world[b.node];
            Some((b.name.clone(), m))
        })
        .collect()
}

/// Worst gaps seen: the player's time off its keyframe (s), local translation (file units), local
/// rotation (rad), world translation, world rotation.
#[derive(Default, Debug)]
struct Gaps {
    seek: f32,
    local_t: f32,
    local_r: f32,
    world_t: f32,
    world_r: f32,
}

#[test]
fn an_exported_rig_clip_plays_in_bevy_as_the_retargeted_poses() {
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR")).join("rig-clip-in-bevy");
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    let (written, clip_name) = retarget_walk_onto_hound(&dir);
    assert_eq!(clip_name, "walk");
    let poses = &written.poses;
    assert!(poses.len() > 30, "{} frames", poses.len());

    // The expected local TRS of every driven bone per frame: the project's conversion of the poses,
    // on the creature and file the exporter read (not the exported file).
    let hound_path: PathBuf = root().join("assets/creatures/hound.glb");
    let c = load_creature(&hound_path).unwrap();
    let (doc, _) = open(&hound_path).unwrap();
    let rig_pose = RigPose::new(&c, &doc).unwrap();
    let mut scratch = RigScratch::default();
    let expected: Vec<Vec<NodeTransform>> = poses
        .iter()
        .map(|p| {
            let mut out = Vec::new();
            rig_pose.write(&c.tree, p, &mut scratch, &mut out).unwrap();
            out
        })
        .collect();
    let driven = rig_pose.driven();
    let body_root = &driven[0];
    assert!(body_root.translates, "the body root carries the root motion");
    // F_b: each node's world matrix at rest, composed from the source file's nodes.
    let mut parent = vec![None; doc.nodes().len()];
    for nd in doc.nodes() {
        for ch in nd.children() {
            parent[ch.index()] = Some(nd.index());
        }
    }
    let local = |i: usize| Matrix4::from(doc.nodes().nth(i).unwrap().transform().matrix());
    let rest_world: Vec<Matrix4<f32>> = (0..doc.nodes().len())
        .map(|mut i| {
            let mut m = local(i);
            while let Some(p) = parent[i] {
                m = local(p) * m;
                i = p;
            }
            m
        })
        .collect();
    // The creature's size (file units): the diagonal of its skinned rest vertices' bounding box.
    let (lo, hi) = c.rig.vertices.iter().fold(
        (Vector3::repeat(f32::INFINITY), Vector3::repeat(f32::NEG_INFINITY)),
        |(lo, hi), (p, _)| (lo.inf(&p.coords), hi.sup(&p.coords)),
    );
    let size = (hi - lo).norm() / c.rig.scale;
    assert!(size.is_finite() && size > 0.0, "size {size}");
    let (pos_tol, rot_tol) = (1e-3 * size, 1e-3);

    // Bevy plays the file: its scene, its glTF asset's animation named after the clip.
    let mut app = app(&dir);
    let server = app.world().resource::<AssetServer>().clone();
    let gltf: Handle<Gltf> = server.load("hound_walk.glb");
    let scene = app.world_mut().spawn(WorldAssetRoot(server.load(GltfAssetLabel::Scene(0).from_asset("hound_walk.glb")))).id();
    let mut animated = None;
    // Until the scene has spawned completely: on a loaded machine its player can exist a frame before
    // the instance is done, and what the test sets on it then would be overwritten.
    update_until(&mut app, |w| {
        if let LoadState::Failed(e) = w.resource::<AssetServer>().load_state(&gltf) {
            panic!("Bevy's glTF loader refused the rig clip: {e}");
        }
        let ready = w
            .get::<WorldInstance>(scene)
            .is_some_and(|i| w.get_resource::<WorldInstanceSpawner>().is_some_and(|s| s.instance_is_ready(**i)));
        animated = w.query_filtered::<Entity, With<AnimationPlayer>>().iter(w).next();
        ready && animated.is_some() && w.resource::<Assets<Gltf>>().get(&gltf).is_some()
    });
    let animated = animated.unwrap();
    assert_eq!(app.world_mut().query::<&AnimationPlayer>().iter(app.world()).count(), 1, "one animation player");
    let g = app.world().resource::<Assets<Gltf>>().get(&gltf).unwrap();
    assert_eq!(g.animations.len(), 1, "the clip alone: the model's own animations are dropped by default");
    let walk = g.named_animations.get(clip_name.as_str()).unwrap_or_else(|| panic!("no animation named {clip_name}")).clone();
    {
        let clips = app.world().resource::<Assets<AnimationClip>>();
        let clip = clips.get(&walk).expect("the walk clip loaded");
        let last = (poses.len() - 1) as f32 / FPS;
        assert!((clip.duration() - last).abs() < 1e-5, "clip lasts {} s, the poses {last} s", clip.duration());
        assert_eq!(clip.curves().len(), driven.len(), "one target per driven bone");
    }

    // The scene's node entities the player animates, by name; each name once. (The entity of the scene
    // itself is named after the glTF scene, `Hound` as the armature's node: it is no animation target.)
    let mut by_name: HashMap<String, Vec<Entity>> = HashMap::new();
    for (e, n) in app.world_mut().query_filtered::<(Entity, &Name), With<AnimationTargetId>>().iter(app.world()) {
        by_name.entry(n.as_str().to_owned()).or_default().push(e);
    }
    let entity = |name: &str| {
        let found = by_name.get(name).map(Vec::as_slice).unwrap_or_default();
        assert_eq!(found.len(), 1, "one entity named {name}");
        found[0]
    };
    let driven_entities: Vec<Entity> = driven.iter().map(|d| entity(&d.name)).collect();
    let held: Vec<(Entity, Transform, String)> = rig_pose
        .held()
        .iter()
        .map(|(i, name)| (entity(name), node_transform(rig_pose.rest(*i)), name.clone()))
        .collect();
    // The armature root (the body root's parent) is held at rest: root motion is not on it.
    let armature = parent[body_root.node].expect("the body root hangs off an armature node");
    assert!(rig_pose.held().iter().any(|(i, _)| *i == armature), "the armature root is held at rest");
    let world_entities: Vec<Entity> = bone_worlds(&c, &rest_world, &poses[0]).iter().map(|(n, _)| entity(n)).collect();

    let (graph, node) = AnimationGraph::from_clip(walk);
    let graph = app.world_mut().resource_mut::<Assets<AnimationGraph>>().add(graph);
    app.world_mut().entity_mut(animated).insert(AnimationGraphHandle(graph));
    // Paused at 0 s for two frames (the graph's evaluation order is built the frame it is added).
    app.world_mut().get_mut::<AnimationPlayer>(animated).unwrap().play(node).pause();
    app.update();
    app.update();

    let mut gaps = Gaps::default();
    let compare = |app: &mut App, k: usize, gaps: &mut Gaps| {
        let seek = app.world().get::<AnimationPlayer>(animated).unwrap().animation(node).unwrap().seek_time();
        assert!((seek - k as f32 / FPS).abs() < 2e-5, "frame {k}: the player is at {seek} s, not on its keyframe");
        gaps.seek = gaps.seek.max((seek - k as f32 / FPS).abs());
        for ((d, &e), want) in driven.iter().zip(&driven_entities).zip(&expected[k]) {
            let got = *app.world().get::<Transform>(e).unwrap();
            let want = node_transform(want);
            let (dt, dr) = (got.translation.distance(want.translation), angle(got.rotation, want.rotation));
            assert!(
                dt < pos_tol && dr < rot_tol,
                "frame {k}, bone {}: Bevy's local transform {got:?} is {dt} file units and {dr} rad from the \
                 retargeted pose's {want:?}",
                d.name
            );
            assert!((got.scale - want.scale).abs().max_element() < 1e-6, "frame {k}, bone {}: scale {}", d.name, got.scale);
            gaps.local_t = gaps.local_t.max(dt);
            gaps.local_r = gaps.local_r.max(dr);
        }
        for (e, rest, name) in &held {
            let got = *app.world().get::<Transform>(*e).unwrap();
            assert!(
                got.translation.distance(rest.translation) < 1e-6 && angle(got.rotation, rest.rotation) < 1e-6,
                "frame {k}: {name}, held by the pose, moved to {got:?} from its rest {rest:?}"
            );
        }
        // World transforms against the tree's pose, independently of `rig_pose` (the scene root at the
        // origin, so that the file's frame is the world's).
        for ((name, m), &e) in bone_worlds(&c, &rest_world, &poses[k]).iter().zip(&world_entities) {
            let got = app.world().get::<GlobalTransform>(e).unwrap().compute_transform();
            let want = Transform::from_matrix(Mat4::from_cols_slice(m.as_slice()));
            let (dt, dr) = (got.translation.distance(want.translation), angle(got.rotation, want.rotation));
            assert!(dt < pos_tol && dr < rot_tol, "frame {k}, bone {name}: world {dt} file units and {dr} rad from the tree's pose");
            gaps.world_t = gaps.world_t.max(dt);
            gaps.world_r = gaps.world_r.max(dr);
        }
        // Root motion: the body root's node stands where the tree puts its link (character frame, metres).
        let at = app.world().get::<GlobalTransform>(driven_entities[0]).unwrap().translation();
        let in_character = c.rig.to_character * Vector3::new(at.x, at.y, at.z) * c.rig.scale;
        let root = c.tree.forward_kinematics(&poses[k])[body_root.link].translation.vector;
        assert!(
            (in_character - root).norm() < 1e-3 * size * c.rig.scale,
            "frame {k}: the body root's node is at {in_character} (m), its link at {root}"
        );
    };

    compare(&mut app, 0, &mut gaps);
    app.world_mut().get_mut::<AnimationPlayer>(animated).unwrap().animation_mut(node).unwrap().resume();
    // One keyframe per fixed step: every frame of the clip, the last one included.
    for k in 1..poses.len() {
        app.update();
        compare(&mut app, k, &mut gaps);
    }
    eprintln!(
        "creature size {size} file units; worst gaps over {} frames: the player {} s off the keyframes, local \
         {} file units and {} rad, world {} file units and {} rad",
        poses.len(),
        gaps.seek,
        gaps.local_t,
        gaps.local_r,
        gaps.world_t,
        gaps.world_r
    );

    // The comparison can fail: the clip moves the bones away from rest and the root across the ground.
    let rest_rotation = |i: usize| node_transform(rig_pose.rest(driven[i].node)).rotation;
    let turned = (0..driven.len()).map(|i| angle(node_transform(&expected[40][i]).rotation, rest_rotation(i))).fold(0.0, f32::max);
    assert!(turned > 0.05, "the bones are {turned} rad from rest at frame 40");
    let travel = (poses.last().unwrap().root.translation.vector - poses[0].root.translation.vector).xy().norm();
    assert!(travel > 0.1 * size * c.rig.scale, "the walk moves the hound {travel} m");
    let moved = expected.last().unwrap()[0].translation - expected[0][0].translation;
    assert!(moved.norm() > 0.1 * size, "the body root's node moved {} file units", moved.norm());
}
