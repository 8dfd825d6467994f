//! Headless ECS tests of the plugin: `MinimalPlugins`, no window, a manual time step. Assets load
//! through the asset server from the bundled `assets/` folder.

use std::time::Duration;

use ace::models::human::{HumanClip, ImportOptions, Joint};
use ace::models::kinematics::CharacterPose;
use ace::models::nalgebra::{Isometry3, Translation3, UnitQuaternion};
use ace::models::runtime::{RetargetedMotion, Retargeter as Offline};
use ace::plugin::convert;
use ace::plugin::prelude::*;
use bevy::asset::LoadState;
use bevy::prelude::*;
use bevy::time::TimeUpdateStrategy;

mod common;
use common::shared;
use common::support::*;

#[test]
fn character_link_transforms_equal_models_forward_kinematics() {
    let mut app = app();
    let placement = Transform::from_xyz(1.0, 0.0, -2.0).with_rotation(Quat::from_rotation_y(0.7));
    let handle: Handle<CharacterAsset> = app.world().resource::<AssetServer>().load("characters/spot.urdf");
    let character = app.world_mut().spawn((Character::new(handle.clone()), placement)).id();
    update_until(&mut app, |w| w.get::<CharacterLinks>(character).is_some());

    let urdf = app.world().resource::<Assets<CharacterAsset>>().get(&handle).unwrap().clone();
    // Every joint away from zero, inside its limits; root lifted, turned and tilted.
    let mut q: Vec<f32> = (0..urdf.tree.dof()).map(|i| 0.4 * ((i as f32) * 1.3).sin()).collect();
    urdf.tree.clamp(&mut q);
    let pose = CharacterPose {
        root: Isometry3::from_parts(Translation3::new(0.3, -0.2, 0.55), UnitQuaternion::from_euler_angles(0.1, -0.05, 0.8)),
        q,
    };
    app.world_mut().entity_mut(character).insert(Pose(pose.clone()));
    app.update();

    let expected = urdf.tree.forward_kinematics(&pose);
    let links = app.world().get::<CharacterLinks>(character).unwrap().0.clone();
    assert_eq!(links.len(), urdf.tree.links.len());
    for (i, &link) in links.iter().enumerate() {
        let got = app.world().get::<GlobalTransform>(link).unwrap().compute_transform();
        let want = placement * convert::transform(&expected[i]);
        assert_close(&got, &want, &urdf.tree.links[i].name);
    }
}

#[test]
fn every_bundled_character_spawns_one_entity_per_link() {
    let mut app = app();
    let server = app.world().resource::<AssetServer>().clone();
    let names = ["spot", "crab", "stretch"];
    let entities: Vec<Entity> = names
        .iter()
        .map(|n| app.world_mut().spawn(Character::new(server.load(format!("characters/{n}.urdf")))).id())
        .collect();
    update_until(&mut app, |w| entities.iter().all(|&e| w.get::<CharacterLinks>(e).is_some()));
    app.update();
    for (&e, name) in entities.iter().zip(names) {
        let character = app.world().get::<Character>(e).unwrap().asset.clone();
        let urdf = app.world().resource::<Assets<CharacterAsset>>().get(&character).unwrap().clone();
        let links = &app.world().get::<CharacterLinks>(e).unwrap().0;
        assert_eq!(links.len(), urdf.tree.links.len(), "{name}");
        // The neutral pose stands on the ground: the root link sits at the standing height.
        let root = app.world().get::<GlobalTransform>(links[0]).unwrap().translation();
        assert!((root.y - urdf.tree.standing_root_height()).abs() < 1e-5, "{name}: root at {root}");
    }
}

#[test]
fn clip_player_poses_the_human_skeleton_deterministically() {
    let mut app = app();
    let handle: Handle<BvhAsset> = app.world().resource::<AssetServer>().load("motions/walk.bvh");
    let player = app.world_mut().spawn(HumanClipPlayer::new(handle.clone())).id();
    update_until(&mut app, |w| w.get::<HumanJoints>(player).is_some());
    let t0 = app.world().get::<HumanClipPlayer>(player).unwrap().time;
    for _ in 0..20 {
        app.update();
    }
    let t1 = app.world().get::<HumanClipPlayer>(player).unwrap().time;
    assert!((t1 - t0 - 20.0 * DT).abs() < 1e-4, "20 fixed steps advanced {} s", t1 - t0);

    let clip = app.world().resource::<Assets<BvhAsset>>().get(&handle).unwrap().clip.clone();
    let frame = clip.frame_at(t1);
    let joints = app.world().get::<HumanJoints>(player).unwrap().0;
    for joint in Joint::ALL {
        let got = app.world().get::<GlobalTransform>(joints[joint.index()]).unwrap().translation();
        let want = convert::vec3(&frame.positions[joint.index()]);
        assert!(got.distance(want) < 1e-5, "{}: {got} vs {want}", joint.name());
    }
    // Z-up to Y-up: the head is above the pelvis in Bevy's frame.
    let head = app.world().get::<GlobalTransform>(joints[Joint::Head.index()]).unwrap().translation();
    let pelvis = app.world().get::<GlobalTransform>(joints[Joint::Pelvis.index()]).unwrap().translation();
    assert!(head.y > pelvis.y + 0.4);

    // Pausing freezes time; seeking moves it.
    app.world_mut().get_mut::<HumanClipPlayer>(player).unwrap().paused = true;
    app.update();
    app.update();
    assert_eq!(app.world().get::<HumanClipPlayer>(player).unwrap().time, t1);
    app.world_mut().get_mut::<HumanClipPlayer>(player).unwrap().seek(1.0);
    app.update();
    let pose = app.world().get::<HumanPose>(player).unwrap();
    assert_eq!(pose.positions, clip.frame_at(1.0).positions);
}

