//! A rigged glTF creature follows a human clip through its own skinned mesh: the bundled hound
//! (`assets/creatures/hound.glb`, Bevy's own glTF scene) driven by a `Retargeter`, beside the human
//! skeleton playing the bundled walk clip, in a window.
//!
//! ```text
//! cargo run --example creature -- [--checkpoint DIR] [--clip NAME] [--screenshot FILE.png]
//! ```
//! `--checkpoint` defaults to the hound's shipped checkpoint (`assets/checkpoints/hound`); any folder
//! holding a hound checkpoint's `ace.json` works. `--screenshot` saves the window after four seconds of
//! the clip and exits. Space pauses, ←/→ scrub by a second.

#[path = "support/screenshot.rs"]
mod screenshot;
use std::path::PathBuf;

use bevy::asset::UnapprovedPathMode;
use bevy::prelude::*;
use screenshot::{ScreenshotAt, report_errors, take_screenshot};
use bevy::transform::TransformSystems;
use bevy_ace::ace_models::human::Joint;
use bevy_ace::prelude::*;

#[derive(Resource)]
struct Player(Entity);

#[derive(Component)]
struct Hound;

const ASSETS: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/assets");

fn main() -> AppExit {
    let mut checkpoint = "checkpoints/hound".to_string();
    let mut clip = "walk".to_string();
    let mut screenshot = None;
    let mut args = std::env::args().skip(1);
    while let Some(a) = args.next() {
        match (a.as_str(), args.next()) {
            ("--checkpoint", Some(v)) => checkpoint = std::path::absolute(&v).map_or(v, |p| p.display().to_string()),
            ("--clip", Some(v)) => clip = v,
            ("--screenshot", Some(v)) => screenshot = Some(PathBuf::from(v)),
            _ => {
                eprintln!("usage: creature [--checkpoint DIR] [--clip NAME] [--screenshot FILE.png]");
                return AppExit::error();
            }
        }
    }
    App::new()
        // A checkpoint given by its path lies outside the asset folder: allow such paths.
        .add_plugins(DefaultPlugins.set(AssetPlugin {
            file_path: ASSETS.into(),
            unapproved_path_mode: UnapprovedPathMode::Allow,
            ..default()
        }))
        .add_plugins(AcePlugin)
        .insert_resource(ScreenshotAt(screenshot.map(|p| (p, 4.0))))
        .add_systems(Startup, move |commands: Commands, server: Res<AssetServer>| setup(commands, server, &checkpoint, &clip))
        .add_systems(Update, (controls, report_errors, take_screenshot))
        // After transform propagation, so that the lines and the camera show this frame's poses.
        .add_systems(PostUpdate, (follow, draw_grid_and_bones).after(TransformSystems::Propagate))
        .run()
}

fn setup(mut commands: Commands, server: Res<AssetServer>, checkpoint: &str, clip: &str) {
    let player = commands.spawn((HumanClipPlayer::new(server.load(format!("motions/{clip}.bvh"))), Transform::from_xyz(0.0, 0.0, 1.0))).id();
    commands.insert_resource(Player(player));
    // The scene as authored faces +z; turned a quarter about y it faces +x like the human's walk (and
    // like URDF characters, whose links face +x).
    commands.spawn((
        Hound,
        WorldAssetRoot(server.load("creatures/hound.glb#Scene0")),
        Retargeter::new(server.load(format!("{checkpoint}/ace.json")), player),
        Transform::from_xyz(0.0, 0.0, -0.6).with_rotation(Quat::from_rotation_y(std::f32::consts::FRAC_PI_2)),
    ));
    commands.spawn((Camera3d::default(), Transform::from_xyz(0.5, 1.6, 4.5).looking_at(Vec3::new(0.5, 0.5, 0.0), Vec3::Y)));
    commands.spawn((
        DirectionalLight { illuminance: 9000.0, shadow_maps_enabled: true, ..default() },
        Transform::from_xyz(3.0, 6.0, 4.0).looking_at(Vec3::ZERO, Vec3::Y),
    ));
    commands.insert_resource(GlobalAmbientLight { brightness: 400.0, ..default() });
}

/// Keeps the camera beside the walkers, the human and the hound.
fn follow(
    player: Res<Player>,
    joints: Query<&HumanJoints>,
    hound: Query<&GlobalTransform, With<Hound>>,
    at: Query<&GlobalTransform>,
    mut camera: Query<&mut Transform, With<Camera3d>>,
) {
    let Some(pelvis) = joints.get(player.0).ok().and_then(|j| at.get(j.0[Joint::Pelvis.index()]).ok()) else { return };
    let (a, b) = (pelvis.translation().x, hound.single().map_or(pelvis.translation().x, |h| h.translation().x));
    let (x, spread) = ((a + b) / 2.0, (a - b).abs());
    for mut t in &mut camera {
        *t = Transform::from_xyz(x, 1.3 + 0.3 * spread, 3.2 + 1.2 * spread).looking_at(Vec3::new(x, 0.45, 0.0), Vec3::Y);
    }
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
}

fn draw_grid_and_bones(mut gizmos: Gizmos, players: Query<&HumanJoints>, joints: Query<&GlobalTransform, With<HumanJoint>>) {
    for i in -40..=40 {
        let c = i as f32 * 0.5;
        gizmos.line(Vec3::new(c, 0.0, -3.0), Vec3::new(c, 0.0, 3.0), Color::srgb(0.35, 0.35, 0.35));
    }
    for i in -6..=6 {
        let c = i as f32 * 0.5;
        gizmos.line(Vec3::new(-20.0, 0.0, c), Vec3::new(20.0, 0.0, c), Color::srgb(0.35, 0.35, 0.35));
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
