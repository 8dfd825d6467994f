//! The editor's egui panels: files and character on the left with the end-effector mapping, the
//! loss weights and "Retrain briefly"; metrics and export on the right; the timeline with its plots
//! at the bottom right.

use std::path::{Path, PathBuf};

use ace::models::features::FeatureBlock;
use ace::models::metrics::percent;
use ace::models::human::EndEffector;
use ace::models::human_set::PROJECT_FPS;
use ace::models::character::is_gltf;
use bevy::asset::LoadState;
use bevy::prelude::*;
use bevy::world_serialization::WorldAssetRoot;
use bevy_ace::prelude::*;
use bevy_egui::{EguiContexts, egui};

use crate::export::export;
use crate::open::{describe, kind, open_character};
use crate::plots;
use crate::preview::Preview;
use crate::retrain::Retrain;
use crate::{Scene, Session};

/// Text fields and messages of the panels.
#[derive(Resource, Default)]
pub struct UiState {
    clip: String,
    character: String,
    checkpoint: String,
    export: String,
    message: Option<String>,
    shown: Option<Session>,
}

fn absolute(text: &str) -> PathBuf {
    let p = Path::new(text.trim());
    std::path::absolute(p).unwrap_or_else(|_| p.to_path_buf())
}

/// All panels.
#[allow(clippy::too_many_arguments)]
pub fn panels(
    mut contexts: EguiContexts,
    mut session: ResMut<Session>,
    scene: Option<Res<Scene>>,
    mut state: ResMut<UiState>,
    preview: Res<Preview>,
    mut retrain: ResMut<Retrain>,
    mut players: Query<&mut HumanClipPlayer>,
    characters: Query<(Option<&Character>, Option<&CreatureScene>, Option<&WorldAssetRoot>, Option<&RetargetStatus>)>,
    character_assets: Res<Assets<CharacterAsset>>,
    server: Res<AssetServer>,
) -> Result {
    let ctx = contexts.ctx_mut()?;
    // The text fields follow the session when it changes from elsewhere (a finished training).
    if state.shown.as_ref() != Some(&*session) {
        state.clip = shown(&session.clip);
        state.character = shown(&session.character);
        state.checkpoint = session.checkpoint.as_deref().map(shown).unwrap_or_default();
        let stem = |p: &Path| p.file_stem().map(|s| s.to_string_lossy().into_owned()).unwrap_or_default();
        state.export = format!("out/editor/{}_{}.glb", stem(&session.clip), stem(&session.character));
        state.shown = Some(session.clone());
    }

    egui::Window::new("ACE editor")
        .anchor(egui::Align2::LEFT_TOP, [8.0, 8.0])
        .default_width(380.0)
        .default_height(ctx.content_rect().height() - 130.0)
        .resizable(false)
        .vscroll(true)
        .show(ctx, |ui| {
            files(ui, &mut session, &mut state, &preview, &mut retrain);
            ui.separator();
            if let Some((character, creature, root, status)) = scene.as_ref().and_then(|s| characters.get(s.character).ok()) {
                let handle = character.map(|c| &c.asset).or(creature.map(|c| &c.asset));
                if let Some(asset) = handle.and_then(|h| character_assets.get(h)) {
                    ui.label(format!("{} ({})", describe(&asset.tree, &asset.morphology), kind(&session.character)));
                }
                // What keeps a creature's scene from showing: Bevy's glTF loader, or joints not found.
                if let Some(LoadState::Failed(e)) = root.map(|r| server.load_state(&r.0)) {
                    ui.colored_label(egui::Color32::LIGHT_RED, format!("the scene of {} did not load: {e}", session.character.display()));
                }
                if let Some(RetargetStatus::Failed(e)) = status {
                    ui.colored_label(egui::Color32::LIGHT_RED, e);
                }
            }
            ui.separator();
            mapping(ui, &preview, &mut retrain);
            ui.separator();
            weights_and_retrain(ui, &preview, &mut retrain);
        });

    egui::Window::new("Metrics")
        .anchor(egui::Align2::RIGHT_TOP, [-8.0, 8.0])
        .default_width(300.0)
        .resizable(false)
        .show(ctx, |ui| metrics_and_export(ui, &preview, &mut state));

    if let Some(scene) = scene {
        if let Ok(mut player) = players.get_mut(scene.player) {
            // Bottom right, under the metrics: the panel on the left reaches down to the bottom.
            egui::Window::new("Timeline")
                .anchor(egui::Align2::RIGHT_BOTTOM, [-8.0, -8.0])
                .default_width(760.0)
                .resizable(false)
                .title_bar(false)
                .show(ctx, |ui| timeline(ui, &mut player, &preview));
        }
    }
    Ok(())
}

