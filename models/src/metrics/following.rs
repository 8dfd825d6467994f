//! Following: does each character end effector do what its human end effector does?
//!
//! L_fea cannot tell: it averages squared differences over all of Ψ, so an arm that never moves scores
//! well wherever the human's hand moves little. This measure looks at each mapped pair on its own,
//! from the poses alone (no network, no training statistics), over one clip:
//!
//! - **Positions.** Each end effector in its own body's heading frame (x forward, y left, z up; origin
//!   at the root), divided by its own body length: the end-effector block of Ψ
//!   ([`crate::features`]), uncentred. Only displacements over the clip matter below, so any constant
//!   offset between the bodies (their rest poses differ) drops out.
//! - **Correlation per axis**: Pearson's correlation of the character's coordinate with the human's over
//!   the clip's frames. It is left out (`None`) where the human's range on that axis is below
//!   [`FollowingConfig::min_motion`] (there is nothing to follow), and on a clip shorter than one
//!   window ([`FollowingConfig::window_s`]: over two frames it is ±1); a character that stays still
//!   there scores 0. 1 is perfect following, −1 is moving against the human.
//! - **Combined score**: the per-axis correlations averaged with the human's range on each axis as
//!   weights, so the axes the human actually moves along count most.
//! - **Amplitude ratio**: the character's extent (length of the per-axis ranges) over the human's, both in
//!   their own body lengths, i.e. the character's range against the human's range scaled to the
//!   character. Left out when the human's extent is below `min_motion`, and on a clip shorter than a
//!   window. 1 is the same relative size.
//! - **Stillness**: the character's extent (body lengths) within windows of
//!   [`FollowingConfig::window_s`] where the human's end effector stays within
//!   [`FollowingConfig::still_extent_m`] metres, median over those windows (`None` when there is no
//!   such window). 0 is a character that stays still when the human does.
//!
//! - **Standing** (the whole body, not a pair): the character's root travel (its body lengths per
//!   second, horizontal) and turning (degrees per second, about the vertical) within the windows where
//!   the human's root travels at most [`FollowingConfig::still_extent_m`] and turns at most
//!   [`FollowingConfig::still_turn_deg`], median over those windows. The end effectors' stillness is
//!   measured from the root and cannot see a character that walks or drives off while the human stands
//!   and waves; this can. 0 is a character that stands where the human stands.
//!
//! - **Heading** (the whole body): the character's change of heading since the clip's first frame
//!   against the human's (each integrated from its root's angular velocity about the vertical), and the
//!   largest difference over the clip in degrees. The end effectors are measured in each body's own
//!   heading frame and cannot see a character that turns where the human walks straight, or walks on
//!   where the human turns: it leaves the human's path. 0 is a character that turns as the human does.
//!
//! - **Pace** (the whole body): within the windows where the human's root travels at least
//!   [`FollowingConfig::walking_speed`], the character's root travel over the human's at the character
//!   dataset's speed scale (the speed L_fea asks for, [`crate::features::human_speed_factor`]), median
//!   over those windows. The end effectors are measured from the root, and the heading only turns:
//!   neither sees a character that keeps the person's heading at a third of the person's pace and
//!   falls behind. 1 keeps the person's pace; 0.5 walks half as fast.
//!
//! A clip's [`FollowingReport::score`] is the mean combined score of its pairs. Over many clips,
//! [`FollowingSummary`] gives per pair the median vertical correlation and amplitude ratio over the
//! clips where the human's end effector moves at least [`MOVING_VERTICAL_M`] up and down, and the
//! median stillness over the clips with still windows.

use serde::{Deserialize, Serialize};

use super::median;
use crate::features::FeatureLayout;
use crate::human::EndEffector;

/// Thresholds of the following measure.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct FollowingConfig {
    /// The human's least range on an axis (body lengths) for that axis to be scored.
    pub min_motion: f32,
    /// The human's largest extent (m) within a window for it to count as still.
    pub still_extent_m: f32,
    /// The human's largest turning (degrees, summed over a window) for the window to count as
    /// standing.
    pub still_turn_deg: f32,
    /// Length of the stillness windows (s); consecutive windows overlap by half.
    pub window_s: f32,
    /// The human's least mean root speed (m/s) within a window for the window to count towards the
    /// pace.
    pub walking_speed: f32,
    /// Frame rate of the poses (frames per second).
    pub fps: f32,
}

