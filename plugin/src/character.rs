//! Characters: a [`CharacterAsset`] spawned as one entity per link, posed by a [`Pose`] component. (A
//! rigged glTF creature can also be driven through its own glTF scene: see [`crate::scene`].)

use ace_models::kinematics::CharacterPose;
use ace_models::nalgebra::Isometry3;
use bevy::prelude::*;

use crate::assets::CharacterAsset;
use crate::convert;

/// A character driven by this plugin. Spawn it with a handle to a character asset (a URDF, or a glTF
/// creature shown as its links' capsules); once the asset is
/// loaded, one child entity per link is spawned ([`CharacterLinks`]) and a neutral [`Pose`] is
/// inserted unless one is already there.
///
/// **Root motion moves the entity.** The pose's ground travel (the root's horizontal position and
/// heading, [`CharacterPose::ground_travel`]) is written to the entity's [`Transform`] as
/// [`RootOrigin`] × travel, and the links below it carry the rest: the root link stands over the
/// entity, facing its +x. [`RootOrigin`] places the character's world (z-up ground plane at the
/// origin) in the Bevy scene; it is the entity's transform when the first pose is applied (insert it
/// yourself to place that world elsewhere, or change it to move that world). A rigged creature driven
/// through its own glTF scene moves the same way ([`crate::scene`]).
#[derive(Component, Clone, Debug)]
#[require(Transform)]
pub struct Character {
    /// The character's file.
    pub asset: Handle<CharacterAsset>,
}

impl Character {
    /// A character from a character asset's handle.
    pub fn new(asset: Handle<CharacterAsset>) -> Self {
        Self { asset }
    }
}

/// The pose a character shows: root link pose (in the character's z-up world) and one position per
/// actuated DoF, in the tree's DoF order. Write it from any system; [`crate::AceSystems::Apply`] turns
/// it into link [`Transform`]s before transform propagation.
#[derive(Component, Clone, Debug, PartialEq, Deref, DerefMut)]
pub struct Pose(pub CharacterPose);

/// Where a character's world stands: the entity's [`Transform`] is this times the pose's ground
/// travel (see [`Character`]).
#[derive(Component, Clone, Copy, Debug, PartialEq, Deref, DerefMut)]
pub struct RootOrigin(pub Transform);

/// Link entities of a spawned character, in the tree's topological link order.
#[derive(Component, Clone, Debug)]
pub struct CharacterLinks(pub Vec<Entity>);

/// Marks a link entity: its character and its index in the kinematic tree.
#[derive(Component, Clone, Copy, Debug)]
pub struct CharacterLink {
    /// The entity holding [`Character`].
    pub character: Entity,
    /// Index into `KinematicTree::links`.
    pub index: usize,
}

/// Spawns link entities for characters whose asset has finished loading.
pub(crate) fn spawn_characters(
    mut commands: Commands,
    characters: Query<(Entity, &Character, Option<&Pose>), Without<CharacterLinks>>,
    assets: Res<Assets<CharacterAsset>>,
    #[cfg(feature = "render")] mut visuals: crate::render::VisualAssets,
) {
    for (entity, character, pose) in &characters {
        let Some(asset) = assets.get(&character.asset) else { continue };
        let mut links: Vec<Entity> = Vec::with_capacity(asset.tree.links.len());
        for (index, link) in asset.tree.links.iter().enumerate() {
            let parent = link.parent.map_or(entity, |p| links[p]);
            let id = commands
                .spawn((Name::new(link.name.clone()), CharacterLink { character: entity, index }, Transform::default(), ChildOf(parent)))
                .id();
            #[cfg(feature = "render")]
            {
                commands.entity(id).insert(Visibility::default());
                visuals.spawn_link_visuals(&mut commands, id, link);
            }
            links.push(id);
        }
        let mut e = commands.entity(entity);
        e.insert(CharacterLinks(links));
        if pose.is_none() {
            e.insert(Pose(asset.tree.standing_pose()));
        }
        #[cfg(feature = "render")]
        e.insert_if_new(Visibility::default());
    }
}

/// Writes each link's [`Transform`] (relative to its parent link; the root link's relative to the
/// entity) and the entity's root motion from the character's [`Pose`].
#[allow(clippy::type_complexity)]
pub(crate) fn apply_poses(
    mut commands: Commands,
    mut characters: Query<
        (Entity, &Character, &Pose, &CharacterLinks, Option<&RootOrigin>, &mut Transform),
        Or<(Changed<Pose>, Added<CharacterLinks>, Changed<RootOrigin>)>,
    >,
    mut transforms: Query<&mut Transform, (With<CharacterLink>, Without<Character>)>,
    assets: Res<Assets<CharacterAsset>>,
    mut world_poses: Local<Vec<Isometry3<f32>>>,
) {
    for (entity, character, pose, links, origin, mut placement) in &mut characters {
        let Some(asset) = assets.get(&character.asset) else { continue };
        if pose.q.len() != asset.tree.dof() {
            warn_once!("a Pose with {} joint positions was given to a character with {} DoF", pose.q.len(), asset.tree.dof());
            continue;
        }
        asset.tree.forward_kinematics_into(pose, &mut world_poses);
        let travel = pose.ground_travel(&asset.tree.standing_pose().root.rotation);
        for (index, link) in asset.tree.links.iter().enumerate() {
            let local = match link.parent {
                Some(p) => world_poses[p].inv_mul(&world_poses[index]),
                None => travel.inv_mul(&world_poses[index]),
            };
            if let Ok(mut t) = transforms.get_mut(links.0[index]) {
                *t = convert::transform(&local);
            }
        }
        let origin = match origin {
            Some(o) => o.0,
            None => {
                commands.entity(entity).insert(RootOrigin(*placement));
                *placement
            }
        };
        *placement = origin * convert::transform(&travel);
    }
}
