//! Features Ψ and the motion-quality metrics: UFR detectors on constructed good and bad motions of
//! the bundled characters, FID and DIV against closed forms and hand computations, and the body-length
//! normalisation of Ψ.

mod common;
use common::robots;

use std::f32::consts::{FRAC_PI_2, PI};
use std::path::PathBuf;

use ace_models::character_state::{CharacterLayout, character_state};
use ace_models::features::{
    EndEffectorMapping, FeatureBlock, FeatureLayout, FeatureWeights, character_body_length, character_features,
    feature_loss, human_features, mean_feature_loss,
};
use ace_models::human::{EndEffector, HumanFrame, HumanState, JOINT_COUNT, layout as hl};
use ace_models::kinematics::{CharacterPose, KinematicTree};
use ace_models::metrics::collision::{Primitive, penetration_depth, segment_distance};
use ace_models::metrics::distribution::sqrt_psd;
use ace_models::metrics::{
    DivConfig, GaussianFit, MetricsInput, MetricsReport, UfrConfig, UfrDetector, diversity, fid, frechet_distance,
    poses_from_state_episodes, poses_from_states, ufr, ufr_episodes,
};
use ace_models::morphology::{Morphology, load_character};
use nalgebra::{DMatrix, Isometry3, Matrix3, Point3, Translation3, UnitQuaternion, Vector3};

const FPS: f32 = 30.0;

fn character(name: &str) -> (KinematicTree, Morphology) {
    let p = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join(format!("../assets/characters/{name}.urdf"));
    load_character(&p).unwrap()
}

/// DoFs on the path from the root to `link`.
fn chain_dofs(tree: &KinematicTree, link: usize) -> Vec<usize> {
    let mut out = Vec::new();
    let mut l = Some(link);
    while let Some(i) = l {
        if let Some(d) = tree.links[i].joint.as_ref().and_then(|j| j.dof) {
            out.push(d);
        }
        l = tree.links[i].parent;
    }
    out
}

/// Damped least-squares IK with a numerical Jacobian: moves the DoFs of the given end effectors'
/// chains so that each end-effector point reaches its world target (the root stays where it is).
fn reach(tree: &KinematicTree, morph: &Morphology, pose: &mut CharacterPose, targets: &[(usize, Point3<f32>)]) {
    let mut dofs: Vec<usize> = targets.iter().flat_map(|(l, _)| chain_dofs(tree, *l)).collect();
    dofs.sort_unstable();
    dofs.dedup();
    let points = |p: &CharacterPose| {
        let links = tree.forward_kinematics(p);
        targets
            .iter()
            .map(|(l, _)| morph.ee_point(*l, &links))
            .collect::<Vec<_>>()
    };
    let m = 3 * targets.len();
    for _ in 0..30 {
        let now = points(pose);
        let r = nalgebra::DVector::from_iterator(
            m,
            targets
                .iter()
                .zip(&now)
                .flat_map(|((_, t), p)| (t - p).iter().copied().collect::<Vec<_>>()),
        );
        if r.norm() < 1e-6 {
            return;
        }
        let mut j = DMatrix::<f32>::zeros(m, dofs.len());
        for (c, &d) in dofs.iter().enumerate() {
            let mut q = pose.clone();
            q.q[d] += 1e-3;
            for (k, (p1, p0)) in points(&q).iter().zip(&now).enumerate() {
                let col = (p1 - p0) / 1e-3;
                j.fixed_view_mut::<3, 1>(3 * k, c).copy_from(&col);
            }
        }
        let jjt = &j * j.transpose() + DMatrix::<f32>::identity(m, m) * 1e-6;
        let dq = j.transpose() * jjt.lu().solve(&r).unwrap();
        for (c, &d) in dofs.iter().enumerate() {
            pose.q[d] += dq[c];
        }
        tree.clamp(&mut pose.q);
    }
}

/// Foot points at the standing pose.
fn standing_feet(tree: &KinematicTree, morph: &Morphology) -> Vec<(usize, Point3<f32>)> {
    let links = tree.forward_kinematics(&tree.standing_pose());
    morph.feet.iter().map(|&f| (f, morph.ee_point(f, &links))).collect()
}

fn count(v: &[bool]) -> usize {
    v.iter().filter(|&&b| b).count()
}

// ---------------------------------------------------------------------------------------------------
// Body length and thresholds

#[test]
fn body_lengths_of_the_bundled_characters() {
    let expect = [("spot", 0.55, 0.65), ("crab", 0.15, 0.25), ("stretch", 1.2, 1.45)];
    for (name, lo, hi) in expect {
        let (t, m) = character(name);
        let l = character_body_length(&t, &m);
        let c = UfrConfig::for_character(&t, &m);
        let det = UfrDetector::new(&t, &m, c);
        println!(
            "{name}: body length {l:.3} m; checked pairs {}; contact {:.4} m, sliding {:.4} m/s, depth {:.4} m",
            det.self_collision().pairs().len(),
            c.contact_height,
            c.sliding_speed,
            c.penetration_depth
        );
        assert!(l > lo && l < hi, "{name}: body length {l}");
        assert!((c.penetration_depth - 0.01 * l).abs() < 1e-6);
        assert!((c.sliding_speed - 0.1 * l).abs() < 1e-6);
    }
}

/// A character's body length leaves out its manipulator arms, as a human's height leaves out raised
/// arms: Spot's and the crab's are the tops of their other links at the standing pose (the body box,
/// the knees), whatever their arms do; with the arms counted they would be taller.
#[test]
fn body_lengths_leave_out_the_manipulator_arms() {
    for name in ["spot", "crab"] {
        let (t, m) = character(name);
        let links = t.forward_kinematics(&t.standing_pose());
        let top_of = |keep: &dyn Fn(usize) -> bool| {
            (0..t.links.len())
                .filter(|&i| keep(i))
                .map(|i| t.links[i].aabb(&links[i]).map_or(links[i].translation.vector.z, |b| b.max.z))
                .fold(f32::NEG_INFINITY, f32::max)
        };
        let on_arm = |i: usize| m.manipulators.iter().any(|&g| t.is_descendant(g, i) && !t.is_descendant(m.feet[0], i));
        let bottom = t.lowest_z(&links);
        let without = top_of(&|i| !on_arm(i)) - bottom;
        let with = top_of(&|_| true) - bottom;
        let l = character_body_length(&t, &m);
        println!("{name}: body length {l:.4} m, without the arms {without:.4}, with them {with:.4}");
        assert!((l - without).abs() < 1e-5, "{name}: {l} against {without}");
        assert!(with > without + 0.01, "{name}: the arms rise above the body at the standing pose");
    }
    // An arm on a mount plate fixed to the body (a link of the root body that carries nothing else) is
    // still an arm: Spot with one measures as Spot.
    let p = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../assets/characters/spot.urdf");
    let xml = std::fs::read_to_string(p).unwrap();
    let mounted = xml.replacen(
        r#"<parent link="body"/><child link="arm_base"/>"#,
        r#"<parent link="arm_mount"/><child link="arm_base"/>"#,
        1,
    );
    let mounted = mounted.replacen(
        "</robot>",
        r#"<link name="arm_mount"/><joint name="mount" type="fixed"><parent link="body"/><child link="arm_mount"/></joint></robot>"#,
        1,
    );
    assert_ne!(mounted, xml);
    let t = KinematicTree::from_urdf_str(&mounted).unwrap();
    let m = Morphology::analyze(&t);
    let (spot, spot_m) = character("spot");
    assert_eq!(m.manipulators.len(), 1);
    assert!((character_body_length(&t, &m) - character_body_length(&spot, &spot_m)).abs() < 1e-5);
}

