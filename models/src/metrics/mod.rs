//! Motion-quality metrics (paper §7.3), usable on any character motion — a dataset, a retargeted clip,
//! a baseline's output:
//! - [`mod@ufr`]: the unrealistic frame ratio with per-frame flags of its three detectors (self-collision,
//!   ground penetration, foot sliding), built on the narrow phase of [`collision`];
//! - [`distribution`]: DIV (diversity of Ψ over random pairs of frames) and FID (Fréchet distance
//!   between Gaussian fits of two Ψ sets);
//! - [`mod@gait`]: swing durations, stride frequency beside the law of dynamic similarity, duty factor,
//!   foot pops and micro-steps of legged characters;
//! - [`mod@following`]: whether each character end effector follows its human end effector
//!   (correlation, amplitude ratio, stillness), which L_fea's average cannot see;
//! - [`mod@joint_limits`]: whether the joints keep within their velocity and position limits, as a
//!   robot that executes the motion must;
//! - L_fea is [`crate::features::mean_feature_loss`];
//! - [`MetricsReport`] gathers them for `ace metrics` (`--json` through serde).
//!
//! A typical evaluation of a retargeted motion (states x^r, one episode):
//! ```no_run
//! # use ace_models::{character_state::CharacterLayout, features::*, metrics::*};
//! # fn f(tree: &ace_models::kinematics::KinematicTree, morph: &ace_models::morphology::Morphology,
//! #       states: &[Vec<f32>], dataset_fit: &GaussianFit, human_psi: &[Vec<f32>]) {
//! let layout = CharacterLayout::new(tree, morph);
//! let mapping = EndEffectorMapping::by_side(tree, morph);
//! let body = character_body_length(tree, morph);
//! let psi: Vec<Vec<f32>> = states.iter().map(|x| character_features(&layout, x, body, &mapping)).collect();
//! let poses = poses_from_states(&layout, states);
//! let ufr = ufr(tree, morph, &poses, 30.0, &UfrConfig::for_character(tree, morph));
//! let report = MetricsReport::compute(&MetricsInput {
//!     features: &psi,
//!     reference: Some(dataset_fit),
//!     source_features: Some(human_psi),
//!     layout: FeatureLayout::new(&mapping),
//!     weights: FeatureWeights::default(),
//!     div: DivConfig::default(),
//! }, &ufr);
//! println!("{report}");
//! # }
//! ```

pub mod collision;
pub mod distribution;
pub mod following;
pub mod gait;
pub mod joint_limits;
pub mod ufr;

use std::fmt;
use std::ops::Range;

use nalgebra::{Isometry3, Translation3};
use serde::{Deserialize, Serialize};

/// A fraction of frames (or swings) as a percentage with one decimal, where a share that rounds to
/// 0.0 % but is not zero reads "< 0.1 %" (a warning of "0.0 % of the frames" was one real frame).
pub fn percent(fraction: f32) -> String {
    let shown = format!("{:.1} %", 100.0 * fraction);
    if fraction > 0.0 && shown == "0.0 %" { "< 0.1 %".into() } else { shown }
}

pub use distribution::{DivConfig, GaussianFit, diversity, fid, frechet_distance};
pub use following::{FollowingConfig, FollowingReport, FollowingSummary, PairFollowing, PairSummary, following, turned_degrees};
pub use gait::{FootTracks, GaitConfig, GaitReport, GaitSummary, gait_of_labelled_poses, gait_of_poses, gait_quality};
pub use joint_limits::{JointLimitUse, JointLimitsReport, joint_limits};
pub use ufr::{
    PairCount, PoseChecks, PoseScratch, UfrConfig, UfrDetector, UfrRates, UfrReport, UfrSummary, ufr, ufr_episodes,
};

use crate::character_state::{CharacterLayout, decode_pose, read_quat};
use crate::features::{FeatureLayout, FeatureWeights, mean_feature_loss};
use crate::kinematics::CharacterPose;

/// What [`MetricsReport::compute`] needs besides the UFR.
#[derive(Clone, Debug)]
pub struct MetricsInput<'a, R: AsRef<[f32]> = Vec<f32>> {
    /// Ψ of every frame of the evaluated motion.
    pub features: &'a [R],
    /// The Gaussian fit of the character dataset's Ψ, for FID (`None`: no FID).
    pub reference: Option<&'a GaussianFit>,
    /// Ψ of the human frames the motion was retargeted from, aligned frame for frame, for L_fea
    /// (`None`: no L_fea, e.g. for a dataset).
    pub source_features: Option<&'a [R]>,
    /// Layout of Ψ.
    pub layout: FeatureLayout,
    /// Weights of L_fea.
    pub weights: FeatureWeights,
    /// DIV sampling.
    pub div: DivConfig,
}

