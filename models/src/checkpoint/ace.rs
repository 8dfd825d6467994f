//! The adversarial stage's files: `ace.json` ([`AceRecord`]: the character, the [`AceConfig`], the
//! correspondence, the x^h statistics, the body lengths, the records of the weights files) beside
//! `generator.safetensors` and `discriminator.safetensors`. See `learn::ace` (feature `learn`) for the format.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};
use serde_json::Value;

use super::LearnError;
use super::files::{CheckpointFiles, FileRecord, read_json};
use super::prior::{CONFIG_FILE as PRIOR_CONFIG_FILE, CharacterInfo, DeviceChoice, WEIGHTS_FILE as PRIOR_WEIGHTS_FILE};
use crate::correspondence::Correspondence;
use crate::features::{FeatureBlock, FeatureWeights};
use crate::human::{EndEffector, layout as human_layout};
use crate::human_set::{HumanSplit, HumanStats};

/// The `kind` of `ace.json`.
pub const KIND: &str = "ace_adversarial";
/// The format version of `ace.json` this build writes and reads.
pub const FORMAT_VERSION: u32 = 1;
/// Name of the metadata file.
pub const ACE_FILE: &str = "ace.json";
/// Name of the generator's weights file.
pub const GENERATOR_FILE: &str = "generator.safetensors";
/// Name of the discriminator's weights file.
pub const DISCRIMINATOR_FILE: &str = "discriminator.safetensors";

/// Sizes and training settings of the adversarial stage. Every field has a default (the CPU
/// defaults, sized for about a quarter of an hour per character on two CPU cores);
/// [`AceConfig::paper`] gives the paper's network sizes. JSON may give any subset.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct AceConfig {
    /// Hidden layer widths of G (paper: 512 × 3).
    pub generator_hidden: Vec<usize>,
    /// Hidden layer widths of D (paper: 512 × 3).
    pub discriminator_hidden: Vec<usize>,
    /// Weight of the adversarial loss w_adv.
    pub w_adv: f64,
    /// Weight of the feature loss w_fea.
    pub w_fea: f64,
    /// Per-block weights inside the feature loss.
    pub feature_weights: FeatureWeights,
    /// Compare the root height and end-effector positions in L_fea as displacements from each
    /// body's mean pose ([`crate::features`], "Centring"); `false` compares them as they are.
    pub centre_features: bool,
    /// Compare the root's linear velocity in L_fea at the character dataset's speed scale
    /// ([`crate::features`], "Speed"); `false` compares body lengths per second on both sides.
    pub match_speed_scale: bool,
    /// Compute the end-effector positions of the generated states' Ψ in L_fea from their joint
    /// positions by forward kinematics (`learn::psi`, "End effectors by forward kinematics");
    /// `false` reads the prior's predicted end-effector entries, as every run did before this setting
    /// existed (their `ace.json` has no such field and reads as `false`).
    pub kinematic_features: bool,
    /// Compute the root's velocities of the generated states' Ψ in L_fea from their displacement and
    /// delta rotation, which carry the root that is shown (`learn::psi`, "Root
    /// velocities from the root's motion"); `false` reads the states' velocity entries, as every run
    /// did before this setting existed (their `ace.json` has no such field and reads as `false`).
    pub kinematic_root: bool,
    /// Weight of the gradient penalty w_gp (paper: 0.1).
    pub w_gp: f64,
    /// Adam's learning rate for G.
    pub generator_lr: f64,
    /// Adam's learning rate for D.
    pub discriminator_lr: f64,
    /// Adam's β₁ for both (0.5 is the usual choice for adversarial training).
    pub adam_beta1: f64,
    /// Human windows (and real transitions) per step.
    pub batch_size: usize,
    /// Frames per human window: G and π are rolled out over this many frames (gradients reach back
    /// this far).
    pub window: usize,
    /// Consecutive windows a rollout continues for: each step picks the human clip up where the last
    /// window ended and the character where G left it, and every this many steps (or when its clip
    /// ends) a rollout starts again from a random window and a random dataset state. 1 starts every
    /// window afresh.
    pub rollout_windows: usize,
    /// Generator steps.
    pub steps: usize,
    /// Discriminator updates per generator step (0 keeps D fixed; it is still evaluated for the log).
    pub discriminator_steps: usize,
    /// A checkpoint is saved every this many steps (and at the end).
    pub checkpoint_every: usize,
    /// Seed of initialisation and of every random draw of training.
    pub seed: u64,
    /// Where to train: the device the caller loads the prior onto (`learn::train_ace::train_ace`
    /// runs wherever the prior is).
    pub device: DeviceChoice,
    /// Manual end-effector mapping: character end-effector link name → human end effector (`null`
    /// leaves that end effector out of Ψ). Entries override the automatic correspondence; links not
    /// listed keep it.
    pub end_effector_mapping: Option<BTreeMap<String, Option<EndEffector>>>,
}

