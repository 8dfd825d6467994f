//! Kinematic controllers on the bundled characters (`assets/characters`) and the real public URDFs in
//! `../shared/data/robots` (set `ACE_ALLOW_MISSING_DATA=1` to skip those when absent).
//!
//! Tolerances, stated once:
//! - joint limits: exact (every value is clamped, so `lower ≤ q ≤ upper` with no slack);
//! - stance feet: the foot point moves less than [`STANCE_TOL`] = 1 mm between consecutive stance frames;
//! - ground: no foot point below z = −[`GROUND_TOL`] = −1 mm;
//! - base velocity: averaged over the end of every command held at least [`HOLD`] s, once the command
//!   filter has settled ([`SETTLE`] s = 4 time constants), the achieved heading-frame velocity is within
//!   5 % of the character's top speed (+1 cm/s) of the command, and the yaw rate within 0.03 rad/s.

mod common;
use common::robots;

use std::path::{Path, PathBuf};
use std::sync::OnceLock;

use ace_models::character_state::CharacterLayout;
use ace_models::controller::{
    BaseMode, Chain, ChainScratch, Command, Controller, ControllerConfig, ReachKind, Rig, ScalingConfig, collide::Proxies,
};
use ace_models::dataset::{DatasetConfig, MotionSet, generate};
use ace_models::kinematics::{JointKind, KinematicTree};
use ace_models::morphology::{Morphology, load_character};
use nalgebra::Point3;
use rand::{RngExt, SeedableRng};

const STANCE_TOL: f32 = 1e-3;
const GROUND_TOL: f32 = 1e-3;
const HOLD: f32 = 2.2;
const SETTLE: f32 = 1.6;
const FRAMES: usize = 2000;

fn manifest() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

/// A character with a small dataset generated once per test binary.
struct Case {
    label: String,
    tree: KinematicTree,
    morph: Morphology,
    rig: Rig,
    set: MotionSet,
}

fn load(path: &Path) -> (KinematicTree, Morphology) {
    assert!(path.is_file(), "character file not found: {}", path.display());
    load_character(path).unwrap_or_else(|e| panic!("{e}"))
}

fn case(label: &str, path: PathBuf) -> Case {
    let (tree, morph) = load(&path);
    let cfg = DatasetConfig {
        frames: FRAMES,
        seed: 7,
        episode_seconds: [10.0, 30.0],
        ..DatasetConfig::default()
    };
    let set = generate(&tree, &morph, &cfg, &mut |_| {}).unwrap_or_else(|e| panic!("{label}: {e}"));
    let rig = Rig::new(&tree, &morph, &cfg.controller, cfg.fps).unwrap_or_else(|e| panic!("{label}: {e}"));
    Case {
        label: label.into(),
        tree,
        morph,
        rig,
        set,
    }
}

/// The bundled characters and, when present, the real URDFs.
fn cases() -> &'static [Case] {
    static CASES: OnceLock<Vec<Case>> = OnceLock::new();
    CASES.get_or_init(|| {
        let chars = manifest().join("../assets/characters");
        let mut out: Vec<Case> = ["spot", "crab", "stretch"]
            .iter()
            .map(|n| case(n, chars.join(format!("{n}.urdf"))))
            .collect();
        if let Some(r) = robots() {
            for (label, rel) in [
                ("spot_with_arm", "spot_arm/spot_with_arm.urdf"),
                ("phantomx", "phantomx_hexapod/phantomx_description/urdf/phantomx.urdf"),
                (
                    "stretch_re1",
                    "stretch_re1/stretch_description_RE1V0_tool_stretch_gripper.urdf",
                ),
            ] {
                out.push(case(label, r.join(rel)));
            }
        }
        out
    })
}

fn bundled(name: &str) -> (KinematicTree, Morphology) {
    load(&manifest().join(format!("../assets/characters/{name}.urdf")))
}

#[test]
fn joint_limits_hold_on_every_frame() {
    for c in cases() {
        let dof = c.tree.dof();
        for (i, q) in c.set.q.chunks_exact(dof).enumerate() {
            for (d, &x) in q.iter().enumerate() {
                assert!(x.is_finite(), "{}: frame {i}, DoF {d} is {x}", c.label);
                let j = c.tree.dof_joint(d);
                if let Some(l) = j.limits {
                    assert!(
                        x >= l.lower && x <= l.upper,
                        "{}: frame {i}, `{}` = {x} outside [{}, {}]",
                        c.label,
                        j.name,
                        l.lower,
                        l.upper
                    );
                }
                if j.kind == JointKind::Continuous {
                    assert!(
                        x.abs() <= std::f32::consts::PI + 1e-5,
                        "{}: wheel angle {x} not wrapped",
                        c.label
                    );
                }
            }
        }
    }
}