impl FollowingConfig {
    /// The project's thresholds at `fps`: axes where the human moves at least 0.02 body lengths,
    /// still when within 5 cm (and, for the root, turning at most 10°) over 1 s, walking at 0.25 m/s
    /// or more over 1 s (the speed at which the cleanup's standing hold lets the root move freely,
    /// [`crate::standing::StandingHold`]).
    pub fn new(fps: f32) -> Self {
        FollowingConfig {
            min_motion: 0.02,
            still_extent_m: 0.05,
            still_turn_deg: 10.0,
            window_s: 1.0,
            walking_speed: 0.25,
            fps,
        }
    }
}

/// A value per heading axis.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct Axes<T> {
    pub forward: T,
    pub lateral: T,
    pub vertical: T,
}

impl<T: Copy> Axes<T> {
    fn from_array(a: [T; 3]) -> Self {
        Axes {
            forward: a[0],
            lateral: a[1],
            vertical: a[2],
        }
    }
}

/// The following of one mapped pair over one clip (see the module docs).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct PairFollowing {
    /// The character end effector (its link name).
    pub character: String,
    /// The human end effector it follows.
    pub human: EndEffector,
    /// Correlation of the displacements per axis.
    pub correlation: Axes<Option<f32>>,
    /// The range-weighted mean of the per-axis correlations.
    pub combined: Option<f32>,
    /// The human's range per axis (human body lengths).
    pub human_range: Axes<f32>,
    /// The character's range per axis (character body lengths).
    pub character_range: Axes<f32>,
    /// The character's extent over the human's.
    pub amplitude_ratio: Option<f32>,
    /// The character's median extent (body lengths) while the human's end effector stays still.
    pub stillness: Option<f32>,
}

impl PairFollowing {
    /// The human's range on the vertical axis in metres, for a human of `body` metres.
    pub fn human_vertical_range_m(&self, body: f32) -> f32 {
        self.human_range.vertical * body
    }
}

/// The following of every mapped pair over one clip.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct FollowingReport {
    /// One entry per mapped pair, in character end-effector order.
    pub pairs: Vec<PairFollowing>,
    /// Mean combined correlation over the pairs that have one.
    pub score: Option<f32>,
    /// The character's median root travel (its body lengths per second) while the human stands;
    /// `None` when the human never stands for a window.
    #[serde(default)]
    pub standing_travel: Option<f32>,
    /// The character's median turning (degrees per second) while the human stands.
    #[serde(default)]
    pub standing_turn: Option<f32>,
    /// The largest difference (degrees) between the character's and the human's change of heading
    /// since the first frame; `None` for a clip of one frame.
    #[serde(default)]
    pub heading_error: Option<f32>,
    /// The character's median root travel over the human's (at the dataset's speed scale) while the
    /// human walks; `None` when the human never walks for a window.
    #[serde(default)]
    pub pace: Option<f32>,
}

