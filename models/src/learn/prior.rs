//! The motion prior of ACE (paper §4, §6.4): a conditional VAE in the style of MVAE (Ling et al. 2020).
//!
//! - Encoder c(x^r_{t−1}, x^r_t) → (μ, log σ²) of the latent z (32 values): an [`Mlp`] with leaky ReLU.
//! - Decoder π(z, x^r_{t−1}) → x^r_t: a [`Mann`] (mode-adaptive mixture of experts, ELU) whose gating
//!   network sees `(z, x^r_{t−1})` and whose every layer gets `z` concatenated to its input.
//!
//! Everything works on *normalised* states, `(x − mean) / std` with the dataset's statistics
//! ([`super::checkpoint::Normaliser`]). Entries the [`state_mask`] zeroes (wheel angles) are set to 0 in
//! every network input and in the decoder's output, and the loss ignores them: a wheel's angle is a
//! function of the base motion and is recomputed from it after decoding.
//!
//! The decoder's output is clamped to per-entry bounds ([`StateBounds`]: the range the training data
//! span, widened by [`PriorConfig::bound_margin`] of its width on each side). The clamp is a safety net
//! for long autoregressive rollouts and for latents a generator invents: an ELU network extrapolates
//! almost linearly far from its data, so a state that strays out of the data's range can otherwise grow
//! without limit. Gradients pass through the clamp as if it were not there (straight-through), so
//! training is not starved where it applies.
//!
//! # Training ([`train_prior`])
//! Each optimiser step draws `batch_size` windows of `rollout + 1` consecutive frames, each inside one
//! episode, and runs the VAE along every window: at step t the encoder sees (previous, x_t), z is drawn
//! by the reparameterisation trick, the decoder predicts x_t from (z, previous), and the loss is the
//! masked mean squared reconstruction error plus β times the KL divergence to N(0, I) (both per entry,
//! averaged over the window). The "previous" state of the next step is, per window, the model's own
//! prediction with the scheduled probability ([`SamplingSchedule`]) and the data otherwise (scheduled
//! sampling): the prior learns to recover from its own errors, which is what keeps long autoregressive
//! rollouts stable. The fed-back prediction is *detached*, as in MVAE: the point is to train on the
//! states the model visits, and back-propagating through the whole rollout would make every step's
//! gradient depend on a product of decoder Jacobians, which is slower and less stable to train.
//!
//! Randomness (weight initialisation, windows, z noise, sampling coins) comes from PCG-64 generators
//! seeded with [`PriorConfig::seed`] (and the step number), never from libtorch's process-wide
//! generator, so the same configuration and data give the same weights on the CPU whatever else runs
//! in the process.
//!
//! The run directory is itself a checkpoint ([`PriorCheckpoint`], saved every
//! [`PriorConfig::checkpoint_every`] steps and at the end) plus [`LOSSES_FILE`], one row per optimiser
//! step: `step` (0-based), `total`, `reconstruction`, `kl` (before weighting), `sampling_probability` and
//! `seconds` of training so far. A run started in a directory that already holds a checkpoint of the
//! same configuration (but for `steps`, `checkpoint_every`, `device`) and data resumes from it: weights
//! and step are restored, log rows after the checkpoint are dropped, and the windows continue as in an
//! uninterrupted run, but Adam's moment estimates restart from zero (they are not saved), so a resumed
//! run is not bit-identical to an uninterrupted one. A checkpoint that has reached `steps` is returned
//! without training; one of another configuration or data is refused.

use std::fs;
use std::io::Write;
use std::ops::Range;
use std::path::Path;
use std::time::Instant;

use rand::{Rng, RngExt, SeedableRng};
use rand_pcg::Pcg64;
use serde_json::Value;
use tch::nn::OptimizerConfig;
use tch::{Device, Kind, Tensor, nn};

use super::checkpoint::{CONFIG_FILE, CharacterInfo, LearnError, Normaliser, PriorCheckpoint, StateBounds};
pub use crate::checkpoint::prior::{DeviceChoice, PriorConfig, SamplingSchedule, state_mask};
use super::files::{open_losses, step_rng};
use super::nets::{Activation, Mann, MannSpec, Mlp};
use crate::dataset::MotionSet;

/// Name of the loss log in a run directory.
pub const LOSSES_FILE: &str = "prior_losses.csv";

/// The columns of [`LOSSES_FILE`]; `seconds` is column [`SECONDS_COLUMN`].
const HEADER: &str = "step,total,reconstruction,kl,sampling_probability,seconds";
const SECONDS_COLUMN: usize = 5;

impl DeviceChoice {
    /// The libtorch device.
    pub fn device(self) -> Device {
        match self {
            DeviceChoice::Auto => Device::cuda_if_available(),
            DeviceChoice::Cpu => Device::Cpu,
            DeviceChoice::Cuda(n) => Device::Cuda(n),
        }
    }

    /// Fails, naming the `device` field and what is valid, unless libtorch can use this device here:
    /// `"auto"` and `"cpu"` always, `"cuda:N"` when libtorch sees more than N CUDA devices. Training
    /// checks it before any work (libtorch aborts the process on a device it does not have); a stored
    /// checkpoint's device is not checked when it is only loaded.
    pub fn check_available(self) -> Result<(), LearnError> {
        let DeviceChoice::Cuda(n) = self else { return Ok(()) };
        let count = super::cuda_devices();
        if n < count {
            return Ok(());
        }
        let seen = match count {
            0 => "no CUDA device".to_string(),
            1 => "1 CUDA device (\"cuda:0\")".to_string(),
            c => format!("{c} CUDA devices (\"cuda:0\" to \"cuda:{}\")", c - 1),
        };
        Err(LearnError::Config(format!(
            "`device` = \"cuda:{n}\" is not available: libtorch sees {seen} on this machine; use \"cpu\" or \"auto\"{}",
            if count > 0 { " or one of those" } else { "" }
        )))
    }
}