// ---------------------------------------------------------------------------------------------------
// UFR: clean motions stay silent

#[test]
fn standing_still_is_clean() {
    for name in ["spot", "crab", "stretch"] {
        let (t, m) = character(name);
        let poses = vec![t.standing_pose(); 60];
        let r = ufr(&t, &m, &poses, FPS, &UfrConfig::for_character(&t, &m));
        assert_eq!(r.frames, 60);
        assert_eq!(r.rates.ufr, 0.0, "{name}: {:?}", r.summary());
    }
}

/// The body sways sideways and bobs (±2 cm, ±1 cm, 0.5 Hz, with a little roll) while IK keeps the
/// feet planted.
fn sway(name: &str) -> (KinematicTree, Morphology, Vec<CharacterPose>) {
    let (t, m) = character(name);
    let poses = sway_of(&t, &m, 0.0);
    (t, m, poses)
}

/// [`sway`] about a root `crouch` metres lower than standing (for legs that are straight at rest).
fn sway_of(t: &KinematicTree, m: &Morphology, crouch: f32) -> Vec<CharacterPose> {
    let feet = standing_feet(t, m);
    let stand = t.standing_pose();
    let mut pose = stand.clone();
    let mut poses = Vec::new();
    for k in 0..90 {
        let s = (2.0 * PI * 0.5 * k as f32 / FPS).sin();
        pose.root = Isometry3::from_parts(
            Translation3::from(stand.root.translation.vector + Vector3::new(0.0, 0.02 * s, 0.01 * s - crouch)),
            UnitQuaternion::from_euler_angles(0.05 * s, 0.0, 0.0),
        );
        reach(t, m, &mut pose, &feet);
        poses.push(pose.clone());
    }
    poses
}

#[test]
fn slow_body_sway_is_clean() {
    for name in ["spot", "crab"] {
        let (t, m, poses) = sway(name);
        // The IK really kept the feet planted.
        let feet = standing_feet(&t, &m);
        let links = t.forward_kinematics(&poses[40]);
        for (f, p) in &feet {
            assert!(
                (m.ee_point(*f, &links) - p).norm() < 1e-4,
                "{name}: IK did not converge"
            );
        }
        let r = ufr(&t, &m, &poses, FPS, &UfrConfig::for_character(&t, &m));
        assert_eq!(r.rates.ufr, 0.0, "{name}: {:?}", r.summary());
    }
}

#[test]
fn spinning_wheels_of_a_rolling_base_are_clean() {
    let (t, m) = character("stretch");
    let wheel_dofs: Vec<usize> = m
        .wheels
        .iter()
        .filter_map(|&w| t.links[w].joint.as_ref()?.dof)
        .collect();
    assert_eq!(wheel_dofs.len(), 2);
    let stand = t.standing_pose();
    let poses: Vec<CharacterPose> = (0..120)
        .map(|k| {
            let x = 0.5 * k as f32 / FPS; // 0.5 m/s
            let mut p = stand.clone();
            p.root.translation.vector.x = x;
            for &d in &wheel_dofs {
                p.q[d] = x / 0.05; // rolling without slip, r = 5 cm
            }
            p
        })
        .collect();
    let r = ufr(&t, &m, &poses, FPS, &UfrConfig::for_character(&t, &m));
    assert_eq!(r.rates.ufr, 0.0, "{:?}", r.summary());
}

// ---------------------------------------------------------------------------------------------------
// UFR: bad motions fire their detector, and only it

#[test]
fn a_foot_pushed_through_the_ground_is_penetration() {
    let (t, m) = character("spot");
    let mut feet = standing_feet(&t, &m);
    let mut pose = t.standing_pose();
    let mut poses = Vec::new();
    for k in 0..40 {
        // Frames 20..30: the front left foot 3 cm (5 % of the body length) below the ground.
        feet[0].1.z = if (20..30).contains(&k) { -0.03 } else { 0.0 };
        reach(&t, &m, &mut pose, &feet);
        poses.push(pose.clone());
    }
    let r = ufr(&t, &m, &poses, FPS, &UfrConfig::for_character(&t, &m));
    let flagged: Vec<usize> = r.flagged_frames().collect();
    assert_eq!(flagged, (20..30).collect::<Vec<_>>(), "{:?}", r.summary());
    assert_eq!(count(&r.penetration), 10);
    assert_eq!(count(&r.sliding) + count(&r.self_collision), 0);
    assert!((r.rates.penetration - 0.25).abs() < 1e-6);
}

#[test]
fn a_dragged_stance_foot_is_sliding() {
    let (t, m) = character("spot");
    let mut feet = standing_feet(&t, &m);
    let mut pose = t.standing_pose();
    let mut poses = Vec::new();
    for k in 0..60 {
        // Frames 30..45: the front left foot dragged forward on the ground at 0.15 m/s (≈ 0.25 L/s).
        if (30..45).contains(&k) {
            feet[0].1.x += 0.15 / FPS;
        }
        reach(&t, &m, &mut pose, &feet);
        poses.push(pose.clone());
    }
    let r = ufr(&t, &m, &poses, FPS, &UfrConfig::for_character(&t, &m));
    assert_eq!(
        r.sliding.iter().positions(),
        (30..45).collect::<Vec<_>>(),
        "{:?}",
        r.summary()
    );
    assert_eq!(count(&r.penetration) + count(&r.self_collision), 0);

    // The same drag 5 cm above the ground is a swing, not a slide.
    let mut feet = standing_feet(&t, &m);
    feet[0].1.z = 0.05;
    let mut pose = t.standing_pose();
    let mut poses = Vec::new();
    for _ in 0..30 {
        feet[0].1.x += 0.15 / FPS;
        reach(&t, &m, &mut pose, &feet);
        poses.push(pose.clone());
    }
    let r = ufr(&t, &m, &poses, FPS, &UfrConfig::for_character(&t, &m));
    assert_eq!(r.rates.ufr, 0.0, "{:?}", r.summary());
}

#[test]
fn sliding_is_not_measured_across_episode_boundaries() {
    let (t, m) = character("spot");
    let a = t.standing_pose();
    let mut b = a.clone();
    b.root.translation.vector.x += 2.0; // the next episode starts elsewhere
    let poses: Vec<CharacterPose> = std::iter::repeat_n(a, 10).chain(std::iter::repeat_n(b, 10)).collect();
    let c = UfrConfig::for_character(&t, &m);
    let whole = ufr(&t, &m, &poses, FPS, &c);
    assert_eq!(
        whole.sliding.iter().positions(),
        vec![10],
        "one episode: the jump slides"
    );
    let split = ufr_episodes(&t, &m, &poses, &[0..10, 10..20], FPS, &c);
    assert_eq!(split.rates.ufr, 0.0, "two episodes: nothing");
}

