//! The project's own creature, `assets/creatures/hound.glb`: made by `scripts/make_creature.py`, it
//! imports as a quadruped with a head and a tail, its motion dataset is clean, and it and a clip
//! exported onto it pass Khronos' validator.

mod common;
use common::khronos_validate;

use std::path::PathBuf;
use std::process::Command;

use ace_models::character::load_creature;
use ace_models::dataset::{DatasetConfig, generate};
use ace_models::export::{RigClipOptions, write_rig_clip};
use ace_models::kinematics::CharacterPose;
use ace_models::metrics::{UfrConfig, ufr_episodes};

fn repo(path: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("..").join(path)
}

#[test]
fn the_script_makes_the_bundled_file_byte_for_byte() {
    let out = PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join("hound.glb");
    let run = Command::new("python3")
        .arg(repo("scripts/make_creature.py"))
        .arg(&out)
        .output()
        .expect("running python3 (the machine's CPython runs scripts/make_creature.py)");
    assert!(run.status.success(), "make_creature.py failed: {}", String::from_utf8_lossy(&run.stderr));
    let made = std::fs::read(&out).unwrap();
    let bundled = std::fs::read(repo("assets/creatures/hound.glb")).unwrap();
    assert!(made == bundled, "assets/creatures/hound.glb is not what scripts/make_creature.py writes: run it again");
}

#[test]
fn the_hound_is_a_quadruped_with_a_head_and_a_tail() {
    let c = load_creature(&repo("assets/creatures/hound.glb")).unwrap_or_else(|e| panic!("{e}"));
    let names = c.morphology.names(&c.tree);
    let mut feet = names.feet.clone();
    feet.sort();
    assert_eq!(feet, ["FrontFoot.L", "FrontFoot.R", "HindFoot.L", "HindFoot.R"]);
    assert_eq!(names.head.as_deref(), Some("Head"));
    assert!(names.manipulators.is_empty() && names.wheels.is_empty());
    assert_eq!(c.plan.tails, ["Tail3"]);
    assert_eq!(c.scale, 1.0, "authored in metres");
    assert!(c.rig.warnings.is_empty(), "{:?}", c.rig.warnings);
    // Standing, the hips are 0.46 m above the ground.
    let stand = c.tree.forward_kinematics(&c.tree.standing_pose());
    let hips = c.tree.link_index("Hips").unwrap();
    assert!((stand[hips].translation.z - 0.46).abs() < 0.03, "hips at {}", stand[hips].translation.z);
}

#[test]
fn the_hounds_dataset_is_clean() {
    let c = load_creature(&repo("assets/creatures/hound.glb")).unwrap();
    let set = generate(&c.tree, &c.morphology, &DatasetConfig { frames: 6000, seed: 3, ..DatasetConfig::default() }, &mut |_| {})
        .unwrap();
    let poses: Vec<CharacterPose> = (0..set.len()).map(|i| set.pose(i)).collect();
    let ufr =
        ufr_episodes(&c.tree, &c.morphology, &poses, &set.episodes, set.fps, &UfrConfig::for_character(&c.tree, &c.morphology));
    assert!(ufr.rates.ufr <= 0.01, "UFR {:.2} % {:?}", 100.0 * ufr.rates.ufr, ufr.collision_pairs);
}

#[test]
fn the_hound_and_a_clip_on_it_pass_the_validator() {
    let file = repo("assets/creatures/hound.glb");
    let Some(report) = khronos_validate(&file) else { return };
    assert_eq!(report["numWarnings"], 0, "{report}");
    // Two seconds of its own dataset, written onto the model.
    let c = load_creature(&file).unwrap();
    let set = generate(&c.tree, &c.morphology, &DatasetConfig { frames: 60, seed: 1, ..DatasetConfig::default() }, &mut |_| {})
        .unwrap();
    let poses: Vec<CharacterPose> = (0..set.len()).map(|i| set.pose(i)).collect();
    let out = PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join("hound-clip.glb");
    let written = write_rig_clip(&out, &c, &poses, set.fps, &RigClipOptions::default()).unwrap();
    assert!(written.animated_nodes >= 17, "{} nodes animated", written.animated_nodes);
    khronos_validate(&out);
}
