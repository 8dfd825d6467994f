//! Export of retargeted motion (paper §7.5): glTF 2.0 binaries for games and viewers, and command
//! trajectories (base velocity, base height, joint positions) for robots.
//!
//! - [`gltf`]: a character motion (and optionally the human skeleton beside it) as one `.glb` with a
//!   node per link, meshes for the visual geometry and one animation;
//! - [`tessellate`]: the triangle meshes of URDF primitives (mesh files are read by
//!   [`crate::mesh_file`]);
//! - [`rig`]: a clip on a rigged glTF creature's own model, as a new animation on its skeleton;
//! - [`trajectory`]: [`CommandTrajectory`], written as JSON or CSV;
//! - [`writer`]: the typed glTF document ([`gltf_json`]) and GLB container both glTF exports write.
//!
//! Every writer goes through [`write_atomic`]: the bytes land in a temporary file beside the target
//! that is renamed over it, so a failed export never leaves a half-written file.

pub mod gltf;
pub mod rig;
pub mod tessellate;
pub mod trajectory;
pub mod writer;

#[cfg(test)]
mod tests;

pub use gltf::{GlbOutput, GltfOptions, HumanOverlay, character_glb, write_glb};
pub use rig::{RigClipOptions, RigClipOutput, rig_clip_glb, write_rig_clip};
pub use trajectory::{CommandFrame, CommandTrajectory};

use std::path::Path;

use thiserror::Error;

use crate::character::gltf::GltfError;
use crate::kinematics::{CharacterPose, KinematicTree};

/// An export error: the file being written (or, for exports to memory, what was being exported) and
/// what is wrong.
#[derive(Debug, Error)]
#[error("{file}: {problem}")]
pub struct ExportError {
    /// The output file, or `<… in memory>` for exports that write no file.
    pub file: String,
    /// What is wrong.
    pub problem: ExportProblem,
}

/// The problems [`ExportError`] reports.
#[derive(Debug, Error)]
pub enum ExportProblem {
    #[error("there are no frames to export")]
    NoFrames,
    #[error("the frame rate must be positive and finite, got {0}")]
    BadFps(f32),
    #[error("frame {frame} has {got} joint values, the character has {want} DoFs")]
    PoseLength { frame: usize, got: usize, want: usize },
    #[error("frame {frame} has a non-finite {what}")]
    NonFinite { frame: usize, what: String },
    #[error("the human skeleton has {human} frames but the character motion has {character}")]
    HumanFrameCount { human: usize, character: usize },
    #[error("the binary data is {0} bytes, more than a GLB can hold")]
    TooLarge(usize),
    #[error("the creature names no file it was loaded from, so there is no model to write its clip onto")]
    NoSource,
    #[error("cannot read the creature's model: {0}")]
    Source(#[from] GltfError),
    #[error("{model} has no skin: a clip goes onto a rigged (skinned) glTF model")]
    NoSkin { model: String },
    #[error("{model} is not the model the creature was loaded from: {why}")]
    NotTheCreature { model: String, why: String },
    #[error("{model}: image {index} cannot be embedded: {reason}")]
    Image { model: String, index: usize, reason: String },
    #[error("cannot write: {0}")]
    Io(#[from] std::io::Error),
}

impl ExportProblem {
    /// Attaches the file name.
    pub fn in_file(self, file: impl Into<String>) -> ExportError {
        ExportError {
            file: file.into(),
            problem: self,
        }
    }
}

/// Checks a motion before export: at least one pose, a positive finite frame rate, one finite value
/// per DoF and a finite root pose in every frame.
pub fn check_poses(tree: &KinematicTree, poses: &[CharacterPose], fps: f32) -> Result<(), ExportProblem> {
    if poses.is_empty() {
        return Err(ExportProblem::NoFrames);
    }
    if !(fps.is_finite() && fps > 0.0) {
        return Err(ExportProblem::BadFps(fps));
    }
    for (frame, p) in poses.iter().enumerate() {
        if p.q.len() != tree.dof() {
            return Err(ExportProblem::PoseLength {
                frame,
                got: p.q.len(),
                want: tree.dof(),
            });
        }
        let root = p
            .root
            .translation
            .vector
            .iter()
            .chain(p.root.rotation.coords.iter());
        if !root.into_iter().all(|v| v.is_finite()) {
            return Err(ExportProblem::NonFinite {
                frame,
                what: "root pose".into(),
            });
        }
        if let Some(d) = p.q.iter().position(|v| !v.is_finite()) {
            return Err(ExportProblem::NonFinite {
                frame,
                what: format!("value of joint `{}`", tree.dof_joint(d).name),
            });
        }
    }
    Ok(())
}

/// Writes the model `glb` (a GLB container) to `path` atomically (see [`write_atomic`]): as it is, or,
/// when `path` ends in `.gltf` (any case), in glTF's JSON form with the binary data embedded
/// ([`writer::gltf_text`]), as the name promises.
pub fn write_model(path: &Path, glb: &[u8]) -> Result<(), ExportError> {
    let text = path.extension().is_some_and(|e| e.eq_ignore_ascii_case("gltf"));
    if text {
        let json = writer::gltf_text(glb).map_err(|p| p.in_file(path.display().to_string()))?;
        write_atomic(path, &json)
    } else {
        write_atomic(path, glb)
    }
}

/// Writes `bytes` to `path` atomically: into a temporary file in the same directory, flushed to disk,
/// then renamed over `path`. On failure the temporary file is removed and `path` is left as it was.
pub fn write_atomic(path: &Path, bytes: &[u8]) -> Result<(), ExportError> {
    crate::temporary::write_atomically(path, bytes).map_err(|e| ExportProblem::Io(e).in_file(path.display().to_string()))
}
