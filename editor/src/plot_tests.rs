//! The data behind the editor's plots: the timeline's following series of the bundled walk clip on
//! Spot, and the losses of a real (brief) retraining as the loss plot takes them.

use std::sync::OnceLock;
use std::time::{Duration, Instant};

use ace::fine_tune::FineTune;
use ace::models::features::human_body_length;
use ace::models::human::{EndEffector, Joint};
use ace::models::morphology::load_character;
use bevy::ecs::system::RunSystemOnce;
use bevy::prelude::*;

use crate::plots::loss_series;
use crate::preview::{self, Preview, PreviewInputs, PreviewResult};
use crate::retrain::{self, Retrain};
use crate::series::ground_speeds;
use crate::tests::{repo, scratch, walk};
use crate::Session;

/// Spot's walk preview, computed once (as the editor does, on the shipped checkpoint).
fn spot_walk() -> &'static PreviewResult {
    static RESULT: OnceLock<PreviewResult> = OnceLock::new();
    RESULT.get_or_init(|| {
        let checkpoint = repo().join("assets/checkpoints/spot");
        preview::compute(&PreviewInputs { character: repo().join("assets/characters/spot.urdf"), checkpoint, clip: walk(), limit_velocity: false })
            .unwrap()
    })
}

fn ace_json(checkpoint: &str) -> serde_json::Value {
    let text = std::fs::read_to_string(repo().join("assets/checkpoints").join(checkpoint).join("ace.json")).unwrap();
    serde_json::from_str(&text).unwrap()
}

fn assert_close(got: &[f32], want: &[f32], tolerance: f32, what: &str) {
    assert_eq!(got.len(), want.len(), "{what}: lengths");
    for (t, (g, w)) in got.iter().zip(want).enumerate() {
        assert!((g - w).abs() <= tolerance, "{what}, frame {t}: {g} against {w}");
    }
}

