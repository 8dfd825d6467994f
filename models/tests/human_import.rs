//! Human BVH import: every clip of the shared data set, hand-made fixtures for conventions the data set
//! lacks (Mixamo, LAFAN1, an unknown rig with a mapping file), bad inputs, resampling and x^h.
//!
//! The shared data lives beside the project (`../shared/data/human`, see DESIGN.md). Tests that need it
//! fail with a message saying where they looked, or skip when `ACE_ALLOW_MISSING_DATA=1`.

use std::path::{Path, PathBuf};
use std::time::Instant;

use ace_models::human::{
    EndEffector, HumanClip, HumanImportError, ImportOptions, JOINT_COUNT, Joint, JointMapping,
    import_with_report, layout,
};

fn fixture(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("tests/data")
        .join(name)
}

/// The shared human clips, or `None` (after saying so) when they are missing and that is allowed.
fn data_dir() -> Option<PathBuf> {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../shared/data/human");
    if dir.is_dir() {
        return Some(dir);
    }
    let msg = format!("shared human mocap not found: looked for {}", dir.display());
    if std::env::var("ACE_ALLOW_MISSING_DATA").as_deref() == Ok("1") {
        eprintln!("SKIPPED: {msg} (ACE_ALLOW_MISSING_DATA=1)");
        None
    } else {
        panic!("{msg}; set ACE_ALLOW_MISSING_DATA=1 to skip tests that need it");
    }
}

fn bvh_files(dir: &Path) -> Vec<PathBuf> {
    let mut out = Vec::new();
    let mut stack = vec![dir.to_path_buf()];
    while let Some(d) = stack.pop() {
        for e in std::fs::read_dir(&d).unwrap() {
            let p = e.unwrap().path();
            if p.is_dir() {
                stack.push(p);
            } else if p.extension().is_some_and(|x| x.eq_ignore_ascii_case("bvh")) {
                out.push(p);
            }
        }
    }
    out.sort();
    out
}

fn expected_convention(folder: &str) -> &'static str {
    match folder {
        "bandai_namco" => "bandai",
        "cmu_cgspeed_max" => "cmu-cgspeed-max",
        "cmu_cgspeed_mb" | "xia_style" => "cmu-cgspeed-mb",
        "cmu_daz" | "cmu_salsa_scaled" => "daz",
        "cmu_iclone" => "iclone",
        "mass" => "humanik",
        other => panic!("unexpected data folder {other}"),
    }
}

fn percentile(mut v: Vec<f32>, q: f32) -> f32 {
    v.sort_by(f32::total_cmp);
    v[((v.len() - 1) as f32 * q).round() as usize]
}

fn lowest_ankle(clip: &HumanClip) -> Vec<f32> {
    clip.frames
        .iter()
        .map(|f| {
            f.position(Joint::LeftFoot)
                .z
                .min(f.position(Joint::RightFoot).z)
        })
        .collect()
}

fn mean_forward_speed(clip: &HumanClip) -> f32 {
    let s = clip.states();
    s.iter().map(|x| x.root_linear_velocity().x).sum::<f32>() / s.len() as f32
}

