//! How legged animals time their steps, as laws of body size and speed (dynamic similarity): the one
//! place where the gait-timing constants and their sources live. The controllers step by these laws
//! ([`crate::controller`]), the gait measure compares any motion with them ([`crate::metrics::gait`])
//! and the foot lock sizes its swings by them ([`crate::foot_lock`]).
//!
//! Animals of different sizes move in a dynamically similar way at equal **Froude numbers**
//! `Fr = v² / (g·h)` (`v` speed, `h` hip height): they then use the same gait with the same duty factor
//! and the same stride length relative to `h` (Alexander & Jayes 1983). The relative stride length
//! follows `λ / h ≈ 2.3 · Fr^0.3` from mice to horses and in humans (Alexander 1976, 1989), so the
//! stride frequency is `f = v / λ`: small animals step faster than large ones at the same speed, and
//! every animal's frequency grows more slowly than its speed.
//!
//! | quantity | value | source |
//! |---|---|---|
//! | relative stride `λ/h` | `2.3 · Fr^0.3` | Alexander 1976; Alexander 1989, fig. 4 |
//! | walk → trot (or run) | `Fr ≈ 0.3–0.5`; here [`WALK_TROT_FROUDE`] | Alexander & Jayes 1983; Alexander 1989 |
//! | trot → gallop | `Fr ≈ 2–3`; here [`TROT_GALLOP_FROUDE`] | Alexander & Jayes 1983; Heglund & Taylor 1988 |
//! | walk duty factor | 0.75 slow → 0.6 at the trot | Alexander & Jayes 1983 (walks: β > 0.5) |
//! | trot duty factor | ≈ 0.5 → 0.4 | Alexander & Jayes 1983 |
//! | gallop duty factor | 0.4 → 0.25 | Alexander & Jayes 1983 |
//! | hexapod wave, ripple, tripod | phase patterns, duty `1 − 1/n`, ≈ 2/3, ≈ 1/2 | Wilson 1966 |
//!
//! - R. McN. Alexander (1976), *Estimates of speeds of dinosaurs*, Nature 261, 129–130.
//! - R. McN. Alexander, A. S. Jayes (1983), *A dynamic similarity hypothesis for the gaits of
//!   quadrupedal mammals*, J. Zool. 201, 135–152.
//! - R. McN. Alexander (1989), *Optimization and gaits in the locomotion of vertebrates*, Physiol. Rev.
//!   69, 1199–1227.
//! - N. C. Heglund, C. R. Taylor (1988), *Speed, stride frequency and energy cost per stride: how do they
//!   change with body size and gait?*, J. Exp. Biol. 138, 301–318.
//! - D. M. Wilson (1966), *Insect walking*, Annu. Rev. Entomol. 11, 103–122.
//!
//! The law says nothing about standing still (`λ → 0`); below [`MIN_FROUDE`] the frequency stays at
//! its value there, so that a character turning on the spot or shuffling still steps at a walk's pace.
//! Hip height here is the mean height of the legs' first moving joints above their feet at the
//! controllers' nominal stance, the posture the character walks in ([`hip_height`]).

use crate::controller::chain::Chain;
use crate::kinematics::{CharacterPose, KinematicTree};
use crate::morphology::Morphology;

/// Gravity (m/s²).
pub const GRAVITY: f32 = 9.81;
/// Coefficient of the relative stride law `λ/h = A · Fr^B` (Alexander 1976).
pub const STRIDE_COEFFICIENT: f32 = 2.3;
/// Exponent of the relative stride law.
pub const STRIDE_EXPONENT: f32 = 0.3;
/// Froude number of the walk → trot transition (quadrupeds; the walk → run of bipeds and the wave or
/// ripple → tripod of hexapods use it too).
pub const WALK_TROT_FROUDE: f32 = 0.4;
/// Froude number of the trot → gallop transition.
pub const TROT_GALLOP_FROUDE: f32 = 2.5;
/// Froude number below which stepping keeps the frequency it has there (see the module docs).
pub const MIN_FROUDE: f32 = 0.005;
/// Froude number below which a motion counts as walking in the gait measure's checks.
pub const WALKING_FROUDE: f32 = 0.3;

/// `Fr = v² / (g·h)`.
pub fn froude(speed: f32, hip_height: f32) -> f32 {
    speed * speed / (GRAVITY * hip_height.max(1e-3))
}

/// The speed at Froude number `fr` for hip height `h` (m/s).
pub fn speed_at_froude(fr: f32, hip_height: f32) -> f32 {
    (fr.max(0.0) * GRAVITY * hip_height.max(1e-3)).sqrt()
}

/// Stride length predicted at speed `speed` (m): `h · 2.3 · Fr^0.3`.
pub fn stride_length(speed: f32, hip_height: f32) -> f32 {
    hip_height * STRIDE_COEFFICIENT * froude(speed, hip_height).powf(STRIDE_EXPONENT)
}

/// The speed at which the law's stride is `stride` long (m/s): the inverse of [`stride_length`].
pub fn speed_for_stride(stride: f32, hip_height: f32) -> f32 {
    let h = hip_height.max(1e-3);
    let fr = (stride.max(0.0) / (STRIDE_COEFFICIENT * h)).powf(1.0 / STRIDE_EXPONENT);
    speed_at_froude(fr, h)
}

