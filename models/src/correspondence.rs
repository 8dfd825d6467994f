//! Automatic end-effector correspondence (paper §5.3).
//!
//! Each character end effector `j` is paired with the human end effector `i` whose position
//! distribution is closest in the Kullback–Leibler sense:
//! `j ↦ argmin_i KL[p(x^{r,j}) ‖ p(x^{h,i})]`.
//!
//! **Positions** are those Ψ compares ([`crate::features`]): in the heading frame (origin at the root,
//! x forward, z up) divided by the body length, so that a 0.5 m robot and a 1.7 m human are on one
//! scale. They come from a character dataset ([`EndEffectorStats::from_motion_set`]) and from human
//! states x^h ([`EndEffectorStats::add_human_states`]).
//!
//! **Distributions** are 3-D Gaussians fitted to each end effector's positions (mean and population
//! covariance, accumulated in one pass so that no frame is stored), and the KL divergence is the
//! closed form for Gaussians ([`Gaussian::kl_divergence`]).
//!
//! **Resolution.** [`COVARIANCE_FLOOR`] is added to the diagonal of every covariance, on both sides.
//! It keeps a rigidly mounted end effector (zero spread) from having a singular Gaussian and an
//! infinite KL, and, as adding a variance is blurring the positions with a Gaussian kernel, it sets the
//! resolution at which places are told apart: [`POSITION_RESOLUTION`] = 0.15 body lengths. With only
//! a numerical floor (1e-4, 0.01 body lengths) the KL is ruled by the spread of the *human* end
//! effectors: `KL[p_r ‖ p_h]` charges a character end effector for every place it goes that the human
//! one does not, in units of the human one's spread, so a widely moving human end effector (a waving
//! hand) wins over a foot that stays within a few centimetres, whatever the character end effector is.
//! On the bundled Spot and clips that floor sends all four feet to the right hand; from a floor of
//! about 0.02 on the feet go to the feet of their own side and the arm to the right hand, as in the
//! paper (§7.5). [`Correspondence::automatic_with_floor`] takes another floor.
//!
//! A user may replace any entry ([`Correspondence::with_overrides`], paper §7.5); the table printed by
//! `Display` keeps the scores, so the automatic choice stays visible next to the manual one.

use std::fmt;

use nalgebra::{Matrix3, Vector3};
use serde::{Deserialize, Serialize};
use thiserror::Error;

use crate::character_state::CharacterLayout;
use crate::dataset::MotionSet;
use crate::features::EndEffectorMapping;
use crate::human::{EndEffector, layout as human_layout};

/// The standard deviation, in body lengths, of the blur under which positions are compared (see the
/// module docs): about 25 cm on a 1.7 m human, 9 cm on Spot.
pub const POSITION_RESOLUTION: f64 = 0.15;

/// Variance added to the diagonal of every fitted covariance, in body lengths²:
/// [`POSITION_RESOLUTION`]².
pub const COVARIANCE_FLOOR: f64 = POSITION_RESOLUTION * POSITION_RESOLUTION;

/// Running mean and covariance of a set of 3-D points (Welford's update, in `f64`).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct PositionMoments {
    count: u64,
    mean: Vector3<f64>,
    /// Sum of the outer products of the deviations from the running mean.
    scatter: Matrix3<f64>,
}

impl PositionMoments {
    /// Adds a point; points with a non-finite coordinate are ignored.
    pub fn push(&mut self, p: [f32; 3]) {
        if !p.iter().all(|v| v.is_finite()) {
            return;
        }
        let x = Vector3::new(f64::from(p[0]), f64::from(p[1]), f64::from(p[2]));
        self.count += 1;
        let before = x - self.mean;
        self.mean += before / self.count as f64;
        self.scatter += before * (x - self.mean).transpose();
    }

    /// Number of points added.
    pub fn count(&self) -> u64 {
        self.count
    }

    /// Mean of the points (zero when there are none).
    pub fn mean(&self) -> Vector3<f64> {
        self.mean
    }

    /// Population covariance of the points (divided by the count; zero for fewer than two points).
    pub fn covariance(&self) -> Matrix3<f64> {
        if self.count < 2 {
            return Matrix3::zeros();
        }
        let c = self.scatter / self.count as f64;
        (c + c.transpose()) * 0.5
    }

    /// The fitted Gaussian with `floor` added to the covariance's diagonal ([`COVARIANCE_FLOOR`]
    /// normally); `None` without points.
    pub fn gaussian(&self, floor: f64) -> Option<Gaussian> {
        (self.count > 0).then(|| Gaussian::new(self.mean, self.covariance() + Matrix3::identity() * floor))
    }
}

/// A 3-D Gaussian distribution.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Gaussian {
    /// Mean.
    pub mean: Vector3<f64>,
    /// Covariance (symmetric positive definite).
    pub covariance: Matrix3<f64>,
}