#[test]
fn spot_arm_folded_into_its_body_collides() {
    let (t, m) = character("spot");
    let sh1 = t.dof_index("arm_sh1").unwrap();
    let c = UfrConfig::for_character(&t, &m);
    let mut poses = Vec::new();
    // Pitch the arm down from 0 (forward, clear of the body) to its limit 0.52 rad (into the body).
    for k in 0..=26 {
        let mut p = t.standing_pose();
        p.q[sh1] = 0.02 * k as f32;
        poses.push(p);
    }
    let r = ufr(&t, &m, &poses, FPS, &c);
    assert!(!r.self_collision[0] && !r.self_collision[5], "{:?}", r.summary());
    assert!(r.self_collision[26], "{:?}", r.summary());
    let first = r.self_collision.iter().position(|&b| b).unwrap();
    assert!(
        r.self_collision[first..].iter().all(|&b| b),
        "collision persists once the arm is in the body"
    );
    let pair = &r.collision_pairs[0];
    assert!([&pair.a, &pair.b].contains(&&"body".to_string()), "{pair:?}");
    // Only pairs that collided are listed, most frames first; the first collides in every frame from `first`.
    assert!(!r.collision_pairs.is_empty() && r.collision_pairs.len() <= 10, "{:?}", r.collision_pairs);
    assert!(r.collision_pairs.iter().all(|p| p.frames > 0), "{:?}", r.collision_pairs);
    assert!(r.collision_pairs.windows(2).all(|w| w[0].frames >= w[1].frames), "{:?}", r.collision_pairs);
    assert_eq!(pair.frames, 27 - first);
    assert!(pair.a.starts_with("arm") || pair.b.starts_with("arm"), "{pair:?}");
    assert_eq!(count(&r.penetration) + count(&r.sliding), 0);
    println!(
        "spot arm collides from sh1 = {:.2} rad: {:?}",
        0.02 * first as f32,
        r.collision_pairs
    );
}

#[test]
fn crab_legs_swung_into_each_other_collide() {
    let (t, m) = character("crab");
    let l1 = t.dof_index("leg_l1_coxa").unwrap();
    let l2 = t.dof_index("leg_l2_coxa").unwrap();
    let c = UfrConfig::for_character(&t, &m);
    // Swing the front and middle left legs toward each other until they cross (the legs are 0.44 rad
    // apart; the body stays up because the other legs... are not needed: the motion is lifted 5 cm).
    let mut poses = Vec::new();
    for k in 0..=16 {
        let a = 0.05 * k as f32;
        let mut p = t.standing_pose();
        p.root.translation.vector.z += 0.05;
        p.q[l1] = a;
        p.q[l2] = -a;
        poses.push(p);
    }
    let r = ufr(&t, &m, &poses, FPS, &c);
    println!("{:?}", r.collision_pairs);
    assert!(!r.self_collision[0], "{:?}", r.summary());
    assert!(
        r.self_collision[8],
        "legs crossed at ±0.4 rad must collide: {:?}",
        r.summary()
    );
    let pair = &r.collision_pairs[0];
    assert!(pair.a.starts_with("leg_l1") && pair.b.starts_with("leg_l2"), "{pair:?}");
    assert_eq!(count(&r.penetration), 0, "{:?}", r.summary());
}

// ---------------------------------------------------------------------------------------------------
// Narrow phase

#[test]
fn narrow_phase_on_primitives() {
    let cap = |a: [f32; 3], b: [f32; 3], r: f32| Primitive::Capsule {
        a: Point3::from(a),
        b: Point3::from(b),
        radius: r,
    };
    let obb = |c: [f32; 3], rot: Matrix3<f32>, h: [f32; 3]| Primitive::Obb {
        center: Point3::from(c),
        axes: rot,
        half: Vector3::from(h),
    };
    // Crossing segments 0.3 apart, radii 0.1 + 0.25 → 0.05 deep.
    let a = cap([-1.0, 0.0, 0.0], [1.0, 0.0, 0.0], 0.1);
    let b = cap([0.0, -1.0, 0.3], [0.0, 1.0, 0.3], 0.25);
    assert!((penetration_depth(&a, &b) - 0.05).abs() < 1e-5);
    // Parallel segments.
    let d = segment_distance(
        &Point3::new(0.0, 0.0, 0.0),
        &Point3::new(1.0, 0.0, 0.0),
        &Point3::new(0.5, 0.2, 0.0),
        &Point3::new(2.0, 0.2, 0.0),
    );
    assert!((d - 0.2).abs() < 1e-6);
    // A sphere 0.05 from a box face, another 0.05 from an edge of a box turned 45° about z.
    let bx = obb([0.0; 3], Matrix3::identity(), [0.5, 0.5, 0.5]);
    assert!((penetration_depth(&cap([0.6, 0.0, 0.0], [0.6, 0.0, 0.0], 0.2), &bx) - 0.1).abs() < 1e-5);
    let rot = *UnitQuaternion::from_euler_angles(0.0, 0.0, PI / 4.0)
        .to_rotation_matrix()
        .matrix();
    let turned = obb([0.0; 3], rot, [0.5, 0.5, 0.5]);
    let edge = 0.5 * 2f32.sqrt();
    let s = cap([edge + 0.05, 0.0, 0.0], [edge + 0.05, 0.0, 0.0], 0.1);
    assert!((penetration_depth(&s, &turned) - 0.05).abs() < 1e-4);
    // A capsule passing through a box counts its radius; one passing beside it is clear.
    assert!((penetration_depth(&cap([-2.0, 0.0, 0.0], [2.0, 0.0, 0.0], 0.1), &bx) - 0.1).abs() < 1e-5);
    assert!(penetration_depth(&cap([-2.0, 0.7, 0.0], [2.0, 0.7, 0.0], 0.1), &bx) < 0.0);
    // Boxes: overlapping by 0.1 along x; separated along a cross axis only.
    let b2 = obb([0.9, 0.2, 0.0], Matrix3::identity(), [0.5, 0.5, 0.5]);
    assert!((penetration_depth(&bx, &b2) - 0.1).abs() < 1e-5);
    let far = obb([1.2, 1.2, 0.0], rot, [0.5, 0.5, 0.5]);
    assert!(penetration_depth(&bx, &far) < 0.0);
    // Lowest points.
    assert!((cap([0.0, 0.0, 1.0], [0.0, 0.0, 0.5], 0.1).lowest_z() - 0.4).abs() < 1e-6);
    assert!((turned.lowest_z() + 0.5).abs() < 1e-6);
}

// ---------------------------------------------------------------------------------------------------
// FID and DIV

/// Deterministic pseudo-random numbers in [−1, 1).
struct Lcg(u64);
impl Lcg {
    fn next(&mut self) -> f32 {
        self.0 = self
            .0
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        ((self.0 >> 40) as f32 / (1u64 << 24) as f32) * 2.0 - 1.0
    }
    /// Roughly normal (sum of uniforms).
    fn normal(&mut self) -> f32 {
        (0..6).map(|_| self.next()).sum::<f32>() / 2.0f32.sqrt()
    }
}

fn correlated_set(n: usize, seed: u64) -> Vec<Vec<f32>> {
    let mut g = Lcg(seed);
    (0..n)
        .map(|_| {
            let (a, b, c) = (g.normal(), g.normal(), g.normal());
            vec![a, 0.5 * a + b, 2.0 * c - a, 0.1 * b, 3.0]
        })
        .collect()
}

