//! Helpers of the plugin's headless tests (`MinimalPlugins`, no window, a manual time step), shared
//! with the `ace` crate's headless tests (which include this file), so that both drive apps the same way.
#![allow(dead_code)]

use std::path::{Path, PathBuf};
use std::time::Duration;

use bevy::prelude::*;
use bevy::time::TimeUpdateStrategy;
use bevy_ace::prelude::*;

/// The fixed time step of the tests' apps, the clips' frame time.
pub const DT: f32 = 1.0 / 30.0;

/// The project's folder (the workspace's, whichever crate includes this file).
pub fn project() -> &'static Path {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .ancestors()
        .find(|p| p.join("Cargo.lock").is_file())
        .expect("the workspace folder above the crate")
}

/// A file of the bundled `assets/` folder.
pub fn asset_path(path: &str) -> PathBuf {
    project().join("assets").join(path)
}

/// A headless app loading assets from the bundled `assets/` folder.
pub fn app() -> App {
    app_with_assets(project().join("assets").to_str().unwrap())
}

/// A headless app loading assets from `asset_root`.
pub fn app_with_assets(asset_root: &str) -> App {
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
pub fn update_until(app: &mut App, mut done: impl FnMut(&mut World) -> bool) {
    for _ in 0..2000 {
        app.update();
        if done(app.world_mut()) {
            return;
        }
        std::thread::sleep(Duration::from_millis(1));
    }
    panic!("condition not reached in 2000 frames");
}

pub fn assert_close(a: &Transform, b: &Transform, what: &str) {
    assert!(a.translation.distance(b.translation) < 1e-4, "{what}: translation {} vs {}", a.translation, b.translation);
    assert!(a.rotation.angle_between(b.rotation) < 1e-3, "{what}: rotation {:?} vs {:?}", a.rotation, b.rotation);
}

// ---- Characters driven by a checkpoint (the Retargeter component) ----

/// Errors written so far.
#[derive(Resource, Default)]
pub struct SeenErrors(pub Vec<RetargetError>);

pub fn record_errors(mut errors: MessageReader<RetargetError>, mut seen: ResMut<SeenErrors>) {
    seen.0.extend(errors.read().cloned());
}

pub fn retargeting_app() -> App {
    let mut app = app();
    app.init_resource::<SeenErrors>().add_systems(Last, record_errors);
    app
}

pub fn tick(app: &App, e: Entity) -> Option<i64> {
    match app.world().get::<RetargetStatus>(e) {
        Some(RetargetStatus::Running { tick }) => Some(*tick),
        Some(RetargetStatus::Failed(m)) => panic!("retargeter failed: {m}"),
        _ => None,
    }
}

/// Spawns a paused walk player, waits until `characters` show tick 0, then unpauses.
pub fn start_together(app: &mut App, player: Entity, characters: &[Entity]) {
    update_until(app, |w| {
        characters.iter().all(|&e| matches!(w.get::<RetargetStatus>(e), Some(RetargetStatus::Running { tick: 0 })))
    });
    app.world_mut().get_mut::<HumanClipPlayer>(player).unwrap().paused = false;
}

pub fn paused_player(app: &mut App, clip: &str) -> Entity {
    let handle: Handle<BvhAsset> = app.world().resource::<AssetServer>().load(format!("motions/{clip}"));
    let mut p = HumanClipPlayer::new(handle);
    p.paused = true;
    p.looping = false;
    app.world_mut().spawn(p).id()
}