/// The following of a clip from the character's Ψ and the human's Ψ (same [`FeatureLayout`], aligned
/// frame for frame; centring of the human's Ψ does not matter), with `pairs` naming the mapped pairs
/// in Ψ's end-effector order, `human_body` the human's body length (m) and `human_speed` the factor
/// the human's root linear velocity entries were multiplied by
/// ([`crate::features::human_speed_factor`]; 1 when they were not).
///
/// # Panics
/// If the two sequences differ in length, a row is shorter than the layout, `pairs` does not match the
/// layout's end effectors, or `human_body` or `human_speed` is not positive.
pub fn following<R: AsRef<[f32]>, S: AsRef<[f32]>>(
    layout: &FeatureLayout,
    pairs: &[(String, EndEffector)],
    character: &[R],
    human: &[S],
    human_body: f32,
    human_speed: f32,
    config: &FollowingConfig,
) -> FollowingReport {
    assert_eq!(character.len(), human.len(), "character and human features must be aligned");
    assert_eq!(pairs.len(), layout.end_effectors, "one pair per end effector of Ψ");
    assert!(human_body > 0.0, "the human's body length must be positive");
    assert!(human_speed > 0.0, "the human's speed factor must be positive");
    let ee = layout.ee_positions().start;
    let track = |rows: &[Vec<f32>], k: usize, axis: usize| -> Vec<f32> { rows.iter().map(|r| r[3 * k + axis]).collect() };
    let (c_rows, h_rows) = (cut_rows(character, ee, pairs.len()), cut_rows(human, ee, pairs.len()));
    let window = ((config.window_s * config.fps).round() as usize).max(2);
    let still = config.still_extent_m / human_body;
    let out: Vec<PairFollowing> = pairs
        .iter()
        .enumerate()
        .map(|(k, (name, end))| {
            let c: [Vec<f32>; 3] = std::array::from_fn(|a| track(&c_rows, k, a));
            let h: [Vec<f32>; 3] = std::array::from_fn(|a| track(&h_rows, k, a));
            let h_range: [f32; 3] = std::array::from_fn(|a| range(&h[a]));
            let c_range: [f32; 3] = std::array::from_fn(|a| range(&c[a]));
            // Over fewer frames than a window a correlation says little (over two it is ±1).
            let long_enough = c_rows.len() >= window;
            let corr: [Option<f32>; 3] =
                std::array::from_fn(|a| (long_enough && h_range[a] >= config.min_motion).then(|| correlation(&c[a], &h[a])));
            let (mut sum, mut weight) = (0.0, 0.0);
            for a in 0..3 {
                if let Some(r) = corr[a] {
                    sum += h_range[a] * r;
                    weight += h_range[a];
                }
            }
            let h_extent = norm(h_range);
            let mut stills: Vec<f32> = windows(c_rows.len(), window)
                .filter(|w| norm(std::array::from_fn(|a| range(&h[a][w.clone()]))) <= still)
                .map(|w| norm(std::array::from_fn(|a| range(&c[a][w.clone()]))))
                .collect();
            PairFollowing {
                character: name.clone(),
                human: *end,
                correlation: Axes::from_array(corr),
                combined: (weight > 0.0).then(|| sum / weight),
                human_range: Axes::from_array(h_range),
                character_range: Axes::from_array(c_range),
                amplitude_ratio: (long_enough && h_extent >= config.min_motion).then(|| norm(c_range) / h_extent),
                stillness: (!stills.is_empty()).then(|| median(&mut stills)),
            }
        })
        .collect();
    let combined: Vec<f32> = out.iter().filter_map(|p| p.combined).collect();
    // Standing: the windows where the human's root travels at most `still_extent_m` metres (its Ψ
    // velocity taken back from L_fea's speed scale and its body lengths) and turns at most
    // `still_turn_deg`; in them the character's travel (body lengths) and turning, per second. Pace:
    // the windows where it travels at least `walking_speed`; in them the character's travel over the
    // human's, both in the character's body lengths at the speed scale.
    let (mut travels, mut turns, mut paces) = (Vec::new(), Vec::new(), Vec::new());
    for w in windows(character.len(), window) {
        let (travel, degrees) = root_motion(layout, &human[w.clone()], config.fps);
        let (c_travel, c_turn) = root_motion(layout, &character[w.clone()], config.fps);
        let seconds = w.len() as f32 / config.fps;
        let metres = travel / human_speed * human_body;
        if metres <= config.still_extent_m && degrees <= config.still_turn_deg {
            travels.push(c_travel / seconds);
            turns.push(c_turn / seconds);
        } else if metres >= config.walking_speed * seconds {
            paces.push(c_travel / travel);
        }
    }
    let med = |mut v: Vec<f32>| (!v.is_empty()).then(|| median(&mut v));
    FollowingReport {
        score: (!combined.is_empty()).then(|| combined.iter().sum::<f32>() / combined.len() as f32),
        pairs: out,
        standing_travel: med(travels),
        standing_turn: med(turns),
        heading_error: heading_error(layout, character, human, config.fps),
        pace: med(paces),
    }
}

/// The largest difference (degrees) between the two bodies' changes of heading since the first frame
/// ([`turned_degrees`] of their Ψ rows' yaw rates); `None` for fewer than two frames.
fn heading_error<R: AsRef<[f32]>, S: AsRef<[f32]>>(layout: &FeatureLayout, character: &[R], human: &[S], fps: f32) -> Option<f32> {
    let yaw = layout.root_angular_velocity().start + 2;
    let c = turned_degrees(character.iter().map(|r| r.as_ref()[yaw]), fps);
    let h = turned_degrees(human.iter().map(|r| r.as_ref()[yaw]), fps);
    (character.len() >= 2).then(|| c.iter().zip(&h).map(|(c, h)| (c - h).abs()).fold(0.0, f32::max))
}