/// Every clip imports with all joints mapped, a plausible height, finite x^h, feet on the floor and
/// the convention expected for its folder.
///
/// Ground contact, with the tolerances real data needs: the importer puts the floor (5th percentile of
/// the lowest foot point per frame, toes included) at z = 0, having found it within 15 cm of the file's
/// own zero (iClone's feet float ~9 cm, some MASS clips ~6 cm, CMU ±5 cm). The canonical foot is the
/// ankle joint, 2–12 cm above the sole when standing, so its 5th-percentile height over the clip must lie
/// in 0–15 cm and it may dip at most 5 cm below the floor (toe-off, capture noise).
#[test]
fn all_shared_clips_import() {
    let Some(dir) = data_dir() else { return };
    let files = bvh_files(&dir);
    assert_eq!(
        files.len(),
        416,
        "expected the 416 clips of SOURCES.md in {}",
        dir.display()
    );
    let start = Instant::now();
    let (mut frames, mut failures) = (0usize, Vec::new());
    for path in &files {
        let rel = path.strip_prefix(&dir).unwrap().display().to_string();
        let folder = rel.split('/').next().unwrap();
        let text = std::fs::read_to_string(path).unwrap();
        let (clip, report) = match import_with_report(&text, &rel, &ImportOptions::default()) {
            Ok(c) => c,
            Err(e) => {
                failures.push(format!("{e}"));
                continue;
            }
        };
        frames += clip.frames.len();
        let mut fail = |m: String| failures.push(format!("{rel}: {m}"));
        if clip.mapped_joints != JOINT_COUNT {
            fail(format!("{} joints mapped", clip.mapped_joints));
        }
        if clip.convention != expected_convention(folder) {
            fail(format!(
                "convention {} (expected {})",
                clip.convention,
                expected_convention(folder)
            ));
        }
        if !(1.3..=2.1).contains(&clip.height_m) {
            fail(format!("height {:.3} m", clip.height_m));
        }
        if report.floor_m.abs() > 0.15 {
            fail(format!("file floor {:.3} m from its zero", report.floor_m));
        }
        let ankles = lowest_ankle(&clip);
        let (p5, min) = (
            percentile(ankles.clone(), 0.05),
            ankles.iter().cloned().fold(f32::INFINITY, f32::min),
        );
        if !(0.0..=0.15).contains(&p5) || min < -0.05 {
            fail(format!("ankle height p5 {p5:.3} m, min {min:.3} m"));
        }
        // The jump warning is for cuts and glitches: the one real glitch of the data (the root of a salsa
        // clip jumps 12 cm in one 120 fps frame, 2.62 s in) and nothing else.
        let jump = clip.root_jump_warning();
        if jump.is_some() != (rel == "cmu_salsa_scaled/60_10_scaled.bvh") {
            fail(format!("jump warning {jump:?}"));
        }
        if let Some(w) = jump.filter(|w| !w.contains("in one frame at 2.62 s (14 m/s")) {
            fail(w);
        }
        // The one clip of no known unit (rescaled by hand) says so.
        if clip.unit_warning().is_some() != (rel == "cmu_salsa_scaled/60_10_scaled.bvh") {
            fail(format!("unit warning {:?}", clip.unit_warning()));
        }
        let states = clip.states();
        if let Some((t, _)) = states
            .iter()
            .enumerate()
            .find(|(_, x)| x.0.iter().any(|v| !v.is_finite()))
        {
            fail(format!("non-finite x^h at frame {t}"));
        }
        // The head is above the pelvis most of the time in every clip of this data set.
        let up = states
            .iter()
            .filter(|x| x.joint_position(Joint::Head).z > 0.2)
            .count();
        if (up as f32) < 0.9 * clip.frames.len() as f32 {
            fail(format!(
                "head above the pelvis in only {up}/{} frames",
                clip.frames.len()
            ));
        }
    }
    let secs = start.elapsed().as_secs_f32();
    eprintln!(
        "imported {} clips, {frames} frames (with x^h) in {secs:.2} s",
        files.len()
    );
    assert!(
        failures.is_empty(),
        "{} problems:\n{}",
        failures.len(),
        failures.join("\n")
    );
}

#[test]
fn walking_clips_move_forward_with_the_head_up() {
    let Some(dir) = data_dir() else { return };
    for (rel, speed) in [
        ("mass/walk.bvh", (0.5, 2.5)),
        ("cmu_cgspeed_mb/02_01.bvh", (0.5, 2.5)),
    ] {
        let clip = HumanClip::from_bvh_file(&dir.join(rel), &ImportOptions::default()).unwrap();
        let v = mean_forward_speed(&clip);
        assert!(
            v > speed.0 && v < speed.1,
            "{rel}: mean forward speed {v:.3} m/s"
        );
        // Sideways and vertical mean velocities are small by comparison.
        let s = clip.states();
        let side = s.iter().map(|x| x.root_linear_velocity().y).sum::<f32>() / s.len() as f32;
        assert!(
            side.abs() < 0.3 * v,
            "{rel}: mean sideways speed {side:.3} m/s"
        );
        for (t, x) in s.iter().enumerate() {
            let head = x.joint_position(Joint::Head);
            assert!(
                head.z > 0.3,
                "{rel} frame {t}: head {head:?} not above the pelvis"
            );
            // Heading frame: left hip on +y, right hip on −y.
            assert!(
                x.joint_position(Joint::LeftThigh).y > 0.0
                    && x.joint_position(Joint::RightThigh).y < 0.0
            );
        }
        assert_eq!(
            clip.name,
            Path::new(rel).file_stem().unwrap().to_str().unwrap()
        );
    }
}

#[test]
fn iclone_root_channels_add_to_the_offset() {
    let Some(dir) = data_dir() else { return };
    let text = std::fs::read_to_string(dir.join("cmu_iclone/002_05.bvh")).unwrap();
    let (clip, report) = import_with_report(&text, "002_05", &ImportOptions::default()).unwrap();
    assert_eq!(
        report.root_translation,
        ace_models::human::fk::Translation::AddToOffset
    );
    assert_eq!(clip.unit, "cm");
    assert_eq!(report.up_axis, "y");
    // Standing: the pelvis about 1 m above the floor.
    let pelvis = clip.frames[0].position(Joint::Pelvis).z;
    assert!((0.8..1.2).contains(&pelvis), "pelvis height {pelvis}");
}

