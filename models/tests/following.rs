//! The following measure on a real clip and a real robot: Stretch's gripper driven by its lift to do
//! what the human's right hand does in the bundled `reach` clip (or the opposite, or nothing), scored
//! from the poses alone.

use std::path::PathBuf;

use ace_models::character_state::{CharacterLayout, character_state};
use ace_models::features::{
    EndEffectorMapping, FeatureLayout, character_body_length, character_features, human_body_length, human_features,
    scale_human_speed,
};
use ace_models::human::{EndEffector, HumanClip, ImportOptions, layout as hl};
use ace_models::kinematics::{CharacterPose, KinematicTree};
use ace_models::metrics::{FollowingConfig, FollowingReport, FollowingSummary, following};
use ace_models::morphology::{Morphology, load_character};
use nalgebra::{Isometry3, Translation3, UnitQuaternion, Vector3};

const FPS: f32 = 30.0;

fn repo(path: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("..").join(path)
}

struct Fixture {
    tree: KinematicTree,
    morph: Morphology,
    mapping: EndEffectorMapping,
    /// x^h of the clip.
    human: Vec<Vec<f32>>,
    human_body: f32,
    character_body: f32,
    /// The measure's thresholds (the project's at 30 fps unless a test changes them).
    config: FollowingConfig,
    /// The mapped pairs, in the character's end-effector order.
    pairs: Vec<(String, EndEffector)>,
}

fn fixture() -> Fixture {
    let f = fixture_for("stretch", vec![EndEffector::RightHand]);
    // Stretch has one end effector, its gripper: it follows the right hand.
    assert_eq!(f.pairs, [("grasp_center".to_string(), EndEffector::RightHand)]);
    f
}

/// The bundled `character` against the bundled `reach` clip, its end effectors following `humans`.
fn fixture_for(character: &str, humans: Vec<EndEffector>) -> Fixture {
    let (tree, morph) = load_character(&repo(&format!("assets/characters/{character}.urdf"))).unwrap();
    let text = std::fs::read_to_string(repo("assets/motions/reach.bvh")).unwrap();
    let clip = HumanClip::from_bvh_str(&text, "reach.bvh", &ImportOptions::default()).unwrap().resampled(FPS);
    let human: Vec<Vec<f32>> = clip.states().into_iter().map(|s| s.0.to_vec()).collect();
    let pairs: Vec<(String, EndEffector)> = morph.end_effector_links(&tree).into_iter().zip(humans.iter().copied()).collect();
    assert_eq!(pairs.len(), humans.len(), "one human end effector per character end effector");
    Fixture {
        mapping: EndEffectorMapping::new(humans.into_iter().map(Some).collect()),
        pairs,
        human_body: human_body_length(&clip),
        character_body: character_body_length(&tree, &morph),
        config: FollowingConfig::new(FPS),
        tree,
        morph,
        human,
    }
}

impl Fixture {
    /// The right hand's height above the pelvis per frame (m).
    fn hand_height(&self) -> Vec<f32> {
        self.human.iter().map(|x| x[hl::ee_position(EndEffector::RightHand)][2]).collect()
    }

    /// Stretch standing still with its lift at `lift(t)` metres, scored against the clip.
    fn score(&self, lift: impl Fn(usize) -> f32) -> FollowingReport {
        let d = self.tree.dof_index("joint_lift").unwrap();
        let poses: Vec<CharacterPose> = (0..self.human.len())
            .map(|t| {
                let mut p = self.tree.neutral_pose(Isometry3::identity());
                p.q[d] = lift(t);
                p
            })
            .collect();
        self.score_poses(&poses, 1.0)
    }

    /// Stretch at `poses` scored against the clip, the human's velocity in Ψ multiplied by `speed`
    /// (as L_fea's speed scale does) and the factor passed on.
    fn score_poses(&self, poses: &[CharacterPose], speed: f32) -> FollowingReport {
        self.score_scaled(poses, speed, speed)
    }