/// Degrees turned since the first frame, per frame, from per-frame yaw rates (rad/s) at `fps`: the sum
/// of the rates of the frames after the first (a frame's velocities, in x^h and x^r, are those that
/// bring the previous frame to it).
pub fn turned_degrees(yaw_rates: impl IntoIterator<Item = f32>, fps: f32) -> Vec<f32> {
    let mut turned = 0.0f64;
    yaw_rates
        .into_iter()
        .enumerate()
        .map(|(t, w)| {
            if t > 0 {
                turned += f64::from(w) / f64::from(fps);
            }
            turned.to_degrees() as f32
        })
        .collect()
}

/// How far the root of `rows` (Ψ rows at `fps`) travels horizontally (Ψ's velocity units times seconds)
/// and how much it turns about the vertical (degrees, every turn counted).
fn root_motion<R: AsRef<[f32]>>(layout: &FeatureLayout, rows: &[R], fps: f32) -> (f32, f32) {
    let (lin, ang) = (layout.root_linear_velocity().start, layout.root_angular_velocity().start);
    rows.iter().fold((0.0, 0.0), |(travel, turn), r| {
        let r = r.as_ref();
        (travel + r[lin].hypot(r[lin + 1]) / fps, turn + r[ang + 2].abs().to_degrees() / fps)
    })
}

/// The first `n` end-effector triples of each row, from entry `start`.
fn cut_rows<S: AsRef<[f32]>>(rows: &[S], start: usize, n: usize) -> Vec<Vec<f32>> {
    rows.iter().map(|r| r.as_ref()[start..start + 3 * n].to_vec()).collect()
}

/// Windows of `len` frames every `len / 2` frames over `n` frames; none when the clip is shorter than
/// one (a clip of one frame is no second of standing).
fn windows(n: usize, len: usize) -> impl Iterator<Item = std::ops::Range<usize>> {
    let hop = (len / 2).max(1);
    let count = if n < len { 0 } else { (n - len) / hop + 1 };
    (0..count).map(move |i| {
        let start = i * hop;
        start..(start + len).min(n)
    })
}

fn range(v: &[f32]) -> f32 {
    let (lo, hi) = v.iter().fold((f32::INFINITY, f32::NEG_INFINITY), |(lo, hi), &x| (lo.min(x), hi.max(x)));
    if v.is_empty() { 0.0 } else { hi - lo }
}

fn norm(v: [f32; 3]) -> f32 {
    (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt()
}

/// Pearson's correlation of `a` and `b`; 0 when either is constant.
fn correlation(a: &[f32], b: &[f32]) -> f32 {
    let n = a.len() as f64;
    let mean = |v: &[f32]| v.iter().map(|&x| x as f64).sum::<f64>() / n;
    let (ma, mb) = (mean(a), mean(b));
    let (mut sab, mut saa, mut sbb) = (0.0, 0.0, 0.0);
    for (&x, &y) in a.iter().zip(b) {
        let (dx, dy) = (x as f64 - ma, y as f64 - mb);
        sab += dx * dy;
        saa += dx * dx;
        sbb += dy * dy;
    }
    // A range below a micrometre in body lengths is numerical noise of a still end effector.
    if saa <= 1e-12 * n || sbb <= 1e-12 * n {
        return 0.0;
    }
    (sab / (saa * sbb).sqrt()) as f32
}

/// The human's least vertical range (m) for a clip to count towards a pair's
/// [`PairSummary::vertical_correlation`] and [`PairSummary::amplitude_ratio`].
pub const MOVING_VERTICAL_M: f32 = 0.3;

/// One pair's following over many clips.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct PairSummary {
    /// The character end effector.
    pub character: String,
    /// The human end effector it follows.
    pub human: EndEffector,
    /// Clips where the human's end effector moves at least [`MOVING_VERTICAL_M`] vertically.
    pub moving_clips: usize,
    /// Median vertical correlation over those clips.
    pub vertical_correlation: Option<f32>,
    /// Median amplitude ratio over those clips.
    pub amplitude_ratio: Option<f32>,
    /// Median combined correlation over all clips that have one.
    pub combined: Option<f32>,
    /// Clips with at least one still window of the human's end effector.
    pub still_clips: usize,
    /// Median of those clips' stillness (character body lengths).
    pub stillness: Option<f32>,
}

