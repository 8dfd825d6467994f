//! The joint-limits measure ([`ace_models::metrics::joint_limits`]) on the bundled robots, and the
//! datasets' joints against their files' limits.

use std::ops::Range;
use std::path::PathBuf;

use ace_models::dataset::{DatasetConfig, generate};
use ace_models::kinematics::{CharacterPose, KinematicTree};
use ace_models::metrics::{joint_limits, percent};
use ace_models::metrics::joint_limits::{POSITION_TOLERANCE, VELOCITY_TOLERANCE};
use ace_models::morphology::{Morphology, load_character};
use ace_models::nalgebra::Isometry3;

mod common;

fn character(name: &str) -> (KinematicTree, Morphology) {
    let p = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join(format!("../assets/characters/{name}.urdf"));
    load_character(&p).unwrap_or_else(|e| panic!("{e}"))
}

/// Stretch standing at its neutral pose for `frames` frames, with `f(k, q)` changing DoF values.
fn stretch_poses(tree: &KinematicTree, frames: usize, f: impl Fn(usize, &mut [f32])) -> Vec<CharacterPose> {
    (0..frames)
        .map(|k| {
            let mut p = tree.neutral_pose(Isometry3::identity());
            f(k, &mut p.q);
            p
        })
        .collect()
}

const FPS: f32 = 30.0;

#[test]
fn a_joint_faster_than_its_limit_is_caught_frame_by_frame() {
    let (tree, _) = character("stretch");
    let lift = tree.dof_index("joint_lift").unwrap();
    let limit = tree.dof_joint(lift).limits.unwrap().velocity;
    assert_eq!(limit, 0.3, "the bundled Stretch's lift");
    let all = |n: usize| -> Vec<Range<usize>> { vec![0..n] };

    // Rising at 0.9 of its limit: never over; the peak is the speed.
    let slow = stretch_poses(&tree, 60, |k, q| q[lift] = 0.1 + 0.9 * limit * k as f32 / FPS);
    let r = joint_limits(&tree, &slow, FPS, &all(60)).unwrap();
    assert_eq!(r.frames, 60);
    assert_eq!(r.over_velocity, 0.0);
    let u = r.joints.iter().find(|u| u.joint == "joint_lift").unwrap();
    assert!((u.peak_velocity - 0.9 * limit).abs() < 1e-4, "{u:?}");
    assert!(r.over().is_empty());
    // Exactly at the limit is not over (float rounding of a motion at its limit), nor at the tolerance.
    let at = stretch_poses(&tree, 60, |k, q| q[lift] = 0.1 + limit * k as f32 / FPS);
    assert_eq!(joint_limits(&tree, &at, FPS, &all(60)).unwrap().over_velocity, 0.0);
    let edge = limit * (1.0 + VELOCITY_TOLERANCE);
    let at_tolerance = stretch_poses(&tree, 2, |k, q| q[lift] = [0.0, edge][k]);
    assert_eq!(joint_limits(&tree, &at_tolerance, 1.0, &all(2)).unwrap().over_velocity, 0.0);
    let past = stretch_poses(&tree, 2, |k, q| q[lift] = [0.0, 1.001 * edge][k]);
    assert_eq!(joint_limits(&tree, &past, 1.0, &all(2)).unwrap().over_velocity, 0.5);

    // Twice its limit for frames 20..30 (ten steps into frames 21..=30), else still.
    let fast = stretch_poses(&tree, 60, |k, q| {
        let t = (k.clamp(20, 30) - 20) as f32 / FPS;
        q[lift] = 0.1 + 2.0 * limit * t;
    });
    let r = joint_limits(&tree, &fast, FPS, &all(60)).unwrap();
    let u = r.joints.iter().find(|u| u.joint == "joint_lift").unwrap();
    assert_eq!(u.frames_over, 10, "{u:?}");
    assert!((u.peak_ratio().unwrap() - 2.0).abs() < 1e-3, "{u:?}");
    assert!((r.over_velocity - 10.0 / 60.0).abs() < 1e-6);
    assert_eq!(r.over()[0].joint, "joint_lift");
    assert!((r.worst_ratio() - 2.0).abs() < 1e-3);
    assert_eq!(r.outside_position, 0.0);
    assert!(r.has_velocity_limits());
    // What `ace metrics` and `ace retarget` print: the share and the joint over its limit.
    let text = r.to_string();
    assert!(
        text.contains("16.7 % of frames over a velocity limit") && text.contains("joint_lift: 0.600 at most, 2.00 times its limit of 0.300, over it in 10 frames"),
        "{text}"
    );

    // The same jump between two episodes is not a velocity.
    let jump = stretch_poses(&tree, 60, |k, q| q[lift] = if k < 30 { 0.1 } else { 0.8 });
    let r = joint_limits(&tree, &jump, FPS, &[0..30, 30..60]).unwrap();
    assert_eq!(r.over_velocity, 0.0, "{r}");
    let r = joint_limits(&tree, &jump, FPS, &all(60)).unwrap();
    assert_eq!(r.over_velocity, 1.0 / 60.0, "{r}");
    // Only the episodes' frames count.
    assert_eq!(joint_limits(&tree, &jump, FPS, &[0..10]).unwrap().frames, 10);
    // One frame in 3,000 is not "0.0 % of frames" (what `ace retarget`'s warning said of it).
    let rare = stretch_poses(&tree, 3000, |k, q| q[lift] = if k < 1500 { 0.1 } else { 0.8 });
    let r = joint_limits(&tree, &rare, FPS, &all(3000)).unwrap();
    assert!(r.to_string().starts_with("joint limits: < 0.1 % of frames over a velocity limit, 0.0 % outside"), "{r}");
    assert_eq!((percent(0.0), percent(0.0004), percent(0.0006), percent(1.0)), ("0.0 %".into(), "< 0.1 %".into(), "0.1 %".into(), "100.0 %".into()));
}

