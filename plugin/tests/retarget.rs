//! The `Retargeter` component, headless: characters driven by a checkpoint from a clip player or a live
//! source move exactly as `ace retarget` writes them, catch up on short jumps and start over on long
//! ones, and turn bad checkpoints and bad live frames into messages. (The rigged creatures' scenes are
//! tested in the `ace` crate's `tests/headless.rs`, which trains small checkpoints with the `ace` binary.)

use std::path::Path;
use std::time::Duration;

use ace_models::cleanup::Cleanup;
use ace_models::human::state::HumanState;
use ace_models::human::{HumanClip, HumanFrame, ImportOptions, Joint};
use ace_models::human_set::HumanRow;
use ace_models::kinematics::CharacterPose;
use ace_models::morphology::load_character;
use ace_models::nalgebra::UnitQuaternion;
use ace_models::runtime::{RetargetedMotion, Retargeter as Offline};
use ace_models::character::load_creature;
use bevy::asset::LoadState;
use bevy::prelude::*;
use bevy::time::TimeUpdateStrategy;
use bevy_ace::convert;
use bevy_ace::prelude::*;

mod support;
use support::*;
/// What `ace retarget` writes for a bundled clip and character with its shipped checkpoint (the CLI
/// calls this same function; the CLI tests check the files).
fn offline(character: &str, clip: &str) -> RetargetedMotion {
    offline_with(character, clip, Cleanup::default())
}

/// [`offline`] with another cleanup (`Cleanup::NONE` is `ace retarget --no-cleanup`).
fn offline_with(character: &str, clip: &str, cleanup: Cleanup) -> RetargetedMotion {
    let (tree, morph) = load_character(&asset_path(&format!("characters/{character}.urdf"))).unwrap();
    let mut r = Offline::load(&asset_path(&format!("checkpoints/{character}"))).unwrap();
    r.set_cleanup(cleanup);
    let clip = HumanClip::from_bvh_file(&asset_path(&format!("motions/{clip}")), &ImportOptions::default()).unwrap();
    r.retarget_clip(&tree, &morph, &clip).unwrap()
}

/// A driven character: its URDF and a retargeter on it.
fn spawn_driven(app: &mut App, character: &str, checkpoint: &str, source: Entity, x: f32) -> Entity {
    let server = app.world().resource::<AssetServer>().clone();
    app.world_mut()
        .spawn((
            Character::new(server.load(format!("characters/{character}.urdf"))),
            Retargeter::new(server.load(format!("checkpoints/{checkpoint}/ace.json")), source),
            Transform::from_xyz(x, 0.0, 0.0),
        ))
        .id()
}

/// Largest distance (m) and quaternion difference (about half the angle in rad, without the
/// rounding `angle_between` suffers near zero) between the character's link transforms and those of `pose`
/// placed by the character's transform.
fn link_gap(app: &App, e: Entity, pose: &CharacterPose) -> (f32, f32) {
    let character = app.world().get::<Character>(e).unwrap().asset.clone();
    let urdf = app.world().resource::<Assets<CharacterAsset>>().get(&character).unwrap().clone();
    // The character's world: where the entity stood when the first pose came (the entity itself
    // moves with the root's ground travel).
    let placement = app.world().get::<RootOrigin>(e).expect("a posed character has its RootOrigin").0;
    let expected = urdf.tree.forward_kinematics(pose);
    let links = &app.world().get::<CharacterLinks>(e).unwrap().0;
    let (mut d, mut a) = (0.0f32, 0.0f32);
    for (i, &link) in links.iter().enumerate() {
        let got = app.world().get::<GlobalTransform>(link).unwrap().compute_transform();
        let want = placement * convert::transform(&expected[i]);
        d = d.max(got.translation.distance(want.translation));
        a = a.max((got.rotation - want.rotation).length().min((got.rotation + want.rotation).length()));
    }
    (d, a)
}

/// Steps the app `ticks` frames from a source's tick 0: one tick per fixed step (one frame behind the
/// clip), each with the character's links within 0.1 mm and 0.001 of `want`'s pose at that tick.
fn plays_as_offline(app: &mut App, e: Entity, want: &RetargetedMotion, ticks: i64) {
    let mut seen = Vec::new();
    for _ in 0..ticks {
        app.update();
        let t = tick(app, e).unwrap();
        let (d, a) = link_gap(app, e, &want.poses[t as usize]);
        assert!(d < 1e-4 && a < 1e-3, "tick {t}: links {d} m and {a} rad from the offline motion");
        seen.push(t);
    }
    assert_eq!(seen, (0..ticks).collect::<Vec<i64>>());
}