impl Gaussian {
    /// A Gaussian from its mean and covariance.
    pub fn new(mean: Vector3<f64>, covariance: Matrix3<f64>) -> Self {
        Gaussian { mean, covariance }
    }

    /// `KL[self ‖ other]` in nats:
    /// `½ (tr(Σ₁⁻¹Σ₀) + (μ₁−μ₀)ᵀΣ₁⁻¹(μ₁−μ₀) − 3 + ln det Σ₁ − ln det Σ₀)` with `self = N(μ₀, Σ₀)` and
    /// `other = N(μ₁, Σ₁)`. Zero for equal distributions, positive otherwise; `+∞` when a covariance
    /// is not positive definite.
    pub fn kl_divergence(&self, other: &Gaussian) -> f64 {
        let (Some(c0), Some(c1)) = (self.covariance.cholesky(), other.covariance.cholesky()) else {
            return f64::INFINITY;
        };
        let log_det = |l: &Matrix3<f64>| 2.0 * (0..3).map(|k| l[(k, k)].ln()).sum::<f64>();
        let trace = c1.solve(&self.covariance).trace();
        let d = other.mean - self.mean;
        let mahalanobis = d.dot(&c1.solve(&d));
        let kl = 0.5 * (trace + mahalanobis - 3.0 + log_det(&c1.l()) - log_det(&c0.l()));
        // Round-off can leave a tiny negative value for (nearly) equal distributions.
        kl.max(0.0)
    }
}

/// Position statistics of a set of end effectors, in the units of Ψ (heading frame, body lengths).
#[derive(Clone, Debug, PartialEq)]
pub struct EndEffectorStats {
    /// End-effector names: the character's link names, or the human end effectors' names.
    pub names: Vec<String>,
    /// Position moments, one per end effector in `names` order.
    pub moments: Vec<PositionMoments>,
}

impl EndEffectorStats {
    /// Empty statistics for end effectors with these names.
    pub fn new(names: Vec<String>) -> Self {
        let moments = vec![PositionMoments::default(); names.len()];
        EndEffectorStats { names, moments }
    }

    /// Empty statistics for the five human end effectors, in [`EndEffector::ALL`] order.
    pub fn human() -> Self {
        Self::new(EndEffector::ALL.iter().map(|e| e.name().to_string()).collect())
    }

    /// The character end-effector positions of every frame of a dataset (`set.layout`), for a
    /// character of `body_length` metres ([`crate::features::character_body_length`]).
    ///
    /// # Panics
    /// If `body_length` is not positive.
    pub fn from_motion_set(set: &MotionSet, body_length: f32) -> Self {
        let mut s = Self::new(set.end_effector_links.clone());
        for i in 0..set.len() {
            s.add_character_state(&set.layout, set.state(i), body_length);
        }
        s
    }

    /// Adds the end-effector positions of one character state x^r laid out by `layout`.
    ///
    /// # Panics
    /// If `x_r` does not match `layout`, `layout` has a different number of end effectors, or
    /// `body_length` is not positive.
    pub fn add_character_state(&mut self, layout: &CharacterLayout, x_r: &[f32], body_length: f32) {
        assert_eq!(x_r.len(), layout.dim(), "x^r has the wrong length for its layout");
        assert_eq!(
            layout.end_effectors,
            self.names.len(),
            "the layout's end effectors do not match the statistics'"
        );
        let inv = positive_inverse(body_length);
        for (k, c) in x_r[layout.ee_positions()].chunks_exact(3).enumerate() {
            self.moments[k].push([c[0] * inv, c[1] * inv, c[2] * inv]);
        }
    }

    /// Human statistics ([`EndEffectorStats::human`]) from x^h rows of one human of `body_length`
    /// metres ([`crate::features::human_body_length`]).
    pub fn from_human_states<R: AsRef<[f32]>>(rows: impl IntoIterator<Item = R>, body_length: f32) -> Self {
        let mut s = Self::human();
        s.add_human_states(rows, body_length);
        s
    }

    /// Adds the end-effector positions of x^h rows (92 values each) of a human of `body_length`
    /// metres; call once per clip when clips differ in body length.
    ///
    /// # Panics
    /// If these are not human statistics, a row is not 92 long or `body_length` is not positive.
    pub fn add_human_states<R: AsRef<[f32]>>(&mut self, rows: impl IntoIterator<Item = R>, body_length: f32) {
        assert_eq!(
            self.names.len(),
            EndEffector::ALL.len(),
            "not human end-effector statistics"
        );
        let inv = positive_inverse(body_length);
        for row in rows {
            let x_h = row.as_ref();
            assert_eq!(
                x_h.len(),
                human_layout::DIM,
                "x^h must have {} values",
                human_layout::DIM
            );
            for (k, e) in EndEffector::ALL.into_iter().enumerate() {
                let p = &x_h[human_layout::ee_position(e)];
                self.moments[k].push([p[0] * inv, p[1] * inv, p[2] * inv]);
            }
        }
    }

