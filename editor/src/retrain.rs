//! "Retrain briefly" (fine-tune the current checkpoint's generator for a few hundred steps under the
//! panel's loss weights and end-effector mapping) and "Train a checkpoint" (both stages from
//! scratch), each on a background thread with its progress; the preview switches to the result.

use std::collections::BTreeMap;
use std::path::PathBuf;
use std::time::Instant;

use ace::fine_tune::{DEFAULT_STEPS, FineTune, Stage, fine_tune};
use ace::models::features::FeatureWeights;
use ace::models::human::EndEffector;
use ace::models::learn::ace::AceConfig;
use ace::models::learn::train_ace::AceProgress;
use ace::train::{TrainArgs, ace as train_ace_stage, prior as train_prior_stage};
use bevy::prelude::*;

use crate::jobs::Job;
use crate::Session;
use crate::preview::Preview;

/// The panel's settings for a retraining.
#[derive(Clone, Debug, PartialEq)]
pub struct Settings {
    pub steps: usize,
    pub w_adv: f64,
    pub w_fea: f64,
    pub feature_weights: FeatureWeights,
    /// Per character end effector (link name): `None` keeps the automatic choice, `Some(None)`
    /// leaves it out of Ψ, `Some(Some(e))` maps it to human end effector `e`.
    pub mapping: BTreeMap<String, Option<Option<EndEffector>>>,
}

impl Settings {
    /// The settings a checkpoint was trained with.
    pub fn of(cfg: &AceConfig, links: &[String]) -> Settings {
        let manual = cfg.end_effector_mapping.clone().unwrap_or_default();
        Settings {
            steps: DEFAULT_STEPS,
            w_adv: cfg.w_adv,
            w_fea: cfg.w_fea,
            feature_weights: cfg.feature_weights,
            mapping: links.iter().map(|l| (l.clone(), manual.get(l).copied())).collect(),
        }
    }

    fn manual_mapping(&self) -> Option<BTreeMap<String, Option<EndEffector>>> {
        let m: BTreeMap<_, _> = self.mapping.iter().filter_map(|(l, v)| v.map(|v| (l.clone(), v))).collect();
        (!m.is_empty()).then_some(m)
    }
}

enum Message {
    Stage(String),
    Step(AceProgress),
    Done(Result<PathBuf, String>),
}

/// State of "Retrain briefly".
#[derive(Resource, Default)]
pub struct Retrain {
    pub settings: Option<Settings>,
    /// The checkpoint the settings were read from.
    pub settings_from: Option<PathBuf>,
    pub stage: String,
    pub history: Vec<AceProgress>,
    pub started: Option<Instant>,
    pub seconds: Option<f32>,
    pub error: Option<String>,
    /// L_fea of the current clip before the run and after it (once the new preview is in).
    pub fea_before: Option<f32>,
    pub fea_after: Option<f32>,
    /// Whether the loss plot is still to be scrolled into view (once per run, at its first step).
    pub reveal_losses: bool,
    /// The checkpoint the last run wrote, until its preview arrives.
    awaiting: Option<PathBuf>,
    job: Option<Job<Message>>,
}

impl Retrain {
    /// Whether a run is going.
    pub fn running(&self) -> bool {
        self.job.is_some()
    }

    /// Starts fine-tuning the preview's checkpoint.
    pub fn start(&mut self, preview: &Preview) {
        let (Some(result), Some(settings)) = (&preview.result, self.settings.clone()) else { return };
        let inputs = &result.inputs;
        let name = inputs.checkpoint.file_name().map(|n| n.to_string_lossy().into_owned()).unwrap_or_default();
        let stamp = std::time::SystemTime::now().duration_since(std::time::UNIX_EPOCH).map(|d| d.as_secs()).unwrap_or(0);
        let to = PathBuf::from("out/editor/retrained").join(format!("{name}-{stamp}"));
        let ft = FineTune {
            urdf: inputs.character.clone(),
            from: inputs.checkpoint.clone(),
            to,
            steps: settings.steps,
            w_adv: settings.w_adv,
            w_fea: settings.w_fea,
            feature_weights: settings.feature_weights,
            end_effector_mapping: settings.manual_mapping(),
            humans: None,
        };
        self.run(ft, result.retargeted.report.feature_loss);
    }