    /// [`Fixture::score_poses`] with the human's velocity multiplied by `speed` and `told` passed as
    /// the factor.
    fn score_scaled(&self, poses: &[CharacterPose], speed: f32, told: f32) -> FollowingReport {
        let layout = CharacterLayout::new(&self.tree, &self.morph);
        let psi: Vec<Vec<f32>> = (0..poses.len())
            .map(|t| {
                let x = character_state(&self.tree, &self.morph, &poses[t.saturating_sub(1)], &poses[t], 1.0 / FPS);
                character_features(&layout, &x, self.character_body, &self.mapping)
            })
            .collect();
        let features = FeatureLayout::new(&self.mapping);
        let human_psi: Vec<Vec<f32>> = self
            .human
            .iter()
            .map(|x| {
                let mut psi = human_features(x, self.human_body, &self.mapping);
                scale_human_speed(&mut psi, &features, speed);
                psi
            })
            .collect();
        following(&features, &self.pairs, &psi, &human_psi, self.human_body, told, &self.config)
    }

    /// The human of the bundled walk instead (it walks at about 1.2 m/s and turns 20° to the left
    /// after 2 s); its clip.
    fn on_the_walk(&mut self) -> HumanClip {
        let text = std::fs::read_to_string(repo("assets/motions/walk.bvh")).unwrap();
        let clip = HumanClip::from_bvh_str(&text, "walk.bvh", &ImportOptions::default()).unwrap().resampled(FPS);
        self.human = clip.states().into_iter().map(|s| s.0.to_vec()).collect();
        clip
    }

    /// The human standing in the clip's first pose for 4 s, its root moving at `v` m/s forward.
    fn standing_human(&mut self, v: f32) {
        let mut first = self.human[0].clone();
        first[hl::ROOT_LINEAR_VELOCITY].copy_from_slice(&[v, 0.0, 0.0]);
        first[hl::ROOT_ANGULAR_VELOCITY].fill(0.0);
        self.human = vec![first; 120];
    }

    /// The lift that moves the gripper up and down as the hand does, scaled from the human's body to
    /// Stretch's, around 0.4 m; `sign` −1 moves it the opposite way.
    fn mirroring(&self, sign: f32) -> impl Fn(usize) -> f32 + '_ {
        let h = self.hand_height();
        let scale = self.character_body / self.human_body;
        move |t| 0.4 + sign * scale * (h[t] - h[0])
    }
}

#[test]
fn a_gripper_that_moves_with_the_hand_follows_it() {
    let f = fixture();
    let h = f.hand_height();
    let hand_range = h.iter().cloned().fold(f32::MIN, f32::max) - h.iter().cloned().fold(f32::MAX, f32::min);
    assert!(hand_range > 0.3, "the reach clip's right hand moves {hand_range} m up and down");
    let r = f.score(f.mirroring(1.0));
    let p = &r.pairs[0];
    assert!(p.correlation.vertical.unwrap() > 0.999, "{p:?}");
    // The same vertical range in each body's lengths.
    assert!((p.character_range.vertical / p.human_range.vertical - 1.0).abs() < 0.01, "{p:?}");
    // The lift moves nothing forward or sideways: a character still on an axis the human moves along
    // scores 0 there.
    if let Some(c) = p.correlation.forward {
        assert_eq!(c, 0.0);
    }
    assert!(p.combined.unwrap() > 0.0 && p.combined.unwrap() < p.correlation.vertical.unwrap());
    // Amplitude: the character's vertical range against the human's whole extent.
    let h_extent = (p.human_range.forward.powi(2) + p.human_range.lateral.powi(2) + p.human_range.vertical.powi(2)).sqrt();
    assert!((p.amplitude_ratio.unwrap() - p.character_range.vertical / h_extent).abs() < 1e-3, "{p:?}");
    // Combined: the correlations scored, weighted by the human's range on their axes.
    let scored: Vec<(f32, f32)> = [
        (p.correlation.forward, p.human_range.forward),
        (p.correlation.lateral, p.human_range.lateral),
        (p.correlation.vertical, p.human_range.vertical),
    ]
    .into_iter()
    .filter_map(|(c, w)| c.map(|c| (c, w)))
    .collect();
    let weighted = scored.iter().map(|(c, w)| c * w).sum::<f32>() / scored.iter().map(|(_, w)| w).sum::<f32>();
    assert!((p.combined.unwrap() - weighted).abs() < 1e-6, "{p:?}: {weighted}");
    assert_eq!(r.score, p.combined);
}

