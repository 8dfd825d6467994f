//! NKN, the baseline of the paper's Table 1: Villegas et al.'s Neural Kinematic Networks (CVPR 2018)
//! as ACE's authors adapt it (§7.3) — a recurrent network with a forward-kinematics layer, trained
//! with an adversarial loss and a cycle-consistency loss and no reconstruction loss.
//!
//! # The model
//! - **Retargeting network** R: a GRU over the normalised human states x^h of a sequence, and a linear
//!   head per frame giving the character's root entries of x^r (height, orientation, displacement,
//!   delta rotation, linear and angular velocity) and its joint positions, normalised with the
//!   character dataset's statistics.
//! - **Forward-kinematics layer** ([`super::fk::FkLayer`]): the end-effector points in the heading
//!   frame from the root orientation and joint positions, differentiably; their velocities from
//!   consecutive frames (the first frame of a sequence takes the second's). With them R's output is a
//!   complete x^r, the state ACE's prior produces.
//! - **Discriminator** D: ACE's ([`super::ace::Discriminator`], same sizes and loss with the gradient
//!   penalty) on transitions `x^r_{t−1} → x^r_t`, real ones from the character dataset the prior was
//!   trained on.
//! - **Cycle network** C: a second GRU mapping the generated character states back to x^h; the cycle
//!   loss is the mean squared error of the normalised human states, human → character → human.
//!
//! R and C minimise `w_adv·L_adv + w_cyc·L_cyc`; D is updated as in ACE. The budget is ACE's: the
//! same steps, batch size, window, learning rates, Adam β₁, seed ([`NknConfig::matching`]).
//!
//! # How it differs from the original NKN
//! Villegas et al. retarget between human skeletons: their network outputs joint rotations of a
//! target *skeleton* and their FK layer yields its joint positions, their discriminator sees joint
//! velocities of real target-skeleton motion, and their cycle maps target motion back to the source
//! skeleton (plus a twist loss and, when available, a reconstruction of identical skeletons). Here, as
//! in the ACE paper's adaptation, the target is a nonhuman character with no paired data: the output
//! is the character state x^r (root motion plus joint positions of the URDF, prismatic joints
//! included), the FK layer is the URDF's kinematic tree, the discriminator reads x^r transitions (ACE's
//! D input), the cycle is on the human state, and there is no reconstruction or twist loss. The
//! encoder–decoder GRU pair of the original is one GRU per direction here. At inference the output is
//! turned into poses exactly as ACE's ([`super::retarget`]: root integration, joint limits, cleanup).

use std::fs;
use std::path::{Path, PathBuf};
use std::time::Instant;

use rand::RngExt;
use serde::{Deserialize, Serialize};
use serde_json::Value;
use tch::nn::{self, Module, OptimizerConfig, RNN};
use tch::{Device, Kind, Tensor};

use crate::temporary;

use super::ace::{AceConfig, Discriminator, discriminator_loss, generator_adv_loss};
use super::checkpoint::{CharacterInfo, LearnError, PriorCheckpoint};
use super::files::{CheckpointFiles, FileRecord, load_weights, open_losses, read_file, read_json, step_rng, write_synced};
use super::fk::{FkLayer, quat_to_matrix};
use super::prior::{DeviceChoice, window_starts};
use super::retarget::{RetargetedMotion, roll_out};
use super::train_ace::{AceInputs, FeatureMatching, human_windows, log_step, normalised_dataset, tracked, weighted_sum};
use crate::character_state::CharacterLayout;
use crate::cleanup::Cleanup;
use crate::features::EndEffectorMapping;
use crate::human::layout as human_layout;
use crate::human_set::{HumanRow, HumanSplit, HumanStats, PROJECT_FPS};
use crate::kinematics::KinematicTree;
use crate::morphology::Morphology;

