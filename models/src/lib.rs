//! # ace_models
//!
//! The Bevy-free core of ACE retargeting (Adversarial Correspondence Embedding, SIGGRAPH Asia 2023):
//! human motion import (BVH → canonical skeleton → human state x^h), character import
//! (URDF → kinematic tree → forward kinematics, morphology, character state x^r), inference with
//! trained checkpoints in pure Rust ([`runtime`]) and, behind the `learn` feature, the learning modules
//! that use libtorch (training, and inference through libtorch for comparison).
//!
//! Conventions everywhere in this crate: right-handed, z up, metres, seconds, `f32`.

/// The glTF reader whose documents [`character::gltf::open`] returns.
pub use gltf;
pub use nalgebra;

pub mod character;
pub mod character_state;
pub mod checkpoint;
pub mod cleanup;
pub mod collision_guard;
pub mod controller;
pub mod correspondence;
pub mod dataset;
pub mod dynamic_similarity;
pub mod effector_hold;
pub mod export;
pub mod features;
pub mod foot_lock;
pub mod frame;
pub mod geometry;
pub mod heading;
pub mod human;
pub mod human_set;
pub mod input;
pub mod kinematics;
pub mod mesh_file;
#[cfg(feature = "learn")]
pub mod learn;
pub mod metrics;
pub mod morphology;
pub mod runtime;
pub mod standing;
pub mod temporary;
#[cfg(test)]
mod test_data;
pub mod urdf;
pub mod velocity_limit;
