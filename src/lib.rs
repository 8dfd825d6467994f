//! ACE for Bevy: the core (`models`), the Bevy plugin (`plugin`), and the commands of the `ace` CLI
//! as a library (the editor runs the same retargeting, scoring, export and training).

// The modules name this crate `ace`, as its users do.
extern crate self as ace;

pub use ace_models as models;
pub use bevy_ace as plugin;

pub mod baselines;
pub mod batch;
pub mod characters;
pub mod dataset;
pub mod demo;
pub mod eval;
pub mod fine_tune;
pub mod humans;
pub mod inspect;
pub mod limits;
pub mod metrics;
pub mod output;
pub mod picture;
pub mod plot;
pub mod progress;
pub mod report;
pub mod retarget;
pub mod scoring;
pub mod train;
