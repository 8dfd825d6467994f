//! Primitive meshes for link geometry and human joints (feature `render`).
//!
//! In a headless app without Bevy's renderer the mesh and material stores are absent and nothing
//! is spawned; the link and joint entities are the same either way.

use ace_models::geometry::{Geometry, Shape};
use ace_models::human::Joint;
use ace_models::kinematics::Link;
use bevy::ecs::system::SystemParam;
use bevy::prelude::*;

use crate::convert;

/// Mesh and material stores, present when Bevy's renderer is.
#[derive(SystemParam)]
pub(crate) struct VisualAssets<'w> {
    meshes: Option<ResMut<'w, Assets<Mesh>>>,
    materials: Option<ResMut<'w, Assets<StandardMaterial>>>,
}

/// The Bevy mesh of a primitive shape, in the shape's own frame after the change of basis.
/// Mesh references are not loaded (the URDF's `package://` paths rarely resolve); `None` for them.
pub fn shape_mesh(shape: &Shape) -> Option<Mesh> {
    match shape {
        Shape::Box { size } => Some(Cuboid::from_size(convert::vec3(size).abs()).into()),
        Shape::Cylinder { radius, length } => Some(Cylinder::new(*radius, *length).into()),
        Shape::Sphere { radius } => Some(Sphere::new(*radius).into()),
        Shape::Capsule { radius, length } => Some(Capsule3d::new(*radius, *length).into()),
        Shape::Mesh { .. } => None,
    }
}

impl VisualAssets<'_> {
    /// Spawns one mesh child per visual geometry of `link` (collision geometry when it has no
    /// primitive visual), under the link entity `parent`.
    pub(crate) fn spawn_link_visuals(&mut self, commands: &mut Commands, parent: Entity, link: &Link) {
        let (Some(meshes), Some(materials)) = (self.meshes.as_mut(), self.materials.as_mut()) else { return };
        let primitive = |g: &&Geometry| !matches!(g.shape, Shape::Mesh { .. });
        let geometry: Vec<&Geometry> = if link.visuals.iter().any(|g| primitive(&g)) {
            link.visuals.iter().filter(primitive).collect()
        } else {
            link.collisions.iter().filter(primitive).collect()
        };
        for g in geometry {
            let Some(mesh) = shape_mesh(&g.shape) else { continue };
            let material = materials.add(StandardMaterial { base_color: Color::srgb(0.85, 0.62, 0.18), perceptual_roughness: 0.6, ..default() });
            commands.spawn((Mesh3d(meshes.add(mesh)), MeshMaterial3d(material), convert::transform(&g.origin), ChildOf(parent)));
        }
    }

    /// Spawns a small sphere on a human joint entity.
    pub(crate) fn spawn_joint_visual(&mut self, commands: &mut Commands, parent: Entity, joint: Joint) {
        let (Some(meshes), Some(materials)) = (self.meshes.as_mut(), self.materials.as_mut()) else { return };
        let radius = if joint == Joint::Head { 0.09 } else { 0.035 };
        let material = materials.add(StandardMaterial { base_color: Color::srgb(0.25, 0.55, 0.9), ..default() });
        commands.spawn((Mesh3d(meshes.add(Sphere::new(radius))), MeshMaterial3d(material), Transform::default(), ChildOf(parent)));
    }
}
