//! Inference with trained checkpoints in pure Rust, without libtorch: what a game ships.
//!
//! A [`Retargeter`] reads a checkpoint directory's files as training wrote them (`config.json`,
//! `prior.safetensors`, `ace.json`, `generator.safetensors`; the discriminator is not needed) through
//! the same checks as the libtorch path ([`crate::checkpoint`]), and runs, per frame and for each
//! character of a batch, `ẑ = G(x^h_t, x^r_{t−1})` and `x^r_t = π(ẑ, x^r_{t−1})` (`nets`): the x^h
//! normalisation, the generator, the prior's gated mixture of experts, its state mask and the clamp to
//! its state bounds. Turning states into poses — root integration, joint limits, wheel angles rolled
//! from the base motion, the cleanup — is [`decode`], which the libtorch path
//! (`crate::learn::retarget`, feature `learn`) uses as well; both give the same poses up to float
//! rounding (the tests of `runtime::equivalence`, with `learn`).

pub mod decode;
pub(crate) mod nets;

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use crate::checkpoint::ace::{AceRecord, GENERATOR_FILE};
use crate::checkpoint::files::{CheckpointFiles, read_weights};
use crate::checkpoint::prior::{CONFIG_FILE, PriorRecord, WEIGHTS_FILE};
use crate::checkpoint::{CharacterInfo, LearnError, Normaliser};
use crate::cleanup::Cleanup;
use crate::human::HumanClip;
use crate::human::layout as human_layout;
use crate::human_set::HumanRow;
use crate::kinematics::KinematicTree;
use crate::morphology::Morphology;
pub use decode::{BODY_LENGTH_TOLERANCE, RetargetedFrame, RetargetedMotion};
use decode::{StateDecoder, check_character, clip_rows, root_height_range, standing_state};
use nets::{Activation, Mann, MannSizes, Mlp};

/// A checkpoint's generator and prior decoder, ready to drive characters (see the module docs).
#[derive(Clone, Debug)]
pub struct Retargeter {
    dir: PathBuf,
    character: CharacterInfo,
    /// x^r statistics.
    stats: Normaliser,
    mask: Vec<f32>,
    /// Bounds of π's normalised output.
    lo: Vec<f32>,
    hi: Vec<f32>,
    root_height_range: Option<(f32, f32)>,
    /// x^h statistics.
    human: Normaliser,
    /// The generator's `ace.json`.
    record: AceRecord,
    generator: Mlp,
    decoder: Mann,
    cleanup: Cleanup,
}

impl Retargeter {
    /// Loads the prior's decoder and the generator from a checkpoint directory, checking that the
    /// files are whole and belong together; every error names the file and the problem.
    pub fn load(dir: &Path) -> Result<Retargeter, LearnError> {
        Retargeter::load_files(&CheckpointFiles::on_disk(dir))
    }

    /// [`Retargeter::load`] from a checkpoint's files on disk or in memory (e.g. read by an asset
    /// loader).
    pub fn load_files(files: &CheckpointFiles) -> Result<Retargeter, LearnError> {
        let prior = PriorRecord::read(files)?;
        let ace = AceRecord::read(files, &prior.mask)?;
        ace.check_prior(files.dir(), &prior.character)?;
        let state = prior.character.layout.dim();
        let sizes = MannSizes {
            state,
            latent: prior.config.latent,
            hidden: prior.config.decoder_hidden.clone(),
            experts: prior.config.experts,
            gating_hidden: prior.config.gating_hidden.clone(),
        };
        // The encoder is not needed; its tensors are left unread.
        let mut shapes = BTreeMap::new();
        Mann::shapes(&mut shapes, "decoder", &sizes);
        let weights = read_weights(files, WEIGHTS_FILE, &prior.weights, &shapes, false, "prior", CONFIG_FILE)?;
        let decoder = Mann::read(&weights, "decoder", &sizes);
        let hidden = &ace.config.generator_hidden;
        let mut shapes = BTreeMap::new();
        Mlp::shapes(&mut shapes, "generator", human_layout::DIM + state, hidden, sizes.latent);
        let ace_file = crate::checkpoint::ace::ACE_FILE;
        let weights = read_weights(files, GENERATOR_FILE, &ace.generator, &shapes, true, "network", ace_file)?;
        let generator = Mlp::read(&weights, "generator", hidden.len(), Activation::LeakyRelu(0.2));
        let stats = Normaliser { mean: prior.mean, std: prior.std };
        Ok(Retargeter {
            dir: files.dir().to_path_buf(),
            root_height_range: root_height_range(&prior.character, &stats, &prior.bounds, prior.config.bound_margin),
            character: prior.character,
            stats,
            mask: prior.mask,
            lo: prior.bounds.lo,
            hi: prior.bounds.hi,
            human: Normaliser { mean: ace.human_stats.mean.clone(), std: ace.human_stats.std.clone() },
            record: ace,
            generator,
            decoder,
            cleanup: Cleanup::default(),
        })
    }