/// The losses of one transition, as tensors (scalars but for `prediction`).
#[derive(Debug)]
pub struct PriorLoss {
    /// `recon + β·kl_loss`.
    pub total: Tensor,
    /// Mean squared error over the modelled entries.
    pub recon: Tensor,
    /// KL divergence of the posterior to N(0, I), averaged over batch and latent entries.
    pub kl: Tensor,
    /// The KL term as the loss counts it: `kl` with free bits ([`PriorConfig::free_bits`]).
    pub kl_loss: Tensor,
    /// The decoder's output `[B, D]` (normalised, masked entries 0).
    pub prediction: Tensor,
}

/// The motion prior: encoder c and decoder π with their own `VarStore` (variables under `encoder.` and
/// `decoder.`). See the module docs.
#[derive(Debug)]
pub struct MotionPrior {
    vs: nn::VarStore,
    encoder: Mlp,
    decoder: Mann,
    /// `[1, D]`; 1 for modelled entries.
    mask: Tensor,
    /// `[1, D]` each: bounds of the decoder's output.
    lo: Tensor,
    hi: Tensor,
    config: PriorConfig,
    state_dim: usize,
}

impl MotionPrior {
    /// A freshly initialised prior for states of width `state_dim` on `device` (`cfg.device` is not
    /// used), with every entry modelled and practically unbounded output (see [`MotionPrior::set_mask`]
    /// and [`MotionPrior::set_bounds`]). Initialisation is seeded with `cfg.seed`.
    pub fn new(cfg: &PriorConfig, state_dim: usize, device: Device) -> MotionPrior {
        let vs = nn::VarStore::new(device);
        let mut rng = Pcg64::seed_from_u64(cfg.seed);
        let d = state_dim;
        let encoder = Mlp::new(
            &(vs.root() / "encoder"),
            2 * d,
            &cfg.encoder_hidden,
            Activation::LEAKY_RELU,
            Some(2 * cfg.latent),
            &mut rng,
        );
        let spec = MannSpec {
            input: d,
            latent: cfg.latent,
            output: d,
            hidden: cfg.decoder_hidden.clone(),
            experts: cfg.experts,
            gating_input: cfg.latent + d,
            gating_hidden: cfg.gating_hidden.clone(),
        };
        let decoder = Mann::new(&(vs.root() / "decoder"), &spec, &mut rng);
        MotionPrior {
            mask: Tensor::ones([1, d as i64], (Kind::Float, device)),
            lo: Tensor::full([1, d as i64], -f64::from(f32::MAX), (Kind::Float, device)),
            hi: Tensor::full([1, d as i64], f64::from(f32::MAX), (Kind::Float, device)),
            vs,
            encoder,
            decoder,
            config: cfg.clone(),
            state_dim,
        }
    }

    /// Sets which entries are modelled ([`state_mask`]); `mask` has one value per state entry.
    pub fn set_mask(&mut self, mask: &[f32]) -> Result<(), LearnError> {
        if mask.len() != self.state_dim {
            return Err(LearnError::Data(format!(
                "the mask has {} entries, the state has {}",
                mask.len(),
                self.state_dim
            )));
        }
        self.mask = Tensor::from_slice(mask).view([1, -1]).to_device(self.vs.device());
        Ok(())
    }

    /// Sets the bounds the decoder's output is clamped to.
    pub fn set_bounds(&mut self, bounds: &StateBounds) -> Result<(), LearnError> {
        if bounds.lo.len() != self.state_dim || bounds.hi.len() != self.state_dim {
            return Err(LearnError::Data(format!(
                "the bounds have {} and {} entries, the state has {}",
                bounds.lo.len(),
                bounds.hi.len(),
                self.state_dim
            )));
        }
        let device = self.vs.device();
        self.lo = Tensor::from_slice(&bounds.lo).view([1, -1]).to_device(device);
        self.hi = Tensor::from_slice(&bounds.hi).view([1, -1]).to_device(device);
        Ok(())
    }

    /// The output bounds, `[1, D]` each.
    pub fn bounds(&self) -> (&Tensor, &Tensor) {
        (&self.lo, &self.hi)
    }

    /// The output bounds as values.
    pub fn state_bounds(&self) -> StateBounds {
        let values =
            |t: &Tensor| Vec::<f32>::try_from(t.to_device(Device::Cpu).flatten(0, -1)).expect("f32 bounds");
        StateBounds {
            lo: values(&self.lo),
            hi: values(&self.hi),
        }
    }

    /// The mask as a `[1, D]` tensor.
    pub fn mask(&self) -> &Tensor {
        &self.mask
    }

    /// The configuration it was built with.
    pub fn config(&self) -> &PriorConfig {
        &self.config
    }

    /// Width of z.
    pub fn latent_dim(&self) -> usize {
        self.config.latent
    }

    /// Width of x^r.
    pub fn state_dim(&self) -> usize {
        self.state_dim
    }

    /// The device its variables live on.
    pub fn device(&self) -> Device {
        self.vs.device()
    }

    /// The variables.
    pub fn var_store(&self) -> &nn::VarStore {
        &self.vs
    }

