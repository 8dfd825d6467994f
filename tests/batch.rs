//! `ace retarget FOLDER --out DIR`: a folder of real mocap (nested, with a broken clip among them)
//! onto the shipped Spot, in parallel.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

use serde_json::Value;

mod common;
use common::{folder_bytes, root, shared};

fn ace(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_ace")).args(args).current_dir(root()).output().expect("running ace")
}

fn fresh(name: &str) -> PathBuf {
    let d = Path::new(env!("CARGO_TARGET_TMPDIR")).join("batch").join(name);
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

/// Four real clips of three skeleton conventions in nested folders, and a clip cut off in its header,
/// in a folder of the test's own (`name`): the tests run in parallel.
fn library(name: &str) -> Option<PathBuf> {
    let lib = fresh(name);
    let clips = [
        ("bandai_namco/dataset-1_walk_normal_002.bvh", "walks/bandai/walk.bvh"),
        ("bandai_namco/dataset-2_wave-left-hand_active_011.bvh", "gestures/wave.bvh"),
        ("xia_style/neutral_16_000.bvh", "walks/xia/neutral.BVH"),
        ("cmu_daz/02_03.bvh", "run.bvh"),
    ];
    for (from, to) in clips {
        let src = shared(&format!("human/{from}"))?;
        let dst = lib.join(to);
        std::fs::create_dir_all(dst.parent().unwrap()).unwrap();
        std::fs::copy(src, dst).unwrap();
    }
    let whole = std::fs::read_to_string(lib.join("run.bvh")).unwrap();
    std::fs::write(lib.join("gestures/broken.bvh"), &whole[..whole.len() / 50]).unwrap();
    std::fs::write(lib.join("notes.txt"), "not a clip").unwrap();
    // A clip whose link leads nowhere fails; the metadata a Mac leaves beside each clip is skipped.
    std::os::unix::fs::symlink(lib.join("moved-away.bvh"), lib.join("walks/gone.bvh")).unwrap();
    std::fs::write(lib.join("gestures/._wave.bvh"), b"\0\x05\x16\x07\0\x02\0\0Mac OS X").unwrap();
    Some(lib)
}

#[test]
fn a_folder_of_clips_is_retargeted_clip_by_clip_and_a_broken_one_is_listed() {
    let Some(lib) = library("library-run") else { return };
    let out = fresh("out");
    let o = ace(&["retarget", lib.to_str().unwrap(), "--character", "spot", "--out", out.to_str().unwrap(), "--jobs", "2"]);
    let stderr = String::from_utf8_lossy(&o.stderr);
    // The broken clip fails the command, naming the file; the others are written.
    assert!(!o.status.success());
    assert!(stderr.contains("broken.bvh") && stderr.contains("2 of 6 clips failed"), "{stderr}");
    for rel in ["walks/bandai/walk", "gestures/wave", "walks/xia/neutral", "run"] {
        for ext in ["glb", "json", "csv", "metrics.json"] {
            let p = out.join(format!("{rel}.{ext}"));
            assert!(p.is_file(), "{} missing; stderr: {stderr}", p.display());
        }
    }
    assert!(!out.join("gestures/broken.glb").exists());
    let summary: Value = serde_json::from_slice(&std::fs::read(out.join("summary.json")).unwrap()).unwrap();
    assert_eq!(summary["clips"], 6);
    let done = summary["done"].as_array().unwrap();
    assert_eq!(done.len(), 4);
    let failed = summary["failed"].as_array().unwrap();
    assert_eq!(failed.len(), 2);
    assert_eq!(failed[0]["clip"], "gestures/broken.bvh");
    // Named once (it was "…/broken.bvh: …/broken.bvh, line …").
    let error = failed[0]["error"].as_str().unwrap();
    assert_eq!(error.matches("broken.bvh").count(), 1, "{error}");
    // The system's reason once (it was "…: cannot read: No such file or directory (os error 2): No such
    // file or directory (os error 2)").
    assert_eq!(failed[1]["clip"], "walks/gone.bvh");
    let error = failed[1]["error"].as_str().unwrap();
    assert_eq!(error.matches("No such file or directory").count(), 1, "{error}");
    // Each clip's frames and metrics are those its own .metrics.json holds.
    let frames: u64 = done.iter().map(|d| d["frames"].as_u64().unwrap()).sum();
    assert_eq!(summary["frames"].as_u64().unwrap(), frames);
    for d in done {
        let glb = PathBuf::from(d["glb"].as_str().unwrap());
        let m: Value = serde_json::from_slice(&std::fs::read(glb.with_extension("metrics.json")).unwrap()).unwrap();
        assert_eq!(m["frames"], d["frames"]);
        assert!(d["frames"].as_u64().unwrap() >= 19, "{d}");
        assert_eq!(d["over_velocity"], m["joint_limits"]["over_velocity"], "{d}");
    }
    assert!(done.iter().any(|d| d["pops"].as_f64().is_some()), "Spot's feet swing in some clip");

    // The same bytes with one worker, and as `ace retarget CLIP` writes the clip alone.
    let one = fresh("out-one-job");
    let o1 = ace(&["retarget", lib.to_str().unwrap(), "--character", "spot", "--out", one.to_str().unwrap(), "--jobs", "1"]);
    assert!(!o1.status.success());
    let without_summary = |d: &Path| folder_bytes(d).into_iter().filter(|(n, _)| n != "summary.json").collect::<Vec<_>>();
    let (a, b) = (without_summary(&out), without_summary(&one));
    assert_eq!(a.len(), 16);
    assert!(a == b, "the outputs depend on the number of workers");
    let single = fresh("single").join("wave.glb");
    let clip = lib.join("gestures/wave.bvh");
    let s = ace(&["retarget", clip.to_str().unwrap(), "--character", "spot", "--out", single.to_str().unwrap()]);
    assert!(s.status.success(), "{}", String::from_utf8_lossy(&s.stderr));
    for ext in ["glb", "json", "csv", "metrics.json"] {
        assert_eq!(
            std::fs::read(single.with_extension(ext)).unwrap(),
            std::fs::read(out.join(format!("gestures/wave.{ext}"))).unwrap(),
            "{ext} differs from a single retarget"
        );
    }
}

#[test]
fn a_folder_run_refuses_outputs_it_cannot_write_before_any_work() {
    let Some(lib) = library("library-refused") else { return };
    let before = folder_bytes(&lib);
    let cases: [(Vec<String>, &str); 4] = [
        // Inside the input folder: it would write among the clips.
        (vec!["--out".into(), lib.join("out").to_string_lossy().into()], "inside the folder of input clips"),
        // A file name where a folder is meant.
        (vec!["--out".into(), lib.join("../x.glb").to_string_lossy().into()], "is a folder"),
        (vec!["--out".into(), fresh("zero").to_string_lossy().into(), "--jobs".into(), "0".into()], "invalid value '0' for '--jobs <JOBS>'"),
        // An empty folder.
        (vec!["--out".into(), fresh("never").to_string_lossy().into()], "no .bvh files"),
    ];
    for (i, (extra, expect)) in cases.into_iter().enumerate() {
        let input = if i == 3 { fresh("empty") } else { lib.clone() };
        let mut args = vec!["retarget".to_string(), input.to_string_lossy().into(), "--character".into(), "spot".into()];
        args.extend(extra);
        let args: Vec<&str> = args.iter().map(String::as_str).collect();
        let o = ace(&args);
        let stderr = String::from_utf8_lossy(&o.stderr);
        assert!(!o.status.success() && stderr.contains(expect), "{args:?}: {stderr}");
    }
    assert!(folder_bytes(&lib) == before, "the input folder changed");
    assert!(!lib.join("out").exists());
    // --jobs with a single clip is a mistake worth saying.
    let clip = lib.join("run.bvh");
    let o = ace(&["retarget", clip.to_str().unwrap(), "--character", "spot", "--out", "/tmp/x.glb", "--jobs", "2"]);
    assert!(!o.status.success() && String::from_utf8_lossy(&o.stderr).contains("--jobs is for a folder"));
}
