//! The `ace` binary as a user runs it: `inspect` on bundled and never-seen files, `demo`, `dataset` and
//! `metrics` on bundled and real characters, bad input.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

use ace::models::character::gltf::open;
use serde_json::Value;

mod common;
use common::{folder_bytes, root, shared};

fn ace(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_ace")).args(args).current_dir(root()).output().expect("running ace")
}

fn inspect_json(path: &Path) -> Value {
    let out = ace(&["inspect", path.to_str().unwrap(), "--json"]);
    assert!(out.status.success(), "ace inspect {} failed: {}", path.display(), String::from_utf8_lossy(&out.stderr));
    serde_json::from_slice(&out.stdout).expect("inspect --json prints JSON")
}

fn names(v: &Value) -> Vec<String> {
    v.as_array().unwrap().iter().map(|x| x.as_str().unwrap().to_string()).collect()
}

/// Run from a game project, whose `assets/characters/` holds its own files, a bundled name is still
/// the bundled character (it once became `assets/characters/spot.urdf` of the folder it was run in).
#[test]
fn a_bundled_name_is_the_bundled_character_from_a_game_projects_folder() {
    let game = Path::new(env!("CARGO_TARGET_TMPDIR")).join("cli-game-project");
    let _ = std::fs::remove_dir_all(&game);
    std::fs::create_dir_all(game.join("assets/characters")).unwrap();
    std::fs::write(game.join("assets/characters/spot.urdf"), "<robot name=\"mine\"><link name=\"box\"/></robot>").unwrap();
    let o = Command::new(env!("CARGO_BIN_EXE_ace"))
        .args(["dataset", "--character", "spot", "--frames", "30", "--out", "d.safetensors"])
        .current_dir(&game)
        .output()
        .expect("running ace");
    let (out, err) = (String::from_utf8_lossy(&o.stdout), String::from_utf8_lossy(&o.stderr));
    assert!(o.status.success(), "{err}");
    assert!(out.contains("character spot (") && out.contains("18 DoF, 4 feet, 1 manipulators"), "{out}");
}

#[test]
fn inspect_bvh_reports_the_canonical_mapping() {
    let v = inspect_json(&root().join("assets/motions/walk.bvh"));
    assert_eq!(v["kind"], "bvh");
    assert_eq!(v["canonical_joints"], 17);
    assert_eq!(v["frames"], 150);
    assert_eq!(v["fps"], 30.0);
    let h = v["height_m"].as_f64().unwrap();
    assert!((1.6..1.8).contains(&h), "height {h}");
    assert_eq!(v["unit"], "cm");
}

#[test]
fn inspect_bvh_on_real_mocap_of_several_conventions() {
    for (rel, convention) in [
        ("human/mass/walk.bvh", "humanik"),
        ("human/cmu_iclone/002_05.bvh", "iclone"),
        ("human/bandai_namco/dataset-1_bye_active_001.bvh", "bandai"),
        ("human/cmu_cgspeed_mb/01_01.bvh", "cmu-cgspeed-mb"),
    ] {
        let Some(path) = shared(rel) else { return };
        let v = inspect_json(&path);
        assert_eq!(v["kind"], "bvh", "{rel}");
        assert_eq!(v["canonical_joints"], 17, "{rel}");
        assert_eq!(v["convention"], convention, "{rel}");
        assert!(v["frames"].as_u64().unwrap() > 10, "{rel}");
        assert!(v["fps"].as_f64().unwrap() >= 24.0, "{rel}");
        let h = v["height_m"].as_f64().unwrap();
        assert!((1.3..2.1).contains(&h), "{rel}: height {h}");
    }
}

#[test]
fn inspect_urdf_reports_morphology_of_real_robots() {
    let Some(spot) = shared("robots/spot_arm/spot_with_arm.urdf") else { return };
    let v = inspect_json(&spot);
    assert_eq!(v["kind"], "urdf");
    assert_eq!(names(&v["feet"]).len(), 4);
    assert_eq!(names(&v["manipulators"]).len(), 1);
    assert!(names(&v["wheels"]).is_empty());
    assert!(v["dof"].as_u64().unwrap() >= 18);

    let Some(hexapod) = shared("robots/phantomx_hexapod/phantomx_description/urdf/phantomx.urdf") else { return };
    let v = inspect_json(&hexapod);
    assert_eq!(names(&v["feet"]).len(), 6);
    assert!(names(&v["wheels"]).is_empty());

    let Some(stretch) = shared("robots/stretch_re1/stretch_description_RE1V0_tool_stretch_gripper.urdf") else { return };
    let v = inspect_json(&stretch);
    assert!(names(&v["feet"]).is_empty());
    assert!(names(&v["wheels"]).len() >= 2);
    assert_eq!(names(&v["manipulators"]).len(), 1);
}

#[test]
fn inspect_urdf_on_bundled_characters() {
    for (name, dof, feet, manipulators, wheels) in [("spot", Some(18), 4, 1, 0), ("crab", Some(24), 6, 2, 0), ("stretch", None, 0, 1, 2)] {
        let v = inspect_json(&root().join(format!("assets/characters/{name}.urdf")));
        if let Some(dof) = dof {
            assert_eq!(v["dof"], dof, "{name}");
        }
        assert_eq!(names(&v["feet"]).len(), feet, "{name}");
        assert_eq!(names(&v["manipulators"]).len(), manipulators, "{name}");
        assert_eq!(names(&v["wheels"]).len(), wheels, "{name}");
    }
}

#[test]
fn inspect_text_output_is_human_readable() {
    let out = ace(&["inspect", "assets/characters/crab.urdf"]);
    assert!(out.status.success());
    let text = String::from_utf8(out.stdout).unwrap();
    assert!(text.contains("dof: 24"), "{text}");
    assert!(!text.trim_start().starts_with('{'));
}

#[test]
fn inspect_rejects_bad_files_naming_them() {
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR")).join("cli-bad");
    std::fs::create_dir_all(&dir).unwrap();
    let truncated = dir.join("truncated.bvh");
    let walk = std::fs::read_to_string(root().join("assets/motions/walk.bvh")).unwrap();
    std::fs::write(&truncated, &walk[..walk.len() * 2 / 3]).unwrap();
    let out = ace(&["inspect", truncated.to_str().unwrap(), "--json"]);
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("truncated.bvh"), "{err}");
    assert!(out.stdout.is_empty());

    let other = dir.join("notes.txt");
    std::fs::write(&other, "hello").unwrap();
    let out = ace(&["inspect", other.to_str().unwrap()]);
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("notes.txt"));
}

/// Runs Khronos' glTF validator (installed by scripts/setup.sh) on `glb`: `None` when it is missing and
/// `ACE_ALLOW_MISSING_DATA=1` allows that, else its report.
fn validate_gltf(glb: &Path) -> Option<Value> {
    let validator = root().join(".local/node/node_modules/gltf-validator");
    if !validator.exists() && std::env::var("ACE_ALLOW_MISSING_DATA").is_ok_and(|v| v == "1") {
        eprintln!("skipping validation: {} is missing", validator.display());
        return None;
    }
    let out = Command::new("node").arg(root().join("scripts/validate-gltf.mjs")).arg(glb).output().expect("running node (scripts/setup.sh installs it)");
    let report: Value = serde_json::from_slice(&out.stdout).unwrap_or_else(|_| panic!("validator output: {}", String::from_utf8_lossy(&out.stderr)));
    assert_eq!(report["issues"]["numErrors"], 0, "{}: {report}", glb.display());
    assert!(out.status.success());
    Some(report)
}

/// `--out NAME.gltf` writes glTF's JSON form, data embedded, for a robot and a rigged creature: the
/// CLI wrote the GLB under that name, since the export picked the format from its staged temporary's
/// name, which ended in `.ace-tmp-<pid>`.
#[test]
fn retarget_to_a_gltf_name_writes_gltf_json() {
    let dir = tmp("gltf-out");
    let clip = root().join("assets/motions/wave.bvh");
    for character in ["spot", "hound"] {
        for name in [format!("{character}.gltf"), format!("{character}-upper.GLTF")] {
            let out = dir.join(&name);
            run_ok(&["retarget", clip.to_str().unwrap(), "--character", character, "--out", out.to_str().unwrap()]);
            let doc: Value = serde_json::from_slice(&std::fs::read(&out).unwrap()).unwrap_or_else(|e| panic!("{name} is not JSON: {e}"));
            assert_eq!(doc["asset"]["version"], "2.0", "{name}");
            assert!(doc["buffers"][0]["uri"].as_str().unwrap().starts_with("data:application/octet-stream;base64,"), "{name}");
            assert_eq!(doc["animations"].as_array().unwrap().len(), 1, "{name}");
            validate_gltf(&out);
        }
    }
    assert!(std::fs::read_dir(&dir).unwrap().all(|e| !e.unwrap().file_name().to_string_lossy().contains("ace-tmp")));
}

