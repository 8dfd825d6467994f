//! ACE training (paper §5): the generator G learns to drive the frozen motion prior π from human
//! motion, against a discriminator D that tells its transitions from the character dataset's.
//!
//! Each generator step:
//! 1. takes `batch_size` windows of `window` consecutive frames from the training human clips and as
//!    many start states. Rollouts are persistent: a rollout continues where its last window ended,
//!    the human clip at the next frame and the character in the state G left it in (detached), for
//!    [`AceConfig::rollout_windows`] steps; then, or when its clip has no further window, it starts
//!    again from a random window (uniform over all windows, so longer clips count more) and a random
//!    character dataset state (a real frame, normalised). A retargeter runs G on its own states along
//!    a whole clip from one start; trained only from random dataset states, whose arm or feet have
//!    nothing to do with the human's frame, G learned to pull towards the human's features from
//!    anywhere instead of following them, and a Stretch arm that moved with the hand in training
//!    ignored it at retargeting (vertical correlation 0.03 over the held-out clips);
//! 2. rolls G and π out over the window, `x̂_t = π(G(x^h_t, x̂_{t−1}), x̂_{t−1})` from the start
//!    state, keeping the whole rollout in the graph so that gradients reach G through every step
//!    (π's weights are frozen, its inputs are not);
//! 3. minimises `w_adv·L_adv + w_fea·L_fea` averaged over the window, where L_fea compares Ψ of the
//!    denormalised x̂_t ([`super::psi`]) with Ψ of the human frame (precomputed with
//!    [`crate::features::human_features`], the same mapping and each clip's body length) and L_adv is
//!    [`generator_adv_loss`] on the generated transitions (D's weights are frozen for this step);
//! 4. then updates D `discriminator_steps` times on real dataset transitions against generated ones
//!    drawn from the rollout (detached), with the gradient penalty on the real ones.
//!
//! Both optimisers are Adam (β₁ = [`AceConfig::adam_beta1`]). Randomness (initialisation, windows,
//! start states, D batches) comes from PCG-64 generators seeded with [`AceConfig::seed`] and the step
//! number, so the same inputs give the same weights on the CPU.
//!
//! # Run directory
//! The run directory holds the motion prior's checkpoint ([`PriorCheckpoint`]; written there if it is
//! not already), the ACE checkpoint ([`AceCheckpoint`]: `generator.safetensors`,
//! `discriminator.safetensors`, `ace.json`) saved every `checkpoint_every` steps and at the end, and
//! `ace_losses.csv` (`step,d_loss,d_bce,gp,g_loss,adv,fea,d_real,d_fake,seconds`; `step` counts from
//! 0, `d_real`/`d_fake` are the mean σ(logit) of the last D update's real and fake batches, `seconds`
//! is cumulative over sessions). A run started in a directory that holds an ACE checkpoint of the same
//! configuration, character, correspondence and human data resumes from it: weights and step are
//! restored and the draws continue as in an uninterrupted run, but Adam's moment estimates restart
//! from zero (they are not saved) and the rollouts start afresh, so a resumed run is not bit-identical
//! to an uninterrupted one.

use std::collections::BTreeMap;
use std::fs;
use std::io::Write;
use std::path::Path;
use std::time::Instant;

use rand::RngExt;
use rand_pcg::Pcg64;
use serde_json::Value;
use tch::nn::OptimizerConfig;
use tch::{Device, Kind, Tensor, nn};

use super::ace::{
    ACE_FILE, AceCheckpoint, AceConfig, AceRecord, BodyLengths, Discriminator, DiscriminatorLoss,
    FORMAT_VERSION, FileRecord, Generator, KIND, discriminator_loss, generator_adv_loss,
};
use super::checkpoint::{CONFIG_FILE, CharacterInfo, LearnError, Normaliser, PriorCheckpoint};
use super::files::{open_losses, step_rng};
use super::prior::window_starts;
use super::psi::{Psi, feature_loss, weight_tensor};
use super::rows_to_tensor;
use crate::correspondence::Correspondence;
use crate::dataset::MotionSet;
use crate::features::{
    FeatureLayout, centre_human_features, centring_offset, character_features, human_features_into, human_speed_factor,
    mean_features, scale_human_speed,
};
use crate::human::layout as human_layout;
use crate::human_set::{HumanSet, HumanStats};
use crate::kinematics::KinematicTree;
use crate::morphology::Morphology;

/// Name of the loss log in a run directory.
pub const LOSSES_FILE: &str = "ace_losses.csv";

/// The columns of [`LOSSES_FILE`]; `seconds` is column [`SECONDS_COLUMN`].
const HEADER: &str = "step,d_loss,d_bce,gp,g_loss,adv,fea,d_real,d_fake,seconds";
const SECONDS_COLUMN: usize = 9;
/// The stream of ACE's step generators, apart from the prior's for the same seed.
const RNG_STREAM: u64 = 0xace0_ace0_ace0_ace0;

/// What ACE trains on.
#[derive(Clone, Copy, Debug)]
pub struct AceInputs<'a> {
    /// The motion prior (its variables stop tracking gradients during training, as after
    /// [`super::prior::MotionPrior::freeze`]). Training runs on its device.
    pub prior: &'a PriorCheckpoint,
    /// The character dataset the prior was trained on (its normalisation must be the prior's).
    pub dataset: &'a MotionSet,
    /// The character (the prior's): Ψ's end effectors come from its forward kinematics
    /// ([`AceConfig::kinematic_features`]).
    pub tree: &'a KinematicTree,
    /// The character's morphology (its end effectors and their points).
    pub morph: &'a Morphology,
    /// The human clips; only the training split is used.
    pub humans: &'a HumanSet,
    /// The end-effector correspondence of Ψ (after any manual overrides).
    pub correspondence: &'a Correspondence,
    /// The character's body length (m), [`crate::features::character_body_length`] times any user scale.
    pub character_body_length: f32,
    /// One body length for every human clip (m); `None` uses each clip's own.
    pub human_body_length: Option<f32>,
    /// The human-equivalent speed scale of the controller that made `dataset`
    /// ([`crate::dataset::speed_scale`]), at which L_fea compares the root's linear velocity.
    pub speed_scale: f32,
    /// Recorded in `ace.json` (a resumed run keeps the stored one when this is `null`).
    pub provenance: &'a Value,
}

/// Reported after every generator step.
#[derive(Clone, Debug, PartialEq)]
pub struct AceProgress {
    /// Steps done (1 after the first).
    pub step: usize,
    /// Steps in the run.
    pub steps: usize,
    /// `w_adv·adv + w_fea·fea`.
    pub g_loss: f64,
    /// D's total loss (cross-entropy plus penalty) of the step's last D update.
    pub d_loss: f64,
    /// L_fea, averaged over the window.
    pub fea: f64,
    /// L_adv, averaged over the window.
    pub adv: f64,
    /// Seconds of training so far (including earlier sessions of a resumed run).
    pub seconds: f64,
}

/// The training human data as tensors: normalised x^h rows and Ψ rows of all usable clips back to
/// back, with the first row of every window.
pub(crate) struct HumanWindows {
    pub(crate) states: Tensor,
    pub(crate) features: Tensor,
    pub(crate) starts: Vec<usize>,
    /// The centring offset already added to `features` (empty without centring).
    pub(crate) offset: Vec<f32>,
    /// The speed scale the root's linear velocity in `features` was brought to (`None`: body lengths
    /// per second).
    pub(crate) speed_scale: Option<f32>,
}

