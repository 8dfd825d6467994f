//! Gait quality of any motion of a legged character (a dataset, a retargeted clip, a baseline's
//! output): how long the feet swing, how often they step for the speed beside the law animals follow
//! ([`crate::dynamic_similarity`]), and the two faults UFR cannot see — foot **pops** and
//! **micro-steps**.
//!
//! # Definitions
//! - **Contact**: a dataset's own stance labels; for any other motion, a foot point within the UFR's
//!   contact band above the ground ([`super::UfrConfig::contact_height`], 2.5 % of the body length).
//! - **Swing**: a run of frames of one foot out of contact, with a contact frame right before and right
//!   after it in the same episode (runs cut by an episode's ends are not swings). Its duration is the
//!   run's length in frames; its distance is the horizontal distance between the foot at the last
//!   contact frame before and the first contact frame after.
//! - **Stride**: from one touchdown (first contact frame after a swing) of a foot to its next. Its
//!   frequency is `fps / frames`, its duty factor the fraction of its frames in contact. Its foot's
//!   speed is the distance between the two touchdown points over its duration (so a foot that steps on
//!   the spot has speed ≈ 0, and a turning body is measured at its feet). Its speed is the mean foot
//!   speed of the strides of every foot that are under way at its midpoint (its own among them): the
//!   legs share one clock, so in a turn the inner feet take short strides at the outer feet's cadence,
//!   and the gait's speed is that of all its feet, not of the slowest. On a straight walk both are the
//!   body's speed. The law's frequency is [`stride_frequency`] at the stride's speed and the character's
//!   hip height; the ratio is measured / law.
//! - **Pop**: a swing of at most [`GaitConfig::POP_FRAMES`] frames, or shorter than
//!   [`GaitConfig::POP_FRACTION`] of the reference median swing (the character dataset's) when given.
//! - **Micro-step**: a swing that moves the foot less than [`GaitConfig::MICRO_STEP`] body lengths.
//! - **Short walking swing**: a swing shorter than [`GaitConfig::WALKING_MIN_SWING`] frames ending a
//!   stride at a Froude number below [`WALKING_FROUDE`].
//!
//! Strides are summarised per speed bin ([`GaitConfig::SPEED_BINS`], m/s) with medians.

use std::fmt;
use std::ops::Range;

use serde::{Deserialize, Serialize};

use super::{UfrConfig, median};
use crate::dynamic_similarity::{WALKING_FROUDE, froude, hip_height, stride_frequency};
use crate::features::character_body_length;
use crate::kinematics::{CharacterPose, KinematicTree};
use crate::morphology::Morphology;

/// What the gait measure needs to know about the character and the motion.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct GaitConfig {
    /// Frames per second.
    pub fps: f32,
    /// Hip height (m) for the law ([`crate::dynamic_similarity::hip_height`]).
    pub hip_height: f32,
    /// Body length (m) for micro-steps ([`crate::features::character_body_length`]).
    pub body_length: f32,
    /// The reference median swing (frames), e.g. the character dataset's, for relative pops.
    pub reference_swing: Option<f32>,
}

impl GaitConfig {
    /// Swings this short (frames) or shorter are pops.
    pub const POP_FRAMES: usize = 2;
    /// Swings shorter than this fraction of the reference median swing are pops.
    pub const POP_FRACTION: f32 = 0.25;
    /// Swings moving the foot less than this many body lengths are micro-steps.
    pub const MICRO_STEP: f32 = 0.1;
    /// Shortest swing (frames) at walking speeds.
    pub const WALKING_MIN_SWING: usize = 4;
    /// Edges of the speed bins (m/s); strides slower than the first edge are left out of the bins.
    pub const SPEED_BINS: [f32; 10] = [0.1, 0.2, 0.35, 0.5, 0.75, 1.0, 1.5, 2.0, 3.0, 5.0];

    /// The configuration for a character at `fps` ([`hip_height`], [`character_body_length`]); `None`
    /// without feet.
    pub fn for_character(
        tree: &KinematicTree,
        morph: &Morphology,
        fps: f32,
        reference_swing: Option<f32>,
    ) -> Option<Self> {
        Some(GaitConfig {
            fps,
            hip_height: hip_height(tree, morph)?,
            body_length: character_body_length(tree, morph),
            reference_swing,
        })
    }
}

