//! The editor's plots (egui_plot: axes, a legend, values on hover, Ctrl and the wheel zoom, a drag
//! pans, a double click resets; the wheel alone scrolls the panel, not the plot): the losses of "Retrain briefly" per step, and on the timeline the
//! root speeds, headings and end-effector heights of the character against the human's ([`Series`]), with
//! the current time marked; a click on a timeline plot seeks there.

use ace::models::learn::train_ace::AceProgress;
use bevy_egui::egui;
use egui_plot::{HoverPosition, Legend, Line, LineStyle, Plot, PlotPoints, VLine};

use crate::series::{PairHeights, Series};

/// A named series of `[x, y]` points.
pub type NamedSeries = (&'static str, Vec<[f64; 2]>);

/// Every loss a retraining reports, per step: L_fea, L_adv, the generator's weighted total and the
/// discriminator's loss.
pub fn loss_series(history: &[AceProgress]) -> [NamedSeries; 4] {
    let series = |value: fn(&AceProgress) -> f64| history.iter().map(|p| [p.step as f64, value(p)]).collect();
    [
        ("L_fea", series(|p| p.fea)),
        ("L_adv", series(|p| p.adv)),
        ("G: w_adv·L_adv + w_fea·L_fea", series(|p| p.g_loss)),
        ("D", series(|p| p.d_loss)),
    ]
}

const LOSS_COLOURS: [egui::Color32; 4] = [
    egui::Color32::from_rgb(235, 150, 40),
    egui::Color32::from_rgb(90, 160, 240),
    egui::Color32::from_rgb(120, 200, 120),
    egui::Color32::from_rgb(200, 120, 200),
];

/// The losses of a retraining (nothing before its first step); the plot's response.
pub fn losses(ui: &mut egui::Ui, history: &[AceProgress]) -> Option<egui::Response> {
    if history.is_empty() {
        return None;
    }
    ui.small("Click a legend entry to hide a series (the axes refit to the rest).");
    let response = Plot::new("losses")
        .height(150.0)
        .allow_scroll(false)
        .legend(Legend::default().position(egui_plot::Corner::RightTop))
        .x_axis_label("step")
        .y_axis_label("loss")
        .label_formatter(|pos| match pos {
            HoverPosition::NearDataPoint { plot_name, position, .. } => {
                Some(format!("{plot_name}\nstep {:.0}: {:.4}", position.x, position.y))
            }
            HoverPosition::Elsewhere { .. } => None,
        })
        .show(ui, |plot| {
            for ((name, points), colour) in loss_series(history).into_iter().zip(LOSS_COLOURS) {
                plot.line(Line::new(name, PlotPoints::from(points)).color(colour));
            }
        });
    Some(response.response)
}

const CHARACTER: egui::Color32 = egui::Color32::from_rgb(235, 150, 40);
const HUMAN: egui::Color32 = egui::Color32::from_rgb(90, 160, 240);
const PAIR_COLOURS: [egui::Color32; 8] = [
    egui::Color32::from_rgb(235, 150, 40),
    egui::Color32::from_rgb(90, 160, 240),
    egui::Color32::from_rgb(120, 200, 120),
    egui::Color32::from_rgb(220, 90, 90),
    egui::Color32::from_rgb(200, 120, 200),
    egui::Color32::from_rgb(230, 210, 80),
    egui::Color32::from_rgb(80, 200, 200),
    egui::Color32::from_rgb(190, 190, 190),
];

/// `values` at `fps` as `[seconds, value]` points.
fn timed(values: &[f32], fps: f32) -> PlotPoints<'static> {
    values.iter().enumerate().map(|(t, &v)| [t as f64 / fps as f64, v as f64]).collect()
}

