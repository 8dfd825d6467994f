//! Per-frame inference cost of the shipped checkpoints (`assets/checkpoints/<character>`), the pure-Rust
//! runtime ([`ace_models::runtime::Retargeter`]) beside libtorch's ([`ace_models::learn::retarget`]),
//! printed as one table. Targets (issue 18): G + π for one character at most 0.1 ms median per frame;
//! 64 characters batched at most 1 ms; 256 at most 4 ms.
//!
//! ```text
//! cargo bench -p ace_models --bench inference
//! ```
//! Rows:
//! - `G + π ×N`: one batched pass of the networks for N characters (x^h normalisation, G, π with its
//!   mask and bounds, denormalisation), the same states fed to both paths; that is what the targets
//!   are about;
//! - `step ×N`: `Retargeter::step` for N characters driven by N human frames in one batch: the
//!   networks plus each character's pose with its cleanup — what the Bevy plugin's worker pays per
//!   frame;
//! - `whole frame ×1`: `Retargeter::retarget_states` per frame on a held clip: the networks plus the
//!   pose (root integration, joint limits, wheels) and the cleanup — what `ace retarget` pays.
//!
//! Both run on one thread (libtorch's setting in the plugin; a game has other work for the other cores).
//! Each figure is the median (and 90th percentile) over many frames after a warm-up.
//!
//! A second table gives this core's floor for `G + π ×N`, measured in the same run: every parameter
//! is read once per pass (one character streams four bytes per parameter from the cache, as the
//! bench's repeated frames keep them in L3) and costs one multiply-add per character (at this core's
//! measured f32 fused multiply-add peak). No exact implementation of these networks goes below it.

use std::path::Path;
use std::time::Instant;

use ace_models::human::{HumanClip, ImportOptions};
use ace_models::human_set::{HumanRow, PROJECT_FPS};
use ace_models::kinematics::KinematicTree;
use ace_models::learn::retarget::Retargeter as TchRetargeter;
use ace_models::learn::set_threads;
use ace_models::morphology::{Morphology, load_character};
use ace_models::runtime::Retargeter;
use tch::Device;

const WARM_UP: usize = 30;

fn percentiles(mut v: Vec<f64>) -> (f64, f64) {
    v.sort_by(f64::total_cmp);
    (v[v.len() / 2], v[v.len() * 9 / 10])
}

/// Milliseconds per call of `f(frame)` over `frames` frames after the warm-up: (median, p90).
fn time(frames: usize, f: &mut dyn FnMut(usize)) -> (f64, f64) {
    let mut times = Vec::with_capacity(frames);
    for t in 0..WARM_UP + frames {
        let t0 = Instant::now();
        f(t);
        if t >= WARM_UP {
            times.push(t0.elapsed().as_secs_f64() * 1e3);
        }
    }
    percentiles(times)
}

/// The two paths' `step` for `batch` characters over `looped`: ((median, p90) runtime, tch).
fn steps(
    tree: &KinematicTree,
    morph: &Morphology,
    ours: &Retargeter,
    theirs: &TchRetargeter,
    looped: &[HumanRow],
    batch: usize,
    frames: usize,
) -> ((f64, f64), (f64, f64)) {
    let mut a: Vec<_> = (0..batch).map(|_| ours.stream(tree, morph).expect("stream")).collect();
    let mut b: Vec<_> = (0..batch).map(|_| theirs.stream(tree, morph).expect("stream")).collect();
    let rt = time(frames, &mut |t| {
        let x = vec![looped[t % looped.len()]; batch];
        let out = ours.step(tree, morph, &mut a.iter_mut().collect::<Vec<_>>(), &x).expect("step");
        assert_eq!(out.len(), batch);
    });
    let tc = time(frames, &mut |t| {
        let x = vec![looped[t % looped.len()]; batch];
        let out = theirs.step(tree, morph, &mut b.iter_mut().collect::<Vec<_>>(), &x).expect("step");
        assert_eq!(out.len(), batch);
    });
    (rt, tc)
}