/// Link transforms within 0.1 mm and 0.001 (quaternion difference) of the offline motion, frame
/// for frame.
#[test]
fn a_retargeted_character_moves_as_ace_retarget_writes_it() {
    let want = offline("spot", "walk.bvh");
    let mut app = retargeting_app();
    let player = paused_player(&mut app, "walk.bvh");
    let spot = spawn_driven(&mut app, "spot", "spot", player, 1.5);
    start_together(&mut app, player, &[spot]);
    plays_as_offline(&mut app, spot, &want, 90);
    let moved = want.poses[89].root.translation.vector - want.poses[0].root.translation.vector;
    assert!(moved.norm() > 0.3, "the walk moves Spot ({} m)", moved.norm());
    // Root motion is on the entity: it stands where it was placed times the root's ground travel, and
    // the root link over it, facing its +x.
    let origin = app.world().get::<RootOrigin>(spot).unwrap().0;
    assert_eq!(origin, Transform::from_xyz(1.5, 0.0, 0.0));
    let rest = load_character(&asset_path("characters/spot.urdf")).unwrap().0.standing_pose().root.rotation;
    let last = tick(&app, spot).unwrap() as usize;
    let entity = *app.world().get::<Transform>(spot).unwrap();
    assert_close(&entity, &(origin * convert::transform(&want.poses[last].ground_travel(&rest))), "the entity");
    assert!(entity.translation.distance(origin.translation) > 0.3, "the entity travels with the walk");
    let root_link = app.world().get::<CharacterLinks>(spot).unwrap().0[0];
    let local = app.world().get::<Transform>(root_link).unwrap();
    assert!(local.translation.x.abs() < 1e-4 && local.translation.z.abs() < 1e-4, "the root link stands over the entity: {local:?}");
    assert!(app.world().resource::<SeenErrors>().0.is_empty());
}

#[test]
fn one_clip_drives_several_characters_and_a_seek_back_starts_over() {
    let (spot_walk, crab_walk) = (offline("spot", "walk.bvh"), offline("crab", "walk.bvh"));
    let mut app = retargeting_app();
    let player = paused_player(&mut app, "walk.bvh");
    let characters = [
        spawn_driven(&mut app, "spot", "spot", player, 1.5),
        spawn_driven(&mut app, "spot", "spot", player, 3.0),
        spawn_driven(&mut app, "crab", "crab", player, -1.5),
    ];
    start_together(&mut app, player, &characters);
    for _ in 0..45 {
        app.update();
        for (&e, want) in characters.iter().zip([&spot_walk, &spot_walk, &crab_walk]) {
            let t = tick(&app, e).unwrap();
            // Batched with another character: equal up to the rounding of batched products.
            let (d, a) = link_gap(&app, e, &want.poses[t as usize]);
            assert!(d < 2e-3 && a < 2e-2, "tick {t}: links {d} m and {a} rad from the offline motion");
        }
    }
    assert_eq!(tick(&app, characters[0]), tick(&app, characters[2]));
    // Scrubbing back: every character starts again from rest at the new time.
    app.world_mut().get_mut::<HumanClipPlayer>(player).unwrap().paused = true;
    app.world_mut().get_mut::<HumanClipPlayer>(player).unwrap().seek(0.0);
    app.update();
    app.update();
    for (&e, want) in characters.iter().zip([&spot_walk, &spot_walk, &crab_walk]) {
        assert_eq!(tick(&app, e), Some(0));
        let (d, _) = link_gap(&app, e, &want.poses[0]);
        assert!(d < 2e-3, "restarted at the clip's first pose ({d} m away)");
    }
}