/// Foot points of every frame, `[frame][foot]`.
fn foot_points(c: &Case) -> Vec<Vec<Point3<f32>>> {
    (0..c.set.len())
        .map(|i| {
            let links = c.tree.forward_kinematics(&c.set.pose(i));
            c.morph.feet.iter().map(|&f| c.morph.ee_point(f, &links)).collect()
        })
        .collect()
}

#[test]
fn stance_feet_stay_put_and_no_foot_goes_underground() {
    for c in cases() {
        let feet = foot_points(c);
        let (mut worst_slip, mut lowest, mut stance_pairs) = (0.0f32, f32::INFINITY, 0usize);
        for e in &c.set.episodes {
            for t in e.start + 1..e.end {
                let (before, now) = (c.set.contact(t - 1), c.set.contact(t));
                for (k, (p, q)) in feet[t - 1].iter().zip(&feet[t]).enumerate() {
                    if before[k] == 1 && now[k] == 1 {
                        stance_pairs += 1;
                        worst_slip = worst_slip.max((q - p).norm());
                    }
                }
            }
        }
        for f in feet.iter().flatten() {
            lowest = lowest.min(f.z);
        }
        println!(
            "{}: worst stance slip {:.4} mm over {stance_pairs} stance steps, lowest foot z {:.4} mm",
            c.label,
            worst_slip * 1e3,
            lowest * 1e3
        );
        assert!(
            worst_slip < STANCE_TOL,
            "{}: a stance foot moved {worst_slip} m in one frame",
            c.label
        );
        if c.set.n_feet > 0 {
            assert!(stance_pairs > 0, "{}: no stance at all", c.label);
            assert!(
                lowest > -GROUND_TOL,
                "{}: a foot went {lowest} m below the ground",
                c.label
            );
        }
    }
}

#[test]
fn the_base_follows_the_command() {
    for c in cases() {
        let s = &c.set;
        let layout = s.layout;
        let rig = &c.rig;
        let top = rig.speed_scale * s.config.controller.commands.forward[1].abs();
        let tol_v = 0.05 * top.min(rig.max_speed) + 0.01;
        let (hold, settle) = ((HOLD * s.fps) as usize, (SETTLE * s.fps) as usize);
        let mut checked = 0;
        for e in &s.episodes {
            let mut start = e.start;
            while start < e.end {
                let mut end = start + 1;
                while end < e.end && s.commands[end] == s.commands[start] {
                    end += 1;
                }
                if end - start >= hold {
                    let window = start + settle..end;
                    let n = window.len() as f32;
                    let mut v = [0.0f32; 3];
                    for t in window {
                        let x = s.state(t);
                        let lin = &x[layout.root_linear_velocity()];
                        v[0] += lin[0] / n;
                        v[1] += lin[1] / n;
                        v[2] += x[layout.root_angular_velocity()][2] / n;
                    }
                    let cmd = s.commands[start];
                    let dv = (v[0] - cmd[0]).hypot(v[1] - cmd[1]);
                    assert!(
                        dv < tol_v && (v[2] - cmd[2]).abs() < 0.03,
                        "{}: frames {start}..{end}: commanded {cmd:?}, achieved {v:?} (tolerance {tol_v} m/s, 0.03 rad/s)",
                        c.label
                    );
                    checked += 1;
                }
                start = end;
            }
        }
        println!(
            "{}: {checked} held commands checked (tolerance {tol_v:.3} m/s)",
            c.label
        );
        assert!(
            checked >= 5,
            "{}: only {checked} commands were held long enough to check",
            c.label
        );
    }
}

