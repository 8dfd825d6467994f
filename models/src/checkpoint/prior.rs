//! The motion prior's files: `config.json` (`PriorRecord`: the character, the [`PriorConfig`], the
//! normalisation statistics, the state mask and bounds, the weights file's record) beside
//! `prior.safetensors`. See `learn::checkpoint` (feature `learn`) for the format.

use serde::{Deserialize, Serialize};
use serde_json::Value;

use super::LearnError;
use super::files::{CheckpointFiles, FileRecord, read_json};
use crate::character_state::CharacterLayout;
use crate::dataset::MotionSet;
use crate::kinematics::KinematicTree;
use crate::morphology::Morphology;

/// The `kind` of a motion-prior checkpoint.
pub const KIND: &str = "ace_motion_prior";
/// The checkpoint format version this build writes and reads.
pub const FORMAT_VERSION: u32 = 1;
/// Name of the configuration and metadata file in a checkpoint directory.
pub const CONFIG_FILE: &str = "config.json";
/// Name of the weights file in a checkpoint directory.
pub const WEIGHTS_FILE: &str = "prior.safetensors";

/// Where training and inference run.
///
/// Written `"auto"`, `"cpu"`, `"cuda"` (device 0), `"cuda:N"` or `{ cuda = N }`.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum DeviceChoice {
    /// The first CUDA device when libtorch sees one, else the CPU.
    #[default]
    Auto,
    /// The CPU.
    Cpu,
    /// CUDA device `n`.
    Cuda(usize),
}

impl<'de> Deserialize<'de> for DeviceChoice {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        struct V;
        const EXPECTED: &str = "\"auto\", \"cpu\", \"cuda\", \"cuda:N\" or { cuda = N }";
        impl<'de> serde::de::Visitor<'de> for V {
            type Value = DeviceChoice;
            fn expecting(&self, f: &mut std::fmt::Formatter) -> std::fmt::Result {
                f.write_str(EXPECTED)
            }
            fn visit_str<E: serde::de::Error>(self, s: &str) -> Result<DeviceChoice, E> {
                match s {
                    "auto" => Ok(DeviceChoice::Auto),
                    "cpu" => Ok(DeviceChoice::Cpu),
                    "cuda" => Ok(DeviceChoice::Cuda(0)),
                    _ => s
                        .strip_prefix("cuda:")
                        .and_then(|n| n.parse().ok())
                        .map(DeviceChoice::Cuda)
                        .ok_or_else(|| E::custom(format!("unknown device `{s}`: expected {EXPECTED}"))),
                }
            }
            fn visit_map<A: serde::de::MapAccess<'de>>(self, mut m: A) -> Result<DeviceChoice, A::Error> {
                let key: String = m
                    .next_key()?
                    .ok_or_else(|| serde::de::Error::custom(format!("empty device table: expected {EXPECTED}")))?;
                if key != "cuda" {
                    return Err(serde::de::Error::custom(format!("unknown device `{key}`: expected {EXPECTED}")));
                }
                let n: usize = m.next_value()?;
                if let Some(k) = m.next_key::<String>()? {
                    return Err(serde::de::Error::custom(format!("unexpected `{k}` in the device table: expected {EXPECTED}")));
                }
                Ok(DeviceChoice::Cuda(n))
            }
        }
        d.deserialize_any(V)
    }
}

/// The probability of feeding the model's own prediction as the next previous state, as a function of
/// training progress: 0 until fraction `start` of the steps, then rising linearly to `max_probability`
/// at fraction `end`, then constant (MVAE's supervised → scheduled → autoregressive phases).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct SamplingSchedule {
    /// Fraction of the steps trained on data only.
    pub start: f64,
    /// Fraction of the steps at which the probability reaches `max_probability`.
    pub end: f64,
    /// Final probability.
    pub max_probability: f64,
}

impl Default for SamplingSchedule {
    fn default() -> Self {
        SamplingSchedule {
            start: 0.1,
            end: 0.3,
            max_probability: 1.0,
        }
    }
}

impl SamplingSchedule {
    /// The probability at optimiser step `step` of `steps`.
    pub fn probability(&self, step: usize, steps: usize) -> f64 {
        let f = step as f64 / steps.max(1) as f64;
        if f < self.start {
            0.0
        } else if f >= self.end {
            self.max_probability
        } else {
            self.max_probability * (f - self.start) / (self.end - self.start)
        }
    }
}

