//! Network building blocks: a plain MLP ([`Mlp`]) and the mode-adaptive neural network ([`Mann`],
//! Zhang et al. 2018) that the motion prior's decoder π is made of.
//!
//! Parameters are initialised from a caller-supplied random generator (a seeded PCG in practice), not
//! from libtorch's process-wide generator, so that building a network is reproducible even when other
//! code draws random tensors on other threads at the same time. The distribution is PyTorch's default
//! for linear layers: weights and biases uniform in ±1/√fan_in.

use rand::{Rng, RngExt};
use serde::{Deserialize, Serialize};
use tch::{Device, Kind, Tensor, nn};

/// The non-linearity between the layers of a network.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Activation {
    /// `max(x, slope·x)`; the paper's encoder and generator use it (slope 0.2 here).
    LeakyRelu(f64),
    /// `x·sigmoid(x)`; the paper's discriminator.
    Silu,
    /// `x` for `x > 0`, `eˣ − 1` otherwise; MANN's choice.
    Elu,
}

impl Activation {
    /// Leaky ReLU with slope 0.2 on the negative side.
    pub const LEAKY_RELU: Activation = Activation::LeakyRelu(0.2);

    /// Applies the activation element-wise.
    pub fn apply(&self, x: &Tensor) -> Tensor {
        match *self {
            // Valid for slopes in [0, 1], where max(x, slope·x) is the leaky ReLU.
            Activation::LeakyRelu(slope) => x.maximum(&(x * slope)),
            Activation::Silu => x.silu(),
            Activation::Elu => x.elu(),
        }
    }
}

/// A `dims`-shaped tensor uniform in `[−bound, bound)`, drawn from `rng`.
fn uniform<R: Rng + ?Sized>(rng: &mut R, dims: &[i64], bound: f64, device: Device) -> Tensor {
    let n: i64 = dims.iter().product();
    let values: Vec<f32> = (0..n)
        .map(|_| ((rng.random::<f64>() * 2.0 - 1.0) * bound) as f32)
        .collect();
    Tensor::from_slice(&values).view(dims).to_device(device)
}

/// A linear layer `x·Wᵀ + b` (weight `[out, in]` as in `tch::nn::Linear`) initialised from `rng`.
fn linear<R: Rng + ?Sized>(p: &nn::Path, input: usize, output: usize, rng: &mut R) -> nn::Linear {
    let bound = 1.0 / (input.max(1) as f64).sqrt();
    let (i, o) = (input as i64, output as i64);
    let ws = p.var_copy("weight", &uniform(rng, &[o, i], bound, p.device()));
    let bs = p.var_copy("bias", &uniform(rng, &[o], bound, p.device()));
    nn::Linear { ws, bs: Some(bs) }
}

/// A multi-layer perceptron: hidden linear layers each followed by the activation, then optionally a
/// linear output layer without activation. Variables are named `layer{i}/weight`, `layer{i}/bias` and
/// `out/weight`, `out/bias` under the path it is built in.
#[derive(Debug)]
pub struct Mlp {
    hidden: Vec<nn::Linear>,
    out: Option<nn::Linear>,
    activation: Activation,
    input: usize,
    output: usize,
}

impl Mlp {
    /// Builds the layers `input → hidden[0] → … → hidden[n−1] (→ output)` under `p`.
    pub fn new<R: Rng + ?Sized>(
        p: &nn::Path,
        input: usize,
        hidden: &[usize],
        activation: Activation,
        output: Option<usize>,
        rng: &mut R,
    ) -> Mlp {
        let mut layers = Vec::with_capacity(hidden.len());
        let mut width = input;
        for (i, &h) in hidden.iter().enumerate() {
            layers.push(linear(&(p / format!("layer{i}")), width, h, rng));
            width = h;
        }
        let out = output.map(|o| linear(&(p / "out"), width, o, rng));
        Mlp {
            hidden: layers,
            out,
            activation,
            input,
            output: output.unwrap_or(width),
        }
    }

    /// Width of the input.
    pub fn input_dim(&self) -> usize {
        self.input
    }

    /// Width of the output.
    pub fn output_dim(&self) -> usize {
        self.output
    }

