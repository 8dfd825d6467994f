//! The editor's egui panels.

use bevy::prelude::*;
use bevy_ace::prelude::*;
use bevy_egui::{EguiContexts, egui};

use crate::Scene;

/// The scene panel: what is loaded, and playback controls for the clip.
pub fn panels(
    mut contexts: EguiContexts,
    scene: Option<Res<Scene>>,
    characters: Query<&Character>,
    mut players: Query<&mut HumanClipPlayer>,
    urdfs: Res<Assets<UrdfAsset>>,
    clips: Res<Assets<BvhAsset>>,
) -> Result {
    let ctx = contexts.ctx_mut()?;
    let Some(scene) = scene else { return Ok(()) };
    egui::Window::new("Scene").anchor(egui::Align2::LEFT_TOP, [8.0, 8.0]).default_width(280.0).resizable(false).show(ctx, |ui| {
        ui.heading("Character");
        match characters.get(scene.character).ok().and_then(|c| urdfs.get(&c.urdf)) {
            Some(urdf) => {
                let names = |v: &[usize]| v.iter().map(|&i| urdf.tree.links[i].name.as_str()).collect::<Vec<_>>().join(", ");
                ui.label(format!("{}: {} links, {} DoF", urdf.tree.name, urdf.tree.links.len(), urdf.tree.dof()));
                ui.label(format!("feet: {}", names(&urdf.morphology.feet)));
                ui.label(format!("manipulators: {}", names(&urdf.morphology.manipulators)));
                ui.label(format!("wheels: {}", names(&urdf.morphology.wheels)));
            }
            None => {
                ui.label("loading…");
            }
        }
        ui.separator();
        ui.heading("Human clip");
        if let Ok(mut player) = players.get_mut(scene.player) {
            match clips.get(&player.clip) {
                Some(asset) => {
                    let clip = &asset.clip;
                    ui.label(format!("{} ({}): {} frames at {} fps", clip.name, clip.convention, clip.frames.len(), clip.fps));
                    ui.label(format!("height {:.2} m", clip.height_m));
                    let duration = clip.duration();
                    ui.horizontal(|ui| {
                        let label = if player.paused { "▶ play" } else { "⏸ pause" };
                        if ui.button(label).clicked() {
                            player.paused = !player.paused;
                        }
                        ui.add(egui::Slider::new(&mut player.speed, 0.1..=2.0).text("speed"));
                    });
                    let mut t = player.time;
                    if ui.add(egui::Slider::new(&mut t, 0.0..=duration).text("s")).changed() {
                        player.seek(t);
                    }
                }
                None => {
                    ui.label("loading…");
                }
            }
        }
    });
    Ok(())
}
