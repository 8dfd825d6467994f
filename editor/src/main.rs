//! The ACE editor: a Bevy + egui authoring app. For now it shows a character and a human clip side
//! by side on a ground grid, with an orbit camera, summaries and playback controls.
//!
//! ```text
//! cargo run -p ace_editor -- [--character FILE.urdf] [--clip FILE.bvh] [--screenshot OUT.png]
//! ```

mod camera;
mod ui;

use std::path::PathBuf;

use bevy::prelude::*;
use bevy::render::view::screenshot::{Screenshot, save_to_disk};
use bevy_ace::ace_models::human::Joint;
use bevy_ace::prelude::*;
use bevy_egui::{EguiPlugin, EguiPrimaryContextPass};
use clap::Parser;

#[derive(Parser, Resource, Clone, Debug)]
#[command(name = "ace-editor", about = "Preview human clips beside nonhuman characters")]
struct Args {
    /// Character URDF (a path, absolute or relative to the working directory).
    #[arg(long, default_value = "assets/characters/spot.urdf")]
    character: PathBuf,
    /// Human clip (BVH).
    #[arg(long, default_value = "assets/motions/walk.bvh")]
    clip: PathBuf,
    /// Save a screenshot of the window to this PNG once the scene is loaded, then exit.
    #[arg(long)]
    screenshot: Option<PathBuf>,
}

fn main() -> AppExit {
    let args = Args::parse();
    App::new()
        .add_plugins(DefaultPlugins.set(WindowPlugin {
            primary_window: Some(Window { title: "ACE editor".into(), resolution: (1280, 720).into(), ..default() }),
            ..default()
        }).set(AssetPlugin {
            // Paths given on the command line are resolved against the working directory.
            file_path: std::env::current_dir().map(|d| d.display().to_string()).unwrap_or_else(|_| ".".into()),
            // The user opens files anywhere on disk, not only below the working directory.
            unapproved_path_mode: bevy::asset::UnapprovedPathMode::Allow,
            ..default()
        }))
        .add_plugins((EguiPlugin::default(), AcePlugin))
        .insert_resource(args)
        .init_resource::<camera::OrbitCamera>()
        .add_systems(Startup, setup)
        .add_systems(Update, (camera::orbit, draw_grid_and_bones, screenshot_when_ready))
        .add_systems(EguiPrimaryContextPass, ui::panels)
        .run()
}

/// The scene's two actors.
#[derive(Resource)]
pub struct Scene {
    pub character: Entity,
    pub player: Entity,
}

fn absolute(p: &std::path::Path) -> PathBuf {
    std::path::absolute(p).unwrap_or_else(|_| p.to_path_buf())
}

fn setup(mut commands: Commands, assets: Res<AssetServer>, args: Res<Args>) {
    let character = commands
        .spawn((Character::new(assets.load(absolute(&args.character))), Transform::from_xyz(0.8, 0.0, 0.0)))
        .id();
    let player = commands
        .spawn((HumanClipPlayer::new(assets.load(absolute(&args.clip))), Transform::from_xyz(-0.8, 0.0, 0.0)))
        .id();
    commands.insert_resource(Scene { character, player });
    commands.spawn((DirectionalLight { illuminance: 9000.0, shadow_maps_enabled: true, ..default() }, Transform::from_xyz(3.0, 6.0, 4.0).looking_at(Vec3::ZERO, Vec3::Y)));
    commands.insert_resource(GlobalAmbientLight { brightness: 400.0, ..default() });
    commands.spawn((Camera3d::default(), camera::OrbitCamera::default().transform()));
}

/// Ground grid and human bones, drawn as gizmos.
fn draw_grid_and_bones(mut gizmos: Gizmos, players: Query<&HumanJoints>, joints: Query<&GlobalTransform, With<HumanJoint>>) {
    for i in -10..=10 {
        let c = i as f32 * 0.5;
        let color = if i == 0 { Color::srgb(0.55, 0.55, 0.55) } else { Color::srgb(0.35, 0.35, 0.35) };
        gizmos.line(Vec3::new(c, 0.0, -5.0), Vec3::new(c, 0.0, 5.0), color);
        gizmos.line(Vec3::new(-5.0, 0.0, c), Vec3::new(5.0, 0.0, c), color);
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

/// With `--screenshot`, waits until both actors are spawned and a few frames have rendered,
/// saves the window and exits.
fn screenshot_when_ready(
    mut commands: Commands,
    args: Res<Args>,
    ready: Query<(), Or<(With<CharacterLinks>, With<HumanJoints>)>>,
    mut frames: Local<u32>,
    mut exit: MessageWriter<AppExit>,
) {
    let Some(path) = &args.screenshot else { return };
    if ready.iter().count() < 2 {
        return;
    }
    *frames += 1;
    if *frames == 30 {
        commands.spawn(Screenshot::primary_window()).observe(save_to_disk(path.clone()));
    }
    if *frames == 45 {
        exit.write(AppExit::Success);
    }
}
