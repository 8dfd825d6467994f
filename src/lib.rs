//! ACE for Bevy: the core (`models`), the Bevy plugin (`plugin`) and the PNG charts the CLI draws
//! (`plot`).

pub use ace_models as models;
pub use bevy_ace as plugin;

pub mod plot;