#[test]
fn a_broken_urdf_fails_to_load_with_a_message_and_no_panic() {
    let dir = std::path::Path::new(env!("CARGO_TARGET_TMPDIR")).join("headless-broken");
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join("loop.urdf");
    std::fs::write(
        &path,
        r#"<robot name="loop">
  <link name="a"/><link name="b"/>
  <joint name="ab" type="fixed"><parent link="a"/><child link="b"/></joint>
  <joint name="ba" type="fixed"><parent link="b"/><child link="a"/></joint>
</robot>"#,
    )
    .unwrap();
    let mut app = app_with_assets(dir.to_str().unwrap());
    let handle: Handle<CharacterAsset> = app.world().resource::<AssetServer>().load("loop.urdf");
    let character = app.world_mut().spawn(Character::new(handle.clone())).id();
    let mut state = LoadState::Loading;
    update_until(&mut app, |w| {
        state = w.resource::<AssetServer>().load_state(&handle);
        matches!(state, LoadState::Failed(_))
    });
    let LoadState::Failed(err) = state else { unreachable!() };
    let msg = err.to_string();
    assert!(msg.contains("loop.urdf"), "{msg}");
    assert!(msg.to_lowercase().contains("cycle") || msg.to_lowercase().contains("root"), "{msg}");
    assert!(app.world().get::<CharacterLinks>(character).is_none());
}

/// A profile beside a character that cannot be read (here a folder by its name) fails the load,
/// naming the profile, rather than giving the automatic body plan as though it were not there.
#[test]
fn an_unreadable_profile_beside_a_character_is_an_error() {
    let dir = std::path::Path::new(env!("CARGO_TARGET_TMPDIR")).join("headless-unreadable-profile");
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(dir.join("spot.profile.toml")).unwrap();
    std::fs::copy(concat!(env!("CARGO_MANIFEST_DIR"), "/assets/characters/spot.urdf"), dir.join("spot.urdf")).unwrap();
    std::fs::copy(concat!(env!("CARGO_MANIFEST_DIR"), "/assets/characters/spot.urdf"), dir.join("plain.urdf")).unwrap();
    let mut app = app_with_assets(dir.to_str().unwrap());
    let server = app.world().resource::<AssetServer>().clone();
    let plain: Handle<CharacterAsset> = server.load("plain.urdf");
    assert!(matches!(settled(&mut app, &plain), LoadState::Loaded), "no profile: the automatic body plan");
    let spot: Handle<CharacterAsset> = server.load("spot.urdf");
    let LoadState::Failed(err) = settled(&mut app, &spot) else { panic!("loaded without its profile") };
    assert!(err.to_string().contains("spot.profile.toml"), "{err}");
}

/// A joint mapping beside a clip that cannot be read (here a folder by its name) fails the clip's
/// load, naming it, rather than reading the clip as though it had none.
#[test]
fn an_unreadable_mapping_beside_a_clip_is_an_error() {
    let dir = std::path::Path::new(env!("CARGO_TARGET_TMPDIR")).join("headless-unreadable-mapping");
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(dir.join("walk.mapping.toml")).unwrap();
    for name in ["walk.bvh", "plain.bvh"] {
        std::fs::copy(concat!(env!("CARGO_MANIFEST_DIR"), "/assets/motions/walk.bvh"), dir.join(name)).unwrap();
    }
    let mut app = app_with_assets(dir.to_str().unwrap());
    let server = app.world().resource::<AssetServer>().clone();
    let plain: Handle<BvhAsset> = server.load("plain.bvh");
    assert!(matches!(settled(&mut app, &plain), LoadState::Loaded), "no mapping: the clip's own names");
    let walk: Handle<BvhAsset> = server.load("walk.bvh");
    let LoadState::Failed(err) = settled(&mut app, &walk) else { panic!("loaded without its mapping") };
    assert!(err.to_string().contains("walk.mapping.toml"), "{err}");
}