/// The gait measure of `poses` (holding `episodes` back to back) with contacts from the UFR's contact
/// band; `None` for a character without feet.
pub fn gait_of_poses(
    tree: &KinematicTree,
    morph: &Morphology,
    poses: &[CharacterPose],
    episodes: &[Range<usize>],
    fps: f32,
    reference_swing: Option<f32>,
) -> Option<GaitReport> {
    let config = GaitConfig::for_character(tree, morph, fps, reference_swing)?;
    let band = UfrConfig::from_body_length(config.body_length).contact_height;
    Some(gait_quality(
        &FootTracks::from_poses(tree, morph, poses, band),
        episodes,
        &config,
    ))
}

/// The gait measure of a dataset's poses with its own stance labels (`labels[frame · feet + foot]`);
/// `None` for a character without feet.
///
/// # Panics
/// If `labels` does not hold one label per foot and frame.
pub fn gait_of_labelled_poses(
    tree: &KinematicTree,
    morph: &Morphology,
    poses: &[CharacterPose],
    labels: &[u8],
    episodes: &[Range<usize>],
    fps: f32,
) -> Option<GaitReport> {
    let config = GaitConfig::for_character(tree, morph, fps, None)?;
    Some(gait_quality(
        &FootTracks::from_labels(tree, morph, poses, labels),
        episodes,
        &config,
    ))
}

/// Contact flags and horizontal positions of each foot, frame by frame (row-major: frame, foot).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct FootTracks {
    /// Feet per frame.
    pub feet: usize,
    /// Whether each foot is in contact.
    pub contact: Vec<bool>,
    /// Each foot point's world (x, y) (m).
    pub xy: Vec<[f32; 2]>,
}

impl FootTracks {
    /// Foot points of `poses` ([`Morphology::ee_point`] of [`Morphology::feet`]), in contact within
    /// `contact_height` above the ground at z = 0.
    pub fn from_poses(tree: &KinematicTree, morph: &Morphology, poses: &[CharacterPose], contact_height: f32) -> Self {
        Self::build(tree, morph, poses, |_, _, z| z < contact_height)
    }

    /// Foot points of `poses` with contact labels (`labels[frame · feet + foot]`, non-zero = stance), as
    /// a dataset stores them.
    ///
    /// # Panics
    /// If `labels` does not hold one label per foot and frame.
    pub fn from_labels(tree: &KinematicTree, morph: &Morphology, poses: &[CharacterPose], labels: &[u8]) -> Self {
        let f = morph.feet.len();
        assert_eq!(labels.len(), poses.len() * f, "one contact label per foot and frame");
        Self::build(tree, morph, poses, |t, k, _| labels[t * f + k] != 0)
    }

    fn build(
        tree: &KinematicTree,
        morph: &Morphology,
        poses: &[CharacterPose],
        contact: impl Fn(usize, usize, f32) -> bool,
    ) -> Self {
        let feet = morph.feet.len();
        let mut out = FootTracks {
            feet,
            contact: Vec::with_capacity(poses.len() * feet),
            xy: Vec::with_capacity(poses.len() * feet),
        };
        let mut links = Vec::new();
        for (t, pose) in poses.iter().enumerate() {
            tree.forward_kinematics_into(pose, &mut links);
            for (k, &foot) in morph.feet.iter().enumerate() {
                let p = morph.ee_point(foot, &links);
                out.contact.push(contact(t, k, p.z));
                out.xy.push([p.x, p.y]);
            }
        }
        out
    }

    /// Frames.
    pub fn frames(&self) -> usize {
        self.contact.len().checked_div(self.feet).unwrap_or(0)
    }

    fn at(&self, t: usize, k: usize) -> (bool, [f32; 2]) {
        (self.contact[t * self.feet + k], self.xy[t * self.feet + k])
    }
}

/// One swing (module docs).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Swing {
    /// Foot index.
    pub foot: usize,
    /// First frame in the air.
    pub start: usize,
    /// Frames in the air.
    pub frames: usize,
    /// Horizontal distance from lift-off to touchdown (m).
    pub distance: f32,
    /// Speed of the stride this swing ends (m/s), when the foot touched down before it.
    pub stride_speed: Option<f32>,
}