fn main() {
    set_threads(1);
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("..");
    let clip = HumanClip::from_bvh_file(
        &root.join("assets/motions/walk.bvh"),
        &ImportOptions {
            fps: Some(PROJECT_FPS),
            mapping: None,
        },
    )
    .expect("bundled clip");
    let rows: Vec<HumanRow> = clip.states().into_iter().map(|s| s.0).collect();
    let looped: Vec<HumanRow> = rows.iter().cycle().take(600).copied().collect();

    println!("| character | measured | frames | pure Rust median (ms) | p90 | libtorch median (ms) | p90 | speed-up |");
    println!("|---|---|---:|---:|---:|---:|---:|---:|");
    let row = |name: &str, what: &str, frames: usize, rt: (f64, f64), tc: (f64, f64)| {
        println!(
            "| {name} | {what} | {frames} | {:.3} | {:.3} | {:.3} | {:.3} | ×{:.1} |",
            rt.0,
            rt.1,
            tc.0,
            tc.1,
            tc.0 / rt.0
        );
    };
    let mut floors = Vec::new();
    for (name, file) in [
        ("spot", "characters/spot.urdf"),
        ("crab", "characters/crab.urdf"),
        ("stretch", "characters/stretch.urdf"),
        ("hound", "creatures/hound.glb"),
    ] {
        let dir = root.join("assets/checkpoints").join(name);
        let (tree, morph) = load_character(&root.join("assets").join(file)).expect("bundled character");
        let (ours, theirs) = match (Retargeter::load(&dir), TchRetargeter::load(&dir, Device::Cpu)) {
            (Ok(a), Ok(b)) => (a, b),
            (Err(e), _) | (_, Err(e)) => {
                println!("| {name} | no checkpoint: {e} | | | | | | |");
                continue;
            }
        };
        for batch in [1usize, 64, 256] {
            let frames = if batch == 256 { 100 } else { 300 };
            let (rt, tc) = networks(&tree, &morph, &ours, &theirs, &looped, batch, frames);
            row(name, &format!("G + π ×{batch}"), frames, rt, tc);
        }
        for batch in [1usize, 16, 64] {
            let (rt, tc) = steps(&tree, &morph, &ours, &theirs, &looped, batch, 300);
            row(name, &format!("step ×{batch}"), 300, rt, tc);
        }
        // The whole-clip path, timed per frame over the clip (one call, so per-frame = total / frames).
        let per_frame = |f: &mut dyn FnMut() -> usize| {
            let mut v = Vec::new();
            for _ in 0..5 {
                let t0 = Instant::now();
                let n = f();
                v.push(t0.elapsed().as_secs_f64() * 1e3 / n as f64);
            }
            percentiles(v)
        };
        let rt = per_frame(&mut || ours.retarget_states(&tree, &morph, &looped).expect("retarget").poses.len());
        let tc = per_frame(&mut || theirs.retarget_states(&tree, &morph, &looped).expect("retarget").poses.len());
        row(name, &format!("whole frame ×1 (5 runs of {} frames)", looped.len()), looped.len(), rt, tc);
        floors.push((name, ours.parameter_count()));
    }

    let peak = fma_peak_gflops();
    println!();
    match peak {
        Some((gflops, isa)) => println!("This core's f32 multiply-add peak: {gflops:.0} GFLOP/s ({isa}, one thread)."),
        None => println!("This core's f32 multiply-add peak: not measured (no AVX2 or AVX-512)."),
    }
    println!();
    println!("| character | parameters | streamed once (ms) | floor ×1 (ms) | floor ×64 | floor ×256 |");
    println!("|---|---:|---:|---:|---:|---:|");
    for (name, parameters) in floors {
        let stream = stream_ms(parameters);
        let floor = |n: usize| match peak {
            Some((gflops, _)) => format!("{:.3}", stream.max(2.0 * (n * parameters) as f64 / (gflops * 1e6))),
            None => "–".into(),
        };
        println!("| {name} | {parameters} | {stream:.3} | {} | {} | {} |", floor(1), floor(64), floor(256));
    }
}

