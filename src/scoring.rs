//! The paper's metrics (§7.3) of character motion under one checkpoint's conventions: its end-effector
//! correspondence and body lengths for Ψ and L_fea, its feature weights, and the Gaussian fit of its
//! training dataset's Ψ (`reference.json`) for FID. `ace retarget` scores one clip with it, `ace eval`
//! whole systems over the held-out clips. Following ([`ace::models::metrics::following()`]) is measured
//! clip by clip on each mapped pair.

use std::ops::Range;
use std::path::Path;

use ace::models::character_state::{CharacterLayout, character_state};
use ace::models::features::{
    EndEffectorMapping, FeatureBlock, FeatureLayout, FeatureWeights, centre_human_features, character_features, human_features,
    human_speed_factor, mean_feature_loss, scale_human_speed,
};
use ace::models::human::EndEffector;
use ace::models::human_set::{HumanRow, PROJECT_FPS};
use ace::models::kinematics::{CharacterPose, KinematicTree};
use ace::models::checkpoint::CharacterInfo;
use ace::models::checkpoint::ace::AceRecord;
use ace::models::metrics::{
    DivConfig, FollowingConfig, FollowingSummary, GaussianFit, MetricsInput, MetricsReport, UfrConfig,
    following, frechet_distance, gait_of_poses, joint_limits, ufr_episodes,
};
use ace::models::morphology::Morphology;
use anyhow::{Context, Result};
use serde::Serialize;

use crate::train::REFERENCE_FILE;

/// FID whole and by feature block: the Fréchet distance of each block's marginal Gaussian to the
/// reference's, a diagnostic of where the distance comes from (the blocks' correlations are left
/// out, so the parts need not add up to the whole).
#[derive(Clone, Debug, Serialize)]
pub struct FidSplit {
    pub total: f64,
    pub blocks: Vec<(&'static str, f64)>,
}

/// Fails unless `fit` is a Gaussian over Ψ of width `width` (FID compares it with fits of the
/// checkpoint's Ψ): a mean of `width` values and a `width × width` covariance (JSON holds finite numbers
/// only). A
/// `reference.json` of another checkpoint, or of another training run of this one, has another width.
fn check_reference(fit: &GaussianFit, width: usize) -> Result<(), String> {
    let (d, rows, cols) = (fit.dim(), fit.cov.nrows(), fit.cov.ncols());
    if d != width || rows != width || cols != width {
        return Err(format!(
            "the Gaussian fit has a mean of {d} entries and a {rows} × {cols} covariance, but the checkpoint's Ψ has \
             {width} entries: it is not this checkpoint's reference; remove it to score without FID, or rerun \
             `ace train` to write it again"
        ));
    }
    Ok(())
}

/// Whether a reference fit was written for the generator of `record`: the same prior, mapping and body
/// length. A `ace train` stopped before its end leaves the previous training's fit beside a new
/// generator. (Fits written before these were recorded carry none of them and are not checked.)
fn check_reference_origin(v: &serde_json::Value, record: &AceRecord) -> Result<(), String> {
    let stale = |what: &str| {
        Err(format!(
            "it was written for another training ({what} differs from ace.json's): rerun `ace train` to finish and \
             write it again, or remove it to score without FID"
        ))
    };
    if let Some(prior) = v.get("prior") {
        if serde_json::from_value::<ace::models::checkpoint::FileRecord>(prior.clone()).ok().as_ref() != Some(&record.prior) {
            return stale("its prior");
        }
    }
    if let Some(mapping) = v.get("mapping") {
        if serde_json::from_value::<ace::models::features::EndEffectorMapping>(mapping.clone()).ok().as_ref() != Some(&record.correspondence.mapping) {
            return stale("its end-effector mapping");
        }
    }
    if let Some(body) = v.get("character_body_length") {
        if body.as_f64().is_none_or(|b| (b as f32 - record.body_lengths.character).abs() > 1e-6 * record.body_lengths.character.abs().max(1.0)) {
            return stale("its character body length");
        }
    }
    Ok(())
}

/// Per-frame flags of a scored motion, for a timeline.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct FrameFlags {
    /// Whether a UFR detector flags the frame.
    pub ufr: Vec<bool>,
    /// Whether a popping swing ([`ace::models::metrics::GaitReport::pop_frames`]) is in the air; all
    /// false for a character without feet.
    pub pops: Vec<bool>,
}

/// Ψ of the human clips a motion was retargeted from, aligned with its frames.
#[derive(Clone, Copy)]
pub struct HumanSource<'a> {
    /// Ψ of every frame ([`Scorer::human_psi`]).
    pub psi: &'a [Vec<f32>],
    /// The body length (m) of each episode's human.
    pub bodies: &'a [f32],
}

