//! Rigged glTF creatures driven through their own glTF scene (feature `scene`): a [`Retargeter`] on an
//! entity with a [`WorldAssetRoot`] (Bevy 0.19's name for the former `SceneRoot`) drives the scene's
//! skin joints, so the artist's skinned mesh deforms.
//!
//! ```no_run
//! # use bevy::prelude::*;
//! # use bevy_ace::prelude::*;
//! fn setup(mut commands: Commands, assets: Res<AssetServer>) {
//!     let walk = commands.spawn(HumanClipPlayer::new(assets.load("motions/walk.bvh"))).id();
//!     commands.spawn((
//!         WorldAssetRoot(assets.load("creatures/hound.glb#Scene0")),
//!         Retargeter::new(assets.load("checkpoints/hound/ace.json"), walk),
//!         Transform::from_xyz(1.5, 0.0, 0.0),
//!     ));
//! }
//! ```
//!
//! - **The character** is the scene's own file, loaded as a [`CharacterAsset`] (`hound.glb` for
//!   `hound.glb#Scene0`, with the profile beside it if any); the checkpoint is checked against it as
//!   for a URDF character. The entity gets a [`CreatureScene`] holding it.
//! - **Joints** are the scene's entities whose [`Name`] is a driven bone's node name, found once the
//!   scene has spawned, and found again when it spawns anew (Bevy respawns a scene whose asset is
//!   replaced: a hot reload, or the file loaded again). Each driven bone must be there exactly once; otherwise the retargeter fails
//!   ([`RetargetStatus::Failed`] and a [`RetargetError`] naming the missing joint), as it does for a
//!   checkpoint trained for another character (a URDF robot's, say).
//! - **Poses** ([`Pose`], as for URDF characters) become the joints' local [`Transform`]s through
//!   [`ace_models::character::rig_pose`], the conversion the rig clip export uses: the scene moves as
//!   the exported clip plays. Nodes that are not driven keep their transforms.
//! - **Root motion moves the entity.** The pose's ground travel (horizontal position and heading) is
//!   written to the entity's [`Transform`] as [`RootOrigin`] × travel; the rest of the pose goes on the
//!   joints. [`RootOrigin`] is the entity's transform when the first pose arrives (insert it yourself to
//!   place the creature's world elsewhere, or change it to move that world).
//! - **Bevy's animation.** The Retargeter owns the skeleton: every frame, after Bevy's animation
//!   systems (`AnimationSystems`), in [`crate::AceSystems::Apply`], the plugin writes the driven joints
//!   from the pose and holds the skeleton's other nodes (the skin's other joints and their ancestors,
//!   found by name) at rest. A playing `AnimationPlayer` of the scene is overridden there and still
//!   shows on everything else (nodes outside the skeleton, morph weights). Removing the Retargeter
//!   removes the [`CreatureScene`] too, and the model's own clip shows again; without a player the
//!   last pose stays where it is.
//!
//! The scene is shown as authored: y up, facing the file's forward axis, in the file's units (scale
//! the entity to resize it; rotate it to stand up a creature whose profile sets another `up`). A URDF
//! character's links face +x instead.

use std::collections::HashMap;

use ace_models::character::is_gltf;
use ace_models::character::rig_pose::{NodeTransform, RigScratch};
use ace_models::kinematics::CharacterPose;
use bevy::prelude::*;
use bevy::world_serialization::{WorldAssetRoot, WorldInstance, WorldInstanceSpawner};

use crate::assets::CharacterAsset;
use crate::character::{Character, Pose, RootOrigin};
use crate::retarget::{RetargetError, RetargetStatus, Retargeter};