#[test]
fn fid_of_a_set_against_itself_is_zero_and_grows_with_a_shift() {
    let a = correlated_set(5000, 1);
    assert!(fid(&a, &a).abs() < 1e-6, "{}", fid(&a, &a));
    let mut last = 0.0;
    for shift in [0.1f32, 0.5, 1.0, 2.0] {
        let b: Vec<Vec<f32>> = a.iter().map(|r| r.iter().map(|x| x + shift).collect()).collect();
        let f = fid(&a, &b);
        // Same covariance: only the mean term remains, ‖δ‖² = 5 δ².
        assert!(
            (f - 5.0 * f64::from(shift).powi(2)).abs() < 1e-3 * (1.0 + f),
            "{shift}: {f}"
        );
        assert!(f > last);
        last = f;
    }
    // An independent sample of the same distribution is close.
    let c = correlated_set(5000, 2);
    assert!(fid(&a, &c) < 0.05, "{}", fid(&a, &c));
}

#[test]
fn fid_matches_the_closed_form_for_gaussians() {
    // 1-D: (μ₁ − μ₂)² + (σ₁ − σ₂)² with the sample moments.
    let mut g = Lcg(7);
    let a: Vec<[f32; 1]> = (0..4000).map(|_| [1.0 + 0.5 * g.normal()]).collect();
    let b: Vec<[f32; 1]> = (0..3000).map(|_| [-0.5 + 2.0 * g.normal()]).collect();
    let moments = |s: &[[f32; 1]]| {
        let n = s.len() as f64;
        let m = s.iter().map(|x| f64::from(x[0])).sum::<f64>() / n;
        let v = s.iter().map(|x| (f64::from(x[0]) - m).powi(2)).sum::<f64>() / (n - 1.0);
        (m, v.sqrt())
    };
    let ((m1, s1), (m2, s2)) = (moments(&a), moments(&b));
    let expect = (m1 - m2).powi(2) + (s1 - s2).powi(2);
    assert!(
        (fid(&a, &b) - expect).abs() < 1e-9 * (1.0 + expect),
        "{} vs {expect}",
        fid(&a, &b)
    );

    // Non-commuting covariances: against the definition with (Σ₁Σ₂)^{1/2} computed by hand for 2×2
    // (tr √M = √(tr M + 2√det M) for a matrix with real non-negative eigenvalues).
    let fa = GaussianFit {
        n: 0,
        mean: nalgebra::DVector::from_vec(vec![0.0, 1.0]),
        cov: DMatrix::from_row_slice(2, 2, &[2.0, 0.8, 0.8, 1.0]),
    };
    let fb = GaussianFit {
        n: 0,
        mean: nalgebra::DVector::from_vec(vec![0.5, -1.0]),
        cov: DMatrix::from_row_slice(2, 2, &[0.5, -0.2, -0.2, 3.0]),
    };
    let m = &fa.cov * &fb.cov;
    let tr_sqrt = (m.trace() + 2.0 * m.determinant().sqrt()).sqrt();
    let expect = 0.25 + 4.0 + fa.cov.trace() + fb.cov.trace() - 2.0 * tr_sqrt;
    assert!(
        (frechet_distance(&fa, &fb) - expect).abs() < 1e-10,
        "{} vs {expect}",
        frechet_distance(&fa, &fb)
    );
}

#[test]
fn a_marginal_fit_is_the_fit_of_its_columns() {
    let a = correlated_set(3000, 4);
    let fit = GaussianFit::fit(&a);
    let cols: Vec<Vec<f32>> = a.iter().map(|r| r[1..4].to_vec()).collect();
    let want = GaussianFit::fit(&cols);
    let got = fit.marginal(1..4);
    assert_eq!((got.n, got.dim()), (3000, 3));
    assert!((&got.mean - &want.mean).amax() < 1e-12 && (&got.cov - &want.cov).amax() < 1e-12);
    // The correlated columns 1 and 2 keep their covariance (a·0.5 against −a: −0.5).
    assert!((got.cov[(0, 1)] + 0.5).abs() < 0.1, "{}", got.cov[(0, 1)]);
}

#[test]
fn div_matches_a_hand_computation() {
    // Three frames; pair distances 5, 10, 5 → mean 20/3 (few enough pairs to use them all).
    let set = vec![vec![0.0f32, 0.0], vec![3.0, 4.0], vec![6.0, 8.0]];
    assert!((diversity(&set, &DivConfig::default()) - 20.0 / 3.0).abs() < 1e-5);
    // Sampled pairs: deterministic per seed, close to the exhaustive mean.
    let big = correlated_set(400, 3);
    let exact = diversity(
        &big,
        &DivConfig {
            pairs: usize::MAX,
            seed: 0,
        },
    );
    let cfg = DivConfig { pairs: 5000, seed: 42 };
    let sampled = diversity(&big, &cfg);
    assert_eq!(sampled, diversity(&big, &cfg));
    assert!((sampled - exact).abs() < 0.03 * exact, "{sampled} vs {exact}");
    assert_ne!(sampled, diversity(&big, &DivConfig { pairs: 5000, seed: 43 }));
    assert_eq!(diversity(&set[..1], &DivConfig::default()), 0.0);
}

#[test]
fn div_uses_every_pair_exactly_when_few_and_distinct_frames_when_sampling() {
    let none: [[f32; 2]; 0] = [];
    assert_eq!(diversity(&none, &DivConfig::default()), 0.0);
    assert_eq!(diversity(&[[0.0f32, 0.0], [3.0, 4.0]], &DivConfig::default()), 5.0, "two frames, one pair");
    assert_eq!(diversity(&[[0.0f32, 0.0], [3.0, 4.0]], &DivConfig { pairs: 0, seed: 0 }), 0.0);
    // Five frames on a line: 10 pairs, exactly as many as asked, so all are used once.
    let line: Vec<[f32; 1]> = (0..5).map(|i| [i as f32]).collect();
    let exact = (0..5).flat_map(|i| (i + 1..5).map(move |j| (j - i) as f32)).sum::<f32>() / 10.0;
    assert!((diversity(&line, &DivConfig { pairs: 10, seed: 0 }) - exact).abs() < 1e-6);
    // A regular tetrahedron: every pair of distinct corners is 1 apart, so sampled pairs of distinct
    // frames average exactly 1 whichever are drawn (a frame paired with itself would pull it down).
    let h = 0.5 * std::f32::consts::FRAC_1_SQRT_2;
    let tetra = [[0.5, 0.0, -h], [-0.5, 0.0, -h], [0.0, 0.5, h], [0.0, -0.5, h]];
    for seed in 0..20 {
        let d = diversity(&tetra, &DivConfig { pairs: 5, seed });
        assert!((d - 1.0).abs() < 1e-5, "seed {seed}: {d}");
    }
}