    /// The character the checkpoint was trained for.
    pub fn character(&self) -> &CharacterInfo {
        &self.character
    }

    /// The generator's record (`ace.json`: configuration, correspondence, human data, body lengths).
    pub fn record(&self) -> &AceRecord {
        &self.record
    }

    /// Sets the cleanup of new streams and of [`Retargeter::retarget_states`] ([`crate::cleanup`];
    /// everything on unless set otherwise, [`Cleanup::NONE`] for the raw output).
    pub fn set_cleanup(&mut self, cleanup: Cleanup) {
        self.cleanup = cleanup;
    }

    /// The cleanup in use.
    pub fn cleanup(&self) -> Cleanup {
        self.cleanup
    }

    /// Width of x^r.
    pub fn state_dim(&self) -> usize {
        self.stats.dim()
    }

    /// Fails with [`LearnError::WrongCharacter`] unless `tree` and `morph` are the checkpoint's
    /// character, at the body length it was trained with (within [`BODY_LENGTH_TOLERANCE`]).
    pub fn check_character(&self, tree: &KinematicTree, morph: &Morphology) -> Result<(), LearnError> {
        check_character(&self.dir, &self.character, self.record.body_lengths.character, tree, morph)
    }

    /// The normalised x^r of the character standing at rest (the standing pose, zero velocities).
    pub fn start_state(&self, tree: &KinematicTree, morph: &Morphology) -> Result<Vec<f32>, LearnError> {
        self.check_character(tree, morph)?;
        Ok(standing_state(&self.stats, &self.mask, tree, morph))
    }

    /// Starts driving one character (the checkpoint's): standing at rest at the origin facing +x,
    /// with this retargeter's cleanup. Advance it with [`Retargeter::step`].
    pub fn stream(&self, tree: &KinematicTree, morph: &Morphology) -> Result<CharacterStream, LearnError> {
        self.stream_with(tree, morph, &self.cleanup)
    }

    /// [`Retargeter::stream`] with a cleanup of the stream's own: streams with different cleanups
    /// still step together in one batch.
    pub fn stream_with(&self, tree: &KinematicTree, morph: &Morphology, cleanup: &Cleanup) -> Result<CharacterStream, LearnError> {
        Ok(CharacterStream {
            prev: self.start_state(tree, morph)?,
            decoder: StateDecoder::new(tree, morph, cleanup, &self.record.correspondence.mapping, self.root_height_range),
        })
    }

    /// One frame for several characters at once (one batched pass of G and π): `x_h[i]` drives
    /// `streams[i]`, all of them the checkpoint's character `tree`/`morph`. Returns each character's
    /// new state and pose, as a whole-motion rollout ([`Retargeter::retarget_states`]) makes them frame
    /// by frame.
    pub fn step(
        &self,
        tree: &KinematicTree,
        morph: &Morphology,
        streams: &mut [&mut CharacterStream],
        x_h: &[HumanRow],
    ) -> Result<Vec<RetargetedFrame>, LearnError> {
        decode::check_batch(streams.len(), x_h.len())?;
        if streams.is_empty() {
            return Ok(Vec::new());
        }
        let prev: Vec<f32> = streams.iter().flat_map(|s| s.prev.iter().copied()).collect();
        let next = self.networks(x_h, &prev);
        let d = self.state_dim();
        Ok(streams
            .iter_mut()
            .zip(next.chunks_exact(d))
            .zip(x_h)
            .map(|((stream, row), h)| {
                stream.prev.copy_from_slice(row);
                let mut state = self.denormalise(row);
                let pose = stream.decoder.decode(tree, morph, &mut state, Some(h));
                RetargetedFrame { state, pose }
            })
            .collect())
    }

