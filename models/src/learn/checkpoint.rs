//! Motion-prior checkpoints on disk, and the error type of the learning modules.
//!
//! One checkpoint is one directory holding two files:
//! - [`CONFIG_FILE`] (`config.json`, pretty JSON): `kind` = [`KIND`], `format_version` =
//!   [`FORMAT_VERSION`], the `character` ([`CharacterInfo`]: `name`, `state_dim`, `layout`
//!   `{dof, end_effectors}`, `dof_names`, `end_effector_links`), the full [`PriorConfig`] under `config`, the training `step`
//!   reached and the `seed`, the dataset's normalisation statistics `mean` and `std`, the state `mask`
//!   ([`super::prior::state_mask`]), the `bounds` `{lo, hi}` of the decoder's normalised output
//!   ([`StateBounds`]), a record of the weights file (`weights`: name, size in bytes and
//!   FNV-1a 64 checksum) and a free-form `provenance` value the caller fills (command line, data files,
//!   commit, …).
//! - [`WEIGHTS_FILE`] (`prior.safetensors`): every variable of the prior's `VarStore` as an F32 tensor
//!   named by its path (`encoder.layer0.weight`, `decoder.layer2.bias`, …).
//!
//! Both files are written under temporary names and renamed into place, the weights first, so a crash
//! never leaves a half-written file; the checksum in `config.json` ties the pair together. Loading
//! checks the kind and version, the shapes of every tensor against the configuration, the checksum
//! and, when asked, that the checkpoint belongs to the expected character. Every error names the file
//! or directory and the problem.

use std::fs;
use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};
use serde_json::Value;
use tch::{Device, TchError, Tensor};
use thiserror::Error;

use super::ShapeError;
use super::files::{CheckpointFiles, FileRecord, load_weights, read_json, write_synced};
use super::prior::{MotionPrior, PriorConfig};
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

/// Errors of the learning modules: checkpoints, configurations, training data and libtorch.
#[derive(Debug, Error)]
pub enum LearnError {
    /// A file that should exist does not.
    #[error("{}: missing file", path.display())]
    MissingFile {
        /// The file.
        path: PathBuf,
    },
    /// A file that exists but cannot be parsed, or whose content is inconsistent.
    #[error("{}: corrupt file: {problem}", path.display())]
    CorruptFile {
        /// The file.
        path: PathBuf,
        /// What is wrong.
        problem: String,
    },
    /// A file of another kind or format version.
    #[error("{}: {problem}", path.display())]
    Format {
        /// The file.
        path: PathBuf,
        /// What is wrong.
        problem: String,
    },
    /// Stored tensors whose names or shapes do not match the configuration.
    #[error("{}: shape mismatch: {problem}", path.display())]
    ShapeMismatch {
        /// The file.
        path: PathBuf,
        /// Which tensor and which shapes.
        problem: String,
    },
    /// A checkpoint made for another character than the one expected.
    #[error("{}: checkpoint of another character: {problem}", path.display())]
    WrongCharacter {
        /// The checkpoint directory.
        path: PathBuf,
        /// How the characters differ.
        problem: String,
    },
    /// A file or directory that cannot be read or written.
    #[error("{}: {source}", path.display())]
    Io {
        /// The file or directory.
        path: PathBuf,
        /// The operating system's error.
        source: std::io::Error,
    },
    /// A configuration value out of range, or a run directory that does not fit the configuration.
    #[error("invalid configuration: {0}")]
    Config(String),
    /// Training data that cannot be used (too short, wrong width, …).
    #[error("invalid training data: {0}")]
    Data(String),
    /// Tensors of the wrong shape handed to the learning code.
    #[error(transparent)]
    Shape(#[from] ShapeError),
    /// An error raised by libtorch.
    #[error("libtorch: {0}")]
    Torch(#[from] TchError),
}

impl LearnError {
    /// An [`LearnError::Io`] for `path`.
    pub fn io(path: &Path, source: std::io::Error) -> LearnError {
        LearnError::Io {
            path: path.to_path_buf(),
            source,
        }
    }
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

    fn tensors(&self, device: Device) -> (Tensor, Tensor) {
        (
            Tensor::from_slice(&self.mean).to_device(device),
            Tensor::from_slice(&self.std).to_device(device),
        )
    }

    /// `(x − mean) / std` for `x: [.., D]` (on `x`'s device).
    pub fn normalise(&self, x: &Tensor) -> Tensor {
        let (m, s) = self.tensors(x.device());
        (x - m) / s
    }

    /// `x·std + mean`, the inverse of [`Normaliser::normalise`].
    pub fn denormalise(&self, x: &Tensor) -> Tensor {
        let (m, s) = self.tensors(x.device());
        x * s + m
    }
}

/// Per-entry bounds of normalised states, `[lo, hi]`: the range a dataset spans, widened by a margin.
/// The prior's decoder output is clamped to them ([`MotionPrior::set_bounds`]); a checkpoint stores
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
}

impl CharacterInfo {
    /// The character of a dataset.
    pub fn of_set(set: &MotionSet) -> CharacterInfo {
        CharacterInfo {
            name: set.character.clone(),
            layout: set.layout,
            dof_names: set.dof_names.clone(),
            end_effector_links: set.end_effector_links.clone(),
        }
    }

