//! Hostile and broken input to the readers: nothing panics, overflows the stack or allocates from a
//! header, nothing absurd is accepted silently, and every error names the file and the problem.

use std::path::{Path, PathBuf};

use ace_models::human::{HumanClip, HumanImportError, ImportOptions};
use ace_models::kinematics::KinematicTree;
use ace_models::urdf::parse_urdf;

fn asset(rel: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("..").join(rel)
}

fn walk() -> String {
    std::fs::read_to_string(asset("assets/motions/walk.bvh")).unwrap()
}

fn scratch(name: &str) -> PathBuf {
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR")).join("reliability").join(name);
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

fn import_err(text: &str) -> String {
    HumanClip::from_bvh_str(text, "bad.bvh", &ImportOptions::default())
        .map(|c| format!("imported {} frames", c.frames.len()))
        .unwrap_err()
        .to_string()
}

/// The walk clip with its first motion line's values replaced by `f(k, v)`.
fn walk_with_first_frame(f: impl Fn(usize, f32) -> f32) -> String {
    let text = walk();
    let (head, motion) = text.split_once("Frame Time: 0.033333\n").unwrap();
    let mut lines = motion.lines();
    let first: Vec<String> = lines
        .next()
        .unwrap()
        .split_whitespace()
        .enumerate()
        .map(|(k, v)| f(k, v.parse().unwrap()).to_string())
        .collect();
    let rest: Vec<&str> = lines.collect();
    format!("{head}Frame Time: 0.033333\n{}\n{}\n", first.join(" "), rest.join("\n"))
}

#[test]
fn a_huge_frame_count_in_the_header_is_not_allocated() {
    // 78 KB of text declaring 10^12 frames: the reader must find the file truncated, not abort
    // allocating 10^12 × channels values first.
    let text = walk().replace("Frames: 150", "Frames: 1000000000000");
    let e = import_err(&text);
    assert!(
        e.contains("bad.bvh") && e.contains("truncated") && e.contains("Frames: 1000000000000"),
        "{e}"
    );
    assert!(e.contains("only 150"), "{e}");
}

#[test]
fn more_motion_lines_than_declared_is_an_error() {
    let text = walk().replace("Frames: 150", "Frames: 149");
    let e = import_err(&text);
    // Line 134 + 149 frames: the 150th frame sits on line 284.
    assert!(
        e.contains("bad.bvh, line 284") && e.contains("more motion lines than `Frames: 149`"),
        "{e}"
    );
    // Trailing blank lines are not frames.
    let ok = HumanClip::from_bvh_str(&format!("{}\n\n\n", walk()), "ok.bvh", &ImportOptions::default()).unwrap();
    assert_eq!(ok.frames.len(), 150);
}

#[test]
fn an_absurd_frame_time_is_an_error() {
    for t in ["1e-9", "0.00001", "100"] {
        let e = import_err(&walk().replace("Frame Time: 0.033333", &format!("Frame Time: {t}")));
        assert!(
            e.contains("bad.bvh, line 134") && e.contains(&format!("`Frame Time: {t}`")),
            "{e}"
        );
        assert!(e.contains("expected 0.001 to 10 seconds per frame"), "{e}");
    }
}

/// The walk clip with `frames` motion lines (its own, repeated) at `Frame Time: {frame_time}`.
fn walk_of(frames: usize, frame_time: &str) -> String {
    let text = walk();
    let (head, motion) = text.split_once("MOTION\n").unwrap();
    let lines: Vec<&str> = motion.lines().skip(2).filter(|l| !l.trim().is_empty()).collect();
    let body: Vec<&str> = (0..frames).map(|k| lines[k % lines.len()]).collect();
    format!("{head}MOTION\nFrames: {frames}\nFrame Time: {frame_time}\n{}\n", body.join("\n"))
}

#[test]
fn a_long_frame_time_is_not_resampled_into_more_frames_than_memory_holds() {
    use ace_models::human::bvh::MAX_CLIP_SECONDS;
    use ace_models::human::import::MAX_RESAMPLED_FRAMES;
    // 2,000 frames of 10 s each: 20,000 s, 600,000 frames at the project's 30 fps. Refused by the
    // reader, naming the header (line 134), before any frame is computed.
    let start = std::time::Instant::now();
    let opts = ImportOptions { fps: Some(30.0), mapping: None };
    let e = HumanClip::from_bvh_str(&walk_of(2_000, "10"), "long.bvh", &opts).unwrap_err().to_string();
    assert_eq!(
        e,
        format!(
            "long.bvh, line 134: `Frames: 2000` at `Frame Time: 10` is 20000 s of motion; clips of at most \
             {MAX_CLIP_SECONDS} s (2 hours) are read: split the clip"
        )
    );
    // Within the reader's two hours, a target frame rate that would make more frames than the limit is
    // refused too: 700 frames of 10 s (6,990 s) at 100 fps.
    let opts = ImportOptions { fps: Some(100.0), mapping: None };
    let e = HumanClip::from_bvh_str(&walk_of(700, "10"), "long.bvh", &opts).unwrap_err().to_string();
    assert_eq!(
        e,
        format!(
            "long.bvh: `Frames: 700` at `Frame Time: 10` (6990 s) resampled to 100 fps would be 699001 frames; \
             at most {MAX_RESAMPLED_FRAMES} are made: split the clip"
        )
    );
    assert!(start.elapsed() < std::time::Duration::from_secs(1), "{:?}", start.elapsed());
    // The same 700 frames at 30 fps (209,700 frames) are within both limits.
    let opts = ImportOptions { fps: Some(30.0), mapping: None };
    let clip = HumanClip::from_bvh_str(&walk_of(700, "10"), "long.bvh", &opts).unwrap();
    assert_eq!(clip.frames.len(), 209_701);
}

/// A chain of `depth` joints below a root, one frame.
fn deep_chain(depth: usize) -> String {
    let mut s = String::from("HIERARCHY\nROOT Hips\n{\nOFFSET 0 0 0\nCHANNELS 3 Xposition Yposition Zposition\n");
    for k in 0..depth {
        s.push_str(&format!("JOINT J{k}\n{{\nOFFSET 0 1 0\nCHANNELS 1 Zrotation\n"));
    }
    s.push_str("End Site\n{\nOFFSET 0 1 0\n}\n");
    for _ in 0..=depth {
        s.push_str("}\n");
    }
    s.push_str("MOTION\nFrames: 1\nFrame Time: 0.033333\n0 0 0");
    s.push_str(&" 0".repeat(depth));
    s.push('\n');
    s
}

#[test]
fn deep_joint_chains_do_not_overflow_the_stack() {
    // Run on a thread with a small stack: the reader must not recurse on the file's depth. A chain of
    // 1000 joints (the most a file may have) parses; one more is refused at its line.
    let handle = std::thread::Builder::new()
        .stack_size(256 * 1024)
        .spawn(|| {
            let text = deep_chain(999);
            let bvh = ace_models::human::bvh::Bvh::parse(&text, "deep.bvh").unwrap();
            assert_eq!(bvh.joints.len(), ace_models::human::bvh::MAX_JOINTS);
            assert_eq!(bvh.joints[999].parent, Some(998));
            (import_err(&text), import_err(&deep_chain(1000)), import_err(&deep_chain(100_000)))
        })
        .unwrap();
    let (generic, over, far_over) = handle.join().expect("no stack overflow");
    // Generic names: an unknown skeleton, with a bounded list of joints.
    assert!(generic.starts_with("bad.bvh: unknown skeleton") && generic.contains("J58, … and"), "{generic}");
    assert!(generic.len() < 2_000, "the message lists a bounded number of joints ({} bytes)", generic.len());
    // `JOINT J999`, the 1001st joint, is on line 6 + 4 × 999.
    for e in [over, far_over] {
        assert_eq!(e, "bad.bvh, line 4002: joint `J999` is one more than the 1000 joints a file may have");
    }
}

/// `walk.bvh` with `extra` more `End Site` blocks (offset zero) in `LeftToe`.
fn walk_with_end_sites(extra: usize) -> String {
    let site = "          End Site\n          {\n            OFFSET 0.0000 0.0000 0.0000\n          }\n";
    let at = "            OFFSET 0.0000 0.0000 5.0000\n          }\n";
    walk().replacen(at, &format!("{at}{}", site.repeat(extra)), 1)
}

/// Every point under a foot is posed in every frame for the floor: the number of end sites is bounded
/// like the joints', and the feet are kept per frame as a box, whatever their number of points.
#[test]
fn end_sites_are_bounded_and_do_not_change_the_floor() {
    let opts = ImportOptions::default();
    let base = HumanClip::from_bvh_str(&walk(), "walk.bvh", &opts).unwrap();
    // The walk has 5 end sites: 995 more make the most a file may have, at the toe's own point.
    let most = HumanClip::from_bvh_str(&walk_with_end_sites(995), "walk.bvh", &opts).unwrap();
    assert_eq!(most.frames, base.frames);
    // One more: the 1001st is then `RightToe`'s own, on line 123 + 4 × 996.
    let e = import_err(&walk_with_end_sites(996));
    assert_eq!(e, "bad.bvh, line 4107: `End Site` in joint `RightToe` is one more than the 1000 a file may have");
}

#[test]
fn duplicate_joint_names_are_an_error_naming_both_lines() {
    // Two joints called `LeftArm`: matching would otherwise map right_upper_arm to the clavicle.
    let text = walk().replace("JOINT RightShoulder", "JOINT LeftArm");
    let e = import_err(&text);
    assert!(
        e.contains("bad.bvh, line 56") && e.contains("duplicate joint name `LeftArm` (first defined at line 36)"),
        "{e}"
    );
}

#[test]
fn a_skeleton_without_legs_or_bone_lengths_is_said_to_be_so() {
    // No legs: drop everything from the left hip on.
    let text = walk();
    let cut = text.find("  JOINT LeftUpLeg").unwrap();
    let motion = text.find("MOTION").unwrap();
    let channels_kept = 6 + 3 * 13; // root + the 13 upper-body joints with channels
    let values: Vec<String> = text[motion..]
        .lines()
        .skip(3)
        .map(|l| l.split_whitespace().take(channels_kept).collect::<Vec<_>>().join(" "))
        .collect();
    let legless = format!(
        "{}}}\nMOTION\nFrames: 150\nFrame Time: 0.033333\n{}\n",
        &text[..cut],
        values.join("\n")
    );
    let e = import_err(&legless);
    assert!(e.contains("bad.bvh: the skeleton has no left leg"), "{e}");
    assert!(!e.contains("unknown skeleton"), "{e}");

    // All-zero offsets.
    let mut zero = String::new();
    for line in text[..motion].lines() {
        if line.trim_start().starts_with("OFFSET") {
            zero.push_str("OFFSET 0 0 0\n");
        } else {
            zero.push_str(line);
            zero.push('\n');
        }
    }
    zero.push_str(&text[motion..]);
    let e = import_err(&zero);
    assert!(e.contains("bad.bvh: every OFFSET below the root is zero"), "{e}");
}

#[test]
fn absurd_finite_values_are_refused_after_unit_detection() {
    // 1e30 in the root's position channel of frame 1.
    let e = import_err(&walk_with_first_frame(|k, v| if k == 1 { 1e30 } else { v }));
    assert!(
        e.contains(
            "bad.bvh: implausible motion: position channel 2 of joint `Hips` (line 2) is 1e30 file units in frame 1"
        ),
        "{e}"
    );
    // 5e6 cm passes as a file value but is 50 km once the unit is known.
    let e = import_err(&walk_with_first_frame(|k, v| if k == 1 { 5e6 } else { v }));
    assert!(
        e.contains("bad.bvh: implausible motion") && e.contains("m from the origin in frame 1 (unit cm)"),
        "{e}"
    );
    // 1e30 in the root's OFFSET (was detected as inches before), and in a bone's.
    for (from, line) in [("OFFSET 0.0000 95.0000 0.0000", 2), ("OFFSET 0.0000 10.0000 0.0000", 6)] {
        let e = import_err(&walk().replacen(from, "OFFSET 0.0000 1e30 0.0000", 1));
        assert!(
            e.contains(&format!("bad.bvh: implausible motion: joint"))
                && e.contains(&format!("(line {line}) has an OFFSET of 1e30")),
            "{e}"
        );
    }
    // A rotation of 1e30 degrees.
    let e = import_err(&walk_with_first_frame(|k, v| if k == 10 { 1e30 } else { v }));
    assert!(
        e.contains("bad.bvh: implausible motion: rotation channel") && e.contains("frame 1"),
        "{e}"
    );
}

#[test]
fn utf16_files_get_an_encoding_hint_and_fifos_are_refused() {
    let dir = scratch("encoding");
    let path = dir.join("walk16.bvh");
    let mut bytes = vec![0xFF, 0xFE];
    bytes.extend(walk().encode_utf16().flat_map(|u| u.to_le_bytes()));
    std::fs::write(&path, bytes).unwrap();
    let e = HumanClip::from_bvh_file(&path, &ImportOptions::default())
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("walk16.bvh") && e.contains("UTF-16 encoded; save it as UTF-8"),
        "{e}"
    );

    let fifo = dir.join("pipe.bvh");
    assert!(
        std::process::Command::new("mkfifo")
            .arg(&fifo)
            .status()
            .unwrap()
            .success()
    );
    // A FIFO would block the reader forever: it must be refused without opening it.
    let (tx, rx) = std::sync::mpsc::channel();
    let f = fifo.clone();
    std::thread::spawn(move || {
        let _ = tx.send(
            HumanClip::from_bvh_file(&f, &ImportOptions::default())
                .map(|_| ())
                .unwrap_err()
                .to_string(),
        );
    });
    let e = rx
        .recv_timeout(std::time::Duration::from_secs(20))
        .expect("the reader hung on a FIFO");
    assert!(e.contains("pipe.bvh") && e.contains("not a regular file"), "{e}");
    let e = ace_models::urdf::read_urdf_file(&fifo).unwrap_err().to_string();
    assert!(e.contains("pipe.bvh") && e.contains("not a regular file"), "{e}");
}

