//! Frame time a headless Bevy app spends on [`Retargeter`]s, printed as a table. Targets: one
//! character at most 1 ms median added, 16 characters at most 4 ms, 16 rigged creatures at most 4 ms
//! (the plugin's issue); 16 characters at most 0.5 ms and 64 at most 2 ms (the pure-Rust runtime's).
//!
//! ```text
//! cargo bench -p bevy_ace --bench frame_time
//! ```
//!
//! Each row is a headless app (`MinimalPlugins`, the asset, transform and ACE plugins, a fixed
//! 1/30 s step so that every frame is one network tick) with one walk clip player and N characters,
//! timed over 600 frames after the assets load. The baseline has the same characters spawned and
//! posed by the plugin but no retargeter; "added" is the difference of the medians.
//! The worker runs while the rest of a frame does, so in a real game part of its time is hidden; the
//! plain rows have no other work, so they are the worst case, and the rows "beside 4 ms of game
//! work" add a system that keeps the main thread busy for 4 ms a frame to both apps. The networks
//! run in pure Rust ([`ace_models::runtime`]), one thread per checkpoint.
//!
//! Rows: Spot (URDF, link entities spawned by the plugin), and with feature `scene` the bundled hound
//! as Bevy's own glTF scene (`WorldAssetRoot`, Bevy's glTF loader, no renderer) whose skin joints the
//! retargeters drive. The hound's checkpoint is `assets/checkpoints/hound`, or the folder
//! `ACE_BENCH_HOUND_CHECKPOINT` names.

use std::time::{Duration, Instant};

use bevy::prelude::*;
use bevy::time::TimeUpdateStrategy;
use bevy_ace::prelude::*;

const FRAMES: usize = 600;
/// The game's own main-thread work per frame in the rows that have it.
const GAME_WORK_MS: f64 = 4.0;
const ASSETS: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/../assets");

fn base_app() -> App {
    let mut app = App::new();
    // ACE_BENCH_HOUND_CHECKPOINT may name a folder outside the assets.
    let unapproved_path_mode = bevy::asset::UnapprovedPathMode::Allow;
    app.add_plugins((MinimalPlugins, AssetPlugin { file_path: ASSETS.into(), unapproved_path_mode, ..default() }, TransformPlugin))
        .insert_resource(TimeUpdateStrategy::ManualDuration(Duration::from_secs_f32(1.0 / 30.0)));
    app
}

/// A game's own work on the main thread: a system in `Update` that keeps the CPU busy for `ms`.
fn game_work(ms: f64) -> impl FnMut() {
    move || {
        let t0 = Instant::now();
        while t0.elapsed().as_secs_f64() * 1e3 < ms {
            std::hint::spin_loop();
        }
    }
}

/// N Spot characters, with or without retargeters, beside `work` ms of the game's own work a frame.
fn spot_app(characters: usize, retarget: bool, work: f64) -> (App, Vec<Entity>) {
    let mut app = base_app();
    app.add_plugins(AcePlugin);
    if work > 0.0 {
        app.add_systems(Update, game_work(work));
    }
    let server = app.world().resource::<AssetServer>().clone();
    let player = app.world_mut().spawn(HumanClipPlayer::new(server.load("motions/walk.bvh"))).id();
    let checkpoint: Handle<CheckpointAsset> = server.load("checkpoints/spot/ace.json");
    let urdf: Handle<CharacterAsset> = server.load("characters/spot.urdf");
    let entities = (0..characters)
        .map(|i| {
            let mut e = app.world_mut().spawn((Character::new(urdf.clone()), Transform::from_xyz(i as f32, 0.0, 0.0)));
            if retarget {
                e.insert(Retargeter::new(checkpoint.clone(), player));
            }
            e.id()
        })
        .collect();
    (app, entities)
}

