//! A live human source fed from code: a mocap stream is simulated by sending the frames of a BVH
//! file as [`LiveHumanFrame`] messages at the file's own rate (120 Hz for the bundled clips), stamped
//! with the stream's clock, the way a network mocap client would. Spot follows the stream.
//!
//! ```text
//! cargo run --example live_source -- [clip.bvh]      (default: assets/motions/wave.bvh)
//! ```

use bevy::prelude::*;
use bevy_ace::ace_models::human::clip::HumanFrame;
use bevy_ace::ace_models::human::{HumanClip, ImportOptions, Joint};
use bevy_ace::prelude::*;

/// The simulated stream: the frames and how many were sent.
#[derive(Resource)]
struct Stream {
    fps: f32,
    frames: Vec<HumanFrame>,
    sent: usize,
    source: Entity,
}

fn main() -> AppExit {
    let path = std::env::args().nth(1).unwrap_or_else(|| concat!(env!("CARGO_MANIFEST_DIR"), "/assets/motions/wave.bvh").into());
    let clip = match HumanClip::from_bvh_file(path.as_ref(), &ImportOptions::default()) {
        Ok(c) => c,
        Err(e) => {
            eprintln!("{e}");
            return AppExit::error();
        }
    };
    App::new()
        .add_plugins(DefaultPlugins.set(AssetPlugin {
            file_path: concat!(env!("CARGO_MANIFEST_DIR"), "/assets").into(),
            ..default()
        }))
        .add_plugins(AcePlugin)
        .insert_resource(Stream { fps: clip.fps, frames: clip.frames, sent: 0, source: Entity::PLACEHOLDER })
        .add_systems(Startup, setup)
        .add_systems(Update, (send_frames, draw))
        .run()
}

fn setup(mut commands: Commands, server: Res<AssetServer>, mut stream: ResMut<Stream>) {
    stream.source = commands.spawn(LiveHuman::default()).id();
    commands.spawn((
        Character::new(server.load("characters/spot.urdf")),
        Retargeter::new(server.load("checkpoints/spot/ace.json"), stream.source),
        Transform::from_xyz(1.0, 0.0, 0.0),
    ));
    commands.spawn((Camera3d::default(), Transform::from_xyz(0.0, 2.0, 5.0).looking_at(Vec3::new(0.0, 0.6, 0.0), Vec3::Y)));
    commands.spawn((DirectionalLight { illuminance: 9000.0, ..default() }, Transform::from_xyz(3.0, 6.0, 4.0).looking_at(Vec3::ZERO, Vec3::Y)));
}

/// Sends every frame whose time has come, looping the recording with a continuing clock.
fn send_frames(time: Res<Time>, mut stream: ResMut<Stream>, mut out: MessageWriter<LiveHumanFrame>) {
    while (stream.sent as f32) / stream.fps <= time.elapsed_secs() {
        let frame = stream.frames[stream.sent % stream.frames.len()].clone();
        out.write(LiveHumanFrame { source: stream.source, time: stream.sent as f32 / stream.fps, frame });
        stream.sent += 1;
    }
}

/// The streamed human as a stick figure beside the robot, and a ground grid.
fn draw(mut gizmos: Gizmos, stream: Res<Stream>, live: Query<&LiveHuman>) {
    for i in -8..=8 {
        let c = i as f32 * 0.5;
        gizmos.line(Vec3::new(c, 0.0, -4.0), Vec3::new(c, 0.0, 4.0), Color::srgb(0.35, 0.35, 0.35));
        gizmos.line(Vec3::new(-4.0, 0.0, c), Vec3::new(4.0, 0.0, c), Color::srgb(0.35, 0.35, 0.35));
    }
    let Ok(l) = live.get(stream.source) else { return };
    let Some(frame) = l.latest_time().and_then(|t| l.frame_at(t)) else { return };
    let at = |j: Joint| bevy_ace::convert::vec3(&frame.position(j)) + Vec3::new(-1.0, 0.0, 0.0);
    for joint in Joint::ALL {
        if let Some(parent) = joint.parent() {
            gizmos.line(at(joint), at(parent), Color::srgb(0.3, 0.6, 1.0));
        }
    }
}
