//! Inference: human motion to character motion with a trained generator and motion prior.
//!
//! A [`Retargeter`] holds a checkpoint directory's prior, generator and normalisation statistics. Per
//! frame, for each character of a batch, `ẑ = G(x^h_t, x^r_{t−1})` and `x^r_t = π(ẑ, x^r_{t−1})`,
//! without gradients; each character keeps its own previous state in a [`CharacterStream`]
//! ([`Retargeter::stream`] starts one from [`Retargeter::start_state`]: the standing pose at rest).
//!
//! [`Retargeter::retarget_clip`] turns a whole human clip into character states and poses: the root is
//! integrated from the states' displacements and delta rotations
//! ([`crate::character_state::decode_pose`]), joint positions are clamped into the URDF limits
//! ([`KinematicTree::clamp`]), and wheel angles — which the networks do not model (the prior's state
//! mask) — are rolled from the base motion ([`crate::controller::wheels`]); with the cleanup on
//! ([`crate::cleanup`], by default, [`Retargeter::set_cleanup`]) the root height is kept within the
//! dataset's range, collisions are undone and planted feet locked to the ground. The
//! returned states carry the resulting joint and end-effector positions, so states and poses agree.

use std::path::{Path, PathBuf};

use rand::SeedableRng;
use rand_pcg::Pcg64;
use tch::{Device, Tensor};

use super::ace::AceCheckpoint;
use super::checkpoint::{LearnError, PriorCheckpoint};
use super::files::CheckpointFiles;
use super::prior::normals;
use super::{rows_to_tensor, tensor_to_rows};
use crate::cleanup::Cleanup;
use crate::features::EndEffectorMapping;
use crate::human::HumanClip;
use crate::human_set::HumanRow;
use crate::kinematics::KinematicTree;
use crate::morphology::Morphology;
use crate::runtime::decode::{self, StateDecoder, check_character, clip_rows, root_height_range, standing_state};
pub use crate::runtime::decode::{BODY_LENGTH_TOLERANCE, RetargetedFrame, RetargetedMotion};

/// A loaded prior and generator (see the module docs).
#[derive(Debug)]
pub struct Retargeter {
    dir: PathBuf,
    prior: PriorCheckpoint,
    ace: AceCheckpoint,
    human_mean: Tensor,
    human_std: Tensor,
    /// The cleanup whole-motion rollouts pass through.
    cleanup: Cleanup,
}

impl Retargeter {
    /// Loads the prior and the generator from a checkpoint directory onto `device`, checking that the
    /// files belong together (see [`PriorCheckpoint::load`] and [`AceCheckpoint::load`]); every error
    /// names the file and the problem.
    pub fn load(dir: &Path, device: Device) -> Result<Retargeter, LearnError> {
        Retargeter::load_files(&CheckpointFiles::on_disk(dir), device)
    }

    /// [`Retargeter::load`] from a checkpoint's files on disk or in memory (e.g. read by an asset
    /// loader).
    pub fn load_files(files: &CheckpointFiles, device: Device) -> Result<Retargeter, LearnError> {
        let prior = PriorCheckpoint::load_files(files, device)?;
        let ace = AceCheckpoint::load_files(files, prior.prior.latent_dim(), &prior.mask, device, false)?;
        Retargeter::from_checkpoints(files.dir(), prior, ace)
    }

    /// A retargeter from checkpoints already in memory (e.g. right after training; `dir` names them
    /// in errors). Fails when the generator was trained for another character than the prior's.
    pub fn from_checkpoints(
        dir: &Path,
        mut prior: PriorCheckpoint,
        ace: AceCheckpoint,
    ) -> Result<Retargeter, LearnError> {
        ace.record.check_prior(dir, &prior.character)?;
        prior.prior.freeze();
        let device = prior.prior.device();
        let stats = &ace.record.human_stats;
        Ok(Retargeter {
            human_mean: Tensor::from_slice(&stats.mean).view([1, -1]).to_device(device),
            human_std: Tensor::from_slice(&stats.std).view([1, -1]).to_device(device),
            cleanup: Cleanup::default(),
            dir: dir.to_path_buf(),
            prior,
            ace,
        })
    }