#[test]
fn the_dataset_covers_the_character() {
    for c in cases() {
        let s = &c.set;
        let rig = &c.rig;
        let dof = c.tree.dof();
        let range = |d: usize| {
            let v = s.q.iter().skip(d).step_by(dof);
            v.clone().fold(f32::NEG_INFINITY, |a, &b| a.max(b)) - v.fold(f32::INFINITY, |a, &b| a.min(b))
        };
        // Every reach group moves, and so does every leg.
        for g in &rig.reach {
            let moved = g.dofs.iter().map(|&d| range(d)).fold(0.0, f32::max);
            assert!(
                moved > 0.1,
                "{}: reach group {:?} hardly moves ({moved})",
                c.label,
                g.kind
            );
        }
        for leg in &rig.legs {
            let moved = leg.chain.active_dofs().map(range).fold(0.0, f32::max);
            assert!(moved > 0.1, "{}: a leg hardly moves ({moved})", c.label);
        }
        // Commands span forward, backward and turning.
        let vx = s.commands.iter().map(|c| c[0]);
        let wz = s.commands.iter().map(|c| c[2]);
        if rig.mode != BaseMode::Fixed {
            // Relative to the body, or to the top speed where that is lower (a hexapod on slow servos
            // walks at 0.11 m/s at most: its joints' limits).
            let (fast, back) = ((0.3 * rig.speed_scale).min(0.5 * rig.max_speed), (0.2 * rig.speed_scale).min(0.2 * rig.max_speed));
            let (most, least) = (vx.clone().fold(0.0, f32::max), vx.fold(0.0, f32::min));
            assert!(most > fast, "{}: never fast forward ({most} m/s)", c.label);
            assert!(least < -back, "{}: never backward ({least} m/s)", c.label);
            // At 0.3 rad/s, or half the yaw rate the feet allow (a crab's sprawled feet on slow joints
            // turn it at 0.35 rad/s at most).
            let turn = 0.3f32.min(0.5 * rig.max_speed / rig.foot_radius);
            assert!(
                wz.clone().fold(0.0, f32::max) > turn && wz.fold(0.0, f32::min) < -turn,
                "{}: never turns both ways",
                c.label
            );
        }
        // Body height and tilt vary on legs.
        if rig.mode == BaseMode::Legged {
            let h: Vec<f32> = s.roots.iter().map(|r| r.translation.vector.z).collect();
            let spread =
                h.iter().fold(f32::NEG_INFINITY, |a, &b| a.max(b)) - h.iter().fold(f32::INFINITY, |a, &b| a.min(b));
            assert!(
                spread > 0.02 * rig.nominal_height,
                "{}: body height hardly varies ({spread})",
                c.label
            );
            let pitch = s
                .roots
                .iter()
                .map(|r| r.rotation.euler_angles().1.abs())
                .fold(0.0, f32::max);
            assert!(
                pitch > 0.3 * rig.max_tilt[0],
                "{}: body never pitches ({pitch})",
                c.label
            );
        }
    }
}

#[test]
fn wheels_roll_with_the_base() {
    for name in ["stretch"] {
        let (tree, morph) = bundled(name);
        let cfg = ControllerConfig::default();
        let rig = Rig::new(&tree, &morph, &cfg, 30.0).unwrap();
        assert_eq!(rig.mode, BaseMode::Wheeled);
        assert_eq!(rig.wheels.len(), 2);
        let mut ctl = Controller::new(&tree, &rig, &cfg, 30.0);
        let mut rng = rand_pcg::Pcg64::seed_from_u64(1);
        ctl.reset(&mut rng);
        ctl.set_command(
            Command {
                vx: 0.4,
                vy: 0.0,
                wz: 0.0,
            },
            100.0,
        );
        for _ in 0..90 {
            ctl.step(&mut rng);
        }
        // Settled: each frame the wheels turn by v·dt / r, the same way.
        let before: Vec<f32> = rig.wheels.iter().map(|w| ctl.q()[w.dof]).collect();
        ctl.step(&mut rng);
        for (w, b) in rig.wheels.iter().zip(before) {
            let turned = ace_models::controller::wheels::wrap(ctl.q()[w.dof] - b);
            let expected = ctl.followed().vx / 30.0 / w.radius * w.axis.y.signum();
            assert!(
                (turned - expected).abs() < 1e-3,
                "wheel turned {turned}, expected {expected}"
            );
        }
        // Holonomic: a sideways command moves the base sideways.
        ctl.set_command(
            Command {
                vx: 0.0,
                vy: 0.3,
                wz: 0.0,
            },
            100.0,
        );
        for _ in 0..90 {
            ctl.step(&mut rng);
        }
        let y0 = ctl.root().translation.vector.y;
        ctl.step(&mut rng);
        let dy = ctl.root().translation.vector.y - y0;
        assert!((dy * 30.0 - ctl.followed().vy).abs() < 1e-3 && dy > 0.0);
    }
}

