//! The scripted tour (`--tour DIR`): the editor shows its main states by itself and saves a
//! screenshot of each (Bevy's screenshot API), for the README and for checking the editor runs:
//! the preview of the clip, "Retrain briefly" under way (with w_fea doubled, a typical change; the
//! other settings are the defaults), and its result; the figures (L_fea before and after, the
//! retraining's duration) go to `tour.json`. Then the app exits.

use std::path::PathBuf;
use std::time::Instant;

use bevy::prelude::*;
use bevy::render::view::screenshot::{Screenshot, save_to_disk};
use serde_json::json;

use bevy_ace::prelude::HumanClipPlayer;

use crate::Scene;
use crate::preview::Preview;
use crate::retrain::Retrain;

/// The clip time the pictures show (s).
const SHOWN_AT: f32 = 1.5;

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Step {
    Preview,
    Retraining,
    Retrained,
    Exit,
}

/// Where the tour is.
#[derive(Resource)]
pub struct Tour {
    dir: PathBuf,
    step: Step,
    frames: u32,
    started: Instant,
}

impl Tour {
    /// A tour saving into `dir`.
    pub fn new(dir: PathBuf) -> Tour {
        Tour { dir, step: Step::Preview, frames: 0, started: Instant::now() }
    }

    fn shoot(&self, commands: &mut Commands, name: &str) {
        let path = self.dir.join(name);
        info!("tour: saving {}", path.display());
        commands.spawn(Screenshot::primary_window()).observe(save_to_disk(path));
    }
}

/// Advances the tour (see the module docs).
#[allow(clippy::too_many_arguments)]
pub fn run(
    mut commands: Commands,
    mut tour: ResMut<Tour>,
    scene: Option<Res<Scene>>,
    mut players: Query<&mut HumanClipPlayer>,
    preview: Res<Preview>,
    mut retrain: ResMut<Retrain>,
    mut exit: MessageWriter<AppExit>,
) {
    if tour.frames == 0 && tour.step == Step::Preview {
        if let Err(e) = std::fs::create_dir_all(&tour.dir) {
            error!("tour: cannot create {}: {e}", tour.dir.display());
            exit.write(AppExit::error());
            return;
        }
    }
    tour.frames += 1;
    // The same moment of the clip in every picture.
    if let Some(mut player) = scene.and_then(|s| players.get_mut(s.player).ok()) {
        if !player.paused || player.time != SHOWN_AT {
            player.paused = true;
            player.seek(SHOWN_AT);
        }
    }
    if let Some(e) = preview.error.as_ref().or(retrain.error.as_ref()) {
        error!("tour: {e}");
        exit.write(AppExit::error());
        return;
    }
    if tour.started.elapsed().as_secs() > 900 {
        error!("tour: not done after 15 minutes");
        exit.write(AppExit::error());
        return;
    }
    match tour.step {
        Step::Preview => {
            if preview.result.is_none() || preview.busy() || retrain.settings.is_none() {
                tour.frames = 1;
            } else if tour.frames == 40 {
                tour.shoot(&mut commands, "editor-preview.png");
            } else if tour.frames == 50 {
                // A user's typical change: the feature loss weighted twice as much.
                if let Some(s) = retrain.settings.as_mut() {
                    s.w_fea *= 2.0;
                }
                retrain.start(&preview);
                tour.step = Step::Retraining;
                tour.frames = 0;
            }
        }
        Step::Retraining => {
            let half = retrain.history.last().is_some_and(|p| {
                let first = retrain.history[0].step;
                2 * (p.step - first) >= p.steps - first
            });
            if half && tour.frames < 1_000_000 {
                tour.shoot(&mut commands, "editor-retraining.png");
                tour.step = Step::Retrained;
                tour.frames = 0;
            }
        }
        Step::Retrained => {
            if retrain.fea_after.is_none() {
                tour.frames = 0;
            } else if tour.frames == 40 {
                tour.shoot(&mut commands, "editor-retrained.png");
                let figures = json!({
                    "steps": retrain.history.len(),
                    "w_fea": retrain.settings.as_ref().map(|s| s.w_fea),
                    "retrain_seconds": retrain.seconds,
                    "fea_before": retrain.fea_before,
                    "fea_after": retrain.fea_after,
                    "checkpoint": preview.result.as_ref().map(|r| r.inputs.checkpoint.display().to_string()),
                });
                let path = tour.dir.join("tour.json");
                if let Err(e) = std::fs::write(&path, serde_json::to_string_pretty(&figures).unwrap_or_default()) {
                    error!("tour: cannot write {}: {e}", path.display());
                }
                info!("tour: {figures}");
                tour.step = Step::Exit;
                tour.frames = 0;
            }
        }
        Step::Exit => {
            if tour.frames == 20 {
                exit.write(AppExit::Success);
            }
        }
    }
}