/// One stride (module docs).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Stride {
    /// Foot index.
    pub foot: usize,
    /// Touchdown frame it starts at.
    pub start: usize,
    /// Frames to the next touchdown.
    pub frames: usize,
    /// Fraction of them in contact.
    pub duty: f32,
    /// Mean foot speed of the strides of every foot under way at its midpoint (m/s; module docs).
    pub speed: f32,
    /// Distance between its own two touchdowns over the duration (m/s).
    pub foot_speed: f32,
    /// `fps / frames` (Hz).
    pub frequency: f32,
    /// The law's frequency at `speed` (Hz).
    pub law: f32,
    /// Frames of the swing that ends it.
    pub swing_frames: usize,
}

/// Strides of one speed bin, by their medians.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct SpeedBin {
    /// Speed range (m/s).
    pub speed: [f32; 2],
    /// Strides in it.
    pub strides: usize,
    /// Median stride speed (m/s).
    pub median_speed: f32,
    /// Median stride frequency (Hz).
    pub frequency: f32,
    /// The law's frequency at the median speed (Hz).
    pub law: f32,
    /// Median of the strides' measured / law ratios.
    pub ratio: f32,
    /// Median swing (frames).
    pub swing_frames: f32,
    /// Median duty factor.
    pub duty: f32,
}

/// The gait measure of a motion without per-swing detail (what reports print).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct GaitSummary {
    /// Swings.
    pub swings: usize,
    /// Strides.
    pub strides: usize,
    /// Median swing (frames; 0 without swings).
    pub median_swing_frames: f32,
    /// Swings of 1–2 frames.
    pub one_or_two_frame_swings: usize,
    /// Pops (module docs).
    pub pops: usize,
    /// Micro-steps.
    pub micro_steps: usize,
    /// Swings shorter than [`GaitConfig::WALKING_MIN_SWING`] at walking Froude numbers.
    pub short_walking_swings: usize,
    /// Median duty factor of the strides (0 without strides).
    pub median_duty: f32,
    /// Median measured / law frequency ratio of strides at [`GaitConfig::SPEED_BINS`] speeds.
    pub median_ratio: Option<f32>,
    /// Per speed bin with strides.
    pub bins: Vec<SpeedBin>,
    /// The configuration used.
    pub config: GaitConfig,
}

impl GaitSummary {
    /// Fraction of swings that pop (0 without swings).
    pub fn pop_rate(&self) -> f32 {
        rate(self.pops, self.swings)
    }

    /// Fraction of swings of 1–2 frames.
    pub fn one_or_two_frame_rate(&self) -> f32 {
        rate(self.one_or_two_frame_swings, self.swings)
    }

    /// Fraction of swings that are micro-steps.
    pub fn micro_step_rate(&self) -> f32 {
        rate(self.micro_steps, self.swings)
    }
}

fn rate(k: usize, n: usize) -> f32 {
    if n == 0 { 0.0 } else { k as f32 / n as f32 }
}

/// The gait measure with every swing and stride.
#[derive(Clone, Debug, PartialEq)]
pub struct GaitReport {
    /// Swings in order of foot, then time.
    pub swings: Vec<Swing>,
    /// Strides in order of foot, then time.
    pub strides: Vec<Stride>,
    /// Per frame, whether a popping swing is in the air (for a timeline).
    pub pop_frames: Vec<bool>,
    /// The summary.
    pub summary: GaitSummary,
}