#[test]
fn a_gaussian_fit_of_more_rows_than_a_block_and_of_one_row() {
    // 5,000 rows: more than one block of the covariance's accumulation, the last one partial.
    let rows: Vec<[f32; 2]> = (0..5000).map(|i| { let t = i as f32 * 0.01; [t.sin(), (1.7 * t).cos() + 0.3 * t.sin()] }).collect();
    let fit = GaussianFit::fit(&rows);
    let n = rows.len() as f64;
    let mean: Vec<f64> = (0..2).map(|k| rows.iter().map(|r| f64::from(r[k])).sum::<f64>() / n).collect();
    for a in 0..2 {
        assert!((fit.mean[a] - mean[a]).abs() < 1e-9);
        for b in 0..2 {
            let c = rows.iter().map(|r| (f64::from(r[a]) - mean[a]) * (f64::from(r[b]) - mean[b])).sum::<f64>() / (n - 1.0);
            assert!((fit.cov[(a, b)] - c).abs() < 1e-9, "cov[{a},{b}] {} vs {c}", fit.cov[(a, b)]);
        }
    }
    // One row: its mean, no spread.
    let one = GaussianFit::fit(&[[2.0f32, -1.0]]);
    assert_eq!((one.mean[0], one.mean[1]), (2.0, -1.0));
    assert!(one.cov.iter().all(|&v| v == 0.0), "{}", one.cov);
}

// ---------------------------------------------------------------------------------------------------
// Features Ψ

/// A human frame walking along +y (facing +y), with the pelvis at `t` m along the way.
fn human_frame(t: f32, k: f32) -> HumanFrame {
    let yaw = UnitQuaternion::from_euler_angles(0.1 * t, 0.05, FRAC_PI_2 + 0.2 * t);
    let mut positions = [Vector3::zeros(); JOINT_COUNT];
    for (j, p) in positions.iter_mut().enumerate() {
        let local = Vector3::new(
            0.05 * (j as f32).sin(),
            0.1 * (j as f32).cos(),
            0.9 - 0.05 * j as f32 + 0.02 * t,
        );
        *p = (Vector3::new(0.3 * t, t, 0.95) + yaw * local) * k;
    }
    HumanFrame {
        positions,
        root_rotation: yaw,
    }
}

#[test]
fn scaling_lengths_and_body_length_together_leaves_psi_unchanged() {
    let mapping = EndEffectorMapping::new(vec![
        Some(EndEffector::LeftFoot),
        Some(EndEffector::RightFoot),
        None,
        Some(EndEffector::RightHand),
        Some(EndEffector::Head),
    ]);
    let layout = FeatureLayout::new(&mapping);
    assert_eq!(layout.end_effectors, 4);
    assert_eq!(layout.dim(), 13 + 12);
    let psi = |k: f32| {
        let s = HumanState::from_frames(&human_frame(0.1, k), &human_frame(0.0, k), &human_frame(0.1, k), 0.1);
        human_features(s.as_slice(), 1.7 * k, &mapping)
    };
    let (a, b) = (psi(1.0), psi(2.5));
    for (x, y) in a.iter().zip(&b) {
        assert!((x - y).abs() < 1e-4, "{a:?}\n{b:?}");
    }
    // The entries are what the state holds, normalised.
    let s = HumanState::from_frames(
        &human_frame(0.1, 1.0),
        &human_frame(0.0, 1.0),
        &human_frame(0.1, 1.0),
        0.1,
    );
    let x = s.as_slice();
    assert!((a[0] - x[0] / 1.7).abs() < 1e-6);
    assert!((a[layout.root_linear_velocity()][1] - x[hl::ROOT_LINEAR_VELOCITY][1] / 1.7).abs() < 1e-6);
    assert_eq!(&a[layout.root_angular_velocity()], &x[hl::ROOT_ANGULAR_VELOCITY]);
    let head = &a[layout.ee_positions()][9..12];
    for (h, v) in head.iter().zip(&x[hl::ee_position(EndEffector::Head)]) {
        assert!((h - v / 1.7).abs() < 1e-6);
    }
}

/// A one-legged robot whose lengths are multiplied by `k`.
fn scaled_robot(k: f32) -> KinematicTree {
    let f = |v: f32| v * k;
    let xml = format!(
        r#"<robot name="hopper">
  <link name="base"><collision><geometry><box size="{} {} {}"/></geometry></collision></link>
  <joint name="hip" type="revolute"><parent link="base"/><child link="thigh"/>
    <origin xyz="{} 0 {}"/><axis xyz="0 1 0"/><limit lower="-1" upper="1" velocity="1" effort="1"/></joint>
  <link name="thigh"><collision><origin xyz="0 0 {}"/><geometry><cylinder radius="{}" length="{}"/></geometry></collision></link>
  <joint name="knee" type="revolute"><parent link="thigh"/><child link="shin"/>
    <origin xyz="0 0 {}"/><axis xyz="0 1 0"/><limit lower="-1" upper="1" velocity="1" effort="1"/></joint>
  <link name="shin"><collision><origin xyz="0 0 {}"/><geometry><cylinder radius="{}" length="{}"/></geometry></collision></link>
  <joint name="ankle" type="revolute"><parent link="shin"/><child link="foot"/>
    <origin xyz="0 0 {}"/><axis xyz="1 0 0"/><limit lower="-1" upper="1" velocity="1" effort="1"/></joint>
  <link name="foot"><collision><geometry><sphere radius="{}"/></geometry></collision></link>
</robot>"#,
        f(0.4),
        f(0.2),
        f(0.1),
        f(0.1),
        f(-0.05),
        f(-0.15),
        f(0.03),
        f(0.3),
        f(-0.3),
        f(-0.15),
        f(0.025),
        f(0.3),
        f(-0.3),
        f(0.03),
    );
    KinematicTree::from_urdf_str(&xml).unwrap()
}

#[test]
fn character_psi_is_scale_free_with_the_body_length() {
    let mut results = Vec::new();
    for k in [1.0f32, 3.0] {
        let t = scaled_robot(k);
        let m = Morphology::analyze(&t);
        assert_eq!(m.feet.len(), 1, "{:?}", m.names(&t));
        let layout = CharacterLayout::new(&t, &m);
        let mapping = EndEffectorMapping::by_side(&t, &m);
        assert_eq!(mapping.human, vec![Some(EndEffector::LeftFoot)]);
        let body = character_body_length(&t, &m);
        let pose = |s: f32| {
            let mut p = t.standing_pose();
            p.root = Isometry3::from_parts(
                Translation3::new(0.4 * s * k, 0.1 * s * k, p.root.translation.z + 0.02 * s * k),
                UnitQuaternion::from_euler_angles(0.1 * s, 0.2 * s, 0.7 * s),
            );
            p.q = vec![0.3 * s, -0.2 * s, 0.1 * s];
            p
        };
        let x = character_state(&t, &m, &pose(0.0), &pose(1.0), 0.1);
        results.push((body, character_features(&layout, &x, body, &mapping)));
    }
    let ((l1, a), (l3, b)) = (&results[0], &results[1]);
    assert!(
        (l3 / l1 - 3.0).abs() < 1e-4,
        "body length scales with the robot: {l1} {l3}"
    );
    for (x, y) in a.iter().zip(b) {
        assert!((x - y).abs() < 1e-4, "{a:?}\n{b:?}");
    }
}