    /// The variables, mutably (to load, freeze, move).
    pub fn var_store_mut(&mut self) -> &mut nn::VarStore {
        &mut self.vs
    }

    /// Stops tracking gradients of its variables (ACE trains G through a fixed π). Gradients still flow
    /// through the networks to their inputs.
    pub fn freeze(&mut self) {
        self.vs.freeze();
    }

    /// Encoder: `(μ, log σ²)`, each `[B, latent]`, of z for the transition `prev → cur` (`[B, D]`
    /// normalised).
    pub fn encode(&self, prev: &Tensor, cur: &Tensor) -> (Tensor, Tensor) {
        let input = Tensor::cat(&[prev * &self.mask, cur * &self.mask], 1);
        let out = self.encoder.forward(&input);
        let latent = self.config.latent as i64;
        (out.narrow(1, 0, latent), out.narrow(1, latent, latent))
    }

    /// Decoder π: the next normalised state `[B, D]` from `z: [B, latent]` and `prev: [B, D]`, clamped
    /// to the bounds (gradients pass as if unclamped), masked entries 0.
    pub fn decode(&self, z: &Tensor, prev: &Tensor) -> Tensor {
        let prev = prev * &self.mask;
        let gate = Tensor::cat(&[z, &prev], 1);
        let y = self.decoder.forward(z, &prev, &gate) * &self.mask;
        // Straight-through: the value is the clamped one exactly (y − y.detach() is 0), the gradient y's.
        y.detach().maximum(&self.lo).minimum(&self.hi) + (&y - y.detach())
    }

    /// The blending coefficients α `[B, K]` the decoder uses for `(z, prev)`.
    pub fn expert_coefficients(&self, z: &Tensor, prev: &Tensor) -> Tensor {
        let prev = prev * &self.mask;
        self.decoder.coefficients(&Tensor::cat(&[z, &prev], 1))
    }

    /// `μ + exp(½ log σ²)·noise`, the reparameterised sample of z.
    pub fn reparameterise(mu: &Tensor, logvar: &Tensor, noise: &Tensor) -> Tensor {
        mu + (logvar * 0.5).exp() * noise
    }

    /// The VAE loss of the transition `prev → cur` (`[B, D]` normalised), with `noise: [B, latent]`
    /// standard normal draws for the reparameterisation. Masked entries do not contribute.
    pub fn loss(&self, prev: &Tensor, cur: &Tensor, noise: &Tensor) -> PriorLoss {
        let (mu, logvar) = self.encode(prev, cur);
        let z = Self::reparameterise(&mu, &logvar, noise);
        let prediction = self.decode(&z, prev);
        let err = (&prediction - cur * &self.mask).square() * &self.mask;
        let modelled = self.mask.sum(Kind::Float) * cur.size()[0] as f64;
        let recon = err.sum(Kind::Float) / modelled;
        let kl_entries = (&logvar + 1.0 - mu.square() - logvar.exp()) * -0.5;
        let kl = kl_entries.mean(Kind::Float);
        let kl_loss = if self.config.free_bits > 0.0 {
            kl_entries
                .mean_dim(0, false, Kind::Float)
                .clamp_min(self.config.free_bits)
                .mean(Kind::Float)
        } else {
            kl.shallow_clone()
        };
        PriorLoss {
            total: &recon + &kl_loss * self.config.kl_weight,
            recon,
            kl,
            kl_loss,
            prediction,
        }
    }

    /// The fraction of entries of `x: [.., D]` that sit exactly on a bound, over entries whose bounds
    /// differ (a measure of how much the clamp shapes a rollout).
    pub fn at_bounds(&self, x: &Tensor) -> f64 {
        let open = self.hi.gt_tensor(&self.lo);
        let on = (x.eq_tensor(&self.lo).logical_or(&x.eq_tensor(&self.hi))).logical_and(&open);
        let total = open
            .expand_as(x)
            .to_kind(Kind::Float)
            .sum(Kind::Float)
            .double_value(&[]);
        on.to_kind(Kind::Float).sum(Kind::Float).double_value(&[]) / total.max(1.0)
    }

    /// Autoregressive rollout without gradients: from `first: [B, D]` (normalised) and `z: [T, B,
    /// latent]`, the `T` states `[T, B, D]` that follow, each decoded from the one before.
    /// Bounded by construction (the decoder's clamp); [`MotionPrior::at_bounds`] tells how often the
    /// clamp acted.
    pub fn rollout(&self, first: &Tensor, z: &Tensor) -> Tensor {
        tch::no_grad(|| {
            let steps = z.size()[0];
            let mut prev = first.shallow_clone();
            let mut out = Vec::with_capacity(steps as usize);
            for t in 0..steps {
                prev = self.decode(&z.get(t), &prev);
                out.push(prev.shallow_clone());
            }
            Tensor::stack(&out, 0)
        })
    }
}

/// Reported after every optimiser step.
#[derive(Clone, Debug, PartialEq)]
pub struct PriorProgress {
    /// Steps done (1 after the first step).
    pub step: usize,
    /// Steps in the run.
    pub steps: usize,
    /// Total loss of the step.
    pub loss: f64,
    /// Reconstruction part.
    pub recon: f64,
    /// KL part (before weighting by β).
    pub kl: f64,
    /// Probability of feeding back predictions at this step.
    pub sampling_probability: f64,
    /// Seconds of training so far (including earlier sessions of a resumed run).
    pub seconds: f64,
}