/// The following of a motion made of one or more clips: each clip's report and, per pair, medians over
/// the clips.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct FollowingSummary {
    /// Median of the clips' scores.
    pub score: Option<f32>,
    /// Per pair, in character end-effector order.
    pub pairs: Vec<PairSummary>,
    /// Clips where the human stands for at least one window.
    #[serde(default)]
    pub standing_clips: usize,
    /// Median of those clips' [`FollowingReport::standing_travel`] (character body lengths per second).
    #[serde(default)]
    pub standing_travel: Option<f32>,
    /// Median of those clips' [`FollowingReport::standing_turn`] (degrees per second).
    #[serde(default)]
    pub standing_turn: Option<f32>,
    /// Median of the clips' [`FollowingReport::heading_error`] (degrees).
    #[serde(default)]
    pub heading_error: Option<f32>,
    /// Clips where the human walks for at least one window.
    #[serde(default)]
    pub walking_clips: usize,
    /// Median of those clips' [`FollowingReport::pace`].
    #[serde(default)]
    pub pace: Option<f32>,
    /// Each clip's report, in order, with its human's body length (m).
    pub clips: Vec<(FollowingReport, f32)>,
}

impl FollowingSummary {
    /// Summarises `clips`: each clip's report with its human's body length (m). All reports must come
    /// from the same mapping.
    pub fn new(clips: Vec<(FollowingReport, f32)>) -> Self {
        let med = |mut v: Vec<f32>| (!v.is_empty()).then(|| median(&mut v));
        let n = clips.first().map_or(0, |c| c.0.pairs.len());
        let pairs = (0..n)
            .map(|k| {
                // This pair in every clip, with the clip's human body length.
                let each: Vec<(&PairFollowing, f32)> = clips.iter().map(|c| (&c.0.pairs[k], c.1)).collect();
                let moving: Vec<&PairFollowing> = each
                    .iter()
                    .filter(|(p, body)| p.human_vertical_range_m(*body) >= MOVING_VERTICAL_M)
                    .map(|(p, _)| *p)
                    .collect();
                let still: Vec<f32> = each.iter().filter_map(|(p, _)| p.stillness).collect();
                let first = each[0].0;
                PairSummary {
                    character: first.character.clone(),
                    human: first.human,
                    moving_clips: moving.len(),
                    vertical_correlation: med(moving.iter().filter_map(|p| p.correlation.vertical).collect()),
                    amplitude_ratio: med(moving.iter().filter_map(|p| p.amplitude_ratio).collect()),
                    combined: med(each.iter().filter_map(|(p, _)| p.combined).collect()),
                    still_clips: still.len(),
                    stillness: med(still),
                }
            })
            .collect();
        let standing: Vec<&FollowingReport> = clips.iter().map(|c| &c.0).filter(|r| r.standing_travel.is_some()).collect();
        FollowingSummary {
            score: med(clips.iter().filter_map(|c| c.0.score).collect()),
            pairs,
            standing_clips: standing.len(),
            standing_travel: med(standing.iter().filter_map(|r| r.standing_travel).collect()),
            standing_turn: med(standing.iter().filter_map(|r| r.standing_turn).collect()),
            heading_error: med(clips.iter().filter_map(|c| c.0.heading_error).collect()),
            walking_clips: clips.iter().filter(|c| c.0.pace.is_some()).count(),
            pace: med(clips.iter().filter_map(|c| c.0.pace).collect()),
            clips,
        }
    }
}