/// How the human's Ψ is brought to the character's before L_fea compares them
/// ([`crate::features`], "Centring" and "Speed").
#[derive(Clone, Copy, Debug)]
pub(crate) struct FeatureMatching {
    pub(crate) centre: bool,
    pub(crate) speed: bool,
}

impl FeatureMatching {
    /// Ψ as it is (NKN, which has no feature loss).
    pub(crate) const NONE: FeatureMatching = FeatureMatching { centre: false, speed: false };

    pub(crate) fn of(cfg: &AceConfig) -> FeatureMatching {
        FeatureMatching { centre: cfg.centre_features, speed: cfg.match_speed_scale }
    }
}

/// Trains G and D (see the module docs) in `run_dir`, resuming from the checkpoint there if any, and
/// returns the final checkpoint (also saved in `run_dir`).
pub fn train_ace(
    inputs: &AceInputs<'_>,
    cfg: &AceConfig,
    run_dir: &Path,
    progress: &mut dyn FnMut(&AceProgress),
) -> Result<AceCheckpoint, LearnError> {
    cfg.check()?;
    cfg.device.check_available()?;
    let prior = inputs.prior;
    let device = prior.prior.device();
    check_inputs(inputs, run_dir)?;
    fs::create_dir_all(run_dir).map_err(|e| LearnError::io(run_dir, e))?;
    place_prior(prior, run_dir)?;

    let human_stats = inputs.humans.train_statistics();
    check_human_stats(inputs.humans, &human_stats)?;
    let mut psi = Psi::new(
        &prior.character.layout,
        &inputs.correspondence.mapping,
        inputs.character_body_length,
        device,
    );
    if cfg.kinematic_features {
        psi = psi.with_kinematics(inputs.tree, inputs.morph);
    }
    if cfg.kinematic_root {
        psi = psi.with_root_motion(1.0 / inputs.dataset.config.fps);
    }
    let humans = human_windows(inputs, &human_stats, psi.layout(), cfg.window, FeatureMatching::of(cfg), device)?;
    let ckpt = start_or_resume(inputs, cfg, &human_stats, &humans, run_dir, device)?;
    if ckpt.record.step >= cfg.steps {
        return Ok(ckpt);
    }
    let AceCheckpoint {
        mut record,
        generator,
        discriminator,
    } = ckpt;
    let mut discriminator = discriminator.expect("training checkpoints hold D");
    let losses_path = run_dir.join(LOSSES_FILE);
    let (mut log, seconds_before) = open_losses(&losses_path, record.step, HEADER, SECONDS_COLUMN)?;

    // The prior stays fixed: no gradients for its variables (they still flow through it).
    for v in prior.prior.var_store().trainable_variables() {
        let _ = v.set_requires_grad(false);
    }
    let set = inputs.dataset;
    let stats = &prior.stats;
    let data = normalised_dataset(prior, set, device)?;
    let (mean, std) = (
        Tensor::from_slice(&stats.mean).to_device(device),
        Tensor::from_slice(&stats.std).to_device(device),
    );
    let real_starts = window_starts(&set.episodes, 1);
    let weights = weight_tensor(psi.layout(), &cfg.feature_weights, device);
    let adam = nn::Adam {
        beta1: cfg.adam_beta1,
        ..nn::Adam::default()
    };
    let mut opt_g = adam.build(generator.var_store(), cfg.generator_lr)?;
    let mut opt_d = adam.build(discriminator.var_store(), cfg.discriminator_lr)?;
    let (b, window) = (cfg.batch_size, cfg.window);
    let clock = Instant::now();
    // Whether a window may start at a human row (it stays inside its clip).
    let mut window_fits = vec![false; humans.states.size()[0] as usize];
    humans.starts.iter().for_each(|&r| window_fits[r] = true);
    // The persistent rollouts: each one's next human row, and the state G left its character in (both
    // set afresh at the session's first step, which restarts every rollout).
    let mut lanes: Vec<usize> = vec![0; b];
    let mut lane_states = Tensor::zeros([b as i64, data.size()[1]], (Kind::Float, device));
    let record_start = record.step;

    for step in record.step..cfg.steps {
        let mut rng = step_rng(cfg.seed, RNG_STREAM, step);
        let draw = |rng: &mut Pcg64, pool: &[usize]| -> Tensor {
            let v: Vec<i64> = (0..b)
                .map(|_| pool[rng.random_range(0..pool.len())] as i64)
                .collect();
            Tensor::from_slice(&v).to_device(device)
        };
        // Rollouts that go on keep their row and state; the others start from a random window and a
        // random dataset state (both drawn for every lane, so the draws do not depend on the lanes).
        let fresh_rows: Vec<usize> = (0..b).map(|_| humans.starts[rng.random_range(0..humans.starts.len())]).collect();
        let fresh_states: Vec<i64> = (0..b).map(|_| rng.random_range(0..set.len()) as i64).collect();
        let restart_all = (step - record_start) % cfg.rollout_windows == 0;
        let mut go_on = vec![false; b];
        for (k, row) in lanes.iter_mut().enumerate() {
            if !restart_all && window_fits.get(*row).copied().unwrap_or(false) {
                go_on[k] = true;
            } else {
                *row = fresh_rows[k];
            }
        }
        let human = Tensor::from_slice(&lanes.iter().map(|&r| r as i64).collect::<Vec<_>>()).to_device(device);
        let fresh = data.index_select(0, &Tensor::from_slice(&fresh_states).to_device(device));
        let keep = Tensor::from_slice(&go_on.iter().map(|&g| if g { 1.0f32 } else { 0.0 }).collect::<Vec<_>>())
            .view([b as i64, 1])
            .to_device(device);
        let mut prev = &lane_states * &keep + fresh * (1.0 - &keep);

        // Generator step through the rollout, with D fixed.
        discriminator.var_store_mut().freeze();
        let mut fea = Tensor::zeros([], (Kind::Float, device));
        let mut adv = Tensor::zeros([], (Kind::Float, device));
        let (mut fake_prev, mut fake_cur) = (Vec::with_capacity(window), Vec::with_capacity(window));
        for t in 0..window {
            let rows = &human + t as i64;
            let z = generator.forward(&humans.states.index_select(0, &rows), &prev);
            let cur = prior.prior.decode(&z, &prev);
            // A term of weight zero (an ablation) is only monitored: computed without a graph, so
            // it costs no backward pass and cannot turn the loss into NaN (0·∞).
            let fea_t = tracked(cfg.w_fea, || {
                let psi_r = psi.features(&(&cur * &std + &mean))?;
                Ok(feature_loss(&psi_r, &humans.features.index_select(0, &rows), &weights))
            })?;
            fea += fea_t;
            adv += tracked(cfg.w_adv, || Ok(generator_adv_loss(&discriminator, &prev, &cur)))?;
            fake_prev.push(prev.detach());
            fake_cur.push(cur.detach());
            prev = cur;
        }
        lane_states = prev.detach();
        lanes.iter_mut().for_each(|r| *r += window);
        let (fea, adv) = (fea / window as f64, adv / window as f64);
        let g_loss = weighted_sum(&[(cfg.w_adv, &adv), (cfg.w_fea, &fea)]);
        opt_g.backward_step(&g_loss);
        discriminator.var_store_mut().unfreeze();

        // Discriminator updates on real transitions against this rollout's.
        let (fake_prev, fake_cur) = (Tensor::cat(&fake_prev, 0), Tensor::cat(&fake_cur, 0));
        let fake_pool: Vec<usize> = (0..window * b).collect();
        let mut last = None;
        for _ in 0..cfg.discriminator_steps.max(1) {
            let real = draw(&mut rng, &real_starts);
            let fake = draw(&mut rng, &fake_pool);
            let l = discriminator_loss(
                &discriminator,
                &data.index_select(0, &real),
                &data.index_select(0, &(&real + 1)),
                &fake_prev.index_select(0, &fake),
                &fake_cur.index_select(0, &fake),
                cfg.w_gp,
            );
            if cfg.discriminator_steps > 0 {
                opt_d.backward_step(&l.total);
            }
            last = Some(l);
        }
        let d = last.expect("at least one D evaluation");

        let scalar = |t: &Tensor| t.double_value(&[]);
        let report = AceProgress {
            step: step + 1,
            steps: cfg.steps,
            g_loss: scalar(&g_loss),
            d_loss: scalar(&d.total),
            fea: scalar(&fea),
            adv: scalar(&adv),
            seconds: seconds_before + clock.elapsed().as_secs_f64(),
        };
        log_step(&mut log, &losses_path, step, &d, [report.g_loss, report.adv, report.fea], report.seconds)?;
        progress(&report);
        record.step = step + 1;
        if record.step % cfg.checkpoint_every == 0 || record.step == cfg.steps {
            record.save(run_dir, &generator, Some(&discriminator))?;
        }
    }
    Ok(AceCheckpoint {
        record,
        generator,
        discriminator: Some(discriminator),
    })
}

