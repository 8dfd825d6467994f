//! Human motion import: BVH files in any of the common skeleton conventions → the canonical 17-joint
//! skeleton in metres, z up ([`HumanClip`]) → the per-frame human state x^h ([`HumanState`], paper §6.1).
//!
//! - [`bvh`]: a strict BVH reader with line-numbered errors;
//! - [`names`], [`matching`]: rule-based joint matching; [`mapping`]: user [`JointMapping`] files;
//! - [`conventions`]: names of the recognised conventions (CMU cgspeed MotionBuilder/3ds Max/Daz,
//!   iClone, HumanIK, Bandai, Mixamo, LAFAN1);
//! - [`fk`]: forward kinematics; [`units`]: units and up axes;
//! - [`import`]: the pipeline, with what it infers from the posed skeleton (translation semantics,
//!   up axis, leading rest frames, floor, height) in private helpers;
//! - [`clip`]: clips, interpolation, resampling; [`state`]: x^h and its [`layout`].

pub mod bvh;
pub mod clip;
pub mod conventions;
mod detect;
pub mod error;
pub mod fk;
pub mod import;
pub mod mapping;
pub mod matching;
pub mod names;
pub mod skeleton;
pub mod state;
#[cfg(test)]
mod test_rig;
mod tracks;
pub mod units;

pub use clip::{HumanClip, HumanFrame, ImportOptions};
pub use error::HumanImportError;
pub use import::{ImportReport, import_with_report};
pub use mapping::JointMapping;
pub use skeleton::{EndEffector, JOINT_COUNT, Joint};
pub use state::{HumanState, layout};