    /// The prior's checkpoint (character, statistics, mask).
    pub fn prior(&self) -> &PriorCheckpoint {
        &self.prior
    }

    /// The ACE checkpoint (configuration, correspondence, human data record).
    pub fn ace(&self) -> &AceCheckpoint {
        &self.ace
    }

    /// Sets the cleanup of [`Retargeter::retarget_states`] and [`Retargeter::random_latent_rollout`]
    /// ([`crate::cleanup`]; everything on unless set otherwise, [`Cleanup::NONE`] for the raw output).
    pub fn set_cleanup(&mut self, cleanup: Cleanup) {
        self.cleanup = cleanup;
    }

    /// The cleanup in use.
    pub fn cleanup(&self) -> Cleanup {
        self.cleanup
    }

    /// Width of x^r.
    pub fn state_dim(&self) -> usize {
        self.prior.prior.state_dim()
    }

    /// Fails with [`LearnError::WrongCharacter`] unless `tree` and `morph` are the checkpoint's
    /// character, at the body length it was trained with (within [`BODY_LENGTH_TOLERANCE`]).
    pub fn check_character(&self, tree: &KinematicTree, morph: &Morphology) -> Result<(), LearnError> {
        check_character(&self.dir, &self.prior.character, self.ace.record.body_lengths.character, tree, morph)
    }

    /// The normalised x^r of the character standing at rest (the standing pose, zero velocities).
    pub fn start_state(&self, tree: &KinematicTree, morph: &Morphology) -> Result<Vec<f32>, LearnError> {
        self.check_character(tree, morph)?;
        Ok(standing_state(&self.prior.stats, &self.prior.mask, tree, morph))
    }

    /// Starts driving one character (the checkpoint's): standing at rest at the origin facing +x,
    /// with this retargeter's cleanup. Advance it with [`Retargeter::step`].
    pub fn stream(&self, tree: &KinematicTree, morph: &Morphology) -> Result<CharacterStream, LearnError> {
        let start = self.start_state(tree, morph)?;
        Ok(CharacterStream {
            prev: rows_to_tensor(&[start], self.prior.prior.device())?,
            decoder: StateDecoder::new(tree, morph, &self.cleanup, &self.ace.record.correspondence.mapping, prior_root_height_range(&self.prior)),
        })
    }