/// A checkpoint file that is there but cannot be read (here a folder in the prior's place) fails the
/// load with the reader's error, not as a missing file.
#[test]
fn an_unreadable_checkpoint_file_is_not_reported_missing() {
    let dir = std::path::Path::new(env!("CARGO_TARGET_TMPDIR")).join("headless-unreadable-checkpoint");
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(dir.join("crab/prior.safetensors")).unwrap();
    for name in ["ace.json", "config.json", "generator.safetensors"] {
        std::fs::copy(std::path::Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/assets/checkpoints/crab")).join(name), dir.join("crab").join(name)).unwrap();
    }
    let mut app = app_with_assets(dir.to_str().unwrap());
    let checkpoint: Handle<CheckpointAsset> = app.world().resource::<AssetServer>().load("crab/ace.json");
    let LoadState::Failed(err) = settled(&mut app, &checkpoint) else { panic!("loaded without its prior") };
    let msg = err.to_string();
    assert!(msg.contains("prior.safetensors") && !msg.contains("missing"), "{msg}");
}

/// Files over the core's bound for their kind fail their load as the CLI refuses them, once that many
/// bytes are read or, from a file source, from their size (an asset source need not know a file's
/// size): a URDF and a checkpoint's `ace.json` of more than [`ace::models::input::MAX_TEXT_BYTES`], and
/// the files read beside one: a profile, a clip's joint mapping and a checkpoint's generator weights
/// (of more than [`ace::models::input::MAX_DATA_BYTES`]; sparse files of zeros, refused unread).
#[test]
fn asset_files_over_their_kinds_bound_fail_to_load() {
    use ace::models::input::{MAX_DATA_BYTES, MAX_TEXT_BYTES};
    let dir = std::path::Path::new(env!("CARGO_TARGET_TMPDIR")).join("headless-huge");
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(dir.join("ck")).unwrap();
    std::fs::create_dir_all(dir.join("crab")).unwrap();
    let sparse = |name: &str, len: u64| std::fs::File::create(dir.join(name)).unwrap().set_len(len).unwrap();
    sparse("huge.urdf", MAX_TEXT_BYTES + 1);
    sparse("ck/ace.json", MAX_TEXT_BYTES + 1);
    let manifest = std::path::Path::new(env!("CARGO_MANIFEST_DIR"));
    std::fs::copy(manifest.join("assets/characters/spot.urdf"), dir.join("spot.urdf")).unwrap();
    std::fs::copy(manifest.join("assets/characters/spot.urdf"), dir.join("profiled.urdf")).unwrap();
    sparse("profiled.profile.toml", MAX_TEXT_BYTES + 1);
    std::fs::copy(manifest.join("assets/motions/walk.bvh"), dir.join("walk.bvh")).unwrap();
    sparse("walk.mapping.toml", MAX_TEXT_BYTES + 1);
    for name in ["ace.json", "config.json", "prior.safetensors"] {
        std::fs::copy(manifest.join("assets/checkpoints/crab").join(name), dir.join("crab").join(name)).unwrap();
    }
    sparse("crab/generator.safetensors", MAX_DATA_BYTES + 1);
    let mut app = app_with_assets(dir.to_str().unwrap());
    let server = app.world().resource::<AssetServer>().clone();
    let spot: Handle<CharacterAsset> = server.load("spot.urdf");
    assert!(matches!(settled(&mut app, &spot), LoadState::Loaded));
    let urdf: Handle<CharacterAsset> = server.load("huge.urdf");
    let profiled: Handle<CharacterAsset> = server.load("profiled.urdf");
    let checkpoint: Handle<CheckpointAsset> = server.load("ck/ace.json");
    let crab: Handle<CheckpointAsset> = server.load("crab/ace.json");
    let clip: Handle<BvhAsset> = server.load("walk.bvh");
    let states = [
        (settled(&mut app, &urdf), "huge.urdf", MAX_TEXT_BYTES),
        (settled(&mut app, &profiled), "profiled.profile.toml", MAX_TEXT_BYTES),
        (settled(&mut app, &checkpoint), "ck/ace.json", MAX_TEXT_BYTES),
        (settled(&mut app, &crab), "crab/generator.safetensors", MAX_DATA_BYTES),
        (settled(&mut app, &clip), "walk.mapping.toml", MAX_TEXT_BYTES),
    ];
    for (state, file, max) in states {
        let LoadState::Failed(err) = state else { panic!("loaded over the bound of {file}") };
        let want = format!("{file}: the file has more than the {max} bytes this kind of file may have");
        assert!(err.to_string().contains(&want), "{err}");
    }
}

/// The load state of `handle` once it is no longer loading.
fn settled<A: Asset>(app: &mut App, handle: &Handle<A>) -> LoadState {
    let mut state = LoadState::Loading;
    update_until(app, |w| {
        state = w.resource::<AssetServer>().load_state(handle);
        matches!(state, LoadState::Loaded | LoadState::Failed(_))
    });
    state
}

/// The BVH loader reads the clip's joint mapping as the CLI does: `<clip>.mapping.toml` beside it, or
/// the file its settings name. Without it a rig of unknown joint names fails to load.
#[test]
fn the_bvh_loader_reads_the_mapping_beside_the_clip_or_in_its_settings() {
    let dir = std::path::Path::new(env!("CARGO_TARGET_TMPDIR")).join("headless-mapping");
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(dir.join("maps")).unwrap();
    let data = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("models/tests/data");
    for name in ["rig.bvh", "bare.bvh", "named.bvh", "missing.bvh"] {
        std::fs::copy(data.join("unknown_rig.bvh"), dir.join(name)).unwrap();
    }
    std::fs::copy(data.join("unknown_rig.toml"), dir.join("rig.mapping.toml")).unwrap();
    std::fs::copy(data.join("unknown_rig.toml"), dir.join("maps/m.toml")).unwrap();
    let mut app = app_with_assets(dir.to_str().unwrap());
    let server = app.world().resource::<AssetServer>().clone();
    let beside: Handle<BvhAsset> = server.load("rig.bvh");
    let bare: Handle<BvhAsset> = server.load("bare.bvh");
    let named: Handle<BvhAsset> =
        server.load_builder().with_settings(|s: &mut BvhSettings| s.mapping = Some("maps/m.toml".into())).load("named.bvh");
    for handle in [&beside, &named] {
        assert!(matches!(settled(&mut app, handle), LoadState::Loaded));
        let clip = app.world().resource::<Assets<BvhAsset>>().get(handle).unwrap().clip.clone();
        assert_eq!((clip.convention.as_str(), clip.mapped_joints), ("user-mapping", 17));
    }
    let LoadState::Failed(err) = settled(&mut app, &bare) else { panic!("bare.bvh loaded without a mapping") };
    assert!(err.to_string().contains("unknown skeleton"), "{err}");
    // A mapping named in the settings must be there.
    let missing: Handle<BvhAsset> =
        server.load_builder().with_settings(|s: &mut BvhSettings| s.mapping = Some("maps/none.toml".into())).load("missing.bvh");
    let LoadState::Failed(err) = settled(&mut app, &missing) else { panic!("loaded without its mapping file") };
    assert!(err.to_string().contains("maps/none.toml"), "{err}");
}


// ---- Rigged glTF creatures driven through their own glTF scene ----

use std::path::{Path, PathBuf};
use std::sync::OnceLock;

use ace::models::character::{Creature, load_creature};
use ace::models::nalgebra::{Matrix4, Vector3};
use bevy::gltf::{Gltf, GltfPlugin};
use bevy::world_serialization::{WorldAsset, WorldAssetRoot, WorldSerializationPlugin};

/// A folder of assets for the creature tests: the bundled hound, a copy of it with its last tail bone
/// renamed (`Tale3`), the walk clip, Spot's URDF and checkpoint, and a tiny hound checkpoint trained
/// once per run with `ace train-prior` and `ace train` (as the CLI tests' tiny trainings).
fn creature_assets() -> &'static Path {
    static DIR: OnceLock<PathBuf> = OnceLock::new();
    DIR.get_or_init(|| {
        let dir = Path::new(env!("CARGO_TARGET_TMPDIR")).join("headless-creature");
        let _ = std::fs::remove_dir_all(&dir);
        for sub in ["creatures", "motions", "characters", "checkpoints/spot", "checkpoints/hound"] {
            std::fs::create_dir_all(dir.join(sub)).unwrap();
        }
        let hound = std::fs::read(asset_path("creatures/hound.glb")).unwrap();
        std::fs::write(dir.join("creatures/hound.glb"), &hound).unwrap();
        let json_len = u32::from_le_bytes(hound[12..16].try_into().unwrap()) as usize;
        let at = hound[20..20 + json_len].windows(7).position(|w| w == b"\"Tail3\"").expect("the hound has a bone Tail3") + 20;
        let mut renamed = hound.clone();
        renamed[at..at + 7].copy_from_slice(b"\"Tale3\"");
        std::fs::write(dir.join("creatures/renamed.glb"), renamed).unwrap();
        std::fs::copy(asset_path("motions/walk.bvh"), dir.join("motions/walk.bvh")).unwrap();
        std::fs::copy(asset_path("characters/spot.urdf"), dir.join("characters/spot.urdf")).unwrap();
        for f in ["ace.json", "config.json", "prior.safetensors", "generator.safetensors"] {
            std::fs::copy(asset_path("checkpoints/spot").join(f), dir.join("checkpoints/spot").join(f)).unwrap();
        }
        train_tiny(&dir, "creatures/hound.glb", "checkpoints/hound");
        dir
    })
}

