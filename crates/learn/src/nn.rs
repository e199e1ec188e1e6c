//! Run-time-sized layers on dfdx tensors: [`Linear`], the tanh [`Mlp`], and a tape-free
//! [`MlpInference`] copy of an MLP for fast batched rollouts.
//!
//! dfdx 0.13's `nn::Linear<I, O>` takes its sizes as const generics; ours come from a RON config,
//! so a layer here holds `Tensor<(usize, usize), f32, Cpu>` weights; models list their tensors
//! through [`Parameters`].

use dfdx::prelude::{Axis, BroadcastTo, Cpu, HasShape, Tape, Tensor, TensorFromVec, TryMatMul};
use rand::Rng;

/// A run-time-sized 2-D tensor on the CPU.
pub type Matrix<T = dfdx::prelude::NoneTape> = Tensor<(usize, usize), f32, Cpu, T>;
/// A run-time-sized 1-D tensor on the CPU.
pub type Vector<T = dfdx::prelude::NoneTape> = Tensor<(usize,), f32, Cpu, T>;

/// An affine layer `y = x·W + b` with `W` stored as `[in × out]`.
#[derive(Clone, Debug)]
pub struct Linear {
    /// Weights, `[in × out]`.
    pub weight: Matrix,
    /// Bias, `[out]`.
    pub bias: Vector,
}

impl Linear {
    /// A layer with weights drawn from `U(-gain/√in, gain/√in)` and zero bias.
    pub fn new(dev: &Cpu, inputs: usize, outputs: usize, gain: f32, rng: &mut impl Rng) -> Self {
        let bound = gain / (inputs as f32).sqrt();
        let w: Vec<f32> = (0..inputs * outputs).map(|_| rng.random_range(-bound..=bound)).collect();
        Linear {
            weight: dev.tensor_from_vec(w, (inputs, outputs)),
            bias: dev.tensor_from_vec(vec![0.0; outputs], (outputs,)),
        }
    }

    /// Input width.
    pub fn inputs(&self) -> usize {
        self.weight.shape().0
    }

    /// Output width.
    pub fn outputs(&self) -> usize {
        self.weight.shape().1
    }

    /// `x·W + b` for a batch `x: [B × in]`, recording on `x`'s tape if it has one.
    pub fn forward<T: Tape<f32, Cpu>>(&self, x: Matrix<T>) -> Matrix<T> {
        let batch = x.shape().0;
        let shape = (batch, self.outputs());
        let xw = x.matmul(self.weight.clone());
        xw + self.bias.clone().broadcast_like::<_, Axis<0>>(&shape)
    }
}

/// A mutable view of one trainable tensor: a matrix or a vector.
#[derive(Debug)]
pub enum ParamMut<'a> {
    /// A 2-D weight.
    Matrix(&'a mut Matrix),
    /// A 1-D bias or log-std.
    Vector(&'a mut Vector),
}

impl ParamMut<'_> {
    /// The tensor's shape.
    pub fn dims(&self) -> Vec<usize> {
        match self {
            ParamMut::Matrix(t) => vec![t.shape().0, t.shape().1],
            ParamMut::Vector(t) => vec![t.shape().0],
        }
    }

    /// A copy of the values, row-major.
    pub fn values(&self) -> Vec<f32> {
        match self {
            ParamMut::Matrix(t) => t.as_vec(),
            ParamMut::Vector(t) => t.as_vec(),
        }
    }

    /// Overwrite the values (row-major; `src.len()` must equal the element count).
    pub fn set_values(&mut self, src: &[f32]) {
        match self {
            ParamMut::Matrix(t) => t.copy_from(src),
            ParamMut::Vector(t) => t.copy_from(src),
        }
    }
}

/// Anything that owns trainable tensors: lists them, in a fixed order, with stable names.
///
/// dfdx 0.13's `TensorCollection` cannot describe tensors of run-time shape (its
/// `TensorOptions` is `#[non_exhaustive]` and every constructor needs `S: ConstShape`), so the
/// optimiser, gradient clipping and checkpoints walk models through this trait instead.
pub trait Parameters {
    /// Every trainable tensor with its name, e.g. `("layers.0.weight", …)`.
    fn params_mut(&mut self) -> Vec<(String, ParamMut<'_>)>;
}

impl Parameters for Linear {
    fn params_mut(&mut self) -> Vec<(String, ParamMut<'_>)> {
        vec![("weight".into(), ParamMut::Matrix(&mut self.weight)), ("bias".into(), ParamMut::Vector(&mut self.bias))]
    }
}

/// Prefix every name of `inner` with `prefix.` (for nesting [`Parameters`]).
pub fn prefixed<'a>(prefix: &str, inner: Vec<(String, ParamMut<'a>)>) -> Vec<(String, ParamMut<'a>)> {
    inner.into_iter().map(|(n, p)| (format!("{prefix}.{n}"), p)).collect()
}

