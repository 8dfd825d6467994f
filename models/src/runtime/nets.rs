//! The trained networks in pure Rust, read from a checkpoint's safetensors files: the MLP of the
//! generator G and the gating network, and the mode-adaptive decoder π of the motion prior (experts
//! blended per sample). They compute what `learn::nets` (feature `learn`) computes with libtorch, in the same
//! order of operations: a linear layer is `x·Wᵀ + b`, an expert layer `(α ⊗ x)·W + α·b` (all K experts
//! in one matrix product, see `ExpertLayer::forward` there), leaky ReLU `max(x, 0.2·x)`, ELU with
//! `eˣ − 1` from `exp_m1`, softmax with the maximum subtracted.
//!
//! Batches are row-major `[rows, width]` slices. The matrix products are the `gemm` crate's, on the
//! calling thread: measured on these networks (Spot's sizes, all products of G and π, one thread,
//! release) it took 0.11 / 2.8 / 9.6 ms for 1 / 64 / 256 characters, against 0.96 / 3.6 / 11.4 ms for
//! `matrixmultiply` (which packs the weights on every call, costly at one row), 0.17 / 3.3 / 11.2 ms
//! for `nalgebra` (gemv for one row) and 0.15 / 3.6 / 10.3 ms for `candle-core`, whose build took two
//! minutes more.
//!
//! `gemm`'s AVX-512 kernels (its `x86-v4` feature, chosen at run time where the CPU has them) took
//! the shipped Spot's batch of 64 from 3.34 to 2.16 ms and of 256 from 12.7 to 7.5 ms on a later
//! machine of the same kind, level with libtorch; one character is bound by reading the weights.

use std::collections::BTreeMap;

use crate::checkpoint::files::Weights;

/// Weights `[k, n]`, row-major, that a batch multiplies from the left: `y = x·W`.
#[derive(Clone, Debug)]
struct Matrix {
    k: usize,
    n: usize,
    data: Vec<f32>,
}

impl Matrix {
    /// The stored `[out, in]` weight of a linear layer, transposed to `[in, out]` so that every product
    /// reads the weights in the same order.
    fn transposed(out: usize, input: usize, w: &[f32]) -> Matrix {
        let mut data = vec![0.0; w.len()];
        for o in 0..out {
            for i in 0..input {
                data[i * out + o] = w[o * input + i];
            }
        }
        Matrix { k: input, n: out, data }
    }
}

/// `out = x·w` (`accumulate`: `out += x·w`) for `x: [rows, w.k]`, `out: [rows, w.n]`, row-major, on
/// the calling thread.
fn matmul(x: &[f32], rows: usize, w: &Matrix, out: &mut [f32], accumulate: bool) {
    assert!(x.len() == rows * w.k && out.len() == rows * w.n && w.data.len() == w.k * w.n);
    // SAFETY: the assert above gives every pointer `rows·k`, `k·n` and `rows·n` valid elements for the
    // row-major strides passed (column stride 1, row stride the width); `out` does not alias the
    // inputs (a unique borrow). With no rows or no columns `gemm` returns before reading any.
    unsafe {
        gemm::gemm(
            rows,
            w.n,
            w.k,
            out.as_mut_ptr(),
            1,
            w.n as isize,
            accumulate,
            x.as_ptr(),
            1,
            w.k as isize,
            w.data.as_ptr(),
            1,
            w.n as isize,
            // out = 1·out + 1·x·w (out is not read without `accumulate`).
            1.0,
            1.0,
            false,
            false,
            false,
            gemm::Parallelism::None,
        );
    }
}

/// `[a | b]` row by row, for `a: [rows, wa]` and `b: [rows, wb]`.
fn concat(a: &[f32], wa: usize, b: &[f32], wb: usize, rows: usize) -> Vec<f32> {
    let mut out = Vec::with_capacity(rows * (wa + wb));
    for r in 0..rows {
        out.extend_from_slice(&a[r * wa..(r + 1) * wa]);
        out.extend_from_slice(&b[r * wb..(r + 1) * wb]);
    }
    out
}