impl Default for AceConfig {
    fn default() -> Self {
        AceConfig {
            generator_hidden: vec![256; 3],
            discriminator_hidden: vec![256; 3],
            w_adv: 1.0,
            w_fea: 10.0,
            feature_weights: FeatureWeights::default(),
            centre_features: true,
            match_speed_scale: true,
            kinematic_features: true,
            kinematic_root: true,
            w_gp: 0.1,
            // At 2e-4 the Spot run collapsed after 3,260 steps (D took over, L_adv jumped from 1 to 8);
            // at 1e-4 it stayed balanced to the end and its held-out FID was lower.
            generator_lr: 1e-4,
            discriminator_lr: 1e-4,
            adam_beta1: 0.5,
            batch_size: 128,
            window: 8,
            rollout_windows: 8,
            steps: 4000,
            discriminator_steps: 1,
            checkpoint_every: 250,
            seed: 0,
            device: DeviceChoice::Auto,
            end_effector_mapping: None,
        }
    }
}

impl AceConfig {
    /// The paper's network sizes (§6.4): G and D both 512 × 3.
    pub fn paper() -> Self {
        AceConfig {
            generator_hidden: vec![512; 3],
            discriminator_hidden: vec![512; 3],
            batch_size: 256,
            steps: 20_000,
            checkpoint_every: 1000,
            ..AceConfig::default()
        }
    }

    /// Checks that every value is in range.
    pub fn check(&self) -> Result<(), LearnError> {
        use super::limits::{self, in_range};
        let bad = |m: String| Err(LearnError::Config(m));
        in_range("batch_size", self.batch_size, 1, limits::BATCH_SIZE)?;
        in_range("window", self.window, 1, limits::WINDOW)?;
        in_range("rollout_windows", self.rollout_windows, 1, limits::STEPS)?;
        in_range("steps", self.steps, 1, limits::STEPS)?;
        in_range("checkpoint_every", self.checkpoint_every, 1, limits::STEPS)?;
        in_range("discriminator_steps", self.discriminator_steps, 0, 1_000)?;
        limits::widths("generator_hidden", &self.generator_hidden)?;
        limits::widths("discriminator_hidden", &self.discriminator_hidden)?;
        // What the sizes come to together.
        let frames = self.batch_size as u128 * self.window as u128;
        limits::budget("`batch_size` × `window` (frames per step)", frames, limits::STEP_FRAMES, "lower batch_size or window")?;
        let (g, d) = (&self.generator_hidden, &self.discriminator_hidden);
        limits::budget(
            "the weights between the hidden layers of `generator_hidden` and `discriminator_hidden`",
            limits::hidden_weights(g) + limits::hidden_weights(d),
            limits::HIDDEN_WEIGHTS,
            "use fewer or narrower hidden layers",
        )?;
        limits::budget(
            "`batch_size` × `window` × the widths of `generator_hidden` and `discriminator_hidden` (hidden activations per step)",
            frames * (limits::width_sum(g) + limits::width_sum(d)),
            limits::ACTIVATIONS,
            "lower batch_size or window, or use fewer or narrower hidden layers",
        )?;
        self.feature_weights.check().map_err(LearnError::Config)?;
        for (name, v) in [("generator_lr", self.generator_lr), ("discriminator_lr", self.discriminator_lr)] {
            limits::float_in_range(name, v, 0.0, limits::LEARNING_RATE, true)?;
        }
        for (name, v) in [("w_adv", self.w_adv), ("w_fea", self.w_fea), ("w_gp", self.w_gp)] {
            limits::float_in_range(name, v, 0.0, limits::LOSS_WEIGHT, false)?;
        }
        if self.w_adv == 0.0 && self.w_fea == 0.0 {
            return bad("w_adv and w_fea are both zero: the generator would have nothing to learn".into());
        }
        let weights = &self.feature_weights;
        if self.w_adv == 0.0 && FeatureBlock::ALL.iter().all(|&b| weights.weight(b) == 0.0) {
            return bad("w_adv is zero and every `feature_weights` entry too: the generator would have nothing to learn".into());
        }
        if !(0.0..1.0).contains(&self.adam_beta1) {
            return bad(format!("`adam_beta1` = {} is out of range: expected 0 to less than 1", self.adam_beta1));
        }
        Ok(())
    }