#[test]
fn leading_t_pose_frames_are_dropped() {
    let Some(dir) = data_dir() else { return };
    let load = |rel: &str| {
        let text = std::fs::read_to_string(dir.join(rel)).unwrap();
        import_with_report(&text, rel, &ImportOptions::default()).unwrap()
    };
    // cgspeed's Daz conversions: a zero-rotation T-pose frame, then a blend into the motion over a few
    // frames (arms swinging down by 90° in 30 ms). The first kept frame has the arms down.
    for rel in [
        "cmu_daz/02_03.bvh",
        "cmu_daz/13_11.bvh",
        "cmu_salsa_scaled/60_10_scaled.bvh",
    ] {
        let (clip, report) = load(rel);
        assert!(
            (2..=8).contains(&report.dropped_rest_frames),
            "{rel}: {report:?}"
        );
        let f = &clip.frames[0];
        let arm = (f.position(Joint::LeftHand) - f.position(Joint::LeftUpperArm)).normalize();
        assert!(
            arm.z < -0.5,
            "{rel}: first frame's left arm direction {arm:?}"
        );
    }
    // This MotionBuilder conversion starts with one zero-rotation frame; the performer then really
    // stands in a T-pose, which is motion and stays.
    let (clip, report) = load("cmu_cgspeed_mb/01_01.bvh");
    assert_eq!(report.dropped_rest_frames, 1);
    assert_eq!(clip.frames.len(), 2752 - 1);
    // No rest frame in the other conventions (the iClone clips of this data set start with motion).
    for rel in [
        "mass/walk.bvh",
        "cmu_iclone/002_05.bvh",
        "cmu_cgspeed_mb/02_01.bvh",
    ] {
        assert_eq!(load(rel).1.dropped_rest_frames, 0, "{rel}");
    }
}

#[test]
fn source_joints_per_convention() {
    let Some(dir) = data_dir() else { return };
    let cases: [(&str, [&str; JOINT_COUNT]); 6] = [
        (
            "cmu_cgspeed_mb/02_01.bvh",
            [
                "Hips",
                "Spine",
                "Spine1",
                "Neck1",
                "Head",
                "LeftArm",
                "LeftForeArm",
                "LeftHand",
                "RightArm",
                "RightForeArm",
                "RightHand",
                "LeftUpLeg",
                "LeftLeg",
                "LeftFoot",
                "RightUpLeg",
                "RightLeg",
                "RightFoot",
            ],
        ),
        (
            "cmu_cgspeed_max/131_01.bvh",
            [
                "Hips",
                "Chest",
                "Chest2",
                "Neck",
                "Head",
                "LeftShoulder",
                "LeftElbow",
                "LeftWrist",
                "RightShoulder",
                "RightElbow",
                "RightWrist",
                "LeftHip",
                "LeftKnee",
                "LeftAnkle",
                "RightHip",
                "RightKnee",
                "RightAnkle",
            ],
        ),
        (
            "cmu_daz/02_03.bvh",
            [
                "hip", "abdomen", "chest", "neck", "head", "lShldr", "lForeArm", "lHand", "rShldr",
                "rForeArm", "rHand", "lThigh", "lShin", "lFoot", "rThigh", "rShin", "rFoot",
            ],
        ),
        (
            "cmu_iclone/002_05.bvh",
            [
                "CC_Base_Hip",
                "CC_Base_Spine01",
                "CC_Base_Spine02",
                "CC_Base_NeckTwist01",
                "CC_Base_Head",
                "CC_Base_L_Upperarm",
                "CC_Base_L_Forearm",
                "CC_Base_L_Hand",
                "CC_Base_R_Upperarm",
                "CC_Base_R_Forearm",
                "CC_Base_R_Hand",
                "CC_Base_L_Thigh",
                "CC_Base_L_Calf",
                "CC_Base_L_Foot",
                "CC_Base_R_Thigh",
                "CC_Base_R_Calf",
                "CC_Base_R_Foot",
            ],
        ),
        // HumanIK helper bones (L_Radius_RIGMESH, R_Femur_RIGMESH, …) are never picked.
        (
            "mass/walk.bvh",
            [
                "Character1_Hips",
                "Character1_Spine",
                "Character1_Spine1",
                "Character1_Neck",
                "Character1_Head",
                "Character1_LeftArm",
                "Character1_LeftForeArm",
                "Character1_LeftHand",
                "Character1_RightArm",
                "Character1_RightForeArm",
                "Character1_RightHand",
                "Character1_LeftUpLeg",
                "Character1_LeftLeg",
                "Character1_LeftFoot",
                "Character1_RightUpLeg",
                "Character1_RightLeg",
                "Character1_RightFoot",
            ],
        ),
        (
            "bandai_namco/dataset-1_walk_normal_001.bvh",
            [
                "Hips",
                "Spine",
                "Chest",
                "Neck",
                "Head",
                "UpperArm_L",
                "LowerArm_L",
                "Hand_L",
                "UpperArm_R",
                "LowerArm_R",
                "Hand_R",
                "UpperLeg_L",
                "LowerLeg_L",
                "Foot_L",
                "UpperLeg_R",
                "LowerLeg_R",
                "Foot_R",
            ],
        ),
    ];
    for (rel, expect) in cases {
        let clip = HumanClip::from_bvh_file(&dir.join(rel), &ImportOptions::default()).unwrap();
        assert_eq!(
            clip.source_joints.to_vec(),
            expect.map(String::from).to_vec(),
            "{rel}"
        );
    }
    // A scale nobody uses (a rescaled Daz conversion, 1.30 m tall in metres) is normalised and says so.
    let clip = HumanClip::from_bvh_file(
        &dir.join("cmu_salsa_scaled/60_10_scaled.bvh"),
        &ImportOptions::default(),
    )
    .unwrap();
    assert_eq!(clip.unit, "unknown (normalised to 1.70 m)");
    assert!((clip.height_m - 1.70).abs() < 1e-4);
}

