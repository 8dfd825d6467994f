//! Motion-prior checkpoints on disk with their networks (the files without tensors, and the error type,
//! are [`crate::checkpoint`]; they are re-exported here).
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
use std::path::Path;

use serde_json::Value;
use tch::{Device, Tensor};

use super::files::{CheckpointFiles, FileRecord, load_weights, write_synced};
use super::prior::{MotionPrior, PriorConfig};
pub use crate::checkpoint::LearnError;
pub use crate::checkpoint::prior::{
    CONFIG_FILE, CharacterInfo, FORMAT_VERSION, KIND, Normaliser, StateBounds, WEIGHTS_FILE,
};
use crate::checkpoint::prior::PriorRecord;
use crate::kinematics::KinematicTree;
use crate::morphology::Morphology;

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

/// The tensor side of [`Normaliser`].
impl Normaliser {
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

impl PriorCheckpoint {
    /// Writes the checkpoint into `dir` (created if needed), replacing any checkpoint there. Each file
    /// is written under a temporary name and renamed into place, the weights first.
    pub fn save(&self, dir: &Path) -> Result<(), LearnError> {
        fs::create_dir_all(dir).map_err(|e| LearnError::io(dir, e))?;
        let weights = dir.join(WEIGHTS_FILE);
        let config = dir.join(CONFIG_FILE);
        // The temporary weights name must keep the `.safetensors` extension: tch picks the format by it.
        let weights_tmp = crate::temporary::beside(&weights, Some("safetensors"));
        let config_tmp = crate::temporary::beside(&config, None);
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

    fn record(&self, weights: &[u8]) -> PriorRecord {
        let c = &self.character;
        PriorRecord {
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
        let record = PriorRecord::read(files)?;
        let corrupt = |problem: String| LearnError::CorruptFile {
            path: files.path(CONFIG_FILE),
            problem,
        };
        let dim = record.character.layout.dim();
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
        self.character.check(dir, expected)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::learn::prior::test_support::{scratch_dir, spot_set, trained_spot_dir};
    use crate::test_data::bundled_character as character;
    use tch::Kind;

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