fn files(ui: &mut egui::Ui, session: &mut Session, state: &mut UiState, preview: &Preview, retrain: &mut Retrain) {
    ui.heading("Clip");
    if let Some(p) = path_row(ui, &mut state.clip, "Open") {
        state.message = None;
        match p.is_file() {
            true => session.clip = p,
            false => state.message = Some(format!("no BVH file at {}", p.display())),
        }
    }
    ui.heading("Character");
    ui.small("a URDF robot, a rigged glTF creature (.glb, .gltf) or a bundled name (spot, crab, stretch, hound)");
    if let Some(text) = text_row(ui, &mut state.character, "Open") {
        state.message = None;
        match open_character(&text) {
            Ok(o) => {
                session.checkpoint = o.checkpoint;
                session.character = o.path;
                session.scene_placement = o.scene_placement;
            }
            Err(e) => state.message = Some(format!("{e:#}")),
        }
    }
    ui.label("Checkpoint");
    if let Some(p) = path_row(ui, &mut state.checkpoint, "Use") {
        state.message = None;
        match p.join("ace.json").is_file() {
            true => session.checkpoint = Some(p),
            false => state.message = Some(format!("{} holds no ace.json (train one with the button below or `ace train`)", p.display())),
        }
    }
    if ui
        .add_enabled(!retrain.running(), egui::Button::new("Train a checkpoint for this character (~45 min)"))
        .on_hover_text("Motion prior, then ACE, with the CPU defaults, into out/editor/checkpoints/")
        .clicked()
    {
        retrain.train_new(session.character.clone());
    }
    ui.checkbox(&mut session.limit_velocity, "Hold joints to their velocity limits").on_hover_text(
        "As `ace retarget --limit-velocity`: no joint but the wheels moves faster than its URDF's velocity limit, \
         which a robot executing the motion needs; the Metrics panel scores the motion as held",
    );
    if let Some(m) = &state.message {
        ui.colored_label(egui::Color32::LIGHT_RED, m);
    }
    if preview.busy() {
        ui.horizontal(|ui| {
            ui.spinner();
            ui.label("retargeting the clip…");
        });
    }
    if let Some(e) = &preview.error {
        ui.colored_label(egui::Color32::LIGHT_RED, e);
    }
    if session.checkpoint.is_none() {
        ui.label("No checkpoint for this character: train one to retarget.");
    }
}

/// A path field with a button; the absolute path when the button is clicked.
/// `path` as the panels show it: relative to the working directory when it lies below it (the session
/// holds absolute paths; a field's text is resolved against the working directory again when opened).
pub(crate) fn shown(path: &Path) -> String {
    std::env::current_dir()
        .ok()
        .and_then(|cwd| path.strip_prefix(cwd).ok().map(Path::to_path_buf))
        .filter(|rel| !rel.as_os_str().is_empty())
        .unwrap_or_else(|| path.to_path_buf())
        .display()
        .to_string()
}

fn path_row(ui: &mut egui::Ui, text: &mut String, button: &str) -> Option<PathBuf> {
    text_row(ui, text, button).map(|t| absolute(&t))
}

/// A text field with a button; the text when the button is clicked.
fn text_row(ui: &mut egui::Ui, text: &mut String, button: &str) -> Option<String> {
    ui.horizontal(|ui| {
        ui.add(egui::TextEdit::singleline(text).desired_width(280.0));
        ui.button(button).clicked().then(|| text.clone())
    })
    .inner
}