/// Trains a tiny checkpoint for the creature `dir/glb` into `dir/checkpoint` (a few seconds).
fn train_tiny(dir: &Path, glb: &str, checkpoint: &str) {
    let (prior, ace_cfg, ck) = (dir.join("prior.toml"), dir.join("ace.toml"), dir.join(checkpoint));
    std::fs::write(&prior, "steps = 60\nbatch_size = 16\ncheckpoint_every = 60\nencoder_hidden = [32, 32]\ndecoder_hidden = [32, 32]\n").unwrap();
    std::fs::write(&ace_cfg, "steps = 20\nbatch_size = 8\ncheckpoint_every = 20\ngenerator_hidden = [32, 32]\ndiscriminator_hidden = [32, 32]\n").unwrap();
    let glb = dir.join(glb);
    let s = |p: &Path| p.to_str().unwrap().to_string();
    for args in [
        vec!["--threads", "1", "train-prior", "--character", &s(&glb), "--frames", "2000", "--config", &s(&prior), "--checkpoint", &s(&ck)],
        vec!["--threads", "1", "train", "--character", &s(&glb), "--config", &s(&ace_cfg), "--checkpoint", &s(&ck), "--humans", "assets/motions"],
    ] {
        let out = std::process::Command::new(env!("CARGO_BIN_EXE_ace"))
            .args(&args)
            .current_dir(env!("CARGO_MANIFEST_DIR"))
            .output()
            .unwrap();
        assert!(out.status.success(), "ace {args:?}: {}", String::from_utf8_lossy(&out.stderr));
    }
}

/// A headless app that also loads glTF scenes (Bevy's loader, without a renderer).
fn creature_app() -> App {
    creature_app_in(creature_assets())
}

fn creature_app_in(assets: &Path) -> App {
    creature_app_ordered(assets, false)
}

/// A creature app with `AcePlugin` added before Bevy's glTF plugin when `ace_first` (the plugin's
/// character loader registered before Bevy's glTF loader), after it otherwise.
fn creature_app_ordered(assets: &Path, ace_first: bool) -> App {
    let mut app = App::new();
    app.add_plugins((
        MinimalPlugins,
        AssetPlugin { file_path: assets.to_str().unwrap().into(), ..default() },
        TransformPlugin,
        WorldSerializationPlugin,
        bevy::mesh::MeshPlugin,
        bevy::image::ImagePlugin::default(),
        bevy::animation::AnimationPlugin,
    ));
    if ace_first {
        app.add_plugins((AcePlugin, GltfPlugin::default()));
    } else {
        app.add_plugins((GltfPlugin::default(), AcePlugin));
    }
    app.insert_resource(TimeUpdateStrategy::ManualDuration(Duration::from_secs_f32(DT)))
        .init_resource::<SeenErrors>()
        .add_systems(Last, record_errors);
    // Bevy's glTF loader is registered when the plugins finish (`App::run` does this).
    app.finish();
    app.cleanup();
    app
}