/// The gait measure of `tracks` cut into `episodes` (ranges of continuous frames).
///
/// # Panics
/// If an episode reaches past the tracks' frames.
pub fn gait_quality(tracks: &FootTracks, episodes: &[Range<usize>], config: &GaitConfig) -> GaitReport {
    let n = tracks.frames();
    let fps = config.fps;
    let mut swings = Vec::new();
    let mut strides = Vec::new();
    // The stride each swing ends, if any.
    let mut swing_stride: Vec<Option<usize>> = Vec::new();
    for e in episodes {
        assert!(e.end <= n, "episode {e:?} reaches past the {n} frames");
        for k in 0..tracks.feet {
            // Last contact frame and the touchdown (frame, point) that started the current stride.
            let mut last_contact: Option<usize> = None;
            let mut touchdown: Option<(usize, [f32; 2])> = None;
            let mut stance = 0usize;
            for t in e.clone() {
                let (c, p) = tracks.at(t, k);
                if !c {
                    continue;
                }
                if let Some(l) = last_contact.filter(|&l| l + 1 < t) {
                    // A swing from l + 1 to t − 1: t is a touchdown.
                    let from = tracks.at(l, k).1;
                    let frames = t - l - 1;
                    let mut stride = None;
                    if let Some((t0, p0)) = touchdown {
                        let len = t - t0;
                        let speed = (p[0] - p0[0]).hypot(p[1] - p0[1]) * fps / len as f32;
                        stride = Some(strides.len());
                        strides.push(Stride {
                            foot: k,
                            start: t0,
                            frames: len,
                            duty: stance as f32 / len as f32,
                            speed,
                            foot_speed: speed,
                            frequency: fps / len as f32,
                            law: 0.0,
                            swing_frames: frames,
                        });
                    }
                    swing_stride.push(stride);
                    swings.push(Swing {
                        foot: k,
                        start: l + 1,
                        frames,
                        distance: (p[0] - from[0]).hypot(p[1] - from[1]),
                        stride_speed: None,
                    });
                    touchdown = Some((t, p));
                    stance = 0;
                }
                stance += 1;
                last_contact = Some(t);
            }
        }
    }
    gait_speeds(&mut strides, tracks.feet);
    for st in &mut strides {
        st.law = stride_frequency(st.speed, config.hip_height);
    }
    for (sw, k) in swings.iter_mut().zip(&swing_stride) {
        sw.stride_speed = k.map(|k| strides[k].speed);
    }
    let pop_limit = config.reference_swing.map_or(0.0, |m| GaitConfig::POP_FRACTION * m);
    let is_pop = |s: &Swing| s.frames <= GaitConfig::POP_FRAMES || (s.frames as f32) < pop_limit;
    let mut pop_frames = vec![false; n];
    for s in swings.iter().filter(|s| is_pop(s)) {
        pop_frames[s.start..s.start + s.frames]
            .iter_mut()
            .for_each(|f| *f = true);
    }
    let summary = GaitSummary {
        swings: swings.len(),
        strides: strides.len(),
        median_swing_frames: median(&mut swings.iter().map(|s| s.frames as f32).collect::<Vec<_>>()),
        one_or_two_frame_swings: swings.iter().filter(|s| s.frames <= 2).count(),
        pops: swings.iter().filter(|s| is_pop(s)).count(),
        micro_steps: swings
            .iter()
            .filter(|s| s.distance < GaitConfig::MICRO_STEP * config.body_length)
            .count(),
        short_walking_swings: swings
            .iter()
            .filter(|s| {
                s.frames < GaitConfig::WALKING_MIN_SWING
                    && s.stride_speed
                        .is_some_and(|v| froude(v, config.hip_height) < WALKING_FROUDE)
            })
            .count(),
        median_duty: median(&mut strides.iter().map(|s| s.duty).collect::<Vec<_>>()),
        median_ratio: {
            let edges = GaitConfig::SPEED_BINS;
            let mut r: Vec<f32> = strides
                .iter()
                .filter(|s| s.speed >= edges[0] && s.speed < edges[edges.len() - 1])
                .map(|s| s.frequency / s.law)
                .collect();
            (!r.is_empty()).then(|| median(&mut r))
        },
        bins: bins(&strides, config.hip_height),
        config: *config,
    };
    GaitReport {
        swings,
        strides,
        pop_frames,
        summary,
    }
}

/// Sets each stride's speed to the mean foot speed of the strides of every foot under way at its
/// midpoint (module docs); `strides` holds each foot's strides in time order within each episode.
fn gait_speeds(strides: &mut [Stride], feet: usize) {
    // Per foot, its strides' (start, end, foot speed) in time order.
    let mut by_foot: Vec<Vec<(usize, usize, f32)>> = vec![Vec::new(); feet];
    for s in strides.iter() {
        by_foot[s.foot].push((s.start, s.start + s.frames, s.foot_speed));
    }
    by_foot.iter_mut().for_each(|v| v.sort_by_key(|&(a, _, _)| a));
    for s in strides.iter_mut() {
        let mid = s.start + s.frames / 2;
        let (mut sum, mut count) = (0.0f32, 0usize);
        for v in &by_foot {
            let i = v.partition_point(|&(a, _, _)| a <= mid);
            if let Some(&(_, end, speed)) = i.checked_sub(1).map(|i| &v[i]) {
                if mid < end {
                    sum += speed;
                    count += 1;
                }
            }
        }
        // Its own stride is always under way at its midpoint.
        s.speed = sum / count.max(1) as f32;
    }
}