/// Bandai's walks go forward, backward, left and right: the facing direction and the handedness of the
/// conversion agree with the labels on every clip.
#[test]
fn bandai_walk_directions_match_their_labels() {
    let Some(dir) = data_dir() else { return };
    let mut checked = 0;
    for path in bvh_files(&dir.join("bandai_namco")) {
        let name = path.file_name().unwrap().to_str().unwrap().to_string();
        let motion = name.split('_').nth(1).unwrap();
        if !motion.starts_with("walk") || motion.starts_with("walk-turn") {
            continue;
        }
        let clip = HumanClip::from_bvh_file(&path, &ImportOptions::default()).unwrap();
        let s = clip.states();
        let v = s
            .iter()
            .map(|x| x.root_linear_velocity())
            .sum::<nalgebra::Vector3<f32>>()
            / s.len() as f32;
        let ok = match motion {
            "walk" => v.x > 0.3,
            "walk-back" => v.x < -0.3,
            "walk-left" => v.y > 0.1,
            "walk-right" => v.y < -0.1,
            other => panic!("unexpected motion {other}"),
        };
        assert!(ok, "{name}: mean root velocity {v:?} (x forward, y left)");
        checked += 1;
    }
    assert_eq!(checked, 53 + 15 * 3);
}

fn check_walk_fixture(clip: &HumanClip, height: (f32, f32)) {
    assert_eq!(clip.mapped_joints, JOINT_COUNT);
    assert!(
        height.0 < clip.height_m && clip.height_m < height.1,
        "height {}",
        clip.height_m
    );
    let v = mean_forward_speed(clip);
    assert!((v - 1.2).abs() < 0.15, "forward speed {v}");
    for x in clip.states() {
        assert!(x.0.iter().all(|v| v.is_finite()));
        assert!(x.joint_position(Joint::Head).z > 0.4);
        assert!(x.joint_position(Joint::LeftFoot).z < -0.7);
        assert!(
            x.joint_position(Joint::LeftHand).y > 0.1
                && x.joint_position(Joint::RightHand).y < -0.1
        );
    }
}

#[test]
fn mixamo_fixture_maps_with_and_without_prefix() {
    let path = fixture("mixamo_walk.bvh");
    let clip = HumanClip::from_bvh_file(&path, &ImportOptions::default()).unwrap();
    assert_eq!(clip.convention, "mixamo");
    assert_eq!(clip.unit, "cm");
    assert_eq!(clip.name, "mixamo_walk");
    assert_eq!(clip.source_fps, 60.0);
    let expect = [
        "Hips",
        "Spine1",
        "Spine2",
        "Neck",
        "Head",
        "LeftArm",
        "LeftForeArm",
        "LeftHand",
        "RightArm",
        "RightForeArm",
        "RightHand",
        "LeftUpLeg",
        "LeftLeg",
        "LeftFoot",
        "RightUpLeg",
        "RightLeg",
        "RightFoot",
    ];
    let prefixed: Vec<String> = expect.iter().map(|n| format!("mixamorig:{n}")).collect();
    assert_eq!(clip.source_joints.to_vec(), prefixed);
    check_walk_fixture(&clip, (1.6, 1.8));

    let bare = std::fs::read_to_string(&path)
        .unwrap()
        .replace("mixamorig:", "");
    let clip = HumanClip::from_bvh_str(&bare, "bare", &ImportOptions::default()).unwrap();
    assert_eq!(clip.convention, "mixamo");
    assert_eq!(
        clip.source_joints.to_vec(),
        expect.map(String::from).to_vec()
    );
    check_walk_fixture(&clip, (1.6, 1.8));

    // A prefix nobody listed, shared by every joint (an armature's, an exporter's), is dropped: the
    // same joints map, the same frames come out (every joint was left unmapped).
    for prefix in ["Armature_", "Ch01_", "Skeleton_", "Hero_Rig_", "Genesis8_"] {
        let text = std::fs::read_to_string(&path).unwrap().replace("mixamorig:", prefix);
        let c = HumanClip::from_bvh_str(&text, "prefixed", &ImportOptions::default()).unwrap_or_else(|e| panic!("{prefix}: {e}"));
        let named: Vec<String> = expect.iter().map(|n| format!("{prefix}{n}")).collect();
        assert_eq!(c.source_joints.to_vec(), named, "{prefix}");
        assert!(c.frames.iter().zip(&clip.frames).all(|(a, b)| a.positions == b.positions), "{prefix}");
    }
}