/// The record beside the weights.
pub const NKN_FILE: &str = "nkn.json";
/// R and C's weights.
pub const NKN_WEIGHTS_FILE: &str = "nkn.safetensors";
/// D's weights.
pub const NKN_DISCRIMINATOR_FILE: &str = "nkn_discriminator.safetensors";
/// The loss log: `step,d_loss,d_bce,gp,g_loss,adv,cycle,d_real,d_fake,seconds`.
pub const NKN_LOSSES_FILE: &str = "nkn_losses.csv";
const HEADER: &str = "step,d_loss,d_bce,gp,g_loss,adv,cycle,d_real,d_fake,seconds";
const SECONDS_COLUMN: usize = 9;
const KIND: &str = "nkn";
const FORMAT_VERSION: u32 = 1;
const RNG_STREAM: u64 = 0x0a4b_0a4b_0a4b_0a4b;

/// NKN's sizes and training settings.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct NknConfig {
    /// Hidden width of R's GRU.
    pub hidden: usize,
    /// Hidden width of C's GRU.
    pub cycle_hidden: usize,
    /// Hidden layer widths of D.
    pub discriminator_hidden: Vec<usize>,
    /// Weight of the adversarial loss.
    pub w_adv: f64,
    /// Weight of the cycle-consistency loss.
    pub w_cyc: f64,
    /// Weight of D's gradient penalty on real transitions.
    pub w_gp: f64,
    /// Adam's learning rate for R and C.
    pub generator_lr: f64,
    /// Adam's learning rate for D.
    pub discriminator_lr: f64,
    /// Adam's β₁.
    pub adam_beta1: f64,
    /// Human sequences per step.
    pub batch_size: usize,
    /// Frames per training sequence.
    pub window: usize,
    /// Steps of R and C.
    pub steps: usize,
    /// A checkpoint is saved every this many steps (and at the end).
    pub checkpoint_every: usize,
    /// Seed of initialisation and of every draw.
    pub seed: u64,
}

impl Default for NknConfig {
    fn default() -> Self {
        NknConfig::matching(&AceConfig::default())
    }
}

impl NknConfig {
    /// ACE's budget for NKN: its steps, batch size, window, learning rates, Adam β₁, seed, D sizes and
    /// gradient penalty; the GRUs as wide as G's first hidden layer; `w_cyc` = ACE's `w_fea` (the loss
    /// that keeps the human's motion, as L_fea does in ACE).
    pub fn matching(ace: &AceConfig) -> NknConfig {
        NknConfig {
            hidden: ace.generator_hidden.first().copied().unwrap_or(256),
            cycle_hidden: ace.generator_hidden.first().copied().unwrap_or(256),
            discriminator_hidden: ace.discriminator_hidden.clone(),
            w_adv: ace.w_adv,
            w_cyc: ace.w_fea,
            w_gp: ace.w_gp,
            generator_lr: ace.generator_lr,
            discriminator_lr: ace.discriminator_lr,
            adam_beta1: ace.adam_beta1,
            batch_size: ace.batch_size,
            window: ace.window,
            steps: ace.steps,
            checkpoint_every: ace.checkpoint_every,
            seed: ace.seed,
        }
    }

    /// Fails on settings training cannot run with.
    pub fn check(&self) -> Result<(), LearnError> {
        let bad = |m: String| Err(LearnError::Config(m));
        if self.hidden == 0 || self.cycle_hidden == 0 || self.discriminator_hidden.contains(&0) {
            return bad("hidden widths must be at least 1".into());
        }
        if self.batch_size == 0 || self.window < 2 || self.checkpoint_every == 0 {
            return bad("batch_size and checkpoint_every must be at least 1, window at least 2".into());
        }
        use crate::checkpoint::limits;
        for (name, v) in [("generator_lr", self.generator_lr), ("discriminator_lr", self.discriminator_lr)] {
            limits::float_in_range(name, v, 0.0, limits::LEARNING_RATE, true)?;
        }
        for (name, v) in [("w_adv", self.w_adv), ("w_cyc", self.w_cyc), ("w_gp", self.w_gp)] {
            limits::float_in_range(name, v, 0.0, limits::LOSS_WEIGHT, false)?;
        }
        if self.w_adv == 0.0 && self.w_cyc == 0.0 {
            return bad("w_adv and w_cyc are both zero".into());
        }
        Ok(())
    }