#[test]
fn a_mapping_file_beside_the_clip_is_read() {
    let dir = scratch("mapping");
    let data = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data");
    let clip = dir.join("rig.bvh");
    std::fs::copy(data.join("unknown_rig.bvh"), &clip).unwrap();
    let err = HumanClip::from_bvh_file(&clip, &ImportOptions::default()).unwrap_err();
    assert!(matches!(err, HumanImportError::Unmapped { .. }), "{err}");
    assert!(err.to_string().contains("--mapping FILE"), "{err}");
    std::fs::copy(data.join("unknown_rig.toml"), dir.join("rig.mapping.toml")).unwrap();
    let clip = HumanClip::from_bvh_file(&clip, &ImportOptions::default()).unwrap();
    assert_eq!(clip.convention, "user-mapping");
    assert_eq!(clip.mapped_joints, 17);
    // A broken mapping beside the clip is reported, naming that file.
    std::fs::write(dir.join("rig.mapping.toml"), "pelvis = 3\n").unwrap();
    let e = HumanClip::from_bvh_file(&dir.join("rig.bvh"), &ImportOptions::default())
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("rig.mapping.toml") && e.contains("`pelvis` must be a string"),
        "{e}"
    );
}

#[test]
fn a_lying_clip_gets_a_posture_warning() {
    let clip = HumanClip::from_bvh_str(&walk(), "walk", &ImportOptions::default()).unwrap();
    assert_eq!(clip.posture_warning(), None);
    assert!(clip.upright_fraction() > 0.99);
    // The same clip turned 90° about the y axis: the person lies on the floor.
    let turn = ace_models::nalgebra::UnitQuaternion::from_axis_angle(&ace_models::nalgebra::Vector3::y_axis(), 1.5708);
    let mut lying = clip.clone();
    for f in &mut lying.frames {
        f.root_rotation = turn * f.root_rotation;
        for p in f.positions.iter_mut() {
            *p = turn * *p;
        }
    }
    let w = lying.posture_warning().expect("a warning");
    assert!(
        w.starts_with("walk: the pelvis is upright (within 60° of vertical) in only 0 % of the frames"),
        "{w}"
    );
}