/// Stride frequency predicted at speed `speed` (Hz): `v / λ`, held at its [`MIN_FROUDE`] value below
/// that Froude number.
pub fn stride_frequency(speed: f32, hip_height: f32) -> f32 {
    let v = speed.abs().max(speed_at_froude(MIN_FROUDE, hip_height));
    v / stride_length(v, hip_height)
}

/// Duty factor of a quadruped-like gait at Froude number `fr` (the table in the module docs): the walk
/// from 0.75 down to 0.6 at the trot, the trot from 0.5 down to 0.4 at the gallop, the gallop from 0.4
/// down to 0.25 at twice the gallop's Froude number.
pub fn duty_factor(fr: f32) -> f32 {
    let lerp = |a: f32, b: f32, t: f32| a + (b - a) * t.clamp(0.0, 1.0);
    if fr < WALK_TROT_FROUDE {
        lerp(0.75, 0.6, fr / WALK_TROT_FROUDE)
    } else if fr < TROT_GALLOP_FROUDE {
        lerp(
            0.5,
            0.4,
            (fr - WALK_TROT_FROUDE) / (TROT_GALLOP_FROUDE - WALK_TROT_FROUDE),
        )
    } else {
        lerp(0.4, 0.25, (fr - TROT_GALLOP_FROUDE) / TROT_GALLOP_FROUDE)
    }
}

/// The natural swing time at speed `speed` (s): `(1 − duty) / f`.
pub fn swing_time(speed: f32, hip_height: f32) -> f32 {
    (1.0 - duty_factor(froude(speed, hip_height))) / stride_frequency(speed, hip_height)
}

/// Mean height of the legs' first moving joints above their foot points in `pose` (m; `None` without
/// feet). Legs are the chains from the root to [`Morphology::feet`].
pub fn hip_height_at(tree: &KinematicTree, morph: &Morphology, pose: &CharacterPose) -> Option<f32> {
    let links = tree.forward_kinematics(pose);
    let heights: Vec<f32> = morph
        .feet
        .iter()
        .filter_map(|&f| {
            let chain = Chain::new(tree, morph, f);
            let hip = chain.links[chain.first_moving()?];
            Some(links[hip].translation.vector.z - morph.ee_point(f, &links).z)
        })
        .filter(|h| *h > 0.0)
        .collect();
    (!heights.is_empty()).then(|| heights.iter().sum::<f32>() / heights.len() as f32)
}

/// The hip height a character walks at: [`hip_height_at`] the nominal stance of its controllers
/// ([`crate::controller::Rig::hip_height`], default configuration), or at the standing pose
/// ([`KinematicTree::standing_pose`]) when they cannot drive it.
pub fn hip_height(tree: &KinematicTree, morph: &Morphology) -> Option<f32> {
    use crate::controller::{BaseMode, ControllerConfig, Rig};
    match Rig::new(tree, morph, &ControllerConfig::default(), 30.0) {
        Ok(rig) if rig.mode == BaseMode::Legged => Some(rig.hip_height),
        _ => hip_height_at(tree, morph, &tree.standing_pose()),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_law_reproduces_alexanders_figures() {
        // A 0.5 m hip at 0.63 m/s: Fr 0.081, λ/h = 2.3 · 0.081^0.3 = 1.08, f = 0.63 / 0.54 = 1.17 Hz.
        let h = 0.5;
        assert!((froude(0.63, h) - 0.0809).abs() < 1e-3);
        assert!((stride_length(0.63, h) / h - 1.082).abs() < 2e-3);
        assert!((stride_frequency(0.63, h) - 1.165).abs() < 5e-3);
        // Smaller animals step faster at the same speed.
        assert!(stride_frequency(0.5, 0.1) > 2.0 * stride_frequency(0.5, 0.5));
        // Frequency grows more slowly than speed: f ∝ v^0.4 at a fixed size.
        let r = stride_frequency(2.0, h) / stride_frequency(1.0, h);
        assert!((r - 2f32.powf(0.4)).abs() < 1e-3, "{r}");
        // The inverse of the stride law.
        assert!((speed_for_stride(stride_length(0.63, h), h) - 0.63).abs() < 1e-4);
        // Standing still keeps a finite frequency.
        assert_eq!(
            stride_frequency(0.0, h),
            stride_frequency(speed_at_froude(MIN_FROUDE, h), h)
        );
        assert!(stride_frequency(0.0, h).is_finite() && stride_frequency(0.0, h) > 0.3);
    }

    #[test]
    fn duty_factor_falls_through_the_gaits() {
        assert_eq!(duty_factor(0.0), 0.75);
        assert!((duty_factor(0.399) - 0.6).abs() < 1e-3);
        assert_eq!(duty_factor(WALK_TROT_FROUDE), 0.5);
        assert_eq!(duty_factor(TROT_GALLOP_FROUDE), 0.4);
        // Halfway through the trot, halfway from 0.5 to 0.4.
        assert!((duty_factor(0.5 * (WALK_TROT_FROUDE + TROT_GALLOP_FROUDE)) - 0.45).abs() < 1e-6);
        // Halfway through the gallop's fall (1.5 times its Froude number), halfway from 0.4 to 0.25.
        assert!((duty_factor(1.5 * TROT_GALLOP_FROUDE) - 0.325).abs() < 1e-6);
        assert_eq!(duty_factor(100.0), 0.25);
        // Swing time at rest for a 0.5 m hip: 0.25 of a ~1.5 s stride.
        let t = swing_time(0.0, 0.5);
        assert!(t > 0.3 && t < 0.45, "{t}");
    }
}
