//! Policies and value functions with sizes from a config: the Gaussian MLP policy, the value MLP,
//! and the hybrid (categorical option + masked Gaussian) head of a meta-controller.
//!
//! Each has a taped path on dfdx for the PPO loss and a tape-free path ([`MlpInference`]) for
//! rollouts; the closed-form log-densities below are shared by both and by the tests.

use dfdx::prelude::*;
use rand::Rng;
use serde::{Deserialize, Serialize};

use crate::nn::{Matrix, Mlp, MlpInference, ParamMut, Parameters, Vector, prefixed};

/// The gradient tape used by the PPO loss.
pub type Taped = OwnedTape<f32, Cpu>;

/// Per-row `(log-probability, entropy)` of a minibatch, on the tape.
pub type LogProbEntropy = (Vector<Taped>, Vector<Taped>);

/// `½·ln(2π)`.
pub const HALF_LN_2PI: f32 = 0.918_938_5;

/// Sizes and options of the policy and value networks (RON-serialisable).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct PolicyConfig {
    /// Hidden widths of the policy MLP (tanh between layers), e.g. `[64, 64]`.
    pub policy_hidden: Vec<usize>,
    /// Hidden widths of the value MLP.
    pub value_hidden: Vec<usize>,
    /// Initial log standard deviation of the Gaussian actions.
    pub init_log_std: f32,
    /// Whether the log-std is trained (state-independent) or held fixed.
    pub learn_log_std: bool,
}

impl Default for PolicyConfig {
    fn default() -> Self {
        PolicyConfig { policy_hidden: vec![64, 64], value_hidden: vec![64, 64], init_log_std: 0.0, learn_log_std: true }
    }
}

/// `log N(x; μ, σ)` summed over dimensions, with `σ = exp(log_std)`.
pub fn gaussian_log_prob(x: &[f32], mean: &[f32], log_std: &[f32]) -> f32 {
    x.iter()
        .zip(mean)
        .zip(log_std)
        .map(|((&x, &m), &ls)| {
            let z = (x - m) * (-ls).exp();
            -0.5 * z * z - ls - HALF_LN_2PI
        })
        .sum()
}

/// Entropy of a diagonal Gaussian: `Σ (log σ + ½ ln(2πe))`.
pub fn gaussian_entropy(log_std: &[f32]) -> f32 {
    log_std.iter().map(|ls| ls + 0.5 + HALF_LN_2PI).sum()
}

/// `log softmax(logits)[k]`.
pub fn categorical_log_prob(logits: &[f32], k: usize) -> f32 {
    logits[k] - log_sum_exp(logits)
}

/// Entropy of `softmax(logits)`: `−Σ p log p`.
pub fn categorical_entropy(logits: &[f32]) -> f32 {
    let lse = log_sum_exp(logits);
    logits
        .iter()
        .map(|&l| {
            let lp = l - lse;
            -lp.exp() * lp
        })
        .sum()
}

fn log_sum_exp(x: &[f32]) -> f32 {
    let max = x.iter().copied().fold(f32::NEG_INFINITY, f32::max);
    max + x.iter().map(|v| (v - max).exp()).sum::<f32>().ln()
}

/// Draws an index from `softmax(logits)` (`lse` is their log-sum-exp) by inverting the CDF;
/// rounding that leaves the sum short of 1 falls to the last option not masked out.
fn sample_categorical(logits: &[f32], lse: f32, rng: &mut impl Rng) -> usize {
    let u: f32 = rng.random();
    let mut acc = 0.0;
    (0..logits.len())
        .find(|&j| {
            acc += (logits[j] - lse).exp();
            u < acc
        })
        .unwrap_or_else(|| {
            (0..logits.len()).rev().find(|&j| logits[j] > MASKED_LOGIT / 2.0).unwrap_or(logits.len() - 1)
        })
}

/// A standard normal sample (Box–Muller; exact and portable, so runs are reproducible).
pub fn standard_normal(rng: &mut impl Rng) -> f32 {
    let u1: f32 = 1.0 - rng.random::<f32>(); // (0, 1]
    let u2: f32 = rng.random::<f32>();
    (-2.0 * u1.ln()).sqrt() * (std::f32::consts::TAU * u2).cos()
}