fn ee_name(e: Option<EndEffector>) -> &'static str {
    e.map_or("none", EndEffector::name)
}

fn mapping(ui: &mut egui::Ui, preview: &Preview, retrain: &mut Retrain) {
    ui.heading("End-effector mapping");
    let (Some(result), Some(settings)) = (&preview.result, retrain.settings.as_mut()) else {
        ui.label("(needs a checkpoint)");
        return;
    };
    let corr = &result.record.correspondence;
    ui.label("KL between each character end effector's and each human end effector's positions (nats); the lowest is the automatic pair.");
    egui::Grid::new("mapping").striped(true).show(ui, |ui| {
        ui.strong("link");
        ui.strong("maps to");
        for e in EndEffector::ALL {
            ui.strong(e.name());
        }
        ui.end_row();
        for (j, link) in corr.character_links.iter().enumerate() {
            ui.label(link);
            let automatic = corr.scores[j]
                .iter()
                .enumerate()
                .min_by(|a, b| a.1.total_cmp(b.1))
                .map(|(i, _)| EndEffector::ALL[i]);
            let choice = settings.mapping.entry(link.clone()).or_default();
            let text = match choice {
                None => format!("auto ({})", ee_name(automatic)),
                Some(e) => ee_name(*e).to_string(),
            };
            egui::ComboBox::from_id_salt(("map", j)).selected_text(text).show_ui(ui, |ui| {
                ui.selectable_value(choice, None, "automatic");
                for e in EndEffector::ALL {
                    ui.selectable_value(choice, Some(Some(e)), e.name());
                }
                ui.selectable_value(choice, Some(None), "none");
            });
            let used = corr.mapping.human[j];
            for (i, e) in EndEffector::ALL.iter().enumerate() {
                let s = format!("{:.2}", corr.scores[j][i]);
                if used == Some(*e) {
                    ui.strong(s);
                } else {
                    ui.label(s);
                }
            }
            ui.end_row();
        }
    });
    ui.small("Bold: the pairs this checkpoint was trained with. A change takes effect with \"Retrain briefly\".");
}

/// A slider for a loss weight, 0 to 100 on a logarithmic scale (weights that matter range from 0.1 to
/// tens: the crab's and Stretch's end effectors weigh 10). Only the user's edits are clamped: showing a
/// checkpoint's settings never changes them, whatever they are.
fn weight_slider<N: egui::emath::Numeric>(v: &mut N) -> egui::Slider<'_> {
    egui::Slider::new(v, N::from_f64(0.0)..=N::from_f64(100.0))
        .logarithmic(true)
        .clamping(egui::SliderClamping::Edits)
}

pub(crate) fn weights_and_retrain(ui: &mut egui::Ui, preview: &Preview, retrain: &mut Retrain) {
    ui.heading("Loss weights");
    if let Some(s) = retrain.settings.as_mut() {
        ui.add(weight_slider(&mut s.w_adv).text("w_adv"));
        ui.add(weight_slider(&mut s.w_fea).text("w_fea"));
        for block in FeatureBlock::ALL {
            ui.add(weight_slider(s.feature_weights.weight_mut(block)).text(block.name()));
        }
        ui.add(egui::Slider::new(&mut s.steps, 20..=2000).logarithmic(true).text("steps"));
    }
    let ready = !retrain.running() && !preview.busy() && preview.result.is_some();
    if ui.add_enabled(ready, egui::Button::new("Retrain briefly")).on_hover_text("Fine-tune the generator from this checkpoint under these settings, into out/editor/retrained/").clicked() {
        retrain.start(preview);
    }
    if retrain.started.is_none() {
        return;
    }
    let steps = retrain.history.last().map(|p| (p.step, p.steps));
    let fraction = steps.map_or(0.0, |(d, n)| {
        let first = retrain.history.first().map_or(0, |p| p.step - 1);
        (d - first) as f32 / (n - first).max(1) as f32
    });
    let elapsed = retrain.seconds.unwrap_or_else(|| retrain.started.map_or(0.0, |s| s.elapsed().as_secs_f32()));
    // Not animated: an animation asks egui for every frame, and a paused editor redraws ten times a second.
    ui.add(egui::ProgressBar::new(fraction).show_percentage());
    ui.label(format!("{} ({elapsed:.0} s)", retrain.stage));
    if let Some(e) = &retrain.error {
        ui.colored_label(egui::Color32::LIGHT_RED, e);
    }
    if let Some(before) = retrain.fea_before {
        let after = retrain.fea_after.map_or("…".to_string(), |a| format!("{a:.3}"));
        ui.label(format!("L_fea on this clip: {before:.3} before, {after} after"));
    }
    if let Some(plot) = plots::losses(ui, &retrain.history) {
        // The plot sits below the mapping and the weights: bring it into view as the run starts.
        if std::mem::take(&mut retrain.reveal_losses) {
            plot.scroll_to_me(Some(egui::Align::BOTTOM));
        }
    }
}