/// Each character keeps its own cleanup: Spot without any beside Spot with the default, on one
/// checkpoint and clip (one batch), each moves as `ace retarget` writes it with that cleanup.
#[test]
fn each_character_keeps_its_own_cleanup() {
    let (cleaned, raw) = (offline("spot", "walk.bvh"), offline_with("spot", "walk.bvh", Cleanup::NONE));
    let mut app = retargeting_app();
    let player = paused_player(&mut app, "walk.bvh");
    let default = spawn_driven(&mut app, "spot", "spot", player, 1.5);
    let bare = spawn_driven(&mut app, "spot", "spot", player, 3.0);
    let with_none = app.world().get::<Retargeter>(bare).unwrap().clone().with_cleanup(Cleanup::NONE);
    app.world_mut().entity_mut(bare).insert(with_none);
    start_together(&mut app, player, &[default, bare]);
    let mut apart = 0.0f32;
    for _ in 0..60 {
        app.update();
        for (e, want) in [(default, &cleaned), (bare, &raw)] {
            let t = tick(&app, e).unwrap() as usize;
            let (d, a) = link_gap(&app, e, &want.poses[t]);
            assert!(d < 2e-3 && a < 2e-2, "tick {t}: links {d} m and {a} rad from the offline motion");
        }
        let t = tick(&app, bare).unwrap() as usize;
        apart = apart.max(link_gap(&app, bare, &cleaned.poses[t]).0);
    }
    // The raw output is another motion: the cleanup moves Spot's links by centimetres on the walk.
    assert!(apart > 0.02, "the raw and the cleaned walk differ by {apart} m");
}

/// A jump of the source's clock by at most `MAX_CATCH_UP` ticks is caught up on, tick by tick, as if
/// played; one tick more and the character starts over, standing at rest at the new tick, as a
/// character that joins the source there does.
#[test]
fn a_short_jump_is_caught_up_on_and_a_longer_one_starts_over() {
    use bevy_ace::retarget::MAX_CATCH_UP;
    let want = offline("spot", "walk.bvh");
    let mut app = retargeting_app();
    let player = paused_player(&mut app, "walk.bvh");
    let spot = spawn_driven(&mut app, "spot", "spot", player, 0.0);
    update_until(&mut app, |w| matches!(w.get::<RetargetStatus>(spot), Some(RetargetStatus::Running { tick: 0 })));
    let seek = |app: &mut App, tick: i64| {
        app.world_mut().get_mut::<HumanClipPlayer>(player).unwrap().seek(tick as f32 / 30.0);
        app.update();
        app.update();
    };
    let short = MAX_CATCH_UP;
    seek(&mut app, short);
    assert_eq!(tick(&app, spot), Some(short));
    let (d, a) = link_gap(&app, spot, &want.poses[short as usize]);
    assert!(d < 1e-4 && a < 1e-3, "caught up: links {d} m and {a} rad from the played motion");

    let long = short + MAX_CATCH_UP + 1;
    seek(&mut app, long);
    let joined = spawn_driven(&mut app, "spot", "spot", player, 0.0);
    update_until(&mut app, |w| matches!(w.get::<RetargetStatus>(joined), Some(RetargetStatus::Running { .. })));
    assert_eq!(tick(&app, spot), Some(long));
    assert_eq!(tick(&app, joined), Some(long));
    let restarted = &app.world().get::<Pose>(joined).unwrap().0;
    let (d, a) = link_gap(&app, spot, restarted);
    assert!(d < 1e-4 && a < 1e-3, "started over: links {d} m and {a} rad from a character that joined there");
    // Starting over is not catching up: the played motion has walked on from the origin.
    let (d, _) = link_gap(&app, spot, &want.poses[long as usize]);
    assert!(d > 0.1, "{d} m from the played motion");
}

/// A mocap stream's bad packets (time not finite, not later than the last, a pose with NaN) are
/// refused with their reason and leave the source as it was.
#[test]
fn a_live_source_refuses_frames_out_of_order_or_not_finite() {
    use bevy_ace::retarget::LiveFrameRefused;
    let clip = HumanClip::from_bvh_file(&asset_path("motions/walk.bvh"), &ImportOptions { fps: Some(30.0), mapping: None }).unwrap();
    let mut live = LiveHuman::default();
    assert_eq!(live.push(0.0, clip.frames[0].clone()), Ok(()));
    assert_eq!(live.push(0.1, clip.frames[3].clone()), Ok(()));
    let held = |l: &LiveHuman| (l.latest_time(), l.frame_at(0.05), l.frame_at(1.0));
    let before = held(&live);
    let mut nan_joint = clip.frames[6].clone();
    nan_joint.positions[Joint::LeftHand.index()].y = f32::NAN;
    let mut nan_root = clip.frames[6].clone();
    nan_root.root_rotation = UnitQuaternion::new_unchecked(ace_models::nalgebra::Quaternion::new(f32::NAN, 0.0, 0.0, 0.0));
    let mut inf_joint = clip.frames[6].clone();
    inf_joint.positions[Joint::Pelvis.index()].z = f32::INFINITY;
    assert_eq!(live.push(f32::NAN, clip.frames[6].clone()), Err(LiveFrameRefused::BadTime));
    assert_eq!(live.push(f32::INFINITY, clip.frames[6].clone()), Err(LiveFrameRefused::BadTime));
    assert_eq!(live.push(0.05, clip.frames[6].clone()), Err(LiveFrameRefused::NotLater));
    assert_eq!(live.push(0.1, clip.frames[6].clone()), Err(LiveFrameRefused::NotLater));
    assert_eq!(live.push(0.2, nan_joint), Err(LiveFrameRefused::BadPose));
    assert_eq!(live.push(0.2, nan_root), Err(LiveFrameRefused::BadPose));
    assert_eq!(live.push(0.2, inf_joint), Err(LiveFrameRefused::BadPose));
    assert_eq!(held(&live), before);
    assert_eq!(live.push(0.2, clip.frames[6].clone()), Ok(()));
    assert_eq!(live.latest_time(), Some(0.2));
}