    /// One frame for several characters at once (one batched pass of G and π): `x_h[i]` drives
    /// `streams[i]`, all of them the checkpoint's character `tree`/`morph`. Returns each character's
    /// new state and pose, exactly as a whole-motion rollout ([`Retargeter::retarget_states`]) makes
    /// them frame by frame.
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
        let prev = Tensor::cat(&streams.iter().map(|s| &s.prev).collect::<Vec<_>>(), 0);
        let next = self.advance(x_h, &prev);
        let rows = tensor_to_rows(&self.prior.stats.denormalise(&next), self.state_dim())?;
        Ok(streams
            .iter_mut()
            .zip(rows)
            .enumerate()
            .map(|(i, (stream, mut state))| {
                stream.prev = next.narrow(0, i as i64, 1).copy();
                let pose = stream.decoder.decode(tree, morph, &mut state, Some(&x_h[i]));
                RetargetedFrame { state, pose }
            })
            .collect())
    }

    /// One batched pass of the networks, `π(G(x^h, prev), prev)`: the normalised next states of
    /// `x_h.len()` characters from their human states and normalised previous states `prev`, one row
    /// each. [`Retargeter::step`] is this plus the poses.
    pub fn networks(&self, x_h: &[HumanRow], prev: &[Vec<f32>]) -> Result<Vec<Vec<f32>>, LearnError> {
        let prev = rows_to_tensor(prev, self.prior.prior.device())?;
        Ok(tensor_to_rows(&self.advance(x_h, &prev), self.state_dim())?)
    }

    /// `π(G(x^h, prev), prev)` without gradients, normalised.
    fn advance(&self, x_h: &[HumanRow], prev: &Tensor) -> Tensor {
        tch::no_grad(|| {
            let device = prev.device();
            let x = rows_to_tensor(x_h, device).expect("x^h rows are 92 wide");
            let x = (x - &self.human_mean) / &self.human_std;
            let z = self.ace.generator.forward(&x, prev);
            self.prior.prior.decode(&z, prev)
        })
    }

    /// Retargets a human clip (resampled to the project's frame rate if needed) from the standing pose
    /// (see the module docs).
    pub fn retarget_clip(
        &self,
        tree: &KinematicTree,
        morph: &Morphology,
        clip: &HumanClip,
    ) -> Result<RetargetedMotion, LearnError> {
        self.retarget_states(tree, morph, &clip_rows(clip))
    }

    /// Retargets a sequence of x^h rows at the project's frame rate from the standing pose (see the module
    /// docs); independent of the batch of [`Retargeter::step`].
    pub fn retarget_states(
        &self,
        tree: &KinematicTree,
        morph: &Morphology,
        x_h: &[HumanRow],
    ) -> Result<RetargetedMotion, LearnError> {
        let human = rows_to_tensor(x_h, self.prior.prior.device())?;
        let human = (human - &self.human_mean) / &self.human_std;
        self.check_character(tree, morph)?;
        roll_out(tree, morph, &self.prior, self.cleanup, &self.ace.record.correspondence.mapping, x_h.len(), x_h, &mut |t, prev| {
            let z = self.ace.generator.forward(&human.narrow(0, t as i64, 1), prev);
            self.prior.prior.decode(&z, prev)
        })
    }

    /// The motion prior alone, driven by latents drawn from its prior N(0, I) (seeded), for `frames`
    /// frames from the standing pose: the reference an evaluation compares the generator's choice of
    /// latents against.
    pub fn random_latent_rollout(
        &self,
        tree: &KinematicTree,
        morph: &Morphology,
        frames: usize,
        seed: u64,
    ) -> Result<RetargetedMotion, LearnError> {
        let latent = self.prior.prior.latent_dim();
        let device = self.prior.prior.device();
        let mut rng = Pcg64::seed_from_u64(seed);
        self.check_character(tree, morph)?;
        roll_out(tree, morph, &self.prior, self.cleanup, &self.ace.record.correspondence.mapping, frames, &[], &mut |_, prev| {
            let z = Tensor::from_slice(&normals(&mut rng, latent))
                .view([1, latent as i64])
                .to_device(device);
            self.prior.prior.decode(&z, prev)
        })
    }

}

/// The rollout loop of [`Retargeter`] and of the NKN baseline ([`super::nkn`]) on tensors:
/// `next(t, prev)` gives the normalised state of frame `t` (`[1, D]`) from the normalised previous one
/// (the first is the standing state); poses come from the shared [`decode::roll_out`] with the
/// character's joint limits, its wheels and `cleanup` (following the x^h rows `human`, if any, with the
/// end effectors paired as `mapping` says), as a [`CharacterStream`] makes them.
#[allow(clippy::too_many_arguments)]
pub(crate) fn roll_out(
    tree: &KinematicTree,
    morph: &Morphology,
    prior: &PriorCheckpoint,
    cleanup: Cleanup,
    mapping: &EndEffectorMapping,
    frames: usize,
    human: &[HumanRow],
    next: &mut dyn FnMut(usize, &Tensor) -> Tensor,
) -> Result<RetargetedMotion, LearnError> {
    let start = rows_to_tensor(&[standing_state(&prior.stats, &prior.mask, tree, morph)], prior.prior.device())?;
    let decoder = StateDecoder::new(tree, morph, &cleanup, mapping, prior_root_height_range(prior));
    let dim = prior.prior.state_dim();
    decode::roll_out(tree, morph, start, decoder, frames, human, &mut |t, prev| {
        let cur = tch::no_grad(|| next(t, prev));
        let state = tensor_to_rows(&prior.stats.denormalise(&cur), dim)?.remove(0);
        Ok((cur, state))
    })
}