/// A clip shorter than one window (1 s) is scored n/a: over two frames a correlation is ±1 ("following
/// 1.00" for a 2-frame clip), and one frame counted as a second of standing.
#[test]
fn a_clip_shorter_than_a_window_is_not_scored() {
    let mut f = fixture();
    // The 30 frames of the reach over which the hand moves most.
    let h = f.hand_height();
    let range = |w: &[f32]| w.iter().cloned().fold(f32::MIN, f32::max) - w.iter().cloned().fold(f32::MAX, f32::min);
    let start = (0..h.len() - 30).max_by(|&a, &b| range(&h[a..a + 30]).total_cmp(&range(&h[b..b + 30]))).unwrap();
    assert!(range(&h[start..start + 30]) > 0.1);
    let all = f.human.clone();
    for (frames, scored) in [(2, false), (29, false), (30, true)] {
        f.human = all[start..start + frames].to_vec();
        let lift = f.mirroring(1.0);
        let r = f.score(lift);
        let p = &r.pairs[0];
        assert_eq!(p.correlation.vertical.is_some(), scored, "{frames} frames: {p:?}");
        assert_eq!((p.amplitude_ratio.is_some(), r.score.is_some()), (scored, scored), "{frames} frames: {r:?}");
        f.human = vec![all[0].clone(); frames];
        let r = f.score(|_| 0.4);
        assert_eq!((r.standing_travel.is_some(), r.pairs[0].stillness.is_some()), (scored, scored), "{frames} frames: {r:?}");
    }
}

#[test]
fn a_gripper_moving_against_the_hand_scores_minus_one_and_a_parked_one_zero() {
    let f = fixture();
    let against = f.score(f.mirroring(-1.0));
    assert!(against.pairs[0].correlation.vertical.unwrap() < -0.999, "{:?}", against.pairs[0]);
    let parked = f.score(|_| 0.0);
    let p = &parked.pairs[0];
    assert_eq!(p.correlation.vertical, Some(0.0));
    assert_eq!(p.amplitude_ratio, Some(0.0));
    assert_eq!(p.character_range.vertical, 0.0);
}

#[test]
fn a_gripper_moving_while_the_hand_is_still_is_caught_by_stillness() {
    let mut f = fixture();
    // The human holds the clip's first pose for 4 s.
    f.human = vec![f.human[0].clone(); 120];
    let amplitude = 0.1; // m, up and down once a second
    let r = f.score(|t| 0.4 + amplitude * (std::f32::consts::TAU * t as f32 / FPS).sin());
    let p = &r.pairs[0];
    assert_eq!(p.correlation.vertical, None, "nothing to follow");
    assert_eq!(p.amplitude_ratio, None);
    assert_eq!((p.combined, r.score), (None, None), "no axis to score");
    let expected = 2.0 * amplitude / f.character_body;
    assert!((p.stillness.unwrap() - expected).abs() < 0.02 * expected, "{p:?} against {expected}");
    let still = f.score(|_| 0.4);
    assert_eq!(still.pairs[0].stillness, Some(0.0));
}