/// Taped Gaussian log-density per row and entropy per row of a batch (`mean`, `actions`:
/// `[B × A]`); `log_std` gets its own tape so it is trained too.
fn gaussian_log_prob_entropy(mean: Matrix<Taped>, log_std: &Vector, actions: &Matrix) -> LogProbEntropy {
    let shape = *mean.shape();
    let log_std = log_std.retaped::<Taped>();
    let ls = log_std.with_empty_tape().broadcast_like::<_, Axis<0>>(&shape);
    let inv_std = log_std.with_empty_tape().negate().exp().broadcast_like::<_, Axis<0>>(&shape);
    let z = (mean - actions.clone()) * inv_std;
    let log_prob = (z.square() * -0.5 - ls - HALF_LN_2PI).sum::<(usize,), Axis<1>>();
    let entropy_row = (log_std + (0.5 + HALF_LN_2PI)).sum::<(), Axis<0>>();
    let entropy = entropy_row.broadcast_like::<_, Axis<0>>(&(shape.0,));
    (log_prob, entropy)
}

/// A Gaussian policy: state-dependent mean from a tanh MLP, state-independent log-std.
#[derive(Clone, Debug)]
pub struct GaussianPolicy {
    /// Observation → action mean.
    pub mean: Mlp,
    /// Log standard deviation per action dimension.
    pub log_std: Vector,
    /// Whether `log_std` is listed as trainable.
    pub learn_log_std: bool,
}

impl GaussianPolicy {
    /// A policy for `obs_dim → act_dim` shaped by `cfg`; the output layer starts small (gain 0.01).
    pub fn new(dev: &Cpu, obs_dim: usize, act_dim: usize, cfg: &PolicyConfig, rng: &mut impl Rng) -> Self {
        GaussianPolicy {
            mean: Mlp::new(dev, obs_dim, &cfg.policy_hidden, act_dim, 0.01, rng),
            log_std: dev.tensor_from_vec(vec![cfg.init_log_std; act_dim], (act_dim,)),
            learn_log_std: cfg.learn_log_std,
        }
    }

    /// Taped `(log π(a|s), entropy)` per row for a minibatch, for the PPO loss.
    pub fn log_prob_entropy(&self, obs: Matrix<Taped>, actions: &Matrix) -> LogProbEntropy {
        gaussian_log_prob_entropy(self.mean.forward(obs), &self.log_std, actions)
    }

    /// A tape-free copy for rollouts.
    pub fn inference(&self) -> GaussianInference {
        GaussianInference { mean: self.mean.inference(), log_std: self.log_std.as_vec() }
    }
}

impl Parameters for GaussianPolicy {
    fn params_mut(&mut self) -> Vec<(String, ParamMut<'_>)> {
        let mut out = prefixed("mean", self.mean.params_mut());
        if self.learn_log_std {
            out.push(("log_std".into(), ParamMut::Vector(&mut self.log_std)));
        }
        out
    }
}

/// Plain-`f32` Gaussian policy for batched sampling during rollouts.
#[derive(Clone, Debug)]
pub struct GaussianInference {
    mean: MlpInference,
    /// Log standard deviation per action dimension.
    pub log_std: Vec<f32>,
}

impl GaussianInference {
    /// Sample `a = μ(s) + σ·ε` for a batch `obs: [N × obs_dim]`, writing the unclipped actions
    /// `[N × act_dim]` and their log-probabilities `[N]`.
    pub fn sample(&mut self, obs: &[f32], rng: &mut impl Rng, actions: &mut [f32], log_probs: &mut [f32]) {
        self.mean.forward(obs, actions);
        let act_dim = self.log_std.len();
        for (a, lp) in actions.chunks_exact_mut(act_dim).zip(log_probs.iter_mut()) {
            let mut sum = 0.0;
            for (x, &ls) in a.iter_mut().zip(&self.log_std) {
                let eps = standard_normal(rng);
                *x += ls.exp() * eps;
                sum += -0.5 * eps * eps - ls - HALF_LN_2PI;
            }
            *lp = sum;
        }
    }