/// Fails when the step's losses are not finite, else appends its row to the loss log `log` (at
/// `path`): `step,d_loss,d_bce,gp,g_loss,adv,<term>,d_real,d_fake,seconds`, where `g = [g_loss, adv,
/// term]` (`term` is L_fea for ACE, the cycle loss for NKN) and `d_real`/`d_fake` are the mean
/// σ(logit) of D's batches.
pub(crate) fn log_step(
    log: &mut fs::File,
    path: &Path,
    step: usize,
    d: &DiscriminatorLoss,
    g: [f64; 3],
    seconds: f64,
) -> Result<(), LearnError> {
    let scalar = |t: &Tensor| t.double_value(&[]);
    let mean_sigmoid = |t: &Tensor| t.sigmoid().mean(Kind::Float).double_value(&[]);
    let d_loss = scalar(&d.total);
    if !(g[0].is_finite() && d_loss.is_finite()) {
        return Err(LearnError::Data(format!(
            "the losses became non-finite at step {} (G {}, D {d_loss}); lower the learning rates",
            step + 1,
            g[0]
        )));
    }
    writeln!(
        log,
        "{step},{d_loss},{},{},{},{},{},{},{},{seconds:.3}",
        scalar(&d.bce),
        scalar(&d.gp),
        g[0],
        g[1],
        g[2],
        mean_sigmoid(&d.real_logits),
        mean_sigmoid(&d.fake_logits),
    )
    .and_then(|_| log.flush())
    .map_err(|e| LearnError::io(path, e))
}

/// Every state of the prior's dataset `set`, normalised and masked as the prior's inputs (`[N, D]`).
pub(crate) fn normalised_dataset(prior: &PriorCheckpoint, set: &MotionSet, device: Device) -> Result<Tensor, LearnError> {
    let rows = rows_to_tensor(&set.states.chunks(set.layout.dim()).collect::<Vec<_>>(), device)?;
    Ok(prior.stats.normalise(&rows) * prior.prior.mask())
}

/// A loss term of weight `w`: in the graph when `w` is positive, computed under
/// [`tch::no_grad`] (monitored only) when it is zero.
pub(crate) fn tracked(w: f64, term: impl FnOnce() -> Result<Tensor, LearnError>) -> Result<Tensor, LearnError> {
    if w > 0.0 { term() } else { tch::no_grad(term) }
}

/// `Σ wᵢ·termᵢ` over the terms of positive weight (zero-weighted terms, monitored only, stay out of
/// the graph). At least one weight must be positive.
pub(crate) fn weighted_sum(terms: &[(f64, &Tensor)]) -> Tensor {
    let mut used = terms.iter().filter(|(w, _)| *w > 0.0).map(|(w, t)| *t * *w);
    let first = used.next().expect("at least one positive loss weight");
    used.fold(first, |acc, t| acc + t)
}

/// The inputs must describe one character with one normalisation.
fn check_inputs(inputs: &AceInputs<'_>, run_dir: &Path) -> Result<(), LearnError> {
    let prior = inputs.prior;
    let set = inputs.dataset;
    if let Some(problem) = CharacterInfo::of_set(set).difference(&prior.character) {
        return Err(LearnError::WrongCharacter {
            path: run_dir.to_path_buf(),
            problem: format!("the dataset and the prior differ: {problem}"),
        });
    }
    if let Some(problem) = CharacterInfo::of_character(inputs.tree, inputs.morph).difference(&prior.character) {
        return Err(LearnError::WrongCharacter {
            path: run_dir.to_path_buf(),
            problem: format!("the character given and the prior's differ: {problem}"),
        });
    }
    if Normaliser::of_set(set) != prior.stats {
        return Err(LearnError::Data(format!(
            "the dataset of `{}` has other normalisation statistics than the prior: the prior was trained \
             on another dataset",
            set.character
        )));
    }
    if window_starts(&set.episodes, 1).is_empty() {
        return Err(LearnError::Data(format!(
            "the dataset of `{}` has no episode of two frames, so no real transition",
            set.character
        )));
    }
    let corr = inputs.correspondence;
    if corr.mapping.human.len() != set.layout.end_effectors || corr.character_links != set.end_effector_links
    {
        return Err(LearnError::Data(format!(
            "the end-effector correspondence is for links [{}], the character `{}` has [{}]",
            corr.character_links.join(", "),
            set.character,
            set.end_effector_links.join(", ")
        )));
    }
    let lengths = [Some(inputs.character_body_length), inputs.human_body_length];
    if lengths.iter().flatten().any(|l| !(l.is_finite() && *l > 0.0)) {
        return Err(LearnError::Config(format!(
            "body lengths must be positive, not character {} / human {:?}",
            inputs.character_body_length, inputs.human_body_length
        )));
    }
    Ok(())
}

/// Makes sure `run_dir` holds `prior`: an equal prior checkpoint there (same configuration, step,
/// statistics, mask and character) is kept, anything else is replaced — unless an ACE checkpoint
/// already depends on it.
pub(crate) fn place_prior(prior: &PriorCheckpoint, run_dir: &Path) -> Result<(), LearnError> {
    if run_dir.join(CONFIG_FILE).exists() {
        let there = PriorCheckpoint::load(run_dir, Device::Cpu)?;
        let same = there.config == prior.config
            && there.step == prior.step
            && there.stats == prior.stats
            && there.mask == prior.mask
            && there.character == prior.character;
        if same {
            return Ok(());
        }
        if run_dir.join(ACE_FILE).exists() {
            return Err(LearnError::Config(format!(
                "{} holds an ACE checkpoint trained against another motion prior; use another run \
                 directory to start afresh",
                run_dir.display()
            )));
        }
    }
    prior.save(run_dir)
}