    /// The settings of D as an [`AceConfig`] (for [`Discriminator::new`]).
    fn discriminator(&self) -> AceConfig {
        AceConfig {
            discriminator_hidden: self.discriminator_hidden.clone(),
            seed: self.seed,
            device: DeviceChoice::Cpu,
            ..AceConfig::default()
        }
    }
}

/// Everything `nkn.json` holds.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct NknRecord {
    /// `"nkn"`.
    pub kind: String,
    /// The file format's version.
    pub format_version: u32,
    /// The character.
    pub character: CharacterInfo,
    /// Steps done.
    pub step: usize,
    /// The configuration.
    pub config: NknConfig,
    /// x^h normalisation statistics (over the training clips).
    pub human_stats: HumanStats,
    /// The folder the human clips came from.
    pub human_folder: PathBuf,
    /// The held-out split of the human clips.
    pub human_split: HumanSplit,
    /// R and C's weights file.
    pub weights: FileRecord,
    /// D's weights file.
    pub discriminator: FileRecord,
    /// How it was made (command line, commit, …).
    pub provenance: Value,
}

/// R and C (one `VarStore`) with the FK layer (see the module docs).
#[derive(Debug)]
pub struct Nkn {
    vs: nn::VarStore,
    retarget: nn::GRU,
    head: nn::Linear,
    cycle: nn::GRU,
    cycle_head: nn::Linear,
    fk: FkLayer,
    layout: CharacterLayout,
    mean: Tensor,
    std: Tensor,
    mask: Tensor,
}

impl Nkn {
    /// Fresh networks (seeded) for the character of `prior` (`tree`, `morph`), normalised with its
    /// statistics and mask.
    pub fn new(cfg: &NknConfig, prior: &PriorCheckpoint, tree: &KinematicTree, morph: &Morphology) -> Nkn {
        let device = prior.prior.device();
        let layout = CharacterLayout::new(tree, morph);
        let dim = layout.dim() as i64;
        let out = layout.ee_positions().start as i64;
        tch::manual_seed(cfg.seed as i64);
        let vs = nn::VarStore::new(device);
        let root = vs.root();
        let rnn = nn::RNNConfig { batch_first: true, ..Default::default() };
        let h = human_layout::DIM as i64;
        let retarget = nn::gru(&root / "retarget", h, cfg.hidden as i64, rnn);
        let head = nn::linear(&root / "retarget_head", cfg.hidden as i64, out, Default::default());
        let cycle = nn::gru(&root / "cycle", dim, cfg.cycle_hidden as i64, rnn);
        let cycle_head = nn::linear(&root / "cycle_head", cfg.cycle_hidden as i64, h, Default::default());
        let t = |v: &[f32]| Tensor::from_slice(v).view([1, 1, -1]).to_device(device);
        Nkn {
            fk: FkLayer::new(tree, morph, device),
            mean: t(&prior.stats.mean),
            std: t(&prior.stats.std),
            mask: t(&prior.mask),
            layout,
            vs,
            retarget,
            head,
            cycle,
            cycle_head,
        }
    }