    /// Retargets a human clip (resampled to the project's rate if needed) from the standing pose.
    pub fn retarget_clip(
        &self,
        tree: &KinematicTree,
        morph: &Morphology,
        clip: &HumanClip,
    ) -> Result<RetargetedMotion, LearnError> {
        self.retarget_states(tree, morph, &clip_rows(clip))
    }

    /// Retargets a sequence of x^h rows at the project's rate from the standing pose.
    pub fn retarget_states(
        &self,
        tree: &KinematicTree,
        morph: &Morphology,
        x_h: &[HumanRow],
    ) -> Result<RetargetedMotion, LearnError> {
        let start = self.start_state(tree, morph)?;
        let decoder = StateDecoder::new(tree, morph, &self.cleanup, &self.record.correspondence.mapping, self.root_height_range);
        decode::roll_out(tree, morph, start, decoder, x_h.len(), x_h, &mut |t, prev| {
            let cur = self.networks(&x_h[t..=t], prev);
            let state = self.denormalise(&cur);
            Ok((cur, state))
        })
    }

    /// One batched pass of the networks, `π(G(x^h, prev), prev)`: the normalised next states
    /// `[rows, D]` (row-major) of `rows = x_h.len()` characters from their human states and normalised
    /// previous states `prev: [rows, D]`. [`Retargeter::step`] is this plus the poses.
    pub fn networks(&self, x_h: &[HumanRow], prev: &[f32]) -> Vec<f32> {
        let rows = x_h.len();
        let d = self.state_dim();
        let hd = human_layout::DIM;
        let mut x = Vec::with_capacity(rows * (hd + d));
        for (r, h) in x_h.iter().enumerate() {
            x.extend(h.iter().zip(&self.human.mean).zip(&self.human.std).map(|((v, m), s)| (v - m) / s));
            x.extend(prev[r * d..(r + 1) * d].iter().zip(&self.mask).map(|(v, k)| v * k));
        }
        let z = self.generator.forward(&x, rows);
        let masked: Vec<f32> = x.chunks_exact(hd + d).flat_map(|r| r[hd..].iter().copied()).collect();
        let mut y = self.decoder.forward(&z, &masked, rows);
        for row in y.chunks_exact_mut(d) {
            for (j, v) in row.iter_mut().enumerate() {
                *v = (*v * self.mask[j]).max(self.lo[j]).min(self.hi[j]);
            }
        }
        y
    }

    /// How many network parameters (f32 weights and biases of G, π's gate and π's experts) one pass
    /// of [`Retargeter::networks`] reads. Each is read once per pass, whatever the batch, and used in
    /// one multiply-add per character: the bytes a single character streams from memory per frame
    /// are four times this, and a batch of N costs about N times this many multiply-adds.
    pub fn parameter_count(&self) -> usize {
        self.generator.parameters() + self.decoder.parameters()
    }

    /// `x·std + mean` of one normalised state.
    fn denormalise(&self, x: &[f32]) -> Vec<f32> {
        x.iter().zip(&self.stats.std).zip(&self.stats.mean).map(|((v, s), m)| v * s + m).collect()
    }
}

/// One character being retargeted frame by frame ([`Retargeter::stream`], [`Retargeter::step`]).
#[derive(Debug)]
pub struct CharacterStream {
    /// Normalised previous state, the networks' input.
    prev: Vec<f32>,
    decoder: StateDecoder,
}

#[cfg(all(test, feature = "learn"))]
mod equivalence;

#[cfg(test)]
mod tests {
    use std::collections::BTreeMap;
    use std::fs;

    use super::*;
    use crate::checkpoint::ace::ACE_FILE;
    use crate::morphology::load_character;

    fn spot_dir() -> PathBuf {
        Path::new(env!("CARGO_MANIFEST_DIR")).join("../assets/checkpoints/spot")
    }

