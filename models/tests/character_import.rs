//! Character import: URDF → kinematic tree → forward kinematics, morphology and character state, on
//! small hand-written URDFs, the project's own characters (`assets/characters`) and the real public
//! URDFs in `../shared/data/robots` (set `ACE_ALLOW_MISSING_DATA=1` to skip those when absent).

mod common;
use common::robots;

use std::f32::consts::FRAC_PI_2;
use std::path::{Path, PathBuf};

use ace_models::character_state::{CharacterLayout, StateScratch, character_state, character_state_into, decode_pose};
use ace_models::geometry::Shape;
use ace_models::kinematics::{CharacterPose, JointKind, KinematicTree};
use ace_models::morphology::{Morphology, Profile, ProfileProblem, load_character};
use ace_models::urdf::UrdfProblem;
use nalgebra::{Isometry3, Point3, Translation3, UnitQuaternion, Vector3};

const EPS: f32 = 1e-4;

fn manifest() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

fn characters() -> PathBuf {
    manifest().join("../assets/characters")
}

fn load(path: &Path) -> (KinematicTree, Morphology) {
    load_character(path).unwrap_or_else(|e| panic!("{e}"))
}

fn pose(tree: &KinematicTree, q: &[f32]) -> CharacterPose {
    assert_eq!(q.len(), tree.dof());
    CharacterPose {
        root: Isometry3::identity(),
        q: q.to_vec(),
    }
}

fn close(a: Vector3<f32>, b: Vector3<f32>) -> bool {
    (a - b).norm() < EPS
}

// ---------------------------------------------------------------------------------------------
// Forward kinematics on hand-written URDFs

const PLANAR_ARM: &str = r#"<robot name="planar">
  <link name="base"/>
  <link name="upper"><visual><origin xyz="0.5 0 0"/><geometry><box size="1 0.1 0.1"/></geometry></visual></link>
  <link name="lower"/>
  <link name="hand"/>
  <joint name="shoulder" type="revolute">
    <parent link="base"/><child link="upper"/><axis xyz="0 0 1"/>
    <limit lower="-3" upper="3" velocity="1" effort="1"/>
  </joint>
  <joint name="elbow" type="revolute">
    <origin xyz="1 0 0"/>
    <parent link="upper"/><child link="lower"/><axis xyz="0 0 1"/>
    <limit lower="-3" upper="3" velocity="1" effort="1"/>
  </joint>
  <joint name="wrist" type="fixed">
    <origin xyz="0.5 0 0"/><parent link="lower"/><child link="hand"/>
  </joint>
</robot>"#;

#[test]
fn planar_two_link_arm_matches_hand_computation() {
    let t = KinematicTree::from_urdf_str(PLANAR_ARM).unwrap();
    assert_eq!(t.dof(), 2);
    assert_eq!(t.dof_names(), ["shoulder", "elbow"]);
    let (a, b) = (0.3f32, 0.9f32);
    let fk = t.forward_kinematics(&pose(&t, &[a, b]));
    let elbow = Vector3::new(a.cos(), a.sin(), 0.0);
    let hand = elbow + 0.5 * Vector3::new((a + b).cos(), (a + b).sin(), 0.0);
    assert!(close(fk[t.link_index("lower").unwrap()].translation.vector, elbow));
    assert!(close(fk[t.link_index("hand").unwrap()].translation.vector, hand));
    assert!((fk[t.link_index("hand").unwrap()].rotation.angle() - (a + b)).abs() < EPS);
    // Root pose composes on the left.
    let root = Isometry3::from_parts(
        Translation3::new(1.0, 2.0, 3.0),
        UnitQuaternion::from_euler_angles(0.0, 0.0, FRAC_PI_2),
    );
    let moved = t.forward_kinematics(&CharacterPose { root, q: vec![a, b] });
    let expect = root.transform_point(&Point3::from(hand));
    assert!(close(moved[3].translation.vector, expect.coords));
}

#[test]
fn prismatic_rpy_and_fixed_chain() {
    let xml = r#"<robot name="chain">
      <link name="a"/><link name="b"/><link name="c"/><link name="d"/>
      <joint name="slide" type="prismatic">
        <origin xyz="0 0 1" rpy="0 0 1.5707963"/>
        <parent link="a"/><child link="b"/><axis xyz="1 0 0"/>
        <limit lower="0" upper="0.5" velocity="1" effort="1"/>
      </joint>
      <joint name="f1" type="fixed"><origin xyz="0 0 0.2" rpy="1.5707963 0 0"/><parent link="b"/><child link="c"/></joint>
      <joint name="f2" type="fixed"><origin xyz="0 0.3 0"/><parent link="c"/><child link="d"/></joint>
    </robot>"#;
    let t = KinematicTree::from_urdf_str(xml).unwrap();
    assert_eq!(t.dof(), 1);
    let fk = t.forward_kinematics(&pose(&t, &[0.25]));
    // The slide axis x is turned by yaw 90° onto world y.
    assert!(close(fk[1].translation.vector, Vector3::new(0.0, 0.25, 1.0)));
    assert!(close(fk[2].translation.vector, Vector3::new(0.0, 0.25, 1.2)));
    // c = Rz(90°)·Rx(90°): its local y is world z.
    assert!(close(fk[2].rotation * Vector3::y(), Vector3::z()));
    assert!(close(fk[3].translation.vector, Vector3::new(0.0, 0.25, 1.5)));
    // Limits clamp; neutral is zero clamped.
    let mut q = vec![2.0];
    t.clamp(&mut q);
    assert_eq!(q, vec![0.5]);
    assert_eq!(t.neutral_q(), vec![0.0]);
}