    /// Runs the network on `[…, input]`, giving `[…, output]`.
    pub fn forward(&self, x: &Tensor) -> Tensor {
        let mut h = x.shallow_clone();
        for l in &self.hidden {
            h = self.activation.apply(&h.apply(l));
        }
        match &self.out {
            Some(o) => h.apply(o),
            None => h,
        }
    }
}

impl nn::Module for Mlp {
    fn forward(&self, xs: &Tensor) -> Tensor {
        Mlp::forward(self, xs)
    }
}

/// One layer of a mode-adaptive network: `K` expert weight matrices `[K, in, out]` and biases
/// `[K, out]`, blended per sample by coefficients α.
#[derive(Debug)]
pub struct ExpertLayer {
    /// Expert weights, `[K, in, out]`.
    pub weight: Tensor,
    /// Expert biases, `[K, out]`.
    pub bias: Tensor,
}

impl ExpertLayer {
    /// Builds `experts` experts mapping `input` to `output` values, as `weight` and `bias` under `p`.
    pub fn new<R: Rng + ?Sized>(
        p: &nn::Path,
        input: usize,
        output: usize,
        experts: usize,
        rng: &mut R,
    ) -> ExpertLayer {
        let bound = 1.0 / (input.max(1) as f64).sqrt();
        let (i, o, k) = (input as i64, output as i64, experts as i64);
        let weight = p.var_copy("weight", &uniform(rng, &[k, i, o], bound, p.device()));
        let bias = p.var_copy("bias", &uniform(rng, &[k, o], bound, p.device()));
        ExpertLayer { weight, bias }
    }

    /// `y_b = Σ_k α_bk (x_b W_k + b_k)` for `x: [B, in]`, `alpha: [B, K]`, giving `[B, out]`.
    ///
    /// Computed without a per-sample weight matrix: `Σ_k α_bk x_b W_k` is one matrix product of the
    /// `[B, K·in]` outer products `α_b ⊗ x_b` with the weights viewed as `[K·in, out]`, and the bias
    /// term is `α·b`. The cost is that of evaluating all K experts, `B·K·in·out` multiply-adds.
    pub fn forward(&self, x: &Tensor, alpha: &Tensor) -> Tensor {
        let (k, i, o) = self.weight.size3().expect("expert weights are [K, in, out]");
        let b = x.size()[0];
        let mixed = (alpha.unsqueeze(2) * x.unsqueeze(1)).view([b, k * i]);
        mixed.matmul(&self.weight.view([k * i, o])) + alpha.matmul(&self.bias)
    }

    /// Number of experts.
    pub fn experts(&self) -> usize {
        self.weight.size()[0] as usize
    }
}

/// Sizes of a [`Mann`].
#[derive(Clone, Debug, PartialEq)]
pub struct MannSpec {
    /// Width of the main input `x` (the previous state for the prior).
    pub input: usize,
    /// Width of the latent `z`, concatenated to the input of every layer.
    pub latent: usize,
    /// Width of the output.
    pub output: usize,
    /// Hidden layer widths of the main network (each an [`ExpertLayer`] followed by ELU).
    pub hidden: Vec<usize>,
    /// Number of experts K.
    pub experts: usize,
    /// Width of the gating network's input.
    pub gating_input: usize,
    /// Hidden layer widths of the gating network (ELU).
    pub gating_hidden: Vec<usize>,
}

/// A mode-adaptive neural network (Zhang et al. 2018) with a latent input as in MVAE (Ling et al.
/// 2020): a gating MLP maps its input to softmax coefficients α over K experts; every layer of the main
/// network is an [`ExpertLayer`] blended by α, with ELU between layers, and `z` concatenated to the
/// input of every layer. Variables: `gate/…` (an [`Mlp`]) and `layer{i}/weight`, `layer{i}/bias`
/// (the last one is the output layer).
#[derive(Debug)]
pub struct Mann {
    gate: Mlp,
    layers: Vec<ExpertLayer>,
    spec: MannSpec,
}

impl Mann {
    /// Builds the gating network and the expert layers under `p`.
    pub fn new<R: Rng + ?Sized>(p: &nn::Path, spec: &MannSpec, rng: &mut R) -> Mann {
        let gate = Mlp::new(
            &(p / "gate"),
            spec.gating_input,
            &spec.gating_hidden,
            Activation::Elu,
            Some(spec.experts),
            rng,
        );
        let widths: Vec<usize> = std::iter::once(spec.input)
            .chain(spec.hidden.iter().copied())
            .chain(std::iter::once(spec.output))
            .collect();
        let layers = widths
            .windows(2)
            .enumerate()
            .map(|(i, w)| {
                ExpertLayer::new(
                    &(p / format!("layer{i}")),
                    w[0] + spec.latent,
                    w[1],
                    spec.experts,
                    rng,
                )
            })
            .collect();
        Mann {
            gate,
            layers,
            spec: spec.clone(),
        }
    }