/// Prepares `run_dir` for fine-tuning a trained checkpoint (`prior` and `ckpt`, with its
/// discriminator, as loaded from directory `from`): the prior and both networks are saved there with
/// the record's configuration replaced by `cfg` and its correspondence by `correspondence`, at the
/// step `ckpt` had reached. [`train_ace`] with the same `cfg` (whose `steps` counts from that step) then
/// continues the networks under the new loss weights, feature weights and mapping. Fails when
/// `run_dir` already holds a checkpoint (nothing there is overwritten) or `cfg` changes the
/// networks' shapes.
pub fn start_fine_tune(
    prior: &PriorCheckpoint,
    mut ckpt: AceCheckpoint,
    from: &Path,
    run_dir: &Path,
    cfg: &AceConfig,
    correspondence: &Correspondence,
) -> Result<AceCheckpoint, LearnError> {
    cfg.check()?;
    if run_dir.join(ACE_FILE).exists() || run_dir.join(CONFIG_FILE).exists() {
        return Err(LearnError::Config(format!(
            "{} already holds a checkpoint; fine-tune into an empty directory",
            run_dir.display()
        )));
    }
    if ckpt.discriminator.is_none() {
        return Err(LearnError::Config(format!(
            "fine-tuning {} needs its discriminator: load the checkpoint with it",
            from.display()
        )));
    }
    let stored = &ckpt.record.config;
    if stored.generator_hidden != cfg.generator_hidden || stored.discriminator_hidden != cfg.discriminator_hidden {
        return Err(LearnError::Config(format!(
            "fine-tuning {} keeps its networks: generator_hidden and discriminator_hidden must stay {:?} and {:?}",
            from.display(),
            stored.generator_hidden,
            stored.discriminator_hidden
        )));
    }
    if correspondence.character_links != ckpt.record.correspondence.character_links {
        return Err(LearnError::Config(format!(
            "the correspondence is for end effectors {:?}, {} has {:?}",
            correspondence.character_links,
            from.display(),
            ckpt.record.correspondence.character_links
        )));
    }
    ckpt.record.config = cfg.clone();
    ckpt.record.correspondence = correspondence.clone();
    fs::create_dir_all(run_dir).map_err(|e| LearnError::io(run_dir, e))?;
    prior.save(run_dir)?;
    ckpt.save(run_dir)?;
    Ok(ckpt)
}

/// Normalised x^h and Ψ of every training clip long enough for a window. Ψ's root linear velocity
/// is brought to the dataset's speed scale ([`human_speed_factor`]) with `matching.speed`; then, with
/// `matching.centre`, Ψ is shifted by the [`centring_offset`] of the training clips against the
/// character dataset.
pub(crate) fn human_windows(
    inputs: &AceInputs<'_>,
    stats: &HumanStats,
    features: &FeatureLayout,
    window: usize,
    matching: FeatureMatching,
    device: Device,
) -> Result<HumanWindows, LearnError> {
    if matching.speed && !(inputs.speed_scale.is_finite() && inputs.speed_scale > 0.0) {
        return Err(LearnError::Config(format!(
            "the dataset's speed scale must be positive, got {}",
            inputs.speed_scale
        )));
    }
    let speed_scale = matching.speed.then_some(inputs.speed_scale);
    let mapping = &inputs.correspondence.mapping;
    let (f, h) = (features.dim(), human_layout::DIM);
    let mut states: Vec<f32> = Vec::new();
    let mut psi: Vec<f32> = Vec::new();
    let mut starts = Vec::new();
    let mut rows = 0;
    for clip in inputs.humans.train_clips().filter(|c| c.states.len() >= window) {
        let body = inputs.human_body_length.unwrap_or(clip.body_length);
        starts.extend(rows..rows + clip.states.len() + 1 - window);
        rows += clip.states.len();
        for x in &clip.states {
            states.extend(
                x.iter()
                    .zip(&stats.mean)
                    .zip(&stats.std)
                    .map(|((v, m), s)| (v - m) / s),
            );
            let at = psi.len();
            psi.resize(at + f, 0.0);
            human_features_into(x, body, mapping, &mut psi[at..]);
            if let Some(s) = speed_scale {
                scale_human_speed(&mut psi[at..], features, human_speed_factor(s, body, inputs.character_body_length));
            }
        }
    }
    if starts.is_empty() {
        return Err(LearnError::Data(format!(
            "{}: no training clip has the {window} frames a window needs",
            inputs.humans.folder.display()
        )));
    }
    let offset = if matching.centre {
        let set = inputs.dataset;
        let character_mean = mean_features((0..set.len()).map(|i| {
            character_features(&set.layout, set.state(i), inputs.character_body_length, mapping)
        }));
        let offset = centring_offset(features, &mean_features(psi.chunks(f)), &character_mean);
        for row in psi.chunks_mut(f) {
            centre_human_features(row, &offset);
        }
        offset
    } else {
        Vec::new()
    };
    let n = rows as i64;
    Ok(HumanWindows {
        states: Tensor::from_slice(&states).view([n, h as i64]).to_device(device),
        features: Tensor::from_slice(&psi).view([n, f as i64]).to_device(device),
        starts,
        offset,
        speed_scale,
    })
}

/// A new ACE checkpoint, or the one in `run_dir` when it fits the configuration and data.
fn start_or_resume(
    inputs: &AceInputs<'_>,
    cfg: &AceConfig,
    human_stats: &HumanStats,
    humans: &HumanWindows,
    run_dir: &Path,
    device: Device,
) -> Result<AceCheckpoint, LearnError> {
    let prior = &inputs.prior;
    let (dim, latent) = (prior.prior.state_dim(), prior.prior.latent_dim());
    let body_lengths = BodyLengths {
        character: inputs.character_body_length,
        human_override: inputs.human_body_length,
        human_clips: inputs
            .humans
            .train_clips()
            .map(|c| (c.relative.clone(), c.body_length))
            .collect::<BTreeMap<_, _>>(),
    };
    let record = AceRecord {
        kind: KIND.into(),
        format_version: FORMAT_VERSION,
        character: prior.character.clone(),
        step: 0,
        config: cfg.clone(),
        correspondence: inputs.correspondence.clone(),
        human_stats: human_stats.clone(),
        human_folder: inputs.humans.folder.clone(),
        human_split: inputs.humans.split.clone(),
        body_lengths,
        feature_offset: humans.offset.clone(),
        speed_scale: humans.speed_scale,
        // The file records are filled in when the checkpoint is saved.
        generator: FileRecord::default(),
        discriminator: FileRecord::default(),
        prior: FileRecord::default(),
        prior_config: None,
        provenance: inputs.provenance.clone(),
    };
    if !run_dir.join(ACE_FILE).exists() {
        return Ok(AceCheckpoint {
            generator: Generator::new(cfg, dim, latent, &prior.mask, device),
            discriminator: Some(Discriminator::new(cfg, dim, &prior.mask, device)),
            record,
        });
    }
    let mut ckpt = AceCheckpoint::load(run_dir, latent, &prior.mask, device, true)?;
    let stored = &ckpt.record;
    let refuse = |what: &str| {
        Err(LearnError::Config(format!(
            "{} holds an ACE checkpoint made with {what}; use another run directory to start afresh",
            run_dir.display()
        )))
    };
    if stored.character != record.character {
        return refuse("another character");
    }
    if !stored.config.resumable_with(cfg) {
        return refuse("another configuration");
    }
    if stored.correspondence.mapping != record.correspondence.mapping {
        return refuse("another end-effector mapping");
    }
    if stored.human_stats != record.human_stats
        || stored.human_split != record.human_split
        || stored.body_lengths != record.body_lengths
    {
        return refuse("other human data (statistics, split or body lengths differ)");
    }
    if stored.speed_scale != record.speed_scale {
        return refuse("another dataset speed scale");
    }
    let step = stored.step;
    let provenance = if inputs.provenance.is_null() {
        stored.provenance.clone()
    } else {
        inputs.provenance.clone()
    };
    ckpt.record = AceRecord {
        step,
        provenance,
        ..record
    };
    Ok(ckpt)
}