/// Stance fraction per foot and the largest number of feet in the air at once, over `seconds` of a
/// fixed command after two seconds of settling.
fn gait_stats(tree: &KinematicTree, rig: &Rig, cmd: Command, seconds: f32) -> (f32, usize, Vec<Vec<bool>>, String) {
    let cfg = ControllerConfig::default();
    let mut ctl = Controller::new(tree, rig, &cfg, 30.0);
    let mut rng = rand_pcg::Pcg64::seed_from_u64(3);
    ctl.reset(&mut rng);
    ctl.set_command(cmd, 1000.0);
    for _ in 0..60 {
        ctl.step(&mut rng);
    }
    let mut frames = Vec::new();
    for _ in 0..(seconds * 30.0) as usize {
        ctl.step(&mut rng);
        frames.push(ctl.contacts().collect::<Vec<bool>>());
    }
    let n = frames.len() * rig.legs.len();
    let duty = frames.iter().flatten().filter(|&&c| c).count() as f32 / n as f32;
    let air = frames
        .iter()
        .map(|f| f.iter().filter(|&&c| !c).count())
        .max()
        .unwrap_or(0);
    (
        duty,
        air,
        frames,
        ctl.gait().map(|g| g.name.to_string()).unwrap_or_default(),
    )
}

#[test]
fn the_quadruped_gait_changes_with_speed() {
    let (tree, morph) = bundled("spot");
    let rig = Rig::new(&tree, &morph, &ControllerConfig::default(), 30.0).unwrap();
    let cmd = |vx| Command { vx, vy: 0.0, wz: 0.0 };
    // Gaits change at the Froude numbers animals change them at (hip height 0.51 m): Spot walks up to
    // about 1.15 m/s (Fr 0.27; the trot takes over below Fr 0.4, where the walk's stride would overrun
    // the step region) and trots through its real 1.6 m/s up to its top speed (3.4 m/s, Fr 2.3): the
    // gallop and bound begin at Fr 2.5 (+10 % hysteresis), beyond it.
    let (walk_duty, walk_air, _, walk) = gait_stats(&tree, &rig, cmd(0.25), 4.0);
    let (trot_duty, _, trot_frames, trot) = gait_stats(&tree, &rig, cmd(1.4), 4.0);
    let (fast_duty, _, _, fast) = gait_stats(&tree, &rig, cmd(rig.max_speed), 4.0);
    println!(
        "spot: {walk} duty {walk_duty:.2} (≤{walk_air} feet up), {trot} duty {trot_duty:.2}, {fast} duty {fast_duty:.2}"
    );
    assert_eq!(walk, "walk");
    assert_eq!(trot, "trot", "Spot should trot at 1.4 m/s, within its real speeds");
    assert_eq!(fast, "trot", "Fr 2.3 is a trot");
    assert!(
        walk_duty > 0.65 && walk_air <= 2,
        "walk: duty {walk_duty}, {walk_air} feet up at once"
    );
    // Duty factors fall with speed: the walk's 0.75 → 0.6, the trot's 0.45 → 0.35.
    assert!(fast_duty < 0.47, "fast trot duty {fast_duty}");
    assert!(walk_duty > trot_duty + 0.1 && trot_duty >= fast_duty);
    // Trot: diagonal feet (fl, rr) and (fr, rl) move together, lateral pairs do not.
    let agree =
        |a: usize, b: usize| trot_frames.iter().filter(|f| f[a] == f[b]).count() as f32 / trot_frames.len() as f32;
    assert!(
        agree(0, 3) > 0.9 && agree(1, 2) > 0.9,
        "diagonals {} {}",
        agree(0, 3),
        agree(1, 2)
    );
    assert!(agree(0, 1) < 0.7, "front pair in phase in a trot ({})", agree(0, 1));
}