/// A multi-layer perceptron with tanh between layers and a linear output.
#[derive(Clone, Debug)]
pub struct Mlp {
    /// The layers, input first.
    pub layers: Vec<Linear>,
}

impl Mlp {
    /// An MLP `inputs → hidden[0] → … → outputs`; the last layer's init is scaled by `out_gain`.
    pub fn new(dev: &Cpu, inputs: usize, hidden: &[usize], outputs: usize, out_gain: f32, rng: &mut impl Rng) -> Self {
        let mut widths = vec![inputs];
        widths.extend_from_slice(hidden);
        widths.push(outputs);
        let n = widths.len() - 1;
        let layers = (0..n)
            .map(|i| {
                let gain = if i + 1 == n { out_gain } else { 1.0 };
                Linear::new(dev, widths[i], widths[i + 1], gain, rng)
            })
            .collect();
        Mlp { layers }
    }

    /// Input width.
    pub fn inputs(&self) -> usize {
        self.layers[0].inputs()
    }

    /// Output width.
    pub fn outputs(&self) -> usize {
        self.layers[self.layers.len() - 1].outputs()
    }

    /// Forward a batch `[B × in] → [B × out]` on dfdx (records on `x`'s tape if it has one).
    pub fn forward<T: Tape<f32, Cpu>>(&self, x: Matrix<T>) -> Matrix<T> {
        let last = self.layers.len() - 1;
        let mut h = x;
        for (i, layer) in self.layers.iter().enumerate() {
            h = layer.forward(h);
            if i != last {
                h = h.tanh();
            }
        }
        h
    }

    /// A tape-free plain-`f32` copy of the current weights for rollouts.
    pub fn inference(&self) -> MlpInference {
        MlpInference {
            layers: self.layers.iter().map(|l| (l.inputs(), l.outputs(), l.weight.as_vec(), l.bias.as_vec())).collect(),
            scratch: [Vec::new(), Vec::new()],
        }
    }
}

impl Parameters for Mlp {
    fn params_mut(&mut self) -> Vec<(String, ParamMut<'_>)> {
        let mut out = Vec::new();
        for (i, layer) in self.layers.iter_mut().enumerate() {
            out.extend(prefixed(&format!("layers.{i}"), layer.params_mut()));
        }
        out
    }
}

/// Plain-`f32` weights of an [`Mlp`] and scratch space: batched forward passes with no tape and no
/// allocation once the scratch has grown to the batch size.
#[derive(Clone, Debug)]
pub struct MlpInference {
    /// `(in, out, W [in × out], b [out])` per layer.
    layers: Vec<(usize, usize, Vec<f32>, Vec<f32>)>,
    scratch: [Vec<f32>; 2],
}

impl MlpInference {
    /// Builds from `(in, out, W [in × out] row-major, b [out])` per layer, input first; `Err`
    /// says which layer does not fit.
    pub fn from_layers(layers: Vec<(usize, usize, Vec<f32>, Vec<f32>)>) -> Result<Self, ShapeError> {
        if layers.is_empty() {
            return Err(ShapeError::NoLayers);
        }
        for (i, (inputs, outputs, w, b)) in layers.iter().enumerate() {
            if w.len() != inputs * outputs || b.len() != *outputs {
                return Err(ShapeError::Weights {
                    layer: i,
                    inputs: *inputs,
                    outputs: *outputs,
                    weights: w.len(),
                    biases: b.len(),
                });
            }
            if i > 0 && layers[i - 1].1 != *inputs {
                return Err(ShapeError::Chain { layer: i, inputs: *inputs, before: layers[i - 1].1 });
            }
            if w.iter().chain(b).any(|v| !v.is_finite()) {
                return Err(ShapeError::NotFinite { layer: i });
            }
        }
        Ok(MlpInference { layers, scratch: [Vec::new(), Vec::new()] })
    }

    /// The layers as `(in, out, W, b)`, input first.
    pub fn layers(&self) -> &[(usize, usize, Vec<f32>, Vec<f32>)] {
        &self.layers
    }