    /// The mean network.
    pub fn mean_net(&self) -> &MlpInference {
        &self.mean
    }

    /// The mean action (deterministic evaluation) for a batch.
    pub fn mean(&mut self, obs: &[f32], actions: &mut [f32]) {
        self.mean.forward(obs, actions);
    }
}

/// A state-value MLP `V(s)`.
#[derive(Clone, Debug)]
pub struct ValueNet {
    /// Observation → scalar value.
    pub net: Mlp,
}

impl ValueNet {
    /// A value net for `obs_dim` inputs shaped by `cfg`.
    pub fn new(dev: &Cpu, obs_dim: usize, cfg: &PolicyConfig, rng: &mut impl Rng) -> Self {
        ValueNet { net: Mlp::new(dev, obs_dim, &cfg.value_hidden, 1, 1.0, rng) }
    }

    /// Taped values `[B]` for a minibatch.
    pub fn forward(&self, obs: Matrix<Taped>) -> Vector<Taped> {
        let batch = obs.shape().0;
        self.net.forward(obs).reshape_like(&(batch,))
    }
}

impl Parameters for ValueNet {
    fn params_mut(&mut self) -> Vec<(String, ParamMut<'_>)> {
        prefixed("net", self.net.params_mut())
    }
}

/// The meta-controller's head: a categorical choice among `K` options plus a Gaussian continuous
/// part of dimension `C`, used only by the options whose `uses_continuous` flag is set.
#[derive(Clone, Debug)]
pub struct HybridPolicy {
    /// Observation → `K` option logits.
    pub logits: Mlp,
    /// Observation → `C` continuous means.
    pub mean: Mlp,
    /// Log standard deviation of the continuous part.
    pub log_std: Vector,
    /// Per option: whether it reads the continuous part.
    pub uses_continuous: Vec<bool>,
}

/// Logit bias of an option the mask forbids (its probability underflows to exactly 0).
pub const MASKED_LOGIT: f32 = -1e9;

/// Plain-`f32` hybrid head for batched sampling during rollouts and for acting.
#[derive(Clone, Debug)]
pub struct HybridInference {
    /// Observation → option logits.
    pub logits: MlpInference,
    /// Observation → continuous means.
    pub mean: MlpInference,
    /// Log standard deviation of the continuous part.
    pub log_std: Vec<f32>,
    /// Per option: whether it reads the continuous part.
    pub uses_continuous: Vec<bool>,
    scratch_logits: Vec<f32>,
    scratch_means: Vec<f32>,
}

impl HybridInference {
    /// Builds from its parts (e.g. loaded from a file).
    pub fn new(logits: MlpInference, mean: MlpInference, log_std: Vec<f32>, uses_continuous: Vec<bool>) -> Self {
        HybridInference {
            logits,
            mean,
            log_std,
            uses_continuous,
            scratch_logits: Vec::new(),
            scratch_means: Vec::new(),
        }
    }

    /// Action width: the option index, then the continuous part.
    pub fn act_dim(&self) -> usize {
        1 + self.log_std.len()
    }

    fn forward(&mut self, obs: &[f32], masks: &[bool]) -> usize {
        let (k, c) = (self.uses_continuous.len(), self.log_std.len());
        let batch = obs.len() / self.logits.inputs().max(1);
        self.scratch_logits.resize(batch * k, 0.0);
        self.scratch_means.resize(batch * c, 0.0);
        self.logits.forward(obs, &mut self.scratch_logits);
        self.mean.forward(obs, &mut self.scratch_means);
        if !masks.is_empty() {
            for (l, &m) in self.scratch_logits.iter_mut().zip(masks) {
                if !m {
                    *l += MASKED_LOGIT;
                }
            }
        }
        batch
    }

