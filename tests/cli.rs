//! The `ace` binary as a user runs it: `inspect` on bundled and never-seen files, `demo`, bad input.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

use serde_json::Value;

fn root() -> &'static Path {
    Path::new(env!("CARGO_MANIFEST_DIR"))
}

fn shared(rel: &str) -> Option<PathBuf> {
    let p = root().join("../shared/data").join(rel);
    if p.exists() {
        return Some(p);
    }
    if std::env::var_os("ACE_ALLOW_MISSING_DATA").is_some() {
        eprintln!("skipping: {} is missing", p.display());
        return None;
    }
    panic!("{} is missing: the shared data must stand beside the project (or set ACE_ALLOW_MISSING_DATA=1)", p.display());
}

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

#[test]
fn demo_writes_summary_and_picture() {
    let out_dir = Path::new(env!("CARGO_TARGET_TMPDIR")).join("cli-demo");
    let _ = std::fs::remove_dir_all(&out_dir);
    let out = ace(&["demo", "--out", out_dir.to_str().unwrap()]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let summary: Value = serde_json::from_str(&std::fs::read_to_string(out_dir.join("summary.json")).unwrap()).unwrap();
    assert_eq!(summary["clip"]["kind"], "bvh");
    assert_eq!(summary["character"]["kind"], "urdf");
    let img = image::open(out_dir.join("scene.png")).unwrap().to_rgb8();
    assert_eq!(img.dimensions(), (1280, 720));
    // Something other than the background was drawn: the character's orange and the human's blue.
    let orange = img.pixels().filter(|p| p.0 == [214, 140, 30]).count();
    let blue = img.pixels().filter(|p| p.0[2] == 235 && p.0[0] < 200).count();
    assert!(orange > 500 && blue > 500, "orange {orange}, blue {blue}");
}
