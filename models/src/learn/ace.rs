//! Generator G and discriminator D (paper §5, §6.4), their losses, and their files.
//!
//! - G(x^h_t, x^r_{t−1}) → ẑ_t: an [`Mlp`] with leaky ReLU on the normalised human state and the
//!   normalised previous character state; the frozen prior's decoder turns ẑ_t into x̂^r_t.
//! - D(x^r_{t−1}, x^r_t) → logit: an [`Mlp`] with SiLU on a normalised transition. σ(logit) is the
//!   paper's D ∈ [0, 1]; the losses work on logits for numerical stability.
//!
//! Both see the character states through the prior's state mask ([`super::prior::state_mask`]):
//! wheel angles are zeroed in their inputs, as they are in the prior's.
//!
//! # Losses
//! - [`discriminator_loss`]: `L_D = −E_real[log D] − E_fake[log(1 − D)]` (as softplus of logits) plus
//!   the gradient penalty `w_gp/2 · E_real[‖∇_{(x_{t−1}, x_t)} logit‖²]` on the *real* transitions
//!   (paper eq. 4; the penalty is taken on the logit, as in ASE which the paper follows).
//! - [`generator_adv_loss`]: `L_adv = −E[log D(x_{t−1}, x̂_t)]`.
//!
//! # Files ([`AceCheckpoint`])
//! An ACE checkpoint lives in the same directory as the motion prior it was trained with
//! ([`super::checkpoint`]): `generator.safetensors` and `discriminator.safetensors` (every variable of
//! each network's own `VarStore`, F32) and `ace.json` (pretty JSON): `kind` = [`KIND`],
//! `format_version`, the character, the training `step`, the [`AceConfig`], the end-effector
//! correspondence with its source (automatic or manual), the x^h normalisation statistics, the human
//! clip folder and split, the body lengths, the `feature_offset` that centres the human's Ψ for L_fea
//! (absent in checkpoints trained without centring), the `speed_scale` at which it compares the
//! root's linear velocity (absent when trained without it), checksums of both weights files and of the
//! prior's weights file it was trained against, and a free-form `provenance`. Files are written under temporary names
//! and renamed into place (weights first); the checksums tie the files together.

use std::fs;
use std::path::{Path, PathBuf};

use rand::SeedableRng;
use rand_pcg::Pcg64;
use tch::{Device, Kind, Tensor, nn};

use super::checkpoint::{CONFIG_FILE as PRIOR_CONFIG_FILE, LearnError, WEIGHTS_FILE as PRIOR_WEIGHTS_FILE};
pub use super::files::FileRecord;
use super::files::{CheckpointFiles, load_weights, read_file, write_synced};
use super::nets::{Activation, Mlp};
pub use crate::checkpoint::ace::{
    ACE_FILE, AceConfig, AceRecord, BodyLengths, DISCRIMINATOR_FILE, FORMAT_VERSION, GENERATOR_FILE, KIND, read_record,
};
use crate::human::layout as human_layout;

/// Fixed offsets mixed into [`AceConfig::seed`] so that G and D start from different draws.
const GENERATOR_STREAM: u64 = 0x6765_6e65_7261_746f;
const DISCRIMINATOR_STREAM: u64 = 0x6469_7363_7269_6d69;

/// The generator G with its own `VarStore` (variables under `generator.`).
#[derive(Debug)]
pub struct Generator {
    vs: nn::VarStore,
    net: Mlp,
    mask: Tensor,
}

impl Generator {
    /// A freshly initialised G (seeded by `cfg.seed`) mapping `(x^h, x^r_{t−1})` to a latent of width
    /// `latent`; `mask` is the prior's state mask (one value per x^r entry).
    pub fn new(cfg: &AceConfig, state_dim: usize, latent: usize, mask: &[f32], device: Device) -> Generator {
        assert_eq!(mask.len(), state_dim, "the mask needs one value per state entry");
        let vs = nn::VarStore::new(device);
        let mut rng = Pcg64::seed_from_u64(cfg.seed ^ GENERATOR_STREAM);
        let net = Mlp::new(
            &(vs.root() / "generator"),
            human_layout::DIM + state_dim,
            &cfg.generator_hidden,
            Activation::LEAKY_RELU,
            Some(latent),
            &mut rng,
        );
        Generator {
            mask: Tensor::from_slice(mask).view([1, -1]).to_device(device),
            vs,
            net,
        }
    }