    /// The fitted Gaussian of every end effector, or the name of the first one without samples.
    fn gaussians(&self, floor: f64) -> Result<Vec<Gaussian>, String> {
        self.moments
            .iter()
            .zip(&self.names)
            .map(|(m, n)| m.gaussian(floor).ok_or_else(|| n.clone()))
            .collect()
    }
}

fn positive_inverse(body_length: f32) -> f32 {
    assert!(
        body_length.is_finite() && body_length > 0.0,
        "body length must be positive, got {body_length}"
    );
    1.0 / body_length
}

/// Why a correspondence could not be built or changed.
#[derive(Debug, Clone, Error, PartialEq)]
pub enum CorrespondenceError {
    /// An end effector without any position sample.
    #[error("{side} end effector `{name}` has no position samples")]
    NoSamples {
        /// `character` or `human`.
        side: &'static str,
        /// Its name.
        name: String,
    },
    /// A covariance floor that is not a positive number.
    #[error("the covariance floor must be positive, not {0}")]
    Floor(f64),
    /// The human statistics are not the five human end effectors.
    #[error("the human statistics must hold the 5 human end effectors in order, not {0:?}")]
    NotHuman(Vec<String>),
    /// An override for a character end effector that does not exist.
    #[error("override for character end effector {index}: the character has {count} end effectors")]
    NoSuchEndEffector {
        /// The index given.
        index: usize,
        /// How many there are.
        count: usize,
    },
}

/// Where a correspondence came from.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum MappingSource {
    /// Every entry is the KL minimum.
    Automatic,
    /// Some entries were set by the user.
    Manual,
}

/// An end-effector correspondence with the KL scores it was chosen from.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Correspondence {
    /// The human end effector of each character end effector.
    pub mapping: EndEffectorMapping,
    /// Link name of each character end effector (the rows of `scores`).
    pub character_links: Vec<String>,
    /// `scores[j][i] = KL[p(x^{r,j}) ‖ p(x^{h,i})]` (nats), `i` in [`EndEffector::ALL`] order.
    pub scores: Vec<Vec<f64>>,
    /// Automatic, or changed by the user.
    pub source: MappingSource,
}

impl Correspondence {
    /// Pairs each character end effector with the human end effector of least KL divergence (the
    /// first on a tie), with covariances floored at [`COVARIANCE_FLOOR`]. `human` must be
    /// [`EndEffectorStats::human`] statistics.
    pub fn automatic(
        character: &EndEffectorStats,
        human: &EndEffectorStats,
    ) -> Result<Correspondence, CorrespondenceError> {
        Self::automatic_with_floor(character, human, COVARIANCE_FLOOR)
    }

    /// [`Correspondence::automatic`] with another covariance floor (body lengths², positive).
    pub fn automatic_with_floor(
        character: &EndEffectorStats,
        human: &EndEffectorStats,
        floor: f64,
    ) -> Result<Correspondence, CorrespondenceError> {
        if !(floor.is_finite() && floor > 0.0) {
            return Err(CorrespondenceError::Floor(floor));
        }
        if human.names != EndEffectorStats::human().names {
            return Err(CorrespondenceError::NotHuman(human.names.clone()));
        }
        let no_samples = |side| move |name| CorrespondenceError::NoSamples { side, name };
        let r = character.gaussians(floor).map_err(no_samples("character"))?;
        let h = human.gaussians(floor).map_err(no_samples("human"))?;
        let scores: Vec<Vec<f64>> = r
            .iter()
            .map(|gr| h.iter().map(|gh| gr.kl_divergence(gh)).collect())
            .collect();
        let mapping = EndEffectorMapping::new(scores.iter().map(|row| argmin(row)).collect());
        Ok(Correspondence {
            mapping,
            character_links: character.names.clone(),
            scores,
            source: MappingSource::Automatic,
        })
    }

    /// Replaces the human end effector of the given character end effectors (`None` leaves one out
    /// of Ψ). The source becomes [`MappingSource::Manual`] unless `overrides` is empty.
    pub fn with_overrides(
        mut self,
        overrides: &[(usize, Option<EndEffector>)],
    ) -> Result<Correspondence, CorrespondenceError> {
        let count = self.mapping.human.len();
        for &(index, human) in overrides {
            let slot = self
                .mapping
                .human
                .get_mut(index)
                .ok_or(CorrespondenceError::NoSuchEndEffector { index, count })?;
            *slot = human;
            self.source = MappingSource::Manual;
        }
        Ok(self)
    }

