//! An orbit camera: left-drag turns, right-drag pans, the wheel zooms.

use bevy::input::mouse::{AccumulatedMouseMotion, AccumulatedMouseScroll};
use bevy::prelude::*;

/// Orbit state, kept as a resource and written to the one 3-D camera.
#[derive(Resource, Clone, Debug)]
pub struct OrbitCamera {
    pub focus: Vec3,
    pub yaw: f32,
    pub pitch: f32,
    pub distance: f32,
}

impl Default for OrbitCamera {
    fn default() -> Self {
        Self { focus: Vec3::new(0.0, 0.6, 0.0), yaw: 0.5, pitch: 0.4, distance: 6.0 }
    }
}

impl OrbitCamera {
    /// The camera transform for this orbit state.
    pub fn transform(&self) -> Transform {
        let rotation = Quat::from_euler(EulerRot::YXZ, self.yaw, -self.pitch, 0.0);
        Transform::from_translation(self.focus + rotation * Vec3::Z * self.distance).looking_at(self.focus, Vec3::Y)
    }
}

/// Applies mouse input (ignored while egui uses the pointer) and places the camera.
pub fn orbit(
    mut orbit: ResMut<OrbitCamera>,
    buttons: Res<ButtonInput<MouseButton>>,
    motion: Res<AccumulatedMouseMotion>,
    scroll: Res<AccumulatedMouseScroll>,
    mut egui: bevy_egui::EguiContexts,
    mut cameras: Query<&mut Transform, With<Camera3d>>,
) {
    let pointer_on_ui = egui.ctx_mut().map(|c| c.egui_wants_pointer_input()).unwrap_or(false);
    if !pointer_on_ui {
        let d = motion.delta;
        if buttons.pressed(MouseButton::Left) {
            orbit.yaw -= d.x * 0.008;
            orbit.pitch = (orbit.pitch + d.y * 0.008).clamp(-1.4, 1.4);
        }
        if buttons.pressed(MouseButton::Right) {
            let t = orbit.transform();
            let pan = (t.right() * -d.x + t.up() * d.y) * 0.002 * orbit.distance;
            orbit.focus += pan;
        }
        orbit.distance = (orbit.distance * (1.0 - scroll.delta.y * 0.1)).clamp(0.5, 40.0);
    }
    if orbit.is_changed() {
        for mut t in &mut cameras {
            *t = orbit.transform();
        }
    }
}