/// Still is within 5 cm in metres: a hand trembling 4 cm up and down is still, one moving 6 cm is not
/// (and at 0.035 body lengths it is motion to follow, where 2 cm is not).
#[test]
fn a_hand_is_still_within_five_centimetres() {
    let mut f = fixture();
    f.standing_human(0.0);
    let standing = f.human.clone();
    let z = hl::ee_position(EndEffector::RightHand).start + 2;
    let trembling = |f: &mut Fixture, amplitude: f32| {
        f.human = standing
            .iter()
            .enumerate()
            .map(|(t, x)| {
                let mut x = x.clone();
                x[z] += 0.5 * amplitude * (std::f32::consts::TAU * t as f32 / FPS).sin();
                x
            })
            .collect();
        f.score(|_| 0.4).pairs.remove(0)
    };
    let p = trembling(&mut f, 0.04);
    assert_eq!(p.stillness, Some(0.0), "{p:?}");
    let p = trembling(&mut f, 0.06);
    assert_eq!(p.stillness, None, "{p:?}");
    assert_eq!(p.correlation.vertical, Some(0.0), "{p:?}");
    let p = trembling(&mut f, 0.02);
    assert_eq!(p.correlation.vertical, None, "{p:?}");
}

/// Stillness is the character's extent within each window of the human's stillness: a gripper rising
/// steadily covers 29 frames' travel in a window of 1 s at 30 fps, and 59 in one of 2 s.
#[test]
fn stillness_is_measured_over_windows_of_the_configured_length() {
    let mut f = fixture();
    f.standing_human(0.0);
    let v = 0.1; // m/s
    for (seconds, frames) in [(1.0, 30.0), (2.0, 60.0)] {
        f.config.window_s = seconds;
        let p = f.score(|t| 0.2 + v * t as f32 / FPS).pairs.remove(0);
        let expected = v * (frames - 1.0) / FPS / f.character_body;
        assert!((p.stillness.unwrap() - expected).abs() < 1e-3 * expected, "{seconds} s: {p:?} against {expected}");
    }
}

/// On a character with several end effectors (Spot: four feet and a gripper), each pair is scored from
/// its own end effector's entries, and the clip's score is the mean of the pairs' combined scores.
#[test]
fn each_pair_is_scored_from_its_own_end_effector_and_the_score_is_their_mean() {
    use EndEffector::*;
    let f = fixture_for("spot", vec![LeftFoot, RightFoot, RightFoot, LeftFoot, RightHand]);
    let names: Vec<&str> = f.pairs.iter().map(|p| p.0.as_str()).collect();
    assert_eq!(names, ["fl_foot", "fr_foot", "rl_foot", "rr_foot", "gripper_tip"]);
    // The shoulder's pitch lifts the gripper as the hand rises; the body and legs stay still.
    let (sh1, h) = (f.tree.dof_index("arm_sh1").unwrap(), f.hand_height());
    let poses: Vec<CharacterPose> = (0..h.len())
        .map(|t| {
            let mut p = f.tree.neutral_pose(Isometry3::identity());
            p.q[sh1] = -(h[t] - h[0]);
            p
        })
        .collect();
    let r = f.score_poses(&poses, 1.0);
    assert_eq!(r.pairs.len(), 5);
    for p in &r.pairs[..4] {
        assert_eq!(p.character_range, Default::default(), "{p:?}");
    }
    let gripper = &r.pairs[4];
    assert!(gripper.correlation.vertical.unwrap() > 0.9, "{gripper:?}");
    let combined: Vec<f32> = r.pairs.iter().filter_map(|p| p.combined).collect();
    assert!(combined.len() >= 2, "the person's feet move too: {r:?}");
    let mean = combined.iter().sum::<f32>() / combined.len() as f32;
    assert!((r.score.unwrap() - mean).abs() < 1e-6, "{r:?}");
}