    /// Index of the character end effector on link `name`.
    pub fn link_index(&self, name: &str) -> Option<usize> {
        self.character_links.iter().position(|l| l == name)
    }

    /// The KL minimum for character end effector `j` (what [`Correspondence::automatic`] chose),
    /// `None` without scores.
    pub fn automatic_choice(&self, j: usize) -> Option<EndEffector> {
        self.scores.get(j).and_then(|row| argmin(row))
    }
}

/// The human end effector of the least finite score.
fn argmin(row: &[f64]) -> Option<EndEffector> {
    row.iter()
        .enumerate()
        .filter(|(_, s)| s.is_finite())
        .fold(None, |best: Option<(usize, f64)>, (i, &s)| match best {
            Some((_, b)) if b <= s => best,
            _ => Some((i, s)),
        })
        .map(|(i, _)| EndEffector::ALL[i])
}

impl fmt::Display for Correspondence {
    /// A table: one row per character end effector, one column of KL scores per human end effector,
    /// `*` before the chosen one; rows set by the user say what the automatic choice was.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let source = match self.source {
            MappingSource::Automatic => "automatic",
            MappingSource::Manual => "manual",
        };
        writeln!(
            f,
            "end-effector correspondence ({source}): KL(character || human) of positions in body lengths, \
             * = chosen"
        )?;
        let width = self
            .character_links
            .iter()
            .map(|l| l.len())
            .chain([9])
            .max()
            .unwrap_or(9);
        write!(f, "{:<width$}", "character")?;
        for e in EndEffector::ALL {
            write!(f, " {:>11}", e.name())?;
        }
        writeln!(f)?;
        for (j, link) in self.character_links.iter().enumerate() {
            let chosen = self.mapping.human.get(j).copied().flatten();
            write!(f, "{link:<width$}")?;
            for (i, e) in EndEffector::ALL.into_iter().enumerate() {
                let mark = if chosen == Some(e) { "*" } else { "" };
                let cell = match self.scores.get(j).and_then(|r| r.get(i)) {
                    Some(s) => format!("{mark}{}", score(*s)),
                    None => format!("{mark}-"),
                };
                write!(f, " {cell:>11}")?;
            }
            let auto = self.automatic_choice(j);
            match chosen {
                None => write!(f, "  unmapped")?,
                Some(_) if auto.is_some() && auto != chosen => {
                    write!(f, "  manual (automatic: {})", auto.map_or("-", |e| e.name()))?
                }
                Some(_) => {}
            }
            writeln!(f)?;
        }
        Ok(())
    }
}

/// A score with three significant digits after the point for small values, fewer for large ones
/// (an infinite one prints as `inf`).
fn score(s: f64) -> String {
    match s {
        s if s < 100.0 => format!("{s:.3}"),
        s if s < 10_000.0 => format!("{s:.1}"),
        s => format!("{s:.3e}"),
    }
}

#[cfg(test)]
mod tests {
    use std::path::PathBuf;

    use nalgebra::Rotation3;
    use rand::{RngExt, SeedableRng};
    use rand_pcg::Pcg64;

    use super::*;
    use crate::dataset::{DatasetConfig, generate};
    use crate::features::{character_body_length, human_body_length};
    use crate::human::{HumanClip, ImportOptions};
    use crate::morphology::load_character;

    use EndEffector::*;

    /// A standard normal sample (Box–Muller).
    fn normal(rng: &mut Pcg64) -> f64 {
        let u: f64 = 1.0 - rng.random::<f64>();
        let v: f64 = rng.random::<f64>();
        (-2.0 * u.ln()).sqrt() * (std::f64::consts::TAU * v).cos()
    }

    /// `n` points around `mean` with independent standard deviations `sd` per axis.
    fn cloud(rng: &mut Pcg64, n: usize, mean: [f64; 3], sd: [f64; 3]) -> Vec<[f32; 3]> {
        (0..n)
            .map(|_| std::array::from_fn(|k| (mean[k] + sd[k] * normal(rng)) as f32))
            .collect()
    }

    fn stats(names: &[&str], clouds: &[Vec<[f32; 3]>]) -> EndEffectorStats {
        let mut s = EndEffectorStats::new(names.iter().map(|n| n.to_string()).collect());
        for (m, c) in s.moments.iter_mut().zip(clouds) {
            c.iter().for_each(|&p| m.push(p));
        }
        s
    }

    fn diag(v: [f64; 3]) -> Matrix3<f64> {
        Matrix3::from_diagonal(&Vector3::from(v))
    }