    /// Normalised x^r `[B, T, D]` of normalised human sequences `[B, T, 92]` (R, then the FK layer).
    pub fn states(&self, x_h: &Tensor) -> Tensor {
        let (b, t) = (x_h.size()[0], x_h.size()[1]);
        let (hidden, _) = self.retarget.seq(x_h);
        let head = self.head.forward(&hidden);
        let l = &self.layout;
        let n = (l.ee_positions().start) as i64;
        let denorm = &head * self.std.narrow(2, 0, n) + self.mean.narrow(2, 0, n);
        let flat = denorm.view([b * t, n]);
        let part = |r: std::ops::Range<usize>| flat.narrow(1, r.start as i64, r.len() as i64);
        let ee = self
            .fk
            .ee_positions(&quat_to_matrix(&part(l.root_orientation())), &part(l.joint_positions()))
            .view([b, t, -1]);
        // World velocity of each point in the current heading frame: the previous point moved into the
        // current heading frame (back by the displacement and height change, turned by the heading
        // change), differenced.
        let e = self.fk.end_effectors() as i64;
        let d = denorm.view([b, t, n]);
        let narrow3 = |r: std::ops::Range<usize>| d.narrow(2, r.start as i64, r.len() as i64);
        let disp = narrow3(l.root_displacement());
        let height = narrow3(l.root_height());
        let dq = narrow3(l.root_delta_rotation());
        let c = |i: i64| dq.select(2, i);
        let (num, den): (Tensor, Tensor) = ((c(0) * c(3) + c(1) * c(2)) * 2.0, 1.0 - (c(2).square() + c(3).square()) * 2.0);
        let yaw = num.atan2(&den);
        let shift = Tensor::cat(&[disp.shallow_clone(), &height - height.roll([1], [1])], 2);
        let cur = ee.narrow(1, 1, t - 1).view([b, t - 1, e, 3]);
        let before = (ee.narrow(1, 0, t - 1).view([b, t - 1, e, 3]) - shift.narrow(1, 1, t - 1).unsqueeze(2))
            .split(1, 3);
        let (cy, sy) = (yaw.narrow(1, 1, t - 1).cos().unsqueeze(2), yaw.narrow(1, 1, t - 1).sin().unsqueeze(2));
        let (bx, by, bz) = (before[0].squeeze_dim(3), before[1].squeeze_dim(3), before[2].squeeze_dim(3));
        let moved = Tensor::stack(&[&cy * &bx + &sy * &by, -&sy * &bx + &cy * &by, bz], 3);
        let vel = ((cur - moved) * f64::from(PROJECT_FPS)).view([b, t - 1, 3 * e]);
        let vel = Tensor::cat(&[vel.narrow(1, 0, 1), vel], 1);
        let tail = Tensor::cat(&[ee, vel], 2);
        let start = l.ee_positions().start as i64;
        let tail = (tail - self.mean.narrow(2, start, 6 * e)) / self.std.narrow(2, start, 6 * e);
        Tensor::cat(&[head, tail], 2) * &self.mask
    }

    /// C: normalised x^h `[B, T, 92]` of normalised character states `[B, T, D]`.
    pub fn cycle(&self, x_r: &Tensor) -> Tensor {
        let (hidden, _) = self.cycle.seq(x_r);
        self.cycle_head.forward(&hidden)
    }

    /// The variables of R and C.
    pub fn var_store(&self) -> &nn::VarStore {
        &self.vs
    }
}

/// A trained NKN with its record and the prior beside it (whose statistics, mask and bounds it uses).
#[derive(Debug)]
pub struct NknCheckpoint {
    /// The record.
    pub record: NknRecord,
    /// The networks.
    pub nkn: Nkn,
    /// The character's prior checkpoint (only its statistics, mask and bounds are used).
    pub prior: PriorCheckpoint,
}

/// Reads the `nkn.json` in `dir`, checking kind and version before the rest.
pub fn read_record(dir: &Path) -> Result<NknRecord, LearnError> {
    read_json(&CheckpointFiles::on_disk(dir), NKN_FILE, KIND, FORMAT_VERSION, "an NKN checkpoint")
}

impl NknCheckpoint {
    /// Loads `nkn.json`, the weights and the prior in `dir` for `tree` and `morph`; every error names
    /// the file and the problem.
    pub fn load(dir: &Path, tree: &KinematicTree, morph: &Morphology, device: Device) -> Result<NknCheckpoint, LearnError> {
        let files = CheckpointFiles::on_disk(dir);
        let record: NknRecord = read_json(&files, NKN_FILE, KIND, FORMAT_VERSION, "an NKN checkpoint")?;
        let prior = PriorCheckpoint::load_for(dir, device, tree, morph)?;
        if let Some(problem) = record.character.difference(&prior.character) {
            return Err(LearnError::WrongCharacter {
                path: dir.join(NKN_FILE),
                problem: format!("NKN does not match the prior beside it: {problem}"),
            });
        }
        let nkn = Nkn::new(&record.config, &prior, tree, morph);
        load_weights(&files, NKN_WEIGHTS_FILE, &record.weights, &nkn.vs, "NKN", NKN_FILE)?;
        Ok(NknCheckpoint { record, nkn, prior })
    }