/// The timeline plots one point per frame of the clip; the pairs are the checkpoint's mapping, in its
/// order; the human's speed and heights are those of the clip's pelvis and end-effector joints, the
/// character's those of the poses shown, each in its own body lengths, the human's speed brought to
/// Spot's speed scale as L_fea asks it of Spot.
#[test]
fn the_following_plots_of_the_walk_on_spot_are_the_clip_and_the_poses() {
    let result = spot_walk();
    let series = &result.series;
    let frames = result.clip.frames.len();
    assert!(frames > 100, "{frames} frames");
    assert_eq!(result.retargeted.motion.poses.len(), frames);
    assert_eq!(series.character_speed.len(), frames);
    assert_eq!(series.human_speed.len(), frames);

    // The pairs: the checkpoint's mapping as ace.json records it.
    let json = ace_json("spot");
    let links: Vec<String> = serde_json::from_value(json["correspondence"]["character_links"].clone()).unwrap();
    let mapping: Vec<Option<EndEffector>> = serde_json::from_value(json["correspondence"]["mapping"]["human"].clone()).unwrap();
    let want: Vec<(String, EndEffector)> =
        links.iter().zip(&mapping).filter_map(|(l, h)| h.map(|h| (l.clone(), h))).collect();
    let got: Vec<(String, EndEffector)> = series.pairs.iter().map(|p| (p.character.clone(), p.human)).collect();
    assert_eq!(got, want);
    assert_eq!(got.len(), 5, "Spot's four feet and its gripper");
    for p in &series.pairs {
        assert_eq!((p.character_height.len(), p.human_height.len()), (frames, frames), "{}", p.character);
    }

    // The human, from the clip's joints (m) over its body length.
    let body = human_body_length(&result.clip);
    assert!(json["body_lengths"]["human_override"].is_null(), "Spot measures each clip's human");
    let pelvis: Vec<[f32; 2]> = result
        .clip
        .frames
        .iter()
        .map(|f| {
            let p = f.positions[Joint::Pelvis.index()];
            [p.x, p.y]
        })
        .collect();
    let speed: Vec<f32> = ground_speeds(&pelvis, result.clip.fps).iter().map(|v| v / body).collect();
    // A walk: the human is on the move most of the time (so the comparisons here can fail).
    let mean = speed.iter().sum::<f32>() / frames as f32;
    assert!(mean > 0.3, "the human walks {mean} body lengths/s on average");
    // Asked of Spot: the pelvis's speed times Spot's speed scale (ace.json), in Spot's body lengths.
    let character_body = json["body_lengths"]["character"].as_f64().unwrap() as f32;
    let scale = json["speed_scale"].as_f64().unwrap() as f32;
    let asked: Vec<f32> = speed.iter().map(|v| v * body * scale / character_body).collect();
    assert_close(&series.human_speed, &asked, 1e-4, "the speed asked of Spot");
    for p in &series.pairs {
        let heights: Vec<f32> = result.clip.frames.iter().map(|f| f.positions[p.human.joint().index()].z / body).collect();
        assert_close(&p.human_height, &heights, 1e-5, &format!("human {} height", p.human.name()));
    }

    // The character, from the poses' root and the feet's forward kinematics, in Spot's body lengths.
    let roots: Vec<[f32; 2]> = result.retargeted.motion.poses.iter().map(|p| [p.root.translation.vector.x, p.root.translation.vector.y]).collect();
    let speed: Vec<f32> = ground_speeds(&roots, 30.0).iter().map(|v| v / character_body).collect();
    assert_close(&series.character_speed, &speed, 1e-4, "character speed");
    assert!(series.character_speed != series.human_speed);
    // Where the person walks, the two speeds' ratio is the pace the metrics report (a median of
    // 1-second windows there; here the whole walk after its first second).
    let pace = result.retargeted.report.following.as_ref().and_then(|f| f.pace).unwrap();
    let ratio = series.character_speed[30..].iter().sum::<f32>() / series.human_speed[30..].iter().sum::<f32>();
    assert!((ratio - pace).abs() < 0.1, "the plotted speeds' ratio {ratio} against the pace {pace}");
    // Headings: the human's turn is the clip's (20° to the left after 2 s), measured here from the
    // pelvis's facing in the clip's frames; the character's is its root's, and the largest gap
    // between the two is the heading error the metrics report.
    assert_eq!((series.character_heading.len(), series.human_heading.len()), (frames, frames));
    let facing = |f: &ace::models::human::HumanFrame| ace::models::frame::heading_yaw(&f.forward());
    let first = facing(&result.clip.frames[0]);
    let turned: Vec<f32> = result.clip.frames.iter().map(|f| (facing(f) - first).to_degrees()).collect();
    assert_close(&series.human_heading, &turned, 1.0, "human heading");
    assert!((turned[frames - 1] - 20.0).abs() < 2.0, "the walk turns 20° left: {}", turned[frames - 1]);
    let gap = series.character_heading.iter().zip(&series.human_heading).map(|(c, h)| (c - h).abs()).fold(0.0f32, f32::max);
    let reported = result.retargeted.report.following.as_ref().and_then(|f| f.heading_error).unwrap();
    assert!((gap - reported).abs() < 2.0, "the plot's largest gap {gap}° against the reported heading error {reported}°");
    let root_yaw = |p: &ace::models::kinematics::CharacterPose| {
        let m = p.root.rotation.to_rotation_matrix();
        m[(1, 0)].atan2(m[(0, 0)])
    };
    let yaw0 = root_yaw(&result.retargeted.motion.poses[0]);
    let wrapped: Vec<f32> = result.retargeted.motion.poses.iter().map(|p| (root_yaw(p) - yaw0).to_degrees()).collect();
    let unwrapped: Vec<f32> = series.character_heading.iter().map(|d| (d + 180.0).rem_euclid(360.0) - 180.0).collect();
    let wrapped: Vec<f32> = wrapped.iter().map(|d| (d + 180.0).rem_euclid(360.0) - 180.0).collect();
    assert_close(&unwrapped, &wrapped, 0.01, "character heading");
    // Heights above the ground, not below the root: Spot's feet touch the ground while it walks.
    let (tree, morph) = load_character(&result.inputs.character).unwrap();
    for (k, p) in series.pairs.iter().enumerate() {
        let link = morph.end_effectors()[k];
        assert_eq!(tree.links[link].name, p.character);
        if k < 4 {
            let lowest = p.character_height.iter().copied().fold(f32::INFINITY, f32::min) * character_body;
            assert!(lowest.abs() < 0.03, "{} comes down to {lowest} m", p.character);
        }
    }
}