/// Sizes and training settings of the motion prior. Every field has a default (the CPU defaults, sized
/// for a run of about a quarter of an hour on two CPU cores); [`PriorConfig::paper`] gives the paper's
/// network sizes. JSON may give any subset.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct PriorConfig {
    /// Width of z (paper: 32).
    pub latent: usize,
    /// Hidden layer widths of the encoder (paper: 512 × 4).
    pub encoder_hidden: Vec<usize>,
    /// Hidden layer widths of the decoder's main network, before its output layer (paper: 512 × 3).
    pub decoder_hidden: Vec<usize>,
    /// Number of experts K (paper: 8).
    pub experts: usize,
    /// Hidden layer widths of the decoder's gating network.
    pub gating_hidden: Vec<usize>,
    /// β, the weight of the KL term (per-entry KL against per-entry squared error). Small enough that z
    /// carries the transition, which ACE's generator needs to steer the character: on Spot, decoding
    /// with the encoder's z had 1.4 times less error than with z = 0 at β = 0.5, six times less at 0.05.
    pub kl_weight: f64,
    /// Free bits λ (nats per latent entry, 0 = off): each latent entry's batch-mean KL counts as at
    /// least λ in the loss, so entries below it cost nothing and the latent is not driven to collapse.
    /// A character whose next state follows almost entirely from the previous one (a wheeled base
    /// whose commands change rarely) otherwise ends with a decoder that ignores z, which leaves ACE's
    /// generator nothing to steer.
    pub free_bits: f64,
    /// Adam's learning rate.
    pub learning_rate: f64,
    /// Windows per optimiser step.
    pub batch_size: usize,
    /// Optimiser steps.
    pub steps: usize,
    /// Transitions per window (the rollout length of scheduled sampling).
    pub rollout: usize,
    /// Probability of feeding back the model's own prediction over training.
    pub sampling: SamplingSchedule,
    /// A checkpoint is saved every this many steps (and at the end).
    pub checkpoint_every: usize,
    /// Margin of the output bounds, as a fraction of each entry's range in the data ([`StateBounds`]).
    pub bound_margin: f64,
    /// Seed of every random draw of initialisation and training.
    pub seed: u64,
    /// Where to train.
    pub device: DeviceChoice,
}

impl Default for PriorConfig {
    fn default() -> Self {
        PriorConfig {
            latent: 32,
            encoder_hidden: vec![256; 4],
            decoder_hidden: vec![256; 3],
            experts: 8,
            gating_hidden: vec![64, 64],
            kl_weight: 0.05,
            free_bits: 0.0,
            learning_rate: 3e-4,
            batch_size: 64,
            steps: 16_000,
            rollout: 8,
            sampling: SamplingSchedule::default(),
            checkpoint_every: 500,
            bound_margin: 0.25,
            seed: 0,
            device: DeviceChoice::Auto,
        }
    }
}

impl PriorConfig {
    /// The paper's sizes (§6.4): encoder 512 × 4, decoder 8 experts of 512 units × 3 layers, z of 32.
    /// The paper does not give the optimisation settings; these follow MVAE.
    pub fn paper() -> Self {
        PriorConfig {
            encoder_hidden: vec![512; 4],
            decoder_hidden: vec![512; 3],
            learning_rate: 1e-4,
            steps: 40_000,
            checkpoint_every: 1000,
            ..PriorConfig::default()
        }
    }

