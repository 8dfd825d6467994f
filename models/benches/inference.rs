//! Per-frame inference cost of the shipped checkpoints (`assets/checkpoints/<character>`), printed as
//! a table. Targets (issue 4): G + π for one character at most 1 ms median per frame; 64 characters
//! batched at most 4 ms.
//!
//! ```text
//! cargo bench -p ace_models --bench inference
//! ```
//! Rows:
//! - `step ×N`: [`Retargeter::step`] for N characters driven by N human frames in one batch: x^h
//!   normalisation, G, π, and each character's pose with its cleanup — what the Bevy plugin's worker
//!   pays per frame;
//! - `whole frame ×1`: [`Retargeter::retarget_states`] per frame on a held clip: the networks plus the
//!   pose (root integration, joint limits, wheels) and foot locking — what `ace retarget` pays.
//!
//! libtorch runs on one thread (the plugin's setting; a game has other work for the other cores).
//! Each figure is the median (and 90th percentile) over many frames after a warm-up.

use std::path::Path;
use std::time::Instant;

use ace_models::human::{HumanClip, ImportOptions};
use ace_models::human_set::{HumanRow, PROJECT_FPS};
use ace_models::learn::retarget::Retargeter;
use ace_models::learn::set_threads;
use ace_models::morphology::load_character;
use tch::Device;

fn percentiles(mut v: Vec<f64>) -> (f64, f64) {
    v.sort_by(f64::total_cmp);
    (v[v.len() / 2], v[v.len() * 9 / 10])
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

    println!("| character | measured | frames | median (ms) | p90 (ms) | median per character (ms) |");
    println!("|---|---|---:|---:|---:|---:|");
    for name in ["spot", "crab", "stretch"] {
        let dir = root.join("assets/checkpoints").join(name);
        let (tree, morph) = load_character(&root.join(format!("assets/characters/{name}.urdf"))).expect("bundled character");
        let r = match Retargeter::load(&dir, Device::Cpu) {
            Ok(r) => r,
            Err(e) => {
                println!("| {name} | no checkpoint: {e} | | | | |");
                continue;
            }
        };
        for batch in [1usize, 16, 64] {
            let mut streams: Vec<_> = (0..batch).map(|_| r.stream(&tree, &morph).expect("stream")).collect();
            let mut times = Vec::new();
            for (t, x) in looped.iter().enumerate() {
                let inputs = vec![*x; batch];
                let t0 = Instant::now();
                let out = r.step(&tree, &morph, &mut streams.iter_mut().collect::<Vec<_>>(), &inputs).expect("step");
                let dt = t0.elapsed().as_secs_f64() * 1e3;
                assert_eq!(out.len(), batch);
                if t >= 30 {
                    times.push(dt);
                }
            }
            let (med, p90) = percentiles(times);
            println!("| {name} | step ×{batch} | {} | {med:.3} | {p90:.3} | {:.4} |", looped.len() - 30, med / batch as f64);
        }
        // The whole-clip path, timed per frame over the clip (one call, so per-frame = total / frames).
        let mut per_frame = Vec::new();
        for _ in 0..5 {
            let t0 = Instant::now();
            let m = r.retarget_states(&tree, &morph, &looped).expect("retarget");
            per_frame.push(t0.elapsed().as_secs_f64() * 1e3 / m.poses.len() as f64);
        }
        let (med, p90) = percentiles(per_frame);
        println!("| {name} | whole frame ×1 (5 runs of {} frames) | {} | {med:.3} | {p90:.3} | {med:.3} |", looped.len(), looped.len());
    }
}