/// Median milliseconds to read `parameters` f32s once from a buffer that stays cached between passes,
/// as the networks' weights do between the bench's frames.
fn stream_ms(parameters: usize) -> f64 {
    let data: Vec<f32> = (0..parameters).map(|i| (i % 7) as f32).collect();
    let mut sink = 0.0f32;
    let (median, _) = time(300, &mut |_| {
        // Sixteen independent sums, so that reading, not adding, sets the pace.
        let mut acc = [0.0f32; 16];
        for chunk in data.chunks_exact(16) {
            acc.iter_mut().zip(chunk).for_each(|(a, v)| *a += v);
        }
        sink += acc.iter().sum::<f32>();
    });
    std::hint::black_box(sink);
    median
}

/// This core's f32 fused multiply-add throughput in GFLOP/s with the widest vector unit it has, and
/// that unit's name; `None` without AVX2 and FMA.
fn fma_peak_gflops() -> Option<(f64, &'static str)> {
    #[cfg(target_arch = "x86_64")]
    {
        const ITERS: usize = 20_000_000;
        let (flops_per_iter, isa, run): (f64, &str, fn(usize) -> f32) = if is_x86_feature_detected!("avx512f") {
            // SAFETY (both arms): the CPU has the features each function is compiled for.
            (12.0 * 16.0 * 2.0, "AVX-512", |n| unsafe { fma_avx512(n) })
        } else if is_x86_feature_detected!("avx2") && is_x86_feature_detected!("fma") {
            (12.0 * 8.0 * 2.0, "AVX2", |n| unsafe { fma_avx2(n) })
        } else {
            return None;
        };
        run(ITERS / 10);
        let t0 = Instant::now();
        std::hint::black_box(run(ITERS));
        Some((flops_per_iter * ITERS as f64 / t0.elapsed().as_secs_f64() / 1e9, isa))
    }
    #[cfg(not(target_arch = "x86_64"))]
    None
}

/// `n` rounds of twelve independent vector multiply-adds (enough in flight to fill both FMA ports).
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx512f")]
fn fma_avx512(n: usize) -> f32 {
    use std::arch::x86_64::*;
    let (b, c) = (_mm512_set1_ps(0.999_999), _mm512_set1_ps(1e-7));
    let mut a = [_mm512_set1_ps(1.0); 12];
    for _ in 0..n {
        for v in a.iter_mut() {
            *v = _mm512_fmadd_ps(*v, b, c);
        }
    }
    a.iter().map(|v| _mm512_reduce_add_ps(*v)).sum()
}

/// [`fma_avx512`] with AVX2's eight lanes.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma")]
fn fma_avx2(n: usize) -> f32 {
    use std::arch::x86_64::*;
    let (b, c) = (_mm256_set1_ps(0.999_999), _mm256_set1_ps(1e-7));
    let mut a = [_mm256_set1_ps(1.0); 12];
    for _ in 0..n {
        for v in a.iter_mut() {
            *v = _mm256_fmadd_ps(*v, b, c);
        }
    }
    let mut out = [0.0f32; 8];
    // SAFETY: `out` holds eight f32s.
    a.iter().map(|v| unsafe { _mm256_storeu_ps(out.as_mut_ptr(), *v); out.iter().sum::<f32>() }).sum()
}

/// The networks alone for `batch` characters (see the module docs), fed the states of a rollout.
fn networks(
    tree: &KinematicTree,
    morph: &Morphology,
    ours: &Retargeter,
    theirs: &TchRetargeter,
    looped: &[HumanRow],
    batch: usize,
    frames: usize,
) -> ((f64, f64), (f64, f64)) {
    let start = ours.start_state(tree, morph).expect("start state");
    let prev: Vec<Vec<f32>> = vec![start; batch];
    let rt = time(frames, &mut |t| {
        let x = vec![looped[t % looped.len()]; batch];
        let out = ours.networks(&x, &prev.concat());
        assert_eq!(out.len(), batch * ours.state_dim());
    });
    let tc = time(frames, &mut |t| {
        let x = vec![looped[t % looped.len()]; batch];
        let out = theirs.networks(&x, &prev).expect("networks");
        assert_eq!(out.len(), batch);
    });
    (rt, tc)
}