#[test]
fn a_live_source_fed_from_code_drives_a_character() {
    let clip = HumanClip::from_bvh_file(&asset_path("motions/walk.bvh"), &ImportOptions { fps: Some(30.0), mapping: None }).unwrap();
    let mut app = retargeting_app();
    let source = app.world_mut().spawn(LiveHuman::default()).id();
    let spot = spawn_driven(&mut app, "spot", "spot", source, 0.0);
    // Frames arrive one per step, stamped with the stream's clock.
    let send = |app: &mut App, k: usize| {
        app.world_mut().write_message(LiveHumanFrame { source, time: k as f32 / 30.0, frame: clip.frames[k].clone() });
    };
    send(&mut app, 0);
    update_until(&mut app, |w| matches!(w.get::<RetargetStatus>(spot), Some(RetargetStatus::Running { .. })));
    for k in 1..60 {
        send(&mut app, k);
        app.update();
    }
    app.update();
    assert_eq!(tick(&app, spot), Some(59));
    // The same as retargeting the frames offline, with the live rule for the first frame (no
    // next frame yet: no velocities).
    let frames = &clip.frames[..60];
    let rows: Vec<HumanRow> = (0..60)
        .map(|k| {
            // What the stream held at tick k: frames 0..=k.
            let at = |t: f32| frames[((t * 30.0).round() as usize).min(k)].clone();
            HumanState::sampled(at, k as f32 / 30.0, 1.0 / 30.0, k == 0).0
        })
        .collect();
    let (tree, morph) = load_character(&asset_path("characters/spot.urdf")).unwrap();
    let r = Offline::load(&asset_path("checkpoints/spot")).unwrap();
    let want = r.retarget_states(&tree, &morph, &rows).unwrap();
    let (d, a) = link_gap(&app, spot, &want.poses[59]);
    assert!(d < 1e-4 && a < 1e-3, "links {d} m and {a} rad from the offline motion");
}

