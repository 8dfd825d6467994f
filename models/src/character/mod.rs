//! Character sources other than URDF. A rigged glTF creature ([`gltf`], [`body_plan`]) becomes the same
//! [`KinematicTree`] and [`Morphology`] a URDF robot does; [`crate::morphology::load_character`] picks
//! the source from the file's extension.

pub mod body_plan;
pub mod clips;
pub mod gltf;
pub mod helpers;
pub mod proxy;
pub mod rig_pose;

use std::path::Path;

use crate::kinematics::KinematicTree;
use crate::morphology::{CharacterError, Morphology, Profile, ProfileError, ProfileProblem};

pub use body_plan::BodyPlan;
pub use gltf::{AnimationInfo, GltfError, SkinInfo};
pub use rig_pose::{NodeTransform, RigPose};

/// Whether `path` names a glTF file (`.glb` or `.gltf`, any case).
pub fn is_gltf(path: &Path) -> bool {
    path.extension()
        .and_then(|e| e.to_str())
        .is_some_and(|e| e.eq_ignore_ascii_case("glb") || e.eq_ignore_ascii_case("gltf"))
}

/// A rigged creature: its tree and morphology, and what the import found and decided.
#[derive(Clone, Debug)]
pub struct Creature {
    pub tree: KinematicTree,
    pub morphology: Morphology,
    pub plan: BodyPlan,
    /// Metres per file unit.
    pub scale: f32,
    /// What was read from the file (bones, vertices, skins, clips), for `ace inspect`, the clips' poses
    /// and the export.
    pub rig: gltf::Rig,
}

/// Loads a glTF creature with the profile beside it, if any (see [`Profile`]'s glTF keys).
pub fn load_creature(path: &Path) -> Result<Creature, CharacterError> {
    let profile = Profile::beside(path)?.unwrap_or_default();
    load_creature_with(path, &profile)
}

/// Loads a glTF creature with `profile`.
pub fn load_creature_with(path: &Path, profile: &Profile) -> Result<Creature, CharacterError> {
    let (doc, buffers) = gltf::open(path)?;
    creature_from_document(&doc, &buffers, path, profile)
}

/// A creature from a glTF document already opened (see [`gltf::open_bytes`] for files read by other
/// means than the file system, such as Bevy's asset reader) with `profile`. `path` names the file in
/// errors and becomes the tree's [`KinematicTree::source`].
pub fn creature_from_document(
    doc: &::gltf::Document,
    buffers: &[Vec<u8>],
    path: &Path,
    profile: &Profile,
) -> Result<Creature, CharacterError> {
    let profile_error = |problem: ProfileProblem| ProfileError {
        file: profile.source.clone().unwrap_or_else(|| path.display().to_string()),
        problem,
    };
    let facing = profile.facing().map_err(profile_error)?;
    let rig = gltf::read_document(doc, buffers, path, profile.scale, facing)?;
    let name = path
        .file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_else(|| "creature".into());
    let ov = body_plan::Overrides {
        feet: profile.feet.clone(),
        manipulators: profile.manipulators.clone(),
        head: profile.head.clone(),
        animated: profile.animated.clone(),
        at_rest: profile.at_rest.clone(),
        dofs: profile.dofs.clone(),
        limits: profile.limits.clone(),
        translate: profile.translate.clone(),
    };
    let (mut tree, mut morphology, plan) =
        body_plan::build(&rig, &name, &ov).map_err(|p| profile_error(ProfileProblem::Body(p)))?;
    if profile.up.is_none() && morphology.feet.len() < 2 {
        if let Some((up, feet)) = stands_up(doc, buffers, path, profile, &name, &ov) {
            tree.warnings.push(format!(
                "with +y up, as glTF says, the creature stands on {} feet; with `up = \"{}\"` it stands on {feet}: \
                 if it lies in the file (exported with z up), set `up` in its profile",
                morphology.feet.len(),
                up.label()
            ));
        }
    }
    tree.source = Some(path.to_path_buf());
    profile.apply_rest_pose(&mut tree)?;
    profile.apply_tip_offsets(&tree, &mut morphology)?;
    Ok(Creature {
        tree,
        morphology,
        plan,
        scale: rig.scale,
        rig,
    })
}

/// The other file axis that, taken as up, gives the creature the most feet (at least two), and how
/// many: a creature that lies in its file stands on none or one.
fn stands_up(
    doc: &::gltf::Document,
    buffers: &[Vec<u8>],
    path: &Path,
    profile: &Profile,
    name: &str,
    ov: &body_plan::Overrides,
) -> Option<(gltf::Axis, usize)> {
    gltf::Axis::ALL[1..]
        .iter()
        .filter_map(|&up| {
            let facing = gltf::Facing::new(profile.forward, Some(up)).ok()?;
            let rig = gltf::read_document(doc, buffers, path, profile.scale, facing).ok()?;
            let (_, morphology, _) = body_plan::build(&rig, name, ov).ok()?;
            Some((up, morphology.feet.len()))
        })
        .filter(|&(_, feet)| feet >= 2)
        .max_by_key(|&(up, feet)| (feet, std::cmp::Reverse(gltf::Axis::ALL.iter().position(|&a| a == up))))
}