#[test]
fn rpy_origin_is_fixed_axis_xyz() {
    let xml = r#"<robot name="r"><link name="a"/><link name="b"/>
      <joint name="j" type="fixed"><origin xyz="0 0 0" rpy="0.3 -0.4 1.2"/><parent link="a"/><child link="b"/></joint>
    </robot>"#;
    let t = KinematicTree::from_urdf_str(xml).unwrap();
    let fk = t.forward_kinematics(&pose(&t, &[]));
    let (r, p, y) = (0.3f32, -0.4f32, 1.2f32);
    let expect = UnitQuaternion::from_axis_angle(&Vector3::z_axis(), y)
        * UnitQuaternion::from_axis_angle(&Vector3::y_axis(), p)
        * UnitQuaternion::from_axis_angle(&Vector3::x_axis(), r);
    assert!(fk[1].rotation.angle_to(&expect) < EPS);
}

#[test]
fn mimic_and_continuous_joints() {
    let xml = r#"<robot name="m"><link name="palm"/><link name="f1"/><link name="f2"/><link name="w"/>
      <joint name="wheel" type="continuous"><parent link="palm"/><child link="w"/><axis xyz="0 1 0"/></joint>
      <joint name="finger1" type="prismatic"><parent link="palm"/><child link="f1"/><axis xyz="0 1 0"/>
        <limit lower="0" upper="0.05" velocity="1" effort="1"/></joint>
      <joint name="finger2" type="prismatic"><parent link="palm"/><child link="f2"/><axis xyz="0 1 0"/>
        <limit lower="-0.05" upper="0" velocity="1" effort="1"/><mimic joint="finger1" multiplier="-1" offset="0.01"/></joint>
    </robot>"#;
    let t = KinematicTree::from_urdf_str(xml).unwrap();
    assert_eq!(t.dof_names(), ["wheel", "finger1"], "mimic joints have no DoF");
    let l = t.limits(0).unwrap();
    assert!(l.lower.is_infinite() && l.upper.is_infinite() && l.velocity.is_infinite());
    let fk = t.forward_kinematics(&pose(&t, &[10.0, 0.04]));
    assert!(close(
        fk[t.link_index("f2").unwrap()].translation.vector,
        Vector3::new(0.0, -0.03, 0.0)
    ));
    let mut q = vec![10.0, 0.0];
    t.clamp(&mut q);
    assert_eq!(q[0], 10.0, "continuous joints are not clamped");
}

#[test]
fn floating_joint_is_fixed_with_a_warning() {
    let xml = r#"<robot name="f"><link name="world"/><link name="base"/><link name="imu"/>
      <joint name="float" type="floating"><origin xyz="0 0 1"/><parent link="world"/><child link="base"/></joint>
      <joint name="imu" type="fixed"><parent link="world"/><child link="imu"/></joint></robot>"#;
    let t = KinematicTree::from_urdf_str(xml).unwrap();
    assert_eq!(t.dof(), 0);
    assert_eq!(t.links[1].joint.as_ref().unwrap().kind, JointKind::Fixed);
    assert!(t.warnings.iter().any(|w| w.contains("float")), "{:?}", t.warnings);
}

#[test]
fn fk_into_does_not_reallocate() {
    let (t, _) = load(&characters().join("crab.urdf"));
    let p = t.standing_pose();
    let mut out = Vec::with_capacity(t.links.len());
    let ptr = out.as_ptr();
    for _ in 0..3 {
        t.forward_kinematics_into(&p, &mut out);
    }
    assert_eq!(out.as_ptr(), ptr);
    assert_eq!(out, t.forward_kinematics(&p));
    // Poses serialise (e.g. for clips on disk).
    let json = serde_json::to_string(&p).unwrap();
    let back: CharacterPose = serde_json::from_str(&json).unwrap();
    assert!((back.root.translation.vector - p.root.translation.vector).norm() < 1e-6 && back.q == p.q);
}

#[test]
fn shapes_and_meshes_are_kept() {
    let xml = r#"<robot name="g"><link name="a">
      <visual><geometry><mesh filename="package://pkg/meshes/a.stl" scale="2 2 2"/></geometry></visual>
      <collision><origin xyz="0 0 -0.5"/><geometry><cylinder radius="0.1" length="1"/></geometry></collision>
      <collision><geometry><sphere radius="0.2"/></geometry></collision></link></robot>"#;
    let t = KinematicTree::from_urdf_str(xml).unwrap();
    match &t.links[0].visuals[0].shape {
        Shape::Mesh {
            filename,
            scale,
            bounds,
        } => {
            assert_eq!(filename, "package://pkg/meshes/a.stl");
            assert_eq!(*scale, Vector3::repeat(2.0));
            assert!(bounds.is_none());
        }
        s => panic!("{s:?}"),
    }
    assert_eq!(t.links[0].collisions.len(), 2);
    // Lowest collision point: cylinder bottom at −1.0 → standing height 1.0.
    assert!((t.standing_root_height() - 1.0).abs() < EPS);
}

// ---------------------------------------------------------------------------------------------
// Errors