#[test]
fn missing_or_mismatched_checkpoints_are_error_messages_not_panics() {
    let mut app = retargeting_app();
    let player = paused_player(&mut app, "walk.bvh");
    let missing = spawn_driven(&mut app, "spot", "no_such_checkpoint", player, 0.0);
    let mismatched = spawn_driven(&mut app, "spot", "crab", player, 1.0);
    let sourceless = spawn_driven(&mut app, "spot", "spot", player, 2.0);
    app.world_mut().get_mut::<Retargeter>(sourceless).unwrap().source = missing;
    // A Retargeter on an entity with neither a Character nor a glTF scene.
    let checkpoint = app.world().resource::<AssetServer>().load("checkpoints/spot/ace.json");
    let bodiless = app.world_mut().spawn(Retargeter::new(checkpoint, player)).id();
    let failed = |w: &mut World, e: Entity| matches!(w.get::<RetargetStatus>(e), Some(RetargetStatus::Failed(_)));
    update_until(&mut app, |w| [missing, mismatched, sourceless, bodiless].iter().all(|&e| failed(w, e)));
    app.update();
    let errors = &app.world().resource::<SeenErrors>().0;
    let message = |e: Entity| {
        let m: Vec<&str> = errors.iter().filter(|r| r.entity == e).map(|r| r.message.as_str()).collect();
        assert_eq!(m.len(), 1, "one message per failure: {m:?}");
        m[0].to_string()
    };
    let m = message(missing);
    assert!(m.contains("no_such_checkpoint/ace.json"), "{m}");
    let m = message(mismatched);
    assert!(m.contains("checkpoints/crab") && m.contains("does not fit character spot"), "{m}");
    let m = message(sourceless);
    assert!(m.contains("neither a HumanClipPlayer nor a LiveHuman"), "{m}");
    let m = message(bodiless);
    assert!(m.contains(&format!("{bodiless} has a Retargeter but neither a Character nor a glTF scene")), "{m}");
    // A broken checkpoint file fails to load with its name.
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR")).join("headless-broken-checkpoint");
    let ckpt = dir.join("checkpoints/spot");
    std::fs::create_dir_all(&ckpt).unwrap();
    for f in ["ace.json", "config.json", "prior.safetensors"] {
        std::fs::copy(asset_path("checkpoints/spot").join(f), ckpt.join(f)).unwrap();
    }
    std::fs::write(ckpt.join("generator.safetensors"), b"not a safetensors file").unwrap();
    std::fs::create_dir_all(dir.join("characters")).unwrap();
    std::fs::copy(asset_path("characters/spot.urdf"), dir.join("characters/spot.urdf")).unwrap();
    std::fs::create_dir_all(dir.join("motions")).unwrap();
    std::fs::copy(asset_path("motions/walk.bvh"), dir.join("motions/walk.bvh")).unwrap();
    let mut app = app_with_assets(dir.to_str().unwrap());
    app.init_resource::<SeenErrors>().add_systems(Last, record_errors);
    let player = paused_player(&mut app, "walk.bvh");
    let spot = spawn_driven(&mut app, "spot", "spot", player, 0.0);
    update_until(&mut app, |w| failed(w, spot));
    let Some(RetargetStatus::Failed(m)) = app.world().get::<RetargetStatus>(spot) else { unreachable!() };
    assert!(m.contains("generator.safetensors"), "{m}");
}