    #[test]
    fn moments_match_a_two_pass_fit_and_skip_non_finite_points() {
        let mut rng = Pcg64::seed_from_u64(3);
        let mut pts = cloud(&mut rng, 500, [0.2, -0.4, 1.5], [0.3, 0.05, 0.1]);
        // Correlate x and z so that an off-diagonal term is checked too.
        for p in &mut pts {
            p[2] += 0.5 * p[0];
        }
        let mut m = PositionMoments::default();
        pts.iter().for_each(|&p| m.push(p));
        m.push([f32::NAN, 0.0, 0.0]);
        m.push([0.0, f32::INFINITY, 0.0]);
        assert_eq!(m.count(), 500);

        let n = pts.len() as f64;
        let v = |p: &[f32; 3]| Vector3::new(f64::from(p[0]), f64::from(p[1]), f64::from(p[2]));
        let mean = pts.iter().map(v).sum::<Vector3<f64>>() / n;
        let cov = pts
            .iter()
            .map(|p| (v(p) - mean) * (v(p) - mean).transpose())
            .sum::<Matrix3<f64>>()
            / n;
        assert!((m.mean() - mean).norm() < 1e-12);
        assert!((m.covariance() - cov).norm() < 1e-12);
        assert!(cov[(0, 2)] > 0.02, "the test cloud should be correlated: {cov}");
        let g = m.gaussian(COVARIANCE_FLOOR).unwrap();
        assert!((g.covariance - cov - Matrix3::identity() * COVARIANCE_FLOOR).norm() < 1e-12);
        assert!(PositionMoments::default().gaussian(COVARIANCE_FLOOR).is_none());
    }

    #[test]
    fn two_points_have_a_covariance_one_or_none_have_none() {
        let mut m = PositionMoments::default();
        assert_eq!(m.covariance(), Matrix3::zeros());
        m.push([1.0, -1.0, 0.5]);
        assert_eq!(m.covariance(), Matrix3::zeros());
        m.push([3.0, 3.0, -0.5]);
        // Two points d apart: the population covariance is d·dᵀ / 4.
        let d = Vector3::new(2.0, 4.0, -1.0);
        assert!((m.covariance() - d * d.transpose() / 4.0).norm() < 1e-12, "{}", m.covariance());
    }

    /// Positions are compared under a blur of [`POSITION_RESOLUTION`] body lengths: two end effectors
    /// that never move, that far apart, are half a nat apart.
    #[test]
    fn still_end_effectors_a_resolution_apart_are_half_a_nat_apart() {
        let still = |x: f32| {
            let mut m = PositionMoments::default();
            (0..10).for_each(|_| m.push([x, 0.0, 0.0]));
            m.gaussian(COVARIANCE_FLOOR).unwrap()
        };
        let kl = still(0.0).kl_divergence(&still(POSITION_RESOLUTION as f32));
        assert!((kl - 0.5).abs() < 1e-6, "{kl}");
        assert!((POSITION_RESOLUTION - 0.15).abs() < 1e-12);
    }

    /// Both sides' positions are divided by their body lengths, on every axis: a body twice as long
    /// halves every mean and quarters every variance.
    #[test]
    fn positions_are_read_in_body_lengths() {
        let halves = |a: &EndEffectorStats, b: &EndEffectorStats| {
            for (x, y) in a.moments.iter().zip(&b.moments) {
                assert!((x.mean() - 2.0 * y.mean()).norm() < 1e-5 * x.mean().norm().max(1.0), "{} vs {}", x.mean(), y.mean());
                assert!((x.covariance() - 4.0 * y.covariance()).norm() < 1e-5 * x.covariance().norm().max(1e-3));
            }
            // Some end effector sits off the origin on every axis, so every axis is checked.
            assert!((0..3).all(|k| a.moments.iter().any(|m| m.mean()[k].abs() > 0.01)));
        };
        let path = assets().join("motions/walk.bvh");
        let clip = HumanClip::from_bvh_file(&path, &ImportOptions::default()).unwrap();
        let states = clip.states();
        let rows = || states.iter().map(|s| s.as_slice());
        let body = human_body_length(&clip);
        halves(&EndEffectorStats::from_human_states(rows(), body), &EndEffectorStats::from_human_states(rows(), 2.0 * body));

        let (tree, morph) = load_character(&assets().join("characters/spot.urdf")).unwrap();
        let cfg = DatasetConfig { frames: 300, seed: 5, ..DatasetConfig::default() };
        let set = generate(&tree, &morph, &cfg, &mut |_| {}).unwrap();
        let body = character_body_length(&tree, &morph);
        halves(&EndEffectorStats::from_motion_set(&set, body), &EndEffectorStats::from_motion_set(&set, 2.0 * body));
    }