/// The non-linearities of the inference networks (as `learn::nets::Activation` computes them).
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) enum Activation {
    /// `max(x, slope·x)` (G: slope 0.2).
    LeakyRelu(f32),
    /// `x` for `x > 0`, `eˣ − 1` otherwise (π and its gate).
    Elu,
}

impl Activation {
    fn apply(self, x: &mut [f32]) {
        match self {
            Activation::LeakyRelu(slope) => x.iter_mut().for_each(|v| *v = v.max(*v * slope)),
            Activation::Elu => x.iter_mut().filter(|v| **v <= 0.0).for_each(|v| *v = v.exp_m1()),
        }
    }
}

/// A linear layer `x·Wᵀ + b` (stored weight `[out, in]`, bias `[out]`).
#[derive(Clone, Debug)]
struct Linear {
    w: Matrix,
    b: Vec<f32>,
}

impl Linear {
    /// Weights and biases.
    fn parameters(&self) -> usize {
        self.w.data.len() + self.b.len()
    }

    fn shapes(shapes: &mut BTreeMap<String, Vec<usize>>, prefix: &str, input: usize, output: usize) {
        shapes.insert(format!("{prefix}.weight"), vec![output, input]);
        shapes.insert(format!("{prefix}.bias"), vec![output]);
    }

    fn read(weights: &Weights, prefix: &str) -> Linear {
        let (shape, w) = weights.get(&format!("{prefix}.weight"));
        let (_, b) = weights.get(&format!("{prefix}.bias"));
        Linear { w: Matrix::transposed(shape[0], shape[1], w), b: b.to_vec() }
    }

    fn forward(&self, x: &[f32], rows: usize) -> Vec<f32> {
        let mut out = Vec::with_capacity(rows * self.w.n);
        for _ in 0..rows {
            out.extend_from_slice(&self.b);
        }
        matmul(x, rows, &self.w, &mut out, true);
        out
    }
}

/// An MLP as `learn::nets::Mlp` stores it: `{prefix}.layer{i}` hidden layers each followed by
/// the activation, then the linear output layer `{prefix}.out`.
#[derive(Clone, Debug)]
pub(crate) struct Mlp {
    hidden: Vec<Linear>,
    out: Linear,
    activation: Activation,
}

impl Mlp {
    /// Adds the stored tensors' names and shapes of an MLP `input → hidden… → output` under `prefix`.
    pub(crate) fn shapes(
        shapes: &mut BTreeMap<String, Vec<usize>>,
        prefix: &str,
        input: usize,
        hidden: &[usize],
        output: usize,
    ) {
        let mut width = input;
        for (i, &h) in hidden.iter().enumerate() {
            Linear::shapes(shapes, &format!("{prefix}.layer{i}"), width, h);
            width = h;
        }
        Linear::shapes(shapes, &format!("{prefix}.out"), width, output);
    }

    /// The MLP under `prefix` of checked `weights` (see [`Mlp::shapes`]).
    pub(crate) fn read(weights: &Weights, prefix: &str, layers: usize, activation: Activation) -> Mlp {
        Mlp {
            hidden: (0..layers).map(|i| Linear::read(weights, &format!("{prefix}.layer{i}"))).collect(),
            out: Linear::read(weights, &format!("{prefix}.out")),
            activation,
        }
    }

    /// Weights and biases of every layer: each is read once per pass and used once per row.
    pub(crate) fn parameters(&self) -> usize {
        self.hidden.iter().chain([&self.out]).map(Linear::parameters).sum()
    }

    /// `[rows, output]` for `x: [rows, input]`.
    pub(crate) fn forward(&self, x: &[f32], rows: usize) -> Vec<f32> {
        let mut h = None::<Vec<f32>>;
        for l in &self.hidden {
            let mut y = l.forward(h.as_deref().unwrap_or(x), rows);
            self.activation.apply(&mut y);
            h = Some(y);
        }
        self.out.forward(h.as_deref().unwrap_or(x), rows)
    }
}

