//! Export: the previewed clip as `ace retarget` writes it (one code path): for a URDF robot its glTF
//! animation with the human beside it, for a rigged glTF creature its own model with the clip as a new
//! animation on its skeleton (the rig clip); the robot command trajectory (JSON, CSV) and the metrics
//! beside it.

use std::path::Path;

use ace::models::morphology::load_character;
use ace::output::Outputs;
use ace::retarget::{Written, write};
use anyhow::Result;

use crate::preview::PreviewResult;

/// Writes the preview's clip to `out` and the files beside it. The export never overwrites what the
/// preview was made from, and appears as a whole or not at all.
pub fn export(result: &PreviewResult, out: &Path) -> Result<Written> {
    let inputs = &result.inputs;
    let (tree, _) = load_character(&inputs.character)?;
    let mut outputs = Outputs::new();
    outputs
        .input_clip(&inputs.clip, "the input clip", None)
        .input(&inputs.checkpoint, "the checkpoint directory")
        .input_character(&inputs.character);
    let written = write(&result.retargeted, &tree, &result.clip, out, true, &mut outputs)?;
    outputs.commit()?;
    Ok(written)
}