#[test]
fn demo_retargets_every_bundled_clip_onto_every_bundled_character() {
    let out_dir = Path::new(env!("CARGO_TARGET_TMPDIR")).join("cli-demo");
    let _ = std::fs::remove_dir_all(&out_dir);
    let out = ace(&["--threads", "1", "demo", "--out", out_dir.to_str().unwrap()]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let report: Value = serde_json::from_str(&std::fs::read_to_string(out_dir.join("report.json")).unwrap()).unwrap();
    let rows = report.as_array().unwrap();
    assert_eq!(rows.len(), 12, "4 characters × 3 clips");
    let md = std::fs::read_to_string(out_dir.join("report.md")).unwrap();
    for c in ["spot", "crab", "stretch", "hound"] {
        for clip in ["reach", "walk", "wave"] {
            let glb = out_dir.join(c).join(format!("{clip}.glb"));
            for ext in ["json", "csv", "metrics.json"] {
                assert!(glb.with_extension(ext).is_file(), "{}: no .{ext}", glb.display());
            }
            validate_gltf(&glb);
            assert!(md.contains(&format!("| {c} | {clip} |")), "{md}");
        }
        let img = image::open(out_dir.join(format!("{c}.png"))).unwrap().to_rgb8();
        assert_eq!(img.dimensions(), (1280, 720));
        // The character's orange and the human's blue were drawn.
        let orange = img.pixels().filter(|p| p.0 == [214, 140, 30]).count();
        let blue = img.pixels().filter(|p| p.0 == [40, 100, 235]).count();
        assert!(orange > 300 && blue > 300, "{c}: orange {orange}, blue {blue}");
    }
    let mut swings = std::collections::HashMap::<String, (u64, u64)>::new();
    for r in rows {
        let m = &r["metrics"];
        for k in ["div", "fid", "feature_loss"] {
            assert!(m[k].as_f64().is_some_and(f64::is_finite), "{r}");
        }
        // The shipped checkpoints with the cleanup: realistic motion on the bundled clips, within the
        // paper's 3 % (the README's promise; the networks' raw output is above 90 %).
        assert!(m["ufr"]["rates"]["ufr"].as_f64().unwrap() <= 0.03, "{r}");
        let c = r["character"].as_str().unwrap().to_string();
        // Stretch's arm, Spot's arm and the crab's right claw follow the hand the bundled wave clip
        // raises (Stretch 0.997 since its retraining on 2026-12-06; Spot 0.93 and the crab 0.95 when shipped).
        let follower = match c.as_str() {
            "stretch" => Some("grasp_center"),
            "spot" => Some("gripper_tip"),
            "crab" => Some("arm_r_claw_tip"),
            _ => None,
        };
        // The human stands through the whole wave clip: the report says how far each character's root
        // travels and turns meanwhile (the crab stands, Stretch drives off: docs/following.md).
        if r["clip"] == "wave" {
            let f = &m["following"];
            assert_eq!(f["standing_clips"], 1, "{c}: {f}");
            for k in ["standing_travel", "standing_turn"] {
                assert!(f[k].as_f64().is_some_and(|v| v.is_finite() && v >= 0.0), "{c}: {k} in {f}");
            }
            assert!(md.contains(&format!("BL/s, {:.1}°/s", f["standing_turn"].as_f64().unwrap())), "{md}");
            // The cleanup's standing hold keeps every root in place (the networks alone travel
            // 0.05–0.28 body lengths/s here; Stretch drives 1.5 m).
            let travel = f["standing_travel"].as_f64().unwrap();
            assert!(travel < 0.01, "{c} travels {travel} body lengths/s while the person stands");
        }
        // The person turns 20° left on the walk; the heading steering keeps every character within
        // 30° of that (9–22° when written; the networks alone turn 64–145° off it).
        if r["clip"] == "walk" {
            let heading = m["following"]["heading_error"].as_f64().unwrap();
            assert!(heading <= 30.0, "{c} strays {heading:.0}° from the person's heading on walk");
        }
        if let (Some(link), true) = (follower, r["clip"] == "wave") {
            let pairs = m["following"]["clips"][0][0]["pairs"].as_array().unwrap();
            let pair = pairs.iter().find(|p| p["character"] == link).unwrap();
            assert_eq!(pair["human"], "right_hand");
            let vertical = pair["correlation"]["vertical"].as_f64().unwrap();
            assert!(vertical > 0.7, "{c}'s {link} against the right hand on wave: {vertical}");
        }
        // Every row says how the joints keep to their limits: the robots' files give velocity limits,
        // the hound's gives none (its column reads n/a).
        let limits = &m["joint_limits"];
        let with_velocity = limits["joints"].as_array().unwrap().iter().any(|j| j["velocity_limit"].is_number());
        assert_eq!(with_velocity, c != "hound", "{c}: {limits}");
        assert!(limits["over_velocity"].as_f64().is_some_and(|v| (0.0..=1.0).contains(&v)), "{c}: {limits}");
        if c == "stretch" {
            assert!(m["gait"].is_null(), "wheels have no gait: {r}");
        } else {
            let e = swings.entry(c).or_default();
            e.0 += m["gait"]["swings"].as_u64().unwrap();
            e.1 += m["gait"]["one_or_two_frame_swings"].as_u64().unwrap();
        }
    }
    // The cleanup's swings: at most 5 % of them pop (1–2 frames) over the bundled clips (the foot lock
    // that let feet jump made 45–100 % of Spot's swings pops).
    for (c, (all, pops)) in swings {
        assert!(all > 0 && pops * 20 <= all, "{c}: {pops} of {all} swings last 1–2 frames");
    }
}

fn tmp(name: &str) -> PathBuf {
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR")).join("cli-dataset");
    std::fs::create_dir_all(&dir).unwrap();
    dir.join(name)
}

/// The folder [`tmp`]`(name)`, emptied and made.
fn fresh(name: &str) -> PathBuf {
    let dir = tmp(name);
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

fn dataset(character: &str, frames: usize, seed: u64, out: &Path, extra: &[&str]) -> Output {
    let (frames, seed) = (frames.to_string(), seed.to_string());
    let mut args = vec!["dataset", "--character", character, "--frames", &frames, "--seed", &seed, "--out", out.to_str().unwrap()];
    args.extend_from_slice(extra);
    ace(&args)
}

fn metrics_json(file: &Path, character: &str) -> Value {
    let out = ace(&["metrics", file.to_str().unwrap(), "--character", character, "--json"]);
    assert!(out.status.success(), "ace metrics {} failed: {}", file.display(), String::from_utf8_lossy(&out.stderr));
    serde_json::from_slice(&out.stdout).expect("metrics --json prints JSON")
}

#[test]
fn dataset_and_metrics_on_bundled_and_real_characters() {
    // (name, --character, UFR limit): the issue's targets for the bundled characters and rigged
    // creatures (0.5 %); real robots only need a clean enough motion.
    let mut characters: Vec<(String, String, f64)> =
        ["spot", "crab", "stretch", "hound"].iter().map(|n| (n.to_string(), n.to_string(), 0.005)).collect();
    for (name, rel, limit) in [
        ("real-spot", "robots/spot_arm/spot_with_arm.urdf", 0.05),
        ("phantomx", "robots/phantomx_hexapod/phantomx_description/urdf/phantomx.urdf", 0.05),
        ("stretch-re1", "robots/stretch_re1/stretch_description_RE1V0_tool_stretch_gripper.urdf", 0.05),
        ("fox", "creatures/Fox/Fox.glb", 0.005),
        ("spider", "creatures/Quaternius_Spider/Spider.glb", 0.005),
    ] {
        let Some(p) = shared(rel) else { continue };
        characters.push((name.to_string(), p.to_str().unwrap().to_string(), limit));
    }
    for (name, arg, limit) in characters {
        let file = tmp(&format!("{name}.safetensors"));
        let out = dataset(&arg, 3000, 3, &file, &[]);
        assert!(out.status.success(), "ace dataset {name}: {}", String::from_utf8_lossy(&out.stderr));
        let v = metrics_json(&file, &arg);
        assert_eq!(v["frames"], 3000, "{name}");
        let div = v["div"].as_f64().unwrap();
        assert!(div.is_finite() && div > 0.0, "{name}: DIV {div}");
        assert!(v["fid"].is_null() && v["feature_loss"].is_null(), "{name}: no reference, no source");
        let ufr = v["ufr"]["rates"]["ufr"].as_f64().unwrap();
        assert!(ufr <= limit, "{name}: dataset UFR {:.3} % above {:.1} %", 100.0 * ufr, 100.0 * limit);
        // Legged characters get the gait measure: steps, none of them pops, and none is shorter than
        // 4 frames where it walks (Fr < 0.3).
        if name.contains("stretch") {
            assert!(v["gait"].is_null(), "{name}: wheels have no gait");
        } else {
            assert!(v["gait"]["strides"].as_u64().unwrap() > 50, "{name}: {}", v["gait"]);
            assert_eq!(v["gait"]["one_or_two_frame_swings"], 0, "{name}: {}", v["gait"]);
            assert_eq!(v["gait"]["short_walking_swings"], 0, "{name}: {}", v["gait"]);
            assert!(!v["gait"]["bins"].as_array().unwrap().is_empty(), "{name}");
        }
    }
}

#[test]
fn the_same_seed_gives_the_same_dataset_file() {
    let (a, b, c) = (tmp("seed-a.safetensors"), tmp("seed-b.safetensors"), tmp("seed-c.safetensors"));
    for (file, seed) in [(&a, 11), (&b, 11), (&c, 12)] {
        let out = dataset("crab", 1500, seed, file, &[]);
        assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    }
    let bytes = |p: &Path| std::fs::read(p).unwrap();
    assert_eq!(bytes(&a), bytes(&b), "same seed, same file");
    assert_ne!(bytes(&a), bytes(&c), "another seed, another dataset");
}

/// `--include-clips`: a rigged creature's own clips fill the end of its dataset, 2 % of the frames
/// unless the configuration's `[own_clips]` gives a share; a robot has no clips and is refused naming
/// its file, with nothing written.
/// A body the controllers cannot move cleanly makes a dataset the prior would learn: a profile that
/// keeps one of the Fox's four feet (the others hang, its body sags onto them) made one of 93 % UFR
/// without a word. `ace dataset` now warns, and says nothing on the Fox as it is.
#[test]
fn an_unclean_dataset_is_warned_of() {
    let Some(fox) = shared("creatures/Fox/Fox.glb") else { return };
    let dir = fresh("one-legged-fox");
    let copy = dir.join("Fox.glb");
    std::fs::copy(&fox, &copy).unwrap();
    let out = dataset(copy.to_str().unwrap(), 2000, 0, &dir.join("four.safetensors"), &[]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success() && !err.contains("unnatural"), "{err}");
    std::fs::write(dir.join("Fox.profile.toml"), "feet = [\"b_RightHand_08\"]\n").unwrap();
    let out = dataset(copy.to_str().unwrap(), 2000, 0, &dir.join("one.safetensors"), &[]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{err}");
    assert!(err.contains("of the dataset's frames are unnatural by the UFR detectors") && err.contains("(feet b_RightHand_08)"), "{err}");
}

#[test]
fn include_clips_adds_a_creatures_own_clips_to_its_dataset() {
    use ace::models::dataset::MotionSet;
    let Some(fox) = shared("creatures/Fox/Fox.glb") else { return };
    let fox = fox.to_str().unwrap();
    let file = tmp("fox-clips.safetensors");
    let out = dataset(fox, 1000, 1, &file, &["--include-clips"]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let set = MotionSet::load(&file).unwrap();
    assert_eq!((set.len(), set.config.own_clips.share), (1000, 0.02));
    assert!(set.episodes.iter().any(|e| e.start == 980), "the clips start at frame 980: {:?}", set.episodes);

    let toml = tmp("fox-clips.toml");
    std::fs::write(&toml, "[own_clips]\nshare = 0.3\nnames = [\"Run\"]\n").unwrap();
    let out = dataset(fox, 1000, 1, &file, &["--include-clips", "--config", toml.to_str().unwrap()]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let set = MotionSet::load(&file).unwrap();
    assert_eq!(set.config.own_clips.share, 0.3);
    let clips: Vec<usize> = set.episodes.iter().filter(|e| e.start >= 700).map(|e| e.len()).collect();
    assert!(clips.len() > 5 && clips[..clips.len() - 1].iter().all(|&n| n == clips[0]), "the run, again and again: {clips:?}");

    let crab = tmp("crab-clips.safetensors");
    let out = dataset("crab", 300, 0, &crab, &["--include-clips"]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success() && err.contains("crab.urdf") && err.contains("only a rigged glTF creature"), "{err}");
    assert!(!crab.exists());
}

#[test]
fn dataset_report_draws_gaits_velocities_and_foot_heights() {
    let file = tmp("report-spot.safetensors");
    let dir = tmp("report-spot");
    let _ = std::fs::remove_dir_all(&dir);
    let out = dataset("spot", 4000, 5, &file, &["--report", dir.to_str().unwrap()]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    for png in ["gait.png", "velocity.png", "foot_heights.png"] {
        let img = image::open(dir.join(png)).unwrap_or_else(|e| panic!("{png}: {e}")).to_rgb8();
        assert!(img.width() >= 800 && img.height() >= 300, "{png}: {:?}", img.dimensions());
        // A chart, not a blank page: a good share of pixels is neither the white background nor grey.
        let coloured = img.pixels().filter(|p| {
            let [r, g, b] = p.0;
            r.max(g).max(b) - r.min(g).min(b) > 60
        });
        assert!(coloured.count() > 2000, "{png} has hardly any coloured pixels");
    }
    let m: Value = serde_json::from_str(&std::fs::read_to_string(dir.join("metrics.json")).unwrap()).unwrap();
    assert_eq!(m["frames"], 4000);
    // A wheeled character has no feet: no gait diagram, but velocities.
    let file = tmp("report-stretch.safetensors");
    let dir = tmp("report-stretch");
    let _ = std::fs::remove_dir_all(&dir);
    let out = dataset("stretch", 1500, 5, &file, &["--report", dir.to_str().unwrap()]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    assert!(dir.join("velocity.png").is_file() && !dir.join("gait.png").exists());
}

#[test]
fn dataset_and_metrics_reject_bad_input_naming_it() {
    let out = dataset("octopus", 100, 0, &tmp("none.safetensors"), &[]);
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("octopus"), "{}", String::from_utf8_lossy(&out.stderr));

    let crab = tmp("mismatch-crab.safetensors");
    assert!(dataset("crab", 300, 0, &crab, &[]).status.success());
    let out = ace(&["metrics", crab.to_str().unwrap(), "--character", "spot"]);
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("mismatch-crab.safetensors") && err.contains("does not match"), "{err}");

    let junk = tmp("junk.safetensors");
    std::fs::write(&junk, b"not a dataset").unwrap();
    let out = ace(&["metrics", junk.to_str().unwrap()]);
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("junk.safetensors"));
}

/// FID against a reference dataset: zero against itself, positive against another seed, and refused
/// (naming the file) for a set with no more frames than Ψ has entries (Spot's 28), whose covariance is
/// singular: a 1-frame reference scored an FID, the same whichever set it was.
#[test]
fn metrics_fid_against_a_reference_needs_more_frames_than_features() {
    let (a, b, short) = (tmp("fid-a.safetensors"), tmp("fid-b.safetensors"), tmp("fid-short.safetensors"));
    for (file, frames, seed) in [(&a, 300, 0), (&b, 300, 1), (&short, 28, 0)] {
        assert!(dataset("spot", frames, seed, file, &[]).status.success());
    }
    let fid = |motion: &Path, reference: &Path| {
        let out = ace(&["metrics", motion.to_str().unwrap(), "--reference", reference.to_str().unwrap(), "--json"]);
        assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
        let v: Value = serde_json::from_slice(&out.stdout).unwrap();
        v["fid"].as_f64().unwrap()
    };
    assert!(fid(&a, &a).abs() < 1e-3, "a set against itself");
    assert!(fid(&a, &b) > 0.01, "two seeds' walks differ");
    for (motion, reference) in [(&a, &short), (&short, &a)] {
        let out = ace(&["metrics", motion.to_str().unwrap(), "--reference", reference.to_str().unwrap()]);
        assert!(!out.status.success());
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(err.contains("fid-short.safetensors: 28 frame(s) cannot give an FID") && err.contains("at least 29"), "{err}");
    }
}

/// Tiny networks and step counts: the whole pipeline in seconds, not a useful model.
#[test]
fn retarget_warns_when_a_joint_of_the_trajectory_is_faster_than_its_limit() {
    let dir = tmp("joint-limits");
    std::fs::create_dir_all(&dir).unwrap();
    let glb = dir.join("wave.glb");
    let out = ace(&["retarget", "assets/motions/wave.bvh", "--character", "stretch", "--out", glb.to_str().unwrap()]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let (stdout, stderr) = (String::from_utf8_lossy(&out.stdout), String::from_utf8_lossy(&out.stderr));
    let m: Value = serde_json::from_str(&std::fs::read_to_string(glb.with_extension("metrics.json")).unwrap()).unwrap();
    let limits = &m["joint_limits"];
    assert_eq!(limits["frames"], m["frames"]);
    let joints = limits["joints"].as_array().unwrap();
    let names: Vec<&str> = joints.iter().map(|j| j["joint"].as_str().unwrap()).collect();
    for j in ["joint_left_wheel", "joint_right_wheel", "joint_lift", "joint_wrist_yaw"] {
        assert!(names.contains(&j), "{names:?}");
    }
    // The measure agrees with the trajectory the same run wrote: each joint's peak speed between two
    // frames of its `.json`, and the frames over the limit.
    let traj: Value = serde_json::from_str(&std::fs::read_to_string(glb.with_extension("json")).unwrap()).unwrap();
    let column = |name: &str| traj["joints"].as_array().unwrap().iter().position(|j| j["name"] == name).unwrap();
    let frames = traj["frames"].as_array().unwrap();
    let lift = joints.iter().find(|j| j["joint"] == "joint_lift").unwrap();
    let k = column("joint_lift");
    let q: Vec<f64> = frames.iter().map(|f| f["q"][k].as_f64().unwrap()).collect();
    let peak = q.windows(2).map(|w| (w[1] - w[0]).abs() * traj["fps"].as_f64().unwrap()).fold(0.0, f64::max);
    assert!((lift["peak_velocity"].as_f64().unwrap() - peak).abs() < 1e-3 * peak.max(1.0), "{lift} against {peak}");
    // Warned exactly when a joint is over, naming the trajectory file and the fastest joint.
    let over = limits["over_velocity"].as_f64().unwrap() > 0.0 || limits["outside_position"].as_f64().unwrap() > 0.0;
    assert_eq!(stderr.contains("a robot would not execute it as written"), over, "{stderr}");
    if limits["over_velocity"].as_f64().unwrap() > 0.0 {
        let fastest = joints
            .iter()
            .filter(|j| j["frames_over"].as_u64().unwrap() > 0)
            .max_by(|a, b| {
                let r = |j: &Value| j["peak_velocity"].as_f64().unwrap() / j["velocity_limit"].as_f64().unwrap();
                r(a).total_cmp(&r(b))
            })
            .unwrap();
        let warning = stderr.lines().find(|l| l.contains("velocity limit")).unwrap();
        assert!(warning.contains(glb.with_extension("json").to_str().unwrap()), "{warning}");
        assert!(warning.contains(fastest["joint"].as_str().unwrap()), "{warning}");
        assert!(stdout.contains("joint limits:"), "{stdout}");
        assert!(warning.contains("--limit-velocity"), "{warning}");
    }

    // `--limit-velocity` holds every joint but the wheels to its limit (a wheel's angle follows the
    // base's travel).
    let held = dir.join("wave-held.glb");
    let out = ace(&["retarget", "assets/motions/wave.bvh", "--character", "stretch", "--limit-velocity", "--out", held.to_str().unwrap()]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let m: Value = serde_json::from_str(&std::fs::read_to_string(held.with_extension("metrics.json")).unwrap()).unwrap();
    for j in m["joint_limits"]["joints"].as_array().unwrap() {
        if !j["joint"].as_str().unwrap().contains("wheel") {
            assert_eq!(j["frames_over"], 0, "{j}");
            assert!(j["peak_velocity"].as_f64().unwrap() <= j["velocity_limit"].as_f64().unwrap() * 1.01, "{j}");
        }
    }
    let peak = |limits: &Value| limits["joints"].as_array().unwrap().iter().find(|j| j["joint"] == "joint_lift").unwrap()["peak_velocity"].as_f64().unwrap();
    if lift["frames_over"].as_u64().unwrap() > 0 {
        assert!(peak(&m["joint_limits"]) < peak(limits), "the lift was held back");
    }
}

const TINY_PRIOR: &str = "steps = 120\nbatch_size = 16\ncheckpoint_every = 60\nencoder_hidden = [32, 32]\ndecoder_hidden = [32, 32]\n";
const TINY_ACE: &str = "steps = 40\nbatch_size = 8\ncheckpoint_every = 20\ngenerator_hidden = [32, 32]\ndiscriminator_hidden = [32, 32]\n";

/// Runs `ace` with `args` and returns its standard output; a failure fails the test with its errors.
fn run_ok(args: &[&str]) -> String {
    let out = ace(args);
    assert!(out.status.success(), "ace {args:?}: {}", String::from_utf8_lossy(&out.stderr));
    String::from_utf8_lossy(&out.stdout).into_owned()
}

/// Trains a tiny prior (on 3,000 frames) and generator for `character` into `dir/ck` and returns the
/// checkpoint folder and what `ace train` printed.
fn tiny_checkpoint(dir: &Path, character: &str) -> (PathBuf, String) {
    tiny_checkpoint_with(dir, character, "")
}

/// [`tiny_checkpoint`] with more lines for the ACE configuration.
fn tiny_checkpoint_with(dir: &Path, character: &str, ace_lines: &str) -> (PathBuf, String) {
    let _ = std::fs::remove_dir_all(dir);
    std::fs::create_dir_all(dir).unwrap();
    let (prior_cfg, ace_cfg, ck) = (dir.join("prior.toml"), dir.join("ace.toml"), dir.join("ck"));
    std::fs::write(&prior_cfg, TINY_PRIOR).unwrap();
    std::fs::write(&ace_cfg, format!("{TINY_ACE}{ace_lines}")).unwrap();
    let s = |p: &Path| p.to_str().unwrap().to_string();
    run_ok(&["--threads", "1", "train-prior", "--character", character, "--frames", "3000", "--config", &s(&prior_cfg), "--checkpoint", &s(&ck)]);
    for f in ["config.json", "prior.safetensors", "prior_losses.csv", "prior_losses.png"] {
        assert!(ck.join(f).is_file(), "train-prior wrote no {f}");
    }
    let stdout = run_ok(&["--threads", "1", "train", "--character", character, "--config", &s(&ace_cfg), "--checkpoint", &s(&ck), "--humans", "assets/motions"]);
    for f in ["ace.json", "generator.safetensors", "discriminator.safetensors", "ace_losses.csv", "ace_losses.png", "reference.json"] {
        assert!(ck.join(f).is_file(), "train wrote no {f}");
    }
    // The reference fit records what it was fitted for, as ace.json records it.
    let json = |f: &str| -> serde_json::Value { serde_json::from_slice(&std::fs::read(ck.join(f)).unwrap()).unwrap() };
    let (ace_json, reference) = (json("ace.json"), json("reference.json"));
    assert_eq!(reference["prior"], ace_json["prior"]);
    assert_eq!(reference["mapping"], ace_json["correspondence"]["mapping"]);
    let f32_of = |v: &serde_json::Value| v.as_f64().map(|x| x as f32);
    assert_eq!(f32_of(&reference["character_body_length"]), f32_of(&ace_json["body_lengths"]["character"]));
    assert!(f32_of(&reference["character_body_length"]).is_some());
    (ck, stdout)
}

#[test]
fn train_prior_generates_its_dataset_with_the_given_settings_and_records_them() {
    let dir = fresh("dataset-config");
    let s = |p: &Path| p.to_str().unwrap().to_string();
    let (prior_cfg, ck) = (dir.join("prior.toml"), dir.join("ck"));
    std::fs::write(&prior_cfg, TINY_PRIOR).unwrap();
    // Spot's own settings file, as scripts/train-checkpoints.sh passes it.
    let settings = root().join("assets/training/spot.dataset.toml");
    run_ok(&["--threads", "1", "train-prior", "--character", "spot", "--frames", "2000", "--config", &s(&prior_cfg), "--dataset-config", &s(&settings), "--checkpoint", &s(&ck)]);
    let config: Value = serde_json::from_slice(&std::fs::read(ck.join("config.json")).unwrap()).unwrap();
    let recorded = &config["provenance"]["dataset"]["config"];
    assert_eq!(recorded["controller"]["reach"]["home_reach"].as_f64(), Some(0.25), "{recorded}");
    assert_eq!(recorded["frames"], 2000, "--frames still wins: {recorded}");

    // A setting out of range is refused before any work, naming the file and the key.
    let bad = dir.join("bad.toml");
    std::fs::write(&bad, "[controller.reach]\nhome_reach = -1\n").unwrap();
    let ck2 = dir.join("ck2");
    let out = ace(&["--threads", "1", "train-prior", "--character", "spot", "--config", &s(&prior_cfg), "--dataset-config", &s(&bad), "--checkpoint", &s(&ck2)]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success() && err.contains("bad.toml") && err.contains("controller.reach.home_reach"), "{err}");
    assert!(!ck2.exists(), "a refused run wrote its checkpoint folder");
    // A dataset file carries its own settings.
    let out = ace(&["train-prior", "--character", "spot", "--dataset", "x.npz", "--dataset-config", &s(&bad)]);
    assert!(!out.status.success() && String::from_utf8_lossy(&out.stderr).contains("--dataset-config"));
}

/// `ace eval`'s `eval.csv` in `dir`: a header naming its columns, then one row per system of
/// `character`, in order, with finite div, fid, l_fea, following, heading error, pace and ufr (the
/// four that need a person empty for the dataset only; the bundled walk gives every other row a
/// pace).
fn check_eval_csv(dir: &Path, character: &str, systems: &[&str]) {
    let csv = std::fs::read_to_string(dir.join("eval.csv")).unwrap();
    let mut lines = csv.lines();
    let header: Vec<&str> = lines.next().unwrap().split(',').collect();
    let columns = ["div", "fid", "l_fea", "following", "heading_error_deg", "pace", "ufr"];
    assert_eq!(&header[3..10], &columns, "{csv}");
    // The share of frames over a velocity limit: a share for a robot, empty for a creature (its file
    // gives no velocity limits).
    let over = header.iter().position(|h| *h == "over_velocity").expect("an over_velocity column");
    let robot = character == "stretch";
    let rows: Vec<&str> = lines.collect();
    assert_eq!(rows.len(), systems.len(), "{csv}");
    for (row, system) in rows.iter().zip(systems) {
        assert!(row.starts_with(&format!("{character},{system},")), "{csv}");
        let cells: Vec<&str> = row.split(',').collect();
        assert_eq!(cells.len(), header.len(), "{csv}");
        for (column, c) in columns.iter().zip(&cells[3..10]) {
            let humanless = c.is_empty() && *system == "Dataset" && ["l_fea", "following", "heading_error_deg", "pace"].contains(column);
            assert!(humanless || c.parse::<f64>().is_ok_and(f64::is_finite), "{column} in {row}");
        }
        let share = cells[over].parse::<f64>();
        assert!(if robot { share.is_ok_and(|v| (0.0..=1.0).contains(&v)) } else { cells[over].is_empty() }, "over_velocity in {row}");
    }
}

#[test]
fn train_prior_train_and_retarget_write_a_valid_clip_and_trajectory() {
    let dir = tmp("pipeline");
    let (ck, stdout) = tiny_checkpoint(&dir, "stretch");
    let s = |p: &Path| p.to_str().unwrap().to_string();
    let run = run_ok;
    assert!(stdout.contains("grasp_center"), "the correspondence table names the end effectors:\n{stdout}");

    let glb = dir.join("wave.glb");
    run(&["--threads", "1", "retarget", "assets/motions/wave.bvh", "--character", "stretch", "--checkpoint", &s(&ck), "--out", &s(&glb)]);
    let frames = inspect_json(&root().join("assets/motions/wave.bvh"))["frames"].as_u64().unwrap() as usize; // at 30 fps
    let csv = std::fs::read_to_string(glb.with_extension("csv")).unwrap();
    assert_eq!(csv.lines().count(), frames + 1, "one row per frame plus the header");
    assert!(csv.lines().next().unwrap().starts_with("t,vx,vy,wz,height,"));
    let traj: Value = serde_json::from_str(&std::fs::read_to_string(glb.with_extension("json")).unwrap()).unwrap();
    assert_eq!(traj["robot"], "stretch");
    let m: Value = serde_json::from_str(&std::fs::read_to_string(glb.with_extension("metrics.json")).unwrap()).unwrap();
    assert_eq!(m["frames"], frames);
    for k in ["div", "fid", "feature_loss"] {
        assert!(m[k].as_f64().is_some_and(f64::is_finite), "{k} = {}", m[k]);
    }
    // Khronos' validator (installed by scripts/setup.sh) finds no errors.
    validate_gltf(&glb);

    // The held-out evaluation writes a complete table with finite values.
    let eval_dir = dir.join("eval");
    let stdout = run(&["--threads", "1", "eval", "--character", "stretch", "--checkpoint", &s(&ck), "--humans", "assets/motions", "--seconds", "4", "--out", &s(&eval_dir)]);
    assert!(stdout.contains("| ACE |"), "{stdout}");
    check_eval_csv(&eval_dir, "stretch", &["Dataset", "ACE", "ACE without cleanup", "Prior with random z"]);
    let e: Value = serde_json::from_str(&std::fs::read_to_string(eval_dir.join("eval.json")).unwrap()).unwrap();
    for st in e["stability"].as_array().unwrap() {
        assert_eq!(st["finite"], true, "{st}");
        assert!((st["seconds"].as_f64().unwrap() - 4.0).abs() < 0.1, "{st}");
    }
    assert!(image::open(eval_dir.join("eval.png")).is_ok());
    // FID split by feature block: every row's whole FID is the table's, and the human clips' own
    // features (what a system with L_fea = 0 would score) are scored the same way.
    for r in e["rows"].as_array().unwrap() {
        let (fid, split) = (r["metrics"]["fid"].as_f64().unwrap(), &r["fid_split"]);
        assert!((split["total"].as_f64().unwrap() - fid).abs() < 1e-3 * (1.0 + fid), "{r}");
        let blocks = split["blocks"].as_array().unwrap();
        assert_eq!(blocks.len(), 5, "{split}");
        assert!(blocks.iter().all(|b| b[1].as_f64().is_some_and(|v| v.is_finite() && v >= 0.0)), "{split}");
    }
    assert!(e["source_fid"]["total"].as_f64().is_some_and(|v| v.is_finite() && v > 0.0), "{}", e["source_fid"]);
    let md = std::fs::read_to_string(eval_dir.join("eval.md")).unwrap();
    assert!(md.contains("FID by feature block") && md.contains("| Human clips (L_fea = 0) |"), "{md}");
    assert_eq!(e["limit_velocity"], false);
    assert!(!md.contains("--limit-velocity"), "{md}");

    // With `--limit-velocity` ACE keeps every joint but the wheels within its limit; the networks'
    // raw output is scored as before.
    let held_dir = dir.join("eval-held");
    run(&["--threads", "1", "eval", "--character", "stretch", "--checkpoint", &s(&ck), "--humans", "assets/motions", "--seconds", "4", "--limit-velocity", "--out", &s(&held_dir)]);
    let held: Value = serde_json::from_str(&std::fs::read_to_string(held_dir.join("eval.json")).unwrap()).unwrap();
    assert_eq!(held["limit_velocity"], true);
    let row = |e: &Value, name: &str| e["rows"].as_array().unwrap().iter().find(|r| r["system"] == name).unwrap().clone();
    let joints = |r: &Value| r["metrics"]["joint_limits"]["joints"].as_array().unwrap().clone();
    for j in joints(&row(&held, "ACE")) {
        if !j["joint"].as_str().unwrap().contains("wheel") {
            assert_eq!(j["frames_over"], 0, "{j}");
        }
    }
    let over = |e: &Value| joints(&row(e, "ACE")).iter().filter(|j| !j["joint"].as_str().unwrap().contains("wheel")).map(|j| j["frames_over"].as_u64().unwrap()).sum::<u64>();
    assert!(over(&e) > 0, "the tiny networks move some arm joint past its limit: nothing to hold back");
    assert_eq!(row(&held, "ACE without cleanup")["metrics"], row(&e, "ACE without cleanup")["metrics"]);
    let md = std::fs::read_to_string(held_dir.join("eval.md")).unwrap();
    assert!(md.lines().next().unwrap().contains("velocity limits (`--limit-velocity`)"), "{md}");
    // The checkpoint records the centring of L_fea that the scores used: one offset per Ψ entry.
    let record: Value = serde_json::from_str(&std::fs::read_to_string(ck.join("ace.json")).unwrap()).unwrap();
    let offset = record["feature_offset"].as_array().unwrap();
    let mapped = record["correspondence"]["mapping"]["human"].as_array().unwrap().iter().filter(|h| !h.is_null()).count();
    assert_eq!(offset.len(), 13 + 3 * mapped, "{offset:?}");
    assert!(offset.iter().any(|o| o.as_f64().unwrap().abs() > 1e-3), "{offset:?}");
    // … and the dataset's speed scale it compared the root velocity at: Stretch's top speed (0.6 m/s,
    // its wheels' limits) over a person's 1.5 m/s walking pace, below its height over 1.7 m (0.77).
    let scale = record["speed_scale"].as_f64().unwrap();
    assert!((0.39..0.41).contains(&scale), "speed scale {scale}");

    // The paper's comparison in its CI setting: the three baselines train for a few steps and every row
    // of the table is complete and finite.
    let (runs, cmp_dir) = (dir.join("baselines"), dir.join("compare"));
    let compare = ["--threads", "1", "eval", "--character", "stretch", "--checkpoint", &s(&ck), "--humans", "assets/motions", "--baselines", "--quick", "--runs", &s(&runs), "--out", &s(&cmp_dir)];
    let stdout = run(&compare);
    let systems = ["Dataset", "ACE", "ACE without cleanup", "Prior with random z", "NKN", "ACE w/o feature", "ACE w/o adversarial"];
    check_eval_csv(&cmp_dir, "stretch", &systems);
    for (system, slug) in [("NKN", "nkn"), ("ACE w/o feature", "ace-no-feature"), ("ACE w/o adversarial", "ace-no-adversarial")] {
        assert!(stdout.contains(&format!("{system}: trained in")), "{stdout}");
        assert!(runs.join(slug).join("prior.safetensors").is_file(), "{slug} has no prior");
    }
    let md = std::fs::read_to_string(cmp_dir.join("eval.md")).unwrap();
    assert!(md.contains("| ACE w/o adversarial |") && md.contains("ours / paper's"), "{md}");
    // A second run finds the baselines trained.
    let stdout = run(&compare);
    assert!(!stdout.contains("trained in"), "{stdout}");
    // Runs trained against another prior (here: its normalisation edited) are not scored as this
    // checkpoint's baselines, and are left as they are.
    let nkn_prior = runs.join("nkn/config.json");
    let original_prior = std::fs::read(&nkn_prior).unwrap();
    let mut record: Value = serde_json::from_slice(&original_prior).unwrap();
    record["mean"][0] = (record["mean"][0].as_f64().unwrap() + 0.5).into();
    let text = serde_json::to_vec_pretty(&record).unwrap();
    std::fs::write(&nkn_prior, &text).unwrap();
    let out = ace(&compare);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success() && err.contains(&s(&runs.join("nkn"))) && err.contains("another motion prior"), "{err}");
    assert_eq!(std::fs::read(&nkn_prior).unwrap(), text);
    std::fs::write(&nkn_prior, &original_prior).unwrap();
    // Nor are runs trained with other settings than this checkpoint gives them (a finished run is not
    // trained again): an ablation of another seed, an NKN of another cycle weight, an ablation of
    // another end-effector mapping, an NKN of another split of the human clips.
    let other = |v: &Value| -> Value {
        match v {
            Value::String(_) => "head".into(),
            _ => v.as_u64().map_or_else(|| (v.as_f64().unwrap() + 0.25).into(), |n| (n + 1).into()),
        }
    };
    for (slug, file, pointer, named) in [
        ("ace-no-adversarial", "ace.json", "/config/seed", "seed:"),
        ("nkn", "nkn.json", "/config/w_cyc", "w_cyc:"),
        ("ace-no-feature", "ace.json", "/correspondence/mapping/human/0", "end-effector mapping"),
        ("nkn", "nkn.json", "/human_split/held_out_fraction", "split of the human clips"),
    ] {
        let path = runs.join(slug).join(file);
        let original = std::fs::read(&path).unwrap();
        let mut run_record: Value = serde_json::from_slice(&original).unwrap();
        let entry = run_record.pointer_mut(pointer).unwrap_or_else(|| panic!("{file} has no {pointer}"));
        *entry = other(entry);
        std::fs::write(&path, serde_json::to_vec_pretty(&run_record).unwrap()).unwrap();
        let out = ace(&compare);
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(!out.status.success() && err.contains(&s(&runs.join(slug))) && err.contains(named), "{pointer}: {err}");
        std::fs::write(&path, &original).unwrap();
    }
    assert!(!run(&compare).contains("trained in"), "the restored runs are scored as they are");

    // A checkpoint of another character is refused with the directory named.
    let out = ace(&["retarget", "assets/motions/wave.bvh", "--character", "crab", "--checkpoint", &s(&ck), "--out", &s(&dir.join("x.glb"))]);
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains(&s(&ck)), "{err}");
    assert!(!dir.join("x.glb").exists(), "nothing written on error");
}

/// A profile that makes one of Spot's feet an arm keeps its list of end effectors, so the shipped
/// checkpoint ran on it (the foot lock let that foot slide: UFR 12 %). The checkpoint records its feet.
#[test]
fn a_profile_that_makes_a_foot_an_arm_is_refused_by_the_shipped_checkpoint() {
    let dir = fresh("profile-roles");
    let urdf = dir.join("spot.urdf");
    std::fs::copy(root().join("assets/characters/spot.urdf"), &urdf).unwrap();
    std::fs::write(dir.join("spot.profile.toml"), "feet = [\"fl_foot\", \"fr_foot\", \"rl_foot\"]\nmanipulators = [\"rr_foot\", \"gripper_tip\"]\n").unwrap();
    let ck = root().join("assets/checkpoints/spot");
    let glb = dir.join("walk.glb");
    for backend in ["rust", "tch"] {
        let out = ace(&["retarget", "assets/motions/walk.bvh", "--character", urdf.to_str().unwrap(), "--checkpoint", ck.to_str().unwrap(), "--backend", backend, "--out", glb.to_str().unwrap()]);
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(!out.status.success() && err.contains(ck.to_str().unwrap()) && err.contains("trained with 4 feet (fl_foot, fr_foot, rl_foot, rr_foot), and the character has 3"), "{backend}: {err}");
        assert!(!glb.exists());
    }
    // As the checkpoint was trained, it runs.
    std::fs::write(dir.join("spot.profile.toml"), "feet = [\"fl_foot\", \"fr_foot\", \"rl_foot\", \"rr_foot\"]\n").unwrap();
    run_ok(&["retarget", "assets/motions/walk.bvh", "--character", urdf.to_str().unwrap(), "--checkpoint", ck.to_str().unwrap(), "--out", glb.to_str().unwrap()]);
}

/// A creature whose model names a texture image that is not beside it (left behind when the model was
/// copied) retargeted the whole clip and then failed writing the output, naming the staged temporary.
/// It is refused before any work, saying what is missing and how to go on; `--animation-only` writes
/// the clip without the model's files.
#[test]
fn a_creature_missing_an_image_beside_it_is_refused_before_the_retarget() {
    let dir = fresh("missing-image");
    let glb = std::fs::read(root().join("assets/creatures/hound.glb")).unwrap();
    let (mut json, bin) = glb_chunks(&glb);
    std::fs::write(dir.join("hound.bin"), &glb[bin]).unwrap();
    json["buffers"][0]["uri"] = "hound.bin".into();
    json["images"] = serde_json::json!([{"uri": "fur.png"}]);
    let model = dir.join("hound.gltf");
    std::fs::write(&model, serde_json::to_vec(&json).unwrap()).unwrap();
    std::fs::copy(root().join("assets/creatures/hound.profile.toml"), dir.join("hound.profile.toml")).unwrap();
    let out = dir.join("walk.glb");
    let run = |extra: &[&str]| {
        let mut args = vec!["retarget", "assets/motions/walk.bvh", "--character", model.to_str().unwrap(), "--checkpoint", "assets/checkpoints/hound", "--out", out.to_str().unwrap()];
        args.extend(extra);
        ace(&args)
    };
    let o = run(&[]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(!o.status.success() && err.contains(&format!("cannot read {}, a file of the model", dir.join("fur.png").display())) && err.contains("--animation-only"), "{err}");
    assert!(!err.contains("ace-tmp") && !out.exists(), "{err}");
    let o = run(&["--animation-only"]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert!(out.exists());
}

/// `ace eval --baselines --runs` naming a file failed only once the clips were read and the first
/// baseline was to train; it is refused before any work.
#[test]
fn eval_runs_naming_a_file_is_refused_before_any_work() {
    let dir = fresh("runs-file");
    let runs = dir.join("runs.txt");
    std::fs::write(&runs, "notes").unwrap();
    let out = ace(&["eval", "--character", "spot", "--baselines", "--quick", "--runs", runs.to_str().unwrap(), "--out", dir.join("eval").to_str().unwrap()]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success() && err.contains(&format!("{}: refusing to write there: it is a file", runs.display())), "{err}");
    assert!(!err.contains("importing") && !dir.join("eval").exists(), "{err}");
    assert_eq!(std::fs::read_to_string(&runs).unwrap(), "notes");
}

/// `ace train` on a prior whose training stopped early learned on it without a word; it now warns,
/// and says nothing on a prior trained to the end.
#[test]
fn train_warns_of_a_part_trained_prior() {
    let dir = fresh("part-trained-prior");
    let (prior_cfg, ace_cfg, ck) = (dir.join("prior.toml"), dir.join("ace.toml"), dir.join("ck"));
    std::fs::write(&prior_cfg, TINY_PRIOR).unwrap();
    std::fs::write(&ace_cfg, TINY_ACE).unwrap();
    let s = |p: &Path| p.to_str().unwrap().to_string();
    run_ok(&["--threads", "1", "train-prior", "--character", "crab", "--frames", "3000", "--config", &s(&prior_cfg), "--checkpoint", &s(&ck)]);
    let train = || ace(&["--threads", "1", "train", "--character", "crab", "--config", &s(&ace_cfg), "--checkpoint", &s(&ck), "--humans", "assets/motions"]);
    let out = train();
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success() && !err.contains("stopped early"), "{err}");
    // As an interrupted `ace train-prior` leaves it: fewer steps done than configured.
    for f in ["ace.json", "generator.safetensors", "discriminator.safetensors"] {
        std::fs::remove_file(ck.join(f)).unwrap();
    }
    let mut record: Value = serde_json::from_slice(&std::fs::read(ck.join("config.json")).unwrap()).unwrap();
    record["step"] = 60.into();
    std::fs::write(ck.join("config.json"), serde_json::to_vec_pretty(&record).unwrap()).unwrap();
    let out = train();
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{err}");
    assert!(err.contains("warning: the motion prior in") && err.contains("trained 60 of its 120 steps: its training stopped early"), "{err}");
}

/// A copy of the shipped Spot checkpoint in `dir/ck` (`dir` emptied first) with `edit` applied to its
/// `ace.json`.
fn spot_checkpoint_edited(dir: &Path, edit: impl FnOnce(&mut Value)) -> PathBuf {
    let _ = std::fs::remove_dir_all(dir);
    let ck = dir.join("ck");
    std::fs::create_dir_all(&ck).unwrap();
    for e in std::fs::read_dir(root().join("assets/checkpoints/spot")).unwrap() {
        let e = e.unwrap();
        std::fs::copy(e.path(), ck.join(e.file_name())).unwrap();
    }
    let mut record: Value = serde_json::from_slice(&std::fs::read(ck.join("ace.json")).unwrap()).unwrap();
    edit(&mut record);
    std::fs::write(ck.join("ace.json"), serde_json::to_vec_pretty(&record).unwrap()).unwrap();
    ck
}

/// A checkpoint trained on a folder of one clip holds none out: `ace eval` said none of its "0
/// held-out clips" was in the folder it was trained on.
#[test]
fn eval_of_a_checkpoint_that_holds_out_no_clips_says_so() {
    let dir = tmp("eval-none-held-out");
    let ck = spot_checkpoint_edited(&dir, |record| record["human_split"]["held_out"] = serde_json::json!([]));
    let out = ace(&["eval", "--character", "spot", "--checkpoint", ck.to_str().unwrap(), "--out", dir.join("eval").to_str().unwrap(), "--seconds", "2"]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success() && err.contains(&format!("{}: the checkpoint holds out no clips", ck.display())), "{err}");
    assert!(!dir.join("eval").exists());
}

/// A checkpoint whose training stopped early (Ctrl-C, a job's time limit) ran in `ace retarget` as if
/// finished; the retarget now says how far it got and how to go on, and a finished one says nothing.
#[test]
fn a_part_trained_checkpoint_is_warned_of() {
    let dir = tmp("part-trained");
    let glb = dir.join("walk.glb");
    let retarget = |ck: &Path| {
        let out = ace(&["retarget", "assets/motions/walk.bvh", "--character", "spot", "--checkpoint", ck.to_str().unwrap(), "--out", glb.to_str().unwrap()]);
        assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
        String::from_utf8_lossy(&out.stderr).into_owned()
    };
    let mut steps = 0;
    let ck = spot_checkpoint_edited(&dir, |record| {
        steps = record["config"]["steps"].as_u64().unwrap();
        record["step"] = serde_json::json!(1200);
    });
    assert!(!retarget(&root().join("assets/checkpoints/spot")).contains("stopped early"));
    let err = retarget(&ck);
    assert!(err.contains(&format!("warning: the checkpoint's generator trained 1200 of its {steps} steps: its training stopped early")), "{err}");
}

#[test]
fn inspect_reports_the_body_plans_of_rigged_glb_creatures() {
    let Some(dir) = shared("creatures") else { return };
    for (file, legs) in [
        ("Fox/Fox.glb", 4),
        ("Quaternius_Wolf/Wolf.gltf", 4),
        ("Quaternius_Spider/Spider.glb", 8),
        ("Quaternius_TRex/t-rex.glb", 2),
        ("Quaternius_Snake/Snake.glb", 0),
    ] {
        let v = inspect_json(&dir.join(file));
        assert_eq!(v["kind"], "gltf", "{file}");
        assert_eq!(names(&v["feet"]).len(), legs, "{file}: {}", v["feet"]);
        assert_eq!(v["dof"].as_u64().unwrap() as usize, names(&v["dof_names"]).len());
        for k in ["links", "manipulators", "head", "standing_height_m", "skins", "animations", "joints_at_rest"] {
            assert!(!v[k].is_null(), "{file}: no {k}");
        }
    }
    let fox = inspect_json(&dir.join("Fox/Fox.glb"));
    assert_eq!(fox["animations"].as_array().unwrap().len(), 3);
    // The spine above the front legs bends with the body; the Wolf's ears stay at rest.
    assert!(names(&fox["dof_names"]).contains(&"b_Spine01_02:yaw".to_string()), "{}", fox["dof_names"]);
    assert!(!names(&fox["joints_at_rest"]).contains(&"b_Spine01_02".to_string()), "{}", fox["joints_at_rest"]);
    let wolf = inspect_json(&dir.join("Quaternius_Wolf/Wolf.gltf"));
    assert!(names(&wolf["joints_at_rest"]).contains(&"Ear1.L".to_string()), "{}", wolf["joints_at_rest"]);
    // The Snake's head is the front of its body, not its tongue.
    assert_eq!(inspect_json(&dir.join("Quaternius_Snake/Snake.glb"))["head"], "Head");
    // A glTF without a skin is refused with the file and the problem named.
    let bare = tmp("creature-bad").join("bare.gltf");
    std::fs::create_dir_all(bare.parent().unwrap()).unwrap();
    std::fs::write(&bare, r#"{"asset": {"version": "2.0"}, "nodes": [{"name": "a"}]}"#).unwrap();
    let out = ace(&["inspect", bare.to_str().unwrap()]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success() && err.contains("bare.gltf") && err.contains("no skin"), "{err}");
}

#[test]
fn a_rigged_creature_trains_and_retargets_end_to_end() {
    let Some(fox) = shared("creatures/Fox/Fox.glb") else { return };
    let dir = tmp("creature");
    let f = fox.to_str().unwrap().to_string();
    let (ck, stdout) = tiny_checkpoint(&dir, &f);
    let s = |p: &Path| p.to_str().unwrap().to_string();
    let run = run_ok;
    // The fox's paws are matched to the human's hands and feet.
    assert!(stdout.contains("b_LeftHand_011") && stdout.contains("b_LeftFoot02_018"), "{stdout}");
    // The checkpoint names the character file and its checksum.
    let record: Value = serde_json::from_str(&std::fs::read_to_string(ck.join("ace.json")).unwrap()).unwrap();
    let file = &record["provenance"]["character_file"];
    assert!(file["file"].as_str().unwrap().ends_with("Fox.glb"), "{record}");
    assert_eq!(file["bytes"].as_u64().unwrap(), std::fs::metadata(&fox).unwrap().len());

    let glb = dir.join("walk.glb");
    let out = ace(&["--threads", "1", "retarget", "assets/motions/walk.bvh", "--character", &f, "--checkpoint", &s(&ck), "--out", &s(&glb)]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{err}");
    assert!(!err.contains("is not the character file"), "the file trained with is not another: {err}");
    // A copy of the fox (same name, another folder) with one byte of its texture changed has the same
    // bones and size: it retargets, with a warning that it is not the file the checkpoint was trained
    // with (`ace eval` says the same).
    let edited = dir.join("edited/Fox.glb");
    std::fs::create_dir_all(edited.parent().unwrap()).unwrap();
    std::fs::write(&edited, with_a_texture_byte_flipped(&std::fs::read(&fox).unwrap())).unwrap();
    let out = ace(&["--threads", "1", "retarget", "assets/motions/walk.bvh", "--character", &s(&edited), "--checkpoint", &s(&ck), "--out", &s(&dir.join("edited.glb"))]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{err}");
    assert!(err.contains("warning: ") && err.contains("edited/Fox.glb is not the character file") && err.contains(file["fnv1a64"].as_str().unwrap()), "{err}");
    // `ace eval` on a creature: a complete table of finite values, and the same warning for the copy.
    let eval_dir = dir.join("eval");
    let out = ace(&["--threads", "1", "eval", "--character", &s(&edited), "--checkpoint", &s(&ck), "--humans", "assets/motions", "--seconds", "2", "--out", &s(&eval_dir)]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{err}");
    assert!(err.contains("edited/Fox.glb is not the character file"), "{err}");
    check_eval_csv(&eval_dir, "Fox", &["Dataset", "ACE", "ACE without cleanup", "Prior with random z"]);
    let frames = inspect_json(&root().join("assets/motions/walk.bvh"))["frames"].as_u64().unwrap() as usize;
    let csv = std::fs::read_to_string(glb.with_extension("csv")).unwrap();
    assert_eq!(csv.lines().count(), frames + 1);
    let m: Value = serde_json::from_str(&std::fs::read_to_string(glb.with_extension("metrics.json")).unwrap()).unwrap();
    assert!(m["ufr"]["rates"]["ufr"].as_f64().is_some_and(f64::is_finite), "{m}");
    assert_eq!(m["frames"], frames);
    validate_gltf(&glb);

    // The clip is written onto the fox's own model: its mesh, skin, material and texture, with the clip
    // as its one animation (a key per frame); --keep-animations keeps its own three clips before it;
    // --animation-only writes the skeleton, its skin and the clip alone.
    let (source, _) = open(&fox).unwrap();
    let channel_keys = |doc: &ace::models::gltf::Document, glb: &Path| {
        let (_, buffers) = open(glb).unwrap();
        let a = doc.animations().last().unwrap();
        assert_eq!(a.name(), Some("walk"));
        a.channels().next().unwrap().reader(|b| buffers.get(b.index()).map(Vec::as_slice)).read_inputs().unwrap().count()
    };
    let (doc, _) = open(&glb).unwrap();
    assert_eq!(doc.animations().count(), 1);
    assert_eq!(channel_keys(&doc, &glb), frames);
    for (what, n, m) in [("meshes", doc.meshes().count(), source.meshes().count()), ("skins", doc.skins().count(), 1), ("images", doc.images().count(), 1), ("nodes", doc.nodes().count(), source.nodes().count())] {
        assert_eq!(n, m, "{what}");
    }
    let kept = dir.join("walk_kept.glb");
    run(&["--threads", "1", "retarget", "assets/motions/walk.bvh", "--character", &f, "--checkpoint", &s(&ck), "--out", &s(&kept), "--keep-animations"]);
    let (doc, _) = open(&kept).unwrap();
    let names: Vec<_> = doc.animations().map(|a| a.name().unwrap_or_default().to_owned()).collect();
    assert_eq!(names, ["Survey", "Walk", "Run", "walk"]);
    assert_eq!(doc.meshes().count(), 1);
    validate_gltf(&kept);
    let only = dir.join("walk_only.glb");
    run(&["--threads", "1", "retarget", "assets/motions/walk.bvh", "--character", &f, "--checkpoint", &s(&ck), "--out", &s(&only), "--animation-only"]);
    let (doc, _) = open(&only).unwrap();
    assert_eq!((doc.meshes().count(), doc.images().count(), doc.skins().count(), doc.animations().count()), (0, 0, 1, 1));
    assert_eq!(channel_keys(&doc, &only), frames);
    validate_gltf(&only);
    for ext in ["json", "csv", "metrics.json"] {
        assert!(only.with_extension(ext).is_file(), "the {ext} output stays");
    }

    // The two options are for glTF creatures only.
    for flag in ["--keep-animations", "--animation-only"] {
        let bad = dir.join("spot.glb");
        let out = ace(&["retarget", "assets/motions/walk.bvh", "--character", "spot", "--out", &s(&bad), flag]);
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(!out.status.success() && err.contains(flag) && err.contains("URDF"), "{err}");
        assert!(!bad.exists());
    }
}

/// A glTF binary with one byte in the middle of its first image changed: the same scene, another file.
fn with_a_texture_byte_flipped(glb: &[u8]) -> Vec<u8> {
    let (json, bin) = glb_chunks(glb);
    let view = &json["bufferViews"][json["images"][0]["bufferView"].as_u64().unwrap() as usize];
    let (offset, len) = (view["byteOffset"].as_u64().unwrap_or(0) as usize, view["byteLength"].as_u64().unwrap() as usize);
    let mut out = glb.to_vec();
    out[bin.start + offset + len / 2] ^= 0x10;
    out
}

/// A glTF binary's JSON and the byte range of its binary chunk's data.
fn glb_chunks(glb: &[u8]) -> (Value, std::ops::Range<usize>) {
    let n = u32::from_le_bytes(glb[12..16].try_into().unwrap()) as usize;
    let json: Value = serde_json::from_slice(&glb[20..20 + n]).unwrap();
    let bin_len = glb.get(20 + n..24 + n).map_or(0, |b| u32::from_le_bytes(b.try_into().unwrap()) as usize);
    (json, 28 + n..28 + n + bin_len)
}

/// Node names of a glTF binary.
fn glb_node_names(glb: &Path) -> Vec<String> {
    let (json, _) = glb_chunks(&std::fs::read(glb).unwrap());
    json["nodes"].as_array().unwrap().iter().filter_map(|v| v["name"].as_str().map(String::from)).collect()
}

#[test]
fn retarget_without_the_cleanup_or_the_human_writes_what_it_says() {
    let dir = fresh("cli-retarget-flags");
    let s = |p: &Path| p.to_str().unwrap().to_string();
    let write = |name: &str, extra: &[&str]| {
        let glb = dir.join(format!("{name}.glb"));
        let mut args = vec!["--threads", "1", "retarget", "assets/motions/walk.bvh", "--character", "spot"];
        let out = s(&glb);
        args.extend(["--out", out.as_str()]);
        args.extend(extra);
        run_ok(&args);
        let metrics: Value = serde_json::from_str(&std::fs::read_to_string(glb.with_extension("metrics.json")).unwrap()).unwrap();
        let trajectory = std::fs::read_to_string(glb.with_extension("json")).unwrap();
        (glb, metrics, trajectory)
    };
    let ufr_of = |m: &Value| m["ufr"]["rates"]["ufr"].as_f64().unwrap();
    let heading_of = |m: &Value| m["following"]["heading_error"].as_f64().unwrap();
    let (glb, metrics, trajectory) = write("default", &[]);
    let (raw_glb, raw_metrics, raw_trajectory) = write("raw", &["--no-cleanup"]);
    let (alone_glb, alone_metrics, alone_trajectory) = write("alone", &["--no-human"]);
    let (ufr, raw_ufr, alone_ufr) = (ufr_of(&metrics), ufr_of(&raw_metrics), ufr_of(&alone_metrics));
    // The cleanup is what keeps the feet planted: without it the networks' feet slide.
    assert!(ufr <= 0.03 && raw_ufr > 0.5, "UFR {ufr} with the cleanup, {raw_ufr} without");
    assert_ne!(trajectory, raw_trajectory, "the cleanup changed no pose");
    // Single steps left out: without the foot lock the feet slide; without the steering Spot strays
    // from the person's heading on the walk (the person turns 20° left) as its networks do.
    let unlocked_ufr = ufr_of(&write("unlocked", &["--without", "foot-lock"]).1);
    assert!(unlocked_ufr > 0.3, "UFR {unlocked_ufr} without the foot lock");
    let unsteered = write("unsteered", &["--without", "heading-steering,effector-hold"]).1;
    let unsteered_ufr = ufr_of(&unsteered);
    assert!(unsteered_ufr <= 0.03, "the other steps still run: UFR {unsteered_ufr}");
    let (steered, unsteered) = (heading_of(&metrics), heading_of(&unsteered));
    assert!(steered <= 30.0 && unsteered > 45.0, "heading error {steered}° steered, {unsteered}° not");
    let both_out = s(&dir.join("both.glb"));
    let both = ace(&["retarget", "assets/motions/walk.bvh", "--character", "spot", "--out", &both_out, "--no-cleanup", "--without", "foot-lock"]);
    assert!(!both.status.success() && String::from_utf8_lossy(&both.stderr).contains("cannot be used with"));
    // The human skeleton is beside the robot unless left out; the robot's motion is the same.
    let (with, without) = (glb_node_names(&glb), glb_node_names(&alone_glb));
    for names in [&with, &glb_node_names(&raw_glb)] {
        assert!(names.iter().any(|n| n == "human") && names.iter().any(|n| n == "right_hand"), "{names:?}");
    }
    assert!(!without.iter().any(|n| n == "human" || n == "pelvis" || n == "right_hand"), "{without:?}");
    assert!(without.iter().any(|n| n == "gripper_tip"), "{without:?}");
    assert_eq!(alone_trajectory, trajectory);
    assert_eq!(alone_ufr, ufr);
    validate_gltf(&alone_glb);
    validate_gltf(&raw_glb);
}

/// Mean of `column` over the rows of an `ace_losses.csv` after step `after`.
fn mean_loss_after(csv: &Path, column: &str, after: usize) -> f64 {
    let text = std::fs::read_to_string(csv).unwrap();
    let mut lines = text.lines();
    let header: Vec<&str> = lines.next().unwrap().split(',').collect();
    let (step, col) = (0, header.iter().position(|h| *h == column).unwrap());
    let values: Vec<f64> = lines
        .map(|l| l.split(',').map(|v| v.parse::<f64>().unwrap()).collect::<Vec<_>>())
        .filter(|r| r[step] as usize > after)
        .map(|r| r[col])
        .collect();
    assert!(!values.is_empty(), "no rows after step {after} in {}", csv.display());
    values.iter().sum::<f64>() / values.len() as f64
}

/// "Retrain briefly": the fine-tuned generator goes where the changed weights ask, and the checkpoint
/// it starts from is left exactly as it was.
#[test]
fn fine_tuning_follows_the_changed_weights_and_leaves_the_source_intact() {
    use ace::fine_tune::{FineTune, fine_tune};
    let dir = tmp("fine-tune");
    // A generator that learns fast enough to show the direction in a few dozen steps.
    let (ck, _) = tiny_checkpoint_with(&dir, "spot", "generator_lr = 0.003\n");
    let source = folder_bytes(&ck);
    let steps = 60;
    let run = |name: &str, w_adv: f64, w_fea: f64| {
        let to = dir.join(name);
        let ft = FineTune {
            urdf: root().join("assets/characters/spot.urdf"),
            from: ck.clone(),
            to: to.clone(),
            steps,
            w_adv,
            w_fea,
            feature_weights: Default::default(),
            end_effector_mapping: None,
            humans: Some(root().join("assets/motions")),
        };
        let mut stages = 0;
        fine_tune(&ft, &mut |_| stages += 1).unwrap();
        assert!(stages > steps, "{stages} stages reported");
        let record: Value = serde_json::from_str(&std::fs::read_to_string(to.join("ace.json")).unwrap()).unwrap();
        assert_eq!(record["step"], 40 + steps, "the tiny run's 40 steps and the new ones");
        assert_eq!(record["config"]["w_adv"], w_adv);
        assert_eq!(record["config"]["w_fea"], w_fea);
        mean_loss_after(&to.join("ace_losses.csv"), "fea", 40 + steps / 2)
    };
    // Only the feature loss against only the adversarial one: the first ends closer to the human.
    let feature_only = run("feature-only", 0.0, 1.0);
    let adversarial_only = run("adversarial-only", 1.0, 0.0);
    assert!(
        feature_only < 0.9 * adversarial_only,
        "L_fea {feature_only} with w_adv = 0 against {adversarial_only} with w_fea = 0"
    );
    assert!(folder_bytes(&ck) == source, "fine-tuning changed the checkpoint it started from");
    // A folder that already holds a checkpoint is refused, and left as it was.
    let again = FineTune {
        urdf: root().join("assets/characters/spot.urdf"),
        from: ck.clone(),
        to: dir.join("feature-only"),
        steps,
        w_adv: 1.0,
        w_fea: 1.0,
        feature_weights: Default::default(),
        end_effector_mapping: None,
        humans: Some(root().join("assets/motions")),
    };
    let before = folder_bytes(&dir.join("feature-only"));
    let err = format!("{:#}", fine_tune(&again, &mut |_| {}).unwrap_err());
    assert!(err.contains("already holds a checkpoint"), "{err}");
    assert!(folder_bytes(&dir.join("feature-only")) == before);
}

/// The numbers of a trajectory CSV (header left out), row by row.
fn csv_numbers(path: &Path) -> Vec<Vec<f64>> {
    let text = std::fs::read_to_string(path).unwrap();
    text.lines().skip(1).map(|l| l.split(',').map(|v| v.parse().unwrap()).collect()).collect()
}

#[test]
fn retarget_runs_the_networks_in_pure_rust_and_with_libtorch_alike() {
    let dir = fresh("cli-retarget-backend");
    let write = |name: &str, extra: &[&str]| {
        let glb = dir.join(format!("{name}.glb"));
        let out = glb.to_str().unwrap().to_string();
        let mut args = vec!["--threads", "1", "retarget", "assets/motions/wave.bvh", "--character", "spot", "--out", &out];
        args.extend(extra);
        run_ok(&args);
        csv_numbers(&glb.with_extension("csv"))
    };
    let rust = write("rust", &[]);
    let explicit = write("rust-explicit", &["--backend", "rust"]);
    let tch = write("tch", &["--backend", "tch"]);
    assert_eq!(rust, explicit, "pure Rust is the default");
    assert_eq!(rust.len(), tch.len());
    assert!(rust.len() > 100 && rust[0].len() > 10);
    // The same commands to float rounding: base velocities, height and joint positions.
    let worst = rust.iter().flatten().zip(tch.iter().flatten()).map(|(a, b)| (a - b).abs()).fold(0.0, f64::max);
    assert!(worst < 1e-3, "the backends' trajectories differ by {worst}");
    // …but from two computations: libtorch's float rounding is not gemm's.
    assert!(worst > 0.0, "--backend tch wrote the pure-Rust trajectory");
    let out = ace(&["retarget", "assets/motions/wave.bvh", "--character", "spot", "--out", "x.glb", "--backend", "onnx"]);
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("rust, tch"), "{}", String::from_utf8_lossy(&out.stderr));
}

/// The shipped Spot (its URDF and checkpoint, on the pure-Rust networks), its scorer, and a bundled
/// clip (`assets/motions/<name>.bvh`).
struct ShippedSpot {
    tree: ace::models::kinematics::KinematicTree,
    morph: ace::models::morphology::Morphology,
    networks: ace::retarget::Networks,
    scorer: ace::scoring::Scorer,
    clip: ace::models::human::HumanClip,
}

fn shipped_spot_on(clip: &str) -> ShippedSpot {
    use ace::retarget::{Backend, Networks, shipped_checkpoint};
    let (tree, morph) = ace::models::morphology::load_character(&root().join("assets/characters/spot.urdf")).unwrap();
    let dir = shipped_checkpoint("spot");
    let networks = Networks::load(&dir, Backend::Rust).unwrap();
    let scorer = ace::scoring::Scorer::new(networks.record(), networks.character(), &dir).unwrap();
    let path = root().join("assets/motions").join(format!("{clip}.bvh"));
    let clip = ace::models::human::HumanClip::from_bvh_file(&path, &Default::default()).unwrap();
    ShippedSpot { tree, morph, networks, scorer, clip }
}

/// Without the cleanup the states carry the generator's own predicted end-effector positions, which
/// disagree with its joints on the shipped Spot's gripper; what is scored is what is shown, the joints'
/// (`Scorer::shown_psi`), as the cleanup's states already are.
#[test]
fn scores_without_the_cleanup_are_of_the_joints_shown() {
    use ace::models::character_state::{CharacterLayout, character_state};
    use ace::models::cleanup::Cleanup;
    use ace::models::features::{FeatureLayout, character_features, human_body_length, mean_feature_loss};
    use ace::models::human_set::HumanRow;
    use ace::retarget::retarget_and_score;

    let ShippedSpot { tree, morph, mut networks, scorer, clip } = shipped_spot_on("wave");
    let human: Vec<HumanRow> = clip.states().into_iter().map(|s| s.0).collect();
    let human_psi = scorer.human_psi(&human, scorer.human_body(human_body_length(&clip)));
    let layout = CharacterLayout::new(&tree, &morph);
    let record = networks.record().clone();
    let mapping = &record.correspondence.mapping;
    let body = record.body_lengths.character;
    for cleanup in [Cleanup::NONE, Cleanup::default()] {
        networks.set_cleanup(cleanup);
        let scored = retarget_and_score(&networks, &scorer, &tree, &morph, &clip).unwrap();
        let m = &scored.motion;
        // Ψ by hand: the states with the poses' own end-effector positions.
        let joints: Vec<Vec<f32>> = m
            .states
            .iter()
            .zip(&m.poses)
            .map(|(x, p)| {
                let mut x = x.clone();
                let shown = character_state(&tree, &morph, p, p, 1.0 / 30.0);
                x[layout.ee_positions()].copy_from_slice(&shown[layout.ee_positions()]);
                character_features(&layout, &x, body, mapping)
            })
            .collect();
        let predicted = scorer.character_psi(&m.states);
        let weights = record.config.feature_weights;
        let features = FeatureLayout::new(mapping);
        let of = |psi: &[Vec<f32>]| mean_feature_loss(&features, psi, &human_psi, &weights);
        let got = scored.report.feature_loss.unwrap();
        assert!((got - of(&joints)).abs() < 1e-5, "{cleanup:?}: L_fea {got} against {} from the joints", of(&joints));
        if cleanup == Cleanup::NONE {
            let gap = (of(&predicted) - of(&joints)).abs();
            // A hundred times the tolerance above: the check tells the joints from the predictions.
            assert!(gap > 1e-3, "the predicted entries agree with the joints after all ({gap})");
        }
    }
}

/// The frames a timeline marks as popping are those of every swing of 1–2 frames, found here by hand
/// from the feet's contacts (the UFR's band): on the shipped Spot's raw networks over the bundled walk,
/// which pop, and after the cleanup, which does not.
#[test]
fn the_flags_mark_the_frames_of_popping_swings() {
    use ace::models::cleanup::Cleanup;
    use ace::models::metrics::{FootTracks, UfrConfig};
    use ace::retarget::retarget_and_score;

    let ShippedSpot { tree, morph, mut networks, scorer, clip } = shipped_spot_on("walk");
    for (cleanup, pops) in [(Cleanup::NONE, true), (Cleanup::default(), false)] {
        networks.set_cleanup(cleanup);
        let scored = retarget_and_score(&networks, &scorer, &tree, &morph, &clip).unwrap();
        let poses = &scored.motion.poses;
        let band = UfrConfig::for_character(&tree, &morph).contact_height;
        let tracks = FootTracks::from_poses(&tree, &morph, poses, band);
        let mut want = vec![false; poses.len()];
        for k in 0..tracks.feet {
            let contact: Vec<bool> = (0..poses.len()).map(|t| tracks.contact[t * tracks.feet + k]).collect();
            let mut last = None;
            for t in (0..poses.len()).filter(|&t| contact[t]) {
                if let Some(l) = last.filter(|&l: &usize| t - l - 1 <= 2 && t - l > 1) {
                    want[l + 1..t].iter_mut().for_each(|f| *f = true);
                }
                last = Some(t);
            }
        }
        let flags = &scored.flags;
        assert_eq!(flags.pops, want, "{cleanup:?}");
        assert_eq!(flags.pops.iter().any(|&f| f), pops, "{cleanup:?}: {} popping frames", want.iter().filter(|&&f| f).count());
        assert_eq!(flags.ufr.len(), poses.len());
        assert_eq!(scored.report.gait.as_ref().unwrap().pops > 0, pops, "{cleanup:?}");
    }
}