#[test]
fn a_wheel_turning_within_its_limit_is_not_over_where_its_angle_wraps() {
    let (tree, _) = character("stretch");
    let wheel = tree.dof_index("joint_left_wheel").unwrap();
    let limit = tree.dof_joint(wheel).limits.unwrap().velocity;
    assert_eq!(limit, 12.0);
    // 10 rad/s with the angle kept in [−π, π], as a wheel's pose angle is: it wraps every 19 frames.
    let spinning = stretch_poses(&tree, 90, |k, q| q[wheel] = ace_models::frame::wrap_pi(10.0 * k as f32 / FPS));
    let r = joint_limits(&tree, &spinning, FPS, &[0..90]).unwrap();
    let u = r.joints.iter().find(|u| u.joint == "joint_left_wheel").unwrap();
    assert_eq!(u.frames_over, 0, "{u:?}");
    assert!((u.peak_velocity - 10.0).abs() < 1e-3, "{u:?}");
    assert_eq!(u.frames_outside, 0, "a continuous joint has no position bounds");
    // 14 rad/s is over in every frame but the first.
    let fast = stretch_poses(&tree, 90, |k, q| q[wheel] = ace_models::frame::wrap_pi(14.0 * k as f32 / FPS));
    let r = joint_limits(&tree, &fast, FPS, &[0..90]).unwrap();
    assert_eq!(r.joints.iter().find(|u| u.joint == "joint_left_wheel").unwrap().frames_over, 89);
}