    /// True when a run with `other` may resume from a checkpoint made with `self`: everything but
    /// `steps`, `checkpoint_every` and `device` agrees.
    pub fn resumable_with(&self, other: &AceConfig) -> bool {
        let neutral = |c: &AceConfig| AceConfig {
            steps: 0,
            checkpoint_every: 1,
            device: DeviceChoice::Cpu,
            ..c.clone()
        };
        neutral(self) == neutral(other)
    }

    /// Fails when [`AceConfig::end_effector_mapping`] names a link that is not one of the character's
    /// end effectors `links` ([`crate::morphology::Morphology::end_effector_links`]), listing them: a
    /// check that needs only the character, made before the dataset and the human clips are loaded.
    pub fn check_mapping_links(&self, links: &[String]) -> Result<(), LearnError> {
        let Some(manual) = &self.end_effector_mapping else {
            return Ok(());
        };
        match manual.keys().find(|link| !links.contains(link)) {
            None => Ok(()),
            Some(link) => Err(LearnError::Config(format!(
                "end_effector_mapping: `{link}` is not an end effector of the character (they are: {})",
                links.join(", ")
            ))),
        }
    }

    /// Applies [`AceConfig::end_effector_mapping`] to an automatic correspondence. Unknown link
    /// names are an error that lists the character's end effectors.
    pub fn resolve_mapping(&self, automatic: Correspondence) -> Result<Correspondence, LearnError> {
        let Some(manual) = &self.end_effector_mapping else {
            return Ok(automatic);
        };
        let mut overrides = Vec::with_capacity(manual.len());
        for (link, human) in manual {
            let index = automatic.link_index(link).ok_or_else(|| {
                LearnError::Config(format!(
                    "end_effector_mapping: `{link}` is not an end effector of the character (they are: {})",
                    automatic.character_links.join(", ")
                ))
            })?;
            overrides.push((index, *human));
        }
        automatic
            .with_overrides(&overrides)
            .map_err(|e| LearnError::Config(format!("end_effector_mapping: {e}")))
    }
}

/// The body lengths Ψ was normalised with during training.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct BodyLengths {
    /// The character's (m).
    pub character: f32,
    /// One length for every human clip (m), when given; else each clip's own.
    pub human_override: Option<f32>,
    /// Each training clip's own body length (m), by relative path.
    pub human_clips: BTreeMap<String, f32>,
}

/// Reads the configuration stored in `ace.json`. One written before [`AceConfig::kinematic_features`]
/// (or [`AceConfig::kinematic_root`]) existed trained on the prior's predicted end-effector (root
/// velocity) entries, so there the missing setting reads as `false`; a partial configuration a user
/// gives still gets the default.
fn stored_config<'de, D: serde::Deserializer<'de>>(d: D) -> Result<AceConfig, D::Error> {
    let mut v = Value::deserialize(d)?;
    if let Some(o) = v.as_object_mut() {
        o.entry("kinematic_features").or_insert(Value::Bool(false));
        o.entry("kinematic_root").or_insert(Value::Bool(false));
    }
    serde_json::from_value(v).map_err(serde::de::Error::custom)
}

/// Everything `ace.json` holds (see the module docs), in file order.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct AceRecord {
    /// [`KIND`].
    pub kind: String,
    /// [`FORMAT_VERSION`].
    pub format_version: u32,
    /// The character.
    pub character: CharacterInfo,
    /// Generator steps done.
    pub step: usize,
    /// The configuration.
    #[serde(deserialize_with = "stored_config")]
    pub config: AceConfig,
    /// The end-effector correspondence Ψ used, with its scores and source.
    pub correspondence: Correspondence,
    /// x^h normalisation statistics (over the training clips).
    pub human_stats: HumanStats,
    /// The folder the human clips came from.
    pub human_folder: PathBuf,
    /// The held-out split of the human clips.
    pub human_split: HumanSplit,
    /// Body lengths of Ψ.
    pub body_lengths: BodyLengths,
    /// Added to the human's Ψ before L_fea compares it ([`crate::features::centring_offset`]); empty
    /// when trained without centring (and in checkpoints from before it).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub feature_offset: Vec<f32>,
    /// The dataset controller's speed scale at which L_fea compares the root's linear velocity
    /// ([`crate::features::human_speed_factor`]); absent when trained without it (and in
    /// checkpoints from before it), which compares body lengths per second.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub speed_scale: Option<f32>,
    /// The generator's weights file.
    pub generator: FileRecord,
    /// The discriminator's weights file.
    pub discriminator: FileRecord,
    /// The prior's weights file G was trained against.
    pub prior: FileRecord,
    /// The prior's `config.json` (its normalisation, state bounds and mask) G was trained against;
    /// absent in checkpoints saved before it was recorded, which are not checked for it.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub prior_config: Option<FileRecord>,
    /// Free-form record of how it was made (command line, data files, commit, …).
    pub provenance: Value,
}

