//! The body's own motion in the shared creatures' datasets (`../shared/data/creatures`; set
//! `ACE_ALLOW_MISSING_DATA=1` to skip when absent): legged creatures bend their spines into their turns
//! and with their strides, and the legless Snake crawls by a wave travelling down its body.

mod common;
use common::creatures;

use std::path::Path;

use ace_models::character::{Creature, load_creature};
use ace_models::controller::spine::Bend;
use ace_models::controller::{BaseMode, ControllerConfig, Rig};
use ace_models::dataset::{DatasetConfig, MotionSet, generate};
use ace_models::metrics::{UfrConfig, UfrRates, ufr_episodes};

const FPS: f32 = 30.0;

fn load(path: &Path) -> Creature {
    load_creature(path).unwrap_or_else(|e| panic!("{e}"))
}

/// A creature's dataset of `frames` frames, its rig and its UFR.
fn dataset(c: &Creature, frames: usize) -> (MotionSet, Rig, UfrRates) {
    let cfg = DatasetConfig { frames, seed: 21, fps: FPS, ..DatasetConfig::default() };
    let set = generate(&c.tree, &c.morphology, &cfg, &mut |_| {}).unwrap_or_else(|e| panic!("{}: {e}", c.tree.name));
    let rig = Rig::new(&c.tree, &c.morphology, &ControllerConfig::default(), FPS).unwrap();
    let poses: Vec<_> = (0..set.len()).map(|i| set.pose(i)).collect();
    let ufr = ufr_episodes(&c.tree, &c.morphology, &poses, &set.episodes, set.fps, &UfrConfig::for_character(&c.tree, &c.morphology));
    (set, rig, ufr.rates)
}

/// Pearson correlation of two series.
fn correlation(a: &[f32], b: &[f32]) -> f32 {
    let n = a.len() as f32;
    let (ma, mb) = (a.iter().sum::<f32>() / n, b.iter().sum::<f32>() / n);
    let cov: f32 = a.iter().zip(b).map(|(x, y)| (x - ma) * (y - mb)).sum();
    let va: f32 = a.iter().map(|x| (x - ma).powi(2)).sum();
    let vb: f32 = b.iter().map(|y| (y - mb).powi(2)).sum();
    cov / (va * vb).sqrt().max(1e-12)
}

/// Yaw of the root's heading (rad).
fn yaw(set: &MotionSet, i: usize) -> f32 {
    let r = set.roots[i].rotation;
    let x = r * nalgebra::Vector3::x();
    x.y.atan2(x.x)
}

/// Per frame (every frame but the first of each episode): the root's yaw rate and the frame index.
fn yaw_rates(set: &MotionSet) -> Vec<(usize, f32)> {
    let mut out = Vec::new();
    for e in &set.episodes {
        for i in e.start + 1..e.end {
            let d = (yaw(set, i) - yaw(set, i - 1) + std::f32::consts::PI).rem_euclid(std::f32::consts::TAU) - std::f32::consts::PI;
            out.push((i, d * set.fps));
        }
    }
    out
}

/// The range a DoF spans over the dataset, as a fraction of its limits.
fn spanned(c: &Creature, set: &MotionSet, d: usize) -> f32 {
    let dof = c.tree.dof();
    let (lo, hi) = (0..set.len())
        .map(|i| set.q[i * dof + d])
        .fold((f32::INFINITY, f32::NEG_INFINITY), |(a, b), v| (a.min(v), b.max(v)));
    let l = c.tree.limits(d).unwrap();
    (hi - lo) / (l.upper - l.lower)
}

