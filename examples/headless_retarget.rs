//! Retargets a bundled human clip onto a bundled character in a headless Bevy app (no window, no
//! renderer), stepping a fixed 1/30 s per frame, and prints where the character's root goes.
//!
//! ```text
//! cargo run --example headless_retarget -- [character] [clip]     (default: spot walk)
//! ```

use std::time::Duration;

use bevy::app::AppExit;
use bevy::prelude::*;
use bevy::time::TimeUpdateStrategy;
use bevy_ace::prelude::*;

fn main() -> AppExit {
    let mut args = std::env::args().skip(1);
    let character = args.next().unwrap_or_else(|| "spot".into());
    let clip = args.next().unwrap_or_else(|| "walk".into());
    let mut app = App::new();
    app.add_plugins((
        MinimalPlugins,
        AssetPlugin { file_path: concat!(env!("CARGO_MANIFEST_DIR"), "/assets").into(), ..default() },
        TransformPlugin,
        AcePlugin,
    ))
    .insert_resource(TimeUpdateStrategy::ManualDuration(Duration::from_secs_f32(1.0 / 30.0)));
    let server = app.world().resource::<AssetServer>().clone();
    let mut player = HumanClipPlayer::new(server.load(format!("motions/{clip}.bvh")));
    player.looping = false;
    // Held at the first frame until the checkpoint is loaded and the character has started.
    player.paused = true;
    let player = app.world_mut().spawn(player).id();
    let robot = app
        .world_mut()
        .spawn((
            Character::new(server.load(format!("characters/{character}.urdf"))),
            Retargeter::new(server.load(format!("checkpoints/{character}/ace.json")), player),
        ))
        .id();

    println!("| tick | time (s) | root x | root y | root height | yaw (deg) |");
    println!("|---:|---:|---:|---:|---:|---:|");
    let mut last = None;
    for _ in 0..20_000 {
        app.update();
        match app.world().get::<RetargetStatus>(robot).cloned() {
            Some(RetargetStatus::Failed(message)) => {
                eprintln!("retargeting failed: {message}");
                return AppExit::error();
            }
            Some(RetargetStatus::Running { tick }) if Some(tick) != last => {
                last = Some(tick);
                app.world_mut().get_mut::<HumanClipPlayer>(player).unwrap().paused = false;
                let pose = app.world().get::<Pose>(robot).expect("a driven character has a pose");
                if tick % 15 == 0 {
                    let p = pose.root.translation.vector;
                    let yaw = pose.root.rotation.euler_angles().2.to_degrees();
                    println!("| {tick} | {:.2} | {:.3} | {:.3} | {:.3} | {yaw:.1} |", tick as f32 / 30.0, p.x, p.y, p.z);
                }
            }
            _ => std::thread::sleep(Duration::from_millis(1)),
        }
        // Done once the clip has ended and its last tick is shown.
        let p = app.world().get::<HumanClipPlayer>(player).unwrap();
        let clips = app.world().resource::<Assets<BvhAsset>>();
        if let (Some(asset), Some(tick)) = (clips.get(&p.clip), last) {
            if p.time >= asset.clip.duration() && tick == (asset.clip.duration() * 30.0 + 1e-3).floor() as i64 {
                println!("{character} followed {clip} for {:.1} s ({} ticks)", asset.clip.duration(), tick + 1);
                return AppExit::Success;
            }
        }
    }
    eprintln!("the clip did not finish");
    AppExit::error()
}