    /// Checks that every value is in range.
    pub fn check(&self) -> Result<(), LearnError> {
        use super::limits::{self, in_range};
        let bad = |m: String| Err(LearnError::Config(m));
        let s = &self.sampling;
        in_range("latent", self.latent, 1, limits::LATENT)?;
        in_range("experts", self.experts, 1, 256)?;
        in_range("batch_size", self.batch_size, 1, limits::BATCH_SIZE)?;
        in_range("rollout", self.rollout, 1, limits::WINDOW)?;
        in_range("steps", self.steps, 1, limits::STEPS)?;
        in_range("checkpoint_every", self.checkpoint_every, 1, limits::STEPS)?;
        limits::widths("encoder_hidden", &self.encoder_hidden)?;
        limits::widths("decoder_hidden", &self.decoder_hidden)?;
        limits::widths("gating_hidden", &self.gating_hidden)?;
        // What the sizes come to together (the decoder's experts each have their own weights and, in the
        // blend, their own activations).
        let frames = self.batch_size as u128 * self.rollout as u128;
        limits::budget("`batch_size` × `rollout` (frames per step)", frames, limits::STEP_FRAMES, "lower batch_size or rollout")?;
        let experts = self.experts as u128;
        let (e, d, g) = (&self.encoder_hidden, &self.decoder_hidden, &self.gating_hidden);
        limits::budget(
            "the weights between the hidden layers of `encoder_hidden`, `experts` × `decoder_hidden` and `gating_hidden`",
            limits::hidden_weights(e) + experts * limits::hidden_weights(d) + limits::hidden_weights(g),
            limits::HIDDEN_WEIGHTS,
            "use fewer experts or fewer or narrower hidden layers",
        )?;
        limits::budget(
            "`batch_size` × `rollout` × the widths of `encoder_hidden`, `experts` × `decoder_hidden` and `gating_hidden` (hidden activations per step)",
            frames * (limits::width_sum(e) + experts * limits::width_sum(d) + limits::width_sum(g)),
            limits::ACTIVATIONS,
            "lower batch_size or rollout, or use fewer experts or fewer or narrower hidden layers",
        )?;
        limits::float_in_range("learning_rate", self.learning_rate, 0.0, limits::LEARNING_RATE, true)?;
        // A margin of a whole range on each side already leaves the outputs three times the data's span.
        limits::float_in_range("bound_margin", self.bound_margin, 0.0, 1.0, false)?;
        // Nats per latent dimension the KL term leaves free; a standard normal prior's entropy is ~1.4.
        limits::float_in_range("free_bits", self.free_bits, 0.0, 100.0, false)?;
        limits::float_in_range("kl_weight", self.kl_weight, 0.0, limits::LOSS_WEIGHT, false)?;
        let ordered = 0.0 <= s.start && s.start <= s.end && s.end <= 1.0;
        if !ordered || !(0.0..=1.0).contains(&s.max_probability) {
            return bad(format!(
                "sampling needs 0 ≤ start ≤ end ≤ 1 and max_probability in [0, 1], not {s:?}"
            ));
        }
        Ok(())
    }

    /// True when `other` builds the same networks and trains them the same way, so that a run with
    /// `other` may resume from a checkpoint made with `self`: everything but `steps`,
    /// `checkpoint_every` and `device` must agree.
    pub fn resumable_with(&self, other: &PriorConfig) -> bool {
        let neutral = |c: &PriorConfig| PriorConfig {
            steps: 0,
            checkpoint_every: 1,
            device: DeviceChoice::Cpu,
            ..c.clone()
        };
        neutral(self) == neutral(other)
    }
}

/// The entries of x^r the networks model: 1 for every entry except the joint positions of wheel DoFs
/// ([`Morphology::wheels`]), which are 0.
pub fn state_mask(tree: &KinematicTree, morph: &Morphology) -> Vec<f32> {
    let layout = CharacterLayout::new(tree, morph);
    let mut mask = vec![1.0; layout.dim()];
    let q0 = layout.joint_positions().start;
    for d in morph.wheel_dofs(tree) {
        mask[q0 + d] = 0.0;
    }
    mask
}

/// Per-entry normalisation statistics of a state vector: `(x − mean) / std`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Normaliser {
    /// Mean of each entry.
    pub mean: Vec<f32>,
    /// Standard deviation of each entry (positive).
    pub std: Vec<f32>,
}

impl Normaliser {
    /// The statistics a dataset was stored with.
    pub fn of_set(set: &MotionSet) -> Normaliser {
        Normaliser {
            mean: set.mean.clone(),
            std: set.std.clone(),
        }
    }

    /// Number of entries.
    pub fn dim(&self) -> usize {
        self.mean.len()
    }
}

/// Per-entry bounds of normalised states, `[lo, hi]`: the range a dataset spans, widened by a margin.
/// The prior's decoder output is clamped to them (`MotionPrior::set_bounds`); a checkpoint stores
/// the prior's bounds in `config.json`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct StateBounds {
    /// Lower bound of each entry.
    pub lo: Vec<f32>,
    /// Upper bound of each entry.
    pub hi: Vec<f32>,
}

impl StateBounds {
    /// Practically no bounds: `[−f32::MAX, f32::MAX]` for each of `dim` entries (finite, so that JSON
    /// can hold them).
    pub fn unbounded(dim: usize) -> StateBounds {
        StateBounds {
            lo: vec![-f32::MAX; dim],
            hi: vec![f32::MAX; dim],
        }
    }