#[test]
fn a_joint_outside_its_bounds_is_caught_and_a_character_without_limits_has_none() {
    let (tree, _) = character("stretch");
    let lift = tree.dof_index("joint_lift").unwrap();
    let l = tree.dof_joint(lift).limits.unwrap();
    let poses = stretch_poses(&tree, 10, |k, q| {
        q[lift] = match k {
            3 => l.upper + 0.01,
            4 => l.lower - 0.01,
            5 => l.upper + 0.0005,
            _ => 0.5 * (l.lower + l.upper),
        }
    });
    let r = joint_limits(&tree, &poses, 1.0, &[0..10]).unwrap();
    let u = r.joints.iter().find(|u| u.joint == "joint_lift").unwrap();
    assert_eq!(u.frames_outside, 2, "{u:?} (within the tolerance is not outside)");
    assert!((r.outside_position - 0.2).abs() < 1e-6);
    // A bound away from zero (the wrist's −1.75 rad): exactly at the tolerance is not outside, past it is.
    let wrist = tree.dof_index("joint_wrist_yaw").unwrap();
    let w = tree.dof_joint(wrist).limits.unwrap();
    let poses = stretch_poses(&tree, 4, |k, q| {
        q[wrist] = [w.lower - POSITION_TOLERANCE, w.lower - 2.0 * POSITION_TOLERANCE, w.upper + POSITION_TOLERANCE, w.upper + 0.1][k]
    });
    let r = joint_limits(&tree, &poses, 1.0, &[0..4]).unwrap();
    assert_eq!(r.joints.iter().find(|u| u.joint == "joint_wrist_yaw").unwrap().frames_outside, 2, "{r}");

    // A creature's bones carry no velocity limits, but its position limits count: the hound's.
    let hound = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../assets/creatures/hound.glb");
    let (tree, _) = load_character(&hound).unwrap();
    let r = joint_limits(&tree, &[tree.neutral_pose(Isometry3::identity()), tree.neutral_pose(Isometry3::identity())], FPS, &[0..2]).unwrap();
    assert!(r.joints.iter().all(|u| u.velocity_limit.is_none()) && !r.has_velocity_limits());
    assert_eq!((r.over_velocity, r.outside_position), (0.0, 0.0));
    assert!(r.to_string().starts_with("joint limits: no velocity limits given, 0.0 % outside"), "{r}");
}

#[test]
fn a_zero_velocity_limit_means_none() {
    // URDF writes velocity="0" for "no limit"; a tree built otherwise may carry the 0 itself.
    let (mut tree, _) = character("stretch");
    let lift = tree.dof_index("joint_lift").unwrap();
    let link = tree.dof_link(lift);
    tree.links[link].joint.as_mut().unwrap().limits.as_mut().unwrap().velocity = 0.0;
    let moving = stretch_poses(&tree, 10, |k, q| q[lift] = 0.1 + 0.05 * k as f32);
    let r = joint_limits(&tree, &moving, FPS, &[0..10]).unwrap();
    let u = r.joints.iter().find(|u| u.joint == "joint_lift").unwrap();
    assert_eq!((u.velocity_limit, u.frames_over), (None, 0), "{u:?}");
}

/// Share of a character's dataset frames (6,000 frames of `cfg`) over a velocity limit, with the
/// report.
fn over_with(tree: &KinematicTree, morph: &Morphology, cfg: DatasetConfig) -> (f32, String) {
    let (over, _, report) = use_with(tree, morph, cfg);
    (over, report)
}

/// [`over_with`], and the highest peak velocity of a foot's chain (the legs) against its joint's limit.
fn use_with(tree: &KinematicTree, morph: &Morphology, cfg: DatasetConfig) -> (f32, f32, String) {
    let set = generate(tree, morph, &DatasetConfig { frames: 6_000, ..cfg }, &mut |_| {}).unwrap();
    let poses: Vec<CharacterPose> = (0..set.len()).map(|i| set.pose(i)).collect();
    let r = joint_limits(tree, &poses, set.fps, &set.episodes).unwrap();
    let on_leg = |name: &str| {
        let d = tree.dof_index(name).unwrap();
        morph.feet.iter().any(|&f| tree.is_descendant(f, tree.dof_link(d)))
    };
    let legs = r
        .joints
        .iter()
        .filter(|u| on_leg(&u.joint))
        .filter_map(|u| u.velocity_limit.map(|l| u.peak_velocity / l))
        .fold(0.0, f32::max);
    (r.over_velocity, legs, r.to_string())
}

/// [`over_with`] a bundled character's default configuration.
fn dataset_over(name: &str) -> (f32, String) {
    let (tree, morph) = character(name);
    over_with(&tree, &morph, DatasetConfig::default())
}

/// The default configuration with the leg joints' limits ignored, as datasets recorded before
/// `leg_limits` read.
fn without_leg_limits() -> DatasetConfig {
    let mut cfg = DatasetConfig::default();
    cfg.controller.scaling.leg_limits = false;
    cfg
}