    /// Samples `[B × (1 + C)]` actions (option index as a float, then the continuous part) and
    /// their log-probabilities for `obs: [B × obs_dim]`, among the options `masks` allows.
    pub fn sample(
        &mut self,
        obs: &[f32],
        masks: &[bool],
        rng: &mut impl Rng,
        actions: &mut [f32],
        log_probs: &mut [f32],
    ) {
        let batch = self.forward(obs, masks);
        let (k, c) = (self.uses_continuous.len(), self.log_std.len());
        for i in 0..batch {
            let l = &self.scratch_logits[i * k..(i + 1) * k];
            let lse = log_sum_exp(l);
            let option = sample_categorical(l, lse, rng);
            let row = &mut actions[i * (1 + c)..(i + 1) * (1 + c)];
            row[0] = option as f32;
            let mean = &self.scratch_means[i * c..(i + 1) * c];
            for ((x, m), ls) in row[1..].iter_mut().zip(mean).zip(&self.log_std) {
                *x = m + ls.exp() * standard_normal(rng);
            }
            let mut lp = l[option] - lse;
            if self.uses_continuous[option] {
                lp += gaussian_log_prob(&row[1..], mean, &self.log_std);
            }
            log_probs[i] = lp;
        }
    }

    /// The most likely allowed option and the mean continuous part (deterministic acting).
    pub fn mode(&mut self, obs: &[f32], masks: &[bool], actions: &mut [f32]) {
        let batch = self.forward(obs, masks);
        let (k, c) = (self.uses_continuous.len(), self.log_std.len());
        for i in 0..batch {
            let l = &self.scratch_logits[i * k..(i + 1) * k];
            let option = (0..k).fold(0, |best, j| if l[j] > l[best] { j } else { best });
            let row = &mut actions[i * (1 + c)..(i + 1) * (1 + c)];
            row[0] = option as f32;
            row[1..].copy_from_slice(&self.scratch_means[i * c..(i + 1) * c]);
        }
    }
}

/// One sampled hybrid action.
#[derive(Clone, Debug, PartialEq)]
pub struct HybridAction {
    /// The chosen option.
    pub option: usize,
    /// The continuous part (sampled even when unused, so shapes stay fixed).
    pub continuous: Vec<f32>,
    /// `log π(option) + [uses_continuous] · log N(continuous)`.
    pub log_prob: f32,
}

impl HybridPolicy {
    /// A head for `obs_dim` inputs, `uses_continuous.len()` options and `cont_dim` continuous dims.
    pub fn new(
        dev: &Cpu,
        obs_dim: usize,
        uses_continuous: Vec<bool>,
        cont_dim: usize,
        cfg: &PolicyConfig,
        rng: &mut impl Rng,
    ) -> Self {
        let k = uses_continuous.len();
        HybridPolicy {
            logits: Mlp::new(dev, obs_dim, &cfg.policy_hidden, k, 0.01, rng),
            mean: Mlp::new(dev, obs_dim, &cfg.policy_hidden, cont_dim, 0.01, rng),
            log_std: dev.tensor_from_vec(vec![cfg.init_log_std; cont_dim], (cont_dim,)),
            uses_continuous,
        }
    }

    /// Taped `(log π, entropy)` per row: the continuous log-density and entropy count only on
    /// rows whose chosen option uses the continuous part. `masks` (`[B × K]`, or empty for all
    /// allowed) removes options that could not be chosen from the softmax.
    pub fn log_prob_entropy(
        &self,
        obs: Matrix<Taped>,
        options: &[usize],
        continuous: &Matrix,
        masks: &[bool],
    ) -> LogProbEntropy {
        let dev = obs.device().clone();
        let (batch, k) = (options.len(), self.uses_continuous.len());
        let bias: Vec<f32> = if masks.is_empty() {
            vec![0.0; batch * k]
        } else {
            masks.iter().map(|&m| if m { 0.0 } else { MASKED_LOGIT }).collect()
        };
        let bias = dev.tensor_from_vec(bias, (batch, k));
        let mut one_hot = vec![0.0; batch * k];
        let mut mask = vec![0.0; batch];
        for (i, &o) in options.iter().enumerate() {
            one_hot[i * k + o] = 1.0;
            mask[i] = if self.uses_continuous[o] { 1.0 } else { 0.0 };
        }
        let one_hot = dev.tensor_from_vec(one_hot, (batch, k));
        let mask = dev.tensor_from_vec(mask, (batch,));

        let obs_mean = obs.with_empty_tape();
        let log_p = (self.logits.forward(obs) + bias).log_softmax::<Axis<1>>();
        let p = log_p.with_empty_tape().exp();
        let cat_entropy = (p * log_p.with_empty_tape()).sum::<(usize,), Axis<1>>().negate();
        let cat_log_prob = (log_p * one_hot).sum::<(usize,), Axis<1>>();

        let (cont_log_prob, cont_entropy) =
            gaussian_log_prob_entropy(self.mean.forward(obs_mean), &self.log_std, continuous);
        let log_prob = cat_log_prob + cont_log_prob * mask.clone();
        let entropy = cat_entropy + cont_entropy * mask;
        (log_prob, entropy)
    }