#[test]
fn orientation_features_are_continuous_and_sign_free() {
    let mapping = EndEffectorMapping::new(vec![]);
    let layout = FeatureLayout::new(&mapping);
    let mut x = [0.0f32; hl::DIM];
    x[0] = 1.0;
    // Rotations about y through ±180°: the quaternion with w ≥ 0 jumps there, Ψ does not.
    let at = |angle: f32, x: &mut [f32; hl::DIM], sign: f32| {
        let q = UnitQuaternion::from_euler_angles(0.0, angle, 0.0);
        let c = q.quaternion().coords; // (i, j, k, w)
        x[hl::ROOT_ORIENTATION].copy_from_slice(&[sign * c.w, sign * c.x, sign * c.y, sign * c.z]);
        human_features(x, 1.0, &mapping)[layout.root_orientation()].to_vec()
    };
    let a = at(PI - 1e-3, &mut x, 1.0);
    let b = at(-PI + 1e-3, &mut x, 1.0);
    let dist: f32 = a.iter().zip(&b).map(|(p, q)| (p - q).powi(2)).sum::<f32>().sqrt();
    assert!(dist < 5e-3, "{a:?} {b:?}");
    assert_eq!(at(0.7, &mut x, 1.0), at(0.7, &mut x, -1.0));
    // Identity: forward x, up z.
    let id = at(0.0, &mut x, 1.0);
    assert_eq!(id, vec![1.0, 0.0, 0.0, 0.0, 0.0, 1.0]);
}

#[test]
fn feature_loss_is_the_weighted_mean_square() {
    let mapping = EndEffectorMapping::new(vec![Some(EndEffector::LeftHand)]);
    let layout = FeatureLayout::new(&mapping);
    assert_eq!(layout.dim(), 16);
    assert_eq!(layout.entry_names().len(), 16);
    let a = vec![0.0f32; 16];
    let mut b = vec![0.0f32; 16];
    b[layout.root_height().start] = 1.0; // squared error 1 in the height block
    b[layout.ee_positions().start] = 2.0; // squared error 4 in the end-effector block
    let w = FeatureWeights::default();
    assert!((feature_loss(&layout, &a, &b, &w) - 5.0 / 16.0).abs() < 1e-7);
    // Weights that change the sum (2·1 + 0.25·4 = 3, against 5 unweighted).
    let w = FeatureWeights {
        root_height: 2.0,
        ee_positions: 0.25,
        ..Default::default()
    };
    assert!((feature_loss(&layout, &a, &b, &w) - 3.0 / 16.0).abs() < 1e-7);
    assert!((feature_loss(&layout, &a, &b, &w.only(FeatureBlock::EePositions)) - 1.0 / 16.0).abs() < 1e-7);
    assert_eq!(
        w.per_element(&layout)[layout.range(FeatureBlock::EePositions)],
        [0.25; 3]
    );
    assert!(
        (mean_feature_loss(&layout, &[a.clone(), a.clone()], &[b, a], &FeatureWeights::default()) - 2.5 / 16.0).abs()
            < 1e-7
    );
}

#[test]
fn human_and_character_psi_align() {
    for name in ["spot", "crab", "stretch"] {
        let (t, m) = character(name);
        let mapping = EndEffectorMapping::by_side(&t, &m);
        assert_eq!(mapping.human.len(), m.n_end_effectors());
        let layout = CharacterLayout::new(&t, &m);
        let x = character_state(&t, &m, &t.standing_pose(), &t.standing_pose(), 1.0 / FPS);
        let psi_r = character_features(&layout, &x, character_body_length(&t, &m), &mapping);
        let psi_h = human_features(&[0.5; hl::DIM], 1.7, &mapping);
        assert_eq!(psi_r.len(), psi_h.len());
        assert_eq!(psi_r.len(), FeatureLayout::new(&mapping).dim());
        println!("{name}: mapping {:?}", mapping.human);
    }
    let (t, m) = character("crab");
    let mapping = EndEffectorMapping::by_side(&t, &m);
    use EndEffector::*;
    assert_eq!(
        mapping.human.iter().flatten().copied().collect::<Vec<_>>(),
        [
            LeftFoot, LeftFoot, LeftFoot, RightFoot, RightFoot, RightFoot, LeftHand, RightHand
        ]
    );
    let (t, m) = character("spot");
    assert_eq!(EndEffectorMapping::by_side(&t, &m).human[4], Some(RightHand));
}

// ---------------------------------------------------------------------------------------------------
// From states to a report

#[test]
fn metrics_from_states_and_the_json_report() {
    let (t, m, poses) = sway("spot");
    // A walk forward and a turn on top of the sway, so that the decoded roots must integrate.
    let poses: Vec<CharacterPose> = poses
        .into_iter()
        .enumerate()
        .map(|(k, mut p)| {
            let turn = Isometry3::from_parts(
                Translation3::new(0.01 * k as f32, 0.0, 0.0),
                UnitQuaternion::from_euler_angles(0.0, 0.0, 0.005 * k as f32),
            );
            p.root = turn * p.root;
            p
        })
        .collect();
    let layout = CharacterLayout::new(&t, &m);
    let states: Vec<Vec<f32>> = (0..poses.len())
        .map(|k| character_state(&t, &m, &poses[k.saturating_sub(1)], &poses[k], 1.0 / FPS))
        .collect();
    let decoded = poses_from_states(&layout, &states);
    for (a, b) in poses.iter().zip(&decoded) {
        assert!((a.root.translation.vector - b.root.translation.vector).norm() < 1e-3);
        assert!(a.root.rotation.angle_to(&b.root.rotation) < 1e-3);
    }
    let c = UfrConfig::for_character(&t, &m);
    let r = ufr(&t, &m, &decoded, FPS, &c);
    assert_eq!(r.rates.ufr, ufr(&t, &m, &poses, FPS, &c).rates.ufr);

    let mapping = EndEffectorMapping::by_side(&t, &m);
    let body = character_body_length(&t, &m);
    let psi: Vec<Vec<f32>> = states
        .iter()
        .map(|x| character_features(&layout, x, body, &mapping))
        .collect();
    let reference = GaussianFit::fit(&psi);
    let report = MetricsReport::compute(
        &MetricsInput {
            features: &psi,
            reference: Some(&reference),
            source_features: Some(&psi),
            layout: FeatureLayout::new(&mapping),
            weights: FeatureWeights::default(),
            div: DivConfig::default(),
        },
        &r,
    );
    assert_eq!(report.frames, poses.len());
    assert!(report.fid.unwrap().abs() < 1e-4);
    assert_eq!(report.feature_loss, Some(0.0));
    assert!(report.div > 0.0);
    let json = serde_json::to_value(&report).unwrap();
    for key in ["frames", "div", "fid", "feature_loss", "ufr"] {
        assert!(json.get(key).is_some(), "{json}");
    }
    assert!(json["ufr"]["rates"]["sliding"].is_number());
    assert!(json["ufr"]["config"]["contact_height"].is_number());
    println!("{report}");
}

/// `positions()` on bool slices: the indices of the true entries.
trait Positions {
    fn positions(self) -> Vec<usize>;
}
impl<'a, I: Iterator<Item = &'a bool>> Positions for I {
    fn positions(self) -> Vec<usize> {
        self.enumerate().filter(|(_, b)| **b).map(|(i, _)| i).collect()
    }
}

