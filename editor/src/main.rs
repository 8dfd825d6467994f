//! The ACE editor: a Bevy + egui authoring app. A human clip and a character side by side on a
//! ground grid with an orbit camera; the clip retargeted with the character's checkpoint (exactly
//! as `ace retarget` does), its metrics and flagged frames on a timeline; the end-effector mapping
//! and the loss weights, "Retrain briefly" to fine-tune under them, and export to glTF and a robot
//! command trajectory.
//!
//! ```text
//! cargo run -p ace_editor -- [--character FILE.urdf|FILE.glb|NAME] [--checkpoint DIR] [--clip FILE.bvh] [--tour DIR]
//! ```
//!
//! A URDF robot is shown as its links (the plugin spawns them); a rigged glTF creature as its own glTF
//! scene, whose skin joints the plugin's creature path drives ([`bevy_ace::scene`]): the skinned mesh
//! deforms. Both are posed from the same [`Pose`], the preview's poses.

mod camera;
mod export;
mod jobs;
mod open;
mod plots;
mod preview;
mod retrain;
mod series;
mod tour;
mod ui;

#[cfg(test)]
mod plot_tests;
#[cfg(test)]
mod tests;

use std::path::PathBuf;
use std::time::Duration;

use bevy::asset::AssetPath;
use bevy::prelude::*;
use bevy::world_serialization::WorldAssetRoot;
use bevy_ace::ace_models::human::Joint;
use bevy_ace::ace_models::nalgebra::{UnitQuaternion, Vector3};
use bevy_ace::convert;
use bevy_ace::prelude::*;
use bevy_egui::{EguiPlugin, EguiPrimaryContextPass};
use clap::Parser;

#[derive(Parser, Resource, Clone, Debug)]
#[command(name = "ace-editor", about = "Retarget human clips onto nonhuman characters, tune and export")]
struct Args {
    /// Character: a URDF robot or a rigged glTF creature (.glb, .gltf), as a path (absolute or relative
    /// to the working directory) or a bundled character's name (spot, crab, stretch, hound).
    #[arg(long, default_value = "assets/characters/spot.urdf")]
    character: String,
    /// Checkpoint directory; by default the one shipped for a bundled character.
    #[arg(long)]
    checkpoint: Option<PathBuf>,
    /// Human clip (BVH).
    #[arg(long, default_value = "assets/motions/walk.bvh")]
    clip: PathBuf,
    /// Run the scripted tour: screenshots of the main states into this folder (the preview, a
    /// brief retraining under way, its result), with the figures in `tour.json`; then exit.
    #[arg(long)]
    tour: Option<PathBuf>,
}

/// What is open: the character, its checkpoint and the clip. Changing it respawns what changed and
/// recomputes the preview.
#[derive(Resource, Clone, Debug, PartialEq)]
pub struct Session {
    /// The character's file (URDF or glTF).
    pub character: PathBuf,
    /// For a glTF creature, where its scene goes ([`open::scene_placement`]).
    pub scene_placement: Option<Transform>,
    pub checkpoint: Option<PathBuf>,
    pub clip: PathBuf,
    /// The preview holds every joint but the wheels to its velocity limit, as `ace retarget
    /// --limit-velocity` does: what a robot executing the motion would do.
    pub limit_velocity: bool,
}

/// The scene's two actors.
#[derive(Resource)]
pub struct Scene {
    pub character: Entity,
    pub player: Entity,
}