#[test]
fn the_hexapod_gait_changes_with_speed() {
    let (tree, morph) = bundled("crab");
    let rig = Rig::new(&tree, &morph, &ControllerConfig::default(), 30.0).unwrap();
    // Its legs' joints (6 rad/s) keep the wave gait below 0.04 m/s: three quarters of the way to the
    // ripple.
    let ripple = rig.gaits.iter().find(|g| g.name == "ripple").unwrap();
    let slow = Command {
        vx: 0.75 * ace_models::dynamic_similarity::speed_at_froude(ripple.from_froude, rig.hip_height),
        vy: 0.0,
        wz: 0.0,
    };
    let fast = Command {
        vx: rig.max_speed,
        vy: 0.0,
        wz: 0.0,
    };
    let (slow_duty, slow_air, _, slow_name) = gait_stats(&tree, &rig, slow, 4.0);
    let (fast_duty, fast_air, frames, fast_name) = gait_stats(&tree, &rig, fast, 4.0);
    println!(
        "crab: {slow_name} duty {slow_duty:.2} (≤{slow_air} up), {fast_name} duty {fast_duty:.2} (≤{fast_air} up)"
    );
    assert_eq!(slow_name, "wave");
    assert_eq!(fast_name, "tripod");
    assert!(slow_air <= 2 && slow_duty > 0.75);
    // The crab's top speed (0.13 m/s, what its leg joints allow) is a walking Froude number: the tripod
    // keeps a walking duty (0.55), stretched by the shortest walking swing (5 frames at 30 fps).
    assert!(fast_air >= 3 && fast_duty < 0.66, "tripod duty {fast_duty}");
    // Tripod: l1, r2, l3 together (legs 0, 4, 2).
    let together = frames.iter().filter(|f| f[0] == f[4] && f[0] == f[2]).count() as f32 / frames.len() as f32;
    // (0.82 at the walking duty of the crab's top speed; 0.85 before the tripod was slowed to it.)
    assert!(together > 0.8, "tripod legs together in {together} of the frames");
}

#[test]
fn damped_least_squares_reaches_random_reachable_targets() {
    let mut rng = rand_pcg::Pcg64::seed_from_u64(11);
    for name in ["spot", "crab", "stretch"] {
        let (tree, morph) = bundled(name);
        let mut scratch = ChainScratch::default();
        for &ee in morph.feet.iter().chain(&morph.manipulators) {
            let chain = Chain::new(&tree, &morph, ee);
            let (mut ok, n) = (0, 30);
            for _ in 0..n {
                let mut q = tree.neutral_q();
                for d in chain.active_dofs() {
                    let l = tree.limits(d).unwrap();
                    q[d] = l.lower + (l.upper - l.lower) * rng.random::<f32>();
                }
                let target = chain.tip_point(&tree, &q, &mut scratch);
                let mut from = tree.neutral_q();
                let r = chain.solve_unstuck(&tree, &mut from, &target, 1e-5, 300, 3, &mut scratch);
                for d in chain.active_dofs() {
                    let l = tree.limits(d).unwrap();
                    assert!(from[d] >= l.lower && from[d] <= l.upper);
                }
                ok += usize::from(r.error < 1e-4);
            }
            println!("{name} {}: {ok}/{n} targets reached", tree.links[ee].name);
            // Joint limits make some targets unreachable from the neutral branch; most must work.
            assert!(
                ok * 10 >= n * 7,
                "{name} {}: only {ok}/{n} targets reached",
                tree.links[ee].name
            );
        }
    }
}

#[test]
fn motion_stays_clear_of_self_collision() {
    // The controllers' own coarse boxes (stricter than the UFR detector's capsules): at most 0.5 % of
    // the frames may have an overlapping checked pair.
    for c in cases() {
        let proxies: &Proxies = &c.rig.proxies;
        let hits = (0..c.set.len())
            .filter(|&i| {
                !proxies
                    .colliding_pairs(&c.tree.forward_kinematics(&c.set.pose(i)), proxies.collision_margin())
                    .is_empty()
            })
            .count();
        println!("{}: {hits} of {} frames with overlapping boxes", c.label, c.set.len());
        assert!(hits * 200 <= c.set.len(), "{}: {hits} frames collide", c.label);
    }
}

#[test]
fn state_vectors_use_the_layout() {
    for c in cases() {
        let layout = CharacterLayout::new(&c.tree, &c.morph);
        assert_eq!(c.set.layout, layout);
        assert_eq!(c.set.states.len(), c.set.len() * layout.dim());
        assert_eq!(c.set.contacts.len(), c.set.len() * c.morph.feet.len());
        assert!(
            c.set.states.iter().all(|x| x.is_finite()),
            "{}: non-finite state",
            c.label
        );
    }
}

