//! The picture report of `ace dataset --report DIR`: so a person can see the gaits at a glance.
//!
//! Two windows of the dataset are shown, the episode with the slowest and the one with the fastest
//! mean commanded speed (at most [`WINDOW_SECONDS`] of each), as
//! - `gait.png`: the contact timeline of each foot (a bar where the foot is in stance), and the
//!   dataset's stride frequency against speed beside Alexander's law (medians per speed bin of the gait
//!   measure);
//! - `velocity.png`: commanded vs achieved base velocity (forward, sideways, yaw rate), the achieved one
//!   read back from x^r;
//! - `foot_heights.png`: the height of each foot point above the ground;
//!
//! plus `metrics.json` (what `ace metrics --json` prints for the file).

use std::ops::Range;
use std::path::Path;

use ace::models::dataset::MotionSet;
use ace::models::dynamic_similarity::stride_frequency;
use ace::models::kinematics::KinematicTree;
use ace::models::metrics::MetricsReport;
use ace::models::morphology::Morphology;
use anyhow::{Context, Result};

use ace::plot::{Color, Figure, LineChart, Series, Timeline};

/// Longest stretch of an episode shown (s).
pub const WINDOW_SECONDS: f32 = 12.0;

/// Writes the report into `dir` (created if needed).
pub fn write(dir: &Path, tree: &KinematicTree, morph: &Morphology, set: &MotionSet, metrics: &MetricsReport) -> Result<()> {
    std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
    let windows = windows(set);
    let time = |w: &Range<usize>, i: usize| (i - w.start) as f64 / f64::from(set.fps);

    let mut gait = Figure::new(1200);
    let mut velocity = Figure::new(1200);
    let mut heights = Figure::new(1200);
    for (label, w) in &windows {
        let title = window_title(set, label, w);
        if set.n_feet > 0 {
            let rows = (0..set.n_feet)
                .map(|f| (set.end_effector_links[f].clone(), w.clone().map(|i| set.contact(i)[f] == 1).collect()))
                .collect();
            gait.push(Timeline { title: format!("Foot contacts: {title}"), x_label: "time (s)".into(), dt: 1.0 / f64::from(set.fps), rows }, 100 + 30 * set.n_feet as u32);
        }
        let lin = set.layout.root_linear_velocity().start;
        let ang = set.layout.root_angular_velocity().start;
        for (k, (name, unit)) in [("forward velocity", "m/s"), ("sideways velocity", "m/s"), ("yaw rate", "rad/s")].into_iter().enumerate() {
            let achieved = |i: usize| f64::from(if k < 2 { set.state(i)[lin + k] } else { set.state(i)[ang + 2] });
            velocity.push(
                LineChart {
                    title: format!("{name}: {title}"),
                    x_label: "time (s)".into(),
                    y_label: unit.into(),
                    series: vec![
                        Series { name: "commanded".into(), color: Color::GRAY, points: w.clone().map(|i| (time(w, i), f64::from(set.commands[i][k]))).collect() },
                        Series { name: "achieved".into(), color: Color::BLUE, points: w.clone().map(|i| (time(w, i), achieved(i))).collect() },
                    ],
                    log_y: false,
                },
                260,
            );
        }
        if set.n_feet > 0 {
            let series = (0..set.n_feet)
                .map(|f| Series {
                    name: set.end_effector_links[f].clone(),
                    color: Color::palette(f),
                    points: w
                        .clone()
                        .map(|i| {
                            let links = tree.forward_kinematics(&set.pose(i));
                            (time(w, i), f64::from(morph.ee_point(morph.feet[f], &links).z))
                        })
                        .collect(),
                })
                .collect();
            heights.push(LineChart { title: format!("Foot heights: {title}"), x_label: "time (s)".into(), y_label: "m".into(), series, log_y: false }, 320);
        }
    }
    if let Some(g) = metrics.gait.as_ref().filter(|g| !g.bins.is_empty()) {
        // Stride frequency against speed, the dataset's bin medians beside Alexander's law.
        let top = g.bins.iter().map(|b| b.speed[1]).fold(0.0, f32::max).min(g.bins.last().map_or(1.0, |b| 1.5 * b.median_speed));
        let law = (1..=60)
            .map(|i| {
                let v = g.bins[0].speed[0] + (top - g.bins[0].speed[0]) * i as f32 / 60.0;
                (f64::from(v), f64::from(stride_frequency(v, g.config.hip_height)))
            })
            .collect();
        let measured = g.bins.iter().map(|b| (f64::from(b.median_speed), f64::from(b.frequency))).collect();
        gait.push(
            LineChart {
                title: format!("Stride frequency against speed: {} (hip height {:.2} m), medians per speed bin", set.character, g.config.hip_height),
                x_label: "speed (m/s)".into(),
                y_label: "Hz".into(),
                series: vec![
                    Series { name: "Alexander's law".into(), color: Color::GRAY, points: law },
                    Series { name: "dataset".into(), color: Color::BLUE, points: measured },
                ],
                log_y: false,
            },
            300,
        );
    }
    if set.n_feet > 0 {
        gait.save(&dir.join("gait.png"))?;
        heights.save(&dir.join("foot_heights.png"))?;
    }
    velocity.save(&dir.join("velocity.png"))?;
    let json = dir.join("metrics.json");
    std::fs::write(&json, serde_json::to_string_pretty(metrics)?).with_context(|| format!("writing {}", json.display()))?;
    Ok(())
}