/// The timeline's plots of `series`, with `time` (s) marked; the time clicked, if any.
pub fn timeline(ui: &mut egui::Ui, series: &Series, time: f32) -> Option<f32> {
    let fps = series.fps;
    let frame_at = |index: usize| format!("frame {index} ({:.2} s)", index as f32 / fps);
    let speed = against_human(
        ui,
        "root speed",
        ("root ground speed (character body lengths/s; human: the speed asked, at the speed scale) over the clip (s)", "speed"),
        (&series.character_speed, &series.human_speed),
        fps,
        time,
        |index| {
            let (c, h) = (series.character_speed.get(index)?, series.human_speed.get(index)?);
            Some(format!("{}\ncharacter {c:.2}, human {h:.2} body lengths/s", frame_at(index)))
        },
    );
    let heading = against_human(
        ui,
        "heading",
        ("change of heading since the first frame (degrees, left positive) over the clip (s)", "heading"),
        (&series.character_heading, &series.human_heading),
        fps,
        time,
        |index| {
            let (c, h) = (series.character_heading.get(index)?, series.human_heading.get(index)?);
            Some(format!("{}\ncharacter {c:.0}°, human {h:.0}° ({:.0}° off)", frame_at(index), (c - h).abs()))
        },
    );
    let small_legend = Legend::default().position(egui_plot::Corner::LeftTop).text_style(egui::TextStyle::Small);
    let heights = timeline_plot("end-effector heights", 130.0, small_legend)
        .x_axis_label("end-effector heights above the ground (body lengths) over the clip (s); solid: character, dashed: human")
        .y_axis_label("height")
        .label_formatter(|pos| match pos {
            HoverPosition::NearDataPoint { plot_name, index, .. } => {
                let p = series.pairs.iter().find(|p| pair_name(p) == *plot_name)?;
                Some(format!(
                    "{plot_name}, {}\ncharacter {:.3}, human {:.3} body lengths",
                    frame_at(*index),
                    p.character_height.get(*index)?,
                    p.human_height.get(*index)?,
                ))
            }
            HoverPosition::Elsewhere { .. } => None,
        })
        .show(ui, |plot| {
            // A pair's two lines share its name, so one legend entry shows or hides both.
            for (k, p) in series.pairs.iter().enumerate() {
                let colour = PAIR_COLOURS[k % PAIR_COLOURS.len()];
                plot.line(Line::new(pair_name(p), timed(&p.character_height, fps)).color(colour));
                plot.line(Line::new(pair_name(p), timed(&p.human_height, fps)).color(colour).style(LineStyle::dashed_dense()));
            }
            plot.vline(now(time));
            clicked_time(plot)
        });
    speed.or(heading).or(heights.inner)
}

/// A timeline plot, 90 px high, of one quantity per frame at `fps`: the character's (solid) against
/// the human's (dashed), `hover` giving the text at a frame; the time clicked, if any.
fn against_human(
    ui: &mut egui::Ui,
    id: &str,
    (x_label, y_label): (&str, &str),
    (character, human): (&[f32], &[f32]),
    fps: f32,
    time: f32,
    hover: impl Fn(usize) -> Option<String>,
) -> Option<f32> {
    timeline_plot(id, 90.0, Legend::default().position(egui_plot::Corner::LeftTop))
        .x_axis_label(x_label)
        .y_axis_label(y_label)
        .label_formatter(|pos| match pos {
            HoverPosition::NearDataPoint { index, .. } => hover(*index),
            HoverPosition::Elsewhere { .. } => None,
        })
        .show(ui, |plot| {
            plot.line(Line::new("character", timed(character, fps)).color(CHARACTER));
            plot.line(Line::new("human", timed(human, fps)).color(HUMAN).style(LineStyle::dashed_dense()));
            plot.vline(now(time));
            clicked_time(plot)
        })
        .inner
}

/// A plot of the timeline: its time axis and cursor linked with the other timeline plots, the wheel
/// left to the panel.
fn timeline_plot<'a>(id: &str, height: f32, legend: Legend) -> Plot<'a> {
    Plot::new(id)
        .height(height)
        .allow_scroll(false)
        .link_axis("timeline", [true, false])
        .link_cursor("timeline", [true, false])
        .legend(legend)
}

/// A pair's name in the legend: the character's end effector and the human's it follows.
pub fn pair_name(p: &PairHeights) -> String {
    format!("{} ~ {}", p.character, p.human.name())
}

/// The current time's mark (no legend entry, no hover).
fn now(time: f32) -> VLine {
    VLine::new("", time).color(egui::Color32::WHITE).allow_hover(false)
}

fn clicked_time(plot: &egui_plot::PlotUi<'_>) -> Option<f32> {
    if plot.response().clicked() { plot.pointer_coordinate().map(|p| p.x.max(0.0) as f32) } else { None }
}
