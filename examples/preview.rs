//! A windowed preview: one human clip drives Spot, the crab and Stretch, each with its shipped
//! checkpoint, side by side on a ground grid.
//!
//! ```text
//! cargo run --example preview -- [clip] [--screenshot FILE.png [--at SECONDS]]   (default: walk)
//! ```
//! Space pauses, ←/→ scrub by a second, ↑/↓ change the speed. `--screenshot` saves the window once the
//! clip has played `--at` seconds (default 4), then exits: a check of the characters in a window.

#[path = "support/screenshot.rs"]
mod screenshot;
use std::path::PathBuf;

use bevy::prelude::*;
use screenshot::{ScreenshotAt, report_errors, take_screenshot};
use bevy_ace::ace_models::human::Joint;
use bevy_ace::prelude::*;

#[derive(Resource)]
struct Player(Entity);

fn main() -> AppExit {
    let (mut clip, mut screenshot, mut at) = ("walk".to_string(), None, 4.0);
    let mut args = std::env::args().skip(1);
    while let Some(a) = args.next() {
        match (a.as_str(), a.starts_with("--").then(|| args.next()).flatten()) {
            ("--screenshot", Some(v)) => screenshot = Some(PathBuf::from(v)),
            ("--at", Some(v)) if v.parse::<f32>().is_ok_and(|t| t >= 0.0) => at = v.parse().unwrap_or(at),
            (name, None) if !name.starts_with("--") => clip = name.to_string(),
            _ => {
                eprintln!("usage: preview [CLIP] [--screenshot FILE.png [--at SECONDS]]");
                return AppExit::error();
            }
        }
    }
    App::new()
        .add_plugins(DefaultPlugins.set(AssetPlugin {
            file_path: concat!(env!("CARGO_MANIFEST_DIR"), "/assets").into(),
            ..default()
        }))
        .add_plugins(AcePlugin)
        .insert_resource(ScreenshotAt(screenshot.map(|p| (p, at))))
        .add_systems(Startup, move |commands: Commands, server: Res<AssetServer>| setup(commands, server, &clip))
        .add_systems(Update, (controls, report_errors, take_screenshot))
        // After transform propagation, so that the bones are drawn where this frame's poses put the
        // joints (before it, they trail them by a frame: visibly so at a software renderer's frame rate).
        .add_systems(PostUpdate, draw_grid_and_bones.after(TransformSystems::Propagate))
        .run()
}

fn setup(mut commands: Commands, server: Res<AssetServer>, clip: &str) {
    let player = commands.spawn((HumanClipPlayer::new(server.load(format!("motions/{clip}.bvh"))), Transform::from_xyz(-3.0, 0.0, 0.0))).id();
    commands.insert_resource(Player(player));
    for (i, name) in ["spot", "crab", "stretch"].into_iter().enumerate() {
        commands.spawn((
            Character::new(server.load(format!("characters/{name}.urdf"))),
            Retargeter::new(server.load(format!("checkpoints/{name}/ace.json")), player),
            Transform::from_xyz(-1.0 + 2.0 * i as f32, 0.0, 0.0),
        ));
    }
    commands.spawn((Camera3d::default(), Transform::from_xyz(0.0, 3.0, 7.0).looking_at(Vec3::new(0.0, 0.5, 0.0), Vec3::Y)));
    commands.spawn((DirectionalLight { illuminance: 9000.0, shadow_maps_enabled: true, ..default() }, Transform::from_xyz(3.0, 6.0, 4.0).looking_at(Vec3::ZERO, Vec3::Y)));
}

fn controls(keys: Res<ButtonInput<KeyCode>>, player: Res<Player>, mut players: Query<&mut HumanClipPlayer>) {
    let Ok(mut p) = players.get_mut(player.0) else { return };
    if keys.just_pressed(KeyCode::Space) {
        p.paused = !p.paused;
    }
    if keys.just_pressed(KeyCode::ArrowLeft) {
        let t = (p.time - 1.0).max(0.0);
        p.seek(t);
    }
    if keys.just_pressed(KeyCode::ArrowRight) {
        let t = p.time + 1.0;
        p.seek(t);
    }
    if keys.just_pressed(KeyCode::ArrowUp) {
        p.speed = (p.speed * 1.25).min(4.0);
    }
    if keys.just_pressed(KeyCode::ArrowDown) {
        p.speed = (p.speed / 1.25).max(0.1);
    }
}

fn draw_grid_and_bones(mut gizmos: Gizmos, players: Query<&HumanJoints>, joints: Query<&GlobalTransform, With<HumanJoint>>) {
    for i in -12..=12 {
        let c = i as f32 * 0.5;
        gizmos.line(Vec3::new(c, 0.0, -6.0), Vec3::new(c, 0.0, 6.0), Color::srgb(0.35, 0.35, 0.35));
        gizmos.line(Vec3::new(-6.0, 0.0, c), Vec3::new(6.0, 0.0, c), Color::srgb(0.35, 0.35, 0.35));
    }
    for player in &players {
        for joint in Joint::ALL {
            let Some(parent) = joint.parent() else { continue };
            if let (Ok(a), Ok(b)) = (joints.get(player.0[joint.index()]), joints.get(player.0[parent.index()])) {
                gizmos.line(a.translation(), b.translation(), Color::srgb(0.3, 0.6, 1.0));
            }
        }
    }
}