    /// Runs the fine-tuning `ft` on its own thread; `fea_before` is L_fea of the clip shown.
    pub(crate) fn run(&mut self, ft: FineTune, fea_before: Option<f32>) {
        let to = ft.to.clone();
        self.fea_before = fea_before;
        self.fea_after = None;
        self.history.clear();
        self.reveal_losses = true;
        self.error = None;
        self.seconds = None;
        self.stage = "starting".into();
        self.started = Some(Instant::now());
        self.job = Some(Job::spawn("ace-retrain", move |tx| {
            let outcome = fine_tune(&ft, &mut |stage| {
                let _ = match stage {
                    Stage::Preparing(what) => tx.send(Message::Stage(what.to_string())),
                    Stage::Training(p) => tx.send(Message::Step(p)),
                };
            });
            let _ = tx.send(Message::Done(outcome.map(|()| to).map_err(|e| format!("{e:#}"))));
        }));
    }

    /// Starts training a checkpoint for `character` (a URDF or glTF file) from scratch (motion prior,
    /// then ACE) into `out/editor/checkpoints/<name>`, with the CPU defaults.
    pub fn train_new(&mut self, character: PathBuf) {
        let name = character.file_stem().map(|n| n.to_string_lossy().into_owned()).unwrap_or_else(|| "character".into());
        let dir = PathBuf::from("out/editor/checkpoints").join(name);
        self.history.clear();
        self.error = None;
        self.fea_before = None;
        self.fea_after = None;
        self.started = Some(Instant::now());
        self.stage = "training the motion prior".into();
        self.job = Some(Job::spawn("ace-train", move |tx| {
            let args = TrainArgs {
                character: character.display().to_string(),
                out: Some(dir.clone()),
                dataset: None,
                frames: None,
                seed: None,
                config: None,
                paper: false,
                humans: None,
                dataset_config: None,
            };
            let outcome = train_prior_stage(&args).and_then(|()| {
                let _ = tx.send(Message::Stage("training ACE".into()));
                train_ace_stage(&args)
            });
            let _ = tx.send(Message::Done(outcome.map(|()| dir).map_err(|e| format!("{e:#}"))));
        }));
    }
}

/// Takes progress; when a run finishes, the session switches to its checkpoint (and the preview
/// follows).
pub fn poll(mut retrain: ResMut<Retrain>, preview: Res<Preview>, mut session: ResMut<Session>) {
    let retrain = &mut *retrain;
    if let Some(job) = retrain.job.as_mut() {
        for m in job.poll() {
            match m {
                Message::Stage(s) => retrain.stage = s,
                Message::Step(p) => {
                    retrain.stage = format!("step {} of {}", p.step, p.steps);
                    retrain.history.push(p);
                }
                Message::Done(Ok(dir)) => {
                    retrain.seconds = retrain.started.map(|s| s.elapsed().as_secs_f32());
                    retrain.stage = format!("done: {}", dir.display());
                    session.checkpoint = Some(dir.clone());
                    retrain.awaiting = Some(dir);
                }
                Message::Done(Err(e)) => {
                    retrain.stage = "failed".into();
                    retrain.error = Some(e);
                }
            }
        }
        if job.finished() {
            if let Some(e) = job.panicked() {
                retrain.stage = "failed".into();
                retrain.error = Some(e);
            }
            retrain.job = None;
        }
    }
    if let (Some(dir), Some(result)) = (&retrain.awaiting, &preview.result) {
        if &result.inputs.checkpoint == dir {
            retrain.fea_after = result.retargeted.report.feature_loss;
            retrain.awaiting = None;
        }
    }
    // The panel's settings follow the checkpoint shown.
    if let Some(result) = &preview.result {
        if retrain.settings_from.as_ref() != Some(&result.inputs.checkpoint) {
            let steps = retrain.settings.as_ref().map_or(DEFAULT_STEPS, |s| s.steps);
            let mut s = Settings::of(&result.record.config, &result.record.correspondence.character_links);
            s.steps = steps;
            retrain.settings = Some(s);
            retrain.settings_from = Some(result.inputs.checkpoint.clone());
        }
    }
}
