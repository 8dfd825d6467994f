//! The editor's creature path, headless: opening the bundled hound (and broken files), its preview
//! posing the hound's own glTF scene through the plugin where the character stands, and its export
//! as a rig clip.

use std::path::{Path, PathBuf};
use std::sync::OnceLock;
use std::time::Duration;

use ace::models::character::gltf::open as open_gltf;
use ace::models::character::is_gltf;
use bevy::asset::UnapprovedPathMode;
use bevy::prelude::*;
use bevy::world_serialization::WorldSerializationPlugin;
use bevy_ace::convert;
use bevy_ace::prelude::*;

use crate::open::{describe, open_character};
use crate::preview::{self, PreviewInputs, PreviewResult};
use crate::{Session, apply_session};

#[path = "../../models/tests/common/mod.rs"]
mod common;

pub(crate) fn repo() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).parent().unwrap().to_path_buf()
}

pub(crate) fn walk() -> PathBuf {
    repo().join("assets/motions/walk.bvh")
}

/// The hound's shipped checkpoint, from its `ace.json`: the DoF names it was trained for.
fn hound_checkpoint_dofs() -> Vec<String> {
    let text = std::fs::read_to_string(repo().join("assets/checkpoints/hound/ace.json")).unwrap();
    let json: serde_json::Value = serde_json::from_str(&text).unwrap();
    json["character"]["dof_names"].as_array().unwrap().iter().map(|v| v.as_str().unwrap().to_owned()).collect()
}

/// The hound's walk preview, computed once (as the editor does, on the shipped checkpoint).
fn hound_walk() -> &'static PreviewResult {
    static RESULT: OnceLock<PreviewResult> = OnceLock::new();
    RESULT.get_or_init(|| {
        let opened = open_character("hound").unwrap();
        preview::compute(&PreviewInputs { character: opened.path, checkpoint: opened.checkpoint.unwrap(), clip: walk(), limit_velocity: false }).unwrap()
    })
}

