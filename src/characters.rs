//! Where the CLI finds characters: `--character` takes a bundled character's name (the robots `spot`,
//! `crab`, `stretch` in `assets/characters/`, the creature `hound` in `assets/creatures/`) or a path to
//! any URDF robot or rigged glTF creature (`.glb`/`.gltf`).

use std::path::{Path, PathBuf};

use ace::models::dataset::MotionSet;
use ace::models::kinematics::KinematicTree;
use ace::models::morphology::{Morphology, load_character};
use anyhow::{Result, bail};

/// Names of the bundled characters.
pub const BUNDLED: [&str; 4] = ["spot", "crab", "stretch", "hound"];

/// The bundled characters' files under `assets/`, in [`BUNDLED`] order.
const BUNDLED_FILES: [&str; 4] = ["characters/spot.urdf", "characters/crab.urdf", "characters/stretch.urdf", "creatures/hound.glb"];

/// The project's `assets/` folder: the one beside the sources this binary was built from, named
/// `./assets` when run from the repository root (so that reports keep relative paths). A game
/// project's own `assets/` is not it (it took over the bundled names); `./assets` stands in only when
/// the sources are gone (a binary moved elsewhere).
pub fn assets_dir() -> PathBuf {
    let (here, built) = (Path::new("assets"), Path::new(env!("CARGO_MANIFEST_DIR")).join("assets"));
    match (here.canonicalize(), built.canonicalize()) {
        (Ok(a), Ok(b)) if a == b => here.to_path_buf(),
        (_, Ok(_)) => built,
        _ if here.join("characters").is_dir() => here.to_path_buf(),
        _ => built,
    }
}

/// The URDF a `--character` value names: an existing path (not a directory) as given, else a bundled
/// character's name.
pub fn character_path(arg: &str) -> Result<PathBuf> {
    let path = Path::new(arg);
    // A FIFO or a device goes to the reader, which refuses it by name (a directory may be a
    // checkpoint folder named after a bundled character).
    if path.is_file() || (path.exists() && !path.is_dir()) {
        return Ok(path.to_path_buf());
    }
    if let Some(k) = BUNDLED.iter().position(|b| *b == arg) {
        return Ok(assets_dir().join(BUNDLED_FILES[k]));
    }
    bail!(
        "no character `{arg}`: not a URDF or glTF file, nor a bundled character ({})",
        BUNDLED.join(", ")
    )
}

/// Loads the character a `--character` value names, with its morphology (and profile, when one sits
/// beside the URDF).
pub fn load(arg: &str) -> Result<(PathBuf, KinematicTree, Morphology)> {
    let path = character_path(arg)?;
    let (tree, morph) = load_character(&path)?;
    // What the importer changed or could not read (a frozen anchor joint, a missing mesh) is said.
    for w in &tree.warnings {
        eprintln!("warning: {}: {w}", path.display());
    }
    Ok((path, tree, morph))
}

/// Fails unless a motion file was made for this character (same DoF names).
pub fn check_dataset(set: &MotionSet, file: &Path, tree: &KinematicTree, urdf: &Path) -> Result<()> {
    let names = tree.dof_names();
    if set.dof_names != names {
        bail!(
            "{}: made for character `{}` with {} DoF, which does not match {} ({} DoF); pass the character's file (URDF or glTF) with --character",
            file.display(),
            set.character,
            set.dof_names.len(),
            urdf.display(),
            names.len()
        );
    }
    Ok(())
}