#[test]
fn a_clip_whose_pelvis_jumps_gets_a_warning_naming_when() {
    let clip = HumanClip::from_bvh_str(&walk(), "walk", &ImportOptions::default()).unwrap();
    assert_eq!(clip.root_jump_warning(), None);
    assert!(clip.warnings().is_empty());
    let (speed, _) = clip.fastest_root_move().unwrap();
    assert!(speed > 0.5 && speed < 5.0, "a walk's pelvis moves at {speed} m/s");
    // From frame 40 on the person stands 1 m further along x: a cut.
    let mut cut = clip.clone();
    for f in &mut cut.frames[40..] {
        for p in f.positions.iter_mut() {
            p.x += 1.0;
        }
    }
    let w = cut.root_jump_warning().expect("a warning");
    let t = 40.0 / cut.fps;
    assert!(w.starts_with(&format!("walk: the pelvis jumps 1.0")) && w.contains(&format!("in one frame at {t:.2} s")), "{w}");
    assert_eq!(cut.warnings(), [w]);
    // Just under the bound: no warning.
    let mut fast = clip.clone();
    let step = 0.99 * ace_models::human::clip::MAX_ROOT_SPEED / fast.fps - (fast.frames[41].positions[0] - fast.frames[40].positions[0]).x;
    for f in &mut fast.frames[41..] {
        for p in f.positions.iter_mut() {
            p.x += step;
        }
    }
    assert!(fast.fastest_root_move().unwrap().0 < ace_models::human::clip::MAX_ROOT_SPEED);
    assert_eq!(fast.root_jump_warning(), None);
}

const ROBOT: &str = r#"<robot name="r">
  <link name="world"/>
  <link name="base"><collision><geometry><box size="0.4 0.2 0.1"/></geometry></collision></link>
  <link name="leg"><collision><geometry><box size="0.05 0.05 0.3"/></geometry></collision></link>
  <joint name="anchor" type="JOINT_TYPE"><parent link="world"/><child link="base"/></joint>
  <joint name="hip" type="revolute"><parent link="base"/><child link="leg"/><axis xyz="0 1 0"/>
    <limit lower="LOWER" upper="UPPER" effort="1" velocity="1"/></joint>
</robot>"#;

fn robot(anchor: &str, lower: &str, upper: &str) -> String {
    ROBOT
        .replace("JOINT_TYPE", anchor)
        .replace("LOWER", lower)
        .replace("UPPER", upper)
}