fn main() -> AppExit {
    let args = Args::parse();
    let absolute = |p: &std::path::Path| std::path::absolute(p).unwrap_or_else(|_| p.to_path_buf());
    let opened = match open::open_character(&args.character) {
        Ok(o) => o,
        Err(e) => {
            eprintln!("error: {e:#}");
            return AppExit::error();
        }
    };
    let session = Session {
        checkpoint: args.checkpoint.as_deref().map(absolute).or(opened.checkpoint),
        clip: absolute(&args.clip),
        character: opened.path,
        scene_placement: opened.scene_placement,
        limit_velocity: false,
    };
    let mut app = App::new();
    app.add_plugins(
        DefaultPlugins
            .set(WindowPlugin {
                primary_window: Some(Window { title: "ACE editor".into(), resolution: (1600, 900).into(), ..default() }),
                ..default()
            })
            .set(AssetPlugin {
                // Paths given on the command line are resolved against the working directory.
                file_path: std::env::current_dir().map(|d| d.display().to_string()).unwrap_or_else(|_| ".".into()),
                // The user opens files anywhere on disk, not only below the working directory.
                unapproved_path_mode: bevy::asset::UnapprovedPathMode::Allow,
                ..default()
            }),
    )
    .add_plugins((EguiPlugin::default(), AcePlugin))
    .insert_resource(session)
    .init_resource::<camera::OrbitCamera>()
    .init_resource::<preview::Preview>()
    .init_resource::<retrain::Retrain>()
    .init_resource::<ui::UiState>()
    .add_systems(Startup, setup)
    .add_systems(Update, (camera::orbit, follow, apply_session, preview::poll, retrain::poll))
    .add_systems(Last, pace)
    .add_systems(
        PostUpdate,
        (
            preview::show.in_set(AceSystems::Retarget),
            // After propagation, so that the bones sit on this frame's joints.
            draw_grid_and_bones.after(bevy::transform::TransformSystems::Propagate),
        ),
    )
    .add_systems(EguiPrimaryContextPass, ui::panels);
    if let Some(dir) = args.tour {
        app.insert_resource(tour::Tour::new(dir)).add_systems(Update, tour::run);
    }
    app.run()
}

fn setup(mut commands: Commands) {
    commands.spawn((DirectionalLight { illuminance: 9000.0, shadow_maps_enabled: true, ..default() }, Transform::from_xyz(3.0, 6.0, 4.0).looking_at(Vec3::ZERO, Vec3::Y)));
    commands.insert_resource(GlobalAmbientLight { brightness: 400.0, ..default() });
    commands.spawn((Camera3d::default(), camera::OrbitCamera::default().transform()));
}

/// Respawns the character or the clip player when the session names other files, and recomputes
/// the preview whenever the session changes.
fn apply_session(
    mut commands: Commands,
    session: Res<Session>,
    mut shown: Local<Option<Session>>,
    scene: Option<ResMut<Scene>>,
    assets: Res<AssetServer>,
    mut preview: ResMut<preview::Preview>,
) {
    if shown.as_ref() == Some(&*session) {
        return;
    }
    let before = shown.replace(session.clone());
    let spawn_character = |commands: &mut Commands| spawn_character(commands, &assets, &session);
    let spawn_player = |commands: &mut Commands| commands.spawn(HumanClipPlayer::new(assets.load(session.clip.clone()))).id();
    match (scene, before) {
        (Some(mut scene), Some(before)) => {
            if (&before.character, before.scene_placement) != (&session.character, session.scene_placement) {
                commands.entity(scene.character).despawn();
                scene.character = spawn_character(&mut commands);
            }
            if before.clip != session.clip {
                commands.entity(scene.player).despawn();
                scene.player = spawn_player(&mut commands);
            }
        }
        _ => {
            let character = spawn_character(&mut commands);
            let player = spawn_player(&mut commands);
            commands.insert_resource(Scene { character, player });
        }
    }
    match &session.checkpoint {
        Some(checkpoint) => preview.compute(preview::PreviewInputs {
            character: session.character.clone(),
            checkpoint: checkpoint.clone(),
            clip: session.clip.clone(),
            limit_velocity: session.limit_velocity,
        }),
        None => preview.result = None,
    }
}

/// While a training runs and the clip is paused, the editor rests a quarter of a second after each
/// frame, leaving the CPU to the training: the progress needs no more. (A frame of the debug build with
/// a software renderer costs about as much CPU as a training step on two cores.)
fn pace(scene: Option<Res<Scene>>, players: Query<&HumanClipPlayer>, retrain: Res<retrain::Retrain>) {
    let playing = scene.and_then(|s| players.get(s.player).ok()).is_some_and(|p| !p.paused);
    if retrain.running() && !playing {
        std::thread::sleep(Duration::from_millis(250));
    }
}