    #[test]
    fn kl_is_zero_for_itself_grows_with_a_shift_and_matches_the_per_axis_formula() {
        let cov = diag([0.04, 0.01, 0.09]);
        let g = Gaussian::new(Vector3::new(0.1, -0.2, 0.3), cov);
        assert!(g.kl_divergence(&g).abs() < 1e-12);

        // With equal covariances the KL is half the squared Mahalanobis distance of the shift.
        let mut last = 0.0;
        for step in 1..=5 {
            let d = Vector3::new(0.05 * step as f64, 0.0, 0.0);
            let shifted = Gaussian::new(g.mean + d, cov);
            let kl = g.kl_divergence(&shifted);
            assert!(kl > last, "KL must grow with the shift: {kl} after {last}");
            assert!((kl - 0.5 * d.x * d.x / cov[(0, 0)]).abs() < 1e-9);
            last = kl;
        }

        // Independent axes: the KL is the sum of 1-D KLs, and a common rotation does not change it.
        let (m0, v0): ([f64; 3], [f64; 3]) = ([0.0, 0.5, -0.2], [0.02, 0.3, 0.05]);
        let (m1, v1): ([f64; 3], [f64; 3]) = ([0.4, 0.1, 0.0], [0.1, 0.2, 0.01]);
        let one_d: f64 = (0..3)
            .map(|k| 0.5 * (v0[k] / v1[k] + (m1[k] - m0[k]).powi(2) / v1[k] - 1.0 + (v1[k] / v0[k]).ln()))
            .sum();
        let rot = Rotation3::from_euler_angles(0.3, -1.1, 2.0).into_inner();
        let rotated =
            |m: [f64; 3], v: [f64; 3]| Gaussian::new(rot * Vector3::from(m), rot * diag(v) * rot.transpose());
        let kl = rotated(m0, v0).kl_divergence(&rotated(m1, v1));
        assert!((kl - one_d).abs() < 1e-9, "{kl} vs {one_d}");
        // KL is not symmetric.
        let back = rotated(m1, v1).kl_divergence(&rotated(m0, v0));
        assert!((back - kl).abs() > 0.1);
        // A singular covariance has no density.
        let flat = Gaussian::new(Vector3::zeros(), diag([1.0, 1.0, 0.0]));
        assert_eq!(g.kl_divergence(&flat), f64::INFINITY);
    }

    /// A human-like set of clouds (body lengths, pelvis origin) and a hexapod-with-arm character.
    fn constructed() -> (EndEffectorStats, EndEffectorStats) {
        let mut rng = Pcg64::seed_from_u64(11);
        let human = stats(
            &EndEffector::ALL.map(|e| e.name()),
            &[
                cloud(&mut rng, 2000, [0.0, 0.06, -0.5], [0.12, 0.03, 0.03]),
                cloud(&mut rng, 2000, [0.0, -0.06, -0.5], [0.12, 0.03, 0.03]),
                cloud(&mut rng, 2000, [0.02, 0.12, -0.05], [0.08, 0.03, 0.08]),
                cloud(&mut rng, 2000, [0.05, -0.12, 0.0], [0.12, 0.05, 0.15]),
                cloud(&mut rng, 2000, [0.02, 0.0, 0.4], [0.03, 0.02, 0.02]),
            ],
        );
        let character = stats(
            &["lf", "lm", "lr", "rf", "rm", "rr", "arm", "camera"],
            &[
                cloud(&mut rng, 1500, [0.1, 0.09, -0.52], [0.1, 0.02, 0.02]),
                cloud(&mut rng, 1500, [0.0, 0.1, -0.5], [0.1, 0.02, 0.02]),
                cloud(&mut rng, 1500, [-0.1, 0.09, -0.52], [0.1, 0.02, 0.02]),
                cloud(&mut rng, 1500, [0.1, -0.09, -0.52], [0.1, 0.02, 0.02]),
                cloud(&mut rng, 1500, [0.0, -0.1, -0.5], [0.1, 0.02, 0.02]),
                cloud(&mut rng, 1500, [-0.1, -0.09, -0.52], [0.1, 0.02, 0.02]),
                cloud(&mut rng, 1500, [0.1, -0.1, 0.05], [0.1, 0.04, 0.1]),
                // A rigid camera: every sample the same.
                vec![[0.03, 0.0, 0.38]; 1500],
            ],
        );
        (character, human)
    }

    #[test]
    fn constructed_distributions_pick_the_obvious_pairs() {
        let (character, human) = constructed();
        let c = Correspondence::automatic(&character, &human).unwrap();
        println!("{c}");
        let want = [
            LeftFoot, LeftFoot, LeftFoot, RightFoot, RightFoot, RightFoot, RightHand, Head,
        ];
        assert_eq!(c.mapping.human, want.map(Some).to_vec());
        assert_eq!(c.source, MappingSource::Automatic);
        assert_eq!(c.scores.len(), 8);
        for (j, row) in c.scores.iter().enumerate() {
            assert_eq!(row.len(), 5);
            assert!(row.iter().all(|s| s.is_finite() && *s >= 0.0), "{row:?}");
            let chosen = want[j] as usize;
            assert!(row.iter().all(|&s| s >= row[chosen]));
        }
    }

