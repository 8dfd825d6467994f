//! Metrics throughput on 200k frames per bundled character, printed as a table.
//!
//! ```text
//! cargo bench -p ace_models --no-default-features --bench metrics [-- FRAMES]
//! ```
//! The motion is synthetic (every joint a sinusoid inside its limits, the root walking and turning),
//! so self-collisions and sliding do occur and the narrow phase is exercised. Timed on one core:
//! UFR (forward kinematics, broad and narrow phase, penetration, sliding), x^r + Ψ for every frame,
//! DIV (10 000 pairs) and FID (Gaussian fit of both sets, Fréchet distance).

use std::path::Path;
use std::time::Instant;

use ace_models::character_state::{CharacterLayout, StateScratch, character_state_into};
use ace_models::features::{EndEffectorMapping, FeatureLayout, character_body_length, character_features_into};
use ace_models::kinematics::CharacterPose;
use ace_models::metrics::{DivConfig, GaussianFit, UfrConfig, diversity, frechet_distance, ufr};
use ace_models::morphology::load_character;
use ace_models::nalgebra::{Isometry3, Translation3, UnitQuaternion};

const FPS: f32 = 30.0;

fn main() {
    let frames: usize = std::env::args().skip(1).find_map(|a| a.parse().ok()).unwrap_or(200_000);
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../assets/characters");
    println!("{frames} frames per character, {FPS} fps, one core");
    println!(
        "{:<8} {:>9} {:>10} {:>10} {:>9} {:>9}   {:>7} {:>7} {:>7}",
        "char", "UFR s", "states s", "Ψ s", "DIV s", "FID s", "UFR %", "coll %", "slide %"
    );
    for name in ["spot", "crab", "stretch"] {
        let (tree, morph) = load_character(&dir.join(format!("{name}.urdf"))).unwrap();
        let stand = tree.standing_pose();
        let poses: Vec<CharacterPose> = (0..frames)
            .map(|t| {
                let s = t as f32 / FPS;
                let mut q = stand.q.clone();
                for (d, x) in q.iter_mut().enumerate() {
                    let lim = tree.limits(d).unwrap();
                    let (lo, hi) = (lim.lower.max(-3.0), lim.upper.min(3.0));
                    let phase = (s * (0.7 + 0.13 * d as f32) + d as f32).sin();
                    *x = 0.5 * (lo + hi) + 0.3 * (hi - lo) * phase;
                }
                CharacterPose {
                    root: Isometry3::from_parts(
                        Translation3::new(0.3 * s, 0.0, stand.root.translation.z + 0.02 * (3.0 * s).sin()),
                        UnitQuaternion::from_euler_angles(0.0, 0.0, 0.1 * s),
                    ),
                    q,
                }
            })
            .collect();

        let config = UfrConfig::for_character(&tree, &morph);
        let t0 = Instant::now();
        let report = ufr(&tree, &morph, &poses, FPS, &config);
        let t_ufr = t0.elapsed().as_secs_f64();

        let layout = CharacterLayout::new(&tree, &morph);
        let mapping = EndEffectorMapping::by_side(&tree, &morph);
        let body = character_body_length(&tree, &morph);
        let t0 = Instant::now();
        let mut scratch = StateScratch::default();
        let states: Vec<Vec<f32>> = (0..frames)
            .map(|t| {
                let mut x = vec![0.0; layout.dim()];
                let prev = &poses[t.saturating_sub(1)];
                character_state_into(&tree, &morph, prev, &poses[t], 1.0 / FPS, &mut scratch, &mut x);
                x
            })
            .collect();
        let t_states = t0.elapsed().as_secs_f64();
        let t0 = Instant::now();
        let dim = FeatureLayout::new(&mapping).dim();
        let psi: Vec<Vec<f32>> = states
            .iter()
            .map(|x| {
                let mut f = vec![0.0; dim];
                character_features_into(&layout, x, body, &mapping, &mut f);
                f
            })
            .collect();
        let t_psi = t0.elapsed().as_secs_f64();

        let t0 = Instant::now();
        let div = diversity(&psi, &DivConfig::default());
        let t_div = t0.elapsed().as_secs_f64();
        let half = frames / 2;
        let t0 = Instant::now();
        let fid = frechet_distance(&GaussianFit::fit(&psi[..half]), &GaussianFit::fit(&psi[half..]));
        let t_fid = t0.elapsed().as_secs_f64();

        let r = &report.rates;
        println!(
            "{name:<8} {t_ufr:>9.3} {t_states:>10.3} {t_psi:>10.3} {t_div:>9.4} {t_fid:>9.3}   {:>7.2} {:>7.2} {:>7.2}   (DIV {div:.3}, FID halves {fid:.4}, Ψ dim {dim})",
            100.0 * r.ufr,
            100.0 * r.self_collision,
            100.0 * r.sliding
        );
    }
}
