//! Distribution metrics over feature vectors Ψ (paper §7.3): DIV (diversity) and FID (Fréchet
//! distance between Gaussian fits).

use nalgebra::{DMatrix, DVector, SymmetricEigen};
use rand::{RngExt, SeedableRng};
use rand_pcg::Pcg64;
use serde::{Deserialize, Serialize};

/// How DIV samples its pairs.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(default)]
pub struct DivConfig {
    /// Number of random pairs `S_d` (default 10 000: the estimate's relative standard error is then
    /// about 1 % or less for spread-out features).
    pub pairs: usize,
    /// Seed of the pair sampling (PCG64), so that runs compare.
    pub seed: u64,
}

impl Default for DivConfig {
    fn default() -> Self {
        DivConfig { pairs: 10_000, seed: 0 }
    }
}

/// DIV: the mean Euclidean distance `(1/S_d) Σ ‖Ψ_i − Ψ'_i‖` between the features of random pairs of
/// distinct frames. The pairs are drawn uniformly with the seeded generator; when the set has no more
/// distinct pairs than `config.pairs`, every pair is used once and the value is exact. 0 for fewer
/// than two frames.
pub fn diversity<R: AsRef<[f32]>>(features: &[R], config: &DivConfig) -> f32 {
    let n = features.len();
    if n < 2 || config.pairs == 0 {
        return 0.0;
    }
    let all = n * (n - 1) / 2;
    let pairs: Vec<(usize, usize)> = if all <= config.pairs {
        (0..n).flat_map(|i| (i + 1..n).map(move |j| (i, j))).collect()
    } else {
        let mut rng = Pcg64::seed_from_u64(config.seed);
        (0..config.pairs)
            .map(|_| {
                let i = rng.random_range(0..n);
                let j = rng.random_range(0..n - 1);
                (i, if j >= i { j + 1 } else { j })
            })
            .collect()
    };
    diversity_of_pairs(features, &pairs)
}

/// The mean Euclidean distance between the features of the given pairs of frames (0 for no pairs).
pub fn diversity_of_pairs<R: AsRef<[f32]>>(features: &[R], pairs: &[(usize, usize)]) -> f32 {
    if pairs.is_empty() {
        return 0.0;
    }
    let sum: f64 = pairs
        .iter()
        .map(|&(i, j)| {
            let (a, b) = (features[i].as_ref(), features[j].as_ref());
            assert_eq!(a.len(), b.len(), "feature rows differ in width");
            a.iter()
                .zip(b)
                .map(|(x, y)| f64::from(x - y).powi(2))
                .sum::<f64>()
                .sqrt()
        })
        .sum();
    (sum / pairs.len() as f64) as f32
}

/// A Gaussian fitted to a set of feature vectors (in f64): sample mean and unbiased covariance.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct GaussianFit {
    /// Number of samples.
    pub n: usize,
    /// Mean.
    pub mean: DVector<f64>,
    /// Covariance (divided by n − 1; zero for fewer than two samples).
    pub cov: DMatrix<f64>,
}

impl GaussianFit {
    /// Fits rows of equal width (two passes: the mean, then the centred covariance).
    ///
    /// # Panics
    /// If there are no rows or they differ in width.
    pub fn fit<R: AsRef<[f32]>>(rows: &[R]) -> Self {
        assert!(!rows.is_empty(), "cannot fit a Gaussian to no samples");
        let d = rows[0].as_ref().len();
        let n = rows.len();
        let mut mean = DVector::<f64>::zeros(d);
        for r in rows {
            let r = r.as_ref();
            assert_eq!(r.len(), d, "feature rows differ in width");
            for (m, &x) in mean.iter_mut().zip(r) {
                *m += f64::from(x);
            }
        }
        mean /= n as f64;
        // Centred rows in blocks, accumulated as Xᵀ·X (a matrix product, fast for 200k rows).
        const BLOCK: usize = 4096;
        let mut cov = DMatrix::<f64>::zeros(d, d);
        let mut x = DMatrix::<f64>::zeros(BLOCK.min(n), d);
        for chunk in rows.chunks(BLOCK) {
            if chunk.len() != x.nrows() {
                x = DMatrix::zeros(chunk.len(), d);
            }
            for (i, r) in chunk.iter().enumerate() {
                for (k, &v) in r.as_ref().iter().enumerate() {
                    x[(i, k)] = f64::from(v) - mean[k];
                }
            }
            cov.gemm_tr(1.0, &x, &x, 1.0);
        }
        if n > 1 {
            cov /= (n - 1) as f64;
        } else {
            cov.fill(0.0);
        }
        cov = (&cov + cov.transpose()) * 0.5;
        GaussianFit { n, mean, cov }
    }

    /// Dimension of the features.
    pub fn dim(&self) -> usize {
        self.mean.len()
    }

    /// The marginal Gaussian of the entries `range` (its mean and covariance block).
    ///
    /// # Panics
    /// If `range` reaches past [`GaussianFit::dim`].
    pub fn marginal(&self, range: std::ops::Range<usize>) -> GaussianFit {
        let len = range.len();
        GaussianFit {
            n: self.n,
            mean: self.mean.rows(range.start, len).into_owned(),
            cov: self.cov.view((range.start, range.start), (len, len)).into_owned(),
        }
    }
}

/// The square root of a symmetric positive semi-definite matrix through its eigen decomposition
/// (`V·diag(√λ)·Vᵀ`, negative eigenvalues from round-off clamped to 0). Only the lower triangle of
/// `m` is read.
pub fn sqrt_psd(m: &DMatrix<f64>) -> DMatrix<f64> {
    let e = SymmetricEigen::new(m.clone());
    let s = e.eigenvalues.map(|l| l.max(0.0).sqrt());
    &e.eigenvectors * DMatrix::from_diagonal(&s) * e.eigenvectors.transpose()
}

/// The Fréchet distance between two Gaussians:
/// `‖μ₁−μ₂‖² + tr(Σ₁) + tr(Σ₂) − 2·tr((Σ₁^{1/2} Σ₂ Σ₁^{1/2})^{1/2})`. The symmetric form of the
/// cross term (equal in trace to `(Σ₁Σ₂)^{1/2}`) keeps every square root that of a symmetric PSD
/// matrix, so it is stable; the result is clamped at 0.
///
/// # Panics
/// If the dimensions differ.
pub fn frechet_distance(a: &GaussianFit, b: &GaussianFit) -> f64 {
    assert_eq!(a.dim(), b.dim(), "Gaussians of different dimensions");
    let s1 = sqrt_psd(&a.cov);
    let m = &s1 * &b.cov * &s1;
    let m = (&m + m.transpose()) * 0.5;
    let cross: f64 = SymmetricEigen::new(m)
        .eigenvalues
        .iter()
        .map(|l| l.max(0.0).sqrt())
        .sum();
    let d = (&a.mean - &b.mean).norm_squared() + a.cov.trace() + b.cov.trace() - 2.0 * cross;
    d.max(0.0)
}

/// FID between two feature sets: [`frechet_distance`] of their [`GaussianFit`]s.
pub fn fid<R: AsRef<[f32]>, S: AsRef<[f32]>>(a: &[R], b: &[S]) -> f64 {
    frechet_distance(&GaussianFit::fit(a), &GaussianFit::fit(b))
}