impl AceRecord {
    /// Reads and checks `ace.json` for the prior beside it, of state mask `prior_mask` (one value per
    /// x^r entry): kind and version, a configuration in range, the character's state width, the x^h
    /// statistics (positive deviations, no implausible entry: [`implausible_human_stat`]), and that the prior's weights file is the one G was trained against. Errors name the
    /// file.
    pub fn read(files: &CheckpointFiles, prior_mask: &[f32]) -> Result<AceRecord, LearnError> {
        let dir = files.dir();
        let path = files.path(ACE_FILE);
        // Read after the prior: a folder without it holds a prior alone (`ace train-prior`'s output).
        let record: AceRecord = read_json(files, ACE_FILE, KIND, FORMAT_VERSION, "an ACE checkpoint").map_err(|e| match e {
            LearnError::MissingFile { path } => LearnError::Format {
                problem: format!(
                    "missing file: the checkpoint holds a motion prior only; `ace train --checkpoint {}` trains its generator",
                    dir.display()
                ),
                path,
            },
            e => e,
        })?;
        let corrupt = |problem: String| LearnError::CorruptFile {
            path: path.clone(),
            problem,
        };
        record.config.check().map_err(|e| corrupt(e.to_string()))?;
        record.check_fields().map_err(corrupt)?;
        let dim = record.character.layout.dim();
        if prior_mask.len() != dim {
            return Err(LearnError::WrongCharacter {
                path: path.clone(),
                problem: format!(
                    "`{}` has states of width {dim}, the prior in {} has {}",
                    record.character.name,
                    dir.display(),
                    prior_mask.len()
                ),
            });
        }
        for (name, len) in [
            ("mean", record.human_stats.mean.len()),
            ("std", record.human_stats.std.len()),
        ] {
            if len != human_layout::DIM {
                return Err(corrupt(format!(
                    "`human_stats.{name}` has {len} entries, x^h has {}",
                    human_layout::DIM
                )));
            }
        }
        if let Some(i) = record
            .human_stats
            .std
            .iter()
            .position(|s| !(s.is_finite() && *s > 0.0))
        {
            return Err(corrupt(format!("`human_stats.std` entry {i} is not positive")));
        }
        if let Some(k) = implausible_human_stat(&record.human_stats.mean, &record.human_stats.std) {
            return Err(corrupt(format!(
                "`human_stats` entry {k} has mean {} and standard deviation {}: no human motion gives more than \
                 {MAX_HUMAN_STAT} (the clips it was trained on held absurd values); retrain with clips the importer \
                 accepts",
                record.human_stats.mean[k], record.human_stats.std[k]
            )));
        }
        record
            .prior
            .verify(&files.path(PRIOR_WEIGHTS_FILE), &files.read(PRIOR_WEIGHTS_FILE)?, ACE_FILE)?;
        if let Some(config) = &record.prior_config {
            config.verify(&files.path(PRIOR_CONFIG_FILE), &files.read(PRIOR_CONFIG_FILE)?, ACE_FILE)?;
        }
        Ok(record)
    }
}