    /// Retargets x^h rows at [`PROJECT_FPS`]: R over the whole sequence, then the same pose decoding,
    /// limits and `cleanup` as ACE's [`super::retarget::Retargeter`]; NKN learns no correspondence,
    /// so the cleanup's end-effector hold pairs the end effectors as `mapping` says (the ACE
    /// checkpoint's it is compared with).
    pub fn retarget_states(
        &self,
        tree: &KinematicTree,
        morph: &Morphology,
        x_h: &[HumanRow],
        cleanup: Cleanup,
        mapping: &EndEffectorMapping,
    ) -> Result<RetargetedMotion, LearnError> {
        let device = self.prior.prior.device();
        let s = &self.record.human_stats;
        let t = |v: &[f32]| Tensor::from_slice(v).view([1, -1]).to_device(device);
        let x = (super::rows_to_tensor(x_h, device)? - t(&s.mean)) / t(&s.std);
        let states = tch::no_grad(|| self.nkn.states(&x.unsqueeze(0))).squeeze_dim(0);
        roll_out(tree, morph, &self.prior, cleanup, mapping, x_h.len(), x_h, &mut |i, _| states.narrow(0, i as i64, 1))
    }
}

/// Reported after every step.
#[derive(Clone, Debug, PartialEq)]
pub struct NknProgress {
    /// Steps done.
    pub step: usize,
    /// Steps in the run.
    pub steps: usize,
    /// `w_adv·adv + w_cyc·cycle`.
    pub g_loss: f64,
    /// D's loss.
    pub d_loss: f64,
    /// L_adv.
    pub adv: f64,
    /// The cycle loss.
    pub cycle: f64,
}