/// The printed summary: one clip's axes per pair, or over many clips the medians with the clips they
/// are taken over.
#[test]
fn the_summary_prints_one_clips_axes_or_many_clips_medians() {
    let f = fixture();
    let with = f.score(f.mirroring(1.0));
    let one = FollowingSummary::new(vec![(with.clone(), f.human_body)]);
    let text = one.to_string();
    assert!(text.starts_with(&format!("following {:.2} ", with.score.unwrap())), "{text}");
    let p = &with.pairs[0];
    let line = format!("grasp_center ~ {}: vertical 1.00, forward {}", EndEffector::RightHand.name(), p.correlation.forward.map_or("n/a".into(), |c| format!("{c:.2}")));
    assert!(text.contains(&line), "{text}\nlacks {line}");
    assert!(!text.contains("clips"), "{text}");
    let many = FollowingSummary::new(vec![(with, f.human_body); 3]);
    let text = many.to_string();
    assert!(text.contains(&"vertical 1.00 (3 clips moving ≥ 0.3 m)"), "{text}");
    assert!(text.contains("(median over the clips)"), "{text}");
    assert!(text.contains(&format!("°/s ({} clips)", many.standing_clips)), "{text}");
    assert!(text.contains(&format!("speed scale ({} clips)", many.walking_clips)), "{text}");
}

#[test]
fn a_summary_takes_medians_over_the_clips_where_the_hand_moves() {
    let f = fixture();
    let (with, against, parked) = (f.score(f.mirroring(1.0)), f.score(f.mirroring(-1.0)), f.score(|_| 0.0));
    let s = FollowingSummary::new(vec![(with.clone(), f.human_body), (against, f.human_body), (parked, f.human_body)]);
    let p = &s.pairs[0];
    assert_eq!(p.moving_clips, 3);
    // Median of (≈1, ≈−1, 0).
    assert_eq!(p.vertical_correlation, Some(0.0));
    assert_eq!(p.amplitude_ratio, with.pairs[0].amplitude_ratio);
    // A clip whose hand moves less than 0.3 m (here: a human 10 times smaller) does not count.
    let tiny = FollowingSummary::new(vec![(with, f.human_body / 10.0)]);
    assert_eq!(tiny.pairs[0].moving_clips, 0);
    assert_eq!(tiny.pairs[0].vertical_correlation, None);
}

/// A character that drives off or turns while the human stands (its root within 5 cm and 10° for
/// 1 s) is caught by the standing measure, in its body lengths and degrees per second; one that
/// stands scores 0, and a walking human gives no standing windows.
#[test]
fn a_character_that_drives_off_while_the_human_stands_is_caught_by_standing() {
    let mut f = fixture();
    f.standing_human(0.0);
    let n = f.human.len();
    let at = |x: f32, yaw_deg: f32| {
        let yaw = UnitQuaternion::from_axis_angle(&Vector3::z_axis(), yaw_deg.to_radians());
        f.tree.neutral_pose(Isometry3::from_parts(Translation3::new(x, 0.0, 0.0), yaw))
    };
    let (v, w) = (0.3, 30.0); // m/s, °/s
    let driving: Vec<CharacterPose> = (0..n).map(|t| at(v * t as f32 / FPS, 0.0)).collect();
    let turning: Vec<CharacterPose> = (0..n).map(|t| at(0.0, w * t as f32 / FPS)).collect();
    let still: Vec<CharacterPose> = (0..n).map(|_| at(0.0, 0.0)).collect();
    let r = f.score_poses(&driving, 1.0);
    let expected = v / f.character_body;
    // The first window counts the first frame, which has no motion before it, as still.
    assert!((r.standing_travel.unwrap() - expected).abs() < 0.04 * expected, "{r:?} against {expected}");
    assert!(r.standing_turn.unwrap() < 1e-3, "{r:?}");
    let r = f.score_poses(&turning, 1.0);
    assert!((r.standing_turn.unwrap() - w).abs() < 0.04 * w, "{r:?}");
    assert!(r.standing_travel.unwrap() < 1e-3, "{r:?}");
    let r = f.score_poses(&still, 1.0);
    assert_eq!((r.standing_travel, r.standing_turn), (Some(0.0), Some(0.0)));
    // Per second, whatever the windows' length.
    f.config.window_s = 2.0;
    let r = f.score_poses(&driving, 1.0);
    assert!((r.standing_travel.unwrap() - expected).abs() < 0.04 * expected, "2 s windows: {r:?} against {expected}");
    let r = f.score_poses(&turning, 1.0);
    assert!((r.standing_turn.unwrap() - w).abs() < 0.04 * w, "2 s windows: {r:?}");
    f.config.window_s = 1.0;
    // A human walking at 1 m/s never stands.
    f.standing_human(1.0);
    let r = f.score_poses(&driving, 1.0);
    assert_eq!((r.standing_travel, r.standing_turn), (None, None));
    // 4 cm in a second is standing at any speed scale L_fea brings it to, once the scale is known.
    f.standing_human(0.04);
    assert!(f.score_poses(&driving, 1.0).standing_travel.is_some());
    assert!(f.score_poses(&driving, 2.0).standing_travel.is_some());
    assert_eq!(f.score_scaled(&driving, 2.0, 1.0).standing_travel, None, "8 cm in a second is not standing");
    // Summaries take the median over the clips where the human stands.
    f.standing_human(0.0);
    let clips = [&driving, &turning, &still].map(|p| (f.score_poses(p, 1.0), f.human_body));
    let s = FollowingSummary::new(clips.to_vec());
    assert_eq!(s.standing_clips, 3);
    assert!(s.standing_travel.unwrap() < 1e-3 && s.standing_turn.unwrap() < 1e-3, "{s:?}");
    f.standing_human(1.0);
    let walking = (f.score_poses(&driving, 1.0), f.human_body);
    let s = FollowingSummary::new(vec![walking, clips[0].clone()]);
    assert_eq!(s.standing_clips, 1);
    assert_eq!(s.standing_travel, clips[0].0.standing_travel);
}

