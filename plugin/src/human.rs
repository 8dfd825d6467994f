//! Human clip playback: a player entity that advances through a BVH clip and poses one entity per
//! canonical joint.

use ace_models::human::{HumanFrame, JOINT_COUNT, Joint};
use bevy::prelude::*;

use crate::assets::BvhAsset;
use crate::convert;

/// Plays a human clip. Once the clip is loaded, one child entity per canonical joint is spawned
/// ([`HumanJoints`]) and [`HumanPose`] holds the frame shown, updated every frame.
#[derive(Component, Clone, Debug)]
#[require(Transform)]
pub struct HumanClipPlayer {
    /// The clip.
    pub clip: Handle<BvhAsset>,
    /// Playback position in seconds.
    pub time: f32,
    /// Playback rate (1 = real time; negative plays backwards).
    pub speed: f32,
    /// Whether time stands still.
    pub paused: bool,
    /// Wrap around at the ends instead of stopping there.
    pub looping: bool,
}

impl HumanClipPlayer {
    /// A looping player at real-time speed, starting at 0 s.
    pub fn new(clip: Handle<BvhAsset>) -> Self {
        Self { clip, time: 0.0, speed: 1.0, paused: false, looping: true }
    }

    /// Moves the playback position to `time` seconds (scrubbing).
    pub fn seek(&mut self, time: f32) {
        self.time = time;
    }
}

/// The human frame currently shown by a [`HumanClipPlayer`] (metres, z up, in the player's frame).
#[derive(Component, Clone, Debug, PartialEq, Deref)]
pub struct HumanPose(pub HumanFrame);

/// Joint entities of a player, in `Joint::ALL` order.
#[derive(Component, Clone, Debug)]
pub struct HumanJoints(pub [Entity; JOINT_COUNT]);

/// Marks a human joint entity.
#[derive(Component, Clone, Copy, Debug)]
pub struct HumanJoint {
    /// The entity holding [`HumanClipPlayer`].
    pub player: Entity,
    /// Which canonical joint.
    pub joint: Joint,
}

/// Spawns joint entities for players whose clip has finished loading.
pub(crate) fn spawn_human_joints(
    mut commands: Commands,
    players: Query<(Entity, &HumanClipPlayer), Without<HumanJoints>>,
    clips: Res<Assets<BvhAsset>>,
    #[cfg(feature = "render")] mut visuals: crate::render::VisualAssets,
) {
    for (player, p) in &players {
        if clips.get(&p.clip).is_none() {
            continue;
        }
        let joints = Joint::ALL.map(|joint| {
            let id = commands
                .spawn((Name::new(joint.name()), HumanJoint { player, joint }, Transform::default(), ChildOf(player)))
                .id();
            #[cfg(feature = "render")]
            {
                commands.entity(id).insert(Visibility::default());
                visuals.spawn_joint_visual(&mut commands, id, joint);
            }
            id
        });
        let mut e = commands.entity(player);
        e.insert(HumanJoints(joints));
        #[cfg(feature = "render")]
        e.insert_if_new(Visibility::default());
    }
}

/// Advances players by the frame's (virtual) time and samples their clips into [`HumanPose`].
pub(crate) fn advance_players(
    mut commands: Commands,
    mut players: Query<(Entity, &mut HumanClipPlayer, Option<&mut HumanPose>)>,
    clips: Res<Assets<BvhAsset>>,
    time: Res<Time>,
) {
    for (entity, mut player, pose) in &mut players {
        let Some(asset) = clips.get(&player.clip) else { continue };
        let duration = asset.clip.duration();
        if !player.paused {
            let t = player.time + time.delta_secs() * player.speed;
            player.time = if player.looping && duration > 0.0 { t.rem_euclid(duration) } else { t.clamp(0.0, duration) };
        }
        let frame = asset.clip.frame_at(player.time);
        match pose {
            Some(mut pose) => pose.0 = frame,
            None => {
                commands.entity(entity).insert(HumanPose(frame));
            }
        }
    }
}

/// Places joint entities at the positions of their player's [`HumanPose`]; the pelvis also takes
/// the root orientation.
pub(crate) fn apply_human_poses(
    players: Query<(&HumanPose, &HumanJoints), Changed<HumanPose>>,
    mut transforms: Query<&mut Transform, With<HumanJoint>>,
) {
    for (pose, joints) in &players {
        for joint in Joint::ALL {
            if let Ok(mut t) = transforms.get_mut(joints.0[joint.index()]) {
                t.translation = convert::vec3(&pose.positions[joint.index()]);
                if joint == Joint::Pelvis {
                    t.rotation = convert::quat(&pose.root_rotation);
                }
            }
        }
    }
}
