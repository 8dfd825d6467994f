//! Character dataset generation throughput: 200k frames per bundled character (the paper's size) and
//! per rigged creature of `../shared/data/creatures` (when present), printed as a table. Targets: under
//! 60 s per robot, under 10 s per creature.
//!
//! ```text
//! cargo bench -p ace_models --no-default-features --bench dataset
//! ACE_BENCH_FRAMES=20000 cargo bench -p ace_models --no-default-features --bench dataset   # quicker
//! ```
//! `rig` is the one-off analysis of the character (leg calibration), `generate` the whole rollout
//! including x^r and the statistics, `save` writing the safetensors file.

use std::path::Path;
use std::time::Instant;

use ace_models::dataset::{DatasetConfig, MotionSet, generate};
use ace_models::kinematics::CharacterPose;
use ace_models::metrics::{UfrConfig, ufr_episodes};
use ace_models::morphology::load_character;

fn main() {
    let frames: usize = std::env::var("ACE_BENCH_FRAMES")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(200_000);
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../assets/characters");
    let out = std::env::temp_dir().join(format!("ace_bench_dataset_{}", std::process::id()));
    std::fs::create_dir_all(&out).expect("temp dir");
    println!(
        "| character | frames | generate (s) | frames/s | s per 200k | save (s) | file (MB) | UFR % (collision / penetration / sliding) |"
    );
    println!("|---|---:|---:|---:|---:|---:|---:|---|");
    let mut notes = Vec::new();
    let creatures = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../shared/data/creatures");
    let mut characters: Vec<(String, std::path::PathBuf)> =
        ["spot", "crab", "stretch"].iter().map(|n| (n.to_string(), dir.join(format!("{n}.urdf")))).collect();
    for f in ["Fox/Fox.glb", "Quaternius_Wolf/Wolf.gltf", "Quaternius_Spider/Spider.glb", "Quaternius_TRex/t-rex.glb", "Quaternius_Snake/Snake.glb"] {
        let p = creatures.join(f);
        if p.is_file() {
            characters.push((p.file_stem().unwrap().to_string_lossy().into_owned(), p));
        }
    }
    for (name, path) in &characters {
        let (tree, morph) = load_character(path).expect("character");
        let cfg = DatasetConfig {
            frames,
            ..DatasetConfig::default()
        };
        let start = Instant::now();
        let set: MotionSet = generate(&tree, &morph, &cfg, &mut |_| {}).expect("dataset");
        let secs = start.elapsed().as_secs_f64();
        let path = out.join(format!("{name}.safetensors"));
        let start = Instant::now();
        set.save(&path).expect("save");
        let save = start.elapsed().as_secs_f64();
        let size = std::fs::metadata(&path).map(|m| m.len()).unwrap_or(0) as f64 / 1e6;
        let poses: Vec<CharacterPose> = (0..set.len()).map(|i| set.pose(i)).collect();
        let ufr = ufr_episodes(
            &tree,
            &morph,
            &poses,
            &set.episodes,
            set.fps,
            &UfrConfig::for_character(&tree, &morph),
        );
        let r = ufr.rates;
        println!(
            "| {name} | {} | {secs:.2} | {:.0} | {:.1} | {save:.2} | {size:.1} | {:.3} ({:.3} / {:.3} / {:.3}) |",
            set.len(),
            set.len() as f64 / secs,
            secs * 200_000.0 / set.len() as f64,
            100.0 * r.ufr,
            100.0 * r.self_collision,
            100.0 * r.penetration,
            100.0 * r.sliding
        );
        for p in &ufr.collision_pairs {
            notes.push(format!("{name}: {} – {} collide in {} frames", p.a, p.b, p.frames));
        }
    }
    for n in notes {
        println!("{n}");
    }
    let _ = std::fs::remove_dir_all(&out);
}