#[test]
fn metrics_run_on_real_urdfs() {
    let Some(dir) = robots() else { return };
    for (p, lo, hi) in [
        ("spot_arm/spot_with_arm.urdf", 0.6, 0.9),
        ("phantomx_hexapod/phantomx_description/urdf/phantomx.urdf", 0.1, 0.3),
        (
            "stretch_re1/stretch_description_RE1V0_tool_stretch_gripper.urdf",
            1.3,
            1.5,
        ),
    ] {
        let (t, m) = load_character(&dir.join(p)).unwrap();
        let c = UfrConfig::for_character(&t, &m);
        assert!(
            c.body_length > lo && c.body_length < hi,
            "{p}: body length {}",
            c.body_length
        );
        let det = UfrDetector::new(&t, &m, c);
        assert!(!det.self_collision().pairs().is_empty(), "{p}");
        // Real robots' legs are nearly straight at joint zero: sway 10 % lower.
        let crouch = 0.1 * t.standing_root_height();
        let poses = if m.feet.is_empty() {
            vec![t.standing_pose(); 30]
        } else {
            sway_of(&t, &m, crouch)
        };
        for (f, target) in standing_feet(&t, &m) {
            let links = t.forward_kinematics(&poses[45]);
            assert!(
                (m.ee_point(f, &links) - target).norm() < 1e-3,
                "{p}: IK did not converge"
            );
        }
        let all = 0..poses.len();
        let r = det.evaluate(&poses, std::slice::from_ref(&all), FPS);
        assert_eq!(r.rates.ufr, 0.0, "{p}: {:?}", r.summary());
        let mapping = EndEffectorMapping::by_side(&t, &m);
        assert_eq!(mapping.human.len(), m.n_end_effectors());
        println!(
            "{p}: body length {:.3} m, {} checked pairs, mapping {:?}",
            c.body_length,
            det.self_collision().pairs().len(),
            mapping.human
        );
    }
}

#[test]
fn dataset_episodes_decode_and_score_separately() {
    // Two standing episodes, the second placed 2 m away and turned: decoded per episode, each starts at
    // the origin, and nothing slides.
    let (t, m) = character("spot");
    let layout = CharacterLayout::new(&t, &m);
    let a = t.standing_pose();
    let mut b = a.clone();
    b.root = Isometry3::from_parts(
        Translation3::new(2.0, 1.0, a.root.translation.z),
        UnitQuaternion::from_euler_angles(0.0, 0.0, 1.0),
    );
    let poses: Vec<CharacterPose> = std::iter::repeat_n(a, 10).chain(std::iter::repeat_n(b, 10)).collect();
    let states: Vec<Vec<f32>> = (0..poses.len())
        .map(|k| character_state(&t, &m, &poses[k.saturating_sub(1)], &poses[k], 1.0 / FPS))
        .collect();
    let episodes = [0..10, 10..20];
    let decoded = poses_from_state_episodes(&layout, &states, &episodes);
    assert_eq!(decoded.len(), 20);
    for p in &decoded {
        assert!(p.root.translation.vector.xy().norm() < 1e-5 && p.root.rotation.angle() < 1e-5);
    }
    let c = UfrConfig::for_character(&t, &m);
    assert_eq!(ufr_episodes(&t, &m, &decoded, &episodes, FPS, &c).rates.ufr, 0.0);
    // Undeclared boundaries integrate through: the jump of frame 10 is one displacement.
    let through = poses_from_states(&layout, &states);
    assert!((through[10].root.translation.vector.xy().norm() - 5f32.sqrt()).abs() < 1e-4);
}

#[test]
fn square_root_of_a_psd_matrix() {
    let a = DMatrix::from_row_slice(3, 3, &[4.0, 1.0, 0.5, 1.0, 3.0, 0.2, 0.5, 0.2, 2.0]);
    let s = sqrt_psd(&a);
    assert!((&s * &s - &a).norm() < 1e-12);
    assert!((&s - s.transpose()).norm() < 1e-12);
    // A singular PSD matrix (rank 1) with round-off.
    let v = nalgebra::DVector::from_vec(vec![1.0, 2.0, -1.0]);
    let r = &v * v.transpose();
    assert!((sqrt_psd(&r) * sqrt_psd(&r) - &r).norm() < 1e-6);
}

/// The UFR's thresholds are fractions of the character's body length: a half-metre character's are
/// half a one-metre character's (the contact height divided by the body length instead of multiplied
/// passed every other test: cargo-mutants).
#[test]
fn ufr_thresholds_scale_with_the_body_length() {
    use ace_models::metrics::ufr::UfrConfig;
    let c = UfrConfig::from_body_length(0.5);
    assert_eq!(c.body_length, 0.5);
    assert_eq!(c.collision_tolerance, 0.5 * UfrConfig::COLLISION_TOLERANCE);
    assert_eq!(c.penetration_depth, 0.5 * UfrConfig::PENETRATION_DEPTH);
    assert_eq!(c.contact_height, 0.5 * UfrConfig::CONTACT_HEIGHT);
    assert_eq!(c.sliding_speed, 0.5 * UfrConfig::SLIDING_SPEED);
}

/// Spot whose first `n` foot points are moved `dz` (m) straight down in the world at the standing
/// pose (up when negative), its geometry left where it is: the foot points and the feet's geometry
/// then disagree, so each criterion of the ground checks can be seen alone.
fn spot_with_foot_points_moved(dz: f32, n: usize) -> (KinematicTree, Morphology) {
    let (t, mut m) = character("spot");
    let links = t.forward_kinematics(&t.standing_pose());
    for foot in m.feet.clone().into_iter().take(n) {
        let down = links[foot].rotation.inverse() * Vector3::new(0.0, 0.0, -dz);
        *m.tip_offsets.entry(foot).or_insert_with(Vector3::zeros) += down;
    }
    (t, m)
}

/// A foot point below the ground is penetration on its own, with the foot's geometry above it: the
/// detectors, `penetrates`, `depth_below_ground` and `offending_links` (exactly that foot) agree.
#[test]
fn a_foot_point_alone_below_the_ground_is_penetration() {
    use ace_models::metrics::ufr::{PoseChecks, PoseScratch};
    let cfg = UfrConfig::for_character(&character("spot").0, &character("spot").1);
    let d = cfg.penetration_depth + 0.01;
    let (t, m) = spot_with_foot_points_moved(d, 1);
    let foot = m.feet[0];
    let standing = vec![t.standing_pose(); 10];
    let r = ufr(&t, &m, &standing, FPS, &cfg);
    assert_eq!(count(&r.penetration), 10, "{:?}", r.summary());
    assert_eq!(count(&r.self_collision) + count(&r.sliding), 0);
    // The same standing Spot with its own foot points is clean.
    let (t0, m0) = character("spot");
    assert_eq!(count(&ufr(&t0, &m0, &standing, FPS, &cfg).penetration), 0);

    let checks = PoseChecks::new(&t, &m, &cfg);
    let mut scratch = PoseScratch::default();
    checks.place(&t, &t.standing_pose(), &mut scratch);
    assert!(checks.penetrates(&m, &scratch));
    assert!(!checks.geometry_penetrates(&scratch), "the foot's geometry stays on the ground");
    let depth = checks.depth_below_ground(&m, &scratch);
    assert!((depth - d).abs() < 2e-3, "depth {depth} against the foot point's {d}");
    let mut hit = Vec::new();
    checks.offending_links(&m, &scratch, true, |l| hit.push(l));
    assert_eq!(hit, vec![foot]);
    hit.clear();
    checks.offending_links(&m, &scratch, false, |l| hit.push(l));
    assert!(hit.is_empty(), "{hit:?}");
}