/// One layer of the mode-adaptive network: K experts' weights `[K, in, out]` and biases `[K, out]`.
#[derive(Clone, Debug)]
struct ExpertLayer {
    /// The weights viewed as `[K·in, out]`.
    w: Matrix,
    /// `[K, out]`.
    b: Matrix,
    experts: usize,
    input: usize,
}

impl ExpertLayer {
    /// `y_b = Σ_k α_bk (x_b W_k + b_k)` as `(α_b ⊗ x_b)·W + α_b·b`, for `x: [rows, in]`, `alpha: [rows, K]`.
    fn forward(&self, x: &[f32], alpha: &[f32], rows: usize) -> Vec<f32> {
        let (k, i) = (self.experts, self.input);
        let mut mixed = vec![0.0; rows * k * i];
        for r in 0..rows {
            let xr = &x[r * i..(r + 1) * i];
            for e in 0..k {
                let a = alpha[r * k + e];
                let dst = &mut mixed[(r * k + e) * i..(r * k + e + 1) * i];
                dst.iter_mut().zip(xr).for_each(|(d, v)| *d = a * v);
            }
        }
        let mut out = vec![0.0; rows * self.w.n];
        matmul(&mixed, rows, &self.w, &mut out, false);
        let mut bias = vec![0.0; rows * self.w.n];
        matmul(alpha, rows, &self.b, &mut bias, false);
        out.iter_mut().zip(&bias).for_each(|(o, b)| *o += b);
        out
    }
}

/// The sizes of the motion prior's decoder π.
#[derive(Clone, Debug, PartialEq)]
pub(crate) struct MannSizes {
    /// Width of the state x^r, π's input and output.
    pub state: usize,
    /// Width of z.
    pub latent: usize,
    /// Hidden widths of the main network.
    pub hidden: Vec<usize>,
    /// Experts K.
    pub experts: usize,
    /// Hidden widths of the gating network.
    pub gating_hidden: Vec<usize>,
}

/// The decoder π (see `learn::nets::Mann`): a softmax gate over `(z, x)` gives α, and every
/// expert layer sees `z` concatenated to its input, with ELU between layers. Stored under
/// `{prefix}.gate.…` and `{prefix}.layer{i}.weight`/`bias`.
#[derive(Clone, Debug)]
pub(crate) struct Mann {
    gate: Mlp,
    layers: Vec<ExpertLayer>,
    latent: usize,
}

impl Mann {
    fn widths(s: &MannSizes) -> Vec<usize> {
        std::iter::once(s.state).chain(s.hidden.iter().copied()).chain(std::iter::once(s.state)).collect()
    }

    /// Adds the stored tensors' names and shapes of π under `prefix`.
    pub(crate) fn shapes(shapes: &mut BTreeMap<String, Vec<usize>>, prefix: &str, s: &MannSizes) {
        Mlp::shapes(shapes, &format!("{prefix}.gate"), s.latent + s.state, &s.gating_hidden, s.experts);
        for (i, w) in Mann::widths(s).windows(2).enumerate() {
            shapes.insert(format!("{prefix}.layer{i}.weight"), vec![s.experts, w[0] + s.latent, w[1]]);
            shapes.insert(format!("{prefix}.layer{i}.bias"), vec![s.experts, w[1]]);
        }
    }

    /// π under `prefix` of checked `weights` (see [`Mann::shapes`]).
    pub(crate) fn read(weights: &Weights, prefix: &str, s: &MannSizes) -> Mann {
        let layers = Mann::widths(s)
            .windows(2)
            .enumerate()
            .map(|(i, w)| {
                let input = w[0] + s.latent;
                let (_, wv) = weights.get(&format!("{prefix}.layer{i}.weight"));
                let (_, bv) = weights.get(&format!("{prefix}.layer{i}.bias"));
                ExpertLayer {
                    w: Matrix { k: s.experts * input, n: w[1], data: wv.to_vec() },
                    b: Matrix { k: s.experts, n: w[1], data: bv.to_vec() },
                    experts: s.experts,
                    input,
                }
            })
            .collect();
        Mann {
            gate: Mlp::read(weights, &format!("{prefix}.gate"), s.gating_hidden.len(), Activation::Elu),
            layers,
            latent: s.latent,
        }
    }