    /// The sizes it was built with.
    pub fn spec(&self) -> &MannSpec {
        &self.spec
    }

    /// The blending coefficients α `[B, K]` (rows sum to 1) for a gating input `[B, gating_input]`.
    pub fn coefficients(&self, gating_input: &Tensor) -> Tensor {
        self.gate.forward(gating_input).softmax(-1, Kind::Float)
    }

    /// The output `[B, output]` for latent `z: [B, latent]`, input `x: [B, input]` and gating input
    /// `g: [B, gating_input]`.
    pub fn forward(&self, z: &Tensor, x: &Tensor, g: &Tensor) -> Tensor {
        self.forward_with(z, x, &self.coefficients(g))
    }

    /// [`Mann::forward`] with given blending coefficients `alpha: [B, K]`.
    pub fn forward_with(&self, z: &Tensor, x: &Tensor, alpha: &Tensor) -> Tensor {
        let mut h = x.shallow_clone();
        let last = self.layers.len() - 1;
        for (i, layer) in self.layers.iter().enumerate() {
            h = layer.forward(&Tensor::cat(&[z, &h], 1), alpha);
            if i < last {
                h = h.elu();
            }
        }
        h
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::SeedableRng;
    use rand_pcg::Pcg64;

    fn rng(seed: u64) -> Pcg64 {
        Pcg64::seed_from_u64(seed)
    }

    #[test]
    fn activations_match_their_definitions() {
        let x = Tensor::from_slice(&[-2.0f32, -0.5, 0.0, 1.5]);
        let leaky = Vec::<f32>::try_from(Activation::LEAKY_RELU.apply(&x)).unwrap();
        assert_eq!(leaky, vec![-0.4, -0.1, 0.0, 1.5]);
        let elu = Vec::<f32>::try_from(Activation::Elu.apply(&x)).unwrap();
        assert!((elu[0] - ((-2.0f32).exp() - 1.0)).abs() < 1e-6 && elu[3] == 1.5);
        let silu = Vec::<f32>::try_from(Activation::Silu.apply(&x)).unwrap();
        assert!((silu[3] - 1.5 / (1.0 + (-1.5f32).exp())).abs() < 1e-6);
    }

    #[test]
    fn mlp_shapes_names_and_seeded_initialisation() {
        let build = |seed| {
            let vs = nn::VarStore::new(Device::Cpu);
            let m = Mlp::new(
                &(vs.root() / "enc"),
                10,
                &[16, 8],
                Activation::LEAKY_RELU,
                Some(3),
                &mut rng(seed),
            );
            (vs, m)
        };
        let (vs, m) = build(7);
        assert_eq!((m.input_dim(), m.output_dim()), (10, 3));
        let mut names: Vec<String> = vs.variables().into_keys().collect();
        names.sort();
        let expected = [
            "enc.layer0.bias",
            "enc.layer0.weight",
            "enc.layer1.bias",
            "enc.layer1.weight",
            "enc.out.bias",
            "enc.out.weight",
        ];
        assert_eq!(names, expected);
        let x = Tensor::randn([5, 10], (Kind::Float, Device::Cpu));
        assert_eq!(m.forward(&x).size(), vec![5, 3]);
        // Without an output layer the last hidden layer (activated) is the output.
        let vs2 = nn::VarStore::new(Device::Cpu);
        let h = Mlp::new(&vs2.root(), 10, &[4], Activation::Elu, None, &mut rng(1));
        assert_eq!(h.output_dim(), 4);
        assert!(h.forward(&x).min().double_value(&[]) >= -1.0);

        // The same seed gives the same weights, another seed other weights.
        let (vs_same, _) = build(7);
        let (vs_other, _) = build(8);
        let w = |vs: &nn::VarStore| vs.variables()["enc.layer0.weight"].shallow_clone();
        assert!(w(&vs).equal(&w(&vs_same)));
        assert!(!w(&vs).equal(&w(&vs_other)));
        let bound = 1.0 / 10f64.sqrt();
        assert!(w(&vs).abs().max().double_value(&[]) <= bound);
    }

    #[test]
    fn expert_blending_equals_the_per_sample_weighted_sum() {
        let vs = nn::VarStore::new(Device::Cpu);
        let (b, k, i, o) = (6, 4, 5, 3);
        let layer = ExpertLayer::new(&vs.root(), i, o, k, &mut rng(3));
        tch::manual_seed(11);
        let x = Tensor::randn([b, i as i64], (Kind::Float, Device::Cpu));
        let alpha = Tensor::randn([b, k as i64], (Kind::Float, Device::Cpu)).softmax(-1, Kind::Float);
        let y = layer.forward(&x, &alpha);
        assert_eq!(y.size(), vec![b, o as i64]);
        // By hand: for every sample, Σ_k α_k (x W_k + b_k) with scalar loops.
        let xv = Vec::<f32>::try_from(x.flatten(0, -1)).unwrap();
        let av = Vec::<f32>::try_from(alpha.flatten(0, -1)).unwrap();
        let wv = Vec::<f32>::try_from(layer.weight.flatten(0, -1)).unwrap();
        let bv = Vec::<f32>::try_from(layer.bias.flatten(0, -1)).unwrap();
        let yv = Vec::<f32>::try_from(y.flatten(0, -1)).unwrap();
        for s in 0..b as usize {
            for c in 0..o {
                let mut sum = 0.0f64;
                for e in 0..k {
                    let mut v = f64::from(bv[e * o + c]);
                    for r in 0..i {
                        v += f64::from(xv[s * i + r]) * f64::from(wv[(e * i + r) * o + c]);
                    }
                    sum += f64::from(av[s * k + e]) * v;
                }
                assert!(
                    (sum - f64::from(yv[s * o + c])).abs() < 1e-5,
                    "sample {s} output {c}"
                );
            }
        }
        // A one-hot α selects one expert exactly.
        let onehot = Tensor::zeros([b, k as i64], (Kind::Float, Device::Cpu));
        let _ = onehot.narrow(1, 2, 1).fill_(1.0);
        let expert2 = x.matmul(&layer.weight.get(2)) + layer.bias.get(2);
        assert!(layer.forward(&x, &onehot).allclose(&expert2, 1e-5, 1e-6, false));
    }

    #[test]
    fn mann_feeds_z_to_every_layer_and_blends_with_a_softmax_gate() {
        let vs = nn::VarStore::new(Device::Cpu);
        let spec = MannSpec {
            input: 7,
            latent: 4,
            output: 7,
            hidden: vec![12, 12],
            experts: 3,
            gating_input: 11,
            gating_hidden: vec![8],
        };
        let mann = Mann::new(&vs.root(), &spec, &mut rng(5));
        let vars = vs.variables();
        assert_eq!(vars["layer0.weight"].size(), vec![3, 7 + 4, 12]);
        assert_eq!(vars["layer1.weight"].size(), vec![3, 12 + 4, 12]);
        assert_eq!(vars["layer2.weight"].size(), vec![3, 12 + 4, 7]);
        assert_eq!(vars["gate.out.weight"].size(), vec![3, 8]);
        tch::manual_seed(2);
        let z = Tensor::randn([9, 4], (Kind::Float, Device::Cpu));
        let x = Tensor::randn([9, 7], (Kind::Float, Device::Cpu));
        let g = Tensor::cat(&[&z, &x], 1);
        let alpha = mann.coefficients(&g);
        assert_eq!(alpha.size(), vec![9, 3]);
        let ones = Tensor::ones([9], (Kind::Float, Device::Cpu));
        assert!(
            alpha
                .sum_dim_intlist(1, false, Kind::Float)
                .allclose(&ones, 1e-5, 1e-6, false)
        );
        let y = mann.forward(&z, &x, &g);
        assert_eq!(y.size(), vec![9, 7]);
        // z reaches the output layer directly: the gradient of the output w.r.t. the last layer's
        // z-rows of the weights is non-zero.
        y.sum(Kind::Float).backward();
        let grad = vars["layer2.weight"].grad();
        assert!(grad.narrow(1, 0, 4).abs().sum(Kind::Float).double_value(&[]) > 0.0);
    }
}