pub(crate) fn scratch(name: &str) -> PathBuf {
    let dir = repo().join("target/editor-tests").join(name);
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

/// `hound` (a bundled name, as `ace --character` takes it) opens the bundled creature with its shipped
/// checkpoint, its scene turned to face +x as the robots do; `spot` stays a URDF robot.
#[test]
fn the_bundled_hound_opens_with_its_checkpoint() {
    let hound = open_character(" hound ").unwrap();
    assert_eq!(hound.path, repo().join("assets/creatures/hound.glb"));
    assert_eq!(hound.checkpoint, Some(repo().join("assets/checkpoints/hound")));
    // The hound is authored +z forward, y up, in metres (scripts/make_creature.py): a quarter turn about y.
    let placement = hound.scene_placement.expect("a creature's scene is placed");
    let want = Quat::from_rotation_y(std::f32::consts::FRAC_PI_2);
    assert!(placement.rotation.abs_diff_eq(want, 1e-6), "{:?}", placement.rotation);
    assert!((placement.scale - Vec3::ONE).length() < 1e-6 && placement.translation == Vec3::ZERO);
    // The same file by its path.
    assert_eq!(open_character(hound.path.to_str().unwrap()).unwrap(), hound);

    let spot = open_character("spot").unwrap();
    assert_eq!(spot.path, repo().join("assets/characters/spot.urdf"));
    assert_eq!(spot.checkpoint, Some(repo().join("assets/checkpoints/spot")));
    assert_eq!(spot.scene_placement, None);
}

/// Files that are not characters are errors naming the file and the problem, never panics.
#[test]
fn broken_character_files_are_errors_naming_the_file() {
    let dir = scratch("broken");
    let hound = std::fs::read(repo().join("assets/creatures/hound.glb")).unwrap();
    let truncated = dir.join("truncated.glb");
    std::fs::write(&truncated, &hound[..hound.len() / 3]).unwrap();
    let text = dir.join("text.glb");
    std::fs::write(&text, "a glb this is not\n").unwrap();
    let skinless = dir.join("skinless.gltf");
    std::fs::write(&skinless, r#"{"asset":{"version":"2.0"},"scenes":[{"nodes":[0]}],"nodes":[{"name":"Box"}]}"#).unwrap();
    let other = dir.join("notes.txt");
    std::fs::write(&other, "hello\n").unwrap();
    let missing = dir.join("missing.glb");
    for (file, problem) in [
        (&truncated, "glb"),
        (&text, "glb"),
        (&skinless, "skin"),
        (&other, "not a character file"),
        (&missing, "no character"),
    ] {
        let e = open_character(file.to_str().unwrap()).expect_err(&file.display().to_string());
        let message = format!("{e:#}");
        eprintln!("{message}");
        let name = file.file_name().unwrap().to_str().unwrap();
        assert!(message.contains(name), "{message} does not name {name}");
        assert!(message.to_lowercase().contains(problem), "{message} does not say `{problem}`");
    }
    let e = open_character("   ").unwrap_err();
    assert!(format!("{e:#}").contains("no character given"));
}

fn headless_app() -> App {
    let mut app = App::new();
    app.add_plugins((
        MinimalPlugins,
        AssetPlugin {
            file_path: repo().display().to_string(),
            unapproved_path_mode: UnapprovedPathMode::Allow,
            ..default()
        },
        TransformPlugin,
        WorldSerializationPlugin,
        bevy::mesh::MeshPlugin,
        bevy::image::ImagePlugin::default(),
        bevy::animation::AnimationPlugin,
        bevy::gltf::GltfPlugin::default(),
        AcePlugin,
    ))
    .init_resource::<preview::Preview>()
    .add_systems(Update, (apply_session, preview::poll))
    .add_systems(PostUpdate, preview::show.in_set(AceSystems::Retarget));
    // Bevy's glTF loader is registered when the plugins finish (`App::run` does this).
    app.finish();
    app.cleanup();
    app
}

/// "Hold joints to their velocity limits": the session's setting reaches the preview, whose Stretch
/// then moves no joint but the wheels faster than its limit on the bundled `wave` (the shipped
/// networks move the lift past its 0.3 m/s), and the Metrics panel's measure says so.
#[test]
fn the_velocity_limit_setting_holds_the_previews_joints() {
    let opened = open_character("stretch").unwrap();
    let wave = repo().join("assets/motions/wave.bvh");
    let mut app = headless_app();
    app.insert_resource(Session {
        character: opened.path.clone(),
        scene_placement: None,
        checkpoint: opened.checkpoint.clone(),
        clip: wave.clone(),
        limit_velocity: true,
    });
    for _ in 0..3000 {
        app.update();
        if app.world().resource::<preview::Preview>().result.is_some() {
            break;
        }
        std::thread::sleep(Duration::from_millis(2));
    }
    let preview = app.world().resource::<preview::Preview>();
    let held = preview.result.as_ref().expect("no preview after 3000 frames");
    assert!(held.inputs.limit_velocity);
    let over = |r: &PreviewResult, joint: &str| {
        let limits = r.retargeted.report.joint_limits.as_ref().expect("Stretch has velocity limits");
        limits.joints.iter().find(|j| j.joint == joint).unwrap().frames_over
    };
    let free = preview::compute(&PreviewInputs { limit_velocity: false, ..held.inputs.clone() }).unwrap();
    assert!(over(&free, "joint_lift") > 0, "the shipped networks move the lift past its limit on wave");
    let limits = held.retargeted.report.joint_limits.as_ref().unwrap();
    for j in limits.joints.iter().filter(|j| !j.joint.contains("wheel")) {
        assert_eq!(j.frames_over, 0, "{} held", j.joint);
    }
}

/// Opening the hound shows its own glTF scene, posed by the preview through the plugin's creature
/// path: every driven bone stands where the character's pose puts its link, in the editor's y-up
/// world (where a robot's link would stand), and the panel's line reports the hound's DoF and feet.
#[test]
fn a_creature_preview_poses_its_gltf_scene_where_the_character_stands() {
    let opened = open_character("hound").unwrap();
    let mut app = headless_app();
    app.insert_resource(Session {
        character: opened.path.clone(),
        scene_placement: opened.scene_placement,
        checkpoint: opened.checkpoint.clone(),
        clip: walk(),
        limit_velocity: false,
    });
    let ready = |w: &mut World| {
        let Some(scene) = w.get_resource::<crate::Scene>() else { return false };
        let (character, player) = (scene.character, scene.player);
        w.resource::<preview::Preview>().result.is_some()
            && w.get::<CreatureScene>(character).is_some_and(|c| c.joints.is_some())
            && w.get::<HumanJoints>(player).is_some()
    };
    for _ in 0..3000 {
        app.update();
        if ready(app.world_mut()) {
            break;
        }
        std::thread::sleep(Duration::from_millis(2));
    }
    assert!(ready(app.world_mut()), "no preview on the hound's scene after 3000 frames");
    let scene = app.world().resource::<crate::Scene>();
    let (hound, player) = (scene.character, scene.player);

    // The panel's line, from the character asset the plugin loaded.
    let handle = app.world().get::<CreatureScene>(hound).unwrap().asset.clone();
    let asset = app.world().resource::<Assets<CharacterAsset>>().get(&handle).unwrap().clone();
    let dofs = hound_checkpoint_dofs();
    assert_eq!(asset.tree.dof_names(), dofs.iter().map(String::as_str).collect::<Vec<_>>());
    assert_eq!(
        describe(&asset.tree, &asset.morphology),
        format!(
            "hound: {} links, {} DoF; feet: FrontFoot.L, FrontFoot.R, HindFoot.L, HindFoot.R; manipulators: none",
            asset.tree.links.len(),
            dofs.len()
        )
    );

    let rig = asset.rig.clone().expect("the hound is a glTF creature");
    let poses = &app.world().resource::<preview::Preview>().result.as_ref().unwrap().retargeted.motion.poses;
    let poses = poses.clone();
    let mut moved = 0.0f32;
    for seconds in [0.0, 1.5, 3.0] {
        {
            let mut p = app.world_mut().get_mut::<HumanClipPlayer>(player).unwrap();
            p.paused = true;
            p.seek(seconds);
        }
        app.update();
        app.update();
        let frame = (seconds * 30.0).round() as usize;
        let pose = &poses[frame];
        assert_eq!(app.world().get::<Pose>(hound).map(|p| &p.0), Some(pose), "the hound shows frame {frame}");
        let fk = asset.tree.forward_kinematics(pose);
        let joints = app.world().get::<CreatureScene>(hound).unwrap().joints.clone().unwrap();
        assert_eq!(joints.len(), rig.driven().len());
        for (d, &e) in rig.driven().iter().zip(&joints) {
            let got = app.world().get::<GlobalTransform>(e).unwrap().translation();
            let want = convert::vec3(&fk[d.link].translation.vector);
            assert!(got.distance(want) < 1e-4, "{seconds} s: bone {} at {got}, its link at {want}", d.name);
            if seconds > 0.0 {
                let rest = convert::vec3(&asset.tree.forward_kinematics(&poses[0])[d.link].translation.vector);
                moved = moved.max(got.distance(rest));
            }
        }
    }
    // The clip moves the hound (so the comparison above can fail).
    assert!(moved > 0.1, "the bones moved {moved} m");
    assert!(matches!(app.world().get::<RetargetStatus>(hound), Some(RetargetStatus::Loading)));
}

/// The editor's Export of a creature writes the hound's own model with the clip as its one animation
/// (the rig clip `ace retarget` writes), which Khronos' validator accepts; it never writes over what
/// the preview was made from.
#[test]
fn the_export_of_a_creature_is_its_rig_clip() {
    let result = hound_walk();
    let dir = scratch("export");
    let out = dir.join("walk_hound.glb");
    let written = crate::export::export(result, &out).unwrap();
    assert_eq!(written.glb, out);
    for p in [&written.glb, &written.json, &written.csv, &written.metrics] {
        assert!(p.is_file(), "{} not written", p.display());
    }
    if common::khronos_validate(&out).is_none() {
        eprintln!("(validation skipped)");
    }
    let (source, _) = open_gltf(&result.inputs.character).unwrap();
    let (doc, _) = open_gltf(&out).unwrap();
    assert_eq!(doc.meshes().count(), source.meshes().count());
    assert_eq!(doc.skins().count(), 1);
    let names = |d: &ace::models::gltf::Document| d.nodes().map(|n| n.name().unwrap_or("").to_owned()).collect::<Vec<_>>();
    assert_eq!(names(&doc), names(&source));
    let animations: Vec<_> = doc.animations().collect();
    assert_eq!(animations.len(), 1);
    assert_eq!(animations[0].name(), Some(result.clip.name.as_str()));
    let frames = result.retargeted.motion.poses.len();
    assert!(frames > 30);
    for channel in animations[0].channels() {
        assert_eq!(channel.sampler().input().count(), frames, "one key per frame");
    }

    // Over an input: refused, the creature's file untouched.
    let before = std::fs::read(&result.inputs.character).unwrap();
    let Err(e) = crate::export::export(result, &result.inputs.character) else { panic!("exported over the creature") };
    assert!(format!("{e:#}").contains("hound.glb"), "{e:#}");
    assert_eq!(std::fs::read(&result.inputs.character).unwrap(), before);
    assert!(is_gltf(&result.inputs.character));
}

/// The panels show paths below the working directory relative to it (the screenshots in the docs must
/// not carry a machine's folders), and other paths whole.
#[test]
fn panels_show_paths_relative_to_the_working_directory() {
    let cwd = std::env::current_dir().unwrap();
    let inside = cwd.join("assets/motions/walk.bvh");
    assert_eq!(crate::ui::shown(&inside), Path::new("assets/motions/walk.bvh").display().to_string());
    let outside = Path::new("/definitely/elsewhere/walk.bvh");
    assert_eq!(crate::ui::shown(outside), outside.display().to_string());
    assert_eq!(crate::ui::shown(&cwd), cwd.display().to_string());
}

/// The loss-weights panel shows a checkpoint's own weights and leaves them as trained: the crab's end
/// effectors weigh 10, beyond the panel's old 0–5 sliders, which egui clamped on display, so that
/// "Retrain briefly" would have continued with 5 unasked. A weight beyond the sliders' range stays too.
#[test]
fn the_weights_panel_leaves_a_checkpoints_weights_as_trained() {
    use ace::models::features::FeatureBlock;
    use ace::models::learn::ace::AceConfig;

    use crate::retrain::{Retrain, Settings};

    let text = std::fs::read_to_string(repo().join("assets/checkpoints/crab/ace.json")).unwrap();
    let json: serde_json::Value = serde_json::from_str(&text).unwrap();
    let cfg: AceConfig = serde_json::from_value(json["config"].clone()).unwrap();
    let links: Vec<String> = serde_json::from_value(json["correspondence"]["character_links"].clone()).unwrap();
    let mut settings = Settings::of(&cfg, &links);
    assert_eq!(settings.feature_weights.weight(FeatureBlock::EePositions), 10.0);
    settings.w_fea = 250.0;
    let mut retrain = Retrain::default();
    retrain.settings = Some(settings.clone());
    let preview = preview::Preview::default();
    let ctx = bevy_egui::egui::Context::default();
    for _ in 0..3 {
        let mut out = ctx.run_ui(Default::default(), |ui| crate::ui::weights_and_retrain(ui, &preview, &mut retrain));
        out.textures_delta.clear();
    }
    assert_eq!(retrain.settings, Some(settings));
}