/// Trains a motion prior on `set` (see the module docs) in `run_dir`, resuming from the checkpoint
/// there if any. `mask` is [`state_mask`] of the set's character. Returns the trained prior; the final
/// checkpoint is in `run_dir` with a `null` provenance (see [`train_prior_with`]).
pub fn train_prior(
    set: &MotionSet,
    mask: &[f32],
    cfg: &PriorConfig,
    run_dir: &Path,
    progress: &mut dyn FnMut(&PriorProgress),
) -> Result<MotionPrior, LearnError> {
    train_prior_with(set, mask, cfg, run_dir, Value::Null, progress)
}

/// [`train_prior`], recording `provenance` in the checkpoints (a resumed run keeps the stored one when
/// `provenance` is `null`).
pub fn train_prior_with(
    set: &MotionSet,
    mask: &[f32],
    cfg: &PriorConfig,
    run_dir: &Path,
    provenance: Value,
    progress: &mut dyn FnMut(&PriorProgress),
) -> Result<MotionPrior, LearnError> {
    cfg.check()?;
    cfg.device.check_available()?;
    let dim = set.layout.dim();
    if mask.len() != dim {
        return Err(LearnError::Data(format!(
            "the mask has {} entries, the dataset's states have {dim}",
            mask.len()
        )));
    }
    if set.states.len() != set.len() * dim || set.mean.len() != dim || set.std.len() != dim {
        return Err(LearnError::Data(format!(
            "dataset of `{}`: states, mean or std do not have width {dim}",
            set.character
        )));
    }
    let starts = window_starts(&set.episodes, cfg.rollout);
    if starts.is_empty() {
        return Err(LearnError::Data(format!(
            "dataset of `{}`: no episode has the {} frames a window needs",
            set.character,
            cfg.rollout + 1
        )));
    }
    let device = cfg.device.device();
    fs::create_dir_all(run_dir).map_err(|e| LearnError::io(run_dir, e))?;

    let mut ckpt = start_or_resume(set, mask, cfg, run_dir, provenance, device)?;
    if ckpt.step >= cfg.steps {
        return Ok(ckpt.prior);
    }
    let losses_path = run_dir.join(LOSSES_FILE);
    let (mut log, seconds_before) = open_losses(&losses_path, ckpt.step, HEADER, SECONDS_COLUMN)?;

    let stats = Normaliser::of_set(set);
    let data = stats.normalise(&super::rows_to_tensor(
        &set.states.chunks(dim).collect::<Vec<_>>(),
        device,
    )?) * ckpt.prior.mask();
    let mut opt = nn::Adam::default().build(ckpt.prior.var_store(), cfg.learning_rate)?;
    let (b, latent) = (cfg.batch_size, cfg.latent);
    let clock = Instant::now();
    for step in ckpt.step..cfg.steps {
        let p = cfg.sampling.probability(step, cfg.steps);
        let mut rng = step_rng(cfg.seed, 0, step);
        let first: Vec<i64> = (0..b)
            .map(|_| starts[rng.random_range(0..starts.len())] as i64)
            .collect();
        let first = Tensor::from_slice(&first).to_device(device);
        let mut prev = data.index_select(0, &first);
        let mut recon = Tensor::zeros([], (Kind::Float, device));
        let mut kl = Tensor::zeros([], (Kind::Float, device));
        let mut kl_loss = Tensor::zeros([], (Kind::Float, device));
        for t in 1..=cfg.rollout {
            let cur = data.index_select(0, &(&first + t as i64));
            let noise = Tensor::from_slice(&normals(&mut rng, b * latent))
                .view([b as i64, latent as i64])
                .to_device(device);
            let l = ckpt.prior.loss(&prev, &cur, &noise);
            recon += l.recon;
            kl += l.kl;
            kl_loss += l.kl_loss;
            let fed: Vec<f32> = (0..b).map(|_| f32::from(rng.random::<f64>() < p)).collect();
            let fed = Tensor::from_slice(&fed).view([b as i64, 1]).to_device(device);
            prev = l.prediction.detach() * &fed + cur * (1.0 - &fed);
        }
        let recon = recon / cfg.rollout as f64;
        let kl = kl / cfg.rollout as f64;
        let total = &recon + kl_loss / cfg.rollout as f64 * cfg.kl_weight;
        opt.backward_step(&total);

        let report = PriorProgress {
            step: step + 1,
            steps: cfg.steps,
            loss: total.double_value(&[]),
            recon: recon.double_value(&[]),
            kl: kl.double_value(&[]),
            sampling_probability: p,
            seconds: seconds_before + clock.elapsed().as_secs_f64(),
        };
        if !report.loss.is_finite() {
            return Err(LearnError::Data(format!(
                "the loss became {} at step {}; lower the learning rate",
                report.loss, report.step
            )));
        }
        writeln!(
            log,
            "{},{},{},{},{},{:.3}",
            step, report.loss, report.recon, report.kl, p, report.seconds
        )
        .and_then(|_| log.flush())
        .map_err(|e| LearnError::io(&losses_path, e))?;
        progress(&report);
        ckpt.step = step + 1;
        if ckpt.step % cfg.checkpoint_every == 0 || ckpt.step == cfg.steps {
            ckpt.save(run_dir)?;
        }
    }
    Ok(ckpt.prior)
}