/// A glTF scene driven as a creature: its character asset and, once the scene has spawned, the
/// entity of each driven joint. Inserted on an entity with a [`Retargeter`] and a [`WorldAssetRoot`].
#[derive(Component, Clone, Debug)]
pub struct CreatureScene {
    /// The scene's file as a character.
    pub asset: Handle<CharacterAsset>,
    /// The entity of each driven node (in [`ace_models::character::RigPose::driven`]'s order), once
    /// found.
    pub joints: Option<Vec<Entity>>,
    /// The entities of the skeleton's other nodes found by name, with their node index: held at rest.
    pub held: Vec<(Entity, usize)>,
}

impl CreatureScene {
    /// A scene showing the character `asset`, its joints yet to be found.
    pub fn new(asset: Handle<CharacterAsset>) -> Self {
        Self { asset, joints: None, held: Vec::new() }
    }
}

fn fail(entity: Entity, message: String, status: &mut RetargetStatus, errors: &mut MessageWriter<RetargetError>) {
    if !matches!(status, RetargetStatus::Failed(_)) {
        errors.write(RetargetError { entity, message: message.clone() });
        *status = RetargetStatus::Failed(message);
    }
}

/// Gives each retargeted scene its [`CreatureScene`], loading the scene's file as a character.
pub(crate) fn bind_scenes(
    mut commands: Commands,
    mut scenes: Query<(Entity, &WorldAssetRoot, &mut RetargetStatus), (With<Retargeter>, Without<Character>, Without<CreatureScene>)>,
    server: Res<AssetServer>,
    mut errors: MessageWriter<RetargetError>,
) {
    for (entity, root, mut status) in &mut scenes {
        let Some(path) = root.0.path() else {
            let message = format!("the scene of {entity} was not loaded from a file: its character cannot be found");
            fail(entity, message, &mut status, &mut errors);
            continue;
        };
        if !is_gltf(path.path()) {
            let message = format!("the scene {path} of {entity} is not a glTF file: only glTF creatures can be driven");
            fail(entity, message, &mut status, &mut errors);
            continue;
        }
        let asset: Handle<CharacterAsset> = server.load(path.without_label().clone_owned());
        commands.entity(entity).insert(CreatureScene::new(asset));
    }
}

/// Forgets the scene of every entity whose [`Retargeter`] was removed, so that nothing drives its
/// joints any more (its own `AnimationPlayer`, if any, shows again). A [`RootOrigin`] stays: it may be
/// the user's.
pub(crate) fn release_scenes(
    mut commands: Commands,
    mut removed: RemovedComponents<Retargeter>,
    scenes: Query<(), (With<CreatureScene>, Without<Retargeter>)>,
) {
    for entity in removed.read() {
        if scenes.contains(entity) {
            commands.entity(entity).remove::<CreatureScene>();
        }
    }
}