/// A character and its checkpoint loaded from a second asset source (`custom://`) read their
/// sibling files there: the checkpoint's configuration, prior and generator, the character's profile,
/// a `.gltf`'s buffer. The default source holds none of them, only a broken profile for Spot that
/// must not be read.
#[test]
fn a_checkpoint_from_another_asset_source_reads_its_files_from_that_source() {
    use bevy::asset::io::AssetSourceBuilder;
    let root = Path::new(env!("CARGO_TARGET_TMPDIR")).join("headless-source");
    let _ = std::fs::remove_dir_all(&root);
    let (main, custom) = (root.join("default"), root.join("custom"));
    for dir in [main.join("characters"), main.join("motions"), custom.join("characters"), custom.join("checkpoints/spot")] {
        std::fs::create_dir_all(dir).unwrap();
    }
    for c in ["spot", "hound"] {
        std::fs::create_dir_all(custom.join("checkpoints").join(c)).unwrap();
        for f in ["ace.json", "config.json", "prior.safetensors", "generator.safetensors"] {
            std::fs::copy(asset_path("checkpoints").join(c).join(f), custom.join("checkpoints").join(c).join(f)).unwrap();
        }
    }
    std::fs::copy(asset_path("characters/spot.urdf"), custom.join("characters/spot.urdf")).unwrap();
    std::fs::copy(asset_path("motions/walk.bvh"), main.join("motions/walk.bvh")).unwrap();
    std::fs::write(main.join("characters/spot.profile.toml"), "not a profile [").unwrap();
    // The hound as a `.gltf` whose buffer is a file beside it.
    std::fs::create_dir_all(custom.join("creatures")).unwrap();
    let glb = std::fs::read(asset_path("creatures/hound.glb")).unwrap();
    let json_len = u32::from_le_bytes(glb[12..16].try_into().unwrap()) as usize;
    let mut json: serde_json::Value = serde_json::from_slice(&glb[20..20 + json_len]).unwrap();
    let bin_at = 20 + json_len;
    let bin_len = u32::from_le_bytes(glb[bin_at..bin_at + 4].try_into().unwrap()) as usize;
    json["buffers"][0]["uri"] = "hound.bin".into();
    std::fs::write(custom.join("creatures/hound.gltf"), serde_json::to_vec(&json).unwrap()).unwrap();
    std::fs::write(custom.join("creatures/hound.bin"), &glb[bin_at + 8..bin_at + 8 + bin_len]).unwrap();
    // The hound's profile (its spine held at rest, as its checkpoint was trained) goes beside it too.
    std::fs::copy(asset_path("creatures/hound.profile.toml"), custom.join("creatures/hound.profile.toml")).unwrap();

    let mut app = App::new();
    app.register_asset_source("custom", AssetSourceBuilder::platform_default(custom.to_str().unwrap(), None))
        .add_plugins((
            MinimalPlugins,
            AssetPlugin { file_path: main.to_str().unwrap().into(), ..default() },
            TransformPlugin,
            AcePlugin,
        ))
        .insert_resource(TimeUpdateStrategy::ManualDuration(Duration::from_secs_f32(DT)))
        .init_resource::<SeenErrors>()
        .add_systems(Last, record_errors);
    let player = paused_player(&mut app, "walk.bvh");
    let server = app.world().resource::<AssetServer>().clone();
    let checkpoint: Handle<CheckpointAsset> = server.load("custom://checkpoints/spot/ace.json");
    let spot = app
        .world_mut()
        .spawn((Character::new(server.load("custom://characters/spot.urdf")), Retargeter::new(checkpoint.clone(), player)))
        .id();
    let hound_gltf: Handle<CharacterAsset> = server.load("custom://creatures/hound.gltf");
    update_until(&mut app, |w| match w.get::<RetargetStatus>(spot) {
        Some(RetargetStatus::Failed(m)) => panic!("retargeter failed: {m}"),
        Some(RetargetStatus::Running { tick: 0 }) => true,
        _ => false,
    });
    let dir = app.world().resource::<Assets<CheckpointAsset>>().get(&checkpoint).unwrap().dir().to_path_buf();
    assert_eq!(dir, std::path::Path::new("checkpoints/spot"));
    app.world_mut().get_mut::<HumanClipPlayer>(player).unwrap().paused = false;
    let want = offline("spot", "walk.bvh");
    plays_as_offline(&mut app, spot, &want, 10);
    assert!(app.world().resource::<SeenErrors>().0.is_empty());
    let mut state = LoadState::Loading;
    update_until(&mut app, |w| {
        state = w.resource::<AssetServer>().load_state(&hound_gltf);
        matches!(state, LoadState::Loaded | LoadState::Failed(_))
    });
    assert!(matches!(state, LoadState::Loaded), "the .gltf with its buffer beside it: {state:?}");
    let hound = app.world().resource::<Assets<CharacterAsset>>().get(&hound_gltf).unwrap();
    assert_eq!(hound.tree.dof(), load_creature(&asset_path("creatures/hound.glb")).unwrap().tree.dof());

    // The hound's checkpoint was trained with `hound.glb`: a copy of it anywhere is that file; the
    // `.gltf` has the same bones but other bytes, which the checkpoint tells (the plugin warns once).
    std::fs::copy(asset_path("creatures/hound.glb"), custom.join("creatures/hound.glb")).unwrap();
    let hound_checkpoint: Handle<CheckpointAsset> = server.load("custom://checkpoints/hound/ace.json");
    let hound_glb: Handle<CharacterAsset> = server.load("custom://creatures/hound.glb");
    update_until(&mut app, |_| {
        [server.load_state(&hound_checkpoint), server.load_state(&hound_glb)].iter().all(|s| matches!(s, LoadState::Loaded))
    });
    let checkpoint = app.world().resource::<Assets<CheckpointAsset>>().get(&hound_checkpoint).unwrap();
    let characters = app.world().resource::<Assets<CharacterAsset>>();
    assert_eq!(checkpoint.character_file_difference(characters.get(&hound_glb).unwrap()), None);
    let w = checkpoint.character_file_difference(characters.get(&hound_gltf).unwrap()).expect("the .gltf is another file");
    assert!(w.contains("creatures/hound.gltf is not the character file") && w.contains("checkpoints/hound"), "{w}");

    // A checkpoint whose training stopped early loads and says so (the loader logs it); the shipped
    // one, trained to the end, does not.
    assert_eq!(checkpoint.unfinished, None);
    let part = custom.join("checkpoints/hound-part");
    std::fs::create_dir_all(&part).unwrap();
    for f in ["ace.json", "config.json", "prior.safetensors", "generator.safetensors"] {
        std::fs::copy(custom.join("checkpoints/hound").join(f), part.join(f)).unwrap();
    }
    let mut record: serde_json::Value = serde_json::from_slice(&std::fs::read(part.join("ace.json")).unwrap()).unwrap();
    record["step"] = 300.into();
    std::fs::write(part.join("ace.json"), serde_json::to_vec(&record).unwrap()).unwrap();
    let part: Handle<CheckpointAsset> = server.load("custom://checkpoints/hound-part/ace.json");
    update_until(&mut app, |_| matches!(server.load_state(&part), LoadState::Loaded));
    let w = app.world().resource::<Assets<CheckpointAsset>>().get(&part).unwrap().unfinished.clone().expect("part-trained");
    assert!(w.starts_with("checkpoint checkpoints/hound-part: the checkpoint's generator trained 300 of its"), "{w}");
}