/// Heading: on the bundled walk, where the person turns 20° to the left after 2 s, Stretch driven to
/// face where the person faces scores a heading error of a few degrees; standing on its first heading
/// it misses the person's turn (about 20°), and turning right at 20°/s it ends up about 120° off.
#[test]
fn a_character_that_turns_away_from_the_humans_path_is_caught_by_heading() {
    let mut f = fixture();
    let clip = f.on_the_walk();
    // The person's facing, from the clip's frames (not from Ψ), unwrapped from the first frame's.
    let yaw0 = ace_models::frame::heading_yaw(&clip.frames[0].forward());
    let facing: Vec<f32> = clip
        .frames
        .iter()
        .map(|fr| {
            let d = ace_models::frame::heading_yaw(&fr.forward()) - yaw0;
            d.sin().atan2(d.cos())
        })
        .collect();
    let turned = facing.last().unwrap().to_degrees();
    assert!((15.0..25.0).contains(&turned), "the walk turns about 20° left: {turned}");
    let turning = |yaw: &dyn Fn(usize) -> f32| -> FollowingReport {
        let poses: Vec<CharacterPose> = (0..f.human.len())
            .map(|t| f.tree.neutral_pose(Isometry3::from_parts(Translation3::identity(), UnitQuaternion::from_axis_angle(&Vector3::z_axis(), yaw(t)))))
            .collect();
        f.score_poses(&poses, 1.0)
    };
    let following = turning(&|t| facing[t]).heading_error.unwrap();
    let standing = turning(&|_| 0.0).heading_error.unwrap();
    let seconds = (f.human.len() - 1) as f32 / FPS;
    let away = turning(&|t| -(20.0f32).to_radians() * t as f32 / FPS).heading_error.unwrap();
    // The pelvis turns to and fro with each step; its yaw rate, not the facing, is what Ψ holds.
    assert!(following < 6.0, "facing where the person faces: {following}°");
    assert!((standing - turned).abs() < 6.0, "standing still: {standing}° against the person's {turned}°");
    assert!((away - (turned + 20.0 * seconds)).abs() < 6.0, "turning right: {away}°");
    // Turning 45° away from the person's facing in the middle of the clip and back is 45° off.
    let n = f.human.len() as f32;
    let detour = turning(&|t| facing[t] + 45f32.to_radians() * (std::f32::consts::PI * t as f32 / (n - 1.0)).sin()).heading_error.unwrap();
    assert!((detour - 45.0).abs() < 6.0, "a detour: {detour}°");
    // A clip of one frame has no heading change; summaries take the median over the clips.
    let s = FollowingSummary::new(vec![
        (turning(&|t| facing[t]), f.human_body),
        (turning(&|_| 0.0), f.human_body),
        (turning(&|t| -(20.0f32).to_radians() * t as f32 / FPS), f.human_body),
    ]);
    assert_eq!(s.heading_error, Some(standing));
    f.human.truncate(1);
    let one = f.score_poses(&[f.tree.neutral_pose(Isometry3::identity())], 1.0);
    assert_eq!(one.heading_error, None);
}

