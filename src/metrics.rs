//! `ace metrics`: the motion-quality metrics of paper §7.3 (UFR with its detectors, DIV, FID) of a
//! character motion file.

use std::path::Path;

use ace::models::dataset::MotionSet;
use ace::models::features::{EndEffectorMapping, FeatureLayout, FeatureWeights, character_body_length, character_features};
use ace::models::kinematics::KinematicTree;
use ace::models::metrics::{
    DivConfig, GaussianFit, MetricsInput, MetricsReport, UfrConfig, gait_of_labelled_poses, joint_limits, ufr_episodes,
};
use ace::models::morphology::Morphology;
use anyhow::{Result, bail};

use crate::characters;

/// Runs `ace metrics FILE [--character C] [--reference DATASET] [--json]`.
pub fn run(file: &Path, character: Option<&str>, reference: Option<&Path>, json: bool) -> Result<()> {
    let set = MotionSet::load(file)?;
    let (urdf, tree, morph) = characters::load(&character_of(&set, file, character)?)?;
    characters::check_dataset(&set, file, &tree, &urdf)?;
    let reference = match reference {
        Some(r) => {
            let other = MotionSet::load(r)?;
            characters::check_dataset(&other, r, &tree, &urdf)?;
            // FID compares the two sets' covariances of Ψ: with fewer frames than Ψ has entries, one
            // of them is singular and the distance says more about the frame count than the motion.
            let dim = FeatureLayout::new(&EndEffectorMapping::by_side(&tree, &morph)).dim();
            for (path, frames) in [(r, other.len()), (file, set.len())] {
                if frames <= dim {
                    bail!(
                        "{}: {frames} frame(s) cannot give an FID: it compares covariances of {dim} features, \
                         which needs at least {} frames in each set (leave out --reference for the other metrics)",
                        path.display(),
                        dim + 1
                    );
                }
            }
            Some(other)
        }
        None => None,
    };
    let report = dataset_metrics(&tree, &morph, &set, reference.as_ref());
    if json {
        println!("{}", serde_json::to_string_pretty(&report)?);
    } else {
        println!("{} ({} on {})\n{report}", file.display(), set.character, urdf.display());
    }
    Ok(())
}

/// The `--character` value for the motion set read from `file`: the one given, else the bundled
/// character of its name, else the character file it recorded being made from. Datasets record that
/// file's absolute path; older ones recorded it as it was given, relative to the folder `ace dataset`
/// ran in: such a path is tried from here, then from the dataset's folder (where `--out FILE` put it).
pub fn character_of(set: &MotionSet, file: &Path, given: Option<&str>) -> Result<String> {
    if let Some(c) = given {
        return Ok(c.to_string());
    }
    if characters::BUNDLED.contains(&set.character.as_str()) {
        return Ok(set.character.clone());
    }
    match &set.character_source {
        Some(urdf) if Path::new(urdf).is_file() => Ok(urdf.clone()),
        Some(urdf) if Path::new(urdf).is_relative() => {
            let beside = file.parent().unwrap_or(Path::new("")).join(urdf);
            if beside.is_file() {
                return Ok(beside.display().to_string());
            }
            bail!(
                "the motion file was made for `{}` from {urdf}, which is not a file from here nor from the motion \
                 file's folder ({}); pass --character URDF",
                set.character,
                beside.display()
            )
        }
        Some(urdf) => bail!(
            "the motion file was made for `{}` from {urdf}, which is not a file from here; pass --character URDF",
            set.character
        ),
        None => bail!(
            "the motion file was made for `{}`, which is not a bundled character ({}), and it does not record \
             its URDF; pass --character URDF",
            set.character,
            characters::BUNDLED.join(", ")
        ),
    }
}

/// Ψ of every frame of a motion set, with the by-side end-effector mapping.
pub fn set_features(tree: &KinematicTree, morph: &Morphology, set: &MotionSet) -> Vec<Vec<f32>> {
    let mapping = EndEffectorMapping::by_side(tree, morph);
    let body = character_body_length(tree, morph);
    (0..set.len()).map(|i| character_features(&set.layout, set.state(i), body, &mapping)).collect()
}

/// The metrics of a motion set: UFR over its episodes from its stored poses, DIV of its Ψ, FID
/// against `reference` when given, the gait measure from its stance labels (legged characters) and the
/// joint limits.
pub fn dataset_metrics(tree: &KinematicTree, morph: &Morphology, set: &MotionSet, reference: Option<&MotionSet>) -> MetricsReport {
    let poses: Vec<_> = (0..set.len()).map(|i| set.pose(i)).collect();
    let ufr = ufr_episodes(tree, morph, &poses, &set.episodes, set.fps, &UfrConfig::for_character(tree, morph));
    let features = set_features(tree, morph, set);
    let fit = reference.map(|r| GaussianFit::fit(&set_features(tree, morph, r)));
    let mapping = EndEffectorMapping::by_side(tree, morph);
    let mut report = MetricsReport::compute(
        &MetricsInput {
            features: &features,
            reference: fit.as_ref(),
            source_features: None,
            layout: FeatureLayout::new(&mapping),
            weights: FeatureWeights::default(),
            div: DivConfig::default(),
        },
        &ufr,
    );
    if set.n_feet == morph.feet.len() {
        report.gait = gait_of_labelled_poses(tree, morph, &poses, &set.contacts, &set.episodes, set.fps).map(|g| g.summary);
    }
    report.joint_limits = joint_limits(tree, &poses, set.fps, &set.episodes);
    report
}
