//! The `ace` binary against a careless or hostile user: it never writes over a file it read, never
//! leaves a partial output set, checks every bound before working, and names the file and the problem.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::process::{Command, Output};
use std::time::{Duration, Instant};

use serde_json::Value;

mod common;
use common::{root, shared};

fn ace(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_ace"))
        .args(args)
        .current_dir(root())
        .output()
        .expect("running ace")
}

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

/// An empty scratch folder.
fn scratch(name: &str) -> PathBuf {
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR"))
        .join("reliability-cli")
        .join(name);
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

fn s(p: &Path) -> String {
    p.to_str().unwrap().to_string()
}

/// Every file below `dir` with its bytes.
fn snapshot(dir: &Path) -> BTreeMap<PathBuf, Vec<u8>> {
    let mut out = BTreeMap::new();
    let mut stack = vec![dir.to_path_buf()];
    while let Some(d) = stack.pop() {
        for e in std::fs::read_dir(&d).unwrap() {
            let p = e.unwrap().path();
            if p.is_dir() {
                stack.push(p);
            } else {
                out.insert(p.clone(), std::fs::read(&p).unwrap());
            }
        }
    }
    out
}

fn copy_dir(from: &Path, to: &Path) {
    std::fs::create_dir_all(to).unwrap();
    for e in std::fs::read_dir(from).unwrap() {
        let p = e.unwrap().path();
        std::fs::copy(&p, to.join(p.file_name().unwrap())).unwrap();
    }
}

#[test]
fn retarget_never_writes_over_its_inputs() {
    let dir = scratch("guard");
    let ck = dir.join("ck");
    copy_dir(&root().join("assets/checkpoints/stretch"), &ck);
    let clip = dir.join("walk.bvh");
    std::fs::copy(root().join("assets/motions/walk.bvh"), &clip).unwrap();
    // Into the checkpoint directory (`ace.json` would become the trajectory), onto the clip itself, and
    // onto the clip through a hard link.
    let link = dir.join("link.glb");
    std::fs::hard_link(&clip, &link).unwrap();
    let before_link = snapshot(&dir);
    for (out, expected) in [
        (ck.join("ace.glb"), "is inside the checkpoint directory"),
        (clip.clone(), "it is the input clip"),
        (link.clone(), "it is the input clip"),
        (clip.with_extension("glb"), ""), // beside the clip: allowed
    ] {
        let o = ace(&[
            "--threads",
            "1",
            "retarget",
            &s(&clip),
            "--character",
            "stretch",
            "--checkpoint",
            &s(&ck),
            "--out",
            &s(&out),
        ]);
        if expected.is_empty() {
            assert!(o.status.success(), "{}", stderr(&o));
            continue;
        }
        assert!(!o.status.success(), "{}: written", out.display());
        let e = stderr(&o);
        assert!(
            e.contains(&format!("error: {}: refusing to write there", out.display())) && e.contains(expected),
            "{e}"
        );
        assert_eq!(snapshot(&dir), before_link, "{}: a file changed", out.display());
    }
    // The trajectory beside the clip is `walk.json`: the clip, the checkpoint and the link are intact.
    let after = snapshot(&dir);
    for (p, bytes) in &before_link {
        assert_eq!(after.get(p), Some(bytes), "{} changed", p.display());
    }
}

#[test]
fn training_refuses_a_config_inside_its_outputs() {
    let dir = scratch("train-guard");
    let ck = dir.join("ck");
    std::fs::create_dir_all(&ck).unwrap();
    let cfg = ck.join("config.json");
    std::fs::write(&cfg, "steps = 10\n").unwrap();
    let o = ace(&[
        "train-prior",
        "--character",
        "stretch",
        "--frames",
        "300",
        "--config",
        &s(&cfg),
        "--checkpoint",
        &s(&ck),
    ]);
    assert!(!o.status.success());
    let e = stderr(&o);
    assert!(
        e.contains("config.json: refusing to write there: it is the configuration file"),
        "{e}"
    );
    assert_eq!(std::fs::read_to_string(&cfg).unwrap(), "steps = 10\n");
}

#[test]
fn demo_clips_of_the_same_file_name_do_not_collide() {
    let dir = scratch("demo-names");
    let (a, b) = (dir.join("a/walk.bvh"), dir.join("b/walk.bvh"));
    std::fs::create_dir_all(a.parent().unwrap()).unwrap();
    std::fs::create_dir_all(b.parent().unwrap()).unwrap();
    std::fs::copy(root().join("assets/motions/walk.bvh"), &a).unwrap();
    std::fs::copy(root().join("assets/motions/wave.bvh"), &b).unwrap();
    let out = dir.join("out");
    let o = ace(&[
        "--threads",
        "1",
        "demo",
        "--characters",
        "stretch",
        "--clip",
        &s(&a),
        "--clip",
        &s(&b),
        "--out",
        &s(&out),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(
        stderr(&o).contains("is written as `walk-2`: another clip has the same file name"),
        "{}",
        stderr(&o)
    );
    let report: Value = serde_json::from_str(&std::fs::read_to_string(out.join("report.json")).unwrap()).unwrap();
    let rows = report.as_array().unwrap();
    assert_eq!(rows.len(), 2);
    // Each row's frames are its own clip's (walk 150, wave another count), each in its own files.
    let frames = |p: &Path| {
        let o = ace(&["inspect", &s(p), "--json"]);
        serde_json::from_slice::<Value>(&o.stdout).unwrap()["frames"]
            .as_u64()
            .unwrap()
    };
    for (row, (clip, name)) in rows.iter().zip([(&a, "walk"), (&b, "walk-2")]) {
        assert_eq!(row["clip"], name);
        assert_eq!(row["metrics"]["frames"].as_u64().unwrap(), frames(clip), "{row}");
        let glb = out.join("stretch").join(format!("{name}.glb"));
        assert_eq!(row["glb"].as_str().unwrap(), s(&glb));
        let m: Value =
            serde_json::from_str(&std::fs::read_to_string(glb.with_extension("metrics.json")).unwrap()).unwrap();
        assert_eq!(m["frames"].as_u64().unwrap(), frames(clip));
    }
    assert_ne!(
        frames(&a),
        frames(&b),
        "the two clips differ in length, so a mix-up would show"
    );
    // No staging folder is left.
    assert!(
        std::fs::read_dir(&dir)
            .unwrap()
            .all(|e| !e.unwrap().file_name().to_string_lossy().contains("ace-tmp"))
    );
}

#[test]
fn numeric_options_are_bounded_before_any_work() {
    let cases: [(&[&str], &str); 8] = [
        (
            &["--threads", "100000", "inspect", "assets/motions/walk.bvh"],
            "invalid value '100000' for '--threads <THREADS>': 100000 is not in 1..=1024",
        ),
        (
            &[
                "dataset",
                "--character",
                "spot",
                "--frames",
                "1000000000000",
                "--out",
                "x.safetensors",
            ],
            "invalid value '1000000000000' for '--frames <FRAMES>': expected a frame count from 1 to 5000000",
        ),
        (
            &["train-prior", "--character", "spot", "--frames", "0"],
            "invalid value '0' for '--frames <FRAMES>'",
        ),
        (
            &["eval", "--character", "spot", "--seconds", "0"],
            "invalid value '0' for '--seconds <SECONDS>': expected seconds from one frame (1/30) to 3600",
        ),
        // Rounds to 0 frames at 30 fps.
        (
            &["eval", "--character", "spot", "--seconds", "0.01"],
            "invalid value '0.01' for '--seconds <SECONDS>': expected seconds from one frame (1/30) to 3600",
        ),
        (
            &["eval", "--character", "spot", "--max-clips", "0"],
            "invalid value '0' for '--max-clips <MAX_CLIPS>': expected a whole number of at least 1",
        ),
        // Checked by the parser, before the folder is listed or a checkpoint loaded (each worker loads
        // its own networks: 10,000 of them would not fit).
        (
            &["retarget", "assets/motions", "--character", "stretch", "--out", "x-out", "--jobs", "0"],
            "invalid value '0' for '--jobs <JOBS>': expected a number of clips at once from 1 to 256",
        ),
        (
            &["retarget", "assets/motions", "--character", "stretch", "--out", "x-out", "--jobs", "10000"],
            "invalid value '10000' for '--jobs <JOBS>': expected a number of clips at once from 1 to 256",
        ),
    ];
    for (args, expected) in cases {
        let start = Instant::now();
        let o = ace(args);
        assert!(!o.status.success(), "{args:?}");
        assert!(stderr(&o).contains(expected), "{args:?}: {}", stderr(&o));
        assert!(
            start.elapsed() < Duration::from_secs(10),
            "{args:?} worked before checking"
        );
    }
    assert!(!root().join("x.safetensors").exists());
    assert!(!root().join("x-out").exists());
}

#[test]
fn config_fields_are_bounded_naming_the_file_and_field() {
    let dir = scratch("config-bounds");
    let ck = dir.join("ck");
    for (text, expected) in [
        (
            "batch_size = 1000000000\n",
            "`batch_size` = 1000000000 is out of range: expected 1 to 65536",
        ),
        ("steps = 0\n", "`steps` = 0 is out of range: expected 1 to 100000000"),
        // A device libtorch does not have: refused where the config is read, before the dataset is
        // generated (libtorch would abort the process on it).
        (
            "device = \"cuda:99\"\n",
            "`device` = \"cuda:99\" is not available: libtorch sees ",
        ),
    ] {
        let cfg = dir.join("prior.toml");
        std::fs::write(&cfg, text).unwrap();
        let start = Instant::now();
        let o = ace(&[
            "train-prior",
            "--character",
            "stretch",
            "--frames",
            "300",
            "--config",
            &s(&cfg),
            "--checkpoint",
            &s(&ck),
        ]);
        assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
        let e = stderr(&o);
        assert!(
            e.contains(&format!("error: {}: invalid configuration: {expected}", cfg.display())),
            "{e}"
        );
        assert!(!ck.exists(), "nothing written");
        assert!(start.elapsed() < Duration::from_secs(10), "{text}: worked before checking");
    }
    // `ace train`'s configuration the same way, before anything is loaded: a step count, a learning
    // rate, and a feature weight (negative, or a key no block has).
    for (text, expected) in [
        ("steps = 0\n", "`steps` = 0 is out of range: expected 1 to 100000000"),
        ("generator_lr = 3.0\n", "`generator_lr` = 3 is out of range: expected more than 0 to 1"),
        ("[feature_weights]\nroot_height = -2.0\n", "`feature_weights.root_height` = -2 is out of range: expected a finite weight ≥ 0"),
        ("[feature_weights]\nroot_heigth = 2.0\n", "unknown field `root_heigth`"),
    ] {
        let cfg = dir.join("ace.toml");
        std::fs::write(&cfg, text).unwrap();
        let o = ace(&["train", "--character", "stretch", "--config", &s(&cfg), "--checkpoint", &s(&ck)]);
        assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
        let e = stderr(&o);
        assert!(e.contains(&format!("error: {}", cfg.display())) && e.contains(expected), "{text}: {e}");
        assert!(!ck.exists(), "nothing written");
    }
    // `ace train` honours `device` too, and checks it before loading anything: on a machine without
    // CUDA, `"cuda"` (device 0) is refused naming the file and the field.
    if ace::models::learn::cuda_devices() == 0 {
        let cfg = dir.join("ace.toml");
        std::fs::write(&cfg, "device = \"cuda\"\n").unwrap();
        let o = ace(&["train", "--character", "stretch", "--config", &s(&cfg), "--checkpoint", &s(&ck)]);
        assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
        let e = stderr(&o);
        assert!(
            e.contains(&format!(
                "error: {}: invalid configuration: `device` = \"cuda:0\" is not available: libtorch sees no CUDA \
                 device on this machine; use \"cpu\" or \"auto\"",
                cfg.display()
            )),
            "{e}"
        );
        assert!(!ck.exists(), "nothing written");
    }
    let cfg = dir.join("data.toml");
    std::fs::write(&cfg, "frames = 1000000000000\n").unwrap();
    let o = ace(&[
        "dataset",
        "--character",
        "stretch",
        "--config",
        &s(&cfg),
        "--out",
        &s(&dir.join("d.safetensors")),
    ]);
    let e = stderr(&o);
    assert!(
        e.contains(&format!("{} (with the command-line options)", cfg.display()))
            && e.contains("`frames` = 1000000000000 is out of range"),
        "{e}"
    );
}

#[test]
fn a_failed_dataset_report_leaves_no_dataset_and_keeps_the_previous_one() {
    let dir = scratch("dataset-set");
    let out = dir.join("d.safetensors");
    std::fs::write(&out, b"previous run").unwrap();
    let blocker = dir.join("file");
    std::fs::write(&blocker, b"").unwrap();
    let report = blocker.join("report"); // cannot be a folder: its parent is a file
    let o = ace(&[
        "dataset",
        "--character",
        "stretch",
        "--frames",
        "300",
        "--out",
        &s(&out),
        "--report",
        &s(&report),
    ]);
    assert!(!o.status.success());
    assert!(stderr(&o).contains(&s(&report)), "{}", stderr(&o));
    assert_eq!(std::fs::read(&out).unwrap(), b"previous run");
    let names: Vec<String> = std::fs::read_dir(&dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    assert_eq!(names.len(), 2, "nothing new is left: {names:?}");
}

#[test]
fn stale_temporaries_of_killed_runs_are_removed() {
    let dir = scratch("stale");
    // A process id that does not exist.
    let dead = (4_000_000..4_100_000)
        .find(|p| !Path::new(&format!("/proc/{p}")).exists())
        .unwrap();
    let stale = [format!(".walk.glb.ace-tmp-{dead}"), format!(".walk.csv.ace-tmp-{dead}")];
    for n in &stale {
        std::fs::write(dir.join(n), b"half").unwrap();
    }
    // A user's files, named like temporaries of other programs, with the dead process' number too.
    let keep = [".hidden-notes.txt".to_string(), format!(".draft.{dead}.tmp"), format!(".x.tmp-{dead}")].map(|n| dir.join(n));
    for k in &keep {
        std::fs::write(k, b"mine").unwrap();
    }
    let out = dir.join("walk.glb");
    let o = ace(&[
        "--threads",
        "1",
        "retarget",
        "assets/motions/walk.bvh",
        "--character",
        "stretch",
        "--out",
        &s(&out),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    for n in &stale {
        assert!(!dir.join(n).exists(), "{n} survived");
    }
    assert!(keep.iter().all(|k| std::fs::read(k).unwrap() == b"mine") && out.is_file());
    let names: Vec<String> = std::fs::read_dir(&dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    assert!(names.iter().all(|n| !n.contains("ace-tmp")), "{names:?}");
}

#[test]
fn sigint_and_sigterm_remove_temporaries() {
    for signal in ["INT", "TERM"] {
        let dir = scratch(&format!("signal-{signal}"));
        let out = dir.join("d.safetensors");
        let report = dir.join("report");
        // The dataset is staged while the report's pictures are drawn: signal then.
        let mut child = Command::new(env!("CARGO_BIN_EXE_ace"))
            .args([
                "dataset",
                "--character",
                "spot",
                "--frames",
                "60000",
                "--out",
                &s(&out),
                "--report",
                &s(&report),
            ])
            .current_dir(root())
            .stdout(std::process::Stdio::null())
            .stderr(std::process::Stdio::piped())
            .spawn()
            .unwrap();
        let deadline = Instant::now() + Duration::from_secs(300);
        let staged = loop {
            let found = std::fs::read_dir(&dir)
                .unwrap()
                .any(|e| e.unwrap().file_name().to_string_lossy().contains("ace-tmp"));
            if found || Instant::now() > deadline || child.try_wait().unwrap().is_some() {
                break found;
            }
            std::thread::sleep(Duration::from_millis(5));
        };
        assert!(staged, "no temporary seen");
        assert!(
            Command::new("kill")
                .args([&format!("-{signal}"), &child.id().to_string()])
                .status()
                .unwrap()
                .success()
        );
        let status = child.wait().unwrap();
        assert!(!status.success());
        let names: Vec<String> = std::fs::read_dir(&dir)
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .collect();
        assert!(names.is_empty(), "SIG{signal} left {names:?}");
    }
}

#[test]
fn a_fifo_named_bvh_is_refused_without_hanging() {
    let dir = scratch("fifo");
    let fifo = dir.join("clip.bvh");
    assert!(Command::new("mkfifo").arg(&fifo).status().unwrap().success());
    let mut child = Command::new(env!("CARGO_BIN_EXE_ace"))
        .args(["inspect", &s(&fifo)])
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    let deadline = Instant::now() + Duration::from_secs(30);
    while child.try_wait().unwrap().is_none() {
        if Instant::now() > deadline {
            let _ = child.kill();
            panic!("ace inspect hung on a FIFO");
        }
        std::thread::sleep(Duration::from_millis(20));
    }
    let o = child.wait_with_output().unwrap();
    assert!(
        stderr(&o).contains("clip.bvh") && stderr(&o).contains("not a regular file"),
        "{}",
        stderr(&o)
    );
}

#[test]
fn mapping_option_reads_an_unknown_rig() {
    let data = root().join("models/tests/data");
    let o = ace(&["inspect", &s(&data.join("unknown_rig.bvh")), "--json"]);
    assert!(!o.status.success());
    assert!(stderr(&o).contains("--mapping FILE"), "{}", stderr(&o));
    let o = ace(&[
        "inspect",
        &s(&data.join("unknown_rig.bvh")),
        "--json",
        "--mapping",
        &s(&data.join("unknown_rig.toml")),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let v: Value = serde_json::from_slice(&o.stdout).unwrap();
    assert_eq!(v["convention"], "user-mapping");
    assert_eq!(v["canonical_joints"], 17);
    // `retarget` (one clip and a folder) and `demo` take it too; without it they refuse the clip.
    let dir = scratch("mapping-option");
    let rig = dir.join("rigs");
    std::fs::create_dir_all(&rig).unwrap();
    std::fs::copy(data.join("unknown_rig.bvh"), rig.join("unknown_rig.bvh")).unwrap();
    let mapping = s(&data.join("unknown_rig.toml"));
    let clip = s(&rig.join("unknown_rig.bvh"));
    let one = s(&dir.join("one.glb"));
    let folder = s(&dir.join("folder"));
    let demo = s(&dir.join("demo"));
    let rigs = s(&rig);
    let runs: [Vec<&str>; 3] = [
        vec!["retarget", &clip, "--character", "stretch", "--out", &one],
        vec!["retarget", &rigs, "--character", "stretch", "--out", &folder],
        vec!["demo", "--characters", "stretch", "--clip", &clip, "--out", &demo],
    ];
    for args in runs {
        let o = ace(&args);
        assert!(!o.status.success() && stderr(&o).contains("--mapping FILE"), "{args:?}: {}", stderr(&o));
        let with: Vec<&str> = args.iter().copied().chain(["--mapping", mapping.as_str()]).collect();
        let o = ace(&with);
        assert!(o.status.success(), "{with:?}: {}", stderr(&o));
    }
    assert!(dir.join("one.glb").is_file() && dir.join("folder/unknown_rig.glb").is_file());
    assert!(dir.join("demo/stretch/unknown_rig.glb").is_file());
}

#[test]
fn urdf_warnings_are_surfaced() {
    let dir = scratch("urdf-warnings");
    let urdf = dir.join("anchored.urdf");
    let text = std::fs::read_to_string(root().join("assets/characters/stretch.urdf")).unwrap();
    // Anchor the robot to a `world` link with a floating joint.
    let base = text
        .split("<link name=\"")
        .nth(1)
        .unwrap()
        .split('"')
        .next()
        .unwrap()
        .to_string();
    let anchored = text.replacen(
        "<link name=\"",
        &format!("<link name=\"world\"/>\n  <joint name=\"world_anchor\" type=\"floating\"><parent link=\"world\"/><child link=\"{base}\"/></joint>\n  <link name=\""),
        1,
    );
    // … and give one link a collision mesh that is not there.
    let anchored = anchored.replacen(
        "<collision>",
        "<collision><geometry><mesh filename=\"missing_part.stl\"/></geometry></collision>\n    <collision>",
        1,
    );
    std::fs::write(&urdf, anchored).unwrap();
    let o = ace(&["inspect", &s(&urdf), "--json"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let v: Value = serde_json::from_slice(&o.stdout).unwrap();
    let warnings = v["warnings"].as_array().unwrap();
    assert!(
        warnings.iter().any(|w| w
            .as_str()
            .unwrap()
            .contains(&format!("root link `world` has no geometry and holds `{base}` by its floating joint `world_anchor`: it is a frame"))),
        "{v}"
    );
    let missing = "not found or not readable as STL, OBJ or Collada (they have no extent): missing_part.stl";
    assert!(warnings.iter().any(|w| w.as_str().unwrap().contains(missing)), "{v}");
    let e = stderr(&o);
    assert!(
        e.contains(&format!("warning: {}: root link `world` has no geometry", urdf.display())),
        "{e}"
    );
    assert!(
        e.contains(&format!("warning: {}: 1 mesh file(s) not found", urdf.display())),
        "{e}"
    );
}

#[test]
fn metrics_finds_the_urdf_a_dataset_was_made_from() {
    let Some(urdf) = shared("robots/phantomx_hexapod/phantomx_description/urdf/phantomx.urdf") else {
        return;
    };
    let dir = scratch("metrics-urdf");
    let file = dir.join("phantomx.safetensors");
    let o = ace(&[
        "dataset",
        "--character",
        &s(&urdf),
        "--frames",
        "600",
        "--out",
        &s(&file),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let o = ace(&["metrics", &s(&file), "--json"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let v: Value = serde_json::from_slice(&o.stdout).unwrap();
    assert_eq!(v["frames"], 600);
}

#[test]
fn damaged_or_mismatched_checkpoints_are_blamed_correctly() {
    let dir = scratch("checkpoint");
    let ck = dir.join("ck");
    copy_dir(&root().join("assets/checkpoints/stretch"), &ck);
    // NaN into the first weight of the generator.
    let gen_path = ck.join("generator.safetensors");
    let mut bytes = std::fs::read(&gen_path).unwrap();
    let header = u64::from_le_bytes(bytes[..8].try_into().unwrap()) as usize;
    bytes[8 + header..8 + header + 4].copy_from_slice(&f32::NAN.to_le_bytes());
    std::fs::write(&gen_path, bytes).unwrap();
    let out = dir.join("x.glb");
    let o = ace(&[
        "--threads",
        "1",
        "retarget",
        "assets/motions/walk.bvh",
        "--character",
        "stretch",
        "--checkpoint",
        &s(&ck),
        "--out",
        &s(&out),
    ]);
    assert!(!o.status.success());
    let e = stderr(&o);
    assert!(
        e.contains(&s(&gen_path)) && e.contains("holds 1 non-finite value(s) (NaN or infinity)"),
        "{e}"
    );
    assert!(!out.exists());

    // The bundled Stretch scaled ×10: same joints, another size.
    let text = std::fs::read_to_string(root().join("assets/characters/stretch.urdf")).unwrap();
    let scaled = scale_lengths(&text, 10.0);
    let urdf = dir.join("stretch.urdf");
    std::fs::write(&urdf, scaled).unwrap();
    let o = ace(&[
        "--threads",
        "1",
        "retarget",
        "assets/motions/walk.bvh",
        "--character",
        &s(&urdf),
        "--checkpoint",
        "assets/checkpoints/stretch",
        "--out",
        &s(&out),
    ]);
    assert!(!o.status.success());
    let e = stderr(&o);
    assert!(
        e.contains("ace.json") && e.contains("with a body length of") && e.contains("(×10"),
        "{e}"
    );
    assert!(!out.exists());
}

/// Every length attribute of a URDF (origins, box sizes, radii, lengths, prismatic limits) × `k`.
fn scale_lengths(text: &str, k: f64) -> String {
    let mut out = String::new();
    let mut rest = text;
    while let Some(i) = rest.find('"') {
        let attr_start = rest[..i].rfind(char::is_whitespace).map_or(0, |w| w + 1);
        let attr = rest[attr_start..i].trim_end_matches('=');
        let j = rest[i + 1..].find('"').unwrap() + i + 1;
        let value = &rest[i + 1..j];
        out.push_str(&rest[..=i]);
        if ["xyz", "size", "radius", "length"].contains(&attr) && !rest[..i].contains("<axis") {
            let scaled: Vec<String> = value
                .split_whitespace()
                .map(|v| (v.parse::<f64>().unwrap() * k).to_string())
                .collect();
            out.push_str(&scaled.join(" "));
        } else {
            out.push_str(value);
        }
        out.push('"');
        rest = &rest[j + 1..];
    }
    out.push_str(rest);
    out
}

/// Every file name in `dir` (not below it), sorted.
fn names(dir: &Path) -> Vec<String> {
    let mut n: Vec<String> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    n.sort();
    n
}

/// Runs `ace` and checks that it failed with status 1 within 10 s (before any work), its error
/// being `expected` exactly; returns nothing, the caller checks what is left on disk.
fn refused_up_front(args: &[&str], expected: &str) {
    let start = Instant::now();
    let o = ace(args);
    assert_eq!(o.status.code(), Some(1), "{args:?}: {}", stderr(&o));
    let e = stderr(&o);
    assert!(e.lines().any(|l| l == format!("error: {expected}")), "{args:?}:\n{e}\nexpected: error: {expected}");
    assert!(start.elapsed() < Duration::from_secs(10), "{args:?} worked before checking");
}

#[test]
fn two_outputs_of_one_path_are_refused_before_any_work() {
    let dir = scratch("collisions");
    let walk = root().join("assets/motions/walk.bvh");
    // `--out x.json`: the glTF binary and the trajectory would be one file; `x.txt`, `x` and `.glb` got a
    // GLB under that name.
    for name in ["x.json", "x.txt", "x", ".glb"] {
        let out = dir.join(name);
        refused_up_front(
            &["retarget", &s(&walk), "--character", "stretch", "--out", &s(&out)],
            &format!(
                "{}: --out is the glTF file, a name ending in .glb (binary) or .gltf (JSON); the trajectory and the metrics \
                 are written beside it",
                out.display()
            ),
        );
    }
    // A folder where `walk.bvh` and `walk.BVH` both make `walk.glb` (and the rest).
    let clips = dir.join("clips");
    std::fs::create_dir_all(&clips).unwrap();
    std::fs::copy(&walk, clips.join("walk.bvh")).unwrap();
    std::fs::copy(root().join("assets/motions/wave.bvh"), clips.join("walk.BVH")).unwrap();
    let out = dir.join("out");
    refused_up_front(
        &["retarget", &s(&clips), "--character", "stretch", "--out", &s(&out)],
        &format!(
            "{}: both the glTF binary of walk.BVH and the glTF binary of walk.bvh would be written there; rename one \
             of the clips",
            out.join("walk.glb").display()
        ),
    );
    // … and where the trajectory of `walk.metrics.bvh` is the metrics file of `walk.bvh`.
    std::fs::remove_file(clips.join("walk.BVH")).unwrap();
    std::fs::copy(root().join("assets/motions/wave.bvh"), clips.join("walk.metrics.bvh")).unwrap();
    refused_up_front(
        &["retarget", &s(&clips), "--character", "stretch", "--out", &s(&out)],
        &format!(
            "{}: both the metrics of walk.bvh and the trajectory (JSON) of walk.metrics.bvh would be written there; \
             rename one of the clips",
            out.join("walk.metrics.json").display()
        ),
    );
    // The demo gathers its outputs the same way.
    let (a, b) = (clips.join("walk.bvh"), clips.join("walk.metrics.bvh"));
    refused_up_front(
        &["demo", "--characters", "stretch", "--clip", &s(&a), "--clip", &s(&b), "--out", &s(&out)],
        &format!(
            "{}: both the metrics of {} on stretch and the trajectory (JSON) of {} on stretch would be written \
             there; rename one of the clips",
            out.join("stretch/walk.metrics.json").display(),
            a.display(),
            b.display()
        ),
    );
    // Nothing was written: the clips are as they were and no output folder or file appeared.
    assert_eq!(names(&dir), ["clips"]);
    assert_eq!(names(&clips), ["walk.bvh", "walk.metrics.bvh"]);
}

/// `hound.glb` rewritten as `hound.gltf` with its binary chunk in `hound.bin` beside it.
fn hound_as_gltf(dir: &Path) -> (PathBuf, PathBuf) {
    let glb = std::fs::read(root().join("assets/creatures/hound.glb")).unwrap();
    let u32_at = |i: usize| u32::from_le_bytes(glb[i..i + 4].try_into().unwrap()) as usize;
    let json_len = u32_at(12);
    let mut json: Value = serde_json::from_slice(&glb[20..20 + json_len]).unwrap();
    let bin_start = 20 + json_len;
    let bin = &glb[bin_start + 8..bin_start + 8 + u32_at(bin_start)];
    json["buffers"][0]["uri"] = Value::from("hound.bin");
    let (gltf, bin_path) = (dir.join("hound.gltf"), dir.join("hound.bin"));
    std::fs::write(&gltf, serde_json::to_vec(&json).unwrap()).unwrap();
    std::fs::write(&bin_path, bin).unwrap();
    (gltf, bin_path)
}

#[test]
fn files_read_implicitly_are_never_written_over() {
    let dir = scratch("implicit-inputs");
    let walk = dir.join("walk.bvh");
    std::fs::copy(root().join("assets/motions/walk.bvh"), &walk).unwrap();
    // A joint mapping beside the clip (read with it), a creature as .glb and as .gltf + .bin, a URDF
    // with a profile beside it.
    let mapping = dir.join("walk.mapping.toml");
    std::fs::write(&mapping, "pelvis = \"Hips\"\n").unwrap();
    let glb = dir.join("hound.glb");
    std::fs::copy(root().join("assets/creatures/hound.glb"), &glb).unwrap();
    let (gltf, bin) = hound_as_gltf(&dir);
    let urdf = dir.join("stretch.urdf");
    std::fs::copy(root().join("assets/characters/stretch.urdf"), &urdf).unwrap();
    let profile = dir.join("stretch.profile.toml");
    std::fs::write(&profile, "# nothing overridden\n").unwrap();
    let before = snapshot(&dir);
    let (hound_ck, stretch_ck) = (root().join("assets/checkpoints/hound"), root().join("assets/checkpoints/stretch"));
    for (character, checkpoint, out, what) in [
        (&glb, &hound_ck, &glb, "the character file"),
        (&gltf, &hound_ck, &bin, "a file of the character's model (buffer or image)"),
        (&urdf, &stretch_ck, &mapping, &*format!("the joint-mapping file read with {}", walk.display())),
        (&urdf, &stretch_ck, &profile, "the character's profile"),
    ] {
        refused_up_front(
            &[
                "retarget",
                &s(&walk),
                "--character",
                &s(character),
                "--checkpoint",
                &s(checkpoint),
                "--out",
                &s(out),
            ],
            &format!(
                "{}: refusing to write there: it is {what} ({}) this command reads; choose another output path",
                out.display(),
                out.display()
            ),
        );
        assert_eq!(snapshot(&dir), before, "{}: a file changed", out.display());
    }
}

#[test]
fn an_output_that_is_a_directory_leaves_the_previous_outputs_alone() {
    let dir = scratch("directory-output");
    let out = dir.join("out.glb");
    std::fs::write(&out, b"previous").unwrap();
    let metrics = dir.join("out.metrics.json");
    std::fs::create_dir(&metrics).unwrap();
    refused_up_front(
        &["retarget", "assets/motions/walk.bvh", "--character", "stretch", "--out", &s(&out)],
        &format!(
            "{}: refusing to write there: it is a directory, and this output is a file; remove the directory or \
             choose another output path",
            metrics.display()
        ),
    );
    assert_eq!(std::fs::read(&out).unwrap(), b"previous");
    assert_eq!(names(&dir), ["out.glb", "out.metrics.json"]);
    assert!(names(&metrics).is_empty());
}

const TINY_PRIOR: &str =
    "steps = 40\nbatch_size = 16\ncheckpoint_every = 20\nencoder_hidden = [32, 32]\ndecoder_hidden = [32, 32]\n";
const TINY_ACE: &str =
    "steps = 10\nbatch_size = 8\ncheckpoint_every = 5\ngenerator_hidden = [32, 32]\ndiscriminator_hidden = [32, 32]\n";

/// A process id that does not exist.
fn dead_pid() -> u32 {
    (4_000_000..4_100_000)
        .find(|p| !Path::new(&format!("/proc/{p}")).exists())
        .unwrap()
}

fn run_ok(args: &[&str]) {
    let o = ace(args);
    assert!(o.status.success(), "ace {args:?}: {}", stderr(&o));
}

#[test]
fn training_removes_temporaries_of_killed_runs_and_its_own_on_sigterm() {
    let dir = scratch("training-temporaries");
    let ck = dir.join("ck");
    std::fs::create_dir_all(&ck).unwrap();
    // What a train-prior, train or eval --baselines run killed with SIGKILL leaves in its checkpoint
    // directory (the saves' temporaries, the loss log's, the FID reference's, a plot's).
    let dead = dead_pid();
    let stale = [
        format!(".prior.safetensors.ace-tmp-{dead}.safetensors"),
        format!(".config.json.ace-tmp-{dead}"),
        format!(".ace.json.ace-tmp-{dead}"),
        format!(".generator.safetensors.ace-tmp-{dead}.safetensors"),
        format!(".ace_losses.csv.ace-tmp-{dead}"),
        format!(".reference.json.ace-tmp-{dead}"),
        format!(".prior_losses.png.ace-tmp-{dead}"),
    ];
    for n in &stale {
        std::fs::write(ck.join(n), b"half").unwrap();
    }
    let notes = ck.join(".notes.txt");
    std::fs::write(&notes, b"mine").unwrap();
    let cfg = dir.join("prior.toml");
    std::fs::write(&cfg, TINY_PRIOR).unwrap();
    run_ok(&["--threads", "1", "train-prior", "--character", "stretch", "--frames", "3000", "--config", &s(&cfg), "--checkpoint", &s(&ck)]);
    assert_eq!(
        names(&ck),
        [".notes.txt", "config.json", "prior.safetensors", "prior_losses.csv", "prior_losses.png"],
        "the stale temporaries are gone, the user's file is kept"
    );

    // SIGTERM while the prior is saved at every step (networks wide enough that a save takes a while):
    // the run's own temporaries go with it.
    let ck = dir.join("ck-signal");
    let cfg = dir.join("prior-long.toml");
    let long = "steps = 1000000\nbatch_size = 16\ncheckpoint_every = 1\nencoder_hidden = [1024, 1024]\n\
                decoder_hidden = [1024, 1024]\n";
    std::fs::write(&cfg, long).unwrap();
    let mut child = Command::new(env!("CARGO_BIN_EXE_ace"))
        .args(["--threads", "1", "train-prior", "--character", "stretch", "--frames", "3000", "--config", &s(&cfg), "--checkpoint", &s(&ck)])
        .current_dir(root())
        .stdout(std::process::Stdio::null())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    let deadline = Instant::now() + Duration::from_secs(300);
    let seen = loop {
        let tmp = ck.is_dir() && names(&ck).iter().any(|n| n.contains("tmp"));
        if tmp || Instant::now() > deadline || child.try_wait().unwrap().is_some() {
            break tmp;
        }
        std::thread::sleep(Duration::from_millis(1));
    };
    assert!(seen, "no temporary seen");
    assert!(Command::new("kill").args(["-TERM", &child.id().to_string()]).status().unwrap().success());
    let o = child.wait_with_output().unwrap();
    assert_eq!(o.status.code(), Some(130), "{} (a process killed by a signal has no code): {}", o.status, stderr(&o));
    let left: Vec<String> = names(&ck).into_iter().filter(|n| n.contains("tmp")).collect();
    assert!(left.is_empty(), "SIGTERM left {left:?}");
}

/// `walk.bvh` with its root raised 5 km (5e5 cm: each frame within the importer's bound of 10 km)
/// from frame `from` on.
fn walk_raised_from(from: usize) -> String {
    let text = std::fs::read_to_string(root().join("assets/motions/walk.bvh")).unwrap();
    let (head, motion) = text.split_once("Frame Time: 0.033333\n").unwrap();
    let lines: Vec<String> = motion
        .lines()
        .filter(|l| !l.trim().is_empty())
        .enumerate()
        .map(|(f, l)| {
            let mut v: Vec<f32> = l.split_whitespace().map(|x| x.parse().unwrap()).collect();
            if f >= from {
                v[1] += 5e5; // the root's Yposition (the clip is y-up, in centimetres)
            }
            v.iter().map(f32::to_string).collect::<Vec<_>>().join(" ")
        })
        .collect();
    format!("{head}Frame Time: 0.033333\n{}\n", lines.join("\n"))
}

/// Every file below `dir` with its bytes, inode and modification time: a file rewritten with the same
/// bytes shows too.
fn snapshot_with_times(dir: &Path) -> BTreeMap<PathBuf, (Vec<u8>, u64, i64, i64)> {
    use std::os::unix::fs::MetadataExt;
    snapshot(dir)
        .into_iter()
        .map(|(p, bytes)| {
            let m = std::fs::metadata(&p).unwrap();
            (p, (bytes, m.ino(), m.mtime(), m.mtime_nsec()))
        })
        .collect()
}

#[test]
fn a_failed_train_leaves_the_checkpoint_as_it_was() {
    let dir = scratch("failed-train");
    let ck = dir.join("ck");
    let (prior_cfg, ace_cfg) = (dir.join("prior.toml"), dir.join("ace.toml"));
    std::fs::write(&prior_cfg, TINY_PRIOR).unwrap();
    std::fs::write(&ace_cfg, TINY_ACE).unwrap();
    run_ok(&["--threads", "1", "train-prior", "--character", "stretch", "--frames", "3000", "--config", &s(&prior_cfg), "--checkpoint", &s(&ck)]);
    run_ok(&["--threads", "1", "train", "--character", "stretch", "--config", &s(&ace_cfg), "--checkpoint", &s(&ck), "--humans", "assets/motions"]);
    assert!(ck.join("reference.json").is_file() && ck.join("ace.json").is_file());
    // Human clips 5 km up in half their frames: each frame passes the importer, their statistics do
    // not (one of the two is held out, the other is trained on).
    let humans = dir.join("humans");
    std::fs::create_dir_all(&humans).unwrap();
    for n in ["high-a.bvh", "high-b.bvh"] {
        std::fs::write(humans.join(n), walk_raised_from(75)).unwrap();
    }
    let before = snapshot_with_times(&ck);
    let o = ace(&["--threads", "1", "train", "--character", "stretch", "--config", &s(&ace_cfg), "--checkpoint", &s(&ck), "--humans", &s(&humans)]);
    assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
    let e = stderr(&o);
    assert!(
        e.contains("error: invalid training data: the human clips' x^h entry 0 has mean ")
            && e.contains("(at most 1000 is plausible): ")
            && e.contains(&s(&humans.join("high-")))
            && e.contains("; nothing was trained or saved"),
        "{e}"
    );
    // Not a byte, an inode or a modification time changed: reference.json is written only after
    // training succeeds.
    assert_eq!(snapshot_with_times(&ck), before);
}

include!("../models/tests/data/bad_dataset_configs.rs");

#[test]
fn every_dataset_configuration_field_is_bounded_naming_the_file_and_field() {
    let dir = scratch("dataset-config-bounds");
    let cfg = dir.join("data.toml");
    for (text, problem) in BAD_DATASET_CONFIGS {
        std::fs::write(&cfg, format!("frames = 300\n{text}\n")).unwrap();
        refused_up_front(
            &[
                "dataset",
                "--character",
                "stretch",
                "--config",
                &s(&cfg),
                "--out",
                &s(&dir.join("d.safetensors")),
                "--report",
                &s(&dir.join("report")),
            ],
            &format!(
                "{} (with the command-line options): invalid dataset configuration: {problem}",
                cfg.display()
            ),
        );
        assert_eq!(names(&dir), ["data.toml"], "{text}: nothing is written");
    }
}

/// Runs `ace`, killing it after 10 s (a reader that opened a FIFO would wait for a writer forever; a
/// command that did not check first would be working), and checks that it failed with status 1 and
/// the error line `expected`; returns its standard error.
fn refused_without_hanging(args: &[&str], expected: &str) -> String {
    let mut child = Command::new(env!("CARGO_BIN_EXE_ace"))
        .args(args)
        .current_dir(root())
        .stdout(std::process::Stdio::null())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    let deadline = Instant::now() + Duration::from_secs(10);
    while child.try_wait().unwrap().is_none() {
        if Instant::now() > deadline {
            let _ = child.kill();
            panic!("ace {args:?} did not finish in 10 s (hung, or working before checking)");
        }
        std::thread::sleep(Duration::from_millis(10));
    }
    let o = child.wait_with_output().unwrap();
    assert_eq!(o.status.code(), Some(1), "{args:?}: {}", stderr(&o));
    let e = stderr(&o);
    assert!(e.lines().any(|l| l == format!("error: {expected}")), "{args:?}:\n{e}\nexpected: error: {expected}");
    e
}

#[test]
fn every_input_file_refuses_a_fifo_and_utf16_from_the_command_line() {
    let dir = scratch("input-files");
    let not_regular = "not a regular file (a directory, FIFO or device)";
    let utf16_hint = "the file is UTF-16 encoded; save it as UTF-8 (e.g. `iconv -f UTF-16 -t UTF-8`)";
    let (toml, set, urdf) = (dir.join("f.toml"), dir.join("f.safetensors"), dir.join("f.urdf"));
    for f in [&toml, &set, &urdf] {
        assert!(Command::new("mkfifo").arg(f).status().unwrap().success());
    }
    let good = dir.join("good.safetensors");
    run_ok(&["dataset", "--character", "stretch", "--frames", "300", "--out", &s(&good)]);
    let ck = dir.join("ck");
    copy_dir(&root().join("assets/checkpoints/stretch"), &ck);
    std::fs::remove_file(ck.join("ace.json")).unwrap();
    assert!(Command::new("mkfifo").arg(ck.join("ace.json")).status().unwrap().success());
    let walk = "assets/motions/walk.bvh";
    let (x, ck2) = (s(&dir.join("x.safetensors")), s(&dir.join("ck2")));
    let fifo = |p: &Path| format!("{}: {not_regular}", p.display());
    for (args, expected) in [
        (vec!["inspect", walk, "--mapping", &s(&toml)], fifo(&toml)),
        (vec!["metrics", &s(&set)], fifo(&set)),
        (vec!["metrics", &s(&good), "--reference", &s(&set)], fifo(&set)),
        (vec!["dataset", "--character", "stretch", "--config", &s(&toml), "--out", &x], fifo(&toml)),
        (vec!["train-prior", "--character", "stretch", "--config", &s(&toml), "--checkpoint", &ck2], fifo(&toml)),
        (vec!["train-prior", "--character", "stretch", "--dataset", &s(&set), "--checkpoint", &ck2], fifo(&set)),
        (
            vec!["retarget", walk, "--character", "stretch", "--checkpoint", &s(&ck), "--out", &s(&dir.join("x.glb"))],
            fifo(&ck.join("ace.json")),
        ),
        (vec!["inspect", &s(&urdf)], format!("{}: cannot read the file: {not_regular}", urdf.display())),
        (
            vec!["dataset", "--character", &s(&urdf), "--out", &x],
            format!("{}: cannot read the file: {not_regular}", urdf.display()),
        ),
    ] {
        refused_without_hanging(&args, &expected);
    }
    // UTF-16 without a byte-order mark: a hint, not a TOML or XML syntax error.
    let utf16 = |text: &str| -> Vec<u8> { text.encode_utf16().flat_map(u16::to_le_bytes).collect() };
    let (toml16, urdf16) = (dir.join("u16.toml"), dir.join("u16.urdf"));
    std::fs::write(&toml16, utf16("frames = 300\n")).unwrap();
    let stretch = std::fs::read_to_string(root().join("assets/characters/stretch.urdf")).unwrap();
    std::fs::write(&urdf16, utf16(&stretch)).unwrap();
    let hint = |p: &Path| format!("{}: {utf16_hint}", p.display());
    for (args, expected) in [
        (vec!["inspect", walk, "--mapping", &s(&toml16)], hint(&toml16)),
        (vec!["dataset", "--character", "stretch", "--config", &s(&toml16), "--out", &x], hint(&toml16)),
        (vec!["train-prior", "--character", "stretch", "--config", &s(&toml16), "--checkpoint", &ck2], hint(&toml16)),
        (vec!["inspect", &s(&urdf16)], format!("{}: cannot read the file: {utf16_hint}", urdf16.display())),
    ] {
        refused_without_hanging(&args, &expected);
    }
    // Nothing was written.
    assert_eq!(names(&dir), ["ck", "f.safetensors", "f.toml", "f.urdf", "good.safetensors", "u16.toml", "u16.urdf"]);
}

/// A sparse file of `len` bytes: its size is in the metadata, its bytes take no disk (nothing may read
/// them: each is refused from its size).
fn sparse(path: &Path, len: u64) {
    std::fs::File::create(path).unwrap().set_len(len).unwrap();
}

#[test]
fn every_input_file_over_its_kinds_bound_is_refused_from_its_size() {
    use ace::models::input::{MAX_BVH_BYTES, MAX_DATA_BYTES, MAX_TEXT_BYTES};
    let dir = scratch("input-sizes");
    let (bvh, toml, set, urdf) = (dir.join("huge.bvh"), dir.join("huge.toml"), dir.join("huge.safetensors"), dir.join("huge.urdf"));
    sparse(&bvh, MAX_BVH_BYTES + 1);
    sparse(&toml, MAX_TEXT_BYTES + 1);
    sparse(&set, MAX_DATA_BYTES + 1);
    sparse(&urdf, MAX_TEXT_BYTES + 1);
    let ck = dir.join("ck");
    copy_dir(&root().join("assets/checkpoints/stretch"), &ck);
    sparse(&ck.join("generator.safetensors"), MAX_DATA_BYTES + 1);
    let too_large = |p: &Path, size: u64, max: u64| format!("{}: the file is {size} bytes, more than the {max} bytes this kind of file may have", p.display());
    let x = s(&dir.join("x.safetensors"));
    for (args, expected) in [
        (vec!["inspect".to_string(), s(&bvh)], too_large(&bvh, MAX_BVH_BYTES + 1, MAX_BVH_BYTES)),
        (
            vec!["dataset".into(), "--character".into(), "stretch".into(), "--config".into(), s(&toml), "--out".into(), x.clone()],
            too_large(&toml, MAX_TEXT_BYTES + 1, MAX_TEXT_BYTES),
        ),
        (vec!["metrics".into(), s(&set)], too_large(&set, MAX_DATA_BYTES + 1, MAX_DATA_BYTES)),
        (vec!["inspect".into(), s(&urdf)], format!("{}: cannot read the file: the file is {} bytes, more than the {MAX_TEXT_BYTES} bytes this kind of file may have", urdf.display(), MAX_TEXT_BYTES + 1)),
        (
            vec!["retarget".into(), "assets/motions/walk.bvh".into(), "--character".into(), "stretch".into(), "--checkpoint".into(), s(&ck), "--out".into(), s(&dir.join("x.glb"))],
            too_large(&ck.join("generator.safetensors"), MAX_DATA_BYTES + 1, MAX_DATA_BYTES),
        ),
    ] {
        let args: Vec<&str> = args.iter().map(String::as_str).collect();
        refused_without_hanging(&args, &expected);
    }
    assert_eq!(names(&dir), ["ck", "huge.bvh", "huge.safetensors", "huge.toml", "huge.urdf"]);
}

fn ace_in(dir: &Path, args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_ace")).args(args).current_dir(dir).output().expect("running ace")
}

#[test]
fn metrics_finds_a_character_given_by_a_relative_path_from_any_folder() {
    use ace::models::dataset::MotionSet;
    let dir = scratch("metrics-relative");
    let (work, robots, elsewhere) = (dir.join("work"), dir.join("robots"), dir.join("elsewhere/deeper"));
    for d in [&work, &robots, &elsewhere] {
        std::fs::create_dir_all(d).unwrap();
    }
    // Not a bundled character's name, so that `ace metrics` needs the recorded file.
    let text = std::fs::read_to_string(root().join("assets/characters/stretch.urdf")).unwrap();
    std::fs::write(robots.join("stretchy.urdf"), text.replacen("<robot name=\"stretch\">", "<robot name=\"stretchy\">", 1))
        .unwrap();
    let o = ace_in(&work, &["dataset", "--character", "../robots/stretchy.urdf", "--frames", "300", "--out", "d.safetensors"]);
    assert!(o.status.success(), "{}", stderr(&o));
    // The dataset records the file's absolute path …
    let set = MotionSet::load(&work.join("d.safetensors")).unwrap();
    let canonical = std::fs::canonicalize(robots.join("stretchy.urdf")).unwrap();
    assert_eq!(set.character_source.as_deref(), Some(&*s(&canonical)));
    // … so that it is scored from another folder.
    let frames = |o: &Output| -> Value {
        assert!(o.status.success(), "{}", stderr(o));
        serde_json::from_slice::<Value>(&o.stdout).unwrap()["frames"].clone()
    };
    assert_eq!(frames(&ace_in(&elsewhere, &["metrics", "../../work/d.safetensors", "--json"])), 300);
    // A dataset of before, which recorded the path as it was given (relative to where `ace dataset`
    // ran, here the dataset's folder), is read from any folder too: from here, else from its folder
    // (`../robots` is nothing from `elsewhere/deeper` or from `dir`).
    let mut old = set.clone();
    old.character_source = Some("../robots/stretchy.urdf".into());
    old.save(&work.join("old.safetensors")).unwrap();
    assert_eq!(frames(&ace_in(&work, &["metrics", "old.safetensors", "--json"])), 300);
    assert_eq!(frames(&ace_in(&elsewhere, &["metrics", "../../work/old.safetensors", "--json"])), 300);
    assert_eq!(frames(&ace_in(&dir, &["metrics", &s(&work.join("old.safetensors")), "--json"])), 300);
    // Where neither exists, the error says both and what to do.
    std::fs::rename(&robots, dir.join("moved")).unwrap();
    let o = ace_in(&elsewhere, &["metrics", "../../work/old.safetensors"]);
    assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
    assert!(
        stderr(&o).lines().any(|l| l
            == "error: the motion file was made for `stretchy` from ../robots/stretchy.urdf, which is not a file from \
                here nor from the motion file's folder (../../work/../robots/stretchy.urdf); pass --character URDF"),
        "{}",
        stderr(&o)
    );
}

/// A binary STL of one triangle.
fn tiny_stl() -> Vec<u8> {
    let mut b = vec![0u8; 80];
    b.extend(1u32.to_le_bytes());
    for v in [0.0f32, 0.0, 1.0, 0.0, 0.0, 0.0, 0.01, 0.0, 0.0, 0.0, 0.01, 0.0] {
        b.extend(v.to_le_bytes());
    }
    b.extend([0u8, 0]);
    b
}

#[test]
fn a_urdf_s_mesh_files_are_never_written_over() {
    let dir = scratch("urdf-meshes");
    let robot = dir.join("robot");
    std::fs::create_dir_all(robot.join("meshes")).unwrap();
    // The Stretch with three mesh visuals: one relative to the URDF, one through `package://`, and an
    // OBJ with its material file.
    let text = std::fs::read_to_string(root().join("assets/characters/stretch.urdf")).unwrap();
    let meshes = "<visual><geometry><mesh filename=\"meshes/part.stl\"/></geometry></visual>\
                  <visual><geometry><mesh filename=\"package://robot/meshes/cover.stl\"/></geometry></visual>\
                  <visual><geometry><mesh filename=\"meshes/panel.obj\"/></geometry></visual>";
    let at = text.find("<visual>").unwrap();
    let urdf = robot.join("stretchy.urdf");
    std::fs::write(&urdf, format!("{}{meshes}{}", &text[..at], &text[at..])).unwrap();
    let (part, cover) = (robot.join("meshes/part.stl"), robot.join("meshes/cover.stl"));
    std::fs::write(&part, tiny_stl()).unwrap();
    std::fs::write(&cover, tiny_stl()).unwrap();
    let (panel, paint) = (robot.join("meshes/panel.obj"), robot.join("meshes/paint.mtl"));
    std::fs::write(&panel, "mtllib paint.mtl\nv 0 0 0\nv 0.01 0 0\nv 0 0.01 0\nusemtl red\nf 1 2 3\n").unwrap();
    std::fs::write(&paint, "newmtl red\nKd 1 0 0\n").unwrap();
    let o = ace(&["inspect", &s(&urdf), "--json"]);
    assert!(o.status.success() && !stderr(&o).contains("not found"), "the meshes are read: {}", stderr(&o));
    let before = snapshot(&dir);
    for mesh in [&part, &cover, &panel, &paint] {
        refused_up_front(
            &["dataset", "--character", &s(&urdf), "--frames", "300", "--out", &s(mesh)],
            &format!(
                "{}: refusing to write there: it is a mesh file of the character ({}) this command reads; choose \
                 another output path",
                mesh.display(),
                mesh.display()
            ),
        );
        assert_eq!(snapshot(&dir), before, "{}: a file changed", mesh.display());
    }
}

#[test]
fn end_effector_mapping_names_are_checked_before_the_dataset_and_clips_are_loaded() {
    let dir = scratch("mapping-names");
    let ck = dir.join("ck");
    copy_dir(&root().join("assets/checkpoints/stretch"), &ck);
    let cfg = dir.join("ace.toml");
    std::fs::write(&cfg, "steps = 10\n[end_effector_mapping]\ngripper = \"right_hand\"\n").unwrap();
    let before = snapshot_with_times(&ck);
    let e = refused_without_hanging(
        &["--threads", "1", "train", "--character", "stretch", "--config", &s(&cfg), "--checkpoint", &s(&ck)],
        &format!(
            "{}: invalid configuration: end_effector_mapping: `gripper` is not an end effector of the character \
             (they are: grasp_center)",
            cfg.display()
        ),
    );
    assert!(!e.contains("generating the character dataset") && !e.contains("importing"), "{e}");
    assert_eq!(snapshot_with_times(&ck), before);
}

#[test]
fn eval_never_trains_its_baselines_into_the_checkpoint_it_reads() {
    let dir = scratch("eval-runs");
    let runs = dir.join("runs");
    // The compared checkpoint is where a baseline run would go, or holds the runs.
    let ck = runs.join("ace-no-feature");
    copy_dir(&root().join("assets/checkpoints/stretch"), &ck);
    let before = snapshot_with_times(&dir);
    for (runs_arg, expected) in [
        (
            &runs,
            format!(
                "{}: refusing to write there: it is the checkpoint directory ({}) this command reads; choose another \
                 output path",
                runs.join("ace-no-feature").display(),
                ck.display()
            ),
        ),
        (
            &ck,
            format!(
                "{}: refusing to write there: it is inside the checkpoint directory ({}) this command reads, whose \
                 files it would overwrite; choose an output path outside it",
                ck.join("nkn").display(),
                ck.display()
            ),
        ),
    ] {
        refused_without_hanging(
            &[
                "--threads", "1", "eval", "--character", "stretch", "--checkpoint", &s(&ck), "--baselines", "--quick",
                "--runs", &s(runs_arg), "--out", &s(&dir.join("eval")),
            ],
            &expected,
        );
        assert_eq!(snapshot_with_times(&dir), before, "--runs {}", runs_arg.display());
    }
}

/// `walk.bvh` lying on its back: the pelvis turned 90° about the horizontal x axis in every frame (the
/// root's rotation order is Y X Z, so this holds whatever the heading), 15 cm above the floor.
fn lying_walk() -> String {
    let text = std::fs::read_to_string(root().join("assets/motions/walk.bvh")).unwrap();
    let (head, motion) = text.split_once("Frame Time: 0.033333\n").unwrap();
    let lines: Vec<String> = motion
        .lines()
        .filter(|l| !l.trim().is_empty())
        .map(|l| {
            let mut v: Vec<f32> = l.split_whitespace().map(|x| x.parse().unwrap()).collect();
            v[1] = 15.0; // Yposition (cm)
            v[4] += 90.0; // Xrotation
            v.iter().map(f32::to_string).collect::<Vec<_>>().join(" ")
        })
        .collect();
    format!("{head}Frame Time: 0.033333\n{}\n", lines.join("\n"))
}

#[test]
fn retarget_warns_that_a_lying_clip_is_far_from_upright() {
    let dir = scratch("lying");
    let clip = dir.join("lying.bvh");
    std::fs::write(&clip, lying_walk()).unwrap();
    // The case: a person lying throughout. The up axis taken from the posture is then the
    // horizontal feet-to-head one and the frames look upright; the skeleton's rest pose tells.
    let warning = "warning: lying: the person seems to lie or crawl through most of the clip: the skeleton stands \
                   along the file's y axis in its rest pose, but the frames' feet-to-head direction is along its z \
                   axis, which was taken as up. ACE is trained on upright humans, so a lying or crawling clip may drive the character \
                   in unintended ways (e.g. walking backwards); to import it as lying, give `up = \"y\"` in a \
                   joint-mapping file (--mapping FILE or lying.mapping.toml)";
    let o = ace(&["--threads", "1", "retarget", &s(&clip), "--character", "spot", "--out", &s(&dir.join("lying.glb"))]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(stderr(&o).lines().any(|l| l == warning), "{}", stderr(&o));
    // Imported as lying, as the warning suggests: the pelvis is upright in none of the frames.
    std::fs::write(dir.join("lying.mapping.toml"), "up = \"y\"\n").unwrap();
    let warning = "warning: lying: the pelvis is upright (within 60° of vertical) in only 0 % of the frames; ACE is \
                   trained on upright humans, so a lying or crawling clip may drive the character in unintended ways \
                   (e.g. walking backwards)";
    let o = ace(&["--threads", "1", "retarget", &s(&clip), "--character", "spot", "--out", &s(&dir.join("lying.glb"))]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(stderr(&o).lines().any(|l| l == warning), "{}", stderr(&o));
    // An upright clip gets none.
    let o = ace(&["--threads", "1", "retarget", "assets/motions/walk.bvh", "--character", "spot", "--out", &s(&dir.join("walk.glb"))]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(!stderr(&o).contains("upright"), "{}", stderr(&o));
}

#[test]
fn train_prior_never_changes_the_prior_under_an_ace_stage() {
    let dir = scratch("prior-under-ace");
    let ck = dir.join("ck");
    let (prior_cfg, ace_cfg, longer) = (dir.join("prior.toml"), dir.join("ace.toml"), dir.join("prior-longer.toml"));
    std::fs::write(&prior_cfg, TINY_PRIOR).unwrap();
    std::fs::write(&ace_cfg, TINY_ACE).unwrap();
    std::fs::write(&longer, TINY_PRIOR.replace("steps = 40", "steps = 80")).unwrap();
    run_ok(&["--threads", "1", "train-prior", "--character", "stretch", "--frames", "3000", "--config", &s(&prior_cfg), "--checkpoint", &s(&ck)]);
    run_ok(&["--threads", "1", "train", "--character", "stretch", "--config", &s(&ace_cfg), "--checkpoint", &s(&ck), "--humans", "assets/motions"]);
    let before = snapshot_with_times(&ck);
    // More steps would resume the prior and save new weights under ace.json, which records the old.
    refused_up_front(
        &["--threads", "1", "train-prior", "--character", "stretch", "--frames", "3000", "--config", &s(&longer), "--checkpoint", &s(&ck)],
        &format!(
            "{}: holds an ACE stage (ace.json) trained against its prior (trained to step 40); training the prior to \
             step 80 would replace the weights the generator was trained with, and the checkpoint would no longer \
             load: use another --checkpoint directory, or remove ace.json, generator.safetensors and \
             discriminator.safetensors first to train the ACE stage again after",
            ck.display()
        ),
    );
    assert_eq!(snapshot_with_times(&ck), before);
    // Rerunning the finished prior (as scripts/train-checkpoints.sh does on a rerun) changes nothing it
    // was trained against, and the checkpoint still loads.
    let weights = |f: &str| std::fs::read(ck.join(f)).unwrap();
    let (prior, config) = (weights("prior.safetensors"), weights("config.json"));
    run_ok(&["--threads", "1", "train-prior", "--character", "stretch", "--frames", "3000", "--config", &s(&prior_cfg), "--checkpoint", &s(&ck)]);
    assert!(weights("prior.safetensors") == prior && weights("config.json") == config);
    run_ok(&["--threads", "1", "retarget", "assets/motions/walk.bvh", "--character", "stretch", "--checkpoint", &s(&ck), "--out", &s(&dir.join("walk.glb"))]);
}

/// A `reference.json` of another checkpoint (the crab's Ψ has 37 entries, Spot's 28) made FID panic on
/// Gaussians of different dimensions: it is refused when the checkpoint is scored, naming the file,
/// and nothing is written.
#[test]
fn a_reference_of_another_checkpoint_is_refused_naming_it() {
    let dir = scratch("reference");
    let ck = dir.join("ck");
    copy_dir(&root().join("assets/checkpoints/spot"), &ck);
    std::fs::copy(root().join("assets/checkpoints/crab/reference.json"), ck.join("reference.json")).unwrap();
    let before = snapshot(&dir);
    let out = dir.join("o.glb");
    let o = ace(&[
        "--threads", "1", "retarget", "assets/motions/walk.bvh", "--character", "spot", "--checkpoint", &s(&ck),
        "--out", &s(&out),
    ]);
    assert!(!o.status.success());
    let e = stderr(&o);
    assert!(!e.contains("panicked"), "{e}");
    assert!(
        e.contains(&format!(
            "{}: the Gaussian fit has a mean of 37 entries and a 37 × 37 covariance, but the checkpoint's Ψ has 28 \
             entries: it is not this checkpoint's reference; remove it to score without FID, or rerun `ace train` to \
             write it again",
            s(&ck.join("reference.json"))
        )),
        "{e}"
    );
    assert_eq!(snapshot(&dir), before, "nothing written");
}

/// A `reference.json` of the same width left from another training (an `ace train` stopped before its
/// end keeps the previous fit beside the new generator) is recognised by what it records: the prior,
/// the mapping and the body length it was fitted for. One recording this checkpoint's is accepted.
#[test]
fn a_reference_left_from_another_training_is_refused_naming_what_differs() {
    let dir = scratch("stale-reference");
    let ck = dir.join("ck");
    copy_dir(&root().join("assets/checkpoints/spot"), &ck);
    let ace_json: Value = serde_json::from_slice(&std::fs::read(ck.join("ace.json")).unwrap()).unwrap();
    let shipped: Value = serde_json::from_slice(&std::fs::read(ck.join("reference.json")).unwrap()).unwrap();
    let with = |key: &str, value: Value| {
        let mut v = shipped.clone();
        v[key] = value;
        std::fs::write(ck.join("reference.json"), serde_json::to_string(&v).unwrap()).unwrap();
    };
    let retarget = || {
        ace(&["--threads", "1", "retarget", "assets/motions/walk.bvh", "--character", "spot", "--checkpoint", &s(&ck), "--out", &s(&dir.join("o.glb"))])
    };
    let mut other_prior = ace_json["prior"].clone();
    other_prior["fnv1a64"] = Value::from("0123456789abcdef");
    let mut other_mapping = ace_json["correspondence"]["mapping"].clone();
    let human = other_mapping["human"].as_array_mut().unwrap();
    human.swap(0, 1);
    let body = ace_json["body_lengths"]["character"].as_f64().unwrap();
    for (key, value, what) in [
        ("prior", other_prior, "its prior"),
        ("mapping", other_mapping, "its end-effector mapping"),
        ("character_body_length", Value::from(body * 2.0), "its character body length"),
    ] {
        with(key, value);
        let before = snapshot(&dir);
        let o = retarget();
        let e = stderr(&o);
        assert!(!o.status.success(), "{key}: {e}");
        let want = format!(
            "{}: it was written for another training ({what} differs from ace.json's): rerun `ace train` to finish and \
             write it again, or remove it to score without FID",
            s(&ck.join("reference.json"))
        );
        assert!(e.contains(&want), "{key}:\n{e}");
        assert_eq!(snapshot(&dir), before, "nothing written");
    }
    let mut v = shipped.clone();
    v["prior"] = ace_json["prior"].clone();
    v["mapping"] = ace_json["correspondence"]["mapping"].clone();
    v["character_body_length"] = Value::from(body);
    std::fs::write(ck.join("reference.json"), serde_json::to_string(&v).unwrap()).unwrap();
    let o = retarget();
    assert!(o.status.success(), "{}", stderr(&o));
}

/// A write that fails midway (here a file size limit, as a full disk would) is reported naming the
/// output, not only its staged temporary, which is removed with the rest of the set: nothing new is
/// left beside the previous outputs.
#[test]
fn a_failed_write_names_the_output_and_leaves_the_previous_set() {
    let dir = scratch("failed-write");
    let out = dir.join("o.glb");
    let previous = ["o.glb", "o.json", "o.csv", "o.metrics.json"];
    for name in previous {
        std::fs::write(dir.join(name), "previous").unwrap();
    }
    let before = snapshot(&dir);
    // 64 KB at most per file (SIGXFSZ ignored, so the write fails with EFBIG): the glTF is larger.
    let o = Command::new("sh")
        .args(["-c", "ulimit -f 64; trap '' XFSZ; exec \"$@\"", "sh", env!("CARGO_BIN_EXE_ace")])
        .args(["--threads", "1", "retarget", "assets/motions/walk.bvh", "--character", "stretch", "--out", &s(&out)])
        .current_dir(root())
        .output()
        .unwrap();
    assert!(!o.status.success());
    let e = stderr(&o);
    assert!(e.contains(&format!("writing {}", s(&out))) && e.contains("File too large"), "{e}");
    assert_eq!(snapshot(&dir), before, "the previous outputs are kept and no temporary is left");
}
