//! Import and kinematics throughput on the shared data, printed as a table.
//!
//! ```text
//! cargo bench -p ace_models --no-default-features --bench import
//! ```
//! BVH import covers parsing, mapping to the canonical skeleton and forward kinematics of every
//! frame; `states` is building x^h for every frame; FK is `forward_kinematics_into` on random poses.

use std::path::{Path, PathBuf};
use std::time::Instant;

use ace_models::human::{HumanClip, ImportOptions};
use ace_models::kinematics::{CharacterPose, KinematicTree};
use ace_models::nalgebra::Isometry3;

#[path = "common/mod.rs"]
mod common;
use common::{bvh_files, shared_data};

/// A small deterministic generator, so runs compare.
struct Lcg(u64);
impl Lcg {
    fn next(&mut self) -> f32 {
        self.0 = self.0.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
        ((self.0 >> 40) as f32 / (1u64 << 24) as f32) * 2.0 - 1.0
    }
}

fn main() {
    let data = shared_data();
    let mut files = Vec::new();
    bvh_files(&data.join("human"), &mut files);
    if files.is_empty() {
        eprintln!("no BVH files under {}; the shared data must stand beside the project", data.display());
        std::process::exit(1);
    }
    let texts: Vec<(String, String)> =
        files.iter().map(|p| (p.file_stem().unwrap().to_string_lossy().into_owned(), std::fs::read_to_string(p).unwrap())).collect();
    let bytes: usize = texts.iter().map(|(_, t)| t.len()).sum();

    println!("| benchmark | input | time | throughput |");
    println!("|---|---|---:|---:|");
    let mut best = f64::MAX;
    let mut clips = Vec::new();
    for _ in 0..3 {
        let start = Instant::now();
        clips = texts.iter().map(|(n, t)| HumanClip::from_bvh_str(t, n, &ImportOptions::default()).unwrap()).collect();
        best = best.min(start.elapsed().as_secs_f64());
    }
    let frames: usize = clips.iter().map(|c| c.frames.len()).sum();
    println!(
        "| BVH import (parse + map + FK) | {} files, {:.1} MB, {} frames | {:.3} s | {:.1} MB/s, {:.0} frames/s |",
        texts.len(),
        bytes as f64 / 1e6,
        frames,
        best,
        bytes as f64 / 1e6 / best,
        frames as f64 / best
    );
    let start = Instant::now();
    let states: usize = clips.iter().map(|c| c.states().len()).sum();
    let dt = start.elapsed().as_secs_f64();
    println!("| human state x^h | {states} frames | {dt:.3} s | {:.0} frames/s |", states as f64 / dt);

    let mut urdfs: Vec<PathBuf> = ["spot", "crab", "stretch"]
        .iter()
        .map(|n| Path::new(env!("CARGO_MANIFEST_DIR")).join(format!("../assets/characters/{n}.urdf")))
        .collect();
    urdfs.push(data.join("robots/spot_arm/spot_with_arm.urdf"));
    urdfs.push(data.join("robots/phantomx_hexapod/phantomx_description/urdf/phantomx.urdf"));
    urdfs.push(data.join("robots/stretch_re1/stretch_description_RE1V0_tool_stretch_gripper.urdf"));
    for path in urdfs {
        let tree = KinematicTree::from_urdf_file(&path).unwrap();
        let mut rng = Lcg(7);
        const POSES: usize = 1000;
        let poses: Vec<CharacterPose> = (0..POSES)
            .map(|_| {
                let mut q: Vec<f32> = (0..tree.dof()).map(|_| rng.next()).collect();
                tree.clamp(&mut q);
                CharacterPose { root: Isometry3::identity(), q }
            })
            .collect();
        let mut out = Vec::with_capacity(tree.links.len());
        let rounds = 200;
        let start = Instant::now();
        let mut sink = 0.0f32;
        for _ in 0..rounds {
            for p in &poses {
                tree.forward_kinematics_into(p, &mut out);
                sink += out[out.len() - 1].translation.vector.x;
            }
        }
        let dt = start.elapsed().as_secs_f64();
        let n = (rounds * POSES) as f64;
        println!(
            "| FK {} | {} links, {} DoF | {:.1} ns/frame | {:.2} M frames/s ({:.0} M links/s) |{}",
            path.file_name().unwrap().to_string_lossy(),
            tree.links.len(),
            tree.dof(),
            dt / n * 1e9,
            n / dt / 1e6,
            n * tree.links.len() as f64 / dt / 1e6,
            if sink.is_nan() { " (NaN seen)" } else { "" }
        );
    }
}