/// An eight-legged spider written here (no file): a box body, four legs a side, each a yaw joint at the
/// body and two pitch joints, ending in a foot sphere.
fn spider() -> KinematicTree {
    let mut x = String::from(
        r#"<robot name="spider"><link name="body"><collision><geometry><box size="0.5 0.2 0.08"/></geometry></collision></link>"#,
    );
    let joint = |name: &str, parent: &str, child: &str, xyz: &str, rpy: &str, axis: &str| {
        format!(
            r#"<joint name="{name}" type="revolute"><parent link="{parent}"/><child link="{child}"/><origin xyz="{xyz}" rpy="{rpy}"/><axis xyz="{axis}"/><limit lower="-1.2" upper="1.2" velocity="5" effort="1"/></joint>"#
        )
    };
    for (side, sy) in [("l", 1.0f32), ("r", -1.0)] {
        for (i, px) in [0.2f32, 0.07, -0.07, -0.2].iter().enumerate() {
            let n = format!("{side}{i}");
            let yaw = sy * std::f32::consts::FRAC_PI_2;
            x += &joint(
                &format!("{n}_yaw"),
                "body",
                &format!("{n}_coxa"),
                &format!("{px} {} 0", 0.1 * sy),
                &format!("0 0 {yaw}"),
                "0 0 1",
            );
            x += &format!(
                r#"<link name="{n}_coxa"><collision><origin xyz="0.02 0 0"/><geometry><box size="0.04 0.03 0.03"/></geometry></collision></link>"#
            );
            x += &joint(
                &format!("{n}_hip"),
                &format!("{n}_coxa"),
                &format!("{n}_femur"),
                "0.04 0 0",
                "0 0 0",
                "0 -1 0",
            );
            x += &format!(
                r#"<link name="{n}_femur"><collision><origin xyz="0.06 0 0.03" rpy="0 -0.46 0"/><geometry><box size="0.13 0.02 0.02"/></geometry></collision></link>"#
            );
            x += &joint(
                &format!("{n}_knee"),
                &format!("{n}_femur"),
                &format!("{n}_tibia"),
                "0.12 0 0.06",
                "0 0 0",
                "0 -1 0",
            );
            x += &format!(
                r#"<link name="{n}_tibia"><collision><origin xyz="0.03 0 -0.08" rpy="0 0.36 0"/><geometry><box size="0.02 0.02 0.17"/></geometry></collision><collision><origin xyz="0.06 0 -0.16"/><geometry><sphere radius="0.01"/></geometry></collision></link>"#
            );
        }
    }
    x += "</robot>";
    KinematicTree::from_urdf_str(&x).unwrap()
}

#[test]
fn eight_legs_walk_without_any_per_robot_code() {
    let tree = spider();
    let morph = Morphology::analyze(&tree);
    assert_eq!(morph.feet.len(), 8, "{:?}", morph.names(&tree));
    let cfg = DatasetConfig {
        frames: 900,
        seed: 2,
        episode_seconds: [10.0, 20.0],
        ..DatasetConfig::default()
    };
    let set = generate(&tree, &morph, &cfg, &mut |_| {}).unwrap_or_else(|e| panic!("{e}"));
    let rig = Rig::new(&tree, &morph, &cfg.controller, cfg.fps).unwrap();
    let names: Vec<_> = rig.gaits.iter().map(|g| g.name).collect();
    assert_eq!(names, ["wave", "ripple", "alternating"]);
    let c = Case {
        label: "spider".into(),
        tree,
        morph,
        rig,
        set,
    };
    let feet = foot_points(&c);
    for e in &c.set.episodes {
        for t in e.start + 1..e.end {
            let (before, now) = (c.set.contact(t - 1), c.set.contact(t));
            for (k, (p, q)) in feet[t - 1].iter().zip(&feet[t]).enumerate() {
                if before[k] == 1 && now[k] == 1 {
                    assert!((q - p).norm() < STANCE_TOL, "frame {t}, foot {k} slid");
                }
                assert!(q.z > -GROUND_TOL);
            }
        }
    }
    let moved = (0..c.set.len()).filter(|&i| c.set.contact(i).contains(&0)).count();
    assert!(
        moved > c.set.len() / 3,
        "the spider hardly steps ({moved} frames with a foot up)"
    );
    let travelled = c
        .set
        .roots
        .iter()
        .map(|r| r.translation.vector.xy().norm())
        .fold(0.0, f32::max);
    assert!(travelled > 0.3, "the spider hardly leaves the origin ({travelled} m)");
}