    /// Weights and biases of the gate and of all K experts of every layer: each is read once per
    /// pass and used once per row (`ExpertLayer::forward` computes every expert for every row).
    pub(crate) fn parameters(&self) -> usize {
        self.gate.parameters() + self.layers.iter().map(|l| l.w.data.len() + l.b.data.len()).sum::<usize>()
    }

    /// The blending coefficients α `[rows, K]` for a gating input `[rows, latent + state]`.
    fn coefficients(&self, gate_input: &[f32], rows: usize) -> Vec<f32> {
        let mut a = self.gate.forward(gate_input, rows);
        let k = a.len() / rows.max(1);
        for row in a.chunks_exact_mut(k.max(1)) {
            let max = row.iter().copied().fold(f32::NEG_INFINITY, f32::max);
            row.iter_mut().for_each(|v| *v = (*v - max).exp());
            let sum: f32 = row.iter().sum();
            row.iter_mut().for_each(|v| *v /= sum);
        }
        a
    }

    /// The output `[rows, state]` for `z: [rows, latent]` and `x: [rows, state]` (the gate sees `[z | x]`).
    pub(crate) fn forward(&self, z: &[f32], x: &[f32], rows: usize) -> Vec<f32> {
        let width = x.len() / rows.max(1);
        let gate_input = concat(z, self.latent, x, width, rows);
        let alpha = self.coefficients(&gate_input, rows);
        let last = self.layers.len() - 1;
        let mut input = gate_input;
        let mut h = Vec::new();
        for (i, layer) in self.layers.iter().enumerate() {
            h = layer.forward(&input, &alpha, rows);
            if i < last {
                Activation::Elu.apply(&mut h);
                input = concat(z, self.latent, &h, h.len() / rows.max(1), rows);
            }
        }
        h
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A gate with no hidden layer whose logits are `x·W` for `W` `[input, K]` given row by row.
    fn gate(w: &[&[f32]]) -> Mann {
        let (input, k) = (w.len(), w[0].len());
        let out = Linear { w: Matrix { k: input, n: k, data: w.concat() }, b: vec![0.0; k] };
        Mann { gate: Mlp { hidden: Vec::new(), out, activation: Activation::Elu }, layers: Vec::new(), latent: 0 }
    }

    #[test]
    fn the_gate_blends_with_a_softmax_that_large_logits_do_not_overflow() {
        // Logits [100, 90, 0] (exp(100) overflows f32) and [1, 0, −1], two rows in one batch.
        let m = gate(&[&[100.0, 90.0, 0.0], &[1.0, 0.0, -1.0]]);
        let a = m.coefficients(&[1.0, 0.0, 0.0, 1.0], 2);
        assert!(a.iter().all(|v| v.is_finite()), "{a:?}");
        let softmax = |l: [f64; 3]| l.map(|v| v.exp() / l.iter().map(|u| u.exp()).sum::<f64>());
        let want: Vec<f64> = [softmax([0.0, -10.0, -100.0]), softmax([1.0, 0.0, -1.0])].concat();
        for (got, want) in a.iter().zip(&want) {
            assert!((*got as f64 - want).abs() < 1e-6, "{a:?} against {want:?}");
        }
    }

    #[test]
    fn a_batch_of_no_rows_gives_no_rows() {
        let w = Matrix { k: 2, n: 3, data: vec![1.0; 6] };
        let mut out = Vec::new();
        matmul(&[], 0, &w, &mut out, false);
        assert!(out.is_empty());
        let linear = Linear { w, b: vec![0.5; 3] };
        assert_eq!(linear.forward(&[1.0, 2.0], 1), vec![3.5; 3]);
        assert!(linear.forward(&[], 0).is_empty());
    }
}