impl std::fmt::Display for FollowingSummary {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let opt = |v: Option<f32>| v.map_or("n/a".to_string(), |v| format!("{v:.2}"));
        write!(f, "following {} (median correlation of the end effectors with the human's)", opt(self.score))?;
        let single = self.clips.len() == 1;
        write!(
            f,
            "\n        standing (the human's root still for 1 s): travel {} body lengths/s, turning {}°/s",
            opt(self.standing_travel),
            self.standing_turn.map_or("n/a".to_string(), |v| format!("{v:.1}"))
        )?;
        if !single {
            write!(f, " ({} clips)", self.standing_clips)?;
        }
        write!(
            f,
            "\n        heading: the character's turning differs from the human's by up to {}°{}",
            self.heading_error.map_or("n/a".to_string(), |v| format!("{v:.0}")),
            if single { "" } else { " (median over the clips)" }
        )?;
        write!(
            f,
            "\n        pace (where the human walks): the character travels {} times as far as the human at the speed scale",
            opt(self.pace)
        )?;
        if !single {
            write!(f, " ({} clips)", self.walking_clips)?;
        }
        for (k, p) in self.pairs.iter().enumerate() {
            if single {
                let c = &self.clips[0].0.pairs[k];
                write!(
                    f,
                    "\n        {} ~ {}: vertical {}, forward {}, combined {}, amplitude {}, stillness {}",
                    p.character,
                    p.human.name(),
                    opt(c.correlation.vertical),
                    opt(c.correlation.forward),
                    opt(c.combined),
                    opt(c.amplitude_ratio),
                    opt(c.stillness)
                )?;
            } else {
                write!(
                    f,
                    "\n        {} ~ {}: vertical {} ({} clips moving ≥ {MOVING_VERTICAL_M} m), amplitude {}, combined {}, stillness {} ({} clips)",
                    p.character,
                    p.human.name(),
                    opt(p.vertical_correlation),
                    p.moving_clips,
                    opt(p.amplitude_ratio),
                    opt(p.combined),
                    opt(p.stillness),
                    p.still_clips
                )?;
            }
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn correlation_is_pearsons_r_and_zero_for_a_still_series() {
        let a = [1.0, 2.0, 3.0, 4.0, 5.0];
        let b = [2.0, 1.0, 4.0, 3.0, 6.0];
        // Centred: a − 3 = (−2, −1, 0, 1, 2), b − 3.2 = (−1.2, −2.2, 0.8, −0.2, 2.8); the sums of
        // products are 10 (a·b), 10 (a·a) and 14.8 (b·b).
        let r = 10.0 / (10.0f32 * 14.8).sqrt();
        assert!((correlation(&a, &b) - r).abs() < 1e-6, "{} against {r}", correlation(&a, &b));
        // Unchanged by the series' offsets and scales, negated by a sign.
        let b_scaled: Vec<f32> = b.iter().map(|x| 3.0 * x + 7.0).collect();
        assert!((correlation(&a, &b_scaled) - r).abs() < 1e-6);
        let b_negated: Vec<f32> = b.iter().map(|x| -x).collect();
        assert!((correlation(&a, &b_negated) + r).abs() < 1e-6);
        assert!((correlation(&a, &a) - 1.0).abs() < 1e-6);
        // A still series, or one that moves by less than a micrometre, follows nothing.
        assert_eq!(correlation(&a, &[0.4; 5]), 0.0);
        let jitter: Vec<f32> = (0..100).map(|i| 0.4 + if i % 2 == 0 { 1e-7 } else { -1e-7 }).collect();
        let ramp: Vec<f32> = (0..100).map(|i| i as f32).collect();
        assert_eq!(correlation(&ramp, &jitter), 0.0);
        assert_eq!(correlation(&jitter, &ramp), 0.0);
        // A millimetre is motion.
        let steps: Vec<f32> = (0..100).map(|i| 0.4 + 1e-3 * (i / 50) as f32).collect();
        assert!(correlation(&ramp, &steps) > 0.8);
    }

    #[test]
    fn windows_overlap_by_half_and_a_clip_shorter_than_one_has_none() {
        let all = |n: usize, len: usize| windows(n, len).collect::<Vec<std::ops::Range<usize>>>();
        assert_eq!(all(100, 30), [0..30, 15..45, 30..60, 45..75, 60..90]);
        assert_eq!(all(31, 30), [0..30]);
        assert_eq!(all(30, 30), [0..30]);
        // A clip of one frame was a "second" of standing.
        assert!(all(29, 30).is_empty() && all(1, 30).is_empty());
        assert!(all(0, 30).is_empty());
        assert_eq!(all(3, 2), [0..2, 1..3]);
    }

    #[test]
    fn ranges_and_extents() {
        assert_eq!(range(&[0.5, -1.0, 2.0, 0.0]), 3.0);
        assert_eq!(range(&[]), 0.0);
        assert_eq!(norm([3.0, 4.0, 12.0]), 13.0);
        assert_eq!(norm([-3.0, 0.0, 4.0]), 5.0);
    }

    #[test]
    fn turning_sums_the_rates_after_the_first_frame() {
        // At 2 frames per second, a frame's rate turns the body by half of it; the first frame's rate
        // brought the body to where the clip starts.
        let turned = turned_degrees([9.0, 1.0, 2.0, -0.5], 2.0);
        let expected = [0.0f32, 0.5, 1.5, 1.25].map(f32::to_degrees);
        for (t, e) in turned.iter().zip(expected) {
            assert!((t - e).abs() < 1e-4, "{turned:?} against {expected:?}");
        }
    }
}