#[test]
fn a_fixed_base_only_reaches() {
    // An arm on a box lying on the ground: no legs, no wheels.
    let xml = r#"<robot name="arm">
      <link name="base"><collision><geometry><box size="0.4 0.4 0.2"/></geometry></collision></link>
      <joint name="a" type="revolute"><parent link="base"/><child link="l1"/><origin xyz="0 0 0.1"/><axis xyz="0 0 1"/><limit lower="-2" upper="2" velocity="2" effort="1"/></joint>
      <link name="l1"><collision><origin xyz="0 0 0.05"/><geometry><cylinder radius="0.03" length="0.1"/></geometry></collision></link>
      <joint name="b" type="revolute"><parent link="l1"/><child link="l2"/><origin xyz="0 0 0.1"/><axis xyz="0 1 0"/><limit lower="-1" upper="1" velocity="2" effort="1"/></joint>
      <link name="l2"><collision><origin xyz="0 0 0.15"/><geometry><cylinder radius="0.025" length="0.3"/></geometry></collision></link>
      <joint name="c" type="revolute"><parent link="l2"/><child link="l3"/><origin xyz="0 0 0.3"/><axis xyz="0 1 0"/><limit lower="-1.5" upper="1.5" velocity="2" effort="1"/></joint>
      <link name="l3"><collision><origin xyz="0 0 0.1"/><geometry><cylinder radius="0.02" length="0.2"/></geometry></collision></link>
    </robot>"#;
    let tree = KinematicTree::from_urdf_str(xml).unwrap();
    let morph = Morphology::analyze(&tree);
    assert!(morph.feet.is_empty() && morph.wheels.is_empty() && morph.manipulators.len() == 1);
    let set = generate(
        &tree,
        &morph,
        &DatasetConfig {
            frames: 300,
            ..DatasetConfig::default()
        },
        &mut |_| {},
    )
    .unwrap();
    assert!(set.commands.iter().all(|c| *c == [0.0; 3]));
    assert!(set.roots.iter().all(|r| *r == set.roots[0]));
    let spread = |d: usize| {
        let v: Vec<f32> = set.q.iter().skip(d).step_by(3).copied().collect();
        v.iter().fold(f32::NEG_INFINITY, |a, &b| a.max(b)) - v.iter().fold(f32::INFINITY, |a, &b| a.min(b))
    };
    assert!((0..3).any(|d| spread(d) > 0.3), "the arm hardly moves");
}

/// Where the gripper tip of Spot's arm is, in the root frame, on every frame of a dataset generated
/// with `cfg`, and the arm's stowed tip and length (first moving joint to tip).
fn spot_gripper_from_stowed(cfg: &DatasetConfig) -> (Vec<f32>, f32) {
    let (tree, morph) = bundled("spot");
    let set = generate(&tree, &morph, cfg, &mut |_| {}).unwrap();
    let rig = Rig::new(&tree, &morph, &cfg.controller, cfg.fps).unwrap();
    let arm = rig.reach.iter().find(|g| matches!(g.kind, ReachKind::Arm(_))).expect("Spot has an arm");
    let ReachKind::Arm(tip) = arm.kind else { unreachable!() };
    let at = |q: &[f32]| {
        tree.forward_kinematics(&ace_models::kinematics::CharacterPose {
            root: nalgebra::Isometry3::identity(),
            q: q.to_vec(),
        })
    };
    let stowed = at(&rig.nominal_q);
    let home = stowed[tip].translation.vector;
    let length = (home - stowed[tree.dof_link(arm.dofs[0])].translation.vector).norm();
    let dof = tree.dof();
    let distances = (0..set.len())
        .map(|i| (at(&set.q[i * dof..(i + 1) * dof])[tip].translation.vector - home).norm() / length)
        .collect();
    (distances, length)
}

fn percentile(mut v: Vec<f32>, p: f32) -> f32 {
    v.sort_by(f32::total_cmp);
    v[((v.len() - 1) as f32 * p).round() as usize]
}