/// Trains NKN on ACE's inputs (the same prior's dataset, human clips and split) in `run_dir`, resuming
/// from an NKN checkpoint of the same configuration there (Adam restarts), and returns it.
pub fn train_nkn(
    inputs: &AceInputs<'_>,
    cfg: &NknConfig,
    run_dir: &Path,
    progress: &mut dyn FnMut(&NknProgress),
) -> Result<NknCheckpoint, LearnError> {
    cfg.check()?;
    let prior = inputs.prior;
    let device = prior.prior.device();
    fs::create_dir_all(run_dir).map_err(|e| LearnError::io(run_dir, e))?;
    super::train_ace::place_prior(prior, run_dir)?;
    let human_stats = inputs.humans.train_statistics();
    let psi = super::psi::Psi::new(&prior.character.layout, &inputs.correspondence.mapping, inputs.character_body_length, device);
    let humans = human_windows(inputs, &human_stats, psi.layout(), cfg.window, FeatureMatching::NONE, device)?;
    let nkn = Nkn::new(cfg, prior, inputs.tree, inputs.morph);
    let mut discriminator = Discriminator::new(&cfg.discriminator(), prior.prior.state_dim(), &prior.mask, device);
    let mut record = NknRecord {
        kind: KIND.into(),
        format_version: FORMAT_VERSION,
        character: prior.character.clone(),
        step: 0,
        config: cfg.clone(),
        human_stats,
        human_folder: inputs.humans.folder.clone(),
        human_split: inputs.humans.split.clone(),
        weights: FileRecord::of(NKN_WEIGHTS_FILE, &[]),
        discriminator: FileRecord::of(NKN_DISCRIMINATOR_FILE, &[]),
        provenance: inputs.provenance.clone(),
    };
    if run_dir.join(NKN_FILE).exists() {
        let files = CheckpointFiles::on_disk(run_dir);
        let there: NknRecord = read_json(&files, NKN_FILE, KIND, FORMAT_VERSION, "an NKN checkpoint")?;
        let neutral = |c: &NknConfig| NknConfig { steps: 0, checkpoint_every: 1, ..c.clone() };
        if neutral(&there.config) == neutral(cfg) && there.character == record.character && there.human_split == record.human_split {
            load_weights(&files, NKN_WEIGHTS_FILE, &there.weights, &nkn.vs, "NKN", NKN_FILE)?;
            load_weights(&files, NKN_DISCRIMINATOR_FILE, &there.discriminator, discriminator.var_store(), "NKN's discriminator", NKN_FILE)?;
            record.step = there.step;
        } else {
            return Err(LearnError::Config(format!(
                "{} holds an NKN checkpoint of another configuration or data; use another run directory",
                run_dir.display()
            )));
        }
    }
    let mut ckpt = NknCheckpoint { record, nkn, prior: PriorCheckpoint::load(run_dir, device)? };
    if ckpt.record.step >= cfg.steps {
        return Ok(ckpt);
    }
    let losses_path = run_dir.join(NKN_LOSSES_FILE);
    let (mut log, seconds_before) = open_losses(&losses_path, ckpt.record.step, HEADER, SECONDS_COLUMN)?;
    let data = normalised_dataset(prior, inputs.dataset, device)?;
    let real_starts = window_starts(&inputs.dataset.episodes, 1);
    let adam = nn::Adam { beta1: cfg.adam_beta1, ..nn::Adam::default() };
    let mut opt_g = adam.build(&ckpt.nkn.vs, cfg.generator_lr)?;
    let mut opt_d = adam.build(discriminator.var_store(), cfg.discriminator_lr)?;
    let (b, window) = (cfg.batch_size, cfg.window as i64);
    let offsets = Tensor::arange(window, (Kind::Int64, device)).view([1, window]);
    let clock = Instant::now();
    for step in ckpt.record.step..cfg.steps {
        let mut rng = step_rng(cfg.seed, RNG_STREAM, step);
        let mut draw = |pool: &[usize]| -> Tensor {
            let v: Vec<i64> = (0..b).map(|_| pool[rng.random_range(0..pool.len())] as i64).collect();
            Tensor::from_slice(&v).to_device(device)
        };
        let rows = (draw(&humans.starts).view([b as i64, 1]) + &offsets).view([-1]);
        let x_h = humans.states.index_select(0, &rows).view([b as i64, window, -1]);
        let nkn = &ckpt.nkn;

        discriminator.var_store_mut().freeze();
        let fake = nkn.states(&x_h);
        let dim = fake.size()[2];
        let prev = fake.narrow(1, 0, window - 1).reshape([-1, dim]);
        let cur = fake.narrow(1, 1, window - 1).reshape([-1, dim]);
        let adv = tracked(cfg.w_adv, || Ok(generator_adv_loss(&discriminator, &prev, &cur)))?;
        let cycle = tracked(cfg.w_cyc, || Ok((nkn.cycle(&fake) - &x_h).square().mean(Kind::Float)))?;
        let g_loss = weighted_sum(&[(cfg.w_adv, &adv), (cfg.w_cyc, &cycle)]);
        opt_g.backward_step(&g_loss);
        discriminator.var_store_mut().unfreeze();

        let real = draw(&real_starts);
        let fake_pool: Vec<usize> = (0..prev.size()[0] as usize).collect();
        let pick = draw(&fake_pool);
        let d = discriminator_loss(
            &discriminator,
            &data.index_select(0, &real),
            &data.index_select(0, &(&real + 1)),
            &prev.detach().index_select(0, &pick),
            &cur.detach().index_select(0, &pick),
            cfg.w_gp,
        );
        opt_d.backward_step(&d.total);

        let scalar = |t: &Tensor| t.double_value(&[]);
        let report = NknProgress {
            step: step + 1,
            steps: cfg.steps,
            g_loss: scalar(&g_loss),
            d_loss: scalar(&d.total),
            adv: scalar(&adv),
            cycle: scalar(&cycle),
        };
        let seconds = seconds_before + clock.elapsed().as_secs_f64();
        log_step(&mut log, &losses_path, step, &d, [report.g_loss, report.adv, report.cycle], seconds)?;
        progress(&report);
        ckpt.record.step = step + 1;
        if ckpt.record.step % cfg.checkpoint_every == 0 || ckpt.record.step == cfg.steps {
            save(&mut ckpt.record, &ckpt.nkn, &discriminator, run_dir)?;
        }
    }
    Ok(ckpt)
}