/// Finds the joints of scenes that have spawned, and again when a scene spawns anew: Bevy respawns
/// every instance of a scene whose asset is replaced (its file hot-reloaded, or loaded a second time,
/// as when the `Gltf` asset was dropped and a clip of the same file is then asked for), with new
/// entities under the same instance.
pub(crate) fn find_joints(
    mut scenes: Query<(Entity, &mut CreatureScene, &WorldInstance, &mut RetargetStatus)>,
    spawner: Option<Res<WorldInstanceSpawner>>,
    names: Query<&Name>,
    characters: Res<Assets<CharacterAsset>>,
    mut errors: MessageWriter<RetargetError>,
) {
    // Without Bevy's world serialization plugin no scene spawns.
    let Some(spawner) = spawner else { return };
    for (entity, mut scene, instance, mut status) in &mut scenes {
        if scene.joints.as_ref().is_some_and(|joints| joints.iter().any(|&e| !names.contains(e))) {
            scene.joints = None;
            scene.held.clear();
        }
        if scene.joints.is_some() || !spawner.instance_is_ready(**instance) || matches!(*status, RetargetStatus::Failed(_)) {
            continue;
        }
        let Some(character) = characters.get(&scene.asset) else { continue };
        let Some(rig) = &character.rig else {
            fail(entity, format!("{} is not a glTF creature", character.tree.name), &mut status, &mut errors);
            continue;
        };
        let mut by_name: HashMap<&str, Vec<Entity>> = HashMap::new();
        for e in spawner.iter_instance_entities(**instance) {
            if let Ok(name) = names.get(e) {
                by_name.entry(name.as_str()).or_default().push(e);
            }
        }
        // Unnamed nodes are `node<i>` to the core and `GltfNode<i>` to Bevy's glTF loader; nodes sharing
        // a name are `<name> (node <i>)` to the core, and several nodes of that name here.
        let lookup = |node: usize, name: &str| {
            let shared = name.strip_suffix(&format!(" (node {node})"));
            by_name
                .get(name)
                .or_else(|| shared.and_then(|n| by_name.get(n)))
                .or_else(|| (name == format!("node{node}")).then(|| by_name.get(format!("GltfNode{node}").as_str())).flatten())
        };
        let mut joints = Vec::with_capacity(rig.driven().len());
        let mut problem = None;
        for d in rig.driven() {
            match lookup(d.node, &d.name).map(Vec::as_slice) {
                Some([e]) => joints.push(*e),
                found => {
                    let what = if found.is_none() { "has no joint named" } else { "has several nodes named" };
                    problem = Some(format!(
                        "the glTF scene of {entity} {what} `{}`, a joint of the creature {} (scene and character file differ)",
                        d.name, character.tree.name
                    ));
                    break;
                }
            }
        }
        match problem {
            Some(message) => fail(entity, message, &mut status, &mut errors),
            None => {
                scene.held = rig
                    .held()
                    .iter()
                    .filter_map(|(node, name)| match lookup(*node, name).map(Vec::as_slice) {
                        Some([e]) => Some((*e, *node)),
                        _ => None,
                    })
                    .collect();
                scene.joints = Some(joints);
            }
        }
    }
}

/// Writes the joints' [`Transform`]s and the entity's root motion from each driven scene's [`Pose`],
/// every frame (a playing `AnimationPlayer` writes the joints every frame too).
pub(crate) fn apply_scene_poses(
    mut commands: Commands,
    mut scenes: Query<(Entity, &CreatureScene, &Pose, Option<&RootOrigin>, &mut Transform)>,
    mut joints: Query<&mut Transform, Without<CreatureScene>>,
    characters: Res<Assets<CharacterAsset>>,
    mut scratch: Local<(RigScratch, Vec<NodeTransform>)>,
) {
    let (scratch, locals) = &mut *scratch;
    for (entity, scene, pose, origin, mut transform) in &mut scenes {
        let (Some(entities), Some(character)) = (&scene.joints, characters.get(&scene.asset)) else { continue };
        let Some(rig) = &character.rig else { continue };
        if pose.q.len() != character.tree.dof() {
            warn_once!("a Pose with {} joint positions was given to a creature with {} DoF", pose.q.len(), character.tree.dof());
            continue;
        }
        let travel = rig.root_motion(pose);
        let rest = CharacterPose { root: travel.inverse() * pose.root, q: pose.q.clone() };
        if let Err(e) = rig.write(&character.tree, &rest, scratch, locals) {
            warn_once!("{}: {e}", character.tree.name);
            continue;
        }
        for (&joint, local) in entities.iter().zip(locals.iter()) {
            if let Ok(mut t) = joints.get_mut(joint) {
                *t = crate::convert::node_transform(local);
            }
        }
        for &(e, node) in &scene.held {
            if let Ok(mut t) = joints.get_mut(e) {
                t.set_if_neq(crate::convert::node_transform(rig.rest(node)));
            }
        }
        let origin = match origin {
            Some(o) => o.0,
            None => {
                commands.entity(entity).insert(RootOrigin(*transform));
                *transform
            }
        };
        *transform = origin * crate::convert::node_transform(&rig.in_file_frame(&travel));
    }
}