#[test]
fn urdf_inverted_limits_and_free_joints_in_the_body_are_errors() {
    let e = parse_urdf(&robot("fixed", "1.0", "-1.0"), "inv.urdf", None)
        .unwrap_err()
        .to_string();
    assert_eq!(
        e,
        "inv.urdf: joint `hip` has inverted limits: lower 1 > upper -1; the lower limit must not exceed the upper"
    );
    // A floating anchor from a geometry-less root link to the body: the link is a frame, dropped with a
    // warning the CLI prints.
    for kind in ["floating", "planar"] {
        let tree: KinematicTree = parse_urdf(&robot(kind, "-1", "1"), "anchor.urdf", None).unwrap();
        assert_eq!(tree.links[0].name, "base");
        assert!(
            tree.warnings
                .iter()
                .any(|w| w.contains(&format!("by its {kind} joint `anchor`: it is a frame"))),
            "{:?}",
            tree.warnings
        );
    }
    // A planar joint inside the body would be frozen silently: refused.
    let body = robot("fixed", "-1", "1").replace(r#"name="hip" type="revolute""#, r#"name="hip" type="planar""#);
    let e = parse_urdf(&body, "body.urdf", None).unwrap_err().to_string();
    assert!(
        e.starts_with("body.urdf: joint `hip` is planar between links `base` and `leg`"),
        "{e}"
    );
}

#[test]
fn a_truncated_urdf_error_gives_a_position() {
    let full = robot("fixed", "-1", "1");
    let cut = &full[..full.find("<link name=\"leg\">").unwrap() + 17];
    let e = parse_urdf(cut, "cut.urdf", None).unwrap_err().to_string();
    assert!(e.starts_with("cut.urdf: malformed URDF/XML"), "{e}");
    assert!(
        e.contains("the file ends at line 4") && e.contains("`<link>` (line 4, column 3) still open"),
        "{e}"
    );
}

#[test]
fn training_configurations_are_bounded_and_strict() {
    use ace_models::learn::ace::AceConfig;
    use ace_models::learn::prior::{DeviceChoice, PriorConfig};
    let ace = |s: &str| toml::from_str::<AceConfig>(s);
    let check = |s: &str| ace(s).unwrap().check().unwrap_err().to_string();
    assert_eq!(
        check("batch_size = 1000000000"),
        "invalid configuration: `batch_size` = 1000000000 is out of range: expected 1 to 65536"
    );
    assert_eq!(
        check("steps = 0"),
        "invalid configuration: `steps` = 0 is out of range: expected 1 to 100000000"
    );
    assert_eq!(
        check("generator_hidden = [100000]"),
        "invalid configuration: `generator_hidden` = 100000 is out of range: expected 1 to 16384"
    );
    assert_eq!(
        check("[feature_weights]\nroot_height = -1.0"),
        "invalid configuration: `feature_weights.root_height` = -1 is out of range: expected a finite weight ≥ 0"
    );
    // Every float field: its name, the value and the valid range.
    for (text, want) in [
        ("generator_lr = 0.0", "`generator_lr` = 0 is out of range: expected more than 0 to 1"),
        ("discriminator_lr = 5.0", "`discriminator_lr` = 5 is out of range: expected more than 0 to 1"),
        ("generator_lr = nan", "`generator_lr` = NaN is out of range: expected more than 0 to 1"),
        ("w_adv = -1.0", "`w_adv` = -1 is out of range: expected 0 to 1000000"),
        ("w_fea = 1e30", "`w_fea` = 1000000000000000000000000000000 is out of range: expected 0 to 1000000"),
        ("w_gp = inf", "`w_gp` = inf is out of range: expected 0 to 1000000"),
        ("adam_beta1 = 1.0", "`adam_beta1` = 1 is out of range: expected 0 to less than 1"),
    ] {
        assert_eq!(check(text), format!("invalid configuration: {want}"), "{text}");
    }
    let e = ace("[feature_weights]\nroot_heigth = 2.0").unwrap_err().to_string();
    assert!(e.contains("unknown field `root_heigth`"), "{e}");
    let prior = |s: &str| {
        toml::from_str::<PriorConfig>(s)
            .unwrap()
            .check()
            .unwrap_err()
            .to_string()
    };
    assert_eq!(
        prior("batch_size = 0"),
        "invalid configuration: `batch_size` = 0 is out of range: expected 1 to 65536"
    );
    let nkn = |lr: f64, w_cyc: f64| {
        let c = ace_models::learn::nkn::NknConfig { generator_lr: lr, w_cyc, ..Default::default() };
        c.check().unwrap_err().to_string()
    };
    assert_eq!(nkn(2.0, 1.0), "invalid configuration: `generator_lr` = 2 is out of range: expected more than 0 to 1");
    assert_eq!(nkn(1e-4, -1.0), "invalid configuration: `w_cyc` = -1 is out of range: expected 0 to 1000000");
    for (text, want) in [
        ("learning_rate = -0.001", "`learning_rate` = -0.001 is out of range: expected more than 0 to 1"),
        ("learning_rate = 10.0", "`learning_rate` = 10 is out of range: expected more than 0 to 1"),
        ("kl_weight = 1e9", "`kl_weight` = 1000000000 is out of range: expected 0 to 1000000"),
        ("free_bits = -0.5", "`free_bits` = -0.5 is out of range: expected 0 to 100"),
        ("bound_margin = 3.0", "`bound_margin` = 3 is out of range: expected 0 to 1"),
    ] {
        assert_eq!(prior(text), format!("invalid configuration: {want}"), "{text}");
    }
    // `device = "cuda"` is the first CUDA device; an unknown one lists what is valid.
    assert_eq!(ace("device = \"cuda\"").unwrap().device, DeviceChoice::Cuda(0));
    assert_eq!(ace("device = \"cuda:1\"").unwrap().device, DeviceChoice::Cuda(1));
    assert_eq!(ace("device = { cuda = 2 }").unwrap().device, DeviceChoice::Cuda(2));
    assert_eq!(ace("device = \"cpu\"").unwrap().device, DeviceChoice::Cpu);
    let e = ace("device = \"tpu\"").unwrap_err().to_string();
    assert!(
        e.contains("unknown device `tpu`: expected \"auto\", \"cpu\", \"cuda\", \"cuda:N\" or { cuda = N }"),
        "{e}"
    );
    // The stored form reads back.
    let json = serde_json::to_string(&DeviceChoice::Cuda(3)).unwrap();
    assert_eq!(
        serde_json::from_str::<DeviceChoice>(&json).unwrap(),
        DeviceChoice::Cuda(3)
    );
}

#[test]
fn dataset_frames_are_bounded_before_allocation() {
    use ace_models::dataset::{DatasetConfig, MAX_FRAMES, check_config};
    let cfg = DatasetConfig {
        frames: 1_000_000_000_000,
        ..DatasetConfig::default()
    };
    assert_eq!(
        check_config(&cfg).unwrap_err().to_string(),
        format!("invalid dataset configuration: `frames` = 1000000000000 is out of range: expected 1 to {MAX_FRAMES}")
    );
}

/// A serial chain of `links` links joined by revolute joints.
fn chain_robot(links: usize) -> String {
    let mut s = String::from("<robot name=\"chain\">\n");
    for i in 0..links {
        s.push_str(&format!("<link name=\"l{i}\"/>\n"));
        if i > 0 {
            s.push_str(&format!(
                "<joint name=\"j{i}\" type=\"revolute\"><parent link=\"l{}\"/><child link=\"l{i}\"/><origin xyz=\"0 0 0.01\"/><axis xyz=\"0 1 0\"/><limit lower=\"-1\" upper=\"1\" effort=\"1\" velocity=\"1\"/></joint>\n",
                i - 1
            ));
        }
    }
    s.push_str("</robot>\n");
    s
}

#[test]
fn a_urdf_with_more_links_than_supported_is_refused_before_any_work() {
    use ace_models::urdf::MAX_LINKS;
    // At the limit the chain imports, with one DoF per joint.
    let tree = parse_urdf(&chain_robot(MAX_LINKS), "long.urdf", None).unwrap();
    assert_eq!((tree.links.len(), tree.dof()), (MAX_LINKS, MAX_LINKS - 1));
    // One more, or 100,000 (which took 9.9 GB in `ace dataset` before the limit), is an error naming
    // the file, the count and the limit.
    for links in [MAX_LINKS + 1, 100_000] {
        let e = parse_urdf(&chain_robot(links), "huge.urdf", None).unwrap_err().to_string();
        assert_eq!(e, format!("huge.urdf: the robot has {links} links, more than the {MAX_LINKS} supported"));
    }
}

#[test]
fn sizes_each_in_range_are_bounded_together_before_any_allocation() {
    use ace_models::checkpoint::limits::{ACTIVATIONS, HIDDEN_WEIGHTS, STEP_FRAMES};
    use ace_models::learn::ace::AceConfig;
    use ace_models::learn::prior::PriorConfig;
    let ace = |s: &str| toml::from_str::<AceConfig>(s).unwrap().check().unwrap_err().to_string();
    let prior = |s: &str| toml::from_str::<PriorConfig>(s).unwrap().check().unwrap_err().to_string();
    let over = |what: &str, v: u128, limit: usize, advice: &str| {
        format!("invalid configuration: {what} = {v}, more than the {limit} a training step may use; {advice}")
    };
    // Every value is within its own bound (batch_size ≤ 65536, window ≤ 1024, widths ≤ 16384, 64 layers).
    assert_eq!(
        ace("batch_size = 65536\nwindow = 1024"),
        over("`batch_size` × `window` (frames per step)", 65536 * 1024, STEP_FRAMES, "lower batch_size or window")
    );
    let hidden = format!("generator_hidden = [{}]", vec!["16384"; 64].join(", "));
    assert_eq!(
        ace(&hidden),
        over(
            "the weights between the hidden layers of `generator_hidden` and `discriminator_hidden`",
            63 * 16384 * 16384 + 2 * 256 * 256,
            HIDDEN_WEIGHTS,
            "use fewer or narrower hidden layers"
        )
    );
    assert_eq!(
        ace("batch_size = 65536\nwindow = 16\ngenerator_hidden = [4096, 4096]"),
        over(
            "`batch_size` × `window` × the widths of `generator_hidden` and `discriminator_hidden` (hidden activations per step)",
            65536 * 16 * (2 * 4096 + 3 * 256),
            ACTIVATIONS,
            "lower batch_size or window, or use fewer or narrower hidden layers"
        )
    );
    assert_eq!(
        prior("batch_size = 65536\nrollout = 1024"),
        over("`batch_size` × `rollout` (frames per step)", 65536 * 1024, STEP_FRAMES, "lower batch_size or rollout")
    );
    assert_eq!(
        prior("experts = 256\ndecoder_hidden = [4096, 4096, 4096, 4096]"),
        over(
            "the weights between the hidden layers of `encoder_hidden`, `experts` × `decoder_hidden` and `gating_hidden`",
            3 * 256 * 256 + 256 * 3 * 4096 * 4096 + 64 * 64,
            HIDDEN_WEIGHTS,
            "use fewer experts or fewer or narrower hidden layers"
        )
    );
    // The defaults and the paper's sizes are well within.
    for cfg in [AceConfig::default(), AceConfig::paper()] {
        cfg.check().unwrap();
    }
    for cfg in [PriorConfig::default(), PriorConfig::paper()] {
        cfg.check().unwrap();
    }
}

#[test]
fn a_dataset_too_large_for_its_character_is_refused_before_allocation() {
    use ace_models::character_state::CharacterLayout;
    use ace_models::dataset::{DatasetConfig, MAX_DATASET_BYTES, MAX_FRAMES, check_budget, generate};
    use ace_models::urdf::MAX_LINKS;
    // The longest chain a URDF may have, and as many frames as `frames` allows: 40 GB of states.
    let tree = parse_urdf(&chain_robot(MAX_LINKS), "long.urdf", None).unwrap();
    let morph = ace_models::morphology::Morphology::analyze(&tree);
    let dim = CharacterLayout::new(&tree, &morph).dim();
    let cfg = DatasetConfig {
        frames: MAX_FRAMES,
        ..DatasetConfig::default()
    };
    let per_frame = 4 * (dim + 1023) as u64;
    let expected = format!(
        "invalid dataset configuration: `frames` = 5000000 of `chain` (1023 DoF, x^r of {dim} values: {per_frame} bytes a \
         frame) is {} bytes, more than the {MAX_DATASET_BYTES} a dataset may hold: at most {} frames of this character",
        5_000_000 * per_frame,
        MAX_DATASET_BYTES / per_frame
    );
    assert_eq!(check_budget(&cfg, &tree, &morph).unwrap_err().to_string(), expected);
    // `generate` refuses it the same way, before its first allocation (no progress is reported).
    let start = std::time::Instant::now();
    let mut reported = false;
    let e = generate(&tree, &morph, &cfg, &mut |_| reported = true).unwrap_err().to_string();
    assert_eq!(e, expected);
    assert!(!reported && start.elapsed() < std::time::Duration::from_secs(1));
    // The bundled characters fit at MAX_FRAMES.
    for name in ["spot", "crab", "stretch"] {
        let (tree, morph) = ace_models::morphology::load_character(&asset(&format!("assets/characters/{name}.urdf"))).unwrap();
        check_budget(&cfg, &tree, &morph).unwrap();
    }
}

include!("data/bad_dataset_configs.rs");

#[test]
fn every_dataset_configuration_field_is_bounded_before_generation() {
    use ace_models::dataset::{DatasetConfig, check_config, generate};
    let (tree, morph) = ace_models::morphology::load_character(&asset("assets/characters/stretch.urdf")).unwrap();
    for (text, problem) in BAD_DATASET_CONFIGS {
        let cfg: DatasetConfig = toml::from_str(&format!("frames = 300\n{text}\n")).unwrap();
        let expected = format!("invalid dataset configuration: {problem}");
        assert_eq!(check_config(&cfg).unwrap_err().to_string(), expected, "{text}");
        // `generate` refuses it before its first frame.
        let mut reported = false;
        let e = generate(&tree, &morph, &cfg, &mut |_| reported = true).unwrap_err().to_string();
        assert_eq!(e, expected, "{text}");
        assert!(!reported, "{text}: generated before checking");
    }
    // The defaults, and the configurations the bundled checkpoints' datasets were generated with (which
    // `ace train` regenerates), are within the bounds.
    check_config(&DatasetConfig::default()).unwrap();
    for name in ["spot", "crab", "stretch", "hound"] {
        let text = std::fs::read_to_string(asset(&format!("assets/checkpoints/{name}/config.json"))).unwrap();
        let v: serde_json::Value = serde_json::from_str(&text).unwrap();
        let cfg = DatasetConfig::from_record(v["provenance"]["dataset"]["config"].clone()).unwrap();
        check_config(&cfg).unwrap_or_else(|e| panic!("{name}: {e}"));
    }
}

#[test]
fn a_dataset_with_non_finite_values_is_neither_written_nor_read() {
    use ace_models::dataset::{DatasetConfig, MotionSet, generate};
    let (tree, morph) = ace_models::morphology::load_character(&asset("assets/characters/stretch.urdf")).unwrap();
    let cfg = DatasetConfig {
        frames: 120,
        ..DatasetConfig::default()
    };
    let good = generate(&tree, &morph, &cfg, &mut |_| {}).unwrap();
    assert_eq!(good.non_finite(), None);
    let dir = scratch("non-finite-dataset");
    let dim = good.layout.dim();
    // An infinity in frame 7's x^r (what `human_leg_length = 0` gave), then a NaN in a joint position.
    let mut bad = good.clone();
    bad.states[7 * dim + 2] = f32::INFINITY;
    bad.states[9 * dim] = f32::NAN;
    let path = dir.join("bad.safetensors");
    assert_eq!(
        bad.save(&path).unwrap_err().to_string(),
        format!(
            "{}: refusing to write a dataset that holds 2 non-finite value(s) (NaN or infinity) in `states`, the first \
             at frame 7 (column 2)",
            path.display()
        )
    );
    let mut bad_q = good.clone();
    bad_q.q[3 * good.dof() + 1] = f32::NAN;
    assert_eq!(
        bad_q.save(&path).unwrap_err().to_string(),
        format!(
            "{}: refusing to write a dataset that holds 1 non-finite value(s) (NaN or infinity) in `q`, the first at \
             frame 3 (column 1)",
            path.display()
        )
    );
    // Nothing was written, not even a temporary.
    assert_eq!(std::fs::read_dir(&dir).unwrap().count(), 0);
    // Such a file written by other means is refused by the reader, naming it.
    std::fs::write(&path, bad.to_bytes().unwrap()).unwrap();
    assert_eq!(
        MotionSet::load(&path).map(|_| "loaded").unwrap_err().to_string(),
        format!(
            "{}: the dataset holds 2 non-finite value(s) (NaN or infinity) in `states`, the first at frame 7 (column 2)",
            path.display()
        )
    );
    // A finite one round-trips.
    good.save(&path).unwrap();
    assert_eq!(MotionSet::load(&path).unwrap(), good);
}

/// `f()`'s result, which must come within 2 s (a reader that opened a FIFO would wait for a writer
/// forever).
fn within_2s(what: &str, f: impl FnOnce() -> String + Send + 'static) -> String {
    let (tx, rx) = std::sync::mpsc::channel();
    std::thread::spawn(move || {
        let _ = tx.send(f());
    });
    rx.recv_timeout(std::time::Duration::from_secs(2))
        .unwrap_or_else(|_| panic!("{what}: the reader hung (on a FIFO?)"))
}

fn mkfifo(path: &Path) {
    assert!(std::process::Command::new("mkfifo").arg(path).status().unwrap().success());
}

/// UTF-16 (little-endian, without a byte-order mark) of `text`.
fn utf16(text: &str) -> Vec<u8> {
    text.encode_utf16().flat_map(u16::to_le_bytes).collect()
}

const NOT_REGULAR: &str = "not a regular file (a directory, FIFO or device)";
const UTF16: &str = "the file is UTF-16 encoded; save it as UTF-8 (e.g. `iconv -f UTF-16 -t UTF-8`)";

#[test]
fn every_reader_refuses_fifos_without_hanging_and_hints_at_utf16() {
    use ace_models::dataset::MotionSet;
    use ace_models::human::JointMapping;
    use ace_models::morphology::Profile;
    use ace_models::runtime::Retargeter;
    use ace_models::urdf::read_urdf_file;
    let dir = scratch("readers");

    // The joint mapping, given or read beside a clip.
    let fifo = dir.join("walk.mapping.toml");
    mkfifo(&fifo);
    let f = fifo.clone();
    let e = within_2s("mapping", move || JointMapping::from_file(&f).map(|_| ()).unwrap_err().to_string());
    assert_eq!(e, format!("{}: {NOT_REGULAR}", fifo.display()));
    std::fs::copy(asset("assets/motions/walk.bvh"), dir.join("walk.bvh")).unwrap();
    let clip = dir.join("walk.bvh");
    let e = within_2s("clip with a mapping beside", move || {
        HumanClip::from_bvh_file(&clip, &ImportOptions::default()).map(|_| ()).unwrap_err().to_string()
    });
    assert_eq!(e, format!("{}: {NOT_REGULAR}", fifo.display()));
    let mapping16 = dir.join("rig16.toml");
    std::fs::write(&mapping16, utf16("pelvis = \"Hips\"\n")).unwrap();
    let e = JointMapping::from_file(&mapping16).map(|_| ()).unwrap_err().to_string();
    assert_eq!(e, format!("{}: {UTF16}", mapping16.display()));

    // The profile, read directly or beside its URDF (one that is there is never skipped).
    let urdf = dir.join("stretch.urdf");
    std::fs::copy(asset("assets/characters/stretch.urdf"), &urdf).unwrap();
    let profile = dir.join("stretch.profile.toml");
    mkfifo(&profile);
    let (p, u) = (profile.clone(), urdf.clone());
    let e = within_2s("profile", move || Profile::from_file(&p).map(|_| ()).unwrap_err().to_string());
    assert_eq!(e, format!("{}: cannot read the file: {NOT_REGULAR}", profile.display()));
    let e = within_2s("profile beside", move || Profile::beside(&u).map(|_| ()).unwrap_err().to_string());
    assert_eq!(e, format!("{}: cannot read the file: {NOT_REGULAR}", profile.display()));
    std::fs::remove_file(&profile).unwrap();
    std::fs::write(&profile, utf16("head = \"\"\n")).unwrap();
    let e = Profile::beside(&urdf).map(|_| ()).unwrap_err().to_string();
    assert_eq!(e, format!("{}: cannot read the file: {UTF16}", profile.display()));
    std::fs::remove_file(&profile).unwrap();

    // The URDF: a FIFO, and UTF-16 without a byte-order mark (it used to pass as UTF-8, NULs and all,
    // and fail as malformed XML).
    let fifo = dir.join("robot.urdf");
    mkfifo(&fifo);
    let f = fifo.clone();
    let e = within_2s("urdf", move || read_urdf_file(&f).map(|_| ()).unwrap_err().to_string());
    assert_eq!(e, format!("{}: cannot read the file: {NOT_REGULAR}", fifo.display()));
    let urdf16 = dir.join("stretch16.urdf");
    std::fs::write(&urdf16, utf16(&std::fs::read_to_string(&urdf).unwrap())).unwrap();
    let e = read_urdf_file(&urdf16).map(|_| ()).unwrap_err().to_string();
    assert_eq!(e, format!("{}: cannot read the file: {UTF16}", urdf16.display()));

    // Datasets (`ace metrics`, `--dataset`, `--reference`): binary, so a FIFO or a directory.
    let fifo = dir.join("set.safetensors");
    mkfifo(&fifo);
    let f = fifo.clone();
    let e = within_2s("dataset", move || MotionSet::load(&f).map(|_| ()).unwrap_err().to_string());
    assert_eq!(e, format!("{}: {NOT_REGULAR}", fifo.display()));
    let e = MotionSet::load(&dir).map(|_| ()).unwrap_err().to_string();
    assert_eq!(e, format!("{}: {NOT_REGULAR}", dir.display()));

    // Checkpoints, through the pure-Rust loader (the plugin's and `ace retarget`'s): each file a FIFO
    // in turn, and the JSON files in UTF-16.
    for name in ["config.json", "ace.json", "prior.safetensors", "generator.safetensors"] {
        let ck = dir.join(format!("ck-{name}"));
        std::fs::create_dir_all(&ck).unwrap();
        for e in std::fs::read_dir(asset("assets/checkpoints/stretch")).unwrap() {
            let p = e.unwrap().path();
            std::fs::copy(&p, ck.join(p.file_name().unwrap())).unwrap();
        }
        let file = ck.join(name);
        std::fs::remove_file(&file).unwrap();
        mkfifo(&file);
        let c = ck.clone();
        let e = within_2s(name, move || Retargeter::load(&c).map(|_| ()).unwrap_err().to_string());
        assert_eq!(e, format!("{}: {NOT_REGULAR}", file.display()));
        if name.ends_with(".json") {
            std::fs::remove_file(&file).unwrap();
            let text = std::fs::read_to_string(asset(&format!("assets/checkpoints/stretch/{name}"))).unwrap();
            std::fs::write(&file, utf16(&text)).unwrap();
            let e = Retargeter::load(&ck).map(|_| ()).unwrap_err().to_string();
            assert_eq!(e, format!("{}: {UTF16}", file.display()));
        }
    }
}

#[test]
fn a_checkpoint_with_implausible_human_statistics_is_refused_naming_its_ace_json() {
    use ace_models::runtime::Retargeter;
    let dir = scratch("human-stats");
    let original: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(asset("assets/checkpoints/stretch/ace.json")).unwrap()).unwrap();
    // A mean 5 km up (what clips with a poisoned root gave before training refused them), and one past
    // f32's range, which reads as infinity.
    for (entry, value, shown) in [("mean", "5e5", "mean 500000"), ("mean", "1e39", "mean inf"), ("std", "2e3", "standard deviation 2000")] {
        let ck = dir.join(format!("ck-{entry}-{value}"));
        std::fs::create_dir_all(&ck).unwrap();
        for e in std::fs::read_dir(asset("assets/checkpoints/stretch")).unwrap() {
            let p = e.unwrap().path();
            std::fs::copy(&p, ck.join(p.file_name().unwrap())).unwrap();
        }
        let mut v = original.clone();
        v["human_stats"][entry][3] = serde_json::from_str(value).unwrap();
        std::fs::write(ck.join("ace.json"), serde_json::to_string(&v).unwrap()).unwrap();
        let e = Retargeter::load(&ck).map(|_| ()).unwrap_err().to_string();
        let (mean, std) = (&v["human_stats"]["mean"][3], &v["human_stats"]["std"][3]);
        let number = |x: &serde_json::Value| -> f32 { x.as_f64().unwrap() as f32 };
        assert_eq!(
            e,
            format!(
                "{}: corrupt file: `human_stats` entry 3 has mean {} and standard deviation {}: no human motion gives \
                 more than 1000 (the clips it was trained on held absurd values); retrain with clips the importer \
                 accepts",
                ck.join("ace.json").display(),
                number(mean),
                number(std)
            )
        );
        assert!(e.contains(shown), "{e}");
    }
}