    /// A tape-free plain-`f32` copy for rollouts and acting.
    pub fn inference(&self) -> HybridInference {
        HybridInference::new(
            self.logits.inference(),
            self.mean.inference(),
            self.log_std.as_vec(),
            self.uses_continuous.clone(),
        )
    }

    /// Sample one action per row of `obs: [B × obs_dim]` without a tape.
    pub fn sample(&self, obs: &[f32], rng: &mut impl Rng) -> Vec<HybridAction> {
        let (k, c) = (self.uses_continuous.len(), self.log_std.shape().0);
        let batch = obs.len() / self.logits.inputs();
        let mut logits = vec![0.0; batch * k];
        let mut means = vec![0.0; batch * c];
        self.logits.inference().forward(obs, &mut logits);
        self.mean.inference().forward(obs, &mut means);
        let log_std = self.log_std.as_vec();
        (0..batch)
            .map(|i| {
                let l = &logits[i * k..(i + 1) * k];
                let lse = log_sum_exp(l);
                let option = sample_categorical(l, lse, rng);
                let mean = &means[i * c..(i + 1) * c];
                let continuous: Vec<f32> =
                    mean.iter().zip(&log_std).map(|(m, ls)| m + ls.exp() * standard_normal(rng)).collect();
                let mut log_prob = categorical_log_prob(l, option);
                if self.uses_continuous[option] {
                    log_prob += gaussian_log_prob(&continuous, mean, &log_std);
                }
                HybridAction { option, continuous, log_prob }
            })
            .collect()
    }
}