    /// The normalised range of every entry over the frames of `set`, widened on each side by `margin`
    /// times its width; entries the mask zeroes get `[0, 0]`.
    pub fn of_set(set: &MotionSet, mask: &[f32], margin: f64) -> StateBounds {
        let dim = set.layout.dim();
        let mut lo = vec![f32::INFINITY; dim];
        let mut hi = vec![f32::NEG_INFINITY; dim];
        for row in set.states.chunks_exact(dim) {
            for (j, &x) in row.iter().enumerate() {
                let v = (x - set.mean[j]) / set.std[j];
                lo[j] = lo[j].min(v);
                hi[j] = hi[j].max(v);
            }
        }
        for j in 0..dim {
            if mask.get(j).is_some_and(|&m| m == 0.0) || lo[j] > hi[j] {
                (lo[j], hi[j]) = (0.0, 0.0);
            } else {
                let pad = (f64::from(hi[j] - lo[j]) * margin) as f32;
                (lo[j], hi[j]) = (lo[j] - pad, hi[j] + pad);
            }
        }
        StateBounds { lo, hi }
    }
}

/// The character a checkpoint was trained for. Stored as the `character` object of both `config.json`
/// and `ace.json`; reading it checks that the widths agree.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(into = "CharacterFile", try_from = "CharacterFile")]
pub struct CharacterInfo {
    /// Robot name.
    pub name: String,
    /// Layout of its state x^r.
    pub layout: CharacterLayout,
    /// Joint name of each DoF.
    pub dof_names: Vec<String>,
    /// End-effector link names, in state order.
    pub end_effector_links: Vec<String>,
    /// How many of `end_effector_links` (the first) are feet; `None` in checkpoints written before it
    /// was recorded. A profile can make a foot an arm and keep the list as it was.
    pub feet: Option<usize>,
}

impl CharacterInfo {
    /// The character of a dataset.
    pub fn of_set(set: &MotionSet) -> CharacterInfo {
        CharacterInfo {
            name: set.character.clone(),
            layout: set.layout,
            dof_names: set.dof_names.clone(),
            end_effector_links: set.end_effector_links.clone(),
            feet: Some(set.n_feet),
        }
    }

    /// A loaded character.
    pub fn of_character(tree: &KinematicTree, morph: &Morphology) -> CharacterInfo {
        CharacterInfo {
            name: tree.name.clone(),
            layout: CharacterLayout::new(tree, morph),
            dof_names: tree.dof_names().into_iter().map(String::from).collect(),
            end_effector_links: morph.end_effector_links(tree),
            feet: Some(morph.feet.len()),
        }
    }

    /// `None` when `self` (stored) and `expected` are the same character, else how they differ.
    pub fn difference(&self, expected: &CharacterInfo) -> Option<String> {
        let describe = |c: &CharacterInfo| {
            format!(
                "`{}` ({} DoF, {} end effectors, state dim {})",
                c.name,
                c.layout.dof,
                c.layout.end_effectors,
                c.layout.dim()
            )
        };
        let same_body = self.layout == expected.layout
            && self.dof_names == expected.dof_names
            && self.end_effector_links == expected.end_effector_links;
        if same_body && self.name != expected.name {
            return Some(format!(
                "it was trained for `{}`, and this character, with the same joints and end effectors, is named `{}`; \
                 a checkpoint runs only on the character it names (a URDF's `<robot name>`, a glTF creature's file \
                 name): give the character that name, or train for it",
                self.name, expected.name
            ));
        }
        if self.layout != expected.layout || self.name != expected.name {
            return Some(format!(
                "it was trained for {}, expected {}{}",
                describe(self),
                describe(expected),
                if self.layout.dof != expected.layout.dof || self.layout.end_effectors != expected.layout.end_effectors {
                    " (a profile beside the character file, `<name>.profile.toml`, sets its DoFs and end effectors: \
                     is the one it was trained with there?)"
                } else {
                    ""
                }
            ));
        }
        if let Some((a, b)) = self
            .dof_names
            .iter()
            .zip(&expected.dof_names)
            .find(|(a, b)| a != b)
        {
            return Some(format!(
                "`{}`: stored DoF `{a}` where the character has `{b}`",
                self.name
            ));
        }
        if let Some((a, b)) = self
            .end_effector_links
            .iter()
            .zip(&expected.end_effector_links)
            .find(|(a, b)| a != b)
        {
            return Some(format!(
                "`{}`: stored end effector `{a}` where the character has `{b}`",
                self.name
            ));
        }
        if let (Some(a), Some(b)) = (self.feet, expected.feet)
            && a != b
        {
            let feet = |n: usize| self.end_effector_links[..n.min(self.end_effector_links.len())].join(", ");
            return Some(format!(
                "`{}`: it was trained with {a} feet ({}), and the character has {b} ({}): its profile \
                 (`<name>.profile.toml`) gives the end effectors other roles",
                self.name,
                feet(a),
                feet(b)
            ));
        }
        None
    }
}