impl AceRecord {
    /// Checks the fields the scorer and the editor index by end effector or divide by: the
    /// correspondence has one entry per character end effector (its links the character's, a score
    /// per human end effector), the centring offset is Ψ's width, the speed scale and body lengths are
    /// finite and positive. The problem names the field and what would be valid.
    fn check_fields(&self) -> Result<(), String> {
        let links = &self.character.end_effector_links;
        let corr = &self.correspondence;
        let n = links.len();
        if corr.mapping.human.len() != n {
            return Err(format!(
                "`correspondence.mapping.human` has {} entries; it needs one per end effector of `{}` ({n})",
                corr.mapping.human.len(),
                self.character.name
            ));
        }
        if &corr.character_links != links {
            return Err(format!(
                "`correspondence.character_links` is [{}]; it must be the character's end-effector links [{}]",
                corr.character_links.join(", "),
                links.join(", ")
            ));
        }
        let humans = EndEffector::ALL.len();
        if corr.scores.len() != n || corr.scores.iter().any(|row| row.len() != humans) {
            return Err(format!(
                "`correspondence.scores` must have {n} rows (one per end effector) of {humans} scores (one per human \
                 end effector)"
            ));
        }
        let width = crate::features::FeatureLayout::new(&corr.mapping).dim();
        let offset = &self.feature_offset;
        if !(offset.is_empty() || offset.len() == width) || offset.iter().any(|v| !v.is_finite()) {
            return Err(format!(
                "`feature_offset` has {} entries; it must be empty or hold {width} finite values (Ψ's width)",
                offset.len()
            ));
        }
        let positive = |v: f32| v.is_finite() && v > 0.0;
        for (field, value) in [
            ("speed_scale", self.speed_scale),
            ("body_lengths.character", Some(self.body_lengths.character)),
            ("body_lengths.human_override", self.body_lengths.human_override),
        ] {
            if let Some(v) = value.filter(|&v| !positive(v)) {
                return Err(format!("`{field}` is {v}; it must be finite and positive"));
            }
        }
        Ok(())
    }

    /// Fails with [`LearnError::WrongCharacter`] (naming `dir`'s `ace.json`) unless the generator was
    /// trained for `prior_character`, the character of the prior beside it.
    pub fn check_prior(&self, dir: &Path, prior_character: &CharacterInfo) -> Result<(), LearnError> {
        match self.character.difference(prior_character) {
            None => Ok(()),
            Some(problem) => Err(LearnError::WrongCharacter {
                path: dir.join(ACE_FILE),
                problem: format!("the generator does not match the prior beside it: {problem}"),
            }),
        }
    }
}

impl AceRecord {
    /// The character file training recorded (`provenance.character_file`: its path, size and
    /// checksum); `None` for a checkpoint made before it was recorded or by hand.
    pub fn character_file(&self) -> Option<FileRecord> {
        serde_json::from_value(self.provenance.get("character_file")?.clone()).ok()
    }

    /// Says how far the generator's training got when it stopped before the steps its configuration
    /// asks for (interrupted, or out of time); `None` when it ran them all. Such a checkpoint runs, but
    /// its networks are part-trained.
    pub fn unfinished(&self) -> Option<String> {
        (self.step < self.config.steps).then(|| {
            format!(
                "the checkpoint's generator trained {} of its {} steps: its training stopped early, and the same \
                 `ace train` run again on the checkpoint resumes it",
                self.step, self.config.steps
            )
        })
    }

    /// How `file`, the record of a character file ([`FileRecord::of`] its bytes, named by its path),
    /// differs from the one the checkpoint was trained with ([`other_character_file`]); `None` when it
    /// is that file or the checkpoint does not record one.
    pub fn character_file_difference(&self, file: &FileRecord) -> Option<String> {
        other_character_file(&self.character_file()?, file)
    }
}

/// How `file` (a character file's record, named by its path) differs from `recorded`, the one a
/// checkpoint was trained with, or `None` when it is that file: same size and checksum, whatever the
/// path. The character check ([`CharacterInfo::difference`]) has passed by then: same joints, end
/// effectors and size. An edited file that keeps those (other meshes, limits, masses or capsules) is
/// refused by nothing, and is worth a warning: the networks learned the other file's geometry.
pub fn other_character_file(recorded: &FileRecord, file: &FileRecord) -> Option<String> {
    (!recorded.same_content(file)).then(|| {
        format!(
            "{} is not the character file the checkpoint was trained with (`{}`: {} bytes, checksum {}; this \
             one: {} bytes, checksum {}). Its joints and size match, so the checkpoint runs, but the networks \
             learned the other file's geometry: retrain if the edit changed the body",
            file.file, recorded.file, recorded.bytes, recorded.fnv1a64, file.bytes, file.fnv1a64
        )
    })
}

/// Largest plausible |mean| or standard deviation of an x^h entry (metres, m/s, rad/s, unit
/// quaternion components): far above any human motion, far below what one corrupt clip produces.
pub const MAX_HUMAN_STAT: f32 = 1e3;