/// A new checkpoint for `set`, or the one in `run_dir` when it fits the configuration and data.
fn start_or_resume(
    set: &MotionSet,
    mask: &[f32],
    cfg: &PriorConfig,
    run_dir: &Path,
    provenance: Value,
    device: Device,
) -> Result<PriorCheckpoint, LearnError> {
    let stats = Normaliser::of_set(set);
    let bounds = StateBounds::of_set(set, mask, cfg.bound_margin);
    let character = CharacterInfo::of_set(set);
    if !run_dir.join(CONFIG_FILE).exists() {
        let mut prior = MotionPrior::new(cfg, set.layout.dim(), device);
        prior.set_mask(mask)?;
        prior.set_bounds(&bounds)?;
        return Ok(PriorCheckpoint {
            config: cfg.clone(),
            stats,
            mask: mask.to_vec(),
            character,
            step: 0,
            provenance,
            prior,
        });
    }
    let mut ckpt = PriorCheckpoint::load(run_dir, device)?;
    ckpt.check_character(run_dir, &character)?;
    let refuse = |what: &str| {
        Err(LearnError::Config(format!(
            "{} holds a prior checkpoint made with {what}; use another run directory to start afresh",
            run_dir.display()
        )))
    };
    if !ckpt.config.resumable_with(cfg) {
        return refuse("another configuration");
    }
    if ckpt.stats != stats || ckpt.mask != mask || ckpt.prior.state_bounds() != bounds {
        return refuse("other data (normalisation statistics, mask or bounds differ)");
    }
    ckpt.config = cfg.clone();
    if !provenance.is_null() {
        ckpt.provenance = provenance;
    }
    Ok(ckpt)
}

/// Every first frame `s` of a window `s..=s + rollout` that lies inside one episode.
pub fn window_starts(episodes: &[Range<usize>], rollout: usize) -> Vec<usize> {
    episodes
        .iter()
        .flat_map(|e| e.start..e.end.saturating_sub(rollout).max(e.start))
        .collect()
}

/// `n` standard normal draws (Box–Muller).
pub(crate) fn normals<R: Rng + ?Sized>(rng: &mut R, n: usize) -> Vec<f32> {
    let mut out = Vec::with_capacity(n + 1);
    while out.len() < n {
        let u1 = 1.0 - rng.random::<f64>(); // in (0, 1]
        let u2 = rng.random::<f64>();
        let r = (-2.0 * u1.ln()).sqrt();
        let a = std::f64::consts::TAU * u2;
        out.push((r * a.cos()) as f32);
        out.push((r * a.sin()) as f32);
    }
    out.truncate(n);
    out
}

/// Shared inputs of the learning tests: a small Spot dataset and a small prior trained on it once.
#[cfg(test)]
pub(crate) mod test_support {
    use std::path::PathBuf;
    use std::sync::OnceLock;

    use super::*;
    use crate::dataset::{DatasetConfig, generate};
    use crate::kinematics::KinematicTree;
    use crate::morphology::Morphology;

    /// Asserts that `vs` holds exactly the `expected` tensors: the same names, equal values. `what` names
    /// whose weights they are (e.g. a resumed run's against those it saved).
    pub(crate) fn assert_weights(vs: &tch::nn::VarStore, expected: impl IntoIterator<Item = (String, Tensor)>, what: &str) {
        let now = vs.variables();
        let expected: Vec<(String, Tensor)> = expected.into_iter().collect();
        assert_eq!(expected.len(), now.len(), "{what}: other variables");
        for (name, t) in &expected {
            assert!(now.get(name).is_some_and(|n| t.equal(n)), "{what}: {name} differs");
        }
    }