#[test]
fn lafan1_fixture_maps() {
    // LAFAN1 layout: bones along each joint's +X (the rest pose is not upright), a non-zero root
    // OFFSET with absolute root positions, left = +Z, walking along −X.
    let clip =
        HumanClip::from_bvh_file(&fixture("lafan1_walk.bvh"), &ImportOptions::default()).unwrap();
    assert_eq!(clip.convention, "lafan1");
    assert_eq!(clip.unit, "cm");
    let expect = [
        "Hips",
        "Spine1",
        "Spine2",
        "Neck",
        "Head",
        "LeftArm",
        "LeftForeArm",
        "LeftHand",
        "RightArm",
        "RightForeArm",
        "RightHand",
        "LeftUpLeg",
        "LeftLeg",
        "LeftFoot",
        "RightUpLeg",
        "RightLeg",
        "RightFoot",
    ];
    assert_eq!(
        clip.source_joints.to_vec(),
        expect.map(String::from).to_vec()
    );
    check_walk_fixture(&clip, (1.65, 1.85));
    // Facing −X in the file, which is −y in the z-up world ((x, y, z) → (z, x, y)).
    let fwd = clip.frames[0].forward().normalize();
    assert!(
        (fwd - nalgebra::Vector3::new(0.0, -1.0, 0.0)).norm() < 1e-3,
        "{fwd:?}"
    );
}

#[test]
fn unknown_skeleton_errors_and_a_mapping_file_fixes_it() {
    let path = fixture("unknown_rig.bvh");
    let err = HumanClip::from_bvh_file(&path, &ImportOptions::default()).unwrap_err();
    let msg = err.to_string();
    assert!(matches!(err, HumanImportError::Unmapped { .. }));
    assert!(msg.contains("unknown_rig.bvh"), "{msg}");
    assert!(
        msg.contains("left_hand") && msg.contains("right_foot") && msg.contains("head"),
        "{msg}"
    );
    assert!(msg.contains("Bone.43") && msg.contains("Bone.34"), "{msg}");

    let mapping = JointMapping::from_file(&fixture("unknown_rig.toml")).unwrap();
    let opts = ImportOptions {
        fps: None,
        mapping: Some(mapping),
    };
    let clip = HumanClip::from_bvh_file(&path, &opts).unwrap();
    assert_eq!(clip.convention, "user-mapping");
    assert_eq!(clip.unit, "m");
    assert_eq!(clip.source_joints[Joint::LeftForearm.index()], "Bone.42");
    assert_eq!(clip.source_joints[Joint::LeftUpperArm.index()], "Bone.41");
    assert_eq!(clip.source_joints[Joint::Chest.index()], "Bone.32");
    assert_eq!(clip.source_joints[Joint::Pelvis.index()], "Bone");
    // Z-up file, walking towards −y (its forward): positive forward speed.
    let v = mean_forward_speed(&clip);
    assert!((v - 1.0).abs() < 0.05, "forward speed {v}");
    assert!((clip.frames[0].position(Joint::Pelvis).z - 0.98).abs() < 0.1);

    // A mapping naming a joint that does not exist says so.
    let bad = JointMapping::from_toml_str("left_hand = \"Bone.99\"").unwrap();
    let e = HumanClip::from_bvh_file(
        &path,
        &ImportOptions {
            fps: None,
            mapping: Some(bad),
        },
    )
    .unwrap_err()
    .to_string();
    assert!(
        e.contains("unknown_rig.bvh") && e.contains("Bone.99") && e.contains("left_hand"),
        "{e}"
    );
    // A mapping that contradicts the hierarchy is refused: a shin on the arm.
    let swapped = JointMapping::from_toml_str(
        "left_hand = \"Bone.43\"\nright_hand = \"Bone.53\"\nleft_foot = \"Bone.12\"\nright_foot = \"Bone.22\"\nhead = \"Bone.34\"\nleft_shin = \"Bone.42\"",
    )
    .unwrap();
    let e = HumanClip::from_bvh_file(
        &path,
        &ImportOptions {
            fps: None,
            mapping: Some(swapped),
        },
    )
    .unwrap_err()
    .to_string();
    assert!(e.contains("left_shin"), "{e}");
}