    /// ẑ `[B, latent]` from the normalised human states `x_h: [B, 92]` and previous character states
    /// `prev: [B, D]`.
    pub fn forward(&self, x_h: &Tensor, prev: &Tensor) -> Tensor {
        self.net.forward(&Tensor::cat(&[x_h, &(prev * &self.mask)], 1))
    }

    /// The variables.
    pub fn var_store(&self) -> &nn::VarStore {
        &self.vs
    }

    /// The variables, mutably.
    pub fn var_store_mut(&mut self) -> &mut nn::VarStore {
        &mut self.vs
    }
}

/// The discriminator D with its own `VarStore` (variables under `discriminator.`).
#[derive(Debug)]
pub struct Discriminator {
    vs: nn::VarStore,
    net: Mlp,
    mask: Tensor,
}

impl Discriminator {
    /// A freshly initialised D (seeded by `cfg.seed`) over transitions of states of width
    /// `state_dim`; `mask` is the prior's state mask.
    pub fn new(cfg: &AceConfig, state_dim: usize, mask: &[f32], device: Device) -> Discriminator {
        assert_eq!(mask.len(), state_dim, "the mask needs one value per state entry");
        let vs = nn::VarStore::new(device);
        let mut rng = Pcg64::seed_from_u64(cfg.seed ^ DISCRIMINATOR_STREAM);
        let net = Mlp::new(
            &(vs.root() / "discriminator"),
            2 * state_dim,
            &cfg.discriminator_hidden,
            Activation::Silu,
            Some(1),
            &mut rng,
        );
        Discriminator {
            mask: Tensor::from_slice(mask).view([1, -1]).to_device(device),
            vs,
            net,
        }
    }

    /// The logits `[B]` of transitions `prev → cur` (`[B, D]` each, normalised); σ(logit) is the
    /// probability that the transition comes from the character dataset.
    pub fn forward(&self, prev: &Tensor, cur: &Tensor) -> Tensor {
        let input = Tensor::cat(&[prev * &self.mask, cur * &self.mask], 1);
        self.net.forward(&input).squeeze_dim(1)
    }

    /// The variables.
    pub fn var_store(&self) -> &nn::VarStore {
        &self.vs
    }

    /// The variables, mutably.
    pub fn var_store_mut(&mut self) -> &mut nn::VarStore {
        &mut self.vs
    }
}

/// The parts of [`discriminator_loss`] (scalars but for the logits).
#[derive(Debug)]
pub struct DiscriminatorLoss {
    /// `bce + gp`, what D minimises.
    pub total: Tensor,
    /// `−E_real[log D] − E_fake[log(1 − D)]`.
    pub bce: Tensor,
    /// The weighted gradient penalty `w_gp/2 · E_real[‖∇ logit‖²]`.
    pub gp: Tensor,
    /// Logits of the real transitions `[B]`.
    pub real_logits: Tensor,
    /// Logits of the fake transitions `[B']`.
    pub fake_logits: Tensor,
}

/// D's loss on real transitions `real_prev → real_cur` from the character dataset and generated ones
/// `fake_prev → fake_cur` (all normalised; the fakes are detached here), with the gradient penalty of
/// weight `w_gp` on the real transitions (see the module docs).
pub fn discriminator_loss(
    d: &Discriminator,
    real_prev: &Tensor,
    real_cur: &Tensor,
    fake_prev: &Tensor,
    fake_cur: &Tensor,
    w_gp: f64,
) -> DiscriminatorLoss {
    // Leaf copies of the real inputs, so that the penalty differentiates with respect to them.
    let rp = real_prev.detach().set_requires_grad(true);
    let rc = real_cur.detach().set_requires_grad(true);
    let real_logits = d.forward(&rp, &rc);
    let fake_logits = d.forward(&fake_prev.detach(), &fake_cur.detach());
    // −log σ(l) = softplus(−l) and −log(1 − σ(l)) = softplus(l), without overflow for large |l|.
    let bce = (-&real_logits).softplus().mean(Kind::Float) + fake_logits.softplus().mean(Kind::Float);
    let gp = if w_gp > 0.0 {
        let grads = Tensor::run_backward(&[real_logits.sum(Kind::Float)], &[&rp, &rc], true, true);
        let sq = grads[0].square().sum_dim_intlist(1, false, Kind::Float)
            + grads[1].square().sum_dim_intlist(1, false, Kind::Float);
        sq.mean(Kind::Float) * (w_gp / 2.0)
    } else {
        Tensor::zeros([], (Kind::Float, real_logits.device()))
    };
    DiscriminatorLoss {
        total: &bce + &gp,
        bce,
        gp,
        real_logits,
        fake_logits,
    }
}