impl Parameters for HybridPolicy {
    fn params_mut(&mut self) -> Vec<(String, ParamMut<'_>)> {
        let mut out = prefixed("logits", self.logits.params_mut());
        out.extend(prefixed("mean", self.mean.params_mut()));
        out.push(("log_std".into(), ParamMut::Vector(&mut self.log_std)));
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::SeedableRng;

    fn close(a: f32, b: f32) {
        assert!((a - b).abs() < 1e-4, "{a} vs {b}");
    }

    #[test]
    fn gaussian_closed_forms() {
        // 1-D: log N(1; 0, e^0.5) = −½(e^−0.5)² − 0.5 − ½ln2π.
        let lp = gaussian_log_prob(&[1.0], &[0.0], &[0.5]);
        close(lp, -0.5 * (-1.0f32).exp() - 0.5 - 0.5 * (2.0 * std::f32::consts::PI).ln());
        // Entropy of N(0, σ²) = ½ ln(2πe σ²).
        let s2 = (2.0f32 * 0.3).exp();
        let e = 0.5 * (2.0 * std::f32::consts::PI * std::f32::consts::E * s2).ln();
        close(gaussian_entropy(&[0.3]), e);
    }

    #[test]
    fn taped_gaussian_matches_closed_form_and_trains_log_std() {
        let dev = Cpu::default();
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(3);
        let cfg = PolicyConfig { init_log_std: -0.4, ..PolicyConfig::default() };
        let mut pi = GaussianPolicy::new(&dev, 3, 2, &cfg, &mut rng);
        let obs = vec![0.1, -0.2, 0.3, 1.0, 0.5, -1.0];
        let acts = vec![0.5, -0.5, 1.5, 0.0];
        let mut means = vec![0.0; 4];
        pi.inference().mean(&obs, &mut means);
        let obs_t = dev.tensor_from_vec(obs, (2, 3));
        let act_t = dev.tensor_from_vec(acts.clone(), (2, 2));
        let (lp, ent) = pi.log_prob_entropy(obs_t.leaky_trace(), &act_t);
        let (lpv, entv) = (lp.as_vec(), ent.as_vec());
        for r in 0..2 {
            let expect = gaussian_log_prob(&acts[r * 2..r * 2 + 2], &means[r * 2..r * 2 + 2], &[-0.4, -0.4]);
            close(lpv[r], expect);
            close(entv[r], gaussian_entropy(&[-0.4, -0.4]));
        }
        // d(mean entropy)/d(log_std_j) = 1.
        let (_, ent) = pi.log_prob_entropy(obs_t.leaky_trace(), &act_t);
        let mut grads = ent.mean().backward();
        let params = pi.params_mut();
        let (name, ParamMut::Vector(ls)) = &params[params.len() - 1] else { panic!("log_std should be last") };
        assert_eq!(name, "log_std");
        for g in grads.get_or_alloc_mut(&**ls).expect("alloc").iter() {
            close(*g, 1.0);
        }
    }

    #[test]
    fn sampled_log_prob_matches_density() {
        let dev = Cpu::default();
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(4);
        let pi = GaussianPolicy::new(&dev, 2, 3, &PolicyConfig::default(), &mut rng);
        let mut inf = pi.inference();
        let obs = [0.3, -0.7];
        let (mut a, mut lp, mut m) = ([0.0; 3], [0.0; 1], [0.0; 3]);
        inf.sample(&obs, &mut rng, &mut a, &mut lp);
        inf.mean(&obs, &mut m);
        close(lp[0], gaussian_log_prob(&a, &m, &inf.log_std));
    }

    #[test]
    fn categorical_closed_forms() {
        let logits = [1.0f32, 2.0, 0.5];
        let z: f32 = logits.iter().map(|l| l.exp()).sum();
        let p: Vec<f32> = logits.iter().map(|l| l.exp() / z).collect();
        close(categorical_log_prob(&logits, 1), p[1].ln());
        close(categorical_entropy(&logits), -p.iter().map(|p| p * p.ln()).sum::<f32>());
        // Uniform over 4: entropy ln 4.
        close(categorical_entropy(&[0.0; 4]), 4f32.ln());
    }

    #[test]
    fn hybrid_masks_the_continuous_part() {
        let dev = Cpu::default();
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(5);
        let cfg = PolicyConfig { policy_hidden: vec![8], init_log_std: 0.2, ..PolicyConfig::default() };
        let head = HybridPolicy::new(&dev, 2, vec![true, false, true], 2, &cfg, &mut rng);
        let obs = vec![0.5, -0.5, 0.1, 0.9];
        let cont = vec![0.3, -0.1, 2.0, 1.0];
        let options = [0usize, 1];
        let mut logits = vec![0.0; 6];
        let mut means = vec![0.0; 4];
        head.logits.inference().forward(&obs, &mut logits);
        head.mean.inference().forward(&obs, &mut means);
        let obs_t = dev.tensor_from_vec(obs, (2, 2));
        let cont_t = dev.tensor_from_vec(cont.clone(), (2, 2));
        let (lp, ent) = head.log_prob_entropy(obs_t.leaky_trace(), &options, &cont_t, &[]);
        let (lp, ent) = (lp.as_vec(), ent.as_vec());
        // Row 0 chose option 0 (uses the continuous part): both terms count.
        let g0 = gaussian_log_prob(&cont[0..2], &means[0..2], &[0.2, 0.2]);
        close(lp[0], categorical_log_prob(&logits[0..3], 0) + g0);
        close(ent[0], categorical_entropy(&logits[0..3]) + gaussian_entropy(&[0.2, 0.2]));
        // Row 1 chose option 1 (does not): only the categorical term.
        close(lp[1], categorical_log_prob(&logits[3..6], 1));
        close(ent[1], categorical_entropy(&logits[3..6]));
        // Sampling reports the same masked log-prob.
        for a in head.sample(&[0.5, -0.5], &mut rng) {
            let mut expect = categorical_log_prob(&logits[0..3], a.option);
            if head.uses_continuous[a.option] {
                expect += gaussian_log_prob(&a.continuous, &means[0..2], &[0.2, 0.2]);
            }
            close(a.log_prob, expect);
        }
    }
}