#[test]
fn mapping_files_are_validated() {
    let e = JointMapping::from_toml_str("left_hnd = \"X\"")
        .unwrap_err()
        .to_string();
    assert!(e.contains("left_hnd") && e.contains("left_hand"), "{e}");
    let e = JointMapping::from_toml_str("unit = \"furlong\"")
        .unwrap_err()
        .to_string();
    assert!(e.contains("furlong"), "{e}");
    let e = JointMapping::from_toml_str("up = \"w\"")
        .unwrap_err()
        .to_string();
    assert!(e.contains("up axis"), "{e}");
    let m = JointMapping::from_toml_str(
        "unit = \"cm\"\nup = \"-z\"\n[joints]\npelvis = \"Bip01_Pelvis\"",
    )
    .unwrap();
    assert_eq!(
        m.joints[Joint::Pelvis.index()].as_deref(),
        Some("Bip01_Pelvis")
    );
    assert_eq!(m.unit.as_deref(), Some("cm"));
    let e = JointMapping::from_file(Path::new("/nonexistent/map.toml"))
        .unwrap_err()
        .to_string();
    assert!(e.contains("/nonexistent/map.toml"), "{e}");
    // A joint given twice was settled by the keys' alphabetical order; one BVH joint for two canonical
    // joints was "could not map canonical joint(s) spine, chest, …", with no word of the duplicate.
    for (text, says) in [
        ("head = \"Neck\"\n[joints]\nhead = \"Head\"", "`head` is given twice, at the top level and in `[joints]`"),
        ("left_foot = \"LeftToe\"\n[joints]\nleft_foot = \"LeftFoot\"", "`left_foot` is given twice"),
        ("left_hand = \"RightHand\"\nright_hand = \"RightHand\"", "`left_hand` and `right_hand` both name the BVH joint `RightHand`"),
    ] {
        let e = JointMapping::parse(text, "walk.mapping.toml").unwrap_err().to_string();
        assert!(e.starts_with("walk.mapping.toml") && e.contains(says), "{text}: {e}");
    }
}

#[test]
fn unit_and_up_overrides_apply() {
    let text = std::fs::read_to_string(fixture("mixamo_walk.bvh")).unwrap();
    // The clip is in centimetres: 1.5 cm per unit makes the human 1.5 times as tall (a unit that
    // makes an implausible human, such as mm here, is refused).
    let mapping = JointMapping::from_toml_str("unit = 0.015").unwrap();
    let clip = HumanClip::from_bvh_str(
        &text,
        "scaled",
        &ImportOptions {
            fps: None,
            mapping: Some(mapping),
        },
    )
    .unwrap();
    assert_eq!(clip.unit, "0.015");
    assert!((clip.height_m - 2.535).abs() < 0.15, "{}", clip.height_m);
}

/// A small valid file to break in various ways: the Mixamo fixture cut to 5 frames.
fn small_bvh() -> (String, usize) {
    let text = std::fs::read_to_string(fixture("mixamo_walk.bvh")).unwrap();
    let lines: Vec<&str> = text.lines().collect();
    let motion = lines.iter().position(|l| *l == "MOTION").unwrap();
    let mut out: Vec<String> = lines[..motion + 3].iter().map(|s| s.to_string()).collect();
    out[motion + 1] = "Frames: 5".into();
    out.extend(lines[motion + 3..motion + 8].iter().map(|s| s.to_string()));
    (out.join("\n") + "\n", motion + 4) // 1-based line of the first frame
}

fn import_err(text: &str) -> String {
    HumanClip::from_bvh_str(text, "broken.bvh", &ImportOptions::default())
        .unwrap_err()
        .to_string()
}

