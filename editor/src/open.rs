//! Opening a character: a URDF robot or a rigged glTF creature, by path or by a bundled character's
//! name (as `ace --character` takes it), read once with the core's importer before the editor shows
//! it, so that a bad file is an error naming it (never a panic, never an empty scene).

use std::path::{Path, PathBuf};

use ace::characters::{BUNDLED, character_path};
use ace::models::character::{Creature, is_gltf, load_creature};
use ace::models::kinematics::KinematicTree;
use ace::models::morphology::{Morphology, load_character};
use ace::models::nalgebra::UnitQuaternion;
use anyhow::{Context, Result, bail};
use bevy::prelude::*;
use bevy_ace::convert;

use crate::preview::checkpoint_beside;

/// A character the editor can show.
#[derive(Clone, Debug, PartialEq)]
pub struct Opened {
    /// Its file (absolute).
    pub path: PathBuf,
    /// The checkpoint shipped for it (`assets/checkpoints/<name>` for a bundled character).
    pub checkpoint: Option<PathBuf>,
    /// For a rigged glTF creature, where its glTF scene goes (see [`scene_placement`]); `None` for a
    /// URDF robot, whose links the plugin spawns.
    pub scene_placement: Option<Transform>,
}

/// Opens `text`: an existing URDF or glTF file, or a bundled character's name (`spot`, `hound`, …).
pub fn open_character(text: &str) -> Result<Opened> {
    let text = text.trim();
    if text.is_empty() {
        bail!("no character given: type the path of a URDF or glTF file, or a bundled character ({})", BUNDLED.join(", "));
    }
    let path = character_path(text)?;
    let path = std::path::absolute(&path).unwrap_or(path);
    let urdf = path.extension().is_some_and(|e| e.eq_ignore_ascii_case("urdf"));
    if !urdf && !is_gltf(&path) {
        bail!("{}: not a character file; the editor opens URDF robots (.urdf) and rigged glTF creatures (.glb, .gltf)", path.display());
    }
    // The importer's errors name the file.
    let opening = || "cannot open the character";
    let scene_placement = if urdf {
        load_character(&path).with_context(opening)?;
        None
    } else {
        Some(scene_placement(&load_creature(&path).with_context(opening)?))
    };
    Ok(Opened { checkpoint: checkpoint_beside(&path), path, scene_placement })
}

/// The transform of a creature's glTF scene (the file's frame and units, as Bevy loads it) that puts it
/// where the plugin puts a URDF character: its z-up, metres character frame turned y-up
/// ([`convert`]), so both face +x and stand on the same grid. It is the import's `C` (the file →
/// character rotation scaled to metres) followed by the change of basis.
pub fn scene_placement(c: &Creature) -> Transform {
    let to_character = UnitQuaternion::from_rotation_matrix(&c.rig.to_character);
    // z-up → y-up, (x, y, z) ↦ (x, z, −y): a −90° turn about x.
    let basis = Quat::from_rotation_x(-std::f32::consts::FRAC_PI_2);
    Transform { translation: Vec3::ZERO, rotation: convert::quat(&to_character) * basis, scale: Vec3::splat(c.scale) }
}

/// One line about a character: its name, links, DoF, feet and manipulators.
pub fn describe(tree: &KinematicTree, morph: &Morphology) -> String {
    let names = |v: &[usize]| match v {
        [] => "none".to_string(),
        _ => v.iter().map(|&i| tree.links[i].name.as_str()).collect::<Vec<_>>().join(", "),
    };
    format!(
        "{}: {} links, {} DoF; feet: {}; manipulators: {}",
        tree.name,
        tree.links.len(),
        tree.dof(),
        names(&morph.feet),
        names(&morph.manipulators)
    )
}

/// The kind of a character file, for labels.
pub fn kind(path: &Path) -> &'static str {
    if is_gltf(path) { "rigged glTF creature" } else { "URDF robot" }
}