pub use crate::checkpoint::ace::MAX_HUMAN_STAT;

/// Refuses human normalisation statistics that no human motion gives
/// ([`crate::checkpoint::ace::implausible_human_stat`]), naming the clip with the most extreme value of
/// the offending entry, before anything is trained or saved with them.
fn check_human_stats(humans: &HumanSet, stats: &HumanStats) -> Result<(), LearnError> {
    let Some(k) = crate::checkpoint::ace::implausible_human_stat(&stats.mean, &stats.std) else { return Ok(()) };
    let worst = humans
        .train_clips()
        .map(|c| (c, c.states.iter().map(|s| s[k].abs()).fold(0.0f32, |a, b| if b.is_nan() || b > a { b } else { a })))
        .max_by(|a, b| a.1.total_cmp(&b.1));
    Err(LearnError::Data(format!(
        "the human clips' x^h entry {k} has mean {} and standard deviation {} (at most {MAX_HUMAN_STAT} is plausible){}; \
         nothing was trained or saved",
        stats.mean[k],
        stats.std[k],
        worst.map_or(String::new(), |(c, v)| format!(": {} reaches {v}", c.path.display()))
    )))
}

/// Shared inputs of the ACE tests: the bundled clips as a human set and a small ACE run on the small
/// Spot prior of [`super::prior::test_support`], trained once per test process.
#[cfg(test)]
pub(crate) mod test_support {
    use std::path::PathBuf;
    use std::sync::OnceLock;

    use super::*;
    use crate::correspondence::EndEffectorStats;
    use crate::features::character_body_length;
    use crate::human_set::HumanSetOptions;
    use crate::learn::prior::DeviceChoice;
    use crate::learn::prior::test_support::{scratch_dir, spot, trained_spot_dir};

    /// The bundled clips (`assets/motions`), all for training.
    pub(crate) fn bundled_humans() -> &'static HumanSet {
        static SET: OnceLock<HumanSet> = OnceLock::new();
        SET.get_or_init(|| {
            let folder = Path::new(env!("CARGO_MANIFEST_DIR")).join("../assets/motions");
            let opts = HumanSetOptions {
                held_out_fraction: 0.0,
                ..HumanSetOptions::default()
            };
            HumanSet::load(&folder, &opts, &mut |_| {}).unwrap()
        })
    }

    /// The automatic correspondence of the test Spot dataset and the bundled clips.
    pub(crate) fn spot_correspondence() -> Correspondence {
        let (tree, morph, set) = spot();
        let body = character_body_length(tree, morph);
        let mut human = EndEffectorStats::human();
        for c in &bundled_humans().clips {
            human.add_human_states(&c.states, c.body_length);
        }
        Correspondence::automatic(&EndEffectorStats::from_motion_set(set, body), &human).unwrap()
    }

    /// Small networks, a learning rate for short runs.
    pub(crate) fn tiny_config(steps: usize) -> AceConfig {
        AceConfig {
            generator_hidden: vec![64, 64],
            discriminator_hidden: vec![64, 64],
            batch_size: 32,
            window: 6,
            steps,
            checkpoint_every: 50,
            generator_lr: 1e-3,
            discriminator_lr: 1e-3,
            device: DeviceChoice::Cpu,
            ..AceConfig::default()
        }
    }

    /// Trains [`tiny_config`] for `steps` steps in `dir`.
    pub(crate) fn train_in(
        dir: &Path,
        cfg: &AceConfig,
    ) -> Result<(AceCheckpoint, Vec<AceProgress>), LearnError> {
        train_in_with(dir, cfg, &spot_correspondence())
    }

    /// [`train_in`] with another correspondence.
    pub(crate) fn train_in_with(
        dir: &Path,
        cfg: &AceConfig,
        corr: &Correspondence,
    ) -> Result<(AceCheckpoint, Vec<AceProgress>), LearnError> {
        with_spot_inputs_for("train_ace", corr, |inputs| {
            let mut reports = Vec::new();
            let ckpt = train_ace(inputs, cfg, dir, &mut |p| reports.push(p.clone()))?;
            Ok((ckpt, reports))
        })
    }

    /// Calls `f` with the inputs of the test Spot: its trained prior and dataset, the bundled clips,
    /// their automatic correspondence, provenance `{"test": test}`.
    pub(crate) fn with_spot_inputs<T>(test: &str, f: impl FnOnce(&AceInputs<'_>) -> T) -> T {
        with_spot_inputs_for(test, &spot_correspondence(), f)
    }

    /// [`with_spot_inputs`] with correspondence `corr`.
    pub(crate) fn with_spot_inputs_for<T>(test: &str, corr: &Correspondence, f: impl FnOnce(&AceInputs<'_>) -> T) -> T {
        let (tree, morph, set) = spot();
        let prior = PriorCheckpoint::load(trained_spot_dir(), Device::Cpu).unwrap();
        let provenance = serde_json::json!({ "test": test });
        f(&AceInputs {
            prior: &prior,
            dataset: set,
            tree,
            morph,
            humans: bundled_humans(),
            correspondence: corr,
            character_body_length: character_body_length(tree, morph),
            human_body_length: None,
            speed_scale: crate::dataset::speed_scale(tree, morph, &set.config).unwrap(),
            provenance: &provenance,
        })
    }

    /// A run directory holding 100 steps of [`tiny_config`] (trained once per process).
    pub(crate) fn trained_ace_dir() -> &'static Path {
        static DIR: OnceLock<PathBuf> = OnceLock::new();
        DIR.get_or_init(|| {
            let dir = scratch_dir("trained_ace");
            train_in(&dir, &tiny_config(100)).unwrap();
            dir
        })
    }
}

#[cfg(test)]
mod tests {
    use super::test_support::*;
    use super::*;
    use crate::learn::ace::{DISCRIMINATOR_FILE, GENERATOR_FILE, read_record};
    use crate::learn::prior::test_support::{assert_weights, scratch_dir};

