//! The smallest game that drives a character with ACE: no window, no renderer, no libtorch (features
//! `runtime` only). A walk clip drives Spot with its shipped checkpoint; the program prints how long it
//! took from start to the first retargeted frame, then the character's root after a second of clip.
//!
//! ```text
//! cargo run --release -p bevy_ace --no-default-features --features runtime --example headless_game
//! ```

use std::time::{Duration, Instant};

use bevy::prelude::*;
use bevy::time::TimeUpdateStrategy;
use bevy_ace::prelude::*;

fn main() {
    let start = Instant::now();
    let mut app = App::new();
    app.add_plugins((
        MinimalPlugins,
        AssetPlugin { file_path: concat!(env!("CARGO_MANIFEST_DIR"), "/../assets").into(), ..default() },
        TransformPlugin,
        AcePlugin,
    ))
    .insert_resource(TimeUpdateStrategy::ManualDuration(Duration::from_secs_f32(1.0 / 30.0)));
    let server = app.world().resource::<AssetServer>().clone();
    // Paused until the character runs, so that it follows the clip from its start whatever loads first.
    let mut player = HumanClipPlayer::new(server.load("motions/walk.bvh"));
    player.paused = true;
    let walk = app.world_mut().spawn(player).id();
    let spot = app
        .world_mut()
        .spawn((
            Character::new(server.load("characters/spot.urdf")),
            Retargeter::new(server.load("checkpoints/spot/ace.json"), walk),
            Transform::default(),
        ))
        .id();
    let mut first = None;
    for _ in 0..10_000 {
        app.update();
        match app.world().get::<RetargetStatus>(spot).cloned() {
            Some(RetargetStatus::Failed(reason)) => {
                eprintln!("error: {reason}");
                std::process::exit(1);
            }
            Some(RetargetStatus::Running { tick }) => {
                if first.is_none() {
                    first = Some(start.elapsed());
                    println!("first retargeted frame {:.1} ms after start", start.elapsed().as_secs_f64() * 1e3);
                    app.world_mut().get_mut::<HumanClipPlayer>(walk).expect("the player").paused = false;
                }
                if tick >= 30 {
                    let root = app.world().get::<CharacterLinks>(spot).and_then(|l| l.0.first().copied());
                    let at = root.and_then(|r| app.world().get::<GlobalTransform>(r)).map(|t| t.translation());
                    println!("tick {tick}: Spot's root at {at:?} (y up)");
                    return;
                }
            }
            _ => {}
        }
        std::thread::sleep(Duration::from_millis(1));
    }
    eprintln!("error: no retargeted frame after 10,000 updates");
    std::process::exit(1);
}