/// The root heights the character's dataset spans (m), when the prior's bounds say.
fn prior_root_height_range(prior: &PriorCheckpoint) -> Option<(f32, f32)> {
    root_height_range(&prior.character, &prior.stats, &prior.prior.state_bounds(), prior.config.bound_margin)
}

/// One character being retargeted frame by frame ([`Retargeter::stream`], [`Retargeter::step`]).
#[derive(Debug)]
pub struct CharacterStream {
    /// `[1, D]` normalised previous state, the networks' input.
    prev: Tensor,
    decoder: StateDecoder,
}

#[cfg(test)]
mod tests {
    use std::fs;

    use super::*;
    use crate::human_set::PROJECT_FPS;
    use crate::character_state::CharacterLayout;
    use crate::checkpoint::CharacterInfo;
    use crate::controller::wheels;
    use crate::human::ImportOptions;
    use nalgebra::Vector2;
    use crate::human_set::DEFAULT_FOLDER;
    use crate::learn::ace::{ACE_FILE, DISCRIMINATOR_FILE, GENERATOR_FILE};
    use crate::learn::checkpoint::{CONFIG_FILE, WEIGHTS_FILE};
    use crate::learn::prior::MotionPrior;
    use crate::learn::prior::test_support::{scratch_dir, spot};
    use crate::learn::train_ace::test_support::{bundled_humans, tiny_config, train_in, trained_ace_dir};
    use crate::test_data::{bundled_character, require};

    fn asset(path: &str) -> PathBuf {
        Path::new(env!("CARGO_MANIFEST_DIR")).join("..").join(path)
    }

    /// A copy of the trained run directory to break.
    fn copy_of_trained(name: &str) -> PathBuf {
        let dir = scratch_dir(name);
        for e in fs::read_dir(trained_ace_dir()).unwrap() {
            let p = e.unwrap().path();
            fs::copy(&p, dir.join(p.file_name().unwrap())).unwrap();
        }
        dir
    }