/// Scores motions of one checkpoint's character (see the module docs).
pub struct Scorer {
    layout: CharacterLayout,
    mapping: EndEffectorMapping,
    /// The mapped pairs in Ψ's end-effector order: character link, human end effector.
    pairs: Vec<(String, EndEffector)>,
    /// Ψ's index map for `mapping`.
    features: FeatureLayout,
    body: f32,
    human_body_override: Option<f32>,
    weights: FeatureWeights,
    feature_offset: Vec<f32>,
    speed_scale: Option<f32>,
    reference: Option<GaussianFit>,
}

impl Scorer {
    /// The scorer of the checkpoint in `dir` (its generator's `record` and its `character`); FID is
    /// left out when the directory has no `reference.json`.
    pub fn new(record: &AceRecord, character: &CharacterInfo, dir: &Path) -> Result<Scorer> {
        let path = dir.join(REFERENCE_FILE);
        // One that is there but is not a regular file (a FIFO, a directory) is an error, not skipped.
        let reference = if path.exists() {
            let text = ace::models::input::read_text(&path).map_err(|e| anyhow::anyhow!("{}: {e}", path.display()))?;
            let v: serde_json::Value =
                serde_json::from_str(&text).with_context(|| format!("{}: not valid JSON", path.display()))?;
            let fit: GaussianFit =
                serde_json::from_value(v["fit"].clone()).with_context(|| format!("{}: no Gaussian fit", path.display()))?;
            check_reference(&fit, FeatureLayout::new(&record.correspondence.mapping).dim())
                .and_then(|()| check_reference_origin(&v, record))
                .map_err(|problem| anyhow::anyhow!("{}: {problem}", path.display()))?;
            Some(fit)
        } else {
            None
        };
        let links = &character.end_effector_links;
        let mapping = &record.correspondence.mapping;
        Ok(Scorer {
            layout: character.layout,
            pairs: mapping.selected().map(|(k, h)| (links[k].clone(), h)).collect(),
            mapping: mapping.clone(),
            features: FeatureLayout::new(&record.correspondence.mapping),
            body: record.body_lengths.character,
            human_body_override: record.body_lengths.human_override,
            weights: record.config.feature_weights,
            feature_offset: record.feature_offset.clone(),
            speed_scale: record.speed_scale,
            reference,
        })
    }

    /// Whether FID can be computed.
    pub fn has_reference(&self) -> bool {
        self.reference.is_some()
    }

    /// Ψ of character states x^r.
    pub fn character_psi<R: AsRef<[f32]>>(&self, states: &[R]) -> Vec<Vec<f32>> {
        states.iter().map(|x| character_features(&self.layout, x.as_ref(), self.body, &self.mapping)).collect()
    }

    /// Ψ of what is shown: the states' entries, with the end-effector positions those of the poses'
    /// joints. The cleanup writes them into the states already; without it the states carry the
    /// generator's own predicted positions, which can disagree with its joints (Spot's gripper: FID
    /// 0.18 from the predicted entries, 0.48 from the joints), and the joints are what is seen, exported
    /// and sent to a robot.
    ///
    /// # Panics
    /// If `states` and `poses` differ in length.
    pub fn shown_psi<R: AsRef<[f32]>>(
        &self,
        tree: &KinematicTree,
        morph: &Morphology,
        states: &[R],
        poses: &[CharacterPose],
    ) -> Vec<Vec<f32>> {
        assert_eq!(states.len(), poses.len(), "one pose per state");
        let ee = self.layout.ee_positions();
        states
            .iter()
            .zip(poses)
            .map(|(x, pose)| {
                // Positions do not depend on the previous pose.
                let shown = character_state(tree, morph, pose, pose, 1.0 / PROJECT_FPS);
                let mut x = x.as_ref().to_vec();
                x[ee.clone()].copy_from_slice(&shown[ee.clone()]);
                character_features(&self.layout, &x, self.body, &self.mapping)
            })
            .collect()
    }

    /// Ψ of human states x^h of a clip whose human has body length `clip_body` (m), brought to the
    /// character as the checkpoint was trained (its `speed_scale` and `feature_offset`); the
    /// checkpoint's fixed human body length wins when it was trained with one.
    pub fn human_psi(&self, x_h: &[HumanRow], clip_body: f32) -> Vec<Vec<f32>> {
        let body = self.human_body(clip_body);
        // 1 without a speed scale: the velocities stay as they are.
        let factor = self.speed_factor(body);
        x_h.iter()
            .map(|x| {
                let mut psi = human_features(x, body, &self.mapping);
                scale_human_speed(&mut psi, &self.features, factor);
                centre_human_features(&mut psi, &self.feature_offset);
                psi
            })
            .collect()
    }

