//! Headless ECS tests of the plugin: `MinimalPlugins`, no window, a manual time step. Assets load
//! through the asset server from the bundled `assets/` folder.

use std::time::Duration;

use ace::models::human::Joint;
use ace::models::kinematics::CharacterPose;
use ace::models::nalgebra::{Isometry3, Translation3, UnitQuaternion};
use ace::plugin::convert;
use ace::plugin::prelude::*;
use bevy::asset::LoadState;
use bevy::prelude::*;
use bevy::time::TimeUpdateStrategy;

const DT: f32 = 1.0 / 30.0;

/// A headless app loading assets from the bundled `assets/` folder.
fn app() -> App {
    app_with_assets(concat!(env!("CARGO_MANIFEST_DIR"), "/assets"))
}

fn app_with_assets(asset_root: &str) -> App {
    let mut app = App::new();
    app.add_plugins((
        MinimalPlugins,
        AssetPlugin { file_path: asset_root.into(), ..default() },
        TransformPlugin,
        AcePlugin,
    ))
    .insert_resource(TimeUpdateStrategy::ManualDuration(Duration::from_secs_f32(DT)));
    app
}

/// Steps the app until `done` holds, at most 2000 frames.
fn update_until(app: &mut App, mut done: impl FnMut(&mut World) -> bool) {
    for _ in 0..2000 {
        app.update();
        if done(app.world_mut()) {
            return;
        }
        std::thread::sleep(Duration::from_millis(1));
    }
    panic!("condition not reached in 2000 frames");
}

fn assert_close(a: &Transform, b: &Transform, what: &str) {
    assert!(a.translation.distance(b.translation) < 1e-4, "{what}: translation {} vs {}", a.translation, b.translation);
    assert!(a.rotation.angle_between(b.rotation) < 1e-3, "{what}: rotation {:?} vs {:?}", a.rotation, b.rotation);
}

#[test]
fn character_link_transforms_equal_models_forward_kinematics() {
    let mut app = app();
    let placement = Transform::from_xyz(1.0, 0.0, -2.0).with_rotation(Quat::from_rotation_y(0.7));
    let handle: Handle<UrdfAsset> = app.world().resource::<AssetServer>().load("characters/spot.urdf");
    let character = app.world_mut().spawn((Character::new(handle.clone()), placement)).id();
    update_until(&mut app, |w| w.get::<CharacterLinks>(character).is_some());

    let urdf = app.world().resource::<Assets<UrdfAsset>>().get(&handle).unwrap().clone();
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
        let character = app.world().get::<Character>(e).unwrap().urdf.clone();
        let urdf = app.world().resource::<Assets<UrdfAsset>>().get(&character).unwrap().clone();
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
    let handle: Handle<UrdfAsset> = app.world().resource::<AssetServer>().load("loop.urdf");
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