/// A creature profile's numbers are checked when it is read (TOML allows `nan` and `inf`): an inverted
/// limit made `f32::clamp` panic in the leg IK, a NaN tip offset gave a NaN dataset naming no profile.
/// The error names the profile, the key and what would be valid.
#[test]
fn a_creature_profiles_numbers_are_checked_when_it_is_read() {
    use ace_models::morphology::Profile;
    let dir = scratch("profile-values");
    let hound = dir.join("hound.glb");
    std::fs::copy(asset("assets/creatures/hound.glb"), &hound).unwrap();
    let shipped = std::fs::read_to_string(asset("assets/creatures/hound.profile.toml")).unwrap();
    // Its top-level keys: each case adds a table of its own.
    let shipped = shipped.split("\n[").next().unwrap();
    let limit = "a limit is [lower, upper] in radians, both finite, with lower ≤ upper";
    let scale = "the scale is metres per file unit, from 0.0001 to 100";
    let cases = [
        ("", "[limits]\n\"Thigh.L:pitch\" = [0.5, -0.5]\n", format!("`limits.\"Thigh.L:pitch\"` = [0.5, -0.5]: {limit}")),
        ("", "[limits]\n\"Thigh.L:pitch\" = [nan, 0.5]\n", format!("`limits.\"Thigh.L:pitch\"` = [NaN, 0.5]: {limit}")),
        ("", "[rest_pose]\n\"Thigh.L:pitch\" = inf\n", "`rest_pose.\"Thigh.L:pitch\"` = inf: a rest position must be finite".into()),
        ("", "[tip_offsets]\n\"Foot.L\" = [nan, 0, 0]\n", "`tip_offsets.\"Foot.L\"` = [NaN, 0.0, 0.0]: a tip offset is [x, y, z] in metres, each finite".into()),
        ("scale = 0.0\n", "", format!("`scale` = 0: {scale}")),
        ("scale = 100.5\n", "", format!("`scale` = 100.5: {scale}")),
    ];
    let profile = dir.join("hound.profile.toml");
    for (top, table, problem) in cases {
        std::fs::write(&profile, format!("{top}{shipped}\n{table}")).unwrap();
        let e = Profile::from_file(&profile).unwrap_err().to_string();
        assert_eq!(e, format!("{}: {problem}", profile.display()));
        // Loading the creature reads the profile beside it: the same error, before any work.
        let e = ace_models::character::load_creature(&hound).map(|_| ()).unwrap_err().to_string();
        assert!(e.contains(&format!("{}: {problem}", profile.display())), "{e}");
    }
    // The bounds themselves are valid.
    let ok = "scale = 100.0\n[limits]\n\"a:pitch\" = [0.5, 0.5]\n[tip_offsets]\n\"b\" = [0, 0, 0]\n";
    Profile::from_toml(ok, "ok.profile.toml").unwrap();
}

