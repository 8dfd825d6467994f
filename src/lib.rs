pub use ace_models as models; pub use bevy_ace as plugin;