    /// A loaded character.
    pub fn of_character(tree: &KinematicTree, morph: &Morphology) -> CharacterInfo {
        CharacterInfo {
            name: tree.name.clone(),
            layout: CharacterLayout::new(tree, morph),
            dof_names: tree.dof_names().into_iter().map(String::from).collect(),
            end_effector_links: morph.end_effector_links(tree),
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
        if self.layout != expected.layout || self.name != expected.name {
            return Some(format!(
                "it was trained for {}, expected {}",
                describe(self),
                describe(expected)
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
        None
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
        Ok(CharacterInfo {
            name: f.name,
            layout,
            dof_names: f.dof_names,
            end_effector_links: f.end_effector_links,
        })
    }
}

/// A trained (or training) motion prior with everything needed to use it: configuration,
/// normalisation statistics, mask, character and bookkeeping (see the module docs for the files).
#[derive(Debug)]
pub struct PriorCheckpoint {
    /// The configuration it was built and trained with.
    pub config: PriorConfig,
    /// The dataset's normalisation statistics; the networks work on normalised states.
    pub stats: Normaliser,
    /// 1 for every modelled state entry, 0 for entries the networks ignore (wheel angles).
    pub mask: Vec<f32>,
    /// The character.
    pub character: CharacterInfo,
    /// Optimiser steps done.
    pub step: usize,
    /// Free-form record of how it was made (command line, data files, commit, …).
    pub provenance: Value,
    /// The networks.
    pub prior: MotionPrior,
}

/// `config.json`, field order as written.
#[derive(Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
struct ConfigFile {
    kind: String,
    format_version: u32,
    character: CharacterInfo,
    step: usize,
    seed: u64,
    config: PriorConfig,
    mean: Vec<f32>,
    std: Vec<f32>,
    mask: Vec<f32>,
    bounds: StateBounds,
    weights: FileRecord,
    provenance: Value,
}

impl PriorCheckpoint {
    /// Writes the checkpoint into `dir` (created if needed), replacing any checkpoint there. Each file
    /// is written under a temporary name and renamed into place, the weights first.
    pub fn save(&self, dir: &Path) -> Result<(), LearnError> {
        fs::create_dir_all(dir).map_err(|e| LearnError::io(dir, e))?;
        let pid = std::process::id();
        let weights = dir.join(WEIGHTS_FILE);
        let config = dir.join(CONFIG_FILE);
        // The temporary weights name must keep the `.safetensors` extension: tch picks the format by it.
        let weights_tmp = dir.join(format!(".prior.{pid}.tmp.safetensors"));
        let config_tmp = dir.join(format!(".config.{pid}.tmp.json"));
        let cleanup = || {
            let _ = fs::remove_file(&weights_tmp);
            let _ = fs::remove_file(&config_tmp);
        };
        let result = (|| {
            self.prior.var_store().save(&weights_tmp)?;
            let bytes = fs::read(&weights_tmp).map_err(|e| LearnError::io(&weights_tmp, e))?;
            fs::File::open(&weights_tmp)
                .and_then(|f| f.sync_all())
                .map_err(|e| LearnError::io(&weights_tmp, e))?;
            let record = self.record(&bytes);
            let mut text = serde_json::to_string_pretty(&record)
                .map_err(|e| LearnError::Config(format!("cannot serialise the checkpoint: {e}")))?;
            text.push('\n');
            write_synced(&config_tmp, text.as_bytes())?;
            fs::rename(&weights_tmp, &weights).map_err(|e| LearnError::io(&weights, e))?;
            fs::rename(&config_tmp, &config).map_err(|e| LearnError::io(&config, e))
        })();
        if result.is_err() {
            cleanup();
        }
        result
    }

    fn record(&self, weights: &[u8]) -> ConfigFile {
        let c = &self.character;
        ConfigFile {
            kind: KIND.into(),
            format_version: FORMAT_VERSION,
            character: c.clone(),
            step: self.step,
            seed: self.config.seed,
            config: self.config.clone(),
            mean: self.stats.mean.clone(),
            std: self.stats.std.clone(),
            mask: self.mask.clone(),
            bounds: self.prior.state_bounds(),
            weights: FileRecord::of(WEIGHTS_FILE, weights),
            provenance: self.provenance.clone(),
        }
    }

    /// Reads the checkpoint in `dir` onto `device` (the configuration's device choice is not used),
    /// checking it (see the module docs).
    pub fn load(dir: &Path, device: Device) -> Result<PriorCheckpoint, LearnError> {
        PriorCheckpoint::load_files(&CheckpointFiles::on_disk(dir), device)
    }

    /// [`PriorCheckpoint::load`] from files on disk or in memory.
    pub fn load_files(files: &CheckpointFiles, device: Device) -> Result<PriorCheckpoint, LearnError> {
        let config_path = files.path(CONFIG_FILE);
        let record: ConfigFile = read_json(files, CONFIG_FILE, KIND, FORMAT_VERSION, "a motion-prior checkpoint")?;
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
        record.config.check().map_err(|e| corrupt(e.to_string()))?;

        let mut prior = MotionPrior::new(&record.config, dim, device);
        prior.set_mask(&record.mask).map_err(|e| corrupt(e.to_string()))?;
        prior
            .set_bounds(&record.bounds)
            .map_err(|e| corrupt(e.to_string()))?;
        load_weights(files, WEIGHTS_FILE, &record.weights, prior.var_store(), "prior", CONFIG_FILE)?;
        Ok(PriorCheckpoint {
            config: record.config,
            stats: Normaliser {
                mean: record.mean,
                std: record.std,
            },
            mask: record.mask,
            character: record.character,
            step: record.step,
            provenance: record.provenance,
            prior,
        })
    }

    /// [`PriorCheckpoint::load`], then [`PriorCheckpoint::check_character`] against a loaded character.
    pub fn load_for(
        dir: &Path,
        device: Device,
        tree: &KinematicTree,
        morph: &Morphology,
    ) -> Result<PriorCheckpoint, LearnError> {
        let ckpt = PriorCheckpoint::load(dir, device)?;
        ckpt.check_character(dir, &CharacterInfo::of_character(tree, morph))?;
        Ok(ckpt)
    }

    /// Fails with [`LearnError::WrongCharacter`] (naming `dir`) unless the checkpoint's character is
    /// `expected`: same name, layout, DoF names and end-effector links.
    pub fn check_character(&self, dir: &Path, expected: &CharacterInfo) -> Result<(), LearnError> {
        match self.character.difference(expected) {
            None => Ok(()),
            Some(problem) => Err(LearnError::WrongCharacter {
                path: dir.to_path_buf(),
                problem,
            }),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::learn::prior::test_support::{scratch_dir, spot_set, trained_spot_dir};
    use crate::morphology::load_character;
    use tch::Kind;

    fn character(name: &str) -> (KinematicTree, Morphology) {
        let path = Path::new(env!("CARGO_MANIFEST_DIR")).join(format!("../assets/characters/{name}.urdf"));
        load_character(&path).unwrap()
    }

    #[test]
    fn save_then_load_gives_identical_outputs() {
        let dir = trained_spot_dir();
        let a = PriorCheckpoint::load(dir, Device::Cpu).unwrap();
        let copy = scratch_dir("ckpt_copy");
        let mut a2 = a;
        a2.provenance = serde_json::json!({"command": "test"});
        a2.save(&copy).unwrap();
        let (tree, morph) = character("spot");
        let b = PriorCheckpoint::load_for(&copy, Device::Cpu, &tree, &morph).unwrap();
        assert_eq!(b.config, a2.config);
        assert_eq!(b.stats, a2.stats);
        assert_eq!(b.mask, a2.mask);
        assert_eq!(b.prior.state_bounds(), a2.prior.state_bounds());
        assert!(
            b.prior.state_bounds().hi.iter().all(|&h| h < 1e3),
            "trained bounds come from the data"
        );
        assert_eq!(b.character, a2.character);
        assert_eq!(b.step, a2.step);
        assert_eq!(b.provenance["command"], "test");
        assert!(b.step > 0);

        let set = spot_set();
        let rows = super::super::rows_to_tensor(
            &set.states.chunks(set.layout.dim()).take(64).collect::<Vec<_>>(),
            Device::Cpu,
        )
        .unwrap();
        let x = a2.stats.normalise(&rows);
        let z = Tensor::randn([63, a2.prior.latent_dim() as i64], (Kind::Float, Device::Cpu));
        let prev = x.narrow(0, 0, 63);
        let ya = a2.prior.decode(&z, &prev);
        let yb = b.prior.decode(&z, &prev);
        assert!(ya.equal(&yb), "decode differs after save → load");
        let (ma, la) = a2.prior.encode(&prev, &x.narrow(0, 1, 63));
        let (mb, lb) = b.prior.encode(&prev, &x.narrow(0, 1, 63));
        assert!(ma.equal(&mb) && la.equal(&lb));
        // The directory holds exactly the two files: no temporaries left behind.
        let mut names: Vec<String> = fs::read_dir(&copy)
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .collect();
        names.sort();
        assert_eq!(names, [CONFIG_FILE, WEIGHTS_FILE]);
        let text = fs::read_to_string(copy.join(CONFIG_FILE)).unwrap();
        let v: Value = serde_json::from_str(&text).unwrap();
        assert_eq!(v["kind"], KIND);
        assert_eq!(v["character"]["state_dim"], set.layout.dim());
        assert_eq!(v["character"]["dof_names"][0], set.dof_names[0].as_str());
        fs::remove_dir_all(&copy).unwrap();
    }

    #[test]
    fn damaged_checkpoints_give_errors_naming_the_file() {
        let src = trained_spot_dir();
        let dir = scratch_dir("ckpt_damaged");
        let copy_in = |dir: &Path| {
            fs::create_dir_all(dir).unwrap();
            for f in [CONFIG_FILE, WEIGHTS_FILE] {
                fs::copy(src.join(f), dir.join(f)).unwrap();
            }
        };
        let weights = dir.join(WEIGHTS_FILE);
        let config = dir.join(CONFIG_FILE);

        // Truncated weights.
        copy_in(&dir);
        let bytes = fs::read(&weights).unwrap();
        fs::write(&weights, &bytes[..bytes.len() / 2]).unwrap();
        let e = PriorCheckpoint::load(&dir, Device::Cpu).unwrap_err();
        assert!(
            matches!(e, LearnError::CorruptFile { ref path, .. } if *path == weights),
            "{e}"
        );
        assert!(e.to_string().contains("prior.safetensors: corrupt file"), "{e}");

        // One flipped byte inside a tensor: still parses, the checksum catches it.
        let mut flipped = bytes.clone();
        let n = flipped.len();
        flipped[n - 3] ^= 0x40;
        fs::write(&weights, &flipped).unwrap();
        let e = PriorCheckpoint::load(&dir, Device::Cpu).unwrap_err();
        assert!(
            e.to_string().contains("prior.safetensors: corrupt file") && e.to_string().contains("checksum"),
            "{e}"
        );

        // Missing weights.
        fs::remove_file(&weights).unwrap();
        let e = PriorCheckpoint::load(&dir, Device::Cpu).unwrap_err();
        assert!(
            matches!(e, LearnError::MissingFile { ref path } if *path == weights),
            "{e}"
        );
        assert!(e.to_string().ends_with("prior.safetensors: missing file"), "{e}");

        // config.json that is not JSON, then of another version.
        copy_in(&dir);
        fs::write(&config, "{\"kind\": \"ace_motion_prior\", ").unwrap();
        let e = PriorCheckpoint::load(&dir, Device::Cpu).unwrap_err();
        assert!(
            e.to_string()
                .contains("config.json: corrupt file: not valid JSON"),
            "{e}"
        );
        let text = fs::read_to_string(src.join(CONFIG_FILE)).unwrap();
        let mut v: Value = serde_json::from_str(&text).unwrap();
        v["format_version"] = 99.into();
        fs::write(&config, v.to_string()).unwrap();
        let e = PriorCheckpoint::load(&dir, Device::Cpu).unwrap_err();
        assert!(
            e.to_string()
                .contains("config.json: format version 99 is not supported"),
            "{e}"
        );

        // A character whose stored width disagrees with its layout.
        let mut v: Value = serde_json::from_str(&text).unwrap();
        v["character"]["state_dim"] = 7.into();
        fs::write(&config, v.to_string()).unwrap();
        let e = PriorCheckpoint::load(&dir, Device::Cpu).unwrap_err();
        assert!(
            e.to_string().contains("config.json: corrupt file")
                && e.to_string().contains("state_dim 7 disagrees with the layout"),
            "{e}"
        );

        // A configuration whose networks are wider than the stored weights.
        let mut v: Value = serde_json::from_str(&text).unwrap();
        let h = v["config"]["decoder_hidden"][0].as_u64().unwrap();
        v["config"]["decoder_hidden"][0] = (h + 4).into();
        fs::write(&config, v.to_string()).unwrap();
        let e = PriorCheckpoint::load(&dir, Device::Cpu).unwrap_err();
        assert!(
            matches!(e, LearnError::ShapeMismatch { ref path, .. } if *path == weights),
            "{e}"
        );
        assert!(
            e.to_string().contains("tensor `decoder.layer0.") && e.to_string().contains("68]"),
            "{e}"
        );

        // No config.json at all.
        fs::remove_file(&config).unwrap();
        let e = PriorCheckpoint::load(&dir, Device::Cpu).unwrap_err();
        assert!(e.to_string().ends_with("config.json: missing file"), "{e}");
        fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn a_checkpoint_of_another_character_is_refused() {
        let (crab_tree, crab_morph) = character("crab");
        let crab = CharacterInfo::of_character(&crab_tree, &crab_morph);
        let spot = CharacterInfo::of_set(spot_set());
        let dim = crab.layout.dim();
        let cfg = super::super::prior::test_support::tiny_config();
        let ckpt = PriorCheckpoint {
            prior: MotionPrior::new(&cfg, dim, Device::Cpu),
            config: cfg,
            stats: Normaliser {
                mean: vec![0.0; dim],
                std: vec![1.0; dim],
            },
            mask: super::super::prior::state_mask(&crab_tree, &crab_morph),
            character: crab,
            step: 0,
            provenance: Value::Null,
        };
        let dir = scratch_dir("ckpt_crab");
        ckpt.save(&dir).unwrap();
        // It loads as itself...
        PriorCheckpoint::load_for(&dir, Device::Cpu, &crab_tree, &crab_morph).unwrap();
        // ...but not for Spot.
        let (spot_tree, spot_morph) = character("spot");
        let e = PriorCheckpoint::load_for(&dir, Device::Cpu, &spot_tree, &spot_morph).unwrap_err();
        assert!(
            matches!(e, LearnError::WrongCharacter { ref path, .. } if *path == dir),
            "{e}"
        );
        let msg = e.to_string();
        assert!(
            msg.contains("trained for `crab`") && msg.contains("expected `spot`"),
            "{msg}"
        );
        assert_eq!(CharacterInfo::of_character(&spot_tree, &spot_morph), spot);
        fs::remove_dir_all(&dir).unwrap();
    }
}