/// Asserts that in the built `PostUpdate` schedule every system of the plugin's sets that touches what
/// a system of Bevy's `AnimationSystems` touches is ordered after it: on the nodes a Retargeter
/// drives, the plugin's pose wins whichever way the executor would break a tie. Bevy's
/// `animate_targets` is `ambiguous_with_all`, so Bevy's ambiguity analysis never reports it; a
/// stand-in writing `Transform`s as it does joins `AnimationSystems` (and never runs).
fn assert_ace_systems_run_after_animation(app: &mut App) {
    use bevy::app::AnimationSystems;
    use bevy::ecs::schedule::Schedules;
    #[derive(SystemSet, Debug, Clone, PartialEq, Eq, Hash)]
    struct StandIn;
    fn writes_transforms_as_animate_targets_does(_: Query<&mut Transform>) {}
    app.add_systems(
        PostUpdate,
        writes_transforms_as_animate_targets_does.in_set(AnimationSystems).in_set(StandIn).run_if(|| false),
    );
    app.update();
    let schedule = app.world().resource::<Schedules>().get(PostUpdate).unwrap();
    let graph = schedule.graph();
    let animation = graph.systems_in_set(AnimationSystems.intern()).unwrap();
    let stand_in = graph.systems_in_set(StandIn.intern()).unwrap();
    assert!(stand_in.len() == 1 && stand_in.iter().all(|k| animation.contains(k)), "the stand-in is in AnimationSystems");
    let mut ace = Vec::new();
    for set in [AceSystems::Spawn, AceSystems::Advance, AceSystems::Retarget, AceSystems::Apply] {
        ace.extend(graph.systems_in_set(set.intern()).unwrap().iter().map(|&k| (k, set)));
    }
    // (The graph's systems moved into the built schedule: names come from there.)
    let names: std::collections::HashMap<_, String> = schedule.systems().unwrap().map(|(k, s)| (k, s.name().to_string())).collect();
    let unordered: Vec<String> = graph
        .conflicting_systems()
        .iter()
        .flat_map(|(a, b, _)| [(a, b), (b, a)])
        .filter(|(a, _)| animation.contains(*a))
        .filter_map(|(a, b)| ace.iter().find(|(k, _)| k == b).map(|(_, set)| format!("{} and {} in {set:?}", names[a], names[b])))
        .collect();
    assert!(unordered.is_empty(), "not ordered after Bevy's animation: {unordered:?}");
}

/// The plugin's systems run after Bevy's animation: an order the executor's tie-break cannot decide.
#[test]
fn the_plugins_systems_are_ordered_after_bevys_animation() {
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR")).join("headless-ordering");
    std::fs::create_dir_all(&dir).unwrap();
    for ace_first in [false, true] {
        assert_ace_systems_run_after_animation(&mut creature_app_ordered(&dir, ace_first));
    }
}