#[test]
fn an_arm_with_a_home_reach_stays_near_where_it_rests_and_still_moves() {
    // The setting Spot's shipped dataset is generated with.
    let text = std::fs::read_to_string(manifest().join("../assets/training/spot.dataset.toml")).unwrap();
    let shipped: DatasetConfig = toml::from_str(&text).unwrap();
    let reach = shipped.controller.reach.home_reach.expect("Spot's dataset limits its arm's reach");
    let base = DatasetConfig {
        frames: 3000,
        seed: 7,
        ..DatasetConfig::default()
    };
    let mut near = base.clone();
    near.controller.reach = shipped.controller.reach.clone();
    let (free, _) = spot_gripper_from_stowed(&base);
    let (held, length) = spot_gripper_from_stowed(&near);
    let (free95, held95, held_max) = (percentile(free, 0.95), percentile(held.clone(), 0.95), percentile(held.clone(), 1.0));
    println!("Spot's gripper from where it rests, in arm lengths ({length:.2} m): 95th percentile {free95:.2} anywhere, {held95:.2} with home_reach {reach}; at most {held_max:.2}");
    // Anywhere, the tip crosses the workspace (1.44 arm lengths at the 95th percentile); held, each DoF
    // alone moves it at most `reach`, and several together a little more (1.8 times at the 95th
    // percentile).
    assert!(free95 > 0.8, "the arm's free targets stay near home: {free95}");
    assert!(held95 < 2.0 * reach, "the arm strays {held95} arm lengths with home_reach {reach}");
    assert!(held_max < 3.0 * reach, "the arm strays {held_max} arm lengths with home_reach {reach}");
    // It still moves: a hand's small gestures, not a frozen arm.
    assert!(percentile(held, 0.75) > 0.2 * reach, "the held arm hardly moves");
}

#[test]
fn a_robot_held_to_a_slow_top_speed_walks_at_it_where_a_person_walks() {
    let rig = |name: &str, cfg: &ControllerConfig| {
        let (tree, morph) = bundled(name);
        Rig::new(&tree, &morph, cfg, 30.0).unwrap()
    };
    let cfg = ControllerConfig::default();
    let pace = cfg.scaling.walking_pace.unwrap();
    let body = ControllerConfig {
        scaling: ScalingConfig { walking_pace: None, ..cfg.scaling.clone() },
        ..cfg.clone()
    };
    // The crab's leg joints and Stretch's wheels hold them below what their bodies' scales would ask of
    // a walking person's 1.5 m/s: the scale maps that walk to their top speed.
    for name in ["crab", "stretch"] {
        let (capped, free) = (rig(name, &cfg), rig(name, &body));
        assert!(free.speed_scale * pace > free.max_speed, "{name}: {} {}", free.speed_scale, free.max_speed);
        assert!((capped.speed_scale * pace - capped.max_speed).abs() < 1e-5 * capped.max_speed, "{name}");
        assert_eq!(capped.max_speed, free.max_speed, "{name}: the top speed does not depend on the scale");
    }
    // Spot is fast enough: its body's scale (leg length / 0.9 m).
    let (capped, free) = (rig("spot", &cfg), rig("spot", &body));
    assert_eq!(capped.speed_scale, free.speed_scale);
    assert!((free.speed_scale - free.leg_length / cfg.scaling.human_leg_length).abs() < 1e-6);
    // An explicit scale is used as given.
    let fixed = ControllerConfig {
        scaling: ScalingConfig { speed_scale: Some(0.5), ..cfg.scaling.clone() },
        ..cfg.clone()
    };
    assert_eq!(rig("crab", &fixed).speed_scale, 0.5);
}

/// A leg whose foot can hardly leave its foothold is refused saying what stops it: the message listed
/// every possible cause (joint limits, a collision, the ground) and left the user to guess. Spot
/// standing with its knees at their limit (a profile's rest pose) cannot step: the foot cannot reach
/// the footholds around it without bending the knee further.
#[test]
fn a_leg_that_cannot_step_names_what_stops_it() {
    use ace_models::morphology::Profile;
    let path = manifest().join("../assets/characters/spot.urdf");
    let legs = ["fl", "fr", "rl", "rr"];
    let toml: String = std::iter::once("[rest_pose]\n".to_string())
        .chain(legs.iter().map(|l| format!("{l}_hip_y = 1.0\n{l}_knee = -1.39\n")))
        .collect();
    let profile = Profile::from_toml(&toml, "spot.profile.toml").unwrap();
    let mut tree = KinematicTree::from_urdf_file(&path).unwrap();
    profile.apply_rest_pose(&mut tree).unwrap();
    let morph = Morphology::with_profile(&tree, &profile).unwrap();
    let Err(e) = generate(&tree, &morph, &DatasetConfig { frames: 10, ..DatasetConfig::default() }, &mut |_| {}) else {
        panic!("Spot with its knees at their limit made a dataset");
    };
    let msg = e.to_string();
    assert!(msg.contains("leg ending in `fl_foot`: the foot can hardly move from its nominal foothold"), "{msg}");
    assert!(msg.contains("most often the foot cannot reach it within the leg's joint limits (24 of 48 footholds just beyond it)"), "{msg}");
}