/// A copy of the bundled checkpoint `name` in `dir`, with `file`'s JSON changed by `edit`.
fn edited_checkpoint(dir: &Path, name: &str, file: &str, edit: impl FnOnce(&mut serde_json::Value)) -> PathBuf {
    std::fs::create_dir_all(dir).unwrap();
    for e in std::fs::read_dir(asset(&format!("assets/checkpoints/{name}"))).unwrap() {
        let p = e.unwrap().path();
        std::fs::copy(&p, dir.join(p.file_name().unwrap())).unwrap();
    }
    let mut v: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(dir.join(file)).unwrap()).unwrap();
    edit(&mut v);
    std::fs::write(dir.join(file), serde_json::to_string(&v).unwrap()).unwrap();
    dir.to_path_buf()
}

/// The fields of `ace.json` the scorer and the editor index by end effector or divide by are checked
/// when the checkpoint is read: a short `feature_offset` or a sixth mapping entry made the scorer
/// panic, empty `scores` crashed the editor, a zero body length gave NaN metrics with rc 0.
#[test]
fn an_ace_json_whose_correspondence_or_lengths_do_not_fit_its_character_is_refused() {
    use ace_models::runtime::Retargeter;
    let dir = scratch("ace-fields");
    let eleven = "`correspondence.scores` must have 5 rows (one per end effector) of 5 scores (one per human end effector)";
    let cases: [(&str, fn(&mut serde_json::Value), &str); 8] = [
        ("offset", |v| v["feature_offset"] = serde_json::json!([0.0]),
         "`feature_offset` has 1 entries; it must be empty or hold 28 finite values (Ψ's width)"),
        ("mapping", |v| v["correspondence"]["mapping"]["human"].as_array_mut().unwrap().push("head".into()),
         "`correspondence.mapping.human` has 6 entries; it needs one per end effector of `spot` (5)"),
        ("links", |v| v["correspondence"]["character_links"][4] = "body".into(),
         "`correspondence.character_links` is [fl_foot, fr_foot, rl_foot, rr_foot, body]; it must be the \
          character's end-effector links [fl_foot, fr_foot, rl_foot, rr_foot, gripper_tip]"),
        ("no-scores", |v| v["correspondence"]["scores"] = serde_json::json!([]), eleven),
        ("short-scores", |v| { v["correspondence"]["scores"][2].as_array_mut().unwrap().pop(); }, eleven),
        ("speed", |v| v["speed_scale"] = serde_json::json!(1e39), "`speed_scale` is inf; it must be finite and positive"),
        ("override", |v| v["body_lengths"]["human_override"] = serde_json::json!(0.0),
         "`body_lengths.human_override` is 0; it must be finite and positive"),
        ("body", |v| v["body_lengths"]["character"] = serde_json::json!(-0.5),
         "`body_lengths.character` is -0.5; it must be finite and positive"),
    ];
    for (name, edit, problem) in cases {
        let ck = edited_checkpoint(&dir.join(name), "spot", "ace.json", edit);
        let e = Retargeter::load(&ck).map(|_| ()).unwrap_err().to_string();
        assert_eq!(e, format!("{}: corrupt file: {problem}", ck.join("ace.json").display()), "{name}");
    }
    // Unchanged, and without the optional fields, it loads.
    Retargeter::load(&edited_checkpoint(&dir.join("ok"), "spot", "ace.json", |v| {
        let o = v.as_object_mut().unwrap();
        o.remove("feature_offset");
        o.remove("speed_scale");
    }))
    .unwrap();
}