/// Issue "Motion dataset": the spine moves. The spine's DoFs of the Fox, the Wolf, the Spider and the
/// T-Rex span a good part of their range over a dataset, within their limits, and the body bends into
/// its turns: the mean lateral bend of the spine follows the root's yaw rate (correlation > 0.5). Before
/// the spine was bent, the bones above the legs had no DoFs and the neck's moved at random, whatever the
/// body did.
#[test]
fn legged_creatures_bend_their_spines_into_their_turns() {
    let Some(dir) = creatures() else { return };
    for file in ["Fox/Fox.glb", "Quaternius_Wolf/Wolf.gltf", "Quaternius_Spider/Spider.glb", "Quaternius_TRex/t-rex.glb"] {
        let c = load(&dir.join(file));
        let (set, rig, rates) = dataset(&c, 6000);
        assert_eq!(rig.mode, BaseMode::Legged, "{file}");
        assert!(!rig.spine.is_empty(), "{file}: no spine joints");
        let dof = c.tree.dof();
        let names = c.tree.dof_names();
        for j in &rig.spine {
            let span = spanned(&c, &set, j.dof);
            let l = c.tree.limits(j.dof).unwrap();
            let within = (0..set.len()).all(|i| (l.lower - 1e-5..=l.upper + 1e-5).contains(&set.q[i * dof + j.dof]));
            println!("{file} {}: {:?}, gain {:.2}, spans {:.0} % of its range", names[j.dof], j.bend, j.gain, 100.0 * span);
            assert!(within, "{file} {}: leaves its limits", names[j.dof]);
            let least = match j.bend {
                Bend::Lateral => 0.2,
                Bend::Vertical => 0.04,
            };
            assert!(span >= least, "{file} {}: spans {:.1} % of its range", names[j.dof], 100.0 * span);
        }
        let lateral: Vec<_> = rig.spine.iter().filter(|j| j.bend == Bend::Lateral).collect();
        let (mut bend, mut rate) = (Vec::new(), Vec::new());
        for (i, w) in yaw_rates(&set) {
            bend.push(lateral.iter().map(|j| j.bend_of(set.q[i * dof + j.dof])).sum::<f32>() / lateral.len() as f32);
            rate.push(w);
        }
        let r = correlation(&bend, &rate);
        println!("{file}: lateral bend ~ yaw rate: r = {r:.2}; UFR {:.3} % {rates:?}", 100.0 * rates.ufr);
        assert!(r > 0.5, "{file}: the spine's lateral bend follows the yaw rate with r = {r:.2}");
    }
}

/// The spine sways with the stride: going straight ahead at a steady pace, the lateral bend of the
/// T-Rex's and the Wolf's spines swings about its slow mean once per stride (its zero crossings come
/// at twice the stepping frequency of a foot, within 25 %), by at least 2 % of the range.
#[test]
fn spines_sway_once_per_stride_going_straight() {
    use ace_models::controller::{Command, Controller};
    use rand::SeedableRng;
    let Some(dir) = creatures() else { return };
    for file in ["Quaternius_TRex/t-rex.glb", "Quaternius_Wolf/Wolf.gltf"] {
        let c = load(&dir.join(file));
        let cfg = ControllerConfig::default();
        let rig = Rig::new(&c.tree, &c.morphology, &cfg, FPS).unwrap();
        let j = rig.spine.iter().find(|j| j.bend == Bend::Lateral).unwrap();
        let mut ctl = Controller::new(&c.tree, &rig, &cfg, FPS);
        let mut rng = rand_pcg::Pcg64::seed_from_u64(5);
        ctl.reset(&mut rng);
        let seconds = 12.0;
        ctl.set_command(Command { vx: 0.4 * rig.max_speed, vy: 0.0, wz: 0.0 }, seconds);
        let (mut bend, mut touchdowns, mut was) = (Vec::new(), 0, true);
        for k in 0..(seconds * FPS) as usize {
            ctl.step(&mut rng);
            if k < 60 {
                continue; // getting under way
            }
            bend.push(j.bend_of(ctl.q()[j.dof]));
            let on = ctl.contacts().next().unwrap();
            touchdowns += usize::from(on && !was);
            was = on;
        }
        // The bend less its mean over the surrounding second.
        let w = FPS as usize / 2;
        let detrended: Vec<f32> = (w..bend.len() - w)
            .map(|i| bend[i] - bend[i - w..=i + w].iter().sum::<f32>() / (2 * w + 1) as f32)
            .collect();
        let duration = detrended.len() as f32 / FPS;
        let crossings = detrended.windows(2).filter(|p| p[0].signum() != p[1].signum()).count();
        let sway = (detrended.iter().map(|x| x * x).sum::<f32>() / detrended.len() as f32).sqrt();
        let (f_bend, f_step) = (crossings as f32 / 2.0 / duration, touchdowns as f32 / (bend.len() as f32 / FPS));
        println!("{file}: sway {:.3} (RMS, fraction of the range), {f_bend:.2} Hz against {f_step:.2} strides/s", sway);
        assert!(sway > 0.02, "{file}: the spine hardly sways going straight ({sway})");
        assert!((f_bend / f_step - 1.0).abs() < 0.25, "{file}: sways at {f_bend} Hz, steps at {f_step} Hz");
    }
}

