//! # bevy_ace
//!
//! The Bevy layer of ACE retargeting: asset loaders for characters (`.urdf` robots, rigged `.glb`/`.gltf`
//! creatures), `.bvh` human clips and trained checkpoints, characters spawned as one entity per link and
//! posed from a [`Pose`] component, a human clip player, and the [`Retargeter`] component that drives a
//! character from a human source with a checkpoint every frame (feature `runtime`, on by default: the
//! networks in pure Rust, no libtorch). With feature `scene` (on by default) a Retargeter also drives a
//! rigged creature's own glTF scene: its skinned mesh deforms (see [`scene`]). The core
//! (kinematics, import, learning) lives in [`ace_models`], which knows nothing of Bevy.
//!
//! ```no_run
//! use bevy::prelude::*;
//! use bevy_ace::prelude::*;
//!
//! fn setup(mut commands: Commands, assets: Res<AssetServer>) {
//!     let walk = commands.spawn(HumanClipPlayer::new(assets.load("motions/walk.bvh"))).id();
//!     commands.spawn((
//!         Character::new(assets.load("characters/spot.urdf")),
//!         Retargeter::new(assets.load("checkpoints/spot/ace.json"), walk),
//!         Transform::from_xyz(1.5, 0.0, 0.0),
//!     ));
//! }
//!
//! App::new().add_plugins((DefaultPlugins, AcePlugin)).add_systems(Startup, setup).run();
//! ```
//!
//! [`Pose`]: character::Pose
//! [`Retargeter`]: retarget::Retargeter

pub mod assets;
pub mod character;
#[cfg(feature = "runtime")]
pub mod checkpoint;
pub mod convert;
pub mod human;
#[cfg(feature = "render")]
pub mod render;
#[cfg(feature = "runtime")]
pub mod retarget;
#[cfg(feature = "scene")]
pub mod scene;
#[cfg(feature = "runtime")]
mod worker;

pub use ace_models;

use bevy::prelude::*;
use bevy::transform::TransformSystems;

/// Commonly used items.
pub mod prelude {
    pub use crate::assets::{BvhAsset, BvhSettings, CharacterAsset};
    #[cfg(feature = "scene")]
    pub use crate::scene::CreatureScene;
    pub use crate::character::{Character, CharacterLink, CharacterLinks, Pose, RootOrigin};
    #[cfg(feature = "runtime")]
    pub use crate::checkpoint::CheckpointAsset;
    pub use crate::human::{HumanClipPlayer, HumanJoint, HumanJoints, HumanPose};
    #[cfg(feature = "runtime")]
    pub use crate::retarget::{LiveFrameRefused, LiveHuman, LiveHumanFrame, RetargetError, RetargetStatus, Retargeter};
    pub use crate::{AcePlugin, AceSystems};
}

/// The plugin's systems, chained in this order in `PostUpdate`, after Bevy's animation
/// (`AnimationSystems`: on the nodes a Retargeter drives, its pose wins) and before transform
/// propagation.
#[derive(SystemSet, Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum AceSystems {
    /// Spawn link and joint entities for newly loaded characters and clips; find a driven glTF scene's
    /// joints.
    Spawn,
    /// Advance clip players and sample their clips.
    Advance,
    /// Drive characters with a [`retarget::Retargeter`] (feature `runtime`): write the poses computed
    /// during the previous frame, send this frame's human states to the worker threads.
    Retarget,
    /// Turn poses into link and joint [`Transform`]s.
    Apply,
}

/// Registers the character (`.urdf`, and `.glb`/`.gltf` by asset type) and `.bvh` assets (and with feature `runtime` the checkpoint asset) and the
/// systems that spawn, play, retarget and pose them.
/// Needs an `AssetPlugin` and Bevy's transform plugin (both in `DefaultPlugins`).
pub struct AcePlugin;

impl Plugin for AcePlugin {
    fn build(&self, app: &mut App) {
        // The loaders read files beside the one loaded through the asset server (bounded reads).
        let server = app.world().resource::<AssetServer>().clone();
        app.init_asset::<assets::CharacterAsset>()
            .init_asset::<assets::BvhAsset>()
            .register_asset_loader(assets::CharacterLoader { server: server.clone() })
            .register_asset_loader(assets::BvhLoader { server: server.clone() })
            .configure_sets(
                PostUpdate,
                (AceSystems::Spawn, AceSystems::Advance, AceSystems::Retarget, AceSystems::Apply)
                    .chain()
                    .after(bevy::app::AnimationSystems)
                    .before(TransformSystems::Propagate),
            )
            .add_systems(
                PostUpdate,
                (
                    (character::spawn_characters, human::spawn_human_joints).in_set(AceSystems::Spawn),
                    human::advance_players.in_set(AceSystems::Advance),
                    (character::apply_poses, human::apply_human_poses).in_set(AceSystems::Apply),
                ),
            );
        #[cfg(feature = "runtime")]
        app.init_asset::<checkpoint::CheckpointAsset>()
            .register_asset_loader(checkpoint::CheckpointLoader { server })
            .init_resource::<retarget::Workers>()
            .add_message::<retarget::LiveHumanFrame>()
            .add_message::<retarget::RetargetError>()
            .add_observer(retarget::reset_removed)
            .add_systems(
                PostUpdate,
                (retarget::receive_live_frames, retarget::collect_poses, retarget::request_poses)
                    .chain()
                    .in_set(AceSystems::Retarget),
            );
        #[cfg(feature = "scene")]
        app.add_systems(
            PostUpdate,
            (
                (scene::release_scenes, scene::bind_scenes, scene::find_joints).chain().in_set(AceSystems::Spawn),
                scene::apply_scene_poses.in_set(AceSystems::Apply),
            ),
        );
    }
}