/// The first x^h entry whose normalisation statistics no human motion gives: a mean of more than
/// [`MAX_HUMAN_STAT`] in magnitude, a standard deviation above it, or either not finite. Training
/// refuses such statistics before anything is saved; [`AceRecord::read`] refuses a checkpoint that
/// holds them (made before the check, or edited).
pub fn implausible_human_stat(mean: &[f32], std: &[f32]) -> Option<usize> {
    mean.iter()
        .zip(std)
        .position(|(m, s)| !(m.abs() <= MAX_HUMAN_STAT && *s <= MAX_HUMAN_STAT))
}

/// Reads the `ace.json` in `dir`, checking kind and version before the rest.
pub fn read_record(dir: &Path) -> Result<AceRecord, LearnError> {
    read_json(&CheckpointFiles::on_disk(dir), ACE_FILE, KIND, FORMAT_VERSION, "an ACE checkpoint")
}

#[cfg(test)]
mod tests {
    use std::path::PathBuf;

    use super::*;

    fn root() -> PathBuf {
        Path::new(env!("CARGO_MANIFEST_DIR")).join("..")
    }

    #[test]
    fn a_configuration_that_leaves_the_generator_nothing_to_learn_is_refused() {
        let mut c = AceConfig { w_adv: 0.0, ..AceConfig::default() };
        c.check().unwrap();
        c.feature_weights = FeatureWeights { root_height: 0.0, root_orientation: 0.0, root_linear_velocity: 0.0, root_angular_velocity: 0.0, ee_positions: 0.0 };
        // g_loss was 0 at every step of such a run.
        assert!(c.check().unwrap_err().to_string().contains("w_adv is zero and every `feature_weights` entry too"));
        c.feature_weights.ee_positions = 1.0;
        c.check().unwrap();
        // The discriminator alone is the ablation without L_fea: it learns.
        let mut c = AceConfig { w_fea: 1.0, ..c };
        c.feature_weights.ee_positions = 0.0;
        c.w_adv = 1.0;
        c.check().unwrap();
    }

    #[test]
    fn a_checkpoint_tells_another_version_of_its_character_file_by_content() {
        let record = read_record(&root().join("assets/checkpoints/crab")).unwrap();
        let recorded = record.character_file().expect("the crab's checkpoint records its URDF");
        let bundled = std::fs::read(root().join(&recorded.file)).unwrap();
        // The file trained with, under any name: nothing to say.
        assert_eq!(record.character_file_difference(&FileRecord::of("elsewhere/crab.urdf", &bundled)), None);
        // A comment more: another file. The warning names it and both sizes and checksums.
        let mut edited = bundled.clone();
        edited.extend_from_slice(b"<!-- edited -->\n");
        let now = FileRecord::of("my/crab.urdf", &edited);
        let w = record.character_file_difference(&now).expect("an edited file is told");
        for part in ["my/crab.urdf", &recorded.file, &recorded.fnv1a64, &now.fnv1a64, &format!("{} bytes", edited.len())] {
            assert!(w.contains(part), "`{part}` missing from: {w}");
        }
        // The same size with one bit changed: the checksum tells.
        let mut flipped = bundled.clone();
        flipped[bundled.len() / 2] ^= 1;
        assert!(record.character_file_difference(&FileRecord::of("crab.urdf", &flipped)).is_some());
        // A checkpoint that recorded no character file has nothing to compare.
        let mut old = record.clone();
        old.provenance = serde_json::json!({ "command": "ace train" });
        assert_eq!(old.character_file(), None);
        assert_eq!(old.character_file_difference(&now), None);
    }

    #[test]
    fn the_shipped_checkpoints_were_trained_on_the_bundled_files_as_they_are() {
        let mut compared = Vec::new();
        for name in ["spot", "crab", "stretch", "hound"] {
            let record = read_record(&root().join("assets/checkpoints").join(name)).unwrap();
            let Some(recorded) = record.character_file() else { continue };
            let bytes = std::fs::read(root().join(&recorded.file))
                .unwrap_or_else(|e| panic!("{name}: the recorded character file {}: {e}", recorded.file));
            assert_eq!(
                record.character_file_difference(&FileRecord::of(&recorded.file, &bytes)),
                None,
                "{name}: the bundled character file changed since its checkpoint was trained; retrain it"
            );
            compared.push(name);
        }
        assert!(compared.len() >= 3, "only {compared:?} record their character files");
    }
}