/// Bevy's animation beside a Retargeter: the Fox plays its own Walk clip through its `AnimationPlayer`
/// while a Retargeter drives it; the bones show the Retargeter's poses (it writes after the animation).
#[test]
fn a_retargeter_wins_over_the_scenes_playing_animation_player() {
    use bevy::animation::{AnimationClip, AnimationPlayer, graph::AnimationGraph};
    use bevy::gltf::GltfAssetLabel;
    let Some(fox_glb) = shared("creatures/Fox/Fox.glb") else { return };
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR")).join("headless-fox");
    let _ = std::fs::remove_dir_all(&dir);
    for sub in ["creatures", "motions"] {
        std::fs::create_dir_all(dir.join(sub)).unwrap();
    }
    std::fs::copy(&fox_glb, dir.join("creatures/Fox.glb")).unwrap();
    std::fs::copy(asset_path("motions/walk.bvh"), dir.join("motions/walk.bvh")).unwrap();
    train_tiny(&dir, "creatures/Fox.glb", "checkpoints/fox");
    let c = load_creature(&dir.join("creatures/Fox.glb")).unwrap();
    let clip = HumanClip::from_bvh_file(&asset_path("motions/walk.bvh"), &ImportOptions::default()).unwrap();
    let r = Offline::load(&dir.join("checkpoints/fox")).unwrap();
    let want = r.retarget_clip(&c.tree, &c.morphology, &clip).unwrap();

    let mut app = creature_app_in(&dir);
    // Without the plugin's ordering, animate_targets still ran first here (it comes first in the
    // schedule's topological order and shares Transform with the plugin's systems, so the executor
    // never overlaps them): the bones below would show the Retargeter's pose by that chance. The
    // order itself is checked.
    assert_ace_systems_run_after_animation(&mut app);
    let player = paused_player(&mut app, "walk.bvh");
    let server = app.world().resource::<AssetServer>().clone();
    // Everything the test loads from the Fox's file is loaded, and held, before its scene spawns. Bevy
    // may still respawn the scene while the test runs (in about one whole-binary run in ten): the
    // Retargeter follows (`a_scene_that_spawns_anew_is_driven_again`), and the Walk clip is played on
    // every AnimationPlayer that appears, as a game starts its clips.
    let walk: Handle<AnimationClip> = server.load(GltfAssetLabel::Animation(1).from_asset("creatures/Fox.glb"));
    let scene: Handle<WorldAsset> = server.load("creatures/Fox.glb#Scene0");
    let character: Handle<CharacterAsset> = server.load("creatures/Fox.glb");
    update_until(&mut app, |w| {
        let s = w.resource::<AssetServer>();
        s.is_loaded_with_dependencies(&walk) && s.is_loaded_with_dependencies(&scene) && s.is_loaded_with_dependencies(&character)
    });
    let (graph, node) = AnimationGraph::from_clip(walk.clone());
    let graph = app.world_mut().resource_mut::<Assets<AnimationGraph>>().add(graph);
    app.insert_resource(PlayWalk(graph, node)).add_systems(Update, play_walk);
    let fox = app
        .world_mut()
        .spawn((WorldAssetRoot(scene.clone()), Retargeter::new(server.load("checkpoints/fox/ace.json"), player)))
        .id();
    update_until(&mut app, |w| w.query_filtered::<(), With<AnimationPlayer>>().iter(w).next().is_some());
    start_together(&mut app, player, &[fox]);
    for _ in 0..45 {
        app.update();
        let t = tick(&app, fox).unwrap();
        let (d, a) = bone_gap(&mut app, &c, &Transform::IDENTITY, &want.poses[t as usize]);
        assert!(d < 1e-4 / c.rig.scale && a < 1e-3, "tick {t}: bones {d} file units and {a} rad from the offline motion");
    }
    // Paused, the pose stays the Retargeter's while the Fox's clip keeps playing.
    app.world_mut().get_mut::<HumanClipPlayer>(player).unwrap().paused = true;
    for _ in 0..10 {
        app.update();
    }
    let t = tick(&app, fox).unwrap();
    let (d, a) = bone_gap(&mut app, &c, &Transform::IDENTITY, &want.poses[t as usize]);
    assert!(d < 1e-4 / c.rig.scale && a < 1e-3, "paused at tick {t}: bones {d} file units and {a} rad from the offline motion");
    // The Fox's own clip did play all along.
    assert!(app.world().resource::<Assets<AnimationClip>>().get(&walk).is_some(), "the Walk clip loaded");
    let mut players = app.world_mut().query::<&AnimationPlayer>();
    let elapsed = players.single(app.world()).unwrap().animation(node).map(|a| a.elapsed());
    assert!(elapsed.is_some_and(|e| e > 0.1), "the Walk clip played for {elapsed:?} s");
    assert!(app.world().resource::<SeenErrors>().0.is_empty());
    // And it moves the bones compared above: once the Retargeter is removed (its CreatureScene goes
    // with it), they leave the Retargeter's pose (the comparisons above would fail had the clip
    // written last).
    app.world_mut().entity_mut(fox).remove::<Retargeter>();
    for _ in 0..5 {
        app.update();
    }
    assert!(app.world().get::<CreatureScene>(fox).is_none(), "the scene is released with its Retargeter");
    let (_, a) = bone_gap(&mut app, &c, &Transform::IDENTITY, &want.poses[t as usize]);
    assert!(a > 0.05, "the Fox's clip turns the bones {a} rad from the Retargeter's pose");
}

/// The Fox's Walk clip in its graph, played on every AnimationPlayer that appears.
#[derive(Resource)]
struct PlayWalk(Handle<bevy::animation::graph::AnimationGraph>, bevy::animation::graph::AnimationNodeIndex);

fn play_walk(mut commands: Commands, walk: Res<PlayWalk>, mut players: Query<(Entity, &mut bevy::animation::AnimationPlayer), Added<bevy::animation::AnimationPlayer>>) {
    for (e, mut player) in &mut players {
        commands.entity(e).insert(bevy::animation::graph::AnimationGraphHandle(walk.0.clone()));
        player.play(walk.1).repeat();
    }
}

fn hound() -> Creature {
    load_creature(&creature_assets().join("creatures/hound.glb")).unwrap()
}

/// The hound and the bundled walk clip retargeted onto it offline by the tiny hound checkpoint.
fn hound_walk() -> (Creature, RetargetedMotion) {
    let c = hound();
    let clip = HumanClip::from_bvh_file(&asset_path("motions/walk.bvh"), &ImportOptions::default()).unwrap();
    let r = Offline::load(&creature_assets().join("checkpoints/hound")).unwrap();
    let want = r.retarget_clip(&c.tree, &c.morphology, &clip).unwrap();
    (c, want)
}

/// The world matrix (file frame and units) of each rig bone of `c` in `pose`, straight from the tree:
/// `C⁻¹ · W_b · R_b⁻¹ · C · F_b` (see `ace_models::character::rig_pose`).
fn bone_worlds(c: &Creature, pose: &CharacterPose) -> Vec<(String, Matrix4<f32>)> {
    let fk = c.tree.forward_kinematics(pose);
    // F_b: each node's world matrix at rest, from the file.
    let (doc, _) = ace::models::character::gltf::open(c.tree.source.as_deref().unwrap()).unwrap();
    let mut parent = vec![None; doc.nodes().len()];
    for nd in doc.nodes() {
        for ch in nd.children() {
            parent[ch.index()] = Some(nd.index());
        }
    }
    let file_world = |mut i: usize| {
        let mut m = Matrix4::from(doc.nodes().nth(i).unwrap().transform().matrix());
        while let Some(p) = parent[i] {
            m = Matrix4::from(doc.nodes().nth(p).unwrap().transform().matrix()) * m;
            i = p;
        }
        m
    };
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
            let rest = file_world(b.node);
            Some((b.name.clone(), from_char * fk[link].to_homogeneous() * b.rest.inverse().to_homogeneous() * to_char * rest))
        })
        .collect()
}