/// Pace: on the bundled walk (the person walks at about 1.2 m/s), Stretch driven straight ahead at the
/// person's speed times L_fea's speed scale keeps the person's pace (about 1), at half that speed 0.5,
/// and standing 0; where the person stands there is no pace to keep.
#[test]
fn a_character_that_falls_behind_a_walking_human_is_caught_by_pace() {
    let mut f = fixture();
    f.on_the_walk();
    // The person's mean horizontal pelvis speed once walking (after the first second).
    let speeds: Vec<f32> = f.human[30..].iter().map(|x| x[hl::ROOT_LINEAR_VELOCITY][0].hypot(x[hl::ROOT_LINEAR_VELOCITY][1])).collect();
    let person = speeds.iter().sum::<f32>() / speeds.len() as f32;
    assert!((1.0..1.4).contains(&person), "the bundled walk is about 1.2 m/s: {person}");
    let scale = 0.5; // the character dataset's human-equivalent speed scale
    let factor = ace_models::features::human_speed_factor(scale, f.human_body, f.character_body);
    let (n, tree) = (f.human.len(), f.tree.clone());
    let driving = |v: f32| -> Vec<CharacterPose> {
        (0..n).map(|t| tree.neutral_pose(Isometry3::translation(v * t as f32 / FPS, 0.0, 0.0))).collect()
    };
    let pace = |v: f32| f.score_poses(&driving(v), factor).pace.unwrap();
    let keeping = pace(scale * person);
    // The pelvis sways a little beside its path, so the person's travel is a little longer than a
    // straight line's.
    assert!((0.9..=1.02).contains(&keeping), "at the person's scaled speed: {keeping}");
    let half = pace(0.5 * scale * person);
    assert!((half - 0.5 * keeping).abs() < 0.02, "at half of it: {half} against {keeping}");
    assert_eq!(pace(0.0), 0.0);
    // The speed scale counts: told the human's velocity was not scaled, the same motion reads slower.
    let unscaled = f.score_scaled(&driving(scale * person), 1.0, 1.0).pace.unwrap();
    assert!((unscaled - keeping * factor).abs() < 0.02 * keeping, "{unscaled} against {keeping} · {factor}");
    // Summaries take the median over the clips where the human walks.
    let clips: Vec<(FollowingReport, f32)> =
        [1.0, 0.5, 0.0].iter().map(|k| (f.score_poses(&driving(k * scale * person), factor), f.human_body)).collect();
    f.standing_human(0.0);
    let standing = f.score_poses(&driving(0.3)[..f.human.len()], factor);
    assert_eq!(standing.pace, None, "a standing person sets no pace");
    // Nor does one shuffling at 0.1 m/s (not standing, not walking), over windows of any length.
    f.standing_human(0.1);
    assert_eq!(f.score_poses(&driving(0.3)[..f.human.len()], factor).pace, None);
    f.config.window_s = 2.0;
    assert_eq!(f.score_poses(&driving(0.3)[..f.human.len()], factor).pace, None, "2 s windows");
    let s = FollowingSummary::new([clips, vec![(standing, f.human_body)]].concat());
    assert_eq!(s.walking_clips, 3);
    assert_eq!(s.pace, Some(half));
}