    /// The bundled Spot and a 4000-frame dataset of it (generated once per test process).
    pub(crate) fn spot() -> &'static (KinematicTree, Morphology, MotionSet) {
        static SPOT: OnceLock<(KinematicTree, Morphology, MotionSet)> = OnceLock::new();
        SPOT.get_or_init(|| {
            let (tree, morph) = crate::test_data::bundled_character("spot");
            let cfg = DatasetConfig {
                frames: 4000,
                seed: 5,
                ..DatasetConfig::default()
            };
            let set = generate(&tree, &morph, &cfg, &mut |_| {}).unwrap();
            (tree, morph, set)
        })
    }

    /// The dataset of [`spot`].
    pub(crate) fn spot_set() -> &'static MotionSet {
        &spot().2
    }

    /// A network small enough for tests to train in seconds.
    pub(crate) fn tiny_config() -> PriorConfig {
        PriorConfig {
            encoder_hidden: vec![64, 64],
            decoder_hidden: vec![64],
            experts: 4,
            gating_hidden: vec![16],
            batch_size: 32,
            rollout: 8,
            steps: 300,
            learning_rate: 1e-3,
            checkpoint_every: 100,
            device: DeviceChoice::Cpu,
            ..PriorConfig::default()
        }
    }

    /// An empty directory under the system's temporary directory, unique to this process and `name`.
    pub(crate) fn scratch_dir(name: &str) -> PathBuf {
        let dir = std::env::temp_dir().join(format!("ace_learn_{name}_{}", std::process::id()));
        let _ = fs::remove_dir_all(&dir);
        fs::create_dir_all(&dir).unwrap();
        dir
    }

    /// A run directory holding [`tiny_config`] trained on [`spot_set`] (trained once per process). The
    /// directory outlives the process; the next process to call this removes it (see
    /// [`remove_stale_scratch`]).
    pub(crate) fn trained_spot_dir() -> &'static Path {
        static DIR: OnceLock<PathBuf> = OnceLock::new();
        DIR.get_or_init(|| {
            remove_stale_scratch();
            let dir = scratch_dir("trained_spot");
            let (tree, morph, set) = spot();
            train_prior(set, &state_mask(tree, morph), &tiny_config(), &dir, &mut |_| {}).unwrap();
            dir
        })
    }

    /// Removes the scratch directories of earlier test processes that have ended (their process id,
    /// the name's suffix, no longer runs).
    pub(crate) fn remove_stale_scratch() {
        let Ok(entries) = fs::read_dir(std::env::temp_dir()) else {
            return;
        };
        for e in entries.flatten() {
            let name = e.file_name().to_string_lossy().into_owned();
            let Some(pid) = name.strip_prefix("ace_learn_").and_then(|n| n.rsplit('_').next()) else {
                continue;
            };
            let ended = pid
                .parse::<u32>()
                .is_ok_and(|p| p != std::process::id() && !Path::new(&format!("/proc/{p}")).exists());
            if ended && cfg!(target_os = "linux") {
                let _ = fs::remove_dir_all(e.path());
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::test_support::*;
    use super::*;
    use crate::character_state::CharacterLayout;
    use crate::test_data::bundled_character as load;

    fn batch(set: &MotionSet, frames: &[usize]) -> Tensor {
        let rows: Vec<&[f32]> = frames.iter().map(|&i| set.state(i)).collect();
        Normaliser::of_set(set).normalise(&super::super::rows_to_tensor(&rows, Device::Cpu).unwrap())
    }

    fn read_losses(dir: &Path) -> Vec<Vec<f64>> {
        let text = fs::read_to_string(dir.join(LOSSES_FILE)).unwrap();
        let mut lines = text.lines();
        assert_eq!(
            lines.next().unwrap(),
            "step,total,reconstruction,kl,sampling_probability,seconds"
        );
        lines
            .map(|l| l.split(',').map(|v| v.parse::<f64>().unwrap()).collect())
            .collect()
    }

    #[test]
    fn wheel_angles_are_masked_and_nothing_else() {
        let (tree, morph) = load("stretch");
        assert!(!morph.wheels.is_empty(), "the bundled Stretch has wheels");
        let mask = state_mask(&tree, &morph);
        let layout = CharacterLayout::new(&tree, &morph);
        assert_eq!(mask.len(), layout.dim());
        let names = layout.entry_names(&tree, &morph);
        let wheel_joints: Vec<String> = morph
            .wheels
            .iter()
            .map(|&w| format!("q:{}", tree.links[w].joint.as_ref().unwrap().name))
            .collect();
        for (name, m) in names.iter().zip(&mask) {
            assert_eq!(*m == 0.0, wheel_joints.contains(name), "{name}");
        }
        assert_eq!(mask.iter().filter(|&&m| m == 0.0).count(), morph.wheels.len());
        let (tree, morph) = load("spot");
        assert!(state_mask(&tree, &morph).iter().all(|&m| m == 1.0));
    }

    #[test]
    fn shapes_and_masked_entries_do_not_reach_the_loss() {
        let set = spot_set();
        let d = set.layout.dim();
        let mut cfg = tiny_config();
        cfg.seed = 3;
        let mut prior = MotionPrior::new(&cfg, d, Device::Cpu);
        assert_eq!((prior.state_dim(), prior.latent_dim()), (d, 32));
        let prev = batch(set, &[10, 200, 1500]);
        let cur = batch(set, &[11, 201, 1501]);
        let (mu, logvar) = prior.encode(&prev, &cur);
        assert_eq!((mu.size(), logvar.size()), (vec![3, 32], vec![3, 32]));
        assert_eq!(prior.decode(&mu, &prev).size(), vec![3, d as i64]);
        let alpha = prior.expert_coefficients(&mu, &prev);
        assert_eq!(alpha.size(), vec![3, cfg.experts as i64]);

        // Mask two joint entries, then change them in the data: the loss must not move. Changing an
        // unmasked entry must move it.
        let q0 = set.layout.joint_positions().start;
        let mut mask = vec![1.0f32; d];
        mask[q0] = 0.0;
        mask[q0 + 3] = 0.0;
        prior.set_mask(&mask).unwrap();
        let noise = Tensor::randn([3, 32], (Kind::Float, Device::Cpu));
        let loss = |p: &Tensor, c: &Tensor| prior.loss(p, c, &noise).total.double_value(&[]);
        let base = loss(&prev, &cur);
        let poke = |t: &Tensor, col: i64| {
            let t = t.copy();
            let _ = t.narrow(1, col, 1).fill_(25.0);
            t
        };
        assert_eq!(loss(&poke(&prev, q0 as i64), &poke(&cur, q0 as i64 + 3)), base);
        assert_ne!(loss(&poke(&prev, q0 as i64 + 1), &cur), base);
        assert_ne!(loss(&prev, &poke(&cur, q0 as i64 + 1)), base);
        // The decoder's output is 0 (the mean) at masked entries.
        let y = prior.decode(&mu, &prev);
        assert_eq!(
            y.narrow(1, q0 as i64, 1).abs().sum(Kind::Float).double_value(&[]),
            0.0
        );
        assert!(prior.set_mask(&mask[1..]).is_err());

        // Bounds: the dataset lies inside them; outputs for extreme z are clamped to them, and
        // gradients still reach z through the clamp.
        let bounds = StateBounds::of_set(set, &mask, 0.25);
        let all = batch(set, &(0..set.len()).collect::<Vec<_>>()) * Tensor::from_slice(&mask);
        let (lo, hi) = (Tensor::from_slice(&bounds.lo), Tensor::from_slice(&bounds.hi));
        assert!(bool::try_from(all.ge_tensor(&lo).logical_and(&all.le_tensor(&hi)).all()).unwrap());
        assert_eq!((bounds.lo[q0], bounds.hi[q0]), (0.0, 0.0));
        prior.set_bounds(&bounds).unwrap();
        let z = (Tensor::ones([3, 32], (Kind::Float, Device::Cpu)) * 1e4).set_requires_grad(true);
        let y = prior.decode(&z, &prev);
        assert!(bool::try_from(y.ge_tensor(&lo).logical_and(&y.le_tensor(&hi)).all()).unwrap());
        assert!(prior.at_bounds(&y) > 0.5, "extreme z should hit the bounds");
        y.sum(Kind::Float).backward();
        assert!(z.grad().abs().sum(Kind::Float).double_value(&[]) > 0.0);
    }

    #[test]
    fn free_bits_floor_each_latent_entry_of_the_kl_term() {
        let set = spot_set();
        let d = set.layout.dim();
        let prev = batch(set, &[10, 200, 1500, 2500]);
        let cur = batch(set, &[11, 201, 1501, 2501]);
        let noise = Tensor::zeros([4, 32], (Kind::Float, Device::Cpu));
        let mut cfg = tiny_config();
        let plain = MotionPrior::new(&cfg, d, Device::Cpu).loss(&prev, &cur, &noise);
        assert!(plain.kl_loss.equal(&plain.kl));
        cfg.free_bits = 10.0; // above any entry's KL at initialisation
        let floored = MotionPrior::new(&cfg, d, Device::Cpu).loss(&prev, &cur, &noise);
        // Same weights (same seed): the raw KL is unchanged, the loss counts every entry at λ.
        assert!(floored.kl.equal(&plain.kl));
        assert!((floored.kl_loss.double_value(&[]) - 10.0).abs() < 1e-9);
        let beta = cfg.kl_weight;
        let expected = floored.recon.double_value(&[]) + beta * 10.0;
        assert!((floored.total.double_value(&[]) - expected).abs() < 1e-6);
        cfg.free_bits = -1.0;
        assert!(cfg.check().is_err());
    }

    #[test]
    fn windows_stay_inside_episodes() {
        let set = spot_set();
        assert!(set.episodes.len() > 1, "the test dataset has several episodes");
        for rollout in [1, 4, 8] {
            let starts = window_starts(&set.episodes, rollout);
            for &s in &starts {
                let e = set.episodes.iter().find(|e| e.contains(&s)).unwrap();
                assert!(
                    s + rollout < e.end,
                    "window {s}..={} leaves episode {e:?}",
                    s + rollout
                );
            }
            // Every admissible start is there.
            let expected: usize = set.episodes.iter().map(|e| e.len().saturating_sub(rollout)).sum();
            assert_eq!(starts.len(), expected);
        }
        assert!(window_starts(&[0..3, 3..5], 4).is_empty());
    }

    #[test]
    fn sampling_schedule_ramps() {
        let s = SamplingSchedule {
            start: 0.2,
            end: 0.6,
            max_probability: 0.8,
        };
        assert_eq!(s.probability(0, 100), 0.0);
        assert_eq!(s.probability(19, 100), 0.0);
        assert!((s.probability(40, 100) - 0.4).abs() < 1e-12);
        assert_eq!(s.probability(60, 100), 0.8);
        assert_eq!(s.probability(99, 100), 0.8);
    }

    #[test]
    fn normals_have_unit_moments() {
        let v = normals(&mut Pcg64::seed_from_u64(1), 100_001);
        assert_eq!(v.len(), 100_001);
        let mean = v.iter().map(|&x| f64::from(x)).sum::<f64>() / v.len() as f64;
        let var = v.iter().map(|&x| (f64::from(x) - mean).powi(2)).sum::<f64>() / v.len() as f64;
        assert!(
            mean.abs() < 0.01 && (var - 1.0).abs() < 0.02,
            "mean {mean}, var {var}"
        );
    }

    #[test]
    fn training_lowers_the_reconstruction_loss() {
        let rows = read_losses(trained_spot_dir());
        let steps = tiny_config().steps;
        assert_eq!(rows.len(), steps);
        assert!(
            rows.iter()
                .enumerate()
                .all(|(i, r)| r[0] == i as f64 && r.len() == 6)
        );
        let mean = |r: &[Vec<f64>]| r.iter().map(|r| r[2]).sum::<f64>() / r.len() as f64;
        // The last steps (fully autoregressive, the harder task) against the first (fed with data).
        let (early, last) = (mean(&rows[..10]), mean(&rows[steps - 20..]));
        assert!(last < 0.5 * early, "reconstruction {early} → {last} at the end");
        // The sampling probability follows the schedule.
        assert_eq!(rows[0][4], 0.0);
        assert_eq!(rows[steps - 1][4], 1.0);
    }

    #[test]
    fn a_sixty_second_rollout_with_random_z_stays_finite_and_bounded() {
        let ckpt = PriorCheckpoint::load(trained_spot_dir(), Device::Cpu).unwrap();
        let set = spot_set();
        let starts: Vec<usize> = set.episodes.iter().map(|e| e.start + 5).collect();
        let first = batch(set, &starts);
        let b = starts.len() as i64;
        tch::manual_seed(4);
        let z = Tensor::randn([1800, b, 32], (Kind::Float, Device::Cpu));
        let out = ckpt.prior.rollout(&first, &z);
        assert_eq!(out.size(), vec![1800, b, set.layout.dim() as i64]);
        assert!(
            bool::try_from(out.isfinite().all()).unwrap(),
            "the rollout is not finite"
        );
        // Bounded, and by the prior itself: the output clamp acts on few entries.
        let (lo, hi) = ckpt.prior.bounds();
        assert!(bool::try_from(out.ge_tensor(lo).logical_and(&out.le_tensor(hi)).all()).unwrap());
        let clamped = ckpt.prior.at_bounds(&out);
        assert!(
            clamped < 0.01,
            "{:.2} % of the rollout's entries sit on a bound",
            100.0 * clamped
        );
        // It moves: the rollout does not settle on one state.
        let late = out.narrow(0, 1700, 100);
        let spread = late.std_dim(0, true, false).mean(Kind::Float).double_value(&[]);
        assert!(
            spread > 0.05,
            "the last 100 frames barely move (mean std {spread})"
        );
    }

    #[test]
    fn the_latent_carries_the_transition() {
        // Decoding with the encoder's z must beat decoding with z = 0 clearly, or a generator steering
        // the prior through z would have nothing to steer.
        let ckpt = PriorCheckpoint::load(trained_spot_dir(), Device::Cpu).unwrap();
        let set = spot_set();
        let frames: Vec<usize> = (0..set.len()).step_by(7).filter(|&i| i > 0).collect();
        let cur = batch(set, &frames);
        let prev = batch(set, &frames.iter().map(|i| i - 1).collect::<Vec<_>>());
        tch::no_grad(|| {
            let (mu, _) = ckpt.prior.encode(&prev, &cur);
            let mse = |z: &Tensor| {
                (ckpt.prior.decode(z, &prev) - &cur)
                    .square()
                    .mean(Kind::Float)
                    .double_value(&[])
            };
            let (with_z, without) = (mse(&mu), mse(&mu.zeros_like()));
            assert!(
                with_z < 0.6 * without,
                "one-step error {with_z} with z, {without} with z = 0"
            );
        });
    }

    #[test]
    fn same_seed_same_weights_and_runs_resume() {
        let (tree, morph, set) = spot();
        let mask = state_mask(tree, morph);
        let mut cfg = tiny_config();
        cfg.steps = 12;
        cfg.checkpoint_every = 6;
        cfg.seed = 9;
        let a = scratch_dir("det_a");
        let b = scratch_dir("det_b");
        let pa = train_prior(set, &mask, &cfg, &a, &mut |_| {}).unwrap();
        let pb = train_prior(set, &mask, &cfg, &b, &mut |_| {}).unwrap();
        assert_weights(pb.var_store(), pa.var_store().variables(), "two runs with the same seed");
        let va = pa.var_store().variables();
        let mut other = cfg.clone();
        other.seed = 10;
        let c = scratch_dir("det_c");
        let pc = train_prior(set, &mask, &other, &c, &mut |_| {}).unwrap();
        let name = "decoder.layer0.weight";
        assert!(!va[name].equal(&pc.var_store().variables()[name]));

        // Resume: extend run `a` to 18 steps; it continues at step 12.
        let mut longer = cfg.clone();
        longer.steps = 18;
        let mut seen = Vec::new();
        train_prior(set, &mask, &longer, &a, &mut |p| seen.push(p.step)).unwrap();
        assert_eq!(seen, (13..=18).collect::<Vec<_>>());
        let rows = read_losses(&a);
        assert_eq!(
            rows.iter().map(|r| r[0] as usize).collect::<Vec<_>>(),
            (0..18).collect::<Vec<_>>()
        );
        assert_eq!(PriorCheckpoint::load(&a, Device::Cpu).unwrap().step, 18);
        // The resumed run started from the step-12 weights, not from fresh ones.
        let b12 = start_or_resume(set, &mask, &longer, &b, Value::Null, Device::Cpu).unwrap();
        assert_eq!(b12.step, 12);
        assert_weights(b12.prior.var_store(), pb.var_store().variables(), "the resumed prior against the saved one");
        // The resumed run records its own provenance.
        let note = serde_json::json!({ "run": "resumed" });
        assert_eq!(start_or_resume(set, &mask, &longer, &b, note.clone(), Device::Cpu).unwrap().provenance, note);
        // A checkpoint whose stored statistics or bounds are not what this data gives (written by a
        // version that computed them otherwise, or edited) is refused, each alone.
        for what in ["statistics", "bounds"] {
            let mut edited = PriorCheckpoint::load(&b, Device::Cpu).unwrap();
            if what == "statistics" {
                edited.stats.mean[0] += 0.25;
            } else {
                let mut bounds = edited.prior.state_bounds();
                bounds.hi[0] += 0.25;
                edited.prior.set_bounds(&bounds).unwrap();
            }
            let dir = scratch_dir(&format!("prior_edited_{what}"));
            edited.save(&dir).unwrap();
            let e = start_or_resume(set, &mask, &longer, &dir, Value::Null, Device::Cpu).err().expect(what).to_string();
            assert!(e.contains("other data"), "{what}: {e}");
            fs::remove_dir_all(&dir).unwrap();
        }
        // A finished run returns at once.
        let mut calls = 0;
        train_prior(set, &mask, &longer, &a, &mut |_| calls += 1).unwrap();
        assert_eq!(calls, 0);
        // Another network in the same directory is refused.
        let mut wider = longer.clone();
        wider.decoder_hidden = vec![80];
        let e = train_prior(set, &mask, &wider, &a, &mut |_| {}).unwrap_err();
        assert!(e.to_string().contains("another configuration"), "{e}");
        for d in [a, b, c] {
            fs::remove_dir_all(d).unwrap();
        }
    }
}