/// A dataset's frame rate, foot count and deviations are checked when it is read: `fps = 0` made the
/// sliding detector panic, a tiny one turned it off, a zero deviation gave NaN losses in training
/// that were blamed on the learning rate.
#[test]
fn a_dataset_with_an_absurd_frame_rate_foot_count_or_deviation_is_refused() {
    use ace_models::dataset::{DatasetConfig, MotionSet, STD_FLOOR, generate};
    let (tree, morph) = ace_models::morphology::load_character(&asset("assets/characters/stretch.urdf")).unwrap();
    let good = generate(&tree, &morph, &DatasetConfig { frames: 60, ..DatasetConfig::default() }, &mut |_| {}).unwrap();
    let dir = scratch("dataset-values");
    let path = dir.join("d.safetensors");
    let refused = |set: &MotionSet| {
        std::fs::write(&path, set.to_bytes().unwrap()).unwrap();
        MotionSet::load(&path).map(|_| "loaded").unwrap_err().to_string()
    };
    for fps in [0.0, -30.0, f32::NAN, 1e-30, 0.99, 1000.5] {
        let e = refused(&MotionSet { fps, ..good.clone() });
        assert_eq!(e, format!("{}: metadata `fps` is {fps}; expected 1 to 1000 frames per second", path.display()));
    }
    for sd in [0.0, -1.0, 0.99 * STD_FLOOR] {
        let mut bad = good.clone();
        bad.std[3] = sd;
        let e = refused(&bad);
        assert_eq!(e, format!("{}: tensor `std` entry 3 is {sd}; every standard deviation is at least 0.001", path.display()));
    }
    // A foot count that is not a whole number, which `as usize` truncated to the right count: the
    // header is rewritten (tensor offsets count from the data, so they stay valid).
    let bytes = good.to_bytes().unwrap();
    let len = u64::from_le_bytes(bytes[..8].try_into().unwrap()) as usize;
    let mut header: serde_json::Value = serde_json::from_slice(&bytes[8..8 + len]).unwrap();
    header["__metadata__"]["n_feet"] = format!("{}.5", good.n_feet).into();
    let header = serde_json::to_vec(&header).unwrap();
    let mut bad = (header.len() as u64).to_le_bytes().to_vec();
    bad.extend(&header);
    bad.extend(&bytes[8 + len..]);
    std::fs::write(&path, &bad).unwrap();
    let e = MotionSet::load(&path).map(|_| "loaded").unwrap_err().to_string();
    assert_eq!(e, format!("{}: metadata `n_feet` is not a whole number of feet", path.display()));
    // The bounds themselves load.
    let mut edge = MotionSet { fps: 1000.0, ..good.clone() };
    edge.std[3] = STD_FLOOR;
    std::fs::write(&path, edge.to_bytes().unwrap()).unwrap();
    assert_eq!(MotionSet::load(&path).unwrap(), edge);
}