fn named(app: &mut App, name: &str) -> Entity {
    let mut q = app.world_mut().query::<(Entity, &Name)>();
    let found: Vec<Entity> = q.iter(app.world()).filter(|(_, n)| n.as_str() == name).map(|(e, _)| e).collect();
    assert_eq!(found.len(), 1, "one entity named {name}");
    found[0]
}

/// Largest distance (file units) and rotation difference between the scene's bone entities and the
/// bones of `pose` placed by `origin`.
fn bone_gap(app: &mut App, c: &Creature, origin: &Transform, pose: &CharacterPose) -> (f32, f32) {
    let (mut d, mut a) = (0.0f32, 0.0f32);
    for (name, m) in bone_worlds(c, pose) {
        let e = named(app, &name);
        let got = app.world().get::<GlobalTransform>(e).unwrap().compute_transform();
        let want = *origin * Transform::from_matrix(Mat4::from_cols_slice(m.as_slice()));
        d = d.max(got.translation.distance(want.translation));
        a = a.max((got.rotation - want.rotation).length().min((got.rotation + want.rotation).length()));
    }
    (d, a)
}

/// The hound's glTF scene, driven by its checkpoint through a Retargeter, moves its bones (every rig
/// bone in the tree, driven or not) as `ace retarget`'s poses say, frame for frame; root motion moves
/// the entity.
#[test]
fn a_creature_scene_moves_as_ace_retarget_writes_it() {
    let (c, want) = hound_walk();
    let size = 1.0 / c.rig.scale; // a metre in file units

    let mut app = creature_app();
    let player = paused_player(&mut app, "walk.bvh");
    let server = app.world().resource::<AssetServer>().clone();
    let placement = Transform::from_xyz(1.0, 0.0, -2.0).with_rotation(Quat::from_rotation_y(0.7));
    let hound = app
        .world_mut()
        .spawn((
            WorldAssetRoot(server.load("creatures/hound.glb#Scene0")),
            Retargeter::new(server.load("checkpoints/hound/ace.json"), player),
            placement,
        ))
        .id();
    start_together(&mut app, player, &[hound]);
    let mut seen = Vec::new();
    for _ in 0..90 {
        app.update();
        let t = tick(&app, hound).unwrap();
        let pose = &want.poses[t as usize];
        let (d, a) = bone_gap(&mut app, &c, &placement, pose);
        assert!(d < 1e-4 * size && a < 1e-3, "tick {t}: bones {d} file units and {a} rad from the offline motion");
        // Root motion: the entity stands over the root, in the character's world placed by `placement`.
        let at = app.world().get::<Transform>(hound).unwrap().translation;
        let local = placement.compute_affine().inverse().transform_point3(at);
        let ground = c.rig.to_character * Vector3::new(local.x, local.y, local.z) * c.rig.scale;
        let root = pose.root.translation.vector;
        assert!((ground - Vector3::new(root.x, root.y, 0.0)).norm() < 1e-4, "tick {t}: entity at {ground}, root at {root}");
        seen.push(t);
    }
    assert_eq!(seen, (0..90).collect::<Vec<i64>>());
    // The clip moves the hound's bones away from its rest pose (so the comparison above can fail).
    let (_, turned) = bone_gap(&mut app, &c, &placement, &c.tree.standing_pose());
    assert!(turned > 0.05, "the bones are {turned} rad from rest");
    assert_eq!(app.world().get::<RootOrigin>(hound).map(|o| o.0), Some(placement));
    assert!(app.world().resource::<SeenErrors>().0.is_empty());
}

/// A scene that spawns anew (Bevy respawns every instance of a scene whose asset is replaced: here the
/// file reloaded, as a hot reload does) has new joint entities: the Retargeter finds them and keeps
/// driving the creature, in the same frame, instead of writing to the despawned ones while the new
/// skeleton stands at rest.
#[test]
fn a_scene_that_spawns_anew_is_driven_again() {
    let (c, want) = hound_walk();
    let size = 1.0 / c.rig.scale;
    let mut app = creature_app();
    let player = paused_player(&mut app, "walk.bvh");
    let server = app.world().resource::<AssetServer>().clone();
    let hound = app
        .world_mut()
        .spawn((WorldAssetRoot(server.load("creatures/hound.glb#Scene0")), Retargeter::new(server.load("checkpoints/hound/ace.json"), player)))
        .id();
    start_together(&mut app, player, &[hound]);
    for _ in 0..5 {
        app.update();
    }
    let tail = named(&mut app, "Tail3");
    server.reload("creatures/hound.glb#Scene0");
    let mut respawned = 0;
    // The reload reads and parses the file on Bevy's task pools, which the parallel tests share: every
    // frame but the clip's last ten may wait for it, each giving it a few milliseconds.
    let waiting = want.poses.len() as i64 - 10 - tick(&app, hound).unwrap();
    for _ in 0..waiting {
        app.update();
        let t = tick(&app, hound).unwrap();
        if app.world().get_entity(tail).is_ok() {
            std::thread::sleep(std::time::Duration::from_millis(5));
            continue;
        }
        respawned += 1;
        let (d, a) = bone_gap(&mut app, &c, &Transform::IDENTITY, &want.poses[t as usize]);
        assert!(d < 1e-4 * size && a < 1e-3, "tick {t}, {respawned} frames after the scene spawned anew: bones {d} file units and {a} rad from the offline motion");
    }
    assert!(respawned >= 10, "the scene spawned anew {respawned} frames before the end");
    assert_ne!(named(&mut app, "Tail3"), tail);
    assert!(app.world().resource::<SeenErrors>().0.is_empty());
}