#[test]
fn the_legged_robots_datasets_keep_their_legs_within_their_velocity_limits() {
    // The bundled crab (6 rad/s everywhere) swung its legs at up to 2.2 times their limit without
    // them. Spot (hips 17.6 rad/s, knees 12) keeps to its own but in a swing or two that is not a steady
    // gait's (2 frames of 6,000, at 1.03 and 1.12 times).
    let (tree, morph) = character("crab");
    let (before, report) = over_with(&tree, &morph, without_leg_limits());
    assert!(before > 0.1, "the crab's legs without their limits: {report}");
    let (over, legs, report) = use_with(&tree, &morph, DatasetConfig::default());
    assert_eq!(over, 0.0, "{report}");
    // … and walks about as fast as they allow: its fastest leg joint comes near its limit (0.82).
    assert!(legs > 0.7, "the crab's legs at most {legs} of their limits: {report}");
    let (tree, morph) = character("spot");
    let (over, legs, report) = use_with(&tree, &morph, DatasetConfig::default());
    assert!(over < 0.001 && legs > 0.7, "{legs}: {report}");
}

#[test]
fn the_real_hexapods_legs_keep_within_their_servos_limits() {
    // The shared PhantomX: 5.65 rad/s servos. Without the leg limits 44 % of a 20,000-frame dataset's
    // frames had a joint over (up to 3 times); with them 0.4 % (at most 1.25 times), where a swing is
    // not the steady gait's (speeding up, turning while stepping).
    let Some(robots) = common::robots() else { return };
    let file = robots.join("phantomx_hexapod/phantomx_description/urdf/phantomx.urdf");
    let (tree, morph) = load_character(&file).unwrap_or_else(|e| panic!("{e}"));
    let (before, report) = over_with(&tree, &morph, without_leg_limits());
    assert!(before > 0.2, "{report}");
    let (over, legs, report) = use_with(&tree, &morph, DatasetConfig::default());
    assert!(over < 0.01 && legs > 0.7, "{legs}: {report}");
}

#[test]
fn the_wheeled_robots_dataset_keeps_its_wheels_within_their_velocity_limits() {
    let (over, report) = dataset_over("stretch");
    assert_eq!(over, 0.0, "{report}");
}

#[test]
fn a_dataset_recorded_before_the_wheel_limits_regenerates_as_it_was() {
    let mut record = serde_json::to_value(DatasetConfig::default()).unwrap();
    assert_eq!(record["controller"]["scaling"]["wheel_limits"], true);
    record["controller"]["scaling"].as_object_mut().unwrap().remove("wheel_limits");
    let old = DatasetConfig::from_record(record).unwrap();
    assert!(!old.controller.scaling.wheel_limits);
    let (tree, morph) = character("stretch");
    let set = generate(&tree, &morph, &DatasetConfig { frames: 3_000, ..old }, &mut |_| {}).unwrap();
    let poses: Vec<CharacterPose> = (0..set.len()).map(|i| set.pose(i)).collect();
    assert!(joint_limits(&tree, &poses, set.fps, &set.episodes).unwrap().over_velocity > 0.1);
}

#[test]
fn a_dataset_recorded_before_the_leg_limits_regenerates_as_it_was() {
    // Recorded before the leg limits and the walking pace: neither applies.
    let mut record = serde_json::to_value(DatasetConfig::default()).unwrap();
    assert_eq!(record["controller"]["scaling"]["leg_limits"], true);
    assert_eq!(record["controller"]["scaling"]["walking_pace"], 1.5);
    for key in ["leg_limits", "walking_pace"] {
        record["controller"]["scaling"].as_object_mut().unwrap().remove(key);
    }
    let old = DatasetConfig::from_record(record).unwrap();
    let mut expected = without_leg_limits().controller;
    expected.scaling.walking_pace = None;
    assert_eq!(old.controller, expected);
    let (tree, morph) = character("crab");
    let (over, report) = over_with(&tree, &morph, old);
    assert!(over > 0.1, "{report}");
}