fn bins(strides: &[Stride], hip_height: f32) -> Vec<SpeedBin> {
    GaitConfig::SPEED_BINS
        .windows(2)
        .filter_map(|w| {
            let inside: Vec<&Stride> = strides.iter().filter(|s| s.speed >= w[0] && s.speed < w[1]).collect();
            if inside.is_empty() {
                return None;
            }
            let med = |f: &dyn Fn(&Stride) -> f32| median(&mut inside.iter().map(|s| f(s)).collect::<Vec<_>>());
            let median_speed = med(&|s| s.speed);
            Some(SpeedBin {
                speed: [w[0], w[1]],
                strides: inside.len(),
                median_speed,
                frequency: med(&|s| s.frequency),
                law: stride_frequency(median_speed, hip_height),
                ratio: med(&|s| s.frequency / s.law),
                swing_frames: med(&|s| s.swing_frames as f32),
                duty: med(&|s| s.duty),
            })
        })
        .collect()
}

impl fmt::Display for GaitSummary {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "gait    {} swings (median {:.1} frames), {} strides (median duty {:.2}); pops {} ({} of 1–2 frames), micro-steps {}, short walking swings {}",
            self.swings,
            self.median_swing_frames,
            self.strides,
            self.median_duty,
            super::percent(self.pop_rate()),
            super::percent(self.one_or_two_frame_rate()),
            super::percent(self.micro_step_rate()),
            self.short_walking_swings
        )?;
        if let Some(r) = self.median_ratio {
            write!(f, "\n        stride frequency / Alexander's law: median {r:.2}×")?;
        }
        for b in &self.bins {
            write!(
                f,
                "\n        {:.2}–{:.2} m/s: {:>5} strides, {:.2} Hz vs law {:.2} Hz ({:.2}×), swing {:.1} frames, duty {:.2}",
                b.speed[0], b.speed[1], b.strides, b.frequency, b.law, b.ratio, b.swing_frames, b.duty
            )?;
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// One foot moving along x: `pattern` is its contact per frame ('.' contact, '^' air); the foot
    /// advances `step` metres during each swing.
    fn track(pattern: &str, step: f32) -> FootTracks {
        let mut x = 0.0;
        let mut out = FootTracks {
            feet: 1,
            ..FootTracks::default()
        };
        for c in pattern.chars() {
            let contact = c == '.';
            if !contact {
                x += step;
            }
            out.contact.push(contact);
            out.xy.push([x, 0.0]);
        }
        out
    }

    /// Two feet's single-foot tracks of equal length as one two-foot track.
    fn two_feet(a: &FootTracks, b: &FootTracks) -> FootTracks {
        let mut tr = FootTracks { feet: 2, ..FootTracks::default() };
        for t in 0..a.frames() {
            tr.contact.extend([a.contact[t], b.contact[t]]);
            tr.xy.extend([a.xy[t], b.xy[t]]);
        }
        tr
    }

    fn config(reference_swing: Option<f32>) -> GaitConfig {
        GaitConfig {
            fps: 30.0,
            hip_height: 0.5,
            body_length: 1.0,
            reference_swing,
        }
    }

    #[test]
    fn swings_strides_and_duty_are_counted_between_contacts() {
        // Two strides of 10 frames (6 stance, 4 swing); runs cut by the clip's ends are not swings.
        let p = "^^......^^^^......^^^^......^^";
        let tr = track(p, 0.05);
        let r = gait_quality(&tr, &[0..p.len()], &config(None));
        assert_eq!(r.swings.len(), 2);
        assert_eq!((r.swings[0].start, r.swings[0].frames), (8, 4));
        assert!((r.swings[0].distance - 0.2).abs() < 1e-6);
        assert_eq!(r.swings[0].stride_speed, None);
        assert_eq!(r.strides.len(), 1);
        let s = r.strides[0];
        assert_eq!((s.start, s.frames, s.swing_frames), (12, 10, 4));
        assert!((s.duty - 0.6).abs() < 1e-6 && (s.frequency - 3.0).abs() < 1e-5);
        // 0.2 m in 10 frames = 0.6 m/s.
        assert!((s.speed - 0.6).abs() < 1e-5);
        assert!((s.law - stride_frequency(0.6, 0.5)).abs() < 1e-6);
        let sum = &r.summary;
        assert_eq!((sum.pops, sum.micro_steps, sum.short_walking_swings), (0, 0, 0));
        assert_eq!(sum.median_swing_frames, 4.0);
        assert_eq!(sum.bins.len(), 1);
        assert_eq!(sum.bins[0].speed, [0.5, 0.75]);
        assert!((sum.bins[0].ratio - 3.0 / stride_frequency(0.6, 0.5)).abs() < 1e-5);
        assert_eq!(sum.median_ratio, Some(sum.bins[0].ratio));
    }

    #[test]
    fn a_strides_speed_is_that_of_every_foot_under_way() {
        // Two feet on one clock, as in a turn: the outer one strides 0.2 m per 10 frames (0.6 m/s),
        // the inner one 0.05 m (0.15 m/s). Both strides are measured at the gait's 0.375 m/s.
        let p = "^^......^^^^......^^^^......^^";
        let tr = two_feet(&track(p, 0.05), &track(p, 0.0125));
        let r = gait_quality(&tr, &[0..p.len()], &config(None));
        assert_eq!(r.strides.len(), 2);
        let mut own: Vec<f32> = r.strides.iter().map(|s| s.foot_speed).collect();
        own.sort_by(f32::total_cmp);
        assert!((own[0] - 0.15).abs() < 1e-5 && (own[1] - 0.6).abs() < 1e-5, "{own:?}");
        for s in &r.strides {
            assert!((s.speed - 0.375).abs() < 1e-5, "{}", s.speed);
            assert!((s.law - stride_frequency(0.375, 0.5)).abs() < 1e-6);
        }
        assert!(r.swings.iter().filter_map(|s| s.stride_speed).all(|v| (v - 0.375).abs() < 1e-5));
    }

    #[test]
    fn a_stride_that_has_ended_does_not_set_anothers_speed() {
        // Foot A strides from frame 8 to 18 (0.2 m: 0.6 m/s, midpoint 13); foot B from 4 to 10 (0.04 m:
        // 0.2 m/s), over before A's midpoint and begun before any of A's.
        let a = track("....^^^^......^^^^......", 0.05);
        // Each foot's stride speed, with B stepping as `b`.
        let speeds = |b: &str| {
            let r = gait_quality(&two_feet(&a, &track(b, 0.01)), &[0..24], &config(None));
            assert_eq!(r.strides.len(), 2);
            let speed = |foot: usize| r.strides.iter().find(|s| s.foot == foot).unwrap().speed;
            (speed(0), speed(1))
        };
        let (sa, sb) = speeds("..^^..^^^^..............");
        assert!((sa - 0.6).abs() < 1e-5 && (sb - 0.2).abs() < 1e-5, "{sa} {sb}");
        // B's stride now ends at A's midpoint (frame 13): no longer under way there. A's stride is under
        // way at B's midpoint (frame 8), where it begins: B's speed is the mean of the two.
        let (sa, sb) = speeds("..^^..^^^^^^^...........");
        let own_b = 0.07 * 30.0 / 9.0;
        assert!((sa - 0.6).abs() < 1e-5, "{sa}");
        assert!((sb - (0.6 + own_b) / 2.0).abs() < 1e-5, "{sb}");
    }

    #[test]
    fn the_median_ratio_leaves_out_strides_outside_the_speed_bins() {
        // 10 frames per second: a stride of 10 frames covering 5 m is at 5 m/s, the bins' upper edge
        // (not in them); one covering 0.04 m is at 0.04 m/s, below their lower edge.
        let p = "....^^^^......^^^^....";
        let c = GaitConfig { fps: 10.0, ..config(None) };
        for step in [1.25, 0.01] {
            let r = gait_quality(&track(p, step), &[0..p.len()], &c);
            assert_eq!(r.summary.strides, 1);
            assert_eq!((r.summary.median_ratio, r.summary.bins.len()), (None, 0), "{}", r.strides[0].speed);
        }
        let r = gait_quality(&track(p, 0.25), &[0..p.len()], &c);
        assert!(r.summary.median_ratio.is_some() && r.summary.bins.len() == 1);
        // The report prints the counts, the ratio and the bin.
        let text = r.summary.to_string();
        let ratio = format!("median {:.2}×", r.summary.median_ratio.unwrap());
        for want in ["2 swings", "1 strides (median duty 0.60)", &ratio, "1.00–1.50 m/s:     1 strides"] {
            assert!(text.contains(want), "{want:?} not in {text}");
        }
    }

    #[test]
    fn pops_micro_steps_and_short_walking_swings() {
        // Swings of 1, 2, 3 and 8 frames, each moving the foot 0.02 m a frame.
        let p = "....^....^^....^^^....^^^^^^^^....";
        let tr = track(p, 0.02);
        let r = gait_quality(&tr, &[0..p.len()], &config(None));
        let frames: Vec<usize> = r.swings.iter().map(|s| s.frames).collect();
        assert_eq!(frames, [1, 2, 3, 8]);
        let s = &r.summary;
        assert_eq!(s.one_or_two_frame_swings, 2);
        assert_eq!(s.pops, 2);
        assert_eq!(r.pop_frames.iter().filter(|&&f| f).count(), 3);
        assert!(r.pop_frames[4] && r.pop_frames[9] && r.pop_frames[10] && !r.pop_frames[15]);
        // 0.02, 0.04 and 0.06 m are under 0.1 body lengths; 0.16 m is not.
        assert_eq!(s.micro_steps, 3);
        assert!((s.one_or_two_frame_rate() - 0.5).abs() < 1e-6 && (s.micro_step_rate() - 0.75).abs() < 1e-6);
        // Strides end with the 2-, 3- and 8-frame swings; all slow (≤ 0.16 m per 12 frames = 0.4 m/s,
        // Fr 0.03): the 2- and 3-frame ones are short walking swings.
        assert_eq!(s.strides, 3);
        assert_eq!(s.short_walking_swings, 2);
        // Relative to a reference median swing of 16 frames, the 3-frame swing pops too (3 < 4).
        let r = gait_quality(&tr, &[0..p.len()], &config(Some(16.0)));
        assert_eq!(r.summary.pops, 3);
        assert!((r.summary.pop_rate() - 0.75).abs() < 1e-6);
        // Exactly a quarter of a 12-frame median is not shorter than it: the 3-frame swing stands.
        assert_eq!(gait_quality(&tr, &[0..p.len()], &config(Some(12.0))).summary.pops, 2);
    }

    #[test]
    fn a_swing_is_as_long_as_the_foot_moves_in_any_direction() {
        // A foot 0.5 m to the side stepping sideways, 0.05 m a frame for 4 frames.
        let mut tr = track("....^^^^....", 0.05);
        tr.xy.iter_mut().for_each(|p| *p = [0.0, 0.5 + p[0]]);
        let r = gait_quality(&tr, &[0..12], &config(None));
        assert_eq!(r.swings.len(), 1);
        assert!((r.swings[0].distance - 0.2).abs() < 1e-6, "{}", r.swings[0].distance);
    }

    #[test]
    fn micro_steps_are_shorter_than_a_tenth_of_the_body_length() {
        // Swings of 0.25, 0.5 and 0.75 m.
        let tr = track("....^....^^....^^^....", 0.25);
        let micro = |body_length: f32| {
            let c = GaitConfig { body_length, ..config(None) };
            gait_quality(&tr, &[0..22], &c).summary.micro_steps
        };
        // A 5 m body: only the 0.25 m swing is under 0.5 m. A 2.5 m body: none is under 0.25 m.
        assert_eq!((micro(5.0), micro(2.5)), (1, 0));
    }

    #[test]
    fn episodes_cut_swings_and_strides() {
        let p = "....^^^^....^^^^....";
        let tr = track(p, 0.05);
        assert_eq!(gait_quality(&tr, &[0..p.len()], &config(None)).summary.strides, 1);
        // Cut inside the second swing: one swing left, no stride.
        let r = gait_quality(&tr, &[0..14, 14..p.len()], &config(None));
        assert_eq!((r.summary.swings, r.summary.strides), (1, 0));
    }
}