/// A live source blends its two frames around a time by the time's fraction between them, keeps the
/// last two seconds of frames, and after a pause in the stream still holds the two newest frames.
/// (Times are multiples of 1/8 s, exact in binary, so the two-second edge is hit exactly.)
#[test]
fn a_live_source_interpolates_between_its_frames_and_keeps_two_seconds() {
    let clip = HumanClip::from_bvh_file(&asset_path("motions/walk.bvh"), &ImportOptions { fps: Some(30.0), mapping: None }).unwrap();
    let f = &clip.frames;
    let at = |k: usize| k as f32 / 8.0;
    let mut live = LiveHuman::default();
    for (k, frame) in f.iter().enumerate().take(25) {
        live.push(at(k), frame.clone()).unwrap();
    }
    assert_eq!(live.latest_time(), Some(3.0));
    let same = |a: &HumanFrame, b: &HumanFrame| {
        a.positions.iter().zip(&b.positions).all(|(p, q)| (p - q).norm() < 1e-6) && a.root_rotation.angle_to(&b.root_rotation) < 1e-6
    };
    // A quarter of the way from frame 20 (2.5 s) to frame 21 (2.625 s).
    let blended = live.frame_at(2.53125).unwrap();
    assert!(same(&blended, &f[20].lerp(&f[21], 0.25)), "not a quarter of the way between the two frames");
    assert!(!same(&blended, &f[20]) && !same(&blended, &f[21]));
    // Held: 1.0 s to 3.0 s (the frame exactly two seconds old stays); earlier times get the oldest.
    assert!(same(&live.frame_at(0.0).unwrap(), &f[8]), "the oldest frame held is not the one at 1.0 s");
    assert!(same(&live.frame_at(0.99).unwrap(), &f[8]));
    assert!(same(&live.frame_at(5.0).unwrap(), &f[24]));
    // A stream that stops for ten seconds: both frames around the gap are kept, and blended.
    live.push(13.0, f[40].clone()).unwrap();
    assert!(same(&live.frame_at(8.0).unwrap(), &f[24].lerp(&f[40], 0.5)), "the frames around the gap are not both kept");
}

/// A paused source holds its characters: the same tick and the same pose, frame after frame (no
/// restart from rest, no further ticks).
#[test]
fn a_paused_source_holds_the_character_where_it_is() {
    let want = offline("spot", "walk.bvh");
    let (mut app, spot, _, held) = spot_paused_after_20_ticks();
    assert!(held >= 19, "tick {held}");
    for _ in 0..5 {
        app.update();
        assert_eq!(tick(&app, spot), Some(held));
        let (d, a) = link_gap(&app, spot, &want.poses[held as usize]);
        assert!(d < 1e-4 && a < 1e-3, "paused at tick {held}: links {d} m and {a} rad from the played motion");
    }
}

/// Spot driven by the walk for 20 frames, then the walk paused (and two frames for the last poses to
/// come back): the app, Spot, the walk's player and the tick Spot holds.
fn spot_paused_after_20_ticks() -> (App, Entity, Entity, i64) {
    let mut app = retargeting_app();
    let player = paused_player(&mut app, "walk.bvh");
    let spot = spawn_driven(&mut app, "spot", "spot", player, 0.0);
    start_together(&mut app, player, &[spot]);
    for _ in 0..20 {
        app.update();
    }
    app.world_mut().get_mut::<HumanClipPlayer>(player).unwrap().paused = true;
    app.update();
    app.update();
    let t = tick(&app, spot).unwrap();
    (app, spot, player, t)
}

/// [`spot_paused_after_20_ticks`], then `change` applied to the app (which must leave the source's
/// clock where it is): the app, Spot, a character that joined the source at that tick, and the tick.
/// After a restart Spot stands exactly as the one that joined.
fn run_then(change: impl FnOnce(&mut App, Entity, Entity)) -> (App, Entity, Entity, i64) {
    let (mut app, spot, player, t) = spot_paused_after_20_ticks();
    change(&mut app, spot, player);
    let joined = spawn_driven(&mut app, "spot", "spot", player, 0.0);
    update_until(&mut app, |w| {
        [spot, joined].iter().all(|&e| matches!(w.get::<RetargetStatus>(e), Some(RetargetStatus::Running { .. })))
    });
    app.update();
    (app, spot, joined, t)
}

