//! Frame time a headless Bevy app spends on [`Retargeter`]s (issue targets: one character at most
//! 1 ms median added, 16 characters at most 4 ms), printed as a table.
//!
//! ```text
//! cargo bench -p bevy_ace --bench frame_time
//! ```
//!
//! Each row is a headless app (`MinimalPlugins`, the asset, transform and ACE plugins, a fixed
//! 1/30 s step so that every frame is one network tick) with one walk clip player and N Spot
//! characters, timed over 600 frames after the assets load. The baseline has the same characters
//! spawned and posed by the plugin but no retargeter; "added" is the difference of the medians.
//! The worker runs while the rest of a frame does, so in a real game part of its time is hidden;
//! this loop has no other work, so the figures are the worst case. libtorch uses one thread.

use std::time::{Duration, Instant};

use ace_models::learn::set_threads;
use bevy::prelude::*;
use bevy::time::TimeUpdateStrategy;
use bevy_ace::prelude::*;

const FRAMES: usize = 600;

fn app(characters: usize, retarget: bool) -> (App, Vec<Entity>) {
    let mut app = App::new();
    app.add_plugins((
        MinimalPlugins,
        AssetPlugin { file_path: concat!(env!("CARGO_MANIFEST_DIR"), "/../assets").into(), ..default() },
        TransformPlugin,
        AcePlugin,
    ))
    .insert_resource(TimeUpdateStrategy::ManualDuration(Duration::from_secs_f32(1.0 / 30.0)));
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

/// Median and 90th percentile frame time (ms) once everything runs.
fn time(characters: usize, retarget: bool) -> (f64, f64) {
    let (mut app, entities) = app(characters, retarget);
    for _ in 0..5000 {
        app.update();
        let ready = entities.iter().all(|&e| {
            app.world().get::<CharacterLinks>(e).is_some()
                && (!retarget || matches!(app.world().get::<RetargetStatus>(e), Some(RetargetStatus::Running { .. })))
        });
        if ready {
            break;
        }
        std::thread::sleep(Duration::from_millis(1));
    }
    for &e in &entities {
        if let Some(RetargetStatus::Failed(m)) = app.world().get::<RetargetStatus>(e) {
            panic!("retargeter failed: {m}");
        }
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

fn main() {
    set_threads(1);
    println!("| characters | frame without retargeters (median / p90) | with retargeters (median / p90) | added (median) |");
    println!("|---:|---:|---:|---:|");
    for n in [1usize, 4, 16] {
        let (base, base90) = time(n, false);
        let (with, with90) = time(n, true);
        println!("| {n} | {base:.3} / {base90:.3} ms | {with:.3} / {with90:.3} ms | {:.3} ms |", with - base);
    }
}