/// The foot's geometry below the ground is penetration although its foot point is above: the foot
/// body's primitives count (only mesh boxes on foot bodies are left out), in `geometry_penetrates`,
/// `depth_below_ground` and `offending_links`; and a body other than a foot (Spot upside down, its
/// back in the ground and its feet in the air) counts in the depth.
#[test]
fn a_foot_body_below_the_ground_is_penetration_whatever_its_foot_point() {
    use ace_models::metrics::ufr::{PoseChecks, PoseScratch};
    let (t0, m0) = character("spot");
    let cfg = UfrConfig::for_character(&t0, &m0);
    // The foot points 5 cm up; the whole Spot lowered by the penetration depth and 1 cm.
    let (t, m) = spot_with_foot_points_moved(-0.05, 4);
    let sink = cfg.penetration_depth + 0.01;
    let mut pose = t.standing_pose();
    pose.root.translation.vector.z -= sink;
    let checks = PoseChecks::new(&t, &m, &cfg);
    let mut scratch = PoseScratch::default();
    checks.place(&t, &pose, &mut scratch);
    assert!(m.feet.iter().all(|&f| m.ee_point(f, &scratch.links).z > cfg.ground_z), "the foot points are above the ground");
    assert!(checks.geometry_penetrates(&scratch));
    let depth = checks.depth_below_ground(&m, &scratch);
    assert!((depth - sink).abs() < 2e-3, "depth {depth} against the sink {sink}");
    // Every foot's body is in the ground, no foot point.
    let mut hit = Vec::new();
    checks.offending_links(&m, &scratch, true, |l| hit.push(l));
    hit.sort_unstable();
    let sc = checks.self_collision();
    let mut want: Vec<usize> = m.feet.iter().map(|&f| sc.bodies()[sc.body_of(f)].link).collect();
    want.sort_unstable();
    assert_eq!(hit, want);

    // Upside down at 5 cm: the body's box is in the ground, every foot point far above it.
    let mut flipped = t0.standing_pose();
    flipped.root = Isometry3::from_parts(Translation3::new(0.0, 0.0, 0.05), UnitQuaternion::from_euler_angles(PI, 0.0, 0.0));
    let checks = PoseChecks::new(&t0, &m0, &cfg);
    checks.place(&t0, &flipped, &mut scratch);
    assert!(m0.feet.iter().all(|&f| m0.ee_point(f, &scratch.links).z > 0.2));
    let lowest = scratch.links.iter().map(|l| l.translation.vector.z).fold(f32::INFINITY, f32::min);
    let depth = checks.depth_below_ground(&m0, &scratch);
    assert!(depth > 0.02 && depth > -lowest, "depth {depth}, lowest link origin {lowest}");
    assert!(checks.penetrates(&m0, &scratch));
}

/// Each feature block is named (in `ace eval`'s tables, the editor and the CSV columns) by the
/// `[feature_weights]` key that sets its weight.
#[test]
fn each_feature_block_is_named_as_its_weight_key() {
    for block in FeatureBlock::ALL {
        let w: FeatureWeights = toml::from_str(&format!("{} = 7.0", block.name())).unwrap();
        for other in FeatureBlock::ALL {
            let want = if other == block { 7.0 } else { 1.0 };
            assert_eq!(w.weight(other), want, "`{} = 7.0` set {}", block.name(), other.name());
        }
    }
}

/// Feature weights are finite and non-negative (a negative one would reward moving away from the
/// human); the refusal names the block's key and the value. Zero is allowed: it leaves a block out.
#[test]
fn feature_weights_are_checked_block_by_block() {
    assert_eq!(FeatureWeights::default().check(), Ok(()));
    for block in FeatureBlock::ALL {
        let mut w = FeatureWeights::default();
        *w.weight_mut(block) = 0.0;
        assert_eq!(w.check(), Ok(()), "{} = 0", block.name());
        for bad in [-1.0, f32::NAN, f32::INFINITY] {
            *w.weight_mut(block) = bad;
            let e = w.check().expect_err(&format!("{} = {bad}", block.name()));
            assert!(e.contains(&format!("feature_weights.{}", block.name())) && e.contains(&bad.to_string()), "{e}");
        }
    }
}

/// The pieces that bring a human's Ψ to the character, each against a hand computation on Spot's
/// layout: the mean of feature rows; the centring offset (character mean − human mean on the root
/// height and the end effectors, nothing elsewhere) and its addition; the speed factor
/// (`speed_scale · human body / character body`) on the root's linear velocity only; and a clip's body
/// length (its height, or 1.7 m when it has none).
#[test]
fn the_human_feature_transforms_match_hand_computations() {
    use ace_models::features::{
        DEFAULT_HUMAN_HEIGHT, centre_human_features, centring_offset, human_body_length, human_speed_factor,
        mean_features, scale_human_speed,
    };
    use ace_models::human::HumanClip;

    let (t, m) = character("spot");
    let layout = FeatureLayout::new(&EndEffectorMapping::by_side(&t, &m));
    let dim = layout.dim();
    assert_eq!(mean_features([vec![1.0, 2.0], vec![3.0, 6.0], vec![5.0, 1.0]]), [3.0, 3.0]);
    assert!(mean_features(Vec::<Vec<f32>>::new()).is_empty());

    let human: Vec<f32> = (0..dim).map(|i| i as f32 * 0.1).collect();
    let character: Vec<f32> = (0..dim).map(|i| 1.0 + i as f32 * 0.3).collect();
    let offset = centring_offset(&layout, &human, &character);
    for i in 0..dim {
        let centred = layout.root_height().contains(&i) || layout.ee_positions().contains(&i);
        let want = if centred { character[i] - human[i] } else { 0.0 };
        assert!((offset[i] - want).abs() < 1e-6, "entry {i}: {} against {want}", offset[i]);
    }
    let mut psi = human.clone();
    centre_human_features(&mut psi, &offset);
    for i in 0..dim {
        assert!((psi[i] - (human[i] + offset[i])).abs() < 1e-6, "entry {i}");
    }
    let mut unchanged = human.clone();
    centre_human_features(&mut unchanged, &[]);
    assert_eq!(unchanged, human);

    let factor = human_speed_factor(0.5, 1.7, 0.59);
    assert!((factor - 0.5 * 1.7 / 0.59).abs() < 1e-6, "{factor}");
    let mut psi = human.clone();
    scale_human_speed(&mut psi, &layout, 3.0);
    for i in 0..dim {
        let want = if layout.root_linear_velocity().contains(&i) { 3.0 * human[i] } else { human[i] };
        assert!((psi[i] - want).abs() < 1e-6, "entry {i}: {} against {want}", psi[i]);
    }

    let path = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../assets/motions/walk.bvh");
    let mut clip = HumanClip::from_bvh_file(&path, &Default::default()).unwrap();
    assert!(clip.height_m > 1.0 && clip.height_m < 2.2, "{}", clip.height_m);
    assert_eq!(human_body_length(&clip), clip.height_m);
    for none in [0.0, -1.0, f32::NAN, f32::INFINITY] {
        clip.height_m = none;
        assert_eq!(human_body_length(&clip), DEFAULT_HUMAN_HEIGHT, "height {none}");
    }
}