    /// The shipped Spot checkpoint's files, in memory.
    fn spot_files() -> BTreeMap<String, Vec<u8>> {
        [CONFIG_FILE, WEIGHTS_FILE, ACE_FILE, GENERATOR_FILE]
            .iter()
            .map(|f| (f.to_string(), fs::read(spot_dir().join(f)).unwrap()))
            .collect()
    }

    fn load(files: BTreeMap<String, Vec<u8>>) -> Result<Retargeter, LearnError> {
        Retargeter::load_files(&CheckpointFiles::in_memory(&spot_dir(), files))
    }

    #[test]
    fn the_parameter_count_is_every_tensor_inference_reads() {
        // G's file whole, and the prior's decoder (gate and experts) without its encoder, which only
        // training uses.
        let files = spot_files();
        let count = |file: &str, keep: &dyn Fn(&str) -> bool| -> usize {
            let t = safetensors::SafeTensors::deserialize(&files[file]).unwrap();
            t.tensors().iter().filter(|(n, _)| keep(n)).map(|(_, v)| v.shape().iter().product::<usize>()).sum()
        };
        let expected = count(GENERATOR_FILE, &|_| true) + count(WEIGHTS_FILE, &|n| n.starts_with("decoder."));
        assert!(count(WEIGHTS_FILE, &|n| n.starts_with("encoder.")) > 0);
        assert_eq!(load(files).unwrap().parameter_count(), expected);
    }

    #[test]
    fn broken_or_mismatched_checkpoints_are_named() {
        let dir = spot_dir().display().to_string();
        // Without the discriminator: inference does not need it.
        let r = load(spot_files()).unwrap();
        assert_eq!(r.character().name, "spot");

        let mut files = spot_files();
        files.remove(GENERATOR_FILE);
        let e = load(files).unwrap_err().to_string();
        assert!(e.contains(&dir) && e.ends_with(&format!("{GENERATOR_FILE}: missing file")), "{e}");

        // A prior alone (what `ace train-prior` writes) says what to run; a file is not a folder.
        let mut files = spot_files();
        files.remove(ACE_FILE);
        let e = load(files).unwrap_err().to_string();
        assert_eq!(
            e,
            format!("{dir}/{ACE_FILE}: missing file: the checkpoint holds a motion prior only; `ace train --checkpoint {dir}` trains its generator")
        );
        let config = spot_dir().join(CONFIG_FILE);
        let e = Retargeter::load_files(&CheckpointFiles::on_disk(&config)).unwrap_err().to_string();
        assert_eq!(
            e,
            format!("{}: a file, not a checkpoint folder (the folder that holds config.json, ace.json and their weights)", config.display())
        );

        let mut files = spot_files();
        let half = files[WEIGHTS_FILE].len() / 2;
        files.get_mut(WEIGHTS_FILE).unwrap().truncate(half);
        let e = load(files).unwrap_err().to_string();
        assert!(e.contains(&format!("{WEIGHTS_FILE}: corrupt file")), "{e}");

        // One flipped byte in the generator's last tensor: still readable, the checksum catches it.
        let mut files = spot_files();
        let g = files.get_mut(GENERATOR_FILE).unwrap();
        let n = g.len();
        g[n - 3] ^= 0x40;
        let e = load(files).unwrap_err().to_string();
        assert!(e.contains(GENERATOR_FILE) && e.contains("checksum"), "{e}");

        // `ace.json` describing wider networks than the weights hold.
        let mut files = spot_files();
        let mut v: serde_json::Value = serde_json::from_slice(&files[ACE_FILE]).unwrap();
        v["config"]["generator_hidden"] = serde_json::json!([48, 64]);
        files.insert(ACE_FILE.into(), v.to_string().into_bytes());
        let e = load(files).unwrap_err().to_string();
        assert!(e.contains(GENERATOR_FILE) && e.contains("shape mismatch"), "{e}");

        // Another character than the checkpoint's.
        let (crab, crab_morph) =
            load_character(&Path::new(env!("CARGO_MANIFEST_DIR")).join("../assets/characters/crab.urdf")).unwrap();
        let e = r.stream(&crab, &crab_morph).unwrap_err().to_string();
        assert!(e.contains("another character") && e.contains("crab"), "{e}");
    }
}