#[test]
fn bad_files_give_errors_naming_file_and_line() {
    let (text, first) = small_bvh();
    assert!(HumanClip::from_bvh_str(&text, "ok", &ImportOptions::default()).is_ok());
    let lines: Vec<&str> = text.lines().collect();

    // Truncated: two motion lines missing.
    let truncated = lines[..lines.len() - 2].join("\n");
    let e = import_err(&truncated);
    assert!(
        e.contains("broken.bvh")
            && e.contains("truncated")
            && e.contains("Frames: 5")
            && e.contains("only 3"),
        "{e}"
    );

    // One value missing on the third frame.
    let mut v = lines.iter().map(|s| s.to_string()).collect::<Vec<_>>();
    let k = first - 1 + 2;
    v[k] = v[k].rsplit_once(' ').unwrap().0.to_string();
    let e = import_err(&v.join("\n"));
    assert!(
        e.contains(&format!(
            "broken.bvh, line {}: expected 90 values, found 89",
            first + 2
        )),
        "{e}"
    );

    // A non-numeric value.
    let mut v = lines.iter().map(|s| s.to_string()).collect::<Vec<_>>();
    v[first - 1] = v[first - 1].replacen("0.000000", "zero", 1);
    let e = import_err(&v.join("\n"));
    assert!(
        e.contains(&format!("broken.bvh, line {first}")) && e.contains("`zero` is not a number"),
        "{e}"
    );

    // No MOTION section.
    let head = text.split("MOTION").next().unwrap();
    let e = import_err(head);
    assert!(
        e.contains("broken.bvh") && e.contains("missing MOTION"),
        "{e}"
    );

    // No HIERARCHY.
    let e = import_err(&text.replacen("HIERARCHY", "", 1));
    assert!(
        e.contains("broken.bvh, line") && e.contains("HIERARCHY"),
        "{e}"
    );

    // Unbalanced braces: one closing brace removed.
    let motion = text.find("MOTION").unwrap();
    let cut = text[..motion].rfind('}').unwrap();
    let e = import_err(&format!("{}{}", &text[..cut], &text[cut + 1..]));
    assert!(
        e.contains("broken.bvh") && e.contains("unbalanced braces"),
        "{e}"
    );

    // Missing file.
    let e = HumanClip::from_bvh_file(
        Path::new("/nonexistent/clip.bvh"),
        &ImportOptions::default(),
    )
    .unwrap_err();
    assert!(e.to_string().contains("/nonexistent/clip.bvh"), "{e}");

    // The same checks through from_bvh_file name the path.
    let tmp = std::env::temp_dir().join(format!("ace_human_import_{}.bvh", std::process::id()));
    std::fs::write(&tmp, &truncated).unwrap();
    let e = HumanClip::from_bvh_file(&tmp, &ImportOptions::default())
        .unwrap_err()
        .to_string();
    std::fs::remove_file(&tmp).ok();
    assert!(
        e.contains(&tmp.display().to_string()) && e.contains("truncated"),
        "{e}"
    );
}

#[test]
fn garbage_never_panics() {
    let (text, _) = small_bvh();
    // Every prefix of the file, and a few mangled versions, give Ok or Err but never panic.
    for cut in (0..text.len()).step_by(97) {
        let _ = HumanClip::from_bvh_str(&text[..cut], "prefix", &ImportOptions::default());
    }
    for (from, to) in [
        ("OFFSET", "OFFSET 1"),
        ("CHANNELS 3", "CHANNELS 2"),
        ("{", "{ {"),
        ("Frame Time", "Frame Tim"),
    ] {
        let _ = HumanClip::from_bvh_str(
            &text.replacen(from, to, 1),
            "mangled",
            &ImportOptions::default(),
        );
    }
    let _ = HumanClip::from_bvh_str(
        "HIERARCHY\nROOT a\n{\nOFFSET 0 0 0\n}\nMOTION\nFrames: 1\nFrame Time: 1\n\n",
        "x",
        &ImportOptions::default(),
    );
}

#[test]
fn resampling_keeps_shared_timestamps() {
    // 60 fps fixture → 120 fps (interpolated) → 30 fps: every 30 fps frame is a 120 fps frame k·4 and
    // an original frame k·2.
    let clip =
        HumanClip::from_bvh_file(&fixture("mixamo_walk.bvh"), &ImportOptions::default()).unwrap();
    assert_eq!(clip.frames.len(), 61);
    let fast = clip.resampled(120.0);
    assert_eq!(fast.frames.len(), 121);
    assert!((fast.duration() - clip.duration()).abs() < 1e-5);
    let slow = fast.resampled(30.0);
    assert_eq!(slow.frames.len(), 31);
    for (k, f) in slow.frames.iter().enumerate() {
        for j in 0..JOINT_COUNT {
            assert!((f.positions[j] - fast.frames[4 * k].positions[j]).norm() < 1e-5);
            assert!((f.positions[j] - clip.frames[2 * k].positions[j]).norm() < 1e-5);
        }
        assert!(f.root_rotation.angle_to(&clip.frames[2 * k].root_rotation) < 1e-4);
    }
    // frame_at interpolates and clamps.
    let mid = clip.frame_at(0.5 / 60.0);
    let expect = (clip.frames[0].positions[0] + clip.frames[1].positions[0]) * 0.5;
    assert!((mid.positions[0] - expect).norm() < 1e-5);
    assert_eq!(clip.frame_at(-1.0), clip.frames[0]);
    assert_eq!(clip.frame_at(99.0), *clip.frames.last().unwrap());
    // Import with a target rate does the same.
    let opts = ImportOptions {
        fps: Some(30.0),
        mapping: None,
    };
    let direct = HumanClip::from_bvh_file(&fixture("mixamo_walk.bvh"), &opts).unwrap();
    assert_eq!(
        (direct.fps, direct.source_fps, direct.frames.len()),
        (30.0, 60.0, 31)
    );
}