    #[test]
    fn overrides_change_the_mapping_and_the_table_shows_both_choices() {
        let (character, human) = constructed();
        let auto = Correspondence::automatic(&character, &human).unwrap();
        let arm = auto.link_index("arm").unwrap();
        let cam = auto.link_index("camera").unwrap();
        let manual = auto
            .clone()
            .with_overrides(&[(arm, Some(LeftHand)), (cam, None)])
            .unwrap();
        assert_eq!(manual.source, MappingSource::Manual);
        assert_eq!(manual.mapping.human[arm], Some(LeftHand));
        assert_eq!(manual.mapping.human[cam], None);
        assert_eq!(manual.mapping.human[0], auto.mapping.human[0]);
        assert_eq!(manual.automatic_choice(arm), Some(RightHand));
        assert_eq!(manual.scores, auto.scores);
        assert_eq!(
            auto.clone().with_overrides(&[]).unwrap().source,
            MappingSource::Automatic
        );

        let err = auto.clone().with_overrides(&[(8, Some(Head))]).unwrap_err();
        assert_eq!(err, CorrespondenceError::NoSuchEndEffector { index: 8, count: 8 });
        assert!(err.to_string().contains("end effector 8"), "{err}");

        let table = manual.to_string();
        println!("{table}");
        let line = |name: &str| table.lines().find(|l| l.starts_with(name)).unwrap().to_string();
        assert!(table.lines().nth(1).unwrap().contains("right_hand"));
        let arm_line = line("arm");
        assert!(arm_line.contains("manual (automatic: right_hand)"), "{arm_line}");
        // The `*` sits in the left_hand column (the third score).
        let cells: Vec<&str> = arm_line.split_whitespace().collect();
        assert!(cells[3].starts_with('*'), "{arm_line}");
        assert_eq!(cells.iter().filter(|c| c.starts_with('*')).count(), 1);
        assert!(line("camera").ends_with("unmapped"));
        assert!(!line("camera").contains('*'));
        // A link left at its automatic choice says nothing more.
        assert!(!line("lf").contains("manual"), "{}", line("lf"));
        // Each cell is the score: three decimals below 100, one below 10,000, then exponential.
        assert_eq!(cells[3], format!("*{:.3}", manual.scores[arm][2]));
        assert!(manual.scores[arm][2] < 100.0);
        let shown = [f64::INFINITY, 99.9996, 100.0, 1234.56, 10_000.0, 23456.0].map(score);
        assert_eq!(shown, ["inf", "100.000", "100.0", "1234.6", "1.000e4", "2.346e4"].map(String::from));

        let json = serde_json::to_string(&manual).unwrap();
        let back: Correspondence = serde_json::from_str(&json).unwrap();
        assert_eq!(
            (&back.mapping, &back.character_links, back.source),
            (&manual.mapping, &manual.character_links, manual.source)
        );
        // JSON keeps scores to the last digit or so.
        for (a, b) in back.scores.iter().flatten().zip(manual.scores.iter().flatten()) {
            assert!((a - b).abs() <= 1e-12 * b.abs(), "{a} vs {b}");
        }
    }

    #[test]
    fn the_resolution_keeps_a_widely_moving_human_end_effector_from_taking_everything() {
        let mut rng = Pcg64::seed_from_u64(2);
        // A foot that stays put and a hand that moves a lot; the character's foot is off to the
        // front and below the human's, but much nearer to it than to the hand.
        let human = stats(
            &EndEffector::ALL.map(|e| e.name()),
            &[
                cloud(&mut rng, 3000, [0.0, 0.06, -0.5], [0.05, 0.02, 0.02]),
                cloud(&mut rng, 3000, [0.0, -0.06, -0.5], [0.05, 0.02, 0.02]),
                cloud(&mut rng, 3000, [0.0, 0.15, 0.0], [0.05, 0.02, 0.05]),
                cloud(&mut rng, 3000, [0.1, -0.15, 0.1], [0.2, 0.15, 0.25]),
                cloud(&mut rng, 3000, [0.0, 0.0, 0.4], [0.02, 0.02, 0.02]),
            ],
        );
        let foot = stats(
            &["foot"],
            &[cloud(&mut rng, 3000, [0.4, 0.15, -0.7], [0.1, 0.02, 0.02])],
        );
        let blurred = Correspondence::automatic(&foot, &human).unwrap();
        println!("{blurred}");
        assert_eq!(blurred.mapping.human, [Some(LeftFoot)]);
        let sharp = Correspondence::automatic_with_floor(&foot, &human, 1e-4).unwrap();
        println!("{sharp}");
        assert_eq!(sharp.mapping.human, [Some(RightHand)]);
        for bad in [0.0, -1.0, f64::NAN] {
            let err = Correspondence::automatic_with_floor(&foot, &human, bad).unwrap_err();
            assert!(matches!(err, CorrespondenceError::Floor(_)), "{err}");
        }
    }