/// N hound scenes, with or without retargeters (checkpoint `checkpoint`, an asset path).
#[cfg(feature = "scene")]
fn hound_app(characters: usize, checkpoint: Option<&str>) -> (App, Vec<Entity>) {
    let mut app = base_app();
    app.add_plugins((
        bevy::world_serialization::WorldSerializationPlugin,
        bevy::mesh::MeshPlugin,
        bevy::image::ImagePlugin::default(),
        bevy::animation::AnimationPlugin,
        bevy::gltf::GltfPlugin::default(),
        AcePlugin,
    ));
    app.finish();
    app.cleanup();
    let server = app.world().resource::<AssetServer>().clone();
    let player = app.world_mut().spawn(HumanClipPlayer::new(server.load("motions/walk.bvh"))).id();
    let checkpoint: Option<Handle<CheckpointAsset>> = checkpoint.map(|c| server.load(format!("{c}/ace.json")));
    let scene = server.load("creatures/hound.glb#Scene0");
    let entities = (0..characters)
        .map(|i| {
            let mut e = app.world_mut().spawn((WorldAssetRoot(scene.clone()), Transform::from_xyz(i as f32, 0.0, 0.0)));
            if let Some(c) = &checkpoint {
                e.insert(Retargeter::new(c.clone(), player));
            }
            e.id()
        })
        .collect();
    (app, entities)
}

/// Median and 90th percentile frame time (ms) once every entity is `ready`.
fn time((mut app, entities): (App, Vec<Entity>), ready: impl Fn(&World, Entity) -> bool) -> (f64, f64) {
    for _ in 0..5000 {
        app.update();
        if entities.iter().all(|&e| ready(app.world(), e)) {
            break;
        }
        std::thread::sleep(Duration::from_millis(1));
    }
    for &e in &entities {
        if let Some(RetargetStatus::Failed(m)) = app.world().get::<RetargetStatus>(e) {
            panic!("retargeter failed: {m}");
        }
        assert!(ready(app.world(), e), "not ready after 5000 frames");
    }
    let mut times: Vec<f64> = (0..FRAMES)
        .map(|_| {
            let t0 = Instant::now();
            app.update();
            t0.elapsed().as_secs_f64() * 1e3
        })
        .collect();
    times.sort_by(f64::total_cmp);
    (times[FRAMES / 2], times[FRAMES * 9 / 10])
}

fn running(w: &World, e: Entity) -> bool {
    matches!(w.get::<RetargetStatus>(e), Some(RetargetStatus::Running { .. }))
}

fn row(what: &str, n: usize, (base, base90): (f64, f64), (with, with90): (f64, f64)) {
    println!("| {what} | {n} | {base:.3} / {base90:.3} ms | {with:.3} / {with90:.3} ms | {:.3} ms |", with - base);
}

fn main() {
    println!("| characters | N | frame without retargeters (median / p90) | with retargeters (median / p90) | added (median) |");
    println!("|---|---:|---:|---:|---:|");
    let linked = |w: &World, e: Entity| w.get::<CharacterLinks>(e).is_some();
    // The worker steps the networks while the rest of the frame runs: with the game's own work in the
    // frame, what the retargeters add is what the frame waits for beyond it.
    let beside = format!("Spot (URDF), beside {GAME_WORK_MS} ms of game work");
    for (what, work, sizes) in [("Spot (URDF)", 0.0, &[1usize, 4, 16, 64][..]), (beside.as_str(), GAME_WORK_MS, &[16, 64])] {
        for &n in sizes {
            let base = time(spot_app(n, false, work), linked);
            let with = time(spot_app(n, true, work), |w, e| linked(w, e) && running(w, e));
            row(what, n, base, with);
        }
    }
    #[cfg(feature = "scene")]
    {
        let checkpoint = std::env::var("ACE_BENCH_HOUND_CHECKPOINT").unwrap_or_else(|_| "checkpoints/hound".into());
        if std::path::Path::new(ASSETS).join(&checkpoint).join("ace.json").is_file() {
            // A scene has spawned when its entity has children (the glTF's root nodes).
            let spawned = |w: &World, e: Entity| w.get::<Children>(e).is_some_and(|c| !c.is_empty());
            for n in [1usize, 16] {
                let base = time(hound_app(n, None), spawned);
                let with = time(hound_app(n, Some(&checkpoint)), |w, e| spawned(w, e) && running(w, e));
                row("hound (glTF scene)", n, base, with);
            }
        } else {
            println!("| hound (glTF scene) | — | no checkpoint at {ASSETS}/{checkpoint}: set ACE_BENCH_HOUND_CHECKPOINT | | |");
        }
    }
}