#[test]
fn resampling_real_120_fps_data_to_30() {
    let Some(dir) = data_dir() else { return };
    let clip = HumanClip::from_bvh_file(
        &dir.join("cmu_cgspeed_mb/02_01.bvh"),
        &ImportOptions::default(),
    )
    .unwrap();
    assert!((clip.fps - 120.0).abs() < 0.01, "{}", clip.fps);
    let n = clip.frames.len();
    let slow = clip.resampled(30.0);
    // Frame time is 0.008333 s (not exactly 1/120), so compare at the clip's own timestamps.
    assert_eq!(
        slow.frames.len(),
        ((n - 1) as f32 / clip.fps * 30.0 + 1e-3).floor() as usize + 1
    );
    for (k, f) in slow.frames.iter().enumerate() {
        let expect = clip.frame_at(k as f32 / 30.0);
        for j in 0..JOINT_COUNT {
            assert!((f.positions[j] - expect.positions[j]).norm() < 1e-5);
        }
    }
}

#[test]
fn state_layout_is_contiguous_and_has_92_values() {
    let mut next = 0;
    for (name, r) in layout::BLOCKS {
        assert_eq!(r.start, next, "{name}");
        next = r.end;
    }
    assert_eq!(next, layout::DIM);
    assert_eq!(layout::DIM, 92);
    assert_eq!(layout::ROOT_HEIGHT, 0..1);
    assert_eq!(layout::ROOT_ORIENTATION, 1..5);
    assert_eq!(layout::ROOT_LINEAR_VELOCITY, 5..8);
    assert_eq!(layout::ROOT_ANGULAR_VELOCITY, 8..11);
    assert_eq!(layout::JOINT_POSITIONS, 11..62);
    assert_eq!(layout::EE_POSITIONS, 62..77);
    assert_eq!(layout::EE_VELOCITIES, 77..92);
    // End-effector positions repeat the joint positions.
    let clip =
        HumanClip::from_bvh_file(&fixture("lafan1_walk.bvh"), &ImportOptions::default()).unwrap();
    let x = &clip.states()[3];
    for e in EndEffector::ALL {
        assert_eq!(x.ee_position(e), x.joint_position(e.joint()));
    }
    assert_eq!(x.joint_position(Joint::Pelvis), nalgebra::Vector3::zeros());
    assert!((x.root_height() - clip.frames[3].position(Joint::Pelvis).z).abs() < 1e-6);
    assert!(x.root_orientation().quaternion().w >= 0.0);
}

/// A file of two performers (two `ROOT` skeletons) was retargeted from the first without a word.
#[test]
fn a_file_of_two_skeletons_says_which_one_is_retargeted() {
    let walk = std::fs::read_to_string(Path::new(env!("CARGO_MANIFEST_DIR")).join("../assets/motions/walk.bvh")).unwrap();
    let (hierarchy, motion) = walk.split_once("MOTION").unwrap();
    let skeleton = hierarchy.trim_start().strip_prefix("HIERARCHY").unwrap();
    let renamed: String = skeleton
        .lines()
        .map(|l| match l.trim_start().split_once(' ') {
            Some(("ROOT" | "JOINT", name)) => l.replacen(name, &format!("Second{name}"), 1),
            _ => l.to_string(),
        })
        .collect::<Vec<_>>()
        .join("\n");
    let mut lines = motion.lines();
    let mut doubled = vec![lines.next().unwrap().to_string()];
    for l in lines {
        let l = l.trim();
        doubled.push(if l.starts_with("Frame") || l.is_empty() { l.to_string() } else { format!("{l} {l}") });
    }
    let text = format!("HIERARCHY{skeleton}\n{renamed}\nMOTION{}\n", doubled.join("\n"));
    let clip = HumanClip::from_bvh_str(&text, "pair.bvh", &ImportOptions::default()).unwrap();
    assert_eq!(clip.other_skeletons, ["SecondHips"]);
    let w = clip.skeletons_warning().unwrap();
    assert_eq!(
        w,
        "pair.bvh: the file holds 2 skeletons; the one whose pelvis is `Hips` is retargeted, and the one(s) of ROOT `SecondHips` \
         left out (a joint-mapping file naming another skeleton's joints, --mapping FILE or pair.mapping.toml, selects it)"
    );
    assert!(clip.warnings().contains(&w));
    // One skeleton: no warning.
    let one = HumanClip::from_bvh_str(&walk, "walk.bvh", &ImportOptions::default()).unwrap();
    assert!(one.other_skeletons.is_empty() && one.skeletons_warning().is_none());
}