/// `load::<CharacterAsset>("x.glb")` is the plugin's loader; `"x.glb#Scene0"` and `load::<Gltf>` stay
/// Bevy's, whichever load comes first and whichever loader was registered first (a labelled path goes
/// to the last loader registered for its extension, and `GltfPlugin` reserves its loader's place
/// when added: a loader claiming `.glb` in a plugin added after it would take `#Scene0`).
#[test]
fn glb_files_load_as_characters_by_type_and_as_scenes_by_label() {
    for (ace_first, character_first) in [(false, true), (false, false), (true, true), (true, false)] {
        let mut app = creature_app_ordered(creature_assets(), ace_first);
        let server = app.world().resource::<AssetServer>().clone();
        let (character, scene, gltf): (Handle<CharacterAsset>, Handle<WorldAsset>, Handle<Gltf>) = if character_first {
            let c = server.load("creatures/hound.glb");
            (c, server.load("creatures/hound.glb#Scene0"), server.load("creatures/hound.glb"))
        } else {
            let s = server.load("creatures/hound.glb#Scene0");
            let g = server.load("creatures/hound.glb");
            (server.load("creatures/hound.glb"), s, g)
        };
        update_until(&mut app, |w| {
            let s = w.resource::<AssetServer>();
            [character.id().untyped(), scene.id().untyped(), gltf.id().untyped()]
                .iter()
                .all(|&id| matches!(s.get_load_state(id), Some(LoadState::Loaded | LoadState::Failed(_))))
        });
        let why = format!("ace first: {ace_first}, character first: {character_first}");
        let c = app.world().resource::<Assets<CharacterAsset>>().get(&character).unwrap_or_else(|| panic!("{why}: a CharacterAsset"));
        assert_eq!(c.tree.name, "hound");
        assert_eq!(c.tree.dof(), hound().tree.dof());
        assert!(c.rig.is_some(), "a glTF character has its rig");
        let server = app.world().resource::<AssetServer>();
        assert!(matches!(server.get_load_state(scene.id()), Some(LoadState::Loaded)), "{why}: {:?}", server.get_load_state(scene.id()));
        assert!(app.world().resource::<Assets<WorldAsset>>().get(&scene).is_some(), "{why}: Bevy's scene");
        assert_eq!(app.world().resource::<Assets<Gltf>>().get(&gltf).map(|g| g.scenes.len()), Some(1), "{why}");
    }
}

fn failure(app: &App, e: Entity) -> String {
    let errors: Vec<&RetargetError> = app.world().resource::<SeenErrors>().0.iter().filter(|r| r.entity == e).collect();
    assert_eq!(errors.len(), 1, "one message per failure: {errors:?}");
    errors[0].message.clone()
}

#[test]
fn scenes_and_checkpoints_that_do_not_belong_together_are_errors_not_panics() {
    let mut app = creature_app();
    let player = paused_player(&mut app, "walk.bvh");
    let server = app.world().resource::<AssetServer>().clone();
    let mut spawn = |bundle: (WorldAssetRoot, Retargeter)| app.world_mut().spawn(bundle).id();
    // A URDF robot's checkpoint on the hound's scene.
    let spot_on_hound = spawn((
        WorldAssetRoot(server.load("creatures/hound.glb#Scene0")),
        Retargeter::new(server.load("checkpoints/spot/ace.json"), player),
    ));
    // The hound's checkpoint on a scene whose bones are not the hound's.
    let hound_on_renamed = spawn((
        WorldAssetRoot(server.load("creatures/renamed.glb#Scene0")),
        Retargeter::new(server.load("checkpoints/hound/ace.json"), player),
    ));
    // A scene whose joints are not those of the character it is said to be.
    let wrong_joints = spawn((
        WorldAssetRoot(server.load("creatures/renamed.glb#Scene0")),
        Retargeter::new(server.load("checkpoints/hound/ace.json"), player),
    ));
    app.world_mut()
        .entity_mut(wrong_joints)
        .insert(CreatureScene::new(server.load("creatures/hound.glb")));
    // The hound's checkpoint on a URDF robot.
    let hound_on_spot = app
        .world_mut()
        .spawn((
            Character::new(server.load("characters/spot.urdf")),
            Retargeter::new(server.load("checkpoints/hound/ace.json"), player),
        ))
        .id();
    let all = [spot_on_hound, hound_on_renamed, wrong_joints, hound_on_spot];
    let failed = |w: &mut World, e: Entity| matches!(w.get::<RetargetStatus>(e), Some(RetargetStatus::Failed(_)));
    update_until(&mut app, |w| all.iter().all(|&e| failed(w, e)));
    app.update();
    let m = failure(&app, spot_on_hound);
    assert!(m.contains("checkpoints/spot") && m.contains("does not fit character hound (a glTF creature)"), "{m}");
    assert!(m.contains("`spot`"), "{m}");
    let m = failure(&app, hound_on_renamed);
    assert!(m.contains("does not fit character renamed (a glTF creature)"), "{m}");
    let m = failure(&app, wrong_joints);
    assert!(m.contains("has no joint named `Tail3`") && m.contains("creature hound"), "{m}");
    let m = failure(&app, hound_on_spot);
    assert!(m.contains("checkpoints/hound") && m.contains("does not fit character spot (a URDF character)"), "{m}");
}