/// G's adversarial loss `−E[log D(prev, cur)]` on generated transitions (a scalar).
pub fn generator_adv_loss(d: &Discriminator, prev: &Tensor, cur: &Tensor) -> Tensor {
    (-d.forward(prev, cur)).softplus().mean(Kind::Float)
}

/// G and D with their record: what training writes and inference reads.
#[derive(Debug)]
pub struct AceCheckpoint {
    /// The metadata (its file records are refreshed by [`AceCheckpoint::save`]).
    pub record: AceRecord,
    /// The generator.
    pub generator: Generator,
    /// The discriminator (`None` when loaded for inference only).
    pub discriminator: Option<Discriminator>,
}

impl AceRecord {
    /// Writes the weights of `generator` (and `discriminator`, if given) and this record as `ace.json`
    /// into `dir`, which must already hold the prior the networks were trained with (its weights file's
    /// checksum is recorded). The file records are refreshed. Each file goes to a temporary name first
    /// and is renamed into place, the weights before `ace.json`.
    pub fn save(
        &mut self,
        dir: &Path,
        generator: &Generator,
        discriminator: Option<&Discriminator>,
    ) -> Result<(), LearnError> {
        let prior_path = dir.join(PRIOR_WEIGHTS_FILE);
        self.prior = FileRecord::of(PRIOR_WEIGHTS_FILE, &read_file(&prior_path)?);
        self.prior_config = Some(FileRecord::of(PRIOR_CONFIG_FILE, &read_file(&dir.join(PRIOR_CONFIG_FILE))?));
        let mut moves: Vec<(PathBuf, PathBuf)> = Vec::new();
        let result = (|| {
            let mut stores = vec![(GENERATOR_FILE, generator.var_store())];
            if let Some(d) = discriminator {
                stores.push((DISCRIMINATOR_FILE, d.var_store()));
            }
            for (file, vs) in stores {
                // The temporary name keeps the `.safetensors` extension: tch picks the format by it.
                let tmp = crate::temporary::beside(&dir.join(file), Some("safetensors"));
                moves.push((tmp.clone(), dir.join(file)));
                vs.save(&tmp)?;
                let record = FileRecord::of(file, &read_file(&tmp)?);
                if file == GENERATOR_FILE {
                    self.generator = record;
                } else {
                    self.discriminator = record;
                }
            }
            let tmp = crate::temporary::beside(&dir.join(ACE_FILE), None);
            moves.push((tmp.clone(), dir.join(ACE_FILE)));
            let mut text = serde_json::to_string_pretty(&*self)
                .map_err(|e| LearnError::Config(format!("cannot serialise {ACE_FILE}: {e}")))?;
            text.push('\n');
            write_synced(&tmp, text.as_bytes())?;
            for (from, to) in &moves {
                fs::rename(from, to).map_err(|e| LearnError::io(to, e))?;
            }
            Ok(())
        })();
        if result.is_err() {
            for (from, _) in &moves {
                let _ = fs::remove_file(from);
            }
        }
        result
    }
}

impl AceCheckpoint {
    /// [`AceRecord::save`] of this checkpoint's record and networks.
    pub fn save(&mut self, dir: &Path) -> Result<(), LearnError> {
        self.record
            .save(dir, &self.generator, self.discriminator.as_ref())
    }