    #[test]
    fn missing_samples_and_wrong_human_statistics_are_errors() {
        let (character, human) = constructed();
        let mut empty = character.clone();
        empty.moments[6] = PositionMoments::default();
        let err = Correspondence::automatic(&empty, &human).unwrap_err();
        assert!(err.to_string().contains("character end effector `arm`"), "{err}");
        let mut no_head = human.clone();
        no_head.moments[4] = PositionMoments::default();
        let err = Correspondence::automatic(&character, &no_head).unwrap_err();
        assert!(err.to_string().contains("human end effector `head`"), "{err}");
        let err = Correspondence::automatic(&character, &character).unwrap_err();
        assert!(matches!(err, CorrespondenceError::NotHuman(_)), "{err}");
    }

    fn assets() -> PathBuf {
        PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../assets")
    }

    /// x^h statistics of the bundled clips, each clip with its own body length.
    fn bundled_human() -> EndEffectorStats {
        let mut human = EndEffectorStats::human();
        let mut paths: Vec<PathBuf> = std::fs::read_dir(assets().join("motions"))
            .expect("assets/motions")
            .map(|e| e.unwrap().path())
            .filter(|p| p.extension().is_some_and(|x| x == "bvh"))
            .collect();
        paths.sort();
        assert!(!paths.is_empty(), "no bundled clips");
        for p in &paths {
            let clip =
                HumanClip::from_bvh_file(p, &ImportOptions::default()).unwrap_or_else(|e| panic!("{e}"));
            let states = clip.states();
            human.add_human_states(states.iter().map(|s| s.as_slice()), human_body_length(&clip));
        }
        human
    }

    /// End-effector statistics of a dataset of the bundled character `name`, with its manipulator
    /// links and foot count.
    fn bundled_character(name: &str, frames: usize) -> (EndEffectorStats, Vec<String>, usize) {
        let path = assets().join(format!("characters/{name}.urdf"));
        let (tree, morph) = load_character(&path).unwrap_or_else(|e| panic!("{e}"));
        let cfg = DatasetConfig {
            frames,
            seed: 5,
            episode_seconds: [4.0, 12.0],
            ..DatasetConfig::default()
        };
        let set = generate(&tree, &morph, &cfg, &mut |_| {}).unwrap_or_else(|e| panic!("{name}: {e}"));
        let stats = EndEffectorStats::from_motion_set(&set, character_body_length(&tree, &morph));
        let manipulators = morph
            .manipulators
            .iter()
            .map(|&l| tree.links[l].name.clone())
            .collect();
        (stats, manipulators, morph.feet.len())
    }

    fn print_means(label: &str, stats: &EndEffectorStats) {
        for (name, m) in stats.names.iter().zip(&stats.moments) {
            let (mu, sd) = (m.mean(), m.covariance().diagonal().map(f64::sqrt));
            println!(
                "  {label} {name:<16} mean ({:6.3} {:6.3} {:6.3})  sd ({:5.3} {:5.3} {:5.3})",
                mu.x, mu.y, mu.z, sd.x, sd.y, sd.z
            );
        }
    }

    /// Spot and Stretch must get feet → feet of their side and arms → hands. The crab is only
    /// printed: it is 0.18 m tall and 0.8 m wide, so in body lengths its feet stand two body lengths
    /// to the side, where no human end effector goes, and any choice among them is arbitrary.
    #[test]
    fn bundled_characters_get_a_sane_mapping_from_the_bundled_clips() {
        let human = bundled_human();
        print_means("human", &human);
        for name in ["spot", "crab", "stretch"] {
            let (character, manipulators, n_feet) = bundled_character(name, 3000);
            let c = Correspondence::automatic(&character, &human).unwrap_or_else(|e| panic!("{name}: {e}"));
            println!("{name}:");
            print_means(name, &character);
            println!("{c}");
            if name == "crab" {
                continue;
            }
            for (k, link) in character.names.iter().enumerate() {
                let h = c.mapping.human[k].unwrap();
                if k < n_feet {
                    let left = character.moments[k].mean().y > 0.0;
                    let want = if left { LeftFoot } else { RightFoot };
                    assert_eq!(h, want, "{name}: foot {link}");
                }
                if manipulators.contains(link) {
                    assert!(
                        matches!(h, LeftHand | RightHand),
                        "{name}: manipulator {link} ↦ {h:?}"
                    );
                }
            }
        }
    }
}