    /// Input width.
    pub fn inputs(&self) -> usize {
        self.layers.first().map_or(0, |l| l.0)
    }

    /// Output width.
    pub fn outputs(&self) -> usize {
        self.layers.last().map_or(0, |l| l.1)
    }

    /// Forward `x: [B × in]` into `out: [B × out]`.
    pub fn forward(&mut self, x: &[f32], out: &mut [f32]) {
        let n_layers = self.layers.len();
        let batch = x.len() / self.layers[0].0;
        let [a, b] = &mut self.scratch;
        a.clear();
        a.extend_from_slice(x);
        for (i, (inputs, outputs, w, bias)) in self.layers.iter().enumerate() {
            b.clear();
            b.resize(batch * outputs, 0.0);
            let (inputs, outputs) = (*inputs, *outputs);
            // Rows in blocks of four, so each weight row is loaded once per four rows.
            let mut x_blocks = a.chunks_exact(4 * inputs);
            let mut y_blocks = b.chunks_exact_mut(4 * outputs);
            for (xb, yb) in (&mut x_blocks).zip(&mut y_blocks) {
                affine4_dispatch(xb, yb, w, bias, inputs, outputs);
            }
            for (xr, yr) in
                x_blocks.remainder().chunks_exact(inputs).zip(y_blocks.into_remainder().chunks_exact_mut(outputs))
            {
                affine1(xr, yr, w, bias, outputs);
            }
            if i + 1 != n_layers {
                b.iter_mut().for_each(|y| *y = y.tanh());
            }
            std::mem::swap(a, b);
        }
        out.copy_from_slice(&a[..out.len()]);
    }
}