/// Spawns the session's character: a URDF robot as a [`Character`] (the plugin spawns its links), a
/// glTF creature as its own glTF scene with a [`CreatureScene`] (the plugin finds its joints by name and
/// writes them from the [`Pose`] the preview sets, as it does for a Retargeter), placed by
/// [`open::scene_placement`].
pub fn spawn_character(commands: &mut Commands, assets: &AssetServer, session: &Session) -> Entity {
    let path = session.character.clone();
    match session.scene_placement {
        Some(placement) => commands
            .spawn((
                WorldAssetRoot(assets.load(AssetPath::from_path_buf(path.clone()).with_label("Scene0"))),
                CreatureScene::new(assets.load(path)),
                RetargetStatus::default(),
                placement,
            ))
            .id(),
        None => commands.spawn(Character::new(assets.load(path))).id(),
    }
}

/// Keeps the camera between the actors as the clip travels, and the human 1.2 m beside the
/// character's start, turned to start facing the way the character does (+x).
fn follow(
    scene: Option<Res<Scene>>,
    preview: Res<preview::Preview>,
    links: Query<&CharacterLinks>,
    humans: Query<&HumanJoints>,
    transforms: Query<&GlobalTransform>,
    mut players: Query<&mut Transform, With<HumanClipPlayer>>,
    mut orbit: ResMut<camera::OrbitCamera>,
    time: Res<Time>,
) {
    let Some(scene) = scene else { return };
    if let (Some(result), Ok(mut t)) = (&preview.result, players.get_mut(scene.player)) {
        if let Some(first) = result.clip.frames.first() {
            // The character starts facing +x; the human is turned to start facing the same way.
            let f = first.forward();
            let turn = UnitQuaternion::from_axis_angle(&Vector3::z_axis(), -f.y.atan2(f.x));
            let p = first.positions[Joint::Pelvis.index()];
            let placed = Transform {
                translation: convert::vec3(&(turn * Vector3::new(-p.x, -p.y, 0.0) + Vector3::new(0.0, 1.2, 0.0))),
                rotation: convert::quat(&turn),
                scale: Vec3::ONE,
            };
            if *t != placed {
                *t = placed;
            }
        }
    }
    // A robot's root link; a creature's entity (the plugin moves it with the root's ground travel).
    let root = match links.get(scene.character) {
        Ok(l) => l.0.first().and_then(|&e| transforms.get(e).ok()),
        Err(_) => transforms.get(scene.character).ok(),
    };
    let Some(root) = root else { return };
    let pelvis = humans
        .get(scene.player)
        .ok()
        .and_then(|j| transforms.get(j.0[Joint::Pelvis.index()]).ok())
        .map_or(root.translation(), |p| p.translation());
    let middle = (root.translation() + pelvis) / 2.0;
    let target = Vec3::new(middle.x, 0.6, middle.z);
    // Far enough to see both when the clip takes them apart.
    let apart = root.translation().distance(pelvis);
    let k = (time.delta_secs() * 3.0).min(1.0);
    let focus = orbit.focus.lerp(target, k);
    let distance = orbit.distance.max(4.0 + 1.5 * apart).min(30.0);
    if focus.distance(orbit.focus) > 1e-4 || distance != orbit.distance {
        orbit.focus = focus;
        orbit.distance = distance;
    }
}

/// Ground grid and human bones, drawn as gizmos.
fn draw_grid_and_bones(mut gizmos: Gizmos, players: Query<&HumanJoints>, joints: Query<&GlobalTransform, With<HumanJoint>>) {
    for i in -20..=20 {
        let c = i as f32 * 0.5;
        let color = if i == 0 { Color::srgb(0.55, 0.55, 0.55) } else { Color::srgb(0.35, 0.35, 0.35) };
        gizmos.line(Vec3::new(c, 0.0, -10.0), Vec3::new(c, 0.0, 10.0), color);
        gizmos.line(Vec3::new(-10.0, 0.0, c), Vec3::new(10.0, 0.0, c), color);
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