    /// `walk.bvh` with its root raised 5 km (5e5 cm: within the importer's bound of 10 km) from
    /// frame `from` on.
    fn walk_raised_from(from: usize) -> String {
        let text = fs::read_to_string(Path::new(env!("CARGO_MANIFEST_DIR")).join("../assets/motions/walk.bvh")).unwrap();
        let (head, motion) = text.split_once("Frame Time: 0.033333\n").unwrap();
        let lines: Vec<String> = motion
            .lines()
            .filter(|l| !l.trim().is_empty())
            .enumerate()
            .map(|(f, l)| {
                let mut v: Vec<f32> = l.split_whitespace().map(|x| x.parse().unwrap()).collect();
                if f >= from {
                    v[1] += 5e5; // the root's Yposition (the clip is y-up, in centimetres)
                }
                v.iter().map(f32::to_string).collect::<Vec<_>>().join(" ")
            })
            .collect();
        format!("{head}Frame Time: 0.033333\n{}\n", lines.join("\n"))
    }

    #[test]
    fn implausible_human_statistics_are_refused_naming_the_clip() {
        // The bundled clips are plausible.
        let bundled = bundled_humans();
        check_human_stats(bundled, &bundled.train_statistics()).unwrap();
        // A clip 5 km up in half its frames imports (each frame is within 10 km) but its root height
        // makes the training statistics absurd: refused, naming the entry and the clip.
        let dir = scratch_dir("human_stats");
        fs::copy(Path::new(env!("CARGO_MANIFEST_DIR")).join("../assets/motions/walk.bvh"), dir.join("walk.bvh")).unwrap();
        fs::write(dir.join("high.bvh"), walk_raised_from(75)).unwrap();
        let opts = crate::human_set::HumanSetOptions {
            held_out_fraction: 0.0,
            ..Default::default()
        };
        let set = HumanSet::load(&dir, &opts, &mut |_| {}).unwrap();
        assert!(set.skipped.is_empty(), "{:?}", set.skipped.iter().map(|s| &s.error).collect::<Vec<_>>());
        let stats = set.train_statistics();
        let high = set.clips.iter().find(|c| c.relative == "high.bvh").unwrap();
        let reach = high.states.iter().map(|s| s[0].abs()).fold(0.0f32, f32::max);
        assert!(stats.mean[0] > MAX_HUMAN_STAT && reach > 4_000.0, "{} {reach}", stats.mean[0]);
        assert_eq!(
            check_human_stats(&set, &stats).unwrap_err().to_string(),
            format!(
                "invalid training data: the human clips' x^h entry 0 has mean {} and standard deviation {} (at most \
                 1000 is plausible): {} reaches {reach}; nothing was trained or saved",
                stats.mean[0],
                stats.std[0],
                high.path.display()
            )
        );
        fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn fine_tuning_continues_the_networks_under_new_weights_and_mapping() {
        let from = trained_ace_dir();
        let prior = PriorCheckpoint::load(from, Device::Cpu).unwrap();
        let before = AceCheckpoint::load(from, prior.prior.latent_dim(), &prior.mask, Device::Cpu, true).unwrap();
        let dir = scratch_dir("fine_tune");
        let mut cfg = tiny_config(before.record.step + 10);
        cfg.w_fea = 30.0;
        cfg.feature_weights.ee_positions = 0.5;
        // Map every character end effector to the head: a change the record must keep.
        let mut corr = spot_correspondence();
        let overrides: Vec<_> = (0..corr.character_links.len()).map(|i| (i, Some(crate::human::EndEffector::Head))).collect();
        corr = corr.with_overrides(&overrides).unwrap();
        let load = || AceCheckpoint::load(from, prior.prior.latent_dim(), &prior.mask, Device::Cpu, true).unwrap();
        start_fine_tune(&prior, load(), from, &dir, &cfg, &corr).unwrap();
        let (tuned, reports) = train_in_with(&dir, &cfg, &corr).unwrap();
        assert_eq!(reports.len(), 10, "continues from step {}", before.record.step);
        assert_eq!(tuned.record.step, before.record.step + 10);
        assert_eq!(tuned.record.config.w_fea, 30.0);
        assert_eq!(tuned.record.correspondence, corr);
        // Started from the trained generator, not afresh: its first loss is the trained one's level.
        let fresh = scratch_dir("fine_tune_fresh");
        let (_, fresh_reports) = train_in_with(&fresh, &tiny_config(10), &corr).unwrap();
        assert_ne!(reports[0].fea, fresh_reports[0].fea);
        // Nothing is overwritten: a folder with a whole checkpoint, or with a prior alone.
        let err = start_fine_tune(&prior, load(), from, &dir, &cfg, &corr).unwrap_err();
        assert!(err.to_string().contains("already holds a checkpoint"), "{err}");
        let prior_only = scratch_dir("fine_tune_prior_only");
        prior.save(&prior_only).unwrap();
        let err = start_fine_tune(&prior, load(), from, &prior_only, &cfg, &corr).unwrap_err();
        assert!(err.to_string().contains("already holds a checkpoint"), "{err}");
        fs::remove_dir_all(&prior_only).unwrap();
        let mut wider = cfg.clone();
        wider.generator_hidden = vec![32];
        let err = start_fine_tune(&prior, load(), from, &scratch_dir("fine_tune_wider"), &wider, &corr).unwrap_err();
        assert!(err.to_string().contains("generator_hidden"), "{err}");
        fs::remove_dir_all(&dir).unwrap();
        fs::remove_dir_all(&fresh).unwrap();
    }

    fn read_losses(dir: &Path) -> Vec<Vec<f64>> {
        let text = fs::read_to_string(dir.join(LOSSES_FILE)).unwrap();
        let mut lines = text.lines();
        assert_eq!(lines.next().unwrap(), HEADER);
        lines
            .map(|l| l.split(',').map(|v| v.parse::<f64>().unwrap()).collect())
            .collect()
    }

    /// The ablations of the paper's Table 1: with one weight zero, the other term alone drives G, its
    /// loss falls, and the zero-weighted term is still logged (finite) without entering the loss.
    /// L_adv alone is a game whose loss need not fall while D learns too (it hovers near log 2), so
    /// for that ablation D is held fixed here: G must then learn to fool it, from fresh dataset states
    /// at every step (on its own rollouts the states it is judged on move as it learns).
    #[test]
    fn each_ablation_lowers_its_own_loss() {
        for (name, column) in [("w_fea", 5), ("w_adv", 6)] {
            let mut cfg = tiny_config(60);
            if name == "w_fea" {
                (cfg.w_fea, cfg.discriminator_steps, cfg.rollout_windows) = (0.0, 0, 1);
            } else {
                cfg.w_adv = 0.0;
            }
            let dir = scratch_dir(&format!("ablation_{name}"));
            let (_, reports) = train_in(&dir, &cfg).unwrap();
            let rows = read_losses(&dir);
            assert!(rows.iter().flatten().all(|v| v.is_finite()), "{name} = 0");
            // g_loss is the remaining term alone.
            for (r, p) in rows.iter().zip(&reports) {
                let own = if name == "w_fea" { cfg.w_adv * p.adv } else { cfg.w_fea * p.fea };
                assert!((r[4] - own).abs() <= 1e-5 * own.abs().max(1.0), "{name} = 0: g_loss {} vs {own}", r[4]);
            }
            let mean = |r: &[Vec<f64>]| r.iter().map(|r| r[column]).sum::<f64>() / r.len() as f64;
            let (first, last) = (mean(&rows[..10]), mean(&rows[50..]));
            println!("{name} = 0: own loss, first 10 steps {first:.4}, last 10 steps {last:.4}");
            assert!(last < first, "{name} = 0: own loss {first} → {last}");
            fs::remove_dir_all(&dir).unwrap();
        }
        let mut both = tiny_config(1);
        (both.w_adv, both.w_fea) = (0.0, 0.0);
        assert!(both.check().unwrap_err().to_string().contains("both zero"));
    }

    #[test]
    fn a_short_run_lowers_the_feature_loss_and_writes_a_checkpoint() {
        let dir = trained_ace_dir();
        let rows = read_losses(dir);
        assert_eq!(rows.len(), 100);
        assert!(
            rows.iter()
                .enumerate()
                .all(|(i, r)| r[0] == i as f64 && r.len() == 10)
        );
        assert!(rows.iter().flatten().all(|v| v.is_finite()));
        let fea = |r: &[Vec<f64>]| r.iter().map(|r| r[6]).sum::<f64>() / r.len() as f64;
        let (first, last) = (fea(&rows[..10]), fea(&rows[90..]));
        println!("L_fea: first 10 steps {first:.4}, last 10 steps {last:.4}");
        assert!(last < 0.85 * first, "L_fea {first} → {last}");
        // D's probabilities are probabilities, and the penalty is non-negative.
        assert!(
            rows.iter()
                .all(|r| (0.0..=1.0).contains(&r[7]) && (0.0..=1.0).contains(&r[8]) && r[3] >= 0.0)
        );
        for f in [
            ACE_FILE,
            "generator.safetensors",
            "discriminator.safetensors",
            CONFIG_FILE,
        ] {
            assert!(dir.join(f).is_file(), "{f} missing");
        }
        let record = read_record(&dir).unwrap();
        assert_eq!(record.step, 100);
        assert_eq!(record.config, tiny_config(100));
        assert_eq!(record.human_split.train.len(), 3);
        assert_eq!(record.provenance["test"], "train_ace");
        let corr = spot_correspondence();
        assert_eq!(
            (&record.correspondence.mapping, record.correspondence.source),
            (&corr.mapping, corr.source)
        );
    }

    #[test]
    fn centred_human_features_share_the_character_datasets_mean_pose() {
        let corr = spot_correspondence();
        let (tree, morph, set) = crate::learn::prior::test_support::spot();
        let body = crate::features::character_body_length(tree, morph);
        let character_mean = mean_features(
            (0..set.len()).map(|i| character_features(&set.layout, set.state(i), body, &corr.mapping)),
        );
        let layout = FeatureLayout::new(&corr.mapping);
        let (plain, centred) = with_spot_inputs("centring", |inputs| {
            let stats = inputs.humans.train_statistics();
            let w = |centre| {
                let matching = FeatureMatching { centre, speed: false };
                human_windows(inputs, &stats, &layout, 6, matching, Device::Cpu).unwrap()
            };
            (w(false), w(true))
        });
        let rows = |t: &Tensor| -> Vec<Vec<f32>> {
            let v = Vec::<f32>::try_from(t.flatten(0, -1)).unwrap();
            v.chunks(layout.dim()).map(<[f32]>::to_vec).collect()
        };
        let (plain_rows, centred_rows) = (rows(&plain.features), rows(&centred.features));
        let centred_mean = mean_features(&centred_rows);
        assert!(plain.offset.is_empty());
        assert_eq!(centred.offset.len(), layout.dim());
        for i in layout.root_height().chain(layout.ee_positions()) {
            // The human's mean height and end-effector positions become the character's …
            assert!(
                (centred_mean[i] - character_mean[i]).abs() < 1e-4,
                "entry {i}: {} vs the dataset's {}",
                centred_mean[i],
                character_mean[i]
            );
        }
        // … by a real shift (a human's feet stand under its pelvis, Spot's ahead of and behind it) …
        let ee = layout.ee_positions();
        assert!(centred.offset[ee].iter().any(|o| o.abs() > 0.1), "offset {:?}", centred.offset);
        // … that leaves orientation and velocities alone and moves every frame alike.
        for i in layout.root_orientation().start..layout.root_angular_velocity().end {
            assert_eq!(centred.offset[i], 0.0);
        }
        for (p, c) in plain_rows.iter().zip(&centred_rows).step_by(97) {
            for i in 0..layout.dim() {
                assert!((c[i] - p[i] - centred.offset[i]).abs() < 1e-5);
            }
        }
        // Training records the offset that scoring applies.
        let record = read_record(trained_ace_dir()).unwrap();
        assert_eq!(record.feature_offset, centred.offset);
    }

    #[test]
    fn human_speeds_are_compared_at_the_datasets_speed_scale() {
        let corr = spot_correspondence();
        let layout = FeatureLayout::new(&corr.mapping);
        let (plain, matched, scale, character_body) = with_spot_inputs("speed", |inputs| {
            let stats = inputs.humans.train_statistics();
            let w = |speed| {
                let matching = FeatureMatching { centre: false, speed };
                human_windows(inputs, &stats, &layout, 6, matching, Device::Cpu).unwrap()
            };
            (w(false), w(true), inputs.speed_scale, inputs.character_body_length)
        });
        assert_eq!(plain.speed_scale, None);
        assert_eq!(matched.speed_scale, Some(scale));
        let rows = |t: &Tensor| Vec::<f32>::try_from(t.flatten(0, -1)).unwrap();
        let (p, m) = (rows(&plain.features), rows(&matched.features));
        let velocity = layout.root_linear_velocity();
        let speed = |r: &[f32]| r[velocity.clone()].iter().map(|v| v * v).sum::<f32>().sqrt();
        let bodies: Vec<f32> = bundled_humans().train_clips().map(|c| c.body_length).collect();
        let mut moving = 0;
        for (pr, mr) in p.chunks(layout.dim()).zip(m.chunks(layout.dim())) {
            for i in (0..layout.dim()).filter(|i| !velocity.contains(i)) {
                assert_eq!(pr[i], mr[i], "entry {i} is not a velocity and must not change");
            }
            if speed(pr) > 0.1 {
                moving += 1;
                // One clip's s·H/L: Spot's legs are long for its height, so its dataset moves 1.5–2
                // times as many body lengths per second as a human at the same commanded speed.
                let f = speed(mr) / speed(pr);
                let of_a_clip = bodies.iter().any(|&h| (f - human_speed_factor(scale, h, character_body)).abs() < 1e-3);
                assert!(of_a_clip && (1.4..2.0).contains(&f), "factor {f}");
            }
        }
        assert!(moving > 0, "the bundled walk moves");
        // Training records the scale that scoring applies.
        let record = read_record(trained_ace_dir()).unwrap();
        assert_eq!(record.speed_scale, Some(scale));
    }

    #[test]
    fn runs_before_kinematic_features_read_as_trained_on_the_predicted_entries() {
        let record = read_record(trained_ace_dir()).unwrap();
        assert!(record.config.kinematic_features, "a new run reads Ψ's end effectors from the joints");
        // The same record without the setting, as every `ace.json` before it was written.
        let mut v: Value = serde_json::from_slice(&fs::read(trained_ace_dir().join(ACE_FILE)).unwrap()).unwrap();
        assert!(record.config.kinematic_root, "a new run reads Ψ's root velocities from the root's motion");
        v["config"].as_object_mut().unwrap().remove("kinematic_features").unwrap();
        v["config"].as_object_mut().unwrap().remove("kinematic_root").unwrap();
        let dir = scratch_dir("ace_before_kinematic");
        fs::write(dir.join(ACE_FILE), serde_json::to_vec(&v).unwrap()).unwrap();
        let old = read_record(&dir).unwrap();
        assert!(!old.config.kinematic_features && !old.config.kinematic_root);
        assert_eq!(AceConfig { kinematic_features: true, kinematic_root: true, ..old.config }, record.config);
        // A partial configuration a user writes gets the default.
        let partial = toml::from_str::<AceConfig>("w_fea = 2.0").unwrap();
        assert!(partial.kinematic_features && partial.kinematic_root);
        fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn a_run_directory_gets_the_prior_unless_it_holds_that_one() {
        let prior = PriorCheckpoint::load(crate::learn::prior::test_support::trained_spot_dir(), Device::Cpu).unwrap();
        let dir = scratch_dir("place_prior");
        prior.save(&dir).unwrap();
        // The same prior is kept as it is; one trained to another step (all else equal) is replaced.
        let config = dir.join(CONFIG_FILE);
        let mut record: serde_json::Value = serde_json::from_slice(&fs::read(&config).unwrap()).unwrap();
        record["step"] = (prior.step + 1).into();
        fs::write(&config, serde_json::to_vec_pretty(&record).unwrap()).unwrap();
        assert_eq!(PriorCheckpoint::load(&dir, Device::Cpu).unwrap().step, prior.step + 1);
        place_prior(&prior, &dir).unwrap();
        assert_eq!(PriorCheckpoint::load(&dir, Device::Cpu).unwrap().step, prior.step, "the other prior was kept");
        fs::remove_dir_all(&dir).unwrap();
    }

    /// Both optimisers take the configured Adam β₁ (a GAN's 0.5, not tch's default 0.9): the same short
    /// run repeated ends with the same networks, and with another β₁ with other ones (β₁ acts from
    /// the second step on: the first, bias-corrected, is the same under any β₁).
    #[test]
    fn the_optimisers_take_the_configured_adam_beta1() {
        let run = |beta1: f64, name: &str| {
            let dir = scratch_dir(name);
            let cfg = AceConfig { adam_beta1: beta1, ..tiny_config(3) };
            let (ckpt, _) = train_in(&dir, &cfg).unwrap();
            fs::remove_dir_all(&dir).unwrap();
            let d = ckpt.discriminator.as_ref().unwrap();
            [ckpt.generator.var_store(), d.var_store()].map(|vs| {
                let mut v: Vec<(String, Tensor)> = vs.variables().into_iter().collect();
                v.sort_by(|a, b| a.0.cmp(&b.0));
                v
            })
        };
        let same = |a: &[(String, Tensor)], b: &[(String, Tensor)]| a.iter().zip(b).all(|((n, x), (m, y))| n == m && x.equal(y));
        let (gan, again, default) = (run(0.5, "beta1_a"), run(0.5, "beta1_b"), run(0.9, "beta1_c"));
        for (net, name) in ["generator", "discriminator"].iter().enumerate() {
            assert!(same(&gan[net], &again[net]), "the {name}: a repeated run differs");
            assert!(!same(&gan[net], &default[net]), "the {name}: β₁ 0.5 and 0.9 give the same weights");
        }
    }

    #[test]
    fn a_stopped_run_resumes_from_its_checkpoint() {
        let dir = scratch_dir("ace_resume");
        let (_, first) = train_in(&dir, &tiny_config(60)).unwrap();
        assert_eq!(first.len(), 60);
        // Pretend the run died at step 65, after its step-60 checkpoint: its later rows are redone.
        let mut log = fs::OpenOptions::new()
            .append(true)
            .open(dir.join(LOSSES_FILE))
            .unwrap();
        for step in 60..65 {
            writeln!(log, "{step},-1,-1,-1,-1,-1,-1,-1,-1,999").unwrap();
        }
        drop(log);
        let (ckpt, second) = train_in(&dir, &tiny_config(80)).unwrap();
        assert_eq!(second.first().map(|p| p.step), Some(61));
        assert_eq!(second.len(), 20);
        assert_eq!(ckpt.record.step, 80);
        let rows = read_losses(&dir);
        assert_eq!(
            rows.iter().map(|r| r[0] as usize).collect::<Vec<_>>(),
            (0..80).collect::<Vec<_>>()
        );
        assert!(
            rows.iter().all(|r| r[1] >= 0.0),
            "the rows after the checkpoint were replaced"
        );
        assert!(
            rows.windows(2).all(|w| w[1][9] >= w[0][9]),
            "seconds are cumulative"
        );
        // Resuming starts from the saved networks, not from fresh ones with the step count kept.
        with_spot_inputs("ace_resume", |inputs| {
            let cfg = tiny_config(90);
            let stats = inputs.humans.train_statistics();
            let psi = Psi::new(&inputs.prior.character.layout, &inputs.correspondence.mapping, inputs.character_body_length, Device::Cpu);
            let humans = human_windows(inputs, &stats, psi.layout(), cfg.window, FeatureMatching::of(&cfg), Device::Cpu).unwrap();
            let resumed = start_or_resume(inputs, &cfg, &stats, &humans, &dir, Device::Cpu).unwrap();
            assert_eq!(resumed.record.step, 80);
            // The resumed record names this run's provenance; a resume that brings none keeps the stored.
            assert_eq!(resumed.record.provenance, serde_json::json!({ "test": "ace_resume" }));
            let none = serde_json::Value::Null;
            let anonymous = AceInputs { provenance: &none, ..*inputs };
            let kept = start_or_resume(&anonymous, &cfg, &stats, &humans, &dir, Device::Cpu).unwrap();
            assert_eq!(kept.record.provenance, serde_json::json!({ "test": "train_ace" }));
            let d = resumed.discriminator.as_ref().unwrap();
            for (file, vs) in [(GENERATOR_FILE, resumed.generator.var_store()), (DISCRIMINATOR_FILE, d.var_store())] {
                assert_weights(vs, Tensor::read_safetensors(dir.join(file)).unwrap(), &format!("the resumed run against its {file}"));
            }
            // Other human data refuses to resume, each difference alone: the statistics, the body
            // lengths.
            let refused = |e: LearnError| {
                let e = e.to_string();
                assert!(e.contains(&dir.display().to_string()) && e.contains("other human data"), "{e}");
            };
            let mut shifted = stats.clone();
            shifted.mean[0] += 0.5;
            refused(start_or_resume(inputs, &cfg, &shifted, &humans, &dir, Device::Cpu).err().unwrap());
            let longer = AceInputs { character_body_length: inputs.character_body_length * 1.1, ..*inputs };
            refused(start_or_resume(&longer, &cfg, &stats, &humans, &dir, Device::Cpu).err().unwrap());
        });
        // A run with other networks refuses the directory.
        let other = AceConfig {
            generator_hidden: vec![16],
            ..tiny_config(90)
        };
        let e = train_in(&dir, &other).unwrap_err().to_string();
        assert!(
            e.contains(&dir.display().to_string()) && e.contains("another configuration"),
            "{e}"
        );
        fs::remove_dir_all(&dir).unwrap();
    }
}