/// The loss plot shows every loss a real retraining reports, step by step, with the values the training
/// logged in the new checkpoint's `ace_losses.csv`. (A brief fine-tune of the shipped crab, whose
/// dataset regenerates, on the shared human clips it was trained on.)
#[test]
fn the_loss_plot_carries_the_retrains_logged_losses() {
    let humans = repo().join("../shared/data/human");
    if !humans.is_dir() {
        if std::env::var("ACE_ALLOW_MISSING_DATA").is_ok_and(|v| v == "1") {
            eprintln!("skipping: shared human data not found at {}", humans.display());
            return;
        }
        panic!("shared human data not found at {} (set ACE_ALLOW_MISSING_DATA=1 to skip tests that need it)", humans.display());
    }
    let dir = scratch("retrain");
    let to = dir.join("crab");
    let steps = 3;
    let mut retrain = Retrain::default();
    retrain.run(
        FineTune {
            urdf: repo().join("assets/characters/crab.urdf"),
            from: repo().join("assets/checkpoints/crab"),
            to: to.clone(),
            steps,
            w_adv: 1.0,
            w_fea: 20.0,
            feature_weights: Default::default(),
            end_effector_mapping: None,
            humans: None,
        },
        None,
    );
    let mut world = World::new();
    world.insert_resource(retrain);
    world.init_resource::<Preview>();
    world.insert_resource(Session {
        character: repo().join("assets/characters/crab.urdf"),
        scene_placement: None,
        checkpoint: Some(repo().join("assets/checkpoints/crab")),
        clip: walk(),
        limit_velocity: false,
    });
    let start = Instant::now();
    while world.resource::<Retrain>().running() {
        assert!(start.elapsed() < Duration::from_secs(900), "the retraining did not end in 15 minutes");
        world.run_system_once(retrain::poll).unwrap();
        std::thread::sleep(Duration::from_millis(50));
    }
    let retrain = world.resource::<Retrain>();
    assert_eq!(retrain.error, None);
    assert_eq!(world.resource::<Session>().checkpoint.as_ref(), Some(&to), "the session moves to the new checkpoint");
    assert_eq!(retrain.history.len(), steps);

    // The log: `step,d_loss,d_bce,gp,g_loss,adv,fea,…`, the original run's rows first (steps from 0).
    let text = std::fs::read_to_string(to.join("ace_losses.csv")).unwrap();
    let mut lines = text.lines();
    let header: Vec<&str> = lines.next().unwrap().split(',').collect();
    let rows: Vec<Vec<f64>> = lines.map(|l| l.split(',').map(|v| v.parse().unwrap()).collect()).collect();
    let column = |name: &str| header.iter().position(|h| *h == name).unwrap();
    let logged = &rows[rows.len() - steps..];
    let series = loss_series(&retrain.history);
    let names: Vec<&str> = series.iter().map(|s| s.0).collect();
    assert_eq!(names, ["L_fea", "L_adv", "G: w_adv·L_adv + w_fea·L_fea", "D"]);
    for ((name, points), csv) in series.iter().zip(["fea", "adv", "g_loss", "d_loss"]) {
        let want: Vec<[f64; 2]> = logged.iter().map(|r| [r[column("step")] + 1.0, r[column(csv)]]).collect();
        assert_eq!(points, &want, "{name} against the log's {csv}");
    }
    // Four different series (so that a mix-up cannot pass).
    for (i, a) in series.iter().enumerate() {
        for b in &series[i + 1..] {
            assert!(a.1 != b.1, "{} and {} are the same", a.0, b.0);
        }
    }
}

