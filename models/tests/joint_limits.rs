//! The joint-limits measure ([`ace_models::metrics::joint_limits`]) on the bundled robots, and the
//! datasets' joints against their files' limits.

use std::ops::Range;
use std::path::PathBuf;

use ace_models::dataset::{DatasetConfig, generate};
use ace_models::kinematics::{CharacterPose, KinematicTree};
use ace_models::metrics::joint_limits;
use ace_models::morphology::{Morphology, load_character};
use ace_models::nalgebra::Isometry3;

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
    // Exactly at the limit is not over (float rounding of a motion at its limit).
    let at = stretch_poses(&tree, 60, |k, q| q[lift] = 0.1 + limit * k as f32 / FPS);
    assert_eq!(joint_limits(&tree, &at, FPS, &all(60)).unwrap().over_velocity, 0.0);

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

    // The same jump between two episodes is not a velocity.
    let jump = stretch_poses(&tree, 60, |k, q| q[lift] = if k < 30 { 0.1 } else { 0.8 });
    let r = joint_limits(&tree, &jump, FPS, &[0..30, 30..60]).unwrap();
    assert_eq!(r.over_velocity, 0.0, "{r}");
    let r = joint_limits(&tree, &jump, FPS, &all(60)).unwrap();
    assert_eq!(r.over_velocity, 1.0 / 60.0, "{r}");
    // Only the episodes' frames count.
    assert_eq!(joint_limits(&tree, &jump, FPS, &[0..10]).unwrap().frames, 10);
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

    // A creature's bones carry no velocity limits, but its position limits count: the hound's.
    let hound = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../assets/creatures/hound.glb");
    let (tree, _) = load_character(&hound).unwrap();
    let r = joint_limits(&tree, &[tree.neutral_pose(Isometry3::identity()), tree.neutral_pose(Isometry3::identity())], FPS, &[0..2]).unwrap();
    assert!(r.joints.iter().all(|u| u.velocity_limit.is_none()) && !r.has_velocity_limits());
    assert_eq!((r.over_velocity, r.outside_position), (0.0, 0.0));
}

/// Share of a bundled character's dataset frames (default configuration, 6,000 frames) over a
/// velocity limit, with the report.
fn dataset_over(name: &str) -> (f32, String) {
    let (tree, morph) = character(name);
    let cfg = DatasetConfig {
        frames: 6_000,
        ..DatasetConfig::default()
    };
    let set = generate(&tree, &morph, &cfg, &mut |_| {}).unwrap();
    let poses: Vec<CharacterPose> = (0..set.len()).map(|i| set.pose(i)).collect();
    let r = joint_limits(&tree, &poses, set.fps, &set.episodes).unwrap();
    (r.over_velocity, r.to_string())
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