fn problem(xml: &str) -> UrdfProblem {
    match KinematicTree::from_urdf_str(xml) {
        Ok(_) => panic!("expected an error"),
        Err(e) => {
            assert_eq!(e.file, "<string>");
            e.problem
        }
    }
}

#[test]
fn bad_files_name_the_file_and_the_problem() {
    let dir = manifest().join("tests/data/urdf");
    let cases: [(&str, &[&str]); 4] = [
        ("missing_parent.urdf", &["elbow", "upper_arm", "not defined"]),
        ("cycle.urdf", &["cycle", "a", "b", "c"]),
        ("unknown_joint_type.urdf", &["neck", "ball", "unknown type"]),
        ("malformed.urdf", &["malformed"]),
    ];
    for (file, words) in cases {
        let path = dir.join(file);
        let err = KinematicTree::from_urdf_file(&path).expect_err(file);
        let msg = err.to_string();
        assert!(msg.contains(&path.display().to_string()), "{msg}");
        for w in words {
            assert!(msg.contains(w), "`{msg}` should mention `{w}`");
        }
    }
    let err = KinematicTree::from_urdf_file(&dir.join("does_not_exist.urdf")).unwrap_err();
    assert!(matches!(err.problem, UrdfProblem::Io(_)));
    assert!(err.to_string().contains("does_not_exist.urdf"));
}