impl CharacterInfo {
    /// Fails with [`LearnError::WrongCharacter`] (naming `dir`, the checkpoint) unless `self`, the
    /// stored character, is `expected`: same name, layout, DoF names and end-effector links.
    pub fn check(&self, dir: &std::path::Path, expected: &CharacterInfo) -> Result<(), LearnError> {
        match self.difference(expected) {
            None => Ok(()),
            Some(problem) => Err(LearnError::WrongCharacter {
                path: dir.to_path_buf(),
                problem,
            }),
        }
    }
}

/// [`CharacterInfo`] as stored: the state width is written out so a reader sees it without adding up
/// the layout, and is checked on reading.
#[derive(Clone, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
struct CharacterFile {
    name: String,
    state_dim: usize,
    layout: LayoutFile,
    dof_names: Vec<String>,
    end_effector_links: Vec<String>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    feet: Option<usize>,
}

#[derive(Clone, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
struct LayoutFile {
    dof: usize,
    end_effectors: usize,
}

impl From<CharacterInfo> for CharacterFile {
    fn from(c: CharacterInfo) -> CharacterFile {
        CharacterFile {
            name: c.name,
            state_dim: c.layout.dim(),
            layout: LayoutFile {
                dof: c.layout.dof,
                end_effectors: c.layout.end_effectors,
            },
            dof_names: c.dof_names,
            end_effector_links: c.end_effector_links,
            feet: c.feet,
        }
    }
}

impl TryFrom<CharacterFile> for CharacterInfo {
    type Error = String;

    fn try_from(f: CharacterFile) -> Result<CharacterInfo, String> {
        let layout = CharacterLayout {
            dof: f.layout.dof,
            end_effectors: f.layout.end_effectors,
        };
        if f.state_dim != layout.dim() {
            return Err(format!(
                "character `{}`: state_dim {} disagrees with the layout ({} DoF, {} end effectors: width {})",
                f.name,
                f.state_dim,
                layout.dof,
                layout.end_effectors,
                layout.dim()
            ));
        }
        if f.dof_names.len() != layout.dof || f.end_effector_links.len() != layout.end_effectors {
            return Err(format!(
                "character `{}`: {} DoF names and {} end-effector links for a layout of {} and {}",
                f.name,
                f.dof_names.len(),
                f.end_effector_links.len(),
                layout.dof,
                layout.end_effectors
            ));
        }
        if f.feet.is_some_and(|n| n > layout.end_effectors) {
            return Err(format!("character `{}`: {:?} feet among {} end effectors", f.name, f.feet, layout.end_effectors));
        }
        Ok(CharacterInfo {
            name: f.name,
            layout,
            dof_names: f.dof_names,
            end_effector_links: f.end_effector_links,
            feet: f.feet,
        })
    }
}

/// `config.json`, field order as written (see [`PriorRecord::read`]).
#[derive(Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct PriorRecord {
    pub(crate) kind: String,
    pub(crate) format_version: u32,
    pub(crate) character: CharacterInfo,
    pub(crate) step: usize,
    pub(crate) seed: u64,
    pub(crate) config: PriorConfig,
    pub(crate) mean: Vec<f32>,
    pub(crate) std: Vec<f32>,
    pub(crate) mask: Vec<f32>,
    pub(crate) bounds: StateBounds,
    pub(crate) weights: FileRecord,
    pub(crate) provenance: Value,
}

/// Largest magnitude of a state entry's mean in `config.json`: states are metres, radians and their
/// rates, so no character's average anywhere near it.
pub const MAX_STATE_MEAN: f32 = 1e3;

