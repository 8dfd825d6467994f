//! Checkpoint files without tensors: what training writes and inference reads, and the error type of
//! both. A checkpoint directory holds the motion prior ([`prior`]: `config.json` and
//! `prior.safetensors`) and the generator and discriminator beside it ([`ace`]: `ace.json`,
//! `generator.safetensors`, `discriminator.safetensors`); [`files`] reads and checks the files, on disk
//! or in memory.
//!
//! Nothing here knows libtorch: the pure-Rust inference ([`crate::runtime`]) and, behind the `learn`
//! feature, training and libtorch inference (`crate::learn`) read the same files through the same
//! checks.

use std::path::{Path, PathBuf};

use thiserror::Error;

pub mod ace;
pub mod files;
pub mod prior;

pub use files::{CheckpointFiles, FileRecord};
pub use prior::{CharacterInfo, Normaliser, StateBounds};

/// Errors of checkpoints, configurations, training data and (with `learn`) libtorch.
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
    #[error("{}: {error}", path.display())]
    Io {
        /// The file or directory.
        path: PathBuf,
        /// The operating system's error (in the message, not a source, which `{:#}` would print
        /// again).
        error: std::io::Error,
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
    #[cfg(feature = "learn")]
    #[error("libtorch: {0}")]
    Torch(#[from] tch::TchError),
}

impl LearnError {
    /// An [`LearnError::Io`] for `path`.
    pub fn io(path: &Path, error: std::io::Error) -> LearnError {
        LearnError::Io {
            path: path.to_path_buf(),
            error,
        }
    }
}

/// Errors raised when data handed to the learning code has the wrong shape.
#[derive(Debug, thiserror::Error)]
pub enum ShapeError {
    #[error("state rows have inconsistent widths: row 0 has {expected} values, row {row} has {found}")]
    Ragged { expected: usize, row: usize, found: usize },
    #[error("expected a 2-D float tensor of width {expected}, got shape {found:?}")]
    Tensor { expected: usize, found: Vec<i64> },
}

/// Upper bounds of the training configurations' sizes, checked before any work (a `batch_size` of 10⁹
/// would otherwise ask libtorch for gigabytes and abort the process).
pub mod limits {
    /// Windows or transitions per optimiser step.
    pub const BATCH_SIZE: usize = 65_536;
    /// Width of a hidden layer.
    pub const HIDDEN_WIDTH: usize = 16_384;
    /// Hidden layers per network.
    pub const HIDDEN_LAYERS: usize = 64;
    /// Frames per training window or rollout.
    pub const WINDOW: usize = 1_024;
    /// Optimiser steps.
    pub const STEPS: usize = 100_000_000;
    /// Latent dimensions and experts.
    pub const LATENT: usize = 4_096;

    // The sizes above are bounded one at a time; their products are bounded below, so that no
    // combination of values in range asks for more memory than a workstation has.

    /// Frames one optimiser step rolls out at once (`batch_size` × `window`, or × `rollout` for the
    /// prior): 2²⁰. The paper's settings use 2,048.
    pub const STEP_FRAMES: usize = 1 << 20;
    /// Weights between the hidden layers of a stage's networks together (each expert counted), 2²⁷:
    /// half a gigabyte of `f32`, two with the gradients and Adam's moments. The layers into and out of
    /// the hidden ones, sized by the character, come on top. The paper's prior has 4.2 million.
    pub const HIDDEN_WEIGHTS: usize = 1 << 27;
    /// Hidden activations one optimiser step keeps for its gradients (frames per step × the hidden
    /// widths summed, each expert's counted), 2²⁸: a gigabyte of `f32`. The paper's settings use 7
    /// million.
    pub const ACTIVATIONS: usize = 1 << 28;

    /// Weights between consecutive hidden layers of widths `w`.
    pub fn hidden_weights(w: &[usize]) -> u128 {
        w.windows(2).map(|p| p[0] as u128 * p[1] as u128).sum()
    }

    /// The sum of the widths `w`.
    pub fn width_sum(w: &[usize]) -> u128 {
        w.iter().map(|&v| v as u128).sum()
    }

    /// `Err` saying that `what` (naming the fields) comes to `value`, over `limit`, and `advice` (which
    /// fields to lower) unless `value ≤ limit`.
    pub fn budget(what: &str, value: u128, limit: usize, advice: &str) -> Result<(), super::LearnError> {
        if value <= limit as u128 {
            Ok(())
        } else {
            Err(super::LearnError::Config(format!(
                "{what} = {value}, more than the {limit} a training step may use; {advice}"
            )))
        }
    }

    /// `Err` naming `field`, its value and the valid range unless `lo ≤ v ≤ hi`.
    pub fn in_range(field: &str, v: usize, lo: usize, hi: usize) -> Result<(), super::LearnError> {
        if (lo..=hi).contains(&v) {
            Ok(())
        } else {
            Err(super::LearnError::Config(format!(
                "`{field}` = {v} is out of range: expected {lo} to {hi}"
            )))
        }
    }

    /// Largest learning rate: Adam's steps are about the learning rate in size, and weights of order 1
    /// stepped by more than 1 diverge at once.
    pub const LEARNING_RATE: f64 = 1.0;
    /// Largest loss weight (w_adv, w_fea, w_gp, kl_weight): beyond it the other terms vanish in f32.
    pub const LOSS_WEIGHT: f64 = 1e6;

    /// `Err` naming `field`, its value and the valid range unless `v` is finite and in `lo..=hi`,
    /// or `lo < v ≤ hi` when `positive` (a learning rate of 0 learns nothing).
    pub fn float_in_range(field: &str, v: f64, lo: f64, hi: f64, positive: bool) -> Result<(), super::LearnError> {
        let ok = v.is_finite() && v <= hi && if positive { v > lo } else { v >= lo };
        if ok {
            return Ok(());
        }
        let low = if positive { format!("more than {lo}") } else { format!("{lo}") };
        Err(super::LearnError::Config(format!("`{field}` = {v} is out of range: expected {low} to {hi}")))
    }

    /// [`in_range`] for each width of a hidden-layer list, and for their count.
    pub fn widths(field: &str, w: &[usize]) -> Result<(), super::LearnError> {
        in_range(&format!("{field} (number of layers)"), w.len(), 0, HIDDEN_LAYERS)?;
        w.iter().try_for_each(|&v| in_range(field, v, 1, HIDDEN_WIDTH))
    }
}