/// What a chart of window `w` shows: the episode, its speed, and whether it is the episode's start only.
fn window_title(set: &MotionSet, label: &str, w: &Range<usize>) -> String {
    let mean = mean_speed(set, w);
    let whole = set.episodes.iter().find(|e| e.start == w.start).map_or(w.len(), |e| e.len());
    let part = if whole > w.len() { format!(", its first {WINDOW_SECONDS:.0} s of {:.0}", whole as f32 / set.fps) } else { String::new() };
    format!("{} — {label} episode (mean commanded speed {mean:.2} m/s{part})", set.character)
}

/// Mean commanded planar speed over a frame range.
fn mean_speed(set: &MotionSet, w: &Range<usize>) -> f32 {
    let n = w.len().max(1) as f32;
    w.clone().map(|i| set.commands[i][0].hypot(set.commands[i][1])).sum::<f32>() / n
}

/// The slowest and fastest episodes by mean commanded speed, cut to [`WINDOW_SECONDS`], among those
/// of the configured length at least: the last episode, cut short where the frames ran out (17 frames
/// of a snake), was the "slowest".
fn windows(set: &MotionSet) -> Vec<(&'static str, Range<usize>)> {
    let max = (WINDOW_SECONDS * set.fps) as usize;
    let cut = |e: &Range<usize>| e.start..e.end.min(e.start + max);
    let by_speed = |e: &&Range<usize>| mean_speed(set, e);
    let shortest = (set.config.episode_seconds[0] * set.fps).round() as usize;
    let whole: Vec<&Range<usize>> = set.episodes.iter().filter(|e| e.len() >= shortest).collect();
    let candidates = if whole.is_empty() { set.episodes.iter().collect() } else { whole };
    let slow = candidates.iter().copied().min_by(|a, b| by_speed(a).total_cmp(&by_speed(b)));
    let fast = candidates.iter().copied().max_by(|a, b| by_speed(a).total_cmp(&by_speed(b)));
    match (slow, fast) {
        (Some(s), Some(f)) if s != f => vec![("slowest", cut(s)), ("fastest", cut(f))],
        (Some(s), _) => vec![("only", cut(s))],
        _ => Vec::new(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use ace::models::dataset::{DatasetConfig, generate};
    use ace::models::morphology::load_character;

    /// 1,400 frames of 8–24 s episodes end in a remnant of the last one: never the chart's "slowest"
    /// or "fastest" (the snake's "slowest" was 17 frames). A long episode's chart says it is its start.
    #[test]
    fn the_charted_episodes_are_whole_and_a_cut_one_says_so() {
        let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR"));
        let (tree, morph) = load_character(&root.join("assets/characters/spot.urdf")).unwrap();
        let cfg = DatasetConfig { frames: 1400, seed: 4, ..DatasetConfig::default() };
        let set = generate(&tree, &morph, &cfg, &mut |_| {}).unwrap();
        let shortest = (cfg.episode_seconds[0] * cfg.fps) as usize;
        let last = set.episodes.last().unwrap().clone();
        assert!(last.len() < shortest, "seed 4 ends in a remnant: {:?}", set.episodes);
        let w = windows(&set);
        assert_eq!(w.len(), 2);
        for (_, r) in &w {
            assert_ne!(r.start, last.start, "{w:?}");
            let episode = set.episodes.iter().find(|e| e.start == r.start).unwrap();
            assert!(episode.len() >= shortest);
            let title = window_title(&set, "slowest", r);
            let cut = episode.len() > r.len();
            assert_eq!(title.contains(&format!(", its first 12 s of {:.0})", episode.len() as f32 / set.fps)), cut, "{title}");
        }
    }
}