impl PriorRecord {
    /// Reads and checks `config.json`: kind and version, then every per-entry list one value per state
    /// entry, positive standard deviations, means within [`MAX_STATE_MEAN`], finite bounds in order, a
    /// mask of 0s and 1s, and a configuration in range. Errors name the file.
    pub(crate) fn read(files: &CheckpointFiles) -> Result<PriorRecord, LearnError> {
        let config_path = files.path(CONFIG_FILE);
        let record: PriorRecord = read_json(files, CONFIG_FILE, KIND, FORMAT_VERSION, "a motion-prior checkpoint")?;
        let corrupt = |problem: String| LearnError::CorruptFile {
            path: config_path.clone(),
            problem,
        };
        let dim = record.character.layout.dim();
        for (name, len) in [
            ("mean", record.mean.len()),
            ("std", record.std.len()),
            ("mask", record.mask.len()),
            ("bounds.lo", record.bounds.lo.len()),
            ("bounds.hi", record.bounds.hi.len()),
        ] {
            if len != dim {
                return Err(corrupt(format!(
                    "`{name}` has {len} entries, the state has {dim}"
                )));
            }
        }
        if let Some(i) = record.std.iter().position(|s| !(s.is_finite() && *s > 0.0)) {
            return Err(corrupt(format!(
                "`std` entry {i} is {}, not positive",
                record.std[i]
            )));
        }
        // The prior's outputs are `mean + std · x` clamped to the bounds: an absurd mean or inverted
        // bounds gave a wrong motion with rc 0, an infinite one (`1e39` in JSON) NaN at export.
        if let Some(i) = record.mean.iter().position(|m| !(m.abs() <= MAX_STATE_MEAN)) {
            return Err(corrupt(format!(
                "`mean` entry {i} is {}; a state entry's mean is finite and at most {MAX_STATE_MEAN} in magnitude",
                record.mean[i]
            )));
        }
        let StateBounds { lo, hi } = &record.bounds;
        if let Some(i) = (0..dim).position(|i| !(lo[i].is_finite() && hi[i].is_finite() && lo[i] <= hi[i])) {
            return Err(corrupt(format!(
                "`bounds` entry {i} is [{}, {}]; each entry's bounds are finite, with `lo` ≤ `hi`",
                lo[i], hi[i]
            )));
        }
        if let Some(i) = record.mask.iter().position(|&m| m != 0.0 && m != 1.0) {
            return Err(corrupt(format!("`mask` entry {i} is {}; the mask holds 0 or 1", record.mask[i])));
        }
        record.config.check().map_err(|e| corrupt(e.to_string()))?;
        Ok(record)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::morphology::load_character;

    fn bundled(name: &str) -> CharacterInfo {
        let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join(format!("../assets/characters/{name}.urdf"));
        let (tree, morph) = load_character(&path).unwrap();
        CharacterInfo::of_character(&tree, &morph)
    }

    #[test]
    fn a_difference_says_what_differs_and_where_it_comes_from() {
        let spot = bundled("spot");
        assert_eq!(spot.difference(&spot.clone()), None);
        // Only the name: said as such (it read like two characters of the same size).
        let renamed = CharacterInfo { name: "my_spot".into(), ..spot.clone() };
        let d = spot.difference(&renamed).unwrap();
        assert!(d.starts_with("it was trained for `spot`, and this character, with the same joints and end effectors, is named `my_spot`"), "{d}");
        // Other joints: the profile, which sets them, is named.
        let d = spot.difference(&bundled("crab")).unwrap();
        assert!(d.starts_with("it was trained for `spot` (18 DoF, 5 end effectors") && d.contains("`<name>.profile.toml`"), "{d}");
        let mut other_joint = spot.clone();
        other_joint.dof_names[0] = "hip".into();
        let d = spot.difference(&other_joint).unwrap();
        assert!(d.starts_with(&format!("`spot`: stored DoF `{}` where the character has `hip`", spot.dof_names[0])), "{d}");
        // A foot made an arm by a profile keeps the end-effector list: the feet say it.
        let three_feet = CharacterInfo { feet: Some(3), ..spot.clone() };
        let d = spot.difference(&three_feet).unwrap();
        assert_eq!(
            d,
            "`spot`: it was trained with 4 feet (fl_foot, fr_foot, rl_foot, rr_foot), and the character has 3 (fl_foot, \
             fr_foot, rl_foot): its profile (`<name>.profile.toml`) gives the end effectors other roles"
        );
        // A checkpoint from before the feet were recorded is read as it was.
        assert_eq!(CharacterInfo { feet: None, ..spot.clone() }.difference(&three_feet), None);
    }
}