    /// Reads the ACE checkpoint in `dir` for the prior of latent width `prior_latent` and state mask
    /// `prior_mask` (one value per x^r entry) beside it, checking kind, version, the weights' shapes and checksums and that the
    /// prior's weights file is the one it was trained against. With `with_discriminator` false, D is
    /// neither read nor required.
    pub fn load(
        dir: &Path,
        prior_latent: usize,
        prior_mask: &[f32],
        device: Device,
        with_discriminator: bool,
    ) -> Result<AceCheckpoint, LearnError> {
        let files = CheckpointFiles::on_disk(dir);
        AceCheckpoint::load_files(&files, prior_latent, prior_mask, device, with_discriminator)
    }

    /// [`AceCheckpoint::load`] from files on disk or in memory.
    pub fn load_files(
        files: &CheckpointFiles,
        prior_latent: usize,
        prior_mask: &[f32],
        device: Device,
        with_discriminator: bool,
    ) -> Result<AceCheckpoint, LearnError> {
        let record = AceRecord::read(files, prior_mask)?;
        let dim = record.character.layout.dim();
        let generator = Generator::new(&record.config, dim, prior_latent, prior_mask, device);
        load_weights(files, GENERATOR_FILE, &record.generator, generator.var_store(), "network", ACE_FILE)?;
        let discriminator = if with_discriminator {
            let d = Discriminator::new(&record.config, dim, prior_mask, device);
            load_weights(files, DISCRIMINATOR_FILE, &record.discriminator, d.var_store(), "network", ACE_FILE)?;
            Some(d)
        } else {
            None
        };
        Ok(AceCheckpoint {
            record,
            generator,
            discriminator,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::collections::BTreeMap;

    use crate::correspondence::Correspondence;
    use crate::human::EndEffector;
    use crate::learn::prior::DeviceChoice;
    use crate::learn::checkpoint::Normaliser;
    use crate::learn::prior::test_support::spot;
    use crate::learn::rows_to_tensor;

    fn tiny() -> AceConfig {
        AceConfig {
            generator_hidden: vec![32, 32],
            discriminator_hidden: vec![32, 32],
            device: DeviceChoice::Cpu,
            ..AceConfig::default()
        }
    }

    /// A fresh D of [`tiny`] over the Spot test dataset's states, with its state mask.
    fn tiny_discriminator() -> Discriminator {
        let (tree, morph, set) = spot();
        let mask = crate::learn::prior::state_mask(tree, morph);
        Discriminator::new(&tiny(), set.layout.dim(), &mask, Device::Cpu)
    }

    /// Normalised consecutive frames `(i − 1, i)` of the Spot test dataset.
    fn transitions(frames: &[usize]) -> (Tensor, Tensor) {
        let set = &spot().2;
        let norm = Normaliser::of_set(set);
        let rows = |off: usize| {
            frames
                .iter()
                .map(|&i| set.state(i - off).to_vec())
                .collect::<Vec<_>>()
        };
        let t = |r: Vec<Vec<f32>>| norm.normalise(&rows_to_tensor(&r, Device::Cpu).unwrap());
        (t(rows(1)), t(rows(0)))
    }

    #[test]
    fn the_discriminator_sees_only_the_masked_in_state() {
        // Stretch's wheel angles are left out of the mask (they grow without bound as it drives).
        let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../assets/characters/stretch.urdf");
        let (tree, morph) = crate::morphology::load_character(&path).unwrap();
        let mask = crate::learn::prior::state_mask(&tree, &morph);
        let d = Discriminator::new(&tiny(), mask.len(), &mask, Device::Cpu);
        tch::manual_seed(3);
        let (p, c) = (Tensor::randn([3, mask.len() as i64], (Kind::Float, Device::Cpu)), Tensor::randn([3, mask.len() as i64], (Kind::Float, Device::Cpu)));
        let base = d.forward(&p, &c);
        assert_eq!(base.isfinite().all().int64_value(&[]), 1, "finite logits");
        let off = mask.iter().position(|&m| m == 0.0).expect("the mask leaves the wheels out");
        let on = mask.iter().position(|&m| m != 0.0).expect("the mask keeps entries");
        // `t` with column `k` set to 7.5.
        let bump = |t: &Tensor, k: usize| {
            let t = t.copy();
            let _ = t.narrow(1, k as i64, 1).fill_(7.5);
            t
        };
        for (k, seen) in [(off, false), (on, true)] {
            for logits in [d.forward(&bump(&p, k), &c), d.forward(&p, &bump(&c, k))] {
                let moved = (&logits - &base).abs().max().double_value(&[]);
                assert_eq!(moved > 1e-6, seen, "state entry {k} (mask {}): the logits moved by {moved}", mask[k]);
            }
        }
    }

    #[test]
    fn gradient_penalty_is_taken_on_the_real_samples() {
        let d = tiny_discriminator();
        let (rp, rc) = transitions(&[10, 200, 900, 1500]);
        let (rp2, rc2) = transitions(&[40, 600, 1200, 3000]);
        let (fp, fc) = transitions(&[20, 300, 700, 2500]);
        let fake_noise = fc.randn_like();
        let base = discriminator_loss(&d, &rp, &rc, &fp, &fc, 0.1);
        let gp = |l: &DiscriminatorLoss| l.gp.double_value(&[]);
        assert!(gp(&base) > 0.0);
        // Other fakes: the penalty stays, the cross-entropy moves.
        let other_fake = discriminator_loss(&d, &rp, &rc, &fp, &fake_noise, 0.1);
        assert_eq!(gp(&other_fake), gp(&base));
        assert_ne!(other_fake.bce.double_value(&[]), base.bce.double_value(&[]));
        // Other reals: the penalty moves.
        let other_real = discriminator_loss(&d, &rp2, &rc2, &fp, &fc, 0.1);
        assert!((gp(&other_real) - gp(&base)).abs() > 1e-9 * gp(&base));
        // It scales with w_gp, and total = bce + gp.
        let double = discriminator_loss(&d, &rp, &rc, &fp, &fc, 0.2);
        assert!((gp(&double) - 2.0 * gp(&base)).abs() < 1e-6 * gp(&base));
        let t = base.total.double_value(&[]);
        assert!((t - base.bce.double_value(&[]) - gp(&base)).abs() < 1e-6);
        // The penalty is differentiable in D's weights (it is part of what D minimises).
        base.total.backward();
        let w = d.var_store().variables()["discriminator.layer0.weight"].grad();
        assert!(w.abs().sum(Kind::Float).double_value(&[]) > 0.0);

        // A D that ignores its input (first layer all zero) has no input gradient: penalty 0.
        tch::no_grad(|| {
            let _ = d.var_store().variables()["discriminator.layer0.weight"]
                .shallow_clone()
                .zero_();
        });
        let blind = discriminator_loss(&d, &rp, &rc, &fp, &fc, 0.1);
        assert_eq!(gp(&blind), 0.0);
    }

    #[test]
    fn gradient_penalty_equals_finite_differences_over_both_frames() {
        let d = tiny_discriminator();
        let (rp, rc) = transitions(&[10, 200, 900]);
        let (fp, fc) = transitions(&[20, 300, 700]);
        let w_gp = 0.3;
        let got = discriminator_loss(&d, &rp, &rc, &fp, &fc, w_gp).gp.double_value(&[]);
        // w_gp/2 · mean over the real transitions of ‖∂logit/∂(x_{t−1}, x_t)‖², by central differences.
        let (n, dim) = (rp.size()[0], rp.size()[1]);
        let h = 1e-2;
        let mut sum = 0.0;
        tch::no_grad(|| {
            for i in 0..n {
                let (p, c) = (rp.narrow(0, i, 1).copy(), rc.narrow(0, i, 1).copy());
                for frame in 0..2 {
                    let x = if frame == 0 { &p } else { &c };
                    for k in 0..dim {
                        let v = x.double_value(&[0, k]);
                        let logit = |shift: f64| {
                            let y = x.copy();
                            let _ = y.narrow(1, k, 1).fill_(v + shift);
                            let l = if frame == 0 { d.forward(&y, &c) } else { d.forward(&p, &y) };
                            l.double_value(&[0])
                        };
                        let g = (logit(h) - logit(-h)) / (2.0 * h);
                        sum += g * g;
                    }
                }
            }
        });
        let expected = w_gp / 2.0 * sum / n as f64;
        assert!(expected > 1e-6, "{expected}");
        assert!((got - expected).abs() < 1e-2 * expected, "penalty {got}, finite differences {expected}");
    }

    #[test]
    fn cross_entropy_matches_the_paper_formula() {
        let d = tiny_discriminator();
        let (rp, rc) = transitions(&[5, 50, 500]);
        let (fp, fc) = transitions(&[7, 70, 700]);
        let l = discriminator_loss(&d, &rp, &rc, &fp, &fc, 0.0);
        let real = Vec::<f64>::try_from(l.real_logits.to_kind(Kind::Double)).unwrap();
        let fake = Vec::<f64>::try_from(l.fake_logits.to_kind(Kind::Double)).unwrap();
        let sig = |x: f64| 1.0 / (1.0 + (-x).exp());
        let want = -real.iter().map(|&x| sig(x).ln()).sum::<f64>() / 3.0
            - fake.iter().map(|&x| (1.0 - sig(x)).ln()).sum::<f64>() / 3.0;
        assert!(
            (l.bce.double_value(&[]) - want).abs() < 1e-5,
            "{} vs {want}",
            l.bce.double_value(&[])
        );
        assert_eq!(l.gp.double_value(&[]), 0.0);
        let adv = generator_adv_loss(&d, &fp, &fc).double_value(&[]);
        let want = -fake.iter().map(|&x| sig(x).ln()).sum::<f64>() / 3.0;
        assert!((adv - want).abs() < 1e-5);
    }

    #[test]
    fn manual_mapping_overrides_by_link_name() {
        use crate::correspondence::MappingSource;
        use crate::features::EndEffectorMapping;
        let auto = Correspondence {
            mapping: EndEffectorMapping::new(vec![Some(EndEffector::LeftFoot), Some(EndEffector::RightHand)]),
            character_links: vec!["foot".into(), "gripper".into()],
            scores: vec![vec![0.0; 5]; 2],
            source: MappingSource::Automatic,
        };
        let mut cfg = AceConfig::default();
        assert_eq!(cfg.resolve_mapping(auto.clone()).unwrap(), auto);
        cfg.end_effector_mapping = Some(BTreeMap::from([(
            "gripper".to_string(),
            Some(EndEffector::LeftHand),
        )]));
        let m = cfg.resolve_mapping(auto.clone()).unwrap();
        assert_eq!(
            m.mapping.human,
            vec![Some(EndEffector::LeftFoot), Some(EndEffector::LeftHand)]
        );
        assert_eq!(m.source, MappingSource::Manual);
        cfg.end_effector_mapping = Some(BTreeMap::from([("tail".to_string(), None)]));
        let e = cfg.resolve_mapping(auto).unwrap_err().to_string();
        assert!(e.contains("`tail`") && e.contains("foot, gripper"), "{e}");
    }

    #[test]
    fn configs_round_trip_through_json_and_check_ranges() {
        let paper = AceConfig::paper();
        assert_eq!(paper.generator_hidden, vec![512; 3]);
        assert_eq!(paper.discriminator_hidden, vec![512; 3]);
        assert_eq!(paper.w_gp, 0.1);
        let text = serde_json::to_string(&paper).unwrap();
        assert_eq!(serde_json::from_str::<AceConfig>(&text).unwrap(), paper);
        let partial: AceConfig = serde_json::from_str(r#"{"w_fea": 3.5}"#).unwrap();
        assert_eq!(partial.w_fea, 3.5);
        assert_eq!(partial.generator_hidden, AceConfig::default().generator_hidden);
        let bad = AceConfig {
            w_adv: -1.0,
            ..AceConfig::default()
        };
        assert!(bad.check().unwrap_err().to_string().contains("w_adv"));
        assert!(AceConfig::default().resumable_with(&AceConfig {
            steps: 99,
            ..AceConfig::default()
        }));
        assert!(!AceConfig::default().resumable_with(&AceConfig {
            w_fea: 0.0,
            ..AceConfig::default()
        }));
    }
}