/// The metrics of one motion, as `ace metrics` prints them.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct MetricsReport {
    /// Frames evaluated.
    pub frames: usize,
    /// DIV (closer to the dataset's is better).
    pub div: f32,
    /// FID against the reference set (lower is better).
    pub fid: Option<f32>,
    /// Mean L_fea against the source human (lower is better).
    pub feature_loss: Option<f32>,
    /// UFR and its detectors (lower is better).
    pub ufr: UfrSummary,
    /// The gait measure of a legged character ([`mod@gait`]; `None` without feet or when not measured).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub gait: Option<GaitSummary>,
    /// How the end effectors follow the human's ([`mod@following`]; `None` without a source human).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub following: Option<FollowingSummary>,
    /// How the joints keep to their velocity and position limits ([`mod@joint_limits`]; `None` for a
    /// character without limits or when not measured).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub joint_limits: Option<JointLimitsReport>,
}

impl MetricsReport {
    /// Computes DIV, FID (when a reference is given) and L_fea (when source features are given) and
    /// takes the UFR summary from `ufr`.
    ///
    /// # Panics
    /// If the source features are not aligned with the features, or widths disagree.
    pub fn compute<R: AsRef<[f32]>>(input: &MetricsInput<'_, R>, ufr: &UfrReport) -> Self {
        let features = input.features;
        MetricsReport {
            frames: features.len(),
            div: diversity(features, &input.div),
            fid: input
                .reference
                .filter(|_| !features.is_empty())
                .map(|r| frechet_distance(&GaussianFit::fit(features), r) as f32),
            feature_loss: input
                .source_features
                .map(|s| mean_feature_loss(&input.layout, features, s, &input.weights)),
            ufr: ufr.summary(),
            gait: None,
            following: None,
            joint_limits: None,
        }
    }
}

impl fmt::Display for MetricsReport {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let opt = |v: Option<f32>| v.map_or("n/a".to_string(), |v| format!("{v:.3}"));
        let r = &self.ufr.rates;
        writeln!(f, "frames  {}", self.frames)?;
        writeln!(f, "DIV     {:.3}", self.div)?;
        writeln!(f, "FID     {}", opt(self.fid))?;
        writeln!(f, "L_fea   {}", opt(self.feature_loss))?;
        write!(
            f,
            "UFR     {:.3} % (self-collision {:.3} %, penetration {:.3} %, sliding {:.3} %)",
            100.0 * r.ufr,
            100.0 * r.self_collision,
            100.0 * r.penetration,
            100.0 * r.sliding
        )?;
        for p in &self.ufr.collision_pairs {
            write!(f, "\n        {} × {}: {} frames", p.a, p.b, p.frames)?;
        }
        if let Some(g) = &self.gait {
            write!(f, "\n{g}")?;
        }
        if let Some(fo) = &self.following {
            write!(f, "\n{fo}")?;
        }
        if let Some(j) = &self.joint_limits {
            write!(f, "\n{j}")?;
        }
        Ok(())
    }
}

/// Median of `v` (sorted in place; 0 when empty).
pub(crate) fn median(v: &mut [f32]) -> f32 {
    if v.is_empty() {
        return 0.0;
    }
    v.sort_by(f32::total_cmp);
    let m = v.len() / 2;
    if v.len() % 2 == 1 {
        v[m]
    } else {
        0.5 * (v[m - 1] + v[m])
    }
}

/// The poses of one episode of character states x^r: the first root stands at the origin of the
/// ground facing +x with the state's height and tilt; each next root is integrated from the previous
/// one with the state's displacement and delta rotation ([`decode_pose`]). The world placement is
/// arbitrary but consistent, which is all the UFR needs (heights are absolute).
pub fn poses_from_states<R: AsRef<[f32]>>(layout: &CharacterLayout, states: &[R]) -> Vec<CharacterPose> {
    let mut out: Vec<CharacterPose> = Vec::with_capacity(states.len());
    for s in states {
        let s = s.as_ref();
        let pose = match out.last() {
            Some(prev) => decode_pose(layout, &prev.root, s),
            None => CharacterPose {
                root: Isometry3::from_parts(
                    Translation3::new(0.0, 0.0, s[layout.root_height()][0]),
                    read_quat(&s[layout.root_orientation()]),
                ),
                q: s[layout.joint_positions()].to_vec(),
            },
        };
        out.push(pose);
    }
    out
}

/// [`poses_from_states`] for several episodes stored back to back (e.g. a dataset): each episode is
/// decoded on its own, so no displacement is integrated across a boundary. Frames in no episode are
/// decoded as one-frame episodes. Pass the same `episodes` to [`ufr_episodes`].
///
/// # Panics
/// If an episode reaches past the end of `states`.
pub fn poses_from_state_episodes<R: AsRef<[f32]>>(
    layout: &CharacterLayout,
    states: &[R],
    episodes: &[Range<usize>],
) -> Vec<CharacterPose> {
    let n = states.len();
    let mut continues = vec![false; n];
    for e in episodes {
        assert!(e.end <= n, "episode {e:?} reaches past the {n} frames");
        continues[e.clone()].iter_mut().skip(1).for_each(|c| *c = true);
    }
    let mut out: Vec<CharacterPose> = Vec::with_capacity(n);
    let mut start = 0;
    for t in 1..=n {
        if t == n || !continues[t] {
            out.extend(poses_from_states(layout, &states[start..t]));
            start = t;
        }
    }
    out
}