    #[test]
    fn saved_and_loaded_generators_retarget_identically() {
        let (tree, morph, _) = spot();
        let dir = scratch_dir("retarget_same");
        let (trained, _) = train_in(&dir, &tiny_config(20)).unwrap();
        let from_memory =
            Retargeter::from_checkpoints(&dir, PriorCheckpoint::load(&dir, Device::Cpu).unwrap(), trained)
                .unwrap();
        let loaded = Retargeter::load(&dir, Device::Cpu).unwrap();
        let walk = &bundled_humans().clips[1].states;
        let a = from_memory.retarget_states(tree, morph, walk).unwrap();
        let b = loaded.retarget_states(tree, morph, walk).unwrap();
        assert_eq!(a.states.len(), walk.len());
        assert_eq!(a, b);
        fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn a_looped_clip_gives_finite_poses_for_sixty_seconds() {
        let (tree, morph, _) = spot();
        let r = Retargeter::load(trained_ace_dir(), Device::Cpu).unwrap();
        let clip = crate::test_data::bundled_clip("wave");
        let once = r.retarget_clip(tree, morph, &clip).unwrap();
        // Imported at the file's rate and resampled to the project's.
        assert_eq!(once.states.len(), clip.resampled(PROJECT_FPS).frames.len());
        let rows: Vec<HumanRow> = clip.states().into_iter().map(|s| s.0).collect();
        let looped: Vec<HumanRow> = rows.iter().cycle().take(1800).copied().collect();
        let m = r.retarget_states(tree, morph, &looped).unwrap();
        assert_eq!(m.poses.len(), 1800);
        let layout = CharacterLayout::new(tree, morph);
        for (t, (p, s)) in m.poses.iter().zip(&m.states).enumerate() {
            let root = p.root.translation.vector;
            assert!(
                root.iter().all(|v| v.is_finite()) && p.root.rotation.coords.iter().all(|v| v.is_finite()),
                "frame {t}"
            );
            assert!(p.q.iter().all(|v| v.is_finite()), "frame {t}");
            // Joint positions lie within the URDF limits and the states carry them.
            let mut clamped = p.q.clone();
            tree.clamp(&mut clamped);
            assert_eq!(clamped, p.q, "frame {t}");
            assert_eq!(&s[layout.joint_positions()], &p.q[..], "frame {t}");
            assert!((-1.0..3.0).contains(&root.z), "frame {t}: root height {}", root.z);
        }
    }

    #[test]
    fn streams_stepped_together_follow_the_whole_motion_rollout() {
        let (tree, morph, _) = spot();
        let r = Retargeter::load(trained_ace_dir(), Device::Cpu).unwrap();
        let humans = bundled_humans();
        let (walk, wave) = (&humans.clips[1].states, &humans.clips[2].states);
        let frames = walk.len().min(wave.len()).min(90);
        let whole_walk = r.retarget_states(tree, morph, &walk[..frames]).unwrap();
        let whole_wave = r.retarget_states(tree, morph, &wave[..frames]).unwrap();
        // One stream alone is the rollout itself; three in a batch (two on the same clip) agree up
        // to the rounding of a batched matrix product.
        let mut alone = r.stream(tree, morph).unwrap();
        let mut a = r.stream(tree, morph).unwrap();
        let mut b = r.stream(tree, morph).unwrap();
        let mut c = r.stream(tree, morph).unwrap();
        for t in 0..frames {
            let single = r.step(tree, morph, &mut [&mut alone], &[walk[t]]).unwrap();
            assert_eq!(single[0].pose, whole_walk.poses[t], "frame {t}");
            assert_eq!(single[0].state, whole_walk.states[t], "frame {t}");
            let out = r.step(tree, morph, &mut [&mut a, &mut b, &mut c], &[walk[t], wave[t], walk[t]]).unwrap();
            for (got, want) in [(&out[0], &whole_walk), (&out[1], &whole_wave), (&out[2], &whole_walk)] {
                let d = (got.pose.root.translation.vector - want.poses[t].root.translation.vector).norm();
                assert!(d < 1e-3, "frame {t}: root {d} m away");
                let dq = got.pose.q.iter().zip(&want.poses[t].q).map(|(x, y)| (x - y).abs()).fold(0.0, f32::max);
                assert!(dq < 1e-2, "frame {t}: a joint {dq} rad away");
            }
        }
        let err = r.step(tree, morph, &mut [&mut a], &[walk[0], walk[1]]).unwrap_err();
        assert!(err.to_string().contains("2 human states for 1 characters"), "{err}");
    }

    #[test]
    fn files_in_memory_load_like_the_directory_and_missing_ones_are_named() {
        let (tree, morph, _) = spot();
        let dir = trained_ace_dir();
        let files: std::collections::BTreeMap<String, Vec<u8>> = fs::read_dir(dir)
            .unwrap()
            .map(|e| e.unwrap().path())
            .filter(|p| p.is_file())
            .map(|p| (p.file_name().unwrap().to_string_lossy().into_owned(), fs::read(&p).unwrap()))
            .collect();
        let walk = &bundled_humans().clips[1].states;
        let from_disk = Retargeter::load(dir, Device::Cpu).unwrap();
        let in_memory = Retargeter::load_files(&CheckpointFiles::in_memory(dir, files.clone()), Device::Cpu).unwrap();
        assert_eq!(
            from_disk.retarget_states(tree, morph, walk).unwrap(),
            in_memory.retarget_states(tree, morph, walk).unwrap()
        );
        let mut partial = files;
        partial.remove(GENERATOR_FILE);
        let e = Retargeter::load_files(&CheckpointFiles::in_memory(dir, partial), Device::Cpu).unwrap_err();
        assert!(e.to_string().ends_with(&format!("{GENERATOR_FILE}: missing file")), "{e}");
        assert!(e.to_string().contains(&dir.display().to_string()), "{e}");
    }

    #[test]
    fn random_latent_rollouts_are_seeded_and_ignore_the_generator() {
        let (tree, morph, _) = spot();
        let r = Retargeter::load(trained_ace_dir(), Device::Cpu).unwrap();
        let a = r.random_latent_rollout(tree, morph, 90, 3).unwrap();
        let b = r.random_latent_rollout(tree, morph, 90, 3).unwrap();
        let c = r.random_latent_rollout(tree, morph, 90, 4).unwrap();
        assert_eq!(a.poses.len(), 90);
        assert_eq!(a, b, "same seed, same motion");
        assert_ne!(a.states, c.states, "another seed, another motion");
        assert!(a.states.iter().flatten().all(|v| v.is_finite()));
        // Not what the generator chooses for a human clip of the same length.
        let walk = &bundled_humans().clips[1].states;
        let g = r.retarget_states(tree, morph, &walk[..90.min(walk.len())]).unwrap();
        assert_ne!(g.states[..g.states.len()], a.states[..g.states.len()]);
    }

    #[test]
    fn wheel_angles_roll_with_the_base_instead_of_coming_from_the_networks() {
        use crate::correspondence::{Correspondence, MappingSource};
        use crate::dataset::{DatasetConfig, generate};
        use crate::features::EndEffectorMapping;
        use crate::human_set::HumanStats;
        use crate::learn::ace::{AceConfig, AceRecord, BodyLengths, FileRecord, Generator};
        use crate::learn::checkpoint::Normaliser;
        use crate::learn::prior::{PriorConfig, state_mask};

        let (tree, morph) = bundled_character("stretch");
        let wheels = wheels::find(&tree, &morph, &tree.standing_pose());
        assert!(!wheels.is_empty(), "the bundled Stretch has wheels");
        let set = generate(
            &tree,
            &morph,
            &DatasetConfig {
                frames: 600,
                ..DatasetConfig::default()
            },
            &mut |_| {},
        )
        .unwrap();
        let mask = state_mask(&tree, &morph);
        // Untrained networks: the base wanders, which is all this test needs.
        let pc = PriorConfig {
            decoder_hidden: vec![32],
            encoder_hidden: vec![32],
            ..PriorConfig::default()
        };
        let mut prior = MotionPrior::new(&pc, set.layout.dim(), Device::Cpu);
        prior.set_mask(&mask).unwrap();
        let ac = AceConfig {
            generator_hidden: vec![32],
            ..AceConfig::default()
        };
        let generator = Generator::new(&ac, set.layout.dim(), prior.latent_dim(), &mask, Device::Cpu);
        let humans = bundled_humans();
        let stats = humans.train_statistics();
        let character = CharacterInfo::of_set(&set);
        let correspondence = Correspondence {
            mapping: EndEffectorMapping::by_side(&tree, &morph),
            character_links: set.end_effector_links.clone(),
            scores: Vec::new(),
            source: MappingSource::Manual,
        };
        let ace = AceCheckpoint {
            record: AceRecord {
                kind: String::new(),
                format_version: 1,
                character: character.clone(),
                step: 0,
                config: ac,
                correspondence,
                human_stats: HumanStats {
                    mean: stats.mean.clone(),
                    std: stats.std.clone(),
                },
                human_folder: PathBuf::new(),
                human_split: humans.split.clone(),
                body_lengths: BodyLengths {
                    character: crate::features::character_body_length(&tree, &morph),
                    human_override: None,
                    human_clips: Default::default(),
                },
                feature_offset: Vec::new(),
                speed_scale: None,
                generator: FileRecord::default(),
                discriminator: FileRecord::default(),
                prior: FileRecord::default(),
                prior_config: None,
                provenance: serde_json::Value::Null,
            },
            generator,
            discriminator: None,
        };
        let prior = PriorCheckpoint {
            config: pc,
            stats: Normaliser::of_set(&set),
            mask,
            character,
            step: 0,
            provenance: serde_json::Value::Null,
            prior,
        };
        let r = Retargeter::from_checkpoints(Path::new("<memory>"), prior, ace).unwrap();
        let m = r.retarget_states(&tree, &morph, &humans.clips[1].states).unwrap();
        let layout = CharacterLayout::new(&tree, &morph);
        let dt = 1.0 / PROJECT_FPS;
        let mut moved = 0.0f32;
        let mut prev_q = tree.standing_pose().q;
        for (t, (s, p)) in m.states.iter().zip(&m.poses).enumerate() {
            let v = &s[layout.root_linear_velocity()];
            let wz = s[layout.root_angular_velocity()][2];
            for w in &wheels {
                // The angle advanced by the rolling rate of the base's motion, whatever π output.
                let rate = wheels::spin_rate(w, Vector2::new(v[0], v[1]), wz);
                let step = wheels::wrap(p.q[w.dof] - prev_q[w.dof]);
                assert!(
                    (step - wheels::wrap(rate * dt)).abs() < 1e-4,
                    "frame {t}, DoF {}",
                    w.dof
                );
                moved += step.abs();
            }
            prev_q = p.q.clone();
        }
        assert!(moved > 0.1, "the wheels turned by {moved} rad in total");
    }

    #[test]
    fn a_clip_of_the_shared_human_data_retargets_when_present() {
        let Some(folder) = require(asset(DEFAULT_FOLDER).join("cmu_cgspeed_mb"), "the shared CMU clips") else {
            return;
        };
        let mut files: Vec<PathBuf> = fs::read_dir(&folder)
            .unwrap()
            .map(|e| e.unwrap().path())
            .filter(|p| p.extension().is_some_and(|e| e == "bvh"))
            .collect();
        files.sort();
        let file = files.first().unwrap_or_else(|| panic!("no CMU clips in {}", folder.display()));
        let (tree, morph, _) = spot();
        let r = Retargeter::load(trained_ace_dir(), Device::Cpu).unwrap();
        let opts = ImportOptions {
            fps: Some(PROJECT_FPS),
            mapping: None,
        };
        let clip = HumanClip::from_bvh_file(file, &opts).unwrap();
        let m = r.retarget_clip(tree, morph, &clip).unwrap();
        assert_eq!(m.poses.len(), clip.frames.len());
        // Real poses: within the joint limits, the body standing on the ground, states that carry them.
        let standing = tree.standing_root_height();
        let layout = CharacterLayout::new(tree, morph);
        for (t, (p, s)) in m.poses.iter().zip(&m.states).enumerate() {
            let mut clamped = p.q.clone();
            tree.clamp(&mut clamped);
            assert_eq!(clamped, p.q, "{}: frame {t} outside the joint limits", file.display());
            let z = p.root.translation.z;
            assert!(z > 0.3 * standing && z < 1.5 * standing, "{}: frame {t} root at {z} m", file.display());
            assert_eq!(&s[layout.joint_positions()], &p.q[..], "frame {t}");
        }
    }

    #[test]
    fn broken_or_mismatched_checkpoints_are_named() {
        let err = |dir: &Path| Retargeter::load(dir, Device::Cpu).unwrap_err().to_string();
        let mut broken = Vec::new();

        let dir = copy_of_trained("retarget_missing");
        broken.push(dir.clone());
        fs::remove_file(dir.join(GENERATOR_FILE)).unwrap();
        let e = err(&dir);
        assert!(e.contains(GENERATOR_FILE) && e.contains("missing file"), "{e}");
        // Inference does not need D.
        fs::copy(trained_ace_dir().join(GENERATOR_FILE), dir.join(GENERATOR_FILE)).unwrap();
        fs::remove_file(dir.join(DISCRIMINATOR_FILE)).unwrap();
        assert!(Retargeter::load(&dir, Device::Cpu).is_ok());

        let dir = copy_of_trained("retarget_truncated");
        broken.push(dir.clone());
        let bytes = fs::read(dir.join(GENERATOR_FILE)).unwrap();
        fs::write(dir.join(GENERATOR_FILE), &bytes[..bytes.len() / 2]).unwrap();
        let e = err(&dir);
        assert!(e.contains(GENERATOR_FILE) && e.contains("corrupt"), "{e}");

        let dir = copy_of_trained("retarget_kind");
        broken.push(dir.clone());
        let text = fs::read_to_string(dir.join(ACE_FILE)).unwrap();
        fs::write(
            dir.join(ACE_FILE),
            text.replace("ace_adversarial", "something_else"),
        )
        .unwrap();
        let e = err(&dir);
        assert!(e.contains(ACE_FILE) && e.contains("not an ACE checkpoint"), "{e}");
        fs::write(dir.join(ACE_FILE), &text[..text.len() / 2]).unwrap();
        let e = err(&dir);
        assert!(e.contains(ACE_FILE) && e.contains("not valid JSON"), "{e}");

        // `ace.json` describing other network sizes than the weights hold.
        let dir = copy_of_trained("retarget_shape");
        broken.push(dir.clone());
        let mut v: serde_json::Value = serde_json::from_str(&text).unwrap();
        v["config"]["generator_hidden"] = serde_json::json!([48, 64]);
        fs::write(dir.join(ACE_FILE), v.to_string()).unwrap();
        let e = err(&dir);
        assert!(e.contains(GENERATOR_FILE) && e.contains("shape mismatch"), "{e}");

        // Another prior in the directory (well-formed on its own) than the one G was trained with.
        let dir = copy_of_trained("retarget_prior");
        broken.push(dir.clone());
        let mut other = PriorCheckpoint::load(&dir, Device::Cpu).unwrap();
        let cfg = other.config.clone();
        other.prior = MotionPrior::new(
            &crate::learn::prior::PriorConfig { seed: 99, ..cfg },
            other.prior.state_dim(),
            Device::Cpu,
        );
        other.prior.set_mask(&other.mask).unwrap();
        other.save(&dir).unwrap();
        let e = err(&dir);
        assert!(e.contains(WEIGHTS_FILE) && e.contains(ACE_FILE), "{e}");

        // The prior's `config.json` edited (a normalisation mean moved, still plausible), its weights
        // untouched: G was trained against the other statistics.
        let dir = copy_of_trained("retarget_prior_config");
        broken.push(dir.clone());
        let config = dir.join(CONFIG_FILE);
        let mut v: serde_json::Value = serde_json::from_str(&fs::read_to_string(&config).unwrap()).unwrap();
        let m = v["mean"][0].as_f64().unwrap();
        v["mean"][0] = serde_json::json!(m + 0.1);
        fs::write(&config, serde_json::to_string_pretty(&v).unwrap()).unwrap();
        assert!(PriorCheckpoint::load(&dir, Device::Cpu).is_ok(), "the edited prior is well-formed on its own");
        let e = err(&dir);
        assert!(e.contains(CONFIG_FILE) && e.contains(ACE_FILE) && e.contains("not from the same save"), "{e}");

        // Another character than the checkpoint's.
        let (crab, crab_morph) = bundled_character("crab");
        let r = Retargeter::load(trained_ace_dir(), Device::Cpu).unwrap();
        let e = r.start_state(&crab, &crab_morph).unwrap_err().to_string();
        assert!(e.contains("another character") && e.contains("crab"), "{e}");
        for dir in broken {
            fs::remove_dir_all(dir).unwrap();
        }
    }
}