/// Issue "Motion dataset": a legless creature gets a useful dataset. The Snake's head is the front of
/// its body (not the tongue, which reaches farther forward); its root travels; each segment of its body
/// bends through most of its range as a wave that travels from the head to the tail (the lag at which a
/// segment's bend best matches the first segment's grows down the body); its body stays on the ground
/// and its dataset is clean.
#[test]
fn the_snake_crawls_by_a_wave_travelling_down_its_body() {
    let Some(dir) = creatures() else { return };
    let c = load(&dir.join("Quaternius_Snake/Snake.glb"));
    let names = c.morphology.names(&c.tree);
    assert_eq!(names.head.as_deref(), Some("Head"));
    let axis_front = *c.morphology.body_axis[0].last().unwrap();
    assert_eq!(Some(c.tree.dof_link(axis_front)), c.morphology.head, "the head is the front of the body's axis");

    let (set, rig, rates) = dataset(&c, 6000);
    assert_eq!(rig.mode, BaseMode::Crawling);
    let crawl = rig.crawl.as_ref().unwrap();
    println!("Snake: {} segments, k = {:.2} rad, top speed {:.2} m/s; {rates:?}", crawl.segments.len(), crawl.k, crawl.max_speed);
    assert!(crawl.segments.len() >= 4);
    assert!(rates.ufr <= 0.005 && rates.penetration == 0.0, "{rates:?}");

    // The root travels, forward.
    let mut forward = 0.0;
    for e in &set.episodes {
        for i in e.start + 1..e.end {
            let d = set.roots[i].translation.vector - set.roots[i - 1].translation.vector;
            let heading = nalgebra::Vector2::new(yaw(&set, i).cos(), yaw(&set, i).sin());
            forward += d.xy().dot(&heading);
        }
    }
    let length: f32 = ace_models::features::character_body_length(&c.tree, &c.morphology);
    println!("Snake: {forward:.1} m forward in all, body length {length:.2} m");
    assert!(forward > 10.0 * length, "the Snake crawled {forward} m");

    // Every segment bends through most of its range (a bend into the turns alone spans under half).
    for j in &crawl.segments {
        let span = spanned(&c, &set, j.dof);
        assert!(span > 0.8, "{}: spans {:.0} % of its range", c.tree.dof_names()[j.dof], 100.0 * span);
    }
    // The wave travels from the head to the tail: each segment's bend best matches its front
    // neighbour's of τ > 0 frames earlier (searched within ±20 frames, less than half the shortest
    // period of the wave at the top speed), so the lag behind the head grows down the body.
    let dof = c.tree.dof();
    let bends = |s: usize| -> Vec<f32> { (0..set.len()).map(|i| crawl.segments[s].bend_of(set.q[i * dof + crawl.segments[s].dof])).collect() };
    let lagged = |a: &[f32], b: &[f32], tau: i32| {
        let (u, v): (Vec<f32>, Vec<f32>) = set
            .episodes
            .iter()
            .flat_map(|e| (e.start as i32 + tau.abs()..e.end as i32 - tau.abs()).map(move |i| (i as usize, (i - tau) as usize)))
            .map(|(i, p)| (b[i], a[p]))
            .unzip();
        correlation(&u, &v)
    };
    let mut lags = Vec::new();
    for s in 0..crawl.segments.len() - 1 {
        let (front, back) = (bends(s), bends(s + 1));
        let lag = (-20..=20).max_by(|&x, &y| lagged(&front, &back, x).total_cmp(&lagged(&front, &back, y))).unwrap();
        lags.push(lag);
    }
    println!("Snake: each segment's lag behind its front neighbour (frames): {lags:?}");
    assert!(lags.iter().all(|&l| l > 0), "the wave does not travel down the body: {lags:?}");
}