#[test]
fn structural_errors() {
    assert_eq!(
        problem(
            r#"<robot name="x"><link name="a"/><link name="b"/><link name="c"/>
           <joint name="j" type="fixed"><parent link="a"/><child link="b"/></joint></robot>"#
        ),
        UrdfProblem::MultipleRoots {
            links: vec!["a".into(), "c".into()]
        }
    );
    assert_eq!(
        problem(
            r#"<robot name="x"><link name="a"/><link name="b"/>
           <joint name="j" type="fixed"><parent link="a"/><child link="b"/></joint>
           <joint name="k" type="fixed"><parent link="b"/><child link="a"/></joint></robot>"#
        ),
        UrdfProblem::Cycle {
            links: vec!["a".into(), "b".into(), "a".into()]
        }
    );
    assert_eq!(
        problem(
            r#"<robot name="x"><link name="a"/>
           <joint name="j" type="fixed"><parent link="a"/><child link="zz"/></joint></robot>"#
        ),
        UrdfProblem::MissingChild {
            joint: "j".into(),
            link: "zz".into()
        }
    );
    assert_eq!(
        problem(r#"<robot name="x"><link name="a"/><link name="a"/></robot>"#),
        UrdfProblem::DuplicateLink("a".into())
    );
    assert_eq!(problem(r#"<robot name="x"></robot>"#), UrdfProblem::NoLinks);
    assert!(matches!(
        problem("<robot name=\"x\"><link name=\"a\">"),
        UrdfProblem::Parse(_)
    ));
    assert!(matches!(problem("not xml at all"), UrdfProblem::Parse(_)));
}

#[test]
fn value_errors() {
    let joint = |body: &str| {
        format!(
            r#"<robot name="x"><link name="a"/><link name="b"/><joint name="j" {body}<parent link="a"/><child link="b"/></joint></robot>"#
        )
    };
    assert_eq!(
        problem(&joint(
            r#"type="revolute"><axis xyz="0 0 0"/><limit lower="-1" upper="1" velocity="1" effort="1"/>"#
        )),
        UrdfProblem::ZeroAxis("j".into())
    );
    assert!(matches!(
        problem(&joint(r#"type="fixed"><origin xyz="0 nan 0"/>"#)),
        UrdfProblem::NonFinite(w) if w.contains("joint `j`")
    ));
    assert!(matches!(
        problem(&joint(r#"type="fixed"><origin xyz="0 0 0" rpy="inf 0 0"/>"#)),
        UrdfProblem::NonFinite(_)
    ));
    assert_eq!(
        problem(&joint(r#"type="spherical">"#)),
        UrdfProblem::UnsupportedJointType {
            joint: "j".into(),
            kind: "spherical".into()
        }
    );
    assert_eq!(
        problem(&joint(r#"type="hinge">"#)),
        UrdfProblem::UnknownJointType {
            joint: "j".into(),
            kind: "hinge".into()
        }
    );
    assert!(matches!(
        problem(r#"<robot name="x"><link name="a"><collision><geometry><sphere radius="NaN"/></geometry></collision></link></robot>"#),
        UrdfProblem::NonFinite(w) if w.contains("link `a`")
    ));
    // The axis of a fixed joint is ignored (real files write 0 0 0 there).
    KinematicTree::from_urdf_str(&joint(r#"type="fixed"><axis xyz="0 0 0"/>"#)).unwrap();
    // A vector of another length, or written with commas, names its line (urdf-rs named none).
    let commas = joint("type=\"fixed\">\n<origin xyz=\"0.3,0.06,0\"/>");
    assert_eq!(problem(&commas), UrdfProblem::Parse("line 2: `0.3,0.06,0` is not 3 numbers separated by spaces (0 read as numbers); URDF separates numbers by spaces, not commas".into()));
    let short = joint("type=\"fixed\"><origin rpy='0 1'/>");
    assert_eq!(problem(&short), UrdfProblem::Parse("line 1: `0 1` is not 3 numbers separated by spaces (2 read as numbers)".into()));
    // A limit without its velocity names the joint and the line (urdf-rs named neither).
    let no_velocity = joint(r#"type="revolute"><axis xyz="0 0 1"/>
        <limit lower="-1" upper="1" effort="1"/>"#);
    assert_eq!(problem(&no_velocity), UrdfProblem::LimitWithoutVelocity { line: 2, joint: "j".into() });
    assert!(problem(&no_velocity).to_string().starts_with("line 2: the `<limit>` of joint `j` has no `velocity`, which URDF requires"));
    let commented = joint(r#"type="revolute"><axis xyz="0 0 1"/><!-- <limit lower="-1"/> --><limit lower="-1" upper="1" velocity="2"/>"#);
    assert_eq!(KinematicTree::from_urdf_str(&commented).unwrap().dof(), 1);
}

// ---------------------------------------------------------------------------------------------
// The project's characters

#[test]
fn bundled_spot() {
    let (t, m) = load(&characters().join("spot.urdf"));
    assert_eq!(t.dof(), 18);
    let names = m.names(&t);
    assert_eq!(names.feet, ["fl_foot", "fr_foot", "rl_foot", "rr_foot"]);
    assert_eq!(names.manipulators, ["gripper_tip"]);
    assert!(names.wheels.is_empty() && names.head.is_none());
    assert!(
        m.tip_offsets.is_empty(),
        "foot frames sit at the sole: {:?}",
        m.tip_offsets
    );

    let fk = t.forward_kinematics(&t.neutral_pose(Isometry3::identity()));
    let at = |n: &str| fk[t.link_index(n).unwrap()];
    for leg in ["fl", "fr", "rl", "rr"] {
        let hip = at(&format!("{leg}_thigh")).translation.vector;
        let knee = at(&format!("{leg}_shank")).translation.vector;
        let foot = at(&format!("{leg}_foot"));
        let foot_centre = foot.transform_point(&Point3::new(0.0, 0.0, 0.025)).coords;
        assert!(
            ((knee - hip).norm() - 0.32).abs() < 1e-3,
            "thigh {}",
            (knee - hip).norm()
        );
        assert!(
            ((foot_centre - knee).norm() - 0.32).abs() < 1e-3,
            "shank {}",
            (foot_centre - knee).norm()
        );
        assert!(knee.x < hip.x, "knees point backward");
    }
    let h = t.standing_root_height();
    assert!((0.45..0.55).contains(&h), "standing root height {h}");
    // Standing: every foot on the ground, the body well above it.
    let stand = t.forward_kinematics(&t.standing_pose());
    for &f in &m.feet {
        assert!(m.ee_point(f, &stand).z.abs() < 1e-3);
    }
    assert!((t.lowest_z(&stand)).abs() < 1e-5);
    let arm = t.dof_names().iter().filter(|n| n.starts_with("arm_")).count();
    assert_eq!(arm, 6);
}

#[test]
fn bundled_crab() {
    let (t, m) = load(&characters().join("crab.urdf"));
    assert_eq!(t.dof(), 24);
    assert_eq!(m.feet.len(), 6);
    assert_eq!(m.manipulators.len(), 2);
    assert!(m.wheels.is_empty());
    let names = m.names(&t);
    assert!(names.manipulators.iter().all(|n| n.ends_with("claw_tip")), "{names:?}");
    assert!(names.feet.iter().all(|n| n.ends_with("_foot")), "{names:?}");
    let stand = t.forward_kinematics(&t.standing_pose());
    for &f in &m.feet {
        assert!(m.ee_point(f, &stand).z.abs() < 1e-3);
    }
    for &c in &m.manipulators {
        assert!(m.ee_point(c, &stand).z > 0.1, "claws are held up");
    }
    // Every limb has three revolute joints.
    assert!((0..t.dof()).all(|d| t.dof_joint(d).kind == JointKind::Revolute));
}

#[test]
fn bundled_stretch() {
    let (t, m) = load(&characters().join("stretch.urdf"));
    assert_eq!(t.dof(), 8);
    let names = m.names(&t);
    assert_eq!(names.wheels, ["left_wheel", "right_wheel"]);
    assert!(
        m.wheels
            .iter()
            .all(|&w| t.links[w].joint.as_ref().unwrap().kind == JointKind::Continuous)
    );
    assert_eq!(names.manipulators, ["grasp_center"]);
    assert!(m.feet.is_empty());
    let kinds: Vec<JointKind> = (0..t.dof()).map(|d| t.dof_joint(d).kind).collect();
    assert_eq!(
        kinds.iter().filter(|k| **k == JointKind::Prismatic).count(),
        5,
        "lift + 4 arm stages"
    );
    // Extending the telescope moves the grasp centre along −y by the sum of the stages.
    let mut q = t.neutral_q();
    let fk0 = t.forward_kinematics(&pose(&t, &q));
    for n in ["joint_arm_l3", "joint_arm_l2", "joint_arm_l1", "joint_arm_l0"] {
        q[t.dof_index(n).unwrap()] = 0.1;
    }
    q[t.dof_index("joint_lift").unwrap()] = 0.5;
    let fk1 = t.forward_kinematics(&pose(&t, &q));
    let g = m.manipulators[0];
    let d = fk1[g].translation.vector - fk0[g].translation.vector;
    assert!(close(d, Vector3::new(0.0, -0.4, 0.5)), "{d:?}");
}

// ---------------------------------------------------------------------------------------------
// Real URDFs nobody here wrote

#[test]
fn real_spot_with_arm() {
    let Some(dir) = robots() else { return };
    let (t, m) = load(&dir.join("spot_arm/spot_with_arm.urdf"));
    assert_eq!((t.links.len(), t.dof()), (28, 19));
    assert_eq!(m.feet.len(), 4, "{:?}", m.names(&t));
    assert_eq!(m.manipulators.len(), 1, "{:?}", m.names(&t));
    assert!(m.wheels.is_empty());
    let names = m.names(&t);
    assert!(names.feet.iter().all(|n| n.ends_with("_foot")), "{names:?}");
    // The gripper, not one of the many arm links.
    assert_eq!(names.manipulators, ["arm_link_fngr"]);
    // Mesh references are kept; the missing visual meshes are reported, not fatal.
    assert!(t.warnings.iter().any(|w| w.contains("body.obj")));
}

#[test]
fn real_phantomx() {
    let Some(dir) = robots() else { return };
    let (t, m) = load(&dir.join("phantomx_hexapod/phantomx_description/urdf/phantomx.urdf"));
    assert_eq!(t.dof(), 18);
    assert_eq!(m.feet.len(), 6, "{:?}", m.names(&t));
    assert!(m.wheels.is_empty() && m.manipulators.is_empty());
    // The tibia's lowest point (read from the STL bounds) is the foot point, not the knee.
    let stand = t.forward_kinematics(&t.standing_pose());
    for &f in &m.feet {
        assert!(m.ee_point(f, &stand).z.abs() < 5e-3, "{}", m.ee_point(f, &stand));
    }
}

#[test]
fn real_stretch() {
    let Some(dir) = robots() else { return };
    let (t, m) = load(&dir.join("stretch_re1/stretch_description_RE1V0_tool_stretch_gripper.urdf"));
    assert_eq!(t.dof(), 12);
    assert!(m.wheels.len() >= 2, "{:?}", m.names(&t));
    assert_eq!(m.manipulators.len(), 1, "{:?}", m.names(&t));
    assert!(m.feet.is_empty(), "{:?}", m.names(&t));
    let names = m.names(&t);
    assert_eq!(names.manipulators, ["link_grasp_center"]);
    assert_eq!(names.head.as_deref(), Some("link_head_tilt"));
}

/// `urdf` with a root link without geometry added above its root, holding it by a joint of type
/// `kind` as ROS's `base_footprint` (at the ground under the body) or a `world` link (at the body) do,
/// and with `sensor` also a frame without geometry on it (a laser's); written in a fresh folder
/// beside links to everything in the folder `top`, so that its meshes are found.
fn with_frame_root(urdf: &Path, top: &Path, frame: &str, kind: &str, sensor: bool) -> PathBuf {
    let (t, _) = load(urdf);
    let xml = std::fs::read_to_string(urdf).unwrap();
    // The file's root: the first link that is no joint's child (the tree's may be below it).
    let name_after = |text: &str, key: &str| text.split(key).skip(1).map(|r| r.split('"').next().unwrap().to_string()).collect::<Vec<_>>();
    let children = name_after(&xml, "<child link=\"");
    let root = name_after(&xml, "<link name=\"").into_iter().find(|l| !children.contains(l)).unwrap();
    let z = if frame == "base_footprint" { t.standing_root_height() } else { 0.0 };
    let open = xml.find("<robot").unwrap();
    let at = open + xml[open..].find('>').unwrap() + 1;
    let mut added = format!(
        r#"<link name="{frame}"/><joint name="{frame}_joint" type="{kind}"><parent link="{frame}"/><child link="{root}"/><origin xyz="0 0 {z}"/></joint>"#
    );
    if sensor {
        added += &format!(r#"<link name="test_laser"/><joint name="test_laser_joint" type="fixed"><parent link="{frame}"/><child link="test_laser"/><origin xyz="0.2 0 {z}"/></joint>"#);
    }
    let dir = std::env::temp_dir().join(format!("ace-frame-root-{}-{frame}-{}", std::process::id(), urdf.file_stem().unwrap().to_string_lossy()));
    std::fs::create_dir_all(&dir).unwrap();
    for e in std::fs::read_dir(top).unwrap() {
        let e = e.unwrap();
        let link = dir.join(e.file_name());
        if !link.exists() && e.path().extension().is_none_or(|x| x != "urdf") {
            std::os::unix::fs::symlink(e.path(), link).unwrap();
        }
    }
    let out = dir.join(urdf.file_name().unwrap());
    std::fs::write(&out, format!("{}{added}{}", &xml[..at], &xml[at..])).unwrap();
    out
}

/// ROS's robots hang from a link without geometry: `base_footprint` at the ground under the body, or
/// a `world` link. Every robot once rested on its body at such a frame, its feet taken for
/// manipulators, and its standing height was the frame's (zero), by which the controllers scale a
/// crouch. The frame is no longer the root: the tree, standing height and body plan are the robot's
/// own, with a warning. Where the frame holds other frames too (a laser's) it stays the root, and
/// the body plan still ignores it.
#[test]
fn a_root_frame_without_geometry_leaves_the_body_plan_as_it_is() {
    let mut urdfs: Vec<(PathBuf, PathBuf)> = ["spot", "crab", "stretch"].iter().map(|c| (characters().join(format!("{c}.urdf")), characters())).collect();
    if let Some(dir) = robots() {
        for (top, file) in [
            ("spot_arm", "spot_with_arm.urdf"),
            ("phantomx_hexapod", "phantomx_description/urdf/phantomx.urdf"),
            ("stretch_re1", "stretch_description_RE1V0_tool_stretch_gripper.urdf"),
        ] {
            urdfs.push((dir.join(top).join(file), dir.join(top)));
        }
    }
    for (urdf, top) in &urdfs {
        let (t, m) = load(urdf);
        let want = m.names(&t);
        for (frame, kind, sensor) in [("base_footprint", "fixed", false), ("world", "floating", false), ("base_footprint", "fixed", true)] {
            let (tf, mf) = load(&with_frame_root(urdf, top, frame, kind, sensor));
            if sensor {
                assert_eq!(tf.links[0].name, frame);
            } else {
                assert_eq!((tf.links.len(), &tf.links[0].name), (t.links.len(), &t.links[0].name));
                assert!((tf.standing_root_height() - t.standing_root_height()).abs() < 1e-6);
                let held = tf.warnings.iter().find_map(|w| w.strip_prefix(&format!("root link `{frame}` has no geometry and holds `")));
                let tail = format!("by its {kind} joint `{frame}_joint`: it is a frame, and the character's root is `{}`", t.links[0].name);
                assert!(held.is_some_and(|w| w.ends_with(&tail)), "{:?}", tf.warnings);
            }
            let got = mf.names(&tf);
            assert_eq!(
                (&got.feet, &got.manipulators, &got.wheels, &got.head),
                (&want.feet, &want.manipulators, &want.wheels, &want.head),
                "{} under `{frame}`",
                urdf.display()
            );
        }
    }
}

/// An unexpanded xacro file (real ones ship as `.xacro` and as `.urdf`) is refused at its first
/// xacro construct, saying how to expand it; it once read as a robot of one link and no DoF. A URDF
/// xacro wrote, which keeps the `xmlns:xacro` declaration, reads.
#[test]
fn an_unexpanded_xacro_file_is_refused_at_its_first_xacro_line() {
    let Some(dir) = robots() else { return };
    for (file, line, what) in [
        ("phantomx_hexapod/phantomx_description/urdf/phantomx.xacro", 4, "<xacro:include filename=\"$(find phantomx"),
        ("spot_arm/spot_description/urdf/spot_arm_macro.urdf", 3, "<xacro:macro name=\"load_arm\" params=\""),
    ] {
        let path = dir.join(file);
        let e = KinematicTree::from_urdf_file(&path).unwrap_err();
        assert_eq!(e.problem, UrdfProblem::Xacro { line, what: what.into() }, "{file}");
        assert!(e.to_string().starts_with(&format!("{}: line {line}: `{what}` is xacro, not URDF: expand the file into a URDF first", path.display())), "{e}");
    }
    // Inside a comment it is not used; a `${…}` in a value is.
    let xml = |value: &str| format!("<robot name=\"r\">\n<!-- <xacro:macro name=\"m\"/> ${{x}} -->\n<link name=\"{value}\"/></robot>");
    assert_eq!(KinematicTree::from_urdf_str(&xml("body")).unwrap().links.len(), 1);
    assert_eq!(problem(&xml("${prefix}body")), UrdfProblem::Xacro { line: 3, what: "${prefix}body\"/></robot>".into() });
    load(&dir.join("phantomx_hexapod/phantomx_description/urdf/phantomx.urdf"));
}

#[test]
fn real_urdfs_parse_from_strings_too() {
    let Some(dir) = robots() else { return };
    // Without a file there is no directory to find meshes in: analysis falls back to link origins.
    let xml = std::fs::read_to_string(dir.join("phantomx_hexapod/phantomx_description/urdf/phantomx.urdf")).unwrap();
    let t = KinematicTree::from_urdf_str(&xml).unwrap();
    assert_eq!(Morphology::analyze(&t).feet.len(), 6);
}

// ---------------------------------------------------------------------------------------------
// Profiles

#[test]
fn profile_overrides_and_rest_pose() {
    let path = characters().join("spot.urdf");
    let mut t = KinematicTree::from_urdf_file(&path).unwrap();
    let p = Profile::from_toml(
        r#"manipulators = ["gripper"]
           head = "gripper_tip"
           [rest_pose]
           arm_sh0 = 0.5
           [tip_offsets]
           gripper = [0.1, 0.0, 0.0]"#,
        "test.profile.toml",
    )
    .unwrap();
    p.apply_rest_pose(&mut t).unwrap();
    assert_eq!(t.neutral_q()[t.dof_index("arm_sh0").unwrap()], 0.5);
    let m = Morphology::with_profile(&t, &p).unwrap();
    let names = m.names(&t);
    assert_eq!(names.feet.len(), 4, "feet keep the analysis");
    assert_eq!(names.manipulators, ["gripper"]);
    assert_eq!(names.head.as_deref(), Some("gripper_tip"));
    assert_eq!(m.end_effectors().len(), 6);
    assert_eq!(
        m.tip_offset(t.link_index("gripper").unwrap()),
        Vector3::new(0.1, 0.0, 0.0)
    );

    let bad = Profile::from_toml(r#"feet = ["nope"]"#, "bad.profile.toml").unwrap();
    let e = Morphology::with_profile(&t, &bad).unwrap_err();
    assert_eq!(e.problem, ProfileProblem::UnknownLink("nope".into()));
    assert!(e.to_string().contains("bad.profile.toml"));
    let e = Profile::from_toml("feet = 3", "x.toml").unwrap_err();
    assert!(matches!(e.problem, ProfileProblem::Parse(_)));
    let e = Profile::from_toml("[rest_pose]\nnot_a_joint = 1.0", "x.toml")
        .unwrap()
        .apply_rest_pose(&mut t)
        .unwrap_err();
    assert_eq!(e.problem, ProfileProblem::UnknownJoint("not_a_joint".into()));
    assert_eq!(Profile::path_beside(&path), characters().join("spot.profile.toml"));
}

/// Profile values that read but make no sense for the body: each was accepted, and the dataset or the
/// retarget went on with another body than the one meant (a foot also an arm, two feet on one leg, a
/// knee clamped from 100 "degrees" to its limit, a gripper's tip 50 m off).
#[test]
fn profile_mistakes_are_refused_naming_the_key() {
    let path = characters().join("spot.urdf");
    let refused = |toml: &str, key: &str, value: &str, why: &str| {
        let p = Profile::from_toml(toml, "spot.profile.toml").unwrap();
        let mut t = KinematicTree::from_urdf_file(&path).unwrap();
        let e = p.apply_rest_pose(&mut t).and_then(|()| Morphology::with_profile(&t, &p).map(|_| ())).unwrap_err();
        let msg = e.to_string();
        assert!(msg.starts_with(&format!("spot.profile.toml: `{key}` = {value}: ")) && msg.contains(why), "{toml}: {msg}");
    };
    refused(r#"feet = ["fl_foot", "fr_foot", "fl_foot", "rr_foot"]"#, "feet", "\"fl_foot\"", "listed twice in `feet`");
    refused(r#"manipulators = ["fl_foot", "gripper_tip"]"#, "manipulators", "\"fl_foot\"", "also in `feet`");
    refused(r#"head = "gripper_tip""#, "head", "\"gripper_tip\"", "also in `manipulators`");
    refused(r#"feet = ["fl_shank", "fl_foot", "fr_foot", "rr_foot"]"#, "feet", "\"fl_foot\"", "hangs below `fl_shank`");
    refused("[tip_offsets]\ngripper_tip = [0.0, 0.0, 50.0]", "tip_offsets.\"gripper_tip\"", "[0.0, 0.0, 50.0]", "farther than the character is big");
    refused("[tip_offsets]\nfl_foot = [1e30, 0.0, 0.0]", "tip_offsets.\"fl_foot\"", "[1e30, 0.0, 0.0]", "farther than the character is big");
    refused("[tip_offsets]\nfl_shank = [0.0, 0.0, -0.1]", "tip_offsets.\"fl_shank\"", "[0.0, 0.0, -0.1]", "not an end effector");
    refused("[rest_pose]\nfl_knee = 100.0", "rest_pose.\"fl_knee\"", "100", "outside the joint's limits [-1.39, 1.15]");
    refused("[rest_pose]\nfl_knee = -1.4", "rest_pose.\"fl_knee\"", "-1.4", "outside the joint's limits");
    // A wheel on a fixed joint was accepted and never turned (the wheel's joint has no DoF to spin).
    refused(r#"wheels = ["gripper_tip"]"#, "wheels", "\"gripper_tip\"", "its joint does not turn");
    // Nor does a sliding one (Stretch's lift).
    let p = Profile::from_toml(r#"wheels = ["lift"]"#, "stretch.profile.toml").unwrap();
    let e = Morphology::with_profile(&KinematicTree::from_urdf_file(&characters().join("stretch.urdf")).unwrap(), &p).unwrap_err();
    assert!(e.to_string().starts_with("stretch.profile.toml: `wheels` = \"lift\": its joint does not turn"), "{e}");

    // At the limits, and roles given consistently, they are read.
    for toml in [
        "[rest_pose]\nfl_knee = 1.15\nfr_knee = -1.39",
        r#"feet = ["fl_foot", "fr_foot", "rl_foot"]
           manipulators = ["rr_foot", "gripper_tip"]
           [tip_offsets]
           gripper_tip = [0.0, 0.0, 0.05]"#,
    ] {
        let p = Profile::from_toml(toml, "spot.profile.toml").unwrap();
        let mut t = KinematicTree::from_urdf_file(&path).unwrap();
        p.apply_rest_pose(&mut t).unwrap();
        Morphology::with_profile(&t, &p).unwrap_or_else(|e| panic!("{toml}: {e}"));
    }
}

// ---------------------------------------------------------------------------------------------
// Character state

fn walking_pose(t: &KinematicTree, time: f32, yaw0: f32, speed: f32) -> CharacterPose {
    let mut q = t.neutral_q();
    for (d, x) in q.iter_mut().enumerate() {
        *x += 0.1 * (time * 3.0 + d as f32).sin();
    }
    t.clamp(&mut q);
    let heading = UnitQuaternion::from_axis_angle(&Vector3::z_axis(), yaw0);
    let tilt = UnitQuaternion::from_euler_angles(0.05, -0.03, 0.0);
    let p = heading * Vector3::new(speed * time, 0.0, 0.0) + Vector3::new(0.0, 0.0, 0.5);
    CharacterPose {
        root: Isometry3::from_parts(Translation3::from(p), heading * tilt),
        q,
    }
}

#[test]
fn layout_dims_add_up() {
    let (t, m) = load(&characters().join("spot.urdf"));
    let l = CharacterLayout::new(&t, &m);
    assert_eq!(l.end_effectors, 5);
    let ranges = [
        l.root_height(),
        l.root_orientation(),
        l.root_displacement(),
        l.root_delta_rotation(),
        l.root_linear_velocity(),
        l.root_angular_velocity(),
        l.joint_positions(),
        l.ee_positions(),
        l.ee_velocities(),
    ];
    let lens: Vec<usize> = ranges.iter().map(|r| r.len()).collect();
    assert_eq!(lens, [1, 4, 2, 4, 3, 3, 18, 15, 15]);
    assert!(ranges.windows(2).all(|w| w[0].end == w[1].start));
    assert_eq!(l.dim(), 65);
    assert_eq!(l.entry_names(&t, &m).len(), l.dim());
    let x = character_state(
        &t,
        &m,
        &walking_pose(&t, 0.0, 0.0, 1.0),
        &walking_pose(&t, 0.1, 0.0, 1.0),
        0.1,
    );
    assert_eq!(x.len(), l.dim());
}

#[test]
fn constant_root_velocity_gives_constant_features() {
    let (t, m) = load(&characters().join("crab.urdf"));
    let l = CharacterLayout::new(&t, &m);
    let dt = 1.0 / 30.0;
    // Root moves at 0.6 m/s along its heading (yaw 0.8), keeping its orientation.
    let at = |k: usize| {
        let mut p = walking_pose(&t, k as f32 * dt, 0.8, 0.6);
        p.q = t.neutral_q();
        p
    };
    let states: Vec<Vec<f32>> = (1..5)
        .map(|k| character_state(&t, &m, &at(k - 1), &at(k), dt))
        .collect();
    for s in &states {
        assert!((s[l.root_displacement()][0] - 0.6 * dt).abs() < 1e-5);
        assert!(s[l.root_displacement()][1].abs() < 1e-5);
        let v = &s[l.root_linear_velocity()];
        assert!(
            (v[0] - 0.6).abs() < 1e-3 && v[1].abs() < 1e-3 && v[2].abs() < 1e-3,
            "{v:?}"
        );
        assert!(s[l.root_angular_velocity()].iter().all(|w| w.abs() < 1e-3));
        assert_eq!(&s[l.root_delta_rotation()], &[1.0, 0.0, 0.0, 0.0]);
        assert!((s[l.root_height()][0] - 0.5).abs() < 1e-6);
        // Rigid translation: every end effector moves with the root.
        for c in s[l.ee_velocities()].chunks(3) {
            assert!((c[0] - 0.6).abs() < 1e-3 && c[1].abs() < 1e-3, "{c:?}");
        }
    }
    for w in states.windows(2) {
        assert!(w[0].iter().zip(&w[1]).all(|(a, b)| (a - b).abs() < 1e-3));
    }
}

#[test]
fn state_is_invariant_to_world_yaw_and_position() {
    let (t, m) = load(&characters().join("spot.urdf"));
    let dt = 0.05;
    let (p0, p1) = (walking_pose(&t, 0.0, 0.3, 1.2), walking_pose(&t, dt, 0.3, 1.2));
    let mut p1 = p1;
    p1.root.rotation = UnitQuaternion::from_axis_angle(&Vector3::z_axis(), 0.05) * p1.root.rotation;
    let a = character_state(&t, &m, &p0, &p1, dt);
    let world = Isometry3::from_parts(
        Translation3::new(3.0, -2.0, 0.0),
        UnitQuaternion::from_axis_angle(&Vector3::z_axis(), 2.1),
    );
    let moved = |p: &CharacterPose| CharacterPose {
        root: world * p.root,
        q: p.q.clone(),
    };
    let b = character_state(&t, &m, &moved(&p0), &moved(&p1), dt);
    let worst = a.iter().zip(&b).map(|(x, y)| (x - y).abs()).fold(0.0, f32::max);
    assert!(worst < 1e-4, "largest difference {worst}");
    // The turn shows as yaw in the delta rotation and as angular velocity about z.
    let l = CharacterLayout::new(&t, &m);
    assert!(a[l.root_angular_velocity()][2] > 0.9);
}

#[test]
fn integrate_root_inverts_the_state() {
    let (t, m) = load(&characters().join("stretch.urdf"));
    let l = CharacterLayout::new(&t, &m);
    let dt = 0.1;
    let p0 = walking_pose(&t, 0.0, -1.0, 0.8);
    let mut p1 = walking_pose(&t, dt, -1.0, 0.8);
    p1.root.rotation = UnitQuaternion::from_euler_angles(0.02, 0.1, 0.3) * p1.root.rotation;
    p1.root.translation.vector += Vector3::new(0.01, 0.03, 0.02);
    let mut out = vec![0.0; l.dim()];
    let mut scratch = StateScratch::default();
    character_state_into(&t, &m, &p0, &p1, dt, &mut scratch, &mut out);
    let back = decode_pose(&l, &p0.root, &out);
    assert!((back.root.translation.vector - p1.root.translation.vector).norm() < 1e-5);
    assert!(back.root.rotation.angle_to(&p1.root.rotation) < 1e-4);
    assert_eq!(back.q, p1.q);
    // Root orientation relative to the heading has no yaw left: its x axis stays in the x–z plane.
    let o = &out[l.root_orientation()];
    let local = UnitQuaternion::from_quaternion(nalgebra::Quaternion::new(o[0], o[1], o[2], o[3]));
    assert!((local * Vector3::x()).y.abs() < 1e-5);
}