pub(crate) fn metrics_and_export(ui: &mut egui::Ui, preview: &Preview, state: &mut UiState) {
    let Some(result) = &preview.result else {
        ui.label(if preview.busy() { "retargeting…" } else { "no preview" });
        return;
    };
    let r = &result.retargeted.report;
    let rates = &r.ufr.rates;
    let opt = |v: Option<f32>| v.map_or("n/a".to_string(), |v| format!("{v:.3}"));
    ui.label(format!("{} frames at {PROJECT_FPS} fps, retargeted in {:.1} s", r.frames, result.seconds));
    egui::Grid::new("metrics").striped(true).show(ui, |ui| {
        for (name, value) in [
            ("L_fea (lower is better)", opt(r.feature_loss)),
            ("following (higher is better)", opt(r.following.as_ref().and_then(|f| f.score))),
            ("heading error (lower is better)", ace::eval::heading(r)),
            ("pace (1 = the human's, at the speed scale)", ace::eval::pace(r)),
            ("UFR (lower is better)", format!("{:.2} %", 100.0 * rates.ufr)),
            ("  self-collision", format!("{:.2} %", 100.0 * rates.self_collision)),
            ("  foot penetration", format!("{:.2} %", 100.0 * rates.penetration)),
            ("  foot sliding", format!("{:.2} %", 100.0 * rates.sliding)),
            ("over a velocity limit (lower is better)", ace::eval::velocity_limits(r)),
            ("DIV", format!("{:.3}", r.div)),
            ("FID (lower is better)", opt(r.fid)),
        ]
        .into_iter()
        .chain(r.gait.iter().flat_map(|g| {
            [
                ("steps", format!("{} swings, median {:.0} frames", g.swings, g.median_swing_frames)),
                ("  pops (a foot up 1–2 frames)", percent(g.pop_rate())),
                ("  micro-steps (under 0.1 body lengths)", percent(g.micro_step_rate())),
                ("  stride frequency ÷ Alexander's law", g.median_ratio.map_or("n/a".into(), |x| format!("{x:.2}×"))),
            ]
        })) {
            ui.label(name);
            ui.label(value);
            ui.end_row();
        }
    });
    if r.following.is_some() {
        ui.label(format!("While the human stands (root within 5 cm and 10° for 1 s), the character's root: {}", ace::eval::standing(r)));
    }
    if let Some(clip) = r.following.as_ref().and_then(|f| f.clips.first()) {
        ui.label("Following the human (correlation 1 = does what the human does; amplitude 1 = same size; stillness: body lengths moved while the human's is still):");
        egui::Grid::new("following").striped(true).show(ui, |ui| {
            for h in ["end effector", "vertical", "forward", "amplitude", "stillness"] {
                ui.strong(h);
            }
            ui.end_row();
            for p in &clip.0.pairs {
                ui.label(format!("{} ~ {}", p.character, p.human.name()));
                for v in [p.correlation.vertical, p.correlation.forward, p.amplitude_ratio, p.stillness] {
                    ui.label(opt(v));
                }
                ui.end_row();
            }
        });
    }
    ui.small(format!("checkpoint {}", shown(&result.inputs.checkpoint)));
    ui.separator();
    ui.heading("Export");
    ui.add(egui::TextEdit::singleline(&mut state.export).desired_width(280.0));
    let creature = is_gltf(&result.inputs.character);
    ui.small(if creature {
        "The creature's own model with the clip as a new animation on its skeleton (as `ace retarget` writes it)"
    } else {
        "The robot's animation with the human beside it (as `ace retarget` writes it)"
    });
    if ui.button("Export glTF and trajectory").clicked() {
        let written = export(result, &absolute(&state.export));
        state.message = Some(match written {
            Ok(w) => format!("wrote {}, {}, {} and {}", w.glb.display(), w.json.display(), w.csv.display(), w.metrics.display()),
            Err(e) => format!("export failed: {e:#}"),
        });
    }
    if let Some(m) = &state.message {
        ui.label(m);
    }
}