/// Whether `spot` stands as `joined` (a fresh start at the same tick) does, and not as the motion
/// played on from tick 0.
fn started_over(app: &App, spot: Entity, joined: Entity, t: i64, want: &RetargetedMotion) -> bool {
    assert_eq!(tick(app, spot), Some(t));
    assert_eq!(tick(app, joined), Some(t));
    let fresh = &app.world().get::<Pose>(joined).unwrap().0;
    let (from_fresh, _) = link_gap(app, spot, fresh);
    let (from_played, _) = link_gap(app, spot, &want.poses[t as usize]);
    println!("tick {t}: {from_fresh} m from the fresh start, {from_played} m from the played motion");
    assert!(from_fresh < 1e-4 || from_played < 1e-4, "neither started over nor played on: {from_fresh} m, {from_played} m");
    from_fresh < 1e-4 && from_played > 1e-2
}

/// A Retargeter inserted anew, a checkpoint modified (as a hot reload does), and a Retargeter
/// removed and added back each start the character over at the source's tick; a character left
/// alone plays on.
#[test]
fn a_changed_retargeter_or_checkpoint_starts_over_and_a_removed_one_is_forgotten() {
    let want = offline("spot", "walk.bvh");
    let (app, spot, joined, t) = run_then(|_, _, _| {});
    assert!(!started_over(&app, spot, joined, t, &want), "left alone, Spot started over");

    let (app, spot, joined, t) = run_then(|app, spot, _| {
        let r = app.world().get::<Retargeter>(spot).unwrap().clone();
        app.world_mut().entity_mut(spot).insert(r);
    });
    assert!(started_over(&app, spot, joined, t, &want), "a Retargeter inserted anew did not start over");

    let (app, spot, joined, t) = run_then(|app, spot, _| {
        let id = app.world().get::<Retargeter>(spot).unwrap().checkpoint.id();
        let mut checkpoints = app.world_mut().resource_mut::<Assets<CheckpointAsset>>();
        let mut checkpoint = checkpoints.get_mut(id).expect("the loaded checkpoint");
        let _: &mut CheckpointAsset = &mut checkpoint; // a mutable borrow marks it modified
    });
    assert!(started_over(&app, spot, joined, t, &want), "a modified checkpoint did not start over");

    let (app, spot, joined, t) = run_then(|app, spot, _| {
        let r = app.world_mut().entity_mut(spot).take::<Retargeter>().unwrap();
        app.update();
        app.update();
        app.world_mut().entity_mut(spot).insert(r);
    });
    assert!(started_over(&app, spot, joined, t, &want), "a Retargeter removed and added back did not start over");
    assert!(app.world().resource::<SeenErrors>().0.is_empty(), "{:?}", app.world().resource::<SeenErrors>().0);
}

/// A glTF scene given a Retargeter by a system that runs after the plugin binds scenes (between
/// `AceSystems::Spawn` and `AceSystems::Retarget`) waits to be bound the next frame: it is not taken
/// for an entity with neither a character nor a scene.
#[test]
fn a_scene_given_a_retargeter_late_in_the_frame_waits_to_be_bound() {
    use bevy::world_serialization::{WorldAssetRoot, WorldSerializationPlugin};
    let mut app = retargeting_app();
    app.add_plugins(WorldSerializationPlugin);
    let player = paused_player(&mut app, "walk.bvh");
    let spawn_late = move |mut commands: Commands, server: Res<AssetServer>, mut done: Local<bool>| {
        if !std::mem::replace(&mut *done, true) {
            commands.spawn((
                WorldAssetRoot(server.load("creatures/hound.glb#Scene0")),
                Retargeter::new(server.load("checkpoints/hound/ace.json"), player),
            ));
        }
    };
    app.add_systems(PostUpdate, spawn_late.after(AceSystems::Spawn).before(AceSystems::Retarget));
    for _ in 0..5 {
        app.update();
    }
    let mut scenes = app.world_mut().query_filtered::<&RetargetStatus, With<WorldAssetRoot>>();
    let statuses: Vec<RetargetStatus> = scenes.iter(app.world()).cloned().collect();
    assert_eq!(statuses, vec![RetargetStatus::Loading], "{:?}", app.world().resource::<SeenErrors>().0);
    assert!(app.world().resource::<SeenErrors>().0.is_empty());
}