    /// The human body length (m) Ψ is measured in for a clip whose human is `clip_body` metres: the
    /// checkpoint's fixed one when it was trained with one.
    pub fn human_body(&self, clip_body: f32) -> f32 {
        self.human_body_override.unwrap_or(clip_body)
    }

    /// The factor a human's Ψ velocity (its body lengths per second) is multiplied by to be the
    /// speed L_fea asks of the character, in the character's body lengths per second, for a human of
    /// `body` metres ([`human_speed_factor`] at the checkpoint's speed scale; 1 for a checkpoint
    /// trained without it).
    pub fn speed_factor(&self, body: f32) -> f32 {
        self.speed_scale.map_or(1.0, |s| human_speed_factor(s, body, self.body))
    }

    /// L_fea split by feature block (each block's weighted share; they add up to L_fea).
    pub fn feature_loss_by_block(&self, psi: &[Vec<f32>], human_psi: &[Vec<f32>]) -> Vec<(&'static str, f32)> {
        FeatureBlock::ALL
            .iter()
            .map(|&block| {
                (block.name(), mean_feature_loss(&self.features, psi, human_psi, &self.weights.only(block)))
            })
            .collect()
    }

    /// FID of `psi` against the reference, whole and split by feature block ([`FidSplit`]); `None`
    /// without a reference or rows.
    pub fn fid_split(&self, psi: &[Vec<f32>]) -> Option<FidSplit> {
        let reference = self.reference.as_ref().filter(|_| !psi.is_empty())?;
        let fit = GaussianFit::fit(psi);
        let blocks = FeatureBlock::ALL
            .iter()
            .map(|&block| {
                let r = self.features.range(block);
                (block.name(), frechet_distance(&fit.marginal(r.clone()), &reference.marginal(r)))
            })
            .collect();
        Some(FidSplit { total: frechet_distance(&fit, reference), blocks })
    }

    /// The following of the motion `psi` over each of its `episodes` against the human's.
    ///
    /// # Panics
    /// If `human` is not aligned with `psi` or has no body length per episode.
    pub fn following(&self, psi: &[Vec<f32>], human: HumanSource<'_>, episodes: &[Range<usize>]) -> FollowingSummary {
        assert_eq!(human.bodies.len(), episodes.len(), "one human body length per episode");
        let config = FollowingConfig::new(PROJECT_FPS);
        FollowingSummary::new(
            episodes
                .iter()
                .zip(human.bodies)
                .map(|(e, &body)| {
                    let (c, h) = (&psi[e.clone()], &human.psi[e.clone()]);
                    (following(&self.features, &self.pairs, c, h, body, self.speed_factor(body), &config), body)
                })
                .collect(),
        )
    }

    /// DIV, FID, L_fea and following (when `human` is given, aligned with `psi`), UFR, the gait
    /// measure (legged characters; contacts from the UFR's band) and the joint limits over `poses`, which hold `episodes`
    /// back to back (at the project frame rate).
    pub fn report(
        &self,
        tree: &KinematicTree,
        morph: &Morphology,
        psi: &[Vec<f32>],
        human: Option<HumanSource<'_>>,
        poses: &[CharacterPose],
        episodes: &[Range<usize>],
    ) -> MetricsReport {
        self.report_with_flags(tree, morph, psi, human, poses, episodes).0
    }

    /// [`Scorer::report`] with per-frame flags for a timeline.
    pub fn report_with_flags(
        &self,
        tree: &KinematicTree,
        morph: &Morphology,
        psi: &[Vec<f32>],
        human: Option<HumanSource<'_>>,
        poses: &[CharacterPose],
        episodes: &[Range<usize>],
    ) -> (MetricsReport, FrameFlags) {
        let ufr = ufr_episodes(tree, morph, poses, episodes, PROJECT_FPS, &UfrConfig::for_character(tree, morph));
        let mut report = MetricsReport::compute(
            &MetricsInput {
                features: psi,
                reference: self.reference.as_ref(),
                source_features: human.map(|h| h.psi),
                layout: self.features,
                weights: self.weights,
                div: DivConfig::default(),
            },
            &ufr,
        );
        let pops = match gait_of_poses(tree, morph, poses, episodes, PROJECT_FPS, None) {
            Some(g) => {
                report.gait = Some(g.summary);
                g.pop_frames
            }
            None => vec![false; poses.len()],
        };
        report.following = human.map(|h| self.following(psi, h, episodes));
        report.joint_limits = joint_limits(tree, poses, PROJECT_FPS, episodes);
        (report, FrameFlags { ufr: ufr.any, pops })
    }
}
