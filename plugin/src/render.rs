//! Primitive meshes for link geometry and human joints (feature `render`).
//!
//! In a headless app without Bevy's renderer the mesh and material stores are absent and nothing
//! is spawned; the link and joint entities are the same either way.

use ace_models::geometry::Shape;
use ace_models::human::Joint;
use ace_models::kinematics::Link;
use ace_models::nalgebra::Isometry3;
use bevy::ecs::system::SystemParam;
use bevy::prelude::*;

use crate::convert;

/// Mesh and material stores, present when Bevy's renderer is.
#[derive(SystemParam)]
pub(crate) struct VisualAssets<'w> {
    meshes: Option<ResMut<'w, Assets<Mesh>>>,
    materials: Option<ResMut<'w, Assets<StandardMaterial>>>,
}

/// The Bevy mesh of a shape and where it sits in the shape's frame. Mesh files are not loaded:
/// they show as their bounding box when the importer could read it, else not at all.
pub fn shape_mesh(shape: &Shape) -> Option<(Mesh, Isometry3<f32>)> {
    let at_origin = Isometry3::identity();
    match shape {
        Shape::Box { size } => Some((Cuboid::from_size(convert::vec3(size).abs()).into(), at_origin)),
        Shape::Cylinder { radius, length } => Some((Cylinder::new(*radius, *length).into(), at_origin)),
        Shape::Sphere { radius } => Some((Sphere::new(*radius).into(), at_origin)),
        Shape::Capsule { radius, length } => Some((Capsule3d::new(*radius, *length).into(), at_origin)),
        Shape::Mesh { bounds: Some(b), scale, .. } => {
            let size = (b.max - b.min).component_mul(scale);
            let center = b.center().coords.component_mul(scale);
            Some((Cuboid::from_size(convert::vec3(&size).abs()).into(), Isometry3::translation(center.x, center.y, center.z)))
        }
        Shape::Mesh { bounds: None, .. } => None,
    }
}

impl VisualAssets<'_> {
    /// Spawns one mesh child per visual geometry of `link` under the link entity `parent`.
    pub(crate) fn spawn_link_visuals(&mut self, commands: &mut Commands, parent: Entity, link: &Link) {
        let (Some(meshes), Some(materials)) = (self.meshes.as_mut(), self.materials.as_mut()) else { return };
        for g in &link.visuals {
            let Some((mesh, offset)) = shape_mesh(&g.shape) else { continue };
            let material = materials.add(StandardMaterial { base_color: Color::srgb(0.85, 0.62, 0.18), perceptual_roughness: 0.6, ..default() });
            commands.spawn((Mesh3d(meshes.add(mesh)), MeshMaterial3d(material), convert::transform(&(g.origin * offset)), ChildOf(parent)));
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