/// Writes the weights (temporary names, renamed into place) and then `nkn.json`.
fn save(record: &mut NknRecord, nkn: &Nkn, d: &Discriminator, dir: &Path) -> Result<(), LearnError> {
    for (file, vs) in [(NKN_WEIGHTS_FILE, nkn.var_store()), (NKN_DISCRIMINATOR_FILE, d.var_store())] {
        let tmp = temporary::beside(&dir.join(file), Some("safetensors"));
        vs.save(&tmp)?;
        let r = FileRecord::of(file, &read_file(&tmp)?);
        fs::rename(&tmp, dir.join(file)).map_err(|e| LearnError::io(&dir.join(file), e))?;
        if file == NKN_WEIGHTS_FILE {
            record.weights = r;
        } else {
            record.discriminator = r;
        }
    }
    let tmp = temporary::beside(&dir.join(NKN_FILE), None);
    let text = serde_json::to_string_pretty(&*record).map_err(|e| LearnError::Config(format!("cannot serialise {NKN_FILE}: {e}")))?;
    write_synced(&tmp, text.as_bytes())?;
    fs::rename(&tmp, dir.join(NKN_FILE)).map_err(|e| LearnError::io(&dir.join(NKN_FILE), e))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::learn::prior::test_support::{assert_weights, scratch_dir, spot};
    use crate::learn::train_ace::test_support::{bundled_humans, with_spot_inputs};

    fn tiny(steps: usize) -> NknConfig {
        NknConfig {
            hidden: 64,
            cycle_hidden: 64,
            discriminator_hidden: vec![64, 64],
            batch_size: 32,
            window: 6,
            steps,
            checkpoint_every: 20,
            generator_lr: 1e-3,
            discriminator_lr: 1e-3,
            ..NknConfig::default()
        }
    }

    #[test]
    fn a_short_run_lowers_its_loss_and_retargets_finite_poses() {
        let (tree, morph, _) = spot();
        with_spot_inputs("nkn", |inputs| {
            let dir = scratch_dir("nkn_short");
            let mut reports = Vec::new();
            let steps = 60;
            train_nkn(inputs, &tiny(steps), &dir, &mut |p| reports.push(p.clone())).unwrap();
            assert_eq!(reports.len(), steps);
            let mean = |r: &[NknProgress]| r.iter().map(|p| p.g_loss).sum::<f64>() / r.len() as f64;
            let (first, last) = (mean(&reports[..10]), mean(&reports[steps - 10..]));
            assert!(last < first, "NKN's loss went from {first} to {last}");
            let text = fs::read_to_string(dir.join(NKN_LOSSES_FILE)).unwrap();
            assert_eq!(text.lines().count(), steps + 1);

            // Loaded back, it retargets a clip into finite poses within the joint limits.
            let ckpt = NknCheckpoint::load(&dir, tree, morph, Device::Cpu).unwrap();
            assert_eq!(ckpt.record.step, steps);
            let walk = &bundled_humans().clips[1].states;
            let m = ckpt.retarget_states(tree, morph, walk, Cleanup::default(), &inputs.correspondence.mapping).unwrap();
            assert_eq!(m.poses.len(), walk.len());
            for p in &m.poses {
                assert!(p.q.iter().chain(p.root.translation.vector.iter()).all(|v| v.is_finite()));
                let mut clamped = p.q.clone();
                tree.clamp(&mut clamped);
                assert_eq!(clamped, p.q);
            }
            // A finished run is not trained again; a broken record is named.
            let again = train_nkn(inputs, &tiny(steps), &dir, &mut |_| panic!("no step")).unwrap();
            assert_eq!(again.record.step, steps);
            // It holds the saved weights (not fresh ones under the saved step count).
            assert_weights(&again.nkn.vs, Tensor::read_safetensors(dir.join(NKN_WEIGHTS_FILE)).unwrap(), "the resumed NKN against its weights file");
            fs::write(dir.join(NKN_FILE), "{").unwrap();
            let e = NknCheckpoint::load(&dir, tree, morph, Device::Cpu).unwrap_err().to_string();
            assert!(e.contains(NKN_FILE), "{e}");
            fs::remove_dir_all(&dir).unwrap();
        });
    }
}