/// `config.json`'s mean, bounds and mask are checked when the prior is read: a mean of `1e39` (infinity
/// as f32) gave NaN motion blamed on the output file, a finite absurd mean or swapped bounds a wrong
/// motion with rc 0.
#[test]
fn a_prior_config_with_absurd_means_bounds_or_mask_is_refused_naming_it() {
    use ace_models::runtime::Retargeter;
    let dir = scratch("prior-config");
    let cases: [(&str, fn(&mut serde_json::Value), &str); 6] = [
        ("inf", |v| v["mean"][2] = serde_json::json!(1e39),
         "`mean` entry 2 is inf; a state entry's mean is finite and at most 1000 in magnitude"),
        ("absurd", |v| v["mean"][2] = serde_json::json!(1000.5),
         "`mean` entry 2 is 1000.5; a state entry's mean is finite and at most 1000 in magnitude"),
        ("swapped", |v| { v["bounds"]["lo"][4] = serde_json::json!(2.0); v["bounds"]["hi"][4] = serde_json::json!(-2.0); },
         "`bounds` entry 4 is [2, -2]; each entry's bounds are finite, with `lo` ≤ `hi`"),
        ("infinite-bound", |v| { v["bounds"]["lo"][4] = serde_json::json!(-2.0); v["bounds"]["hi"][4] = serde_json::json!(1e39); },
         "`bounds` entry 4 is [-2, inf]; each entry's bounds are finite, with `lo` ≤ `hi`"),
        ("mask", |v| v["mask"][1] = serde_json::json!(0.5), "`mask` entry 1 is 0.5; the mask holds 0 or 1"),
        ("mask-negative", |v| v["mask"][1] = serde_json::json!(-1.0), "`mask` entry 1 is -1; the mask holds 0 or 1"),
    ];
    for (name, edit, problem) in cases {
        let ck = edited_checkpoint(&dir.join(name), "spot", "config.json", edit);
        let e = Retargeter::load(&ck).map(|_| ()).unwrap_err().to_string();
        assert_eq!(e, format!("{}: corrupt file: {problem}", ck.join("config.json").display()), "{name}");
    }
}

/// URDF numbers are checked as the f32 the tree holds (`1e39` is finite as f64, infinite as f32), and
/// lengths are bounded: sizes above 0 and at most 1 km, origins within 1 km, mesh scales nonzero. Each
/// error names the element and says what would be valid.
#[test]
fn urdf_values_beyond_f32_and_absurd_sizes_are_refused_naming_the_element() {
    let leg_box = r#"<box size="0.05 0.05 0.3"/>"#;
    let hip = r#"<axis xyz="0 1 0"/>"#;
    let of_leg = "of a collision of link `leg`";
    let size = "a size must be greater than 0 and at most 1000 m";
    let f32_range = "(values must be finite numbers within f32's range, ±3.4e38)";
    let cases = [
        (leg_box, r#"<box size="1e39 0.05 0.3"/>"#, format!("non-finite value in the size of box geometry {of_leg} {f32_range}")),
        (leg_box, r#"<box size="0 0.05 0.3"/>"#, format!("the size of box geometry {of_leg} is 0; {size}")),
        (leg_box, r#"<box size="0.05 -0.05 0.3"/>"#, format!("the size of box geometry {of_leg} is -0.05; {size}")),
        (leg_box, r#"<box size="0.05 0.05 1000.5"/>"#, format!("the size of box geometry {of_leg} is 1000.5; {size}")),
        (leg_box, r#"<cylinder radius="0" length="0.3"/>"#, format!("the radius of cylinder geometry {of_leg} is 0; {size}")),
        (leg_box, r#"<sphere radius="-1"/>"#, format!("the radius of sphere geometry {of_leg} is -1; {size}")),
        (leg_box, r#"<mesh filename="leg.stl" scale="1 0 1"/>"#,
         format!("the scale of mesh leg.stl {of_leg} is 0; a mesh's scale must be nonzero along each axis")),
        (hip, r#"<axis xyz="0 1 0"/><origin xyz="1e39 0 0"/>"#, format!("non-finite value in the origin xyz of joint `hip` {f32_range}")),
        (hip, r#"<axis xyz="0 1 0"/><origin xyz="0 0 -1000.5"/>"#,
         "the origin xyz of joint `hip` is -1000.5; an offset must be at most 1000 m along each axis".into()),
    ];
    for (from, to, problem) in cases {
        let text = robot("fixed", "-1", "1").replacen(from, to, 1);
        let e = parse_urdf(&text, "r.urdf", None).map(|_| ()).unwrap_err().to_string();
        assert_eq!(e, format!("r.urdf: {problem}"), "{to}");
    }
    // The bounds themselves load.
    let edge = robot("fixed", "-1", "1")
        .replacen(leg_box, r#"<box size="1000 0.05 0.3"/>"#, 1)
        .replacen(hip, r#"<axis xyz="0 1 0"/><origin xyz="0 0 -1000"/>"#, 1);
    parse_urdf(&edge, "r.urdf", None).unwrap();
}

/// A mapping's `unit` overrides the unit detection, which only picks units giving a 1.4–2 m human:
/// an override that makes the centimetre walk 170 m (or 0.2 µm) tall is refused, naming the clip
/// and the unit; the right one imports.
#[test]
fn a_mapping_unit_that_makes_an_implausible_human_is_refused() {
    use ace_models::human::JointMapping;
    let import = |unit: &str| {
        let opts = ImportOptions { fps: None, mapping: Some(JointMapping::from_toml_str(&format!("unit = {unit}")).unwrap()) };
        HumanClip::from_bvh_str(&walk(), "walk.bvh", &opts)
    };
    for (unit, shown) in [("1", "1"), ("1e-9", "0.000000001"), ("\"m\"", "m")] {
        let e = import(unit).map(|c| format!("imported, {} m tall", c.height_m)).unwrap_err().to_string();
        assert!(e.starts_with(&format!("walk.bvh: invalid joint mapping: unit `{shown}` makes the human ")), "{e}");
        assert!(e.ends_with(" m tall; a human is 0.3 to 3 m tall: check the mapping's `unit`"), "{e}");
    }
    let clip = import("0.01").unwrap();
    assert!((1.4..2.0).contains(&clip.height_m), "{}", clip.height_m);
}

/// A dataset header's layout sizes are bounded before they are added up (`dim()`), which overflowed
/// (a panic in debug builds) for a `dof` of 2^64 − 1.
#[test]
fn a_dataset_layout_too_large_to_add_up_is_refused() {
    use ace_models::dataset::{DatasetConfig, MotionSet, generate};
    let (tree, morph) = ace_models::morphology::load_character(&asset("assets/characters/stretch.urdf")).unwrap();
    let good = generate(&tree, &morph, &DatasetConfig { frames: 10, ..DatasetConfig::default() }, &mut |_| {}).unwrap();
    let bytes = good.to_bytes().unwrap();
    let len = u64::from_le_bytes(bytes[..8].try_into().unwrap()) as usize;
    let mut header: serde_json::Value = serde_json::from_slice(&bytes[8..8 + len]).unwrap();
    for (dof, valid) in [(u64::MAX, false), (6145, false), (6144, true)] {
        let layout = format!(r#"{{"dof":{dof},"end_effectors":1,"dim":1}}"#);
        header["__metadata__"]["layout"] = layout.into();
        let h = serde_json::to_vec(&header).unwrap();
        let mut file = (h.len() as u64).to_le_bytes().to_vec();
        file.extend(&h);
        file.extend(&bytes[8 + len..]);
        let e = MotionSet::from_bytes(&file).map(|_| ()).unwrap_err();
        if valid {
            assert!(e.starts_with("metadata `layout`: dim 1 does not match dof 6144"), "{e}");
        } else {
            assert_eq!(e, format!("metadata `layout`: `dof` is {dof}; at most 6144 (6 per link of the most a robot has)"));
        }
    }
}