/// [`affine4`] compiled for AVX2 when the CPU has it (the same arithmetic, so the same bits:
/// Rust never fuses the multiply and add on its own), SSE2 otherwise.
fn affine4_dispatch(x: &[f32], y: &mut [f32], w: &[f32], bias: &[f32], inputs: usize, outputs: usize) {
    #[cfg(target_arch = "x86_64")]
    if std::is_x86_feature_detected!("avx2") {
        // SAFETY: the running CPU supports AVX2, checked just above.
        return unsafe { affine4_avx2(x, y, w, bias, inputs, outputs) };
    }
    affine4(x, y, w, bias, inputs, outputs);
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
fn affine4_avx2(x: &[f32], y: &mut [f32], w: &[f32], bias: &[f32], inputs: usize, outputs: usize) {
    affine4(x, y, w, bias, inputs, outputs);
}

/// `y[r] = b + x[r]·W` for four rows at once (`x: [4 × inputs]`, `W: [inputs × outputs]`), in
/// column tiles of [`TILE`] whose 4 × `TILE` sums stay in registers over the whole `k` loop.
#[inline(always)]
fn affine4(x: &[f32], y: &mut [f32], w: &[f32], bias: &[f32], inputs: usize, outputs: usize) {
    let (x0, x1, x2, x3) =
        (&x[..inputs], &x[inputs..2 * inputs], &x[2 * inputs..3 * inputs], &x[3 * inputs..4 * inputs]);
    let mut j0 = 0;
    while j0 < outputs {
        let width = TILE.min(outputs - j0);
        let mut acc = [[0.0f32; TILE]; 4];
        for row in &mut acc {
            row[..width].copy_from_slice(&bias[j0..j0 + width]);
        }
        if width == TILE {
            for k in 0..inputs {
                let wk: &[f32; TILE] = w[k * outputs + j0..k * outputs + j0 + TILE].try_into().expect("a full tile");
                let xs = [x0[k], x1[k], x2[k], x3[k]];
                for (row, &xr) in acc.iter_mut().zip(&xs) {
                    for (a, &wv) in row.iter_mut().zip(wk) {
                        *a += xr * wv;
                    }
                }
            }
        } else {
            for k in 0..inputs {
                let wk = &w[k * outputs + j0..k * outputs + j0 + width];
                let xs = [x0[k], x1[k], x2[k], x3[k]];
                for (row, &xr) in acc.iter_mut().zip(&xs) {
                    for (a, &wv) in row.iter_mut().zip(wk) {
                        *a += xr * wv;
                    }
                }
            }
        }
        for (r, row) in acc.iter().enumerate() {
            y[r * outputs + j0..r * outputs + j0 + width].copy_from_slice(&row[..width]);
        }
        j0 += TILE;
    }
}

/// Output columns per register tile of [`affine4`].
const TILE: usize = 16;

/// `y = b + x·W` for one row.
fn affine1(x: &[f32], y: &mut [f32], w: &[f32], bias: &[f32], outputs: usize) {
    y.copy_from_slice(bias);
    for (&xk, wk) in x.iter().zip(w.chunks_exact(outputs)) {
        for (yj, &wkj) in y.iter_mut().zip(wk) {
            *yj += xk * wkj;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::SeedableRng;

    #[test]
    fn inference_matches_dfdx_forward() {
        let dev = Cpu::default();
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(0);
        let mlp = Mlp::new(&dev, 5, &[16, 8], 3, 1.0, &mut rng);
        let x: Vec<f32> = (0..20).map(|i| (i as f32 * 0.37).sin()).collect();
        let y = mlp.forward(dev.tensor_from_vec(x.clone(), (4, 5))).as_vec();
        let mut fast = mlp.inference();
        let mut out = vec![0.0; 12];
        fast.forward(&x, &mut out);
        for (a, b) in y.iter().zip(&out) {
            assert!((a - b).abs() < 1e-5, "{a} vs {b}");
        }
    }
}

/// Why saved networks do not fit a learner, or an edit of them cannot be made
/// ([`crate::acting::ActingPolicy::load_into`], [`crate::acting::ActingPolicy::widened`],
/// [`crate::acting::ActingHybrid::load_into`], ...).
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum ShapeError {
    /// Another number of layers than the learner's configuration.
    #[error("the {what} network has {saved} layers, the configuration {config}")]
    Layers {
        /// Which network (`policy`, `value`, `option`, `continuous`).
        what: &'static str,
        /// Layers saved.
        saved: usize,
        /// Layers configured.
        config: usize,
    },
    /// A layer of another shape (inputs × outputs).
    #[error("{what} layer {layer} is {}×{} in the file, {}×{} in the configuration", saved.0, saved.1, config.0, config.1)]
    Layer {
        /// Which network.
        what: &'static str,
        /// Its index, input first.
        layer: usize,
        /// Saved inputs × outputs.
        saved: (usize, usize),
        /// Configured inputs × outputs.
        config: (usize, usize),
    },
    /// Another width of something both have (observations, actions, continuous values).
    #[error("the saved {what} is {saved} wide, the learner's {learner}")]
    Width {
        /// What (`observation`, `action`, `value network's input`).
        what: &'static str,
        /// Saved width.
        saved: usize,
        /// The learner's.
        learner: usize,
    },
    /// Inputs inserted past the network's last.
    #[error("cannot insert inputs at {at}: the network takes {inputs}")]
    InsertPast {
        /// Where.
        at: usize,
        /// How many it takes.
        inputs: usize,
    },
    /// Widening to fewer inputs than it takes.
    #[error("cannot narrow a policy from {have} to {want} inputs")]
    Narrow {
        /// Inputs now.
        have: usize,
        /// Inputs asked for.
        want: usize,
    },
    /// A controller's head into a learner whose environment has no hybrid actions.
    #[error("the learner's environment has no hybrid actions")]
    NotHybrid,
    /// A controller's options read the continuous part otherwise than the learner's.
    #[error("the controller's options read the continuous part as {saved:?}, the learner's as {learner:?}")]
    Options {
        /// Per option, whether it reads the continuous part (saved).
        saved: Vec<bool>,
        /// The learner's.
        learner: Vec<bool>,
    },
    /// Weights and biases that do not fill a layer ([`crate::nn::MlpInference::from_layers`]).
    #[error("layer {layer}: {inputs}×{outputs} needs {} weights and {outputs} biases, found {weights} and {biases}", inputs * outputs)]
    Weights {
        /// The layer.
        layer: usize,
        /// Its inputs.
        inputs: usize,
        /// Its outputs.
        outputs: usize,
        /// Weights given.
        weights: usize,
        /// Biases given.
        biases: usize,
    },
    /// No layers at all.
    #[error("an MLP needs at least one layer")]
    NoLayers,
    /// A layer taking another number of inputs than the layer before gives.
    #[error("layer {layer} takes {inputs} inputs but the layer before gives {before}")]
    Chain {
        /// The layer.
        layer: usize,
        /// Its inputs.
        inputs: usize,
        /// The outputs of the layer before.
        before: usize,
    },
    /// A NaN or infinite weight or bias.
    #[error("layer {layer} holds a NaN or infinite weight")]
    NotFinite {
        /// The layer.
        layer: usize,
    },
}