/// The timeline strip's background.
pub(crate) const STRIP: egui::Color32 = egui::Color32::from_gray(40);
/// The timeline's mark of a frame a UFR detector flags (in the strip's upper half).
pub(crate) const UFR_MARK: egui::Color32 = egui::Color32::from_rgb(230, 80, 70);
/// The timeline's mark of a frame a popping swing is in the air (in the strip's lower half).
pub(crate) const POP_MARK: egui::Color32 = egui::Color32::from_rgb(240, 180, 40);

pub(crate) fn timeline(ui: &mut egui::Ui, player: &mut HumanClipPlayer, preview: &Preview) {
    let flags = preview.result.as_ref().map(|r| &r.retargeted.flags);
    let (ufr, pops): (&[bool], &[bool]) = flags.map_or((&[], &[]), |f| (&f.ufr, &f.pops));
    let duration = (ufr.len().max(1) - 1) as f32 / PROJECT_FPS;
    ui.horizontal(|ui| {
        if ui.button(if player.paused { "▶ play" } else { "⏸ pause" }).clicked() {
            player.paused = !player.paused;
        }
        ui.add(egui::Slider::new(&mut player.speed, 0.1..=2.0).text("speed"));
        ui.label(format!("{:.2} / {duration:.2} s, frame {}", player.time, (player.time * PROJECT_FPS).round() as usize));
        let count = |f: &[bool]| f.iter().filter(|&&f| f).count();
        ui.colored_label(UFR_MARK, format!("{} frames flagged by the UFR detectors", count(ufr)));
        ui.colored_label(POP_MARK, format!("{} frames of popping swings (a foot up 1–2 frames)", count(pops)));
    });
    let (rect, response) = ui.allocate_exact_size(egui::vec2(ui.available_width(), 26.0), egui::Sense::click_and_drag());
    let painter = ui.painter_at(rect);
    painter.rect_filled(rect, 3.0, STRIP);
    let x_of = |t: f32| rect.left() + rect.width() * (t / duration.max(1e-6)).clamp(0.0, 1.0);
    let (top, middle, bottom) = (rect.top() + 3.0, rect.center().y, rect.bottom() - 3.0);
    for (marks, colour, [y0, y1]) in [(ufr, UFR_MARK, [top, middle]), (pops, POP_MARK, [middle, bottom])] {
        for (k, _) in marks.iter().enumerate().filter(|(_, f)| **f) {
            let x = x_of(k as f32 / PROJECT_FPS);
            painter.line_segment([egui::pos2(x, y0), egui::pos2(x, y1)], egui::Stroke::new(2.0, colour));
        }
    }
    let x = x_of(player.time);
    painter.line_segment([egui::pos2(x, rect.top()), egui::pos2(x, rect.bottom())], egui::Stroke::new(2.5, egui::Color32::WHITE));
    if let Some(pos) = response.interact_pointer_pos() {
        let t = ((pos.x - rect.left()) / rect.width()).clamp(0.0, 1.0) * duration;
        player.seek(t);
    }
    let Some(result) = &preview.result else { return };
    egui::CollapsingHeader::new("Following: the character against the human, each in its own body lengths").default_open(true).show(ui, |ui| {
        if let Some(t) = plots::timeline(ui, &result.series, player.time) {
            player.seek(t.min(duration));
        }
    });
}