/// The timeline marks every frame a UFR detector flags in the strip's upper half, and every frame of a
/// popping swing in its lower half. The preview's own flags are swapped for those of the shipped Spot's
/// raw networks on the same clip (no cleanup), whose feet pop and slide; the cleaned preview has none.
/// The Metrics panel shows the preview's steps.
#[test]
fn the_timeline_marks_ufr_frames_and_popping_swings() {
    use ace::models::cleanup::Cleanup;
    use ace::models::human::{HumanClip, ImportOptions};
    use ace::models::human_set::PROJECT_FPS;
    use ace::retarget::{Backend, Networks, retarget_and_score};
    use ace::scoring::Scorer;
    use bevy_egui::egui;

    use crate::ui::{POP_MARK, STRIP, UFR_MARK, UiState, metrics_and_export, timeline};

    let checkpoint = repo().join("assets/checkpoints/spot");
    let character = repo().join("assets/characters/spot.urdf");
    let mut preview = Preview::default();
    let mut result = preview::compute(&PreviewInputs { character: character.clone(), checkpoint: checkpoint.clone(), clip: walk(), limit_velocity: false }).unwrap();
    let (tree, morph) = load_character(&character).unwrap();
    let mut networks = Networks::load(&checkpoint, Backend::Rust).unwrap();
    networks.set_cleanup(Cleanup::NONE);
    let scorer = Scorer::new(networks.record(), networks.character(), &checkpoint).unwrap();
    let clip = HumanClip::from_bvh_file(&walk(), &ImportOptions { fps: Some(PROJECT_FPS), mapping: None }).unwrap();
    let raw = retarget_and_score(&networks, &scorer, &tree, &morph, &clip).unwrap().flags;
    let count = |f: &[bool]| f.iter().filter(|&&f| f).count();
    assert_eq!(count(&result.retargeted.flags.pops), 0, "the cleaned walk pops");
    let (ufr, pops) = (count(&raw.ufr), count(&raw.pops));
    assert!(ufr > 0 && pops > 0 && ufr != pops, "raw: {ufr} UFR frames, {pops} popping");
    result.retargeted.flags = raw;
    preview.result = Some(result);

    let mut player = bevy_ace::prelude::HumanClipPlayer::new(Handle::default());
    let ctx = egui::Context::default();
    let mut out = ctx.run_ui(Default::default(), |ui| timeline(ui, &mut player, &preview));
    out.textures_delta.clear();
    // (colour, whether in the lower half) of each mark; the strip is the background rectangle's.
    let strip = out
        .shapes
        .iter()
        .find_map(|s| match &s.shape {
            egui::Shape::Rect(r) if r.fill == STRIP => Some(r.rect),
            _ => None,
        })
        .expect("the timeline's strip");
    let marks: Vec<(egui::Color32, bool)> = out
        .shapes
        .iter()
        .filter_map(|s| match &s.shape {
            egui::Shape::LineSegment { points, stroke } if [UFR_MARK, POP_MARK].contains(&stroke.color) => {
                Some((stroke.color, points[0].y.min(points[1].y) >= strip.center().y - 1e-3))
            }
            _ => None,
        })
        .collect();
    assert_eq!(marks.iter().filter(|m| **m == (UFR_MARK, false)).count(), ufr);
    assert_eq!(marks.iter().filter(|m| **m == (POP_MARK, true)).count(), pops);
    assert_eq!(marks.len(), ufr + pops);

    // The Metrics panel's steps are the cleaned walk's gait.
    let gait = preview.result.as_ref().unwrap().retargeted.report.gait.clone().unwrap();
    let mut out = ctx.run_ui(Default::default(), |ui| metrics_and_export(ui, &preview, &mut UiState::default()));
    out.textures_delta.clear();
    let texts: Vec<String> = out
        .shapes
        .iter()
        .filter_map(|s| match &s.shape {
            egui::Shape::Text(t) => Some(t.galley.text().to_owned()),
            _ => None,
        })
        .collect();
    let want = format!("{} swings, median {:.0} frames", gait.swings, gait.median_swing_frames);
    assert!(gait.swings > 10 && texts.contains(&want), "{want} not among {texts:?}");
    let ratio = format!("{:.2}×", gait.median_ratio.unwrap());
    assert!(texts.contains(&ratio), "{ratio} not among {texts:?}");
}
