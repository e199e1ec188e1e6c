//! The NPMP model (Merel et al. 2019; MoCapAct): an encoder `q(z_t | z_{t−1}, s_{t+1..t+k})`
//! giving a diagonal Gaussian over a latent `z` (default 60-D), a decoder `π(a_t | s_t, z_t)`
//! that sees proprioception only, and the AR(1) prior `p(z_t | z_{t−1}) = N(α z_{t−1},
//! (1 − α²) I)` whose stationary law `N(0, I)` is the prior of a sequence's first step.
//!
//! [`LatentNet`] is the trainable form on dfdx (taped loss: `−log π + β·KL`, the KL in closed
//! form per step); [`LatentPolicy`] is the frozen, tape-free form that acts, saved as a RON
//! manifest beside a safetensors file.

use std::collections::HashMap;
use std::path::{Path, PathBuf};

use dfdx::prelude::*;
use rand::Rng;
use repertoire_learn::checkpoint::{CheckpointError, fnv1a};
use repertoire_learn::nn::{Linear, Matrix, MlpInference, ParamMut, Parameters, Vector, prefixed};
use repertoire_learn::policy::{HALF_LN_2PI, Taped};
use repertoire_scenes::obs::LayoutEntry;
use repertoire_scenes::{Feature, ObservationLayout, WorldModel};
use safetensors::{Dtype, SafeTensors, tensor::TensorView};
use serde::{Deserialize, Serialize};

use crate::error::{LatentError, Result, write_atomic};
use crate::rollout::Controller;

/// Format of the latent-model manifests this build writes and reads.
pub const MODEL_FORMAT: u32 = 1;
/// Largest magnitude of a normalised input.
pub const INPUT_CLIP: f32 = 10.0;

/// How transitions are weighted in the loss.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub enum Weighting {
    /// Behaviour cloning: every transition counts the same.
    Bc,
    /// Every skill's transitions together count the same, however many there are.
    ClipBalanced,
    /// Reward-weighted regression (MoCapAct's best): weight `exp(G_t / temperature)`, with
    /// `G_t` the discounted return-to-go of the imitation reward, normalised to mean 1 and
    /// capped at `max_weight`.
    Rwr {
        /// Temperature of the exponent.
        temperature: f32,
        /// Discount of the return-to-go.
        gamma: f32,
        /// Largest weight after normalisation.
        max_weight: f32,
    },
    /// Advantage-weighted regression (Peng et al. 2019): weight `exp(A_t / temperature)` with
    /// `A_t = G_t − V_t`, `G_t` the discounted imitation return-to-go and `V_t` its mean over the
    /// dataset's transitions of the same skill at the same reference frame (the clip phase; a
    /// frame with fewer than [`AWR_MIN_CELL`] transitions takes its skill's mean), normalised to
    /// mean 1 and capped at `max_weight`. Unlike RWR it does not favour the easy phases of a clip
    /// (a standing frame earns more than a landing one whatever the action): it favours the
    /// transitions that did better than the others at the same point of the same clip.
    Awr {
        /// Temperature of the exponent.
        temperature: f32,
        /// Discount of the return-to-go.
        gamma: f32,
        /// Largest weight after normalisation.
        max_weight: f32,
    },
}

impl Weighting {
    /// A short name for tables: `BC`, `clip-balanced`, `RWR, temperature 1`, `AWR, temperature 1`.
    pub fn label(&self) -> String {
        match self {
            Weighting::Bc => "BC".into(),
            Weighting::ClipBalanced => "clip-balanced".into(),
            Weighting::Rwr { temperature, .. } => format!("RWR, temperature {temperature}"),
            Weighting::Awr { temperature, .. } => format!("AWR, temperature {temperature}"),
        }
    }
}

/// Fewest transitions at one (skill, reference frame) for AWR to use their mean as the baseline.
pub const AWR_MIN_CELL: usize = 8;

/// Which recorded action the decoder learns.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub enum ActionTarget {
    /// The expert's mean action at the state the noisy rollout reached (DART-style).
    Mean,
    /// The noisy action actually taken.
    Noisy,
}

/// Sizes and training settings of a latent model (RON).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct LatentConfig {
    /// Width of `z`.
    pub latent_dim: usize,
    /// AR(1) prior coefficient `α`.
    pub alpha: f32,
    /// Weight of the KL term.
    pub beta: f32,
    /// Hidden widths of the encoder (tanh).
    pub encoder_hidden: Vec<usize>,
    /// Hidden widths of the decoder (tanh).
    pub decoder_hidden: Vec<usize>,
    /// Fixed standard deviation of the decoder's Gaussian over actions.
    pub action_std: f32,
    /// Which action is learned.
    pub target: ActionTarget,
    /// Transition weights.
    pub weighting: Weighting,
    /// Steps per training sequence (`z` is carried along it).
    pub seq_len: usize,
    /// Sequences per update.
    pub batch_sequences: usize,
    /// Adam's learning rate.
    pub learning_rate: f64,
    /// Global gradient-norm clip.
    pub max_grad_norm: f32,
    /// Seed of the initial weights and the sampling.
    pub seed: u64,
}

impl Default for LatentConfig {
    fn default() -> Self {
        LatentConfig {
            latent_dim: 60,
            alpha: 0.95,
            beta: 0.01,
            encoder_hidden: vec![256, 256],
            decoder_hidden: vec![256, 256],
            action_std: 0.1,
            target: ActionTarget::Mean,
            weighting: Weighting::Bc,
            seq_len: 32,
            batch_sequences: 32,
            learning_rate: 3e-4,
            max_grad_norm: 1.0,
            seed: 1,
        }
    }
}

impl LatentConfig {
    /// Checks ranges; the message names the setting.
    pub fn validate(&self) -> Result<()> {
        let bad = |m: String| Err(LatentError::Invalid(format!("latent config: {m}")));
        if self.latent_dim == 0 || self.seq_len == 0 || self.batch_sequences == 0 {
            return bad("latent_dim, seq_len and batch_sequences must be positive".into());
        }
        if !(0.0..1.0).contains(&self.alpha) {
            return bad(format!("alpha must be in [0, 1), got {}", self.alpha));
        }
        if !(self.beta.is_finite() && self.beta >= 0.0) {
            return bad(format!("beta must be ≥ 0, got {}", self.beta));
        }
        if !(self.action_std.is_finite() && self.action_std > 0.0) {
            return bad(format!("action_std must be positive, got {}", self.action_std));
        }
        if self.encoder_hidden.is_empty()
            || self.decoder_hidden.is_empty()
            || self.encoder_hidden.contains(&0)
            || self.decoder_hidden.contains(&0)
        {
            return bad("encoder_hidden and decoder_hidden need at least one positive width".into());
        }
        if !(self.learning_rate > 0.0 && self.learning_rate.is_finite()) {
            return bad(format!("learning_rate must be positive, got {}", self.learning_rate));
        }
        if let Weighting::Rwr { temperature, gamma, max_weight } | Weighting::Awr { temperature, gamma, max_weight } =
            self.weighting
            && !(temperature > 0.0 && (0.0..=1.0).contains(&gamma) && max_weight >= 1.0)
        {
            return bad(format!(
                "{:?} needs temperature > 0, gamma in [0, 1], max_weight ≥ 1 (got {temperature}, {gamma}, {max_weight})",
                self.weighting
            ));
        }
        Ok(())
    }
}

/// Per-step `KL(N(μ, σ²) ‖ N(m, v))` summed over dimensions, on dfdx (taped if `mu` and
/// `log_std` are): `Σ ½ ln v − ln σ + (σ² + (μ − m)²) / (2v) − ½`. `prior_mean` is `α z_{t−1}`;
/// `inv_2var` holds `1 / (2v)` and `half_ln_var` holds `½ ln v` per element.
pub fn kl_rows<T: Tape<f32, Cpu> + Merge<T>>(
    mu: Matrix<T>,
    log_std: Matrix<T>,
    prior_mean: &Matrix,
    inv_2var: &Matrix,
    half_ln_var: &Matrix,
) -> Vector<T> {
    let var_q = (log_std.with_empty_tape() * 2.0).exp();
    let d2 = (mu - prior_mean.clone()).square();
    let scaled = (var_q + d2) * inv_2var.clone();
    let per = scaled - log_std + half_ln_var.clone() - 0.5;
    per.sum::<(usize,), Axis<1>>()
}

/// The AR(1) prior's mean and variance for one step: `N(0, 1)` at a sequence's first step (the
/// process's stationary law), else `N(α z_{t−1}, 1 − α²)`.
pub fn ar1_prior(z_prev: f32, alpha: f32, first: bool) -> (f32, f32) {
    if first { (0.0, 1.0) } else { (alpha * z_prev, 1.0 - alpha * alpha) }
}

/// [`kl_rows`] on plain slices (`[B × Z]` each), with the prior of [`ar1_prior`] per row
/// (`first[b]` marks a sequence start): the same dfdx code the training loss runs.
pub fn kl_ar1(mu: &[f32], log_std: &[f32], z_prev: &[f32], first: &[bool], alpha: f32) -> Vec<f32> {
    let rows = first.len();
    let z = mu.len() / rows.max(1);
    let dev = Cpu::default();
    let (mut m, mut inv, mut half) =
        (Vec::with_capacity(mu.len()), Vec::with_capacity(mu.len()), Vec::with_capacity(mu.len()));
    for (r, &f) in first.iter().enumerate() {
        for i in 0..z {
            let (pm, pv) = ar1_prior(z_prev[r * z + i], alpha, f);
            m.push(pm);
            inv.push(0.5 / pv);
            half.push(0.5 * pv.ln());
        }
    }
    let t = |v: Vec<f32>| dev.tensor_from_vec(v, (rows, z));
    kl_rows(t(mu.to_vec()), t(log_std.to_vec()), &t(m), &t(inv), &t(half)).as_vec()
}

/// The trainable encoder and decoder.
#[derive(Clone, Debug)]
pub struct LatentNet {
    /// Encoder trunk: `[F + Z] → hidden…` (tanh after each layer).
    pub enc: Vec<Linear>,
    /// Encoder head for `μ`.
    pub enc_mu: Linear,
    /// Encoder head for `log σ`.
    pub enc_log_std: Linear,
    /// Decoder's first layer on proprioception `S → H₀` (with the bias).
    pub dec_s: Linear,
    /// Decoder's first layer on the latent `Z → H₀` (no bias).
    pub dec_z: Matrix,
    /// The decoder's other layers `H₀ → … → A` (tanh between, linear output).
    pub dec: Vec<Linear>,
}

/// One training batch of `R = T × B` rows (time-major), all plain data: the gradient reaches
/// `z_{t−1}` only through the step that made it (truncated backpropagation).
#[derive(Clone, Debug)]
pub struct Batch {
    /// Rows.
    pub rows: usize,
    /// Encoder inputs `[R × (F + Z)]`: normalised reference features, then `z_{t−1}`.
    pub enc_in: Vec<f32>,
    /// Normalised proprioception `[R × S]`.
    pub proprio: Vec<f32>,
    /// Target actions `[R × A]`.
    pub target: Vec<f32>,
    /// Standard normal draws of the reparameterisation `[R × Z]`.
    pub eps: Vec<f32>,
    /// Prior means `α z_{t−1}` `[R × Z]`.
    pub prior_mean: Vec<f32>,
    /// Prior variances per row `[R]`.
    pub prior_var: Vec<f32>,
    /// Row weights `[R]` (0 past an episode's end).
    pub weight: Vec<f32>,
}

/// Figures of one loss evaluation (per weighted step).
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct LossStats {
    /// `−log π(a | s, z)`.
    pub nll: f32,
    /// `KL(q ‖ prior)`.
    pub kl: f32,
    /// Mean squared error of the decoder's mean action per action value.
    pub action_mse: f32,
    /// The loss `−log π + β·KL`.
    pub loss: f32,
}

impl LatentNet {
    /// A fresh network for `F` reference values, `S` proprioceptive values and `A` actions.
    pub fn new(dev: &Cpu, cfg: &LatentConfig, f: usize, s: usize, a: usize, rng: &mut impl Rng) -> Self {
        let z = cfg.latent_dim;
        let mut enc = Vec::new();
        let mut width = f + z;
        for &h in &cfg.encoder_hidden {
            enc.push(Linear::new(dev, width, h, 1.0, rng));
            width = h;
        }
        let enc_mu = Linear::new(dev, width, z, 0.1, rng);
        let enc_log_std = Linear::new(dev, width, z, 0.01, rng);
        let h0 = cfg.decoder_hidden[0];
        // The first decoder layer reads [s, z]; drawn as one layer over S + Z inputs.
        let first = Linear::new(dev, s + z, h0, 1.0, rng);
        let w = first.weight.as_vec();
        let dec_s = Linear { weight: dev.tensor_from_vec(w[..s * h0].to_vec(), (s, h0)), bias: first.bias.clone() };
        let dec_z = dev.tensor_from_vec(w[s * h0..].to_vec(), (z, h0));
        let mut dec = Vec::new();
        let mut width = h0;
        for &h in &cfg.decoder_hidden[1..] {
            dec.push(Linear::new(dev, width, h, 1.0, rng));
            width = h;
        }
        dec.push(Linear::new(dev, width, a, 0.1, rng));
        LatentNet { enc, enc_mu, enc_log_std, dec_s, dec_z, dec }
    }

    /// The taped loss `Σ w (−log π + β·KL) / Σ w` of a batch, and its figures.
    pub fn loss(&self, cfg: &LatentConfig, batch: &Batch) -> (Tensor<(), f32, Cpu, Taped>, LossStats) {
        let dev = Cpu::default();
        let r = batch.rows;
        let z = cfg.latent_dim;
        let a = self.dec.last().expect("an output layer").outputs();
        let s = self.dec_s.inputs();
        let mat = |v: &[f32], w: usize| dev.tensor_from_vec(v.to_vec(), (r, w));
        let mut h = mat(&batch.enc_in, self.enc[0].inputs()).leaky_trace();
        for layer in &self.enc {
            h = layer.forward(h).tanh();
        }
        let mu = self.enc_mu.forward(h.with_empty_tape());
        let log_std = self.enc_log_std.forward(h);
        let eps = mat(&batch.eps, z);
        let zs = mu.with_empty_tape() + log_std.with_empty_tape().exp() * eps;
        let inv: Vec<f32> = batch.prior_var.iter().flat_map(|&v| std::iter::repeat_n(0.5 / v, z)).collect();
        let half: Vec<f32> = batch.prior_var.iter().flat_map(|&v| std::iter::repeat_n(0.5 * v.ln(), z)).collect();
        let kl = kl_rows(mu, log_std, &mat(&batch.prior_mean, z), &mat(&inv, z), &mat(&half, z));

        let hs = self.dec_s.forward(mat(&batch.proprio, s).leaky_trace());
        let mut h = (hs + zs.matmul(self.dec_z.clone())).tanh();
        let last = self.dec.len() - 1;
        for (i, layer) in self.dec.iter().enumerate() {
            h = layer.forward(h);
            if i != last {
                h = h.tanh();
            }
        }
        let sq = (h - mat(&batch.target, a)).square();
        let sq_rows = sq.sum::<(usize,), Axis<1>>();
        let sq_v = sq_rows.as_vec();
        let log_norm = a as f32 * (cfg.action_std.ln() + HALF_LN_2PI);
        let nll = sq_rows * (0.5 / (cfg.action_std * cfg.action_std)) + log_norm;
        let w_sum: f32 = batch.weight.iter().sum::<f32>().max(1e-6);
        let w = dev.tensor_from_vec(batch.weight.iter().map(|x| x / w_sum).collect::<Vec<f32>>(), (r,));
        let (nll_v, kl_v) = (nll.as_vec(), kl.as_vec());
        let wv = w.as_vec();
        let dot = |v: &[f32]| v.iter().zip(&wv).map(|(x, w)| x * w).sum::<f32>();
        let stats = LossStats {
            nll: dot(&nll_v),
            kl: dot(&kl_v),
            action_mse: dot(&sq_v) / a as f32,
            loss: dot(&nll_v) + cfg.beta * dot(&kl_v),
        };
        let total = ((nll + kl * cfg.beta) * w).sum::<(), Axis<0>>();
        (total, stats)
    }

    /// The encoder as one tape-free MLP `[F + Z] → [μ, log σ]`.
    pub fn encoder_inference(&self) -> MlpInference {
        let mut layers: Vec<(usize, usize, Vec<f32>, Vec<f32>)> =
            self.enc.iter().map(|l| (l.inputs(), l.outputs(), l.weight.as_vec(), l.bias.as_vec())).collect();
        let (h, z) = (self.enc_mu.inputs(), self.enc_mu.outputs());
        let (wm, wl) = (self.enc_mu.weight.as_vec(), self.enc_log_std.weight.as_vec());
        let mut w = Vec::with_capacity(h * 2 * z);
        for k in 0..h {
            w.extend_from_slice(&wm[k * z..(k + 1) * z]);
            w.extend_from_slice(&wl[k * z..(k + 1) * z]);
        }
        let mut b = self.enc_mu.bias.as_vec();
        b.extend(self.enc_log_std.bias.as_vec());
        layers.push((h, 2 * z, w, b));
        MlpInference::from_layers(layers).expect("the encoder's layers fit")
    }

    /// The decoder as one tape-free MLP `[S + Z] → A`.
    pub fn decoder_inference(&self) -> MlpInference {
        let (s, h0) = (self.dec_s.inputs(), self.dec_s.outputs());
        let z = self.dec_z.shape().0;
        let mut w = self.dec_s.weight.as_vec();
        w.extend(self.dec_z.as_vec());
        let mut layers = vec![(s + z, h0, w, self.dec_s.bias.as_vec())];
        layers.extend(self.dec.iter().map(|l| (l.inputs(), l.outputs(), l.weight.as_vec(), l.bias.as_vec())));
        MlpInference::from_layers(layers).expect("the decoder's layers fit")
    }
}

impl Parameters for LatentNet {
    fn params_mut(&mut self) -> Vec<(String, ParamMut<'_>)> {
        let mut out = Vec::new();
        for (i, l) in self.enc.iter_mut().enumerate() {
            out.extend(prefixed(&format!("enc.{i}"), l.params_mut()));
        }
        out.extend(prefixed("enc_mu", self.enc_mu.params_mut()));
        out.extend(prefixed("enc_log_std", self.enc_log_std.params_mut()));
        out.extend(prefixed("dec_s", self.dec_s.params_mut()));
        out.push(("dec_z.weight".into(), ParamMut::Matrix(&mut self.dec_z)));
        for (i, l) in self.dec.iter_mut().enumerate() {
            out.extend(prefixed(&format!("dec.{i}"), l.params_mut()));
        }
        out
    }
}

/// Per-value mean and standard deviation of the encoder's and decoder's raw inputs.
#[derive(Clone, Debug, PartialEq)]
pub struct InputNorm {
    /// Proprioception mean `[S]`.
    pub proprio_mean: Vec<f32>,
    /// Proprioception standard deviation `[S]`.
    pub proprio_std: Vec<f32>,
    /// Reference-feature mean `[F]`.
    pub reference_mean: Vec<f32>,
    /// Reference-feature standard deviation `[F]`.
    pub reference_std: Vec<f32>,
}

/// Mean and standard deviation (floored at 0.01) of each column of `rows` (`[N × w]`).
pub fn column_stats(rows: &[f32], w: usize) -> (Vec<f32>, Vec<f32>) {
    let n = (rows.len() / w.max(1)).max(1) as f64;
    let mut mean = vec![0.0f64; w];
    let mut sq = vec![0.0f64; w];
    for row in rows.chunks_exact(w) {
        for ((m, s), &x) in mean.iter_mut().zip(&mut sq).zip(row) {
            *m += f64::from(x);
            *s += f64::from(x) * f64::from(x);
        }
    }
    let mean: Vec<f64> = mean.iter().map(|m| m / n).collect();
    let std = sq.iter().zip(&mean).map(|(s, m)| ((s / n - m * m).max(0.0).sqrt().max(0.01)) as f32).collect();
    (mean.into_iter().map(|m| m as f32).collect(), std)
}

/// `(x − mean) / std`, clipped to ±[`INPUT_CLIP`], into `out`.
pub fn normalize_into(x: &[f32], mean: &[f32], std: &[f32], out: &mut [f32]) {
    for (((o, &v), &m), &s) in out.iter_mut().zip(x).zip(mean).zip(std) {
        *o = ((v - m) / s).clamp(-INPUT_CLIP, INPUT_CLIP);
    }
}

/// Training figures recorded with a model.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct TrainingFigures {
    /// Adam updates.
    pub updates: usize,
    /// Transition rows seen.
    pub rows: u64,
    /// Wall-clock seconds.
    pub seconds: f64,
    /// Loss figures of the first update.
    pub first: LossStats,
    /// Loss figures averaged over the last updates.
    pub last: LossStats,
}

/// The dataset a model was trained on.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct DatasetRecord {
    /// Where it was.
    pub path: String,
    /// FNV-1a of its data file.
    pub data_fnv1a: u64,
    /// Transitions.
    pub steps: usize,
    /// Its skills.
    pub skills: Vec<String>,
}

/// `latent.ron`: what a latent model reads, writes and was trained on.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct LatentManifest {
    /// [`MODEL_FORMAT`].
    pub format: u32,
    /// Width of `z`.
    pub latent_dim: usize,
    /// AR(1) coefficient.
    pub alpha: f32,
    /// KL weight.
    pub beta: f32,
    /// Reference frames ahead in the encoder's input.
    pub k: usize,
    /// Action width.
    pub act_dim: usize,
    /// The encoder's input: reference features, then `z_prev`.
    pub encoder_input: Vec<LayoutEntry>,
    /// The decoder's observation features (proprioception only; checked on load).
    pub decoder_features: Vec<Feature>,
    /// The decoder's input: the observation layout's entries, then `z`.
    pub decoder_input: Vec<LayoutEntry>,
    /// Content hash of the body.
    pub body_hash: String,
    /// Control rate (Hz).
    pub control_hz: u32,
    /// The training settings.
    pub config: LatentConfig,
    /// Training figures.
    pub training: TrainingFigures,
    /// The dataset.
    pub dataset: DatasetRecord,
    /// FNV-1a of `latent.safetensors` (checked on load).
    pub weights_fnv1a: u64,
    /// The command that trained it.
    pub command: String,
    /// Git commit of the code that trained it.
    pub git_hash: Option<String>,
}

impl LatentManifest {
    /// Width of the reference features.
    pub fn reference_size(&self) -> usize {
        self.encoder_input.iter().filter(|e| e.name != "z_prev").map(|e| e.len).sum()
    }

    /// Width of the decoder's observation.
    pub fn proprio_size(&self) -> usize {
        self.decoder_input.iter().filter(|e| e.name != "z").map(|e| e.len).sum()
    }

    /// Refuses a decoder that would read anything but proprioception (a prop's pose).
    pub fn check_decoder_is_proprioceptive(&self, path: &Path) -> Result<()> {
        let prop =
            self.decoder_features.iter().find(|f| matches!(f, Feature::PropPose(_))).map(Feature::name).or_else(|| {
                self.decoder_input.iter().find(|e| e.name.starts_with("prop_pose")).map(|e| e.name.clone())
            });
        match prop {
            Some(name) => Err(LatentError::Mismatch {
                path: path.to_path_buf(),
                message: format!(
                    "the decoder's input holds the prop feature `{name}`; a latent decoder sees proprioception only, so it transfers across scenes"
                ),
            }),
            None => Ok(()),
        }
    }
}

/// A frozen latent model that acts: encoder, decoder and input statistics, tape-free.
#[derive(Clone, Debug)]
pub struct LatentPolicy {
    /// The manifest.
    pub manifest: LatentManifest,
    /// `[F + Z] → [μ, log σ]`.
    pub encoder: MlpInference,
    /// `[S + Z] → A`.
    pub decoder: MlpInference,
    /// Input statistics.
    pub norm: InputNorm,
    z_prev: Vec<f32>,
    mu: Vec<f32>,
    log_std: Vec<f32>,
    enc_in: Vec<f32>,
    enc_out: Vec<f32>,
    dec_in: Vec<f32>,
}

fn weight_entries(prefix: &str, mlp: &MlpInference, out: &mut Vec<(String, Vec<usize>, Vec<f32>)>) {
    for (i, (inputs, outputs, w, b)) in mlp.layers().iter().enumerate() {
        out.push((format!("{prefix}.{i}.weight"), vec![*inputs, *outputs], w.clone()));
        out.push((format!("{prefix}.{i}.bias"), vec![*outputs], b.clone()));
    }
}

/// The MLP under `prefix`, read by the learning core's reader, its error re-homed here.
fn read_mlp(path: &Path, st: &SafeTensors<'_>, prefix: &str) -> Result<MlpInference> {
    repertoire_learn::acting::read_mlp(path, st, prefix).map_err(|e| match e {
        CheckpointError::Corrupt { reason, .. } => LatentError::corrupt(path, reason),
        other => LatentError::corrupt(path, other.to_string()),
    })
}

fn read_f32(path: &Path, st: &SafeTensors<'_>, name: &str) -> Result<(Vec<usize>, Vec<f32>)> {
    let t = st.tensor(name).map_err(|_| LatentError::corrupt(path, format!("no tensor `{name}`")))?;
    if t.dtype() != Dtype::F32 {
        return Err(LatentError::corrupt(path, format!("tensor `{name}` is {:?}, expected F32", t.dtype())));
    }
    let v: Vec<f32> = t.data().chunks_exact(4).map(|b| f32::from_le_bytes([b[0], b[1], b[2], b[3]])).collect();
    if v.iter().any(|x| !x.is_finite()) {
        return Err(LatentError::corrupt(path, format!("tensor `{name}` holds a NaN or infinite value")));
    }
    Ok((t.shape().to_vec(), v))
}

impl LatentPolicy {
    /// A policy from trained parts.
    pub fn new(manifest: LatentManifest, encoder: MlpInference, decoder: MlpInference, norm: InputNorm) -> Self {
        LatentPolicy {
            manifest,
            encoder,
            decoder,
            norm,
            z_prev: Vec::new(),
            mu: Vec::new(),
            log_std: Vec::new(),
            enc_in: Vec::new(),
            enc_out: Vec::new(),
            dec_in: Vec::new(),
        }
    }

    /// Width of `z`.
    pub fn latent_dim(&self) -> usize {
        self.manifest.latent_dim
    }

    /// The encoder's mean and log-std `[B × Z]` each for raw reference features `[B × F]` and
    /// the previous latents `[B × Z]`.
    pub fn encode(&mut self, reference: &[f32], z_prev: &[f32], mu: &mut [f32], log_std: &mut [f32]) {
        let (f, z) = (self.manifest.reference_size(), self.latent_dim());
        let b = reference.len() / f;
        self.enc_in.resize(b * (f + z), 0.0);
        self.enc_out.resize(b * 2 * z, 0.0);
        for r in 0..b {
            let row = &mut self.enc_in[r * (f + z)..(r + 1) * (f + z)];
            normalize_into(
                &reference[r * f..(r + 1) * f],
                &self.norm.reference_mean,
                &self.norm.reference_std,
                &mut row[..f],
            );
            row[f..].copy_from_slice(&z_prev[r * z..(r + 1) * z]);
        }
        self.encoder.forward(&self.enc_in, &mut self.enc_out);
        for r in 0..b {
            let o = &self.enc_out[r * 2 * z..(r + 1) * 2 * z];
            mu[r * z..(r + 1) * z].copy_from_slice(&o[..z]);
            log_std[r * z..(r + 1) * z].copy_from_slice(&o[z..]);
        }
    }

    /// The decoder's mean actions `[B × A]` for raw proprioception `[B × S]` and latents `[B × Z]`.
    pub fn decode(&mut self, proprio: &[f32], z_batch: &[f32], actions: &mut [f32]) {
        let (s, z) = (self.manifest.proprio_size(), self.latent_dim());
        let b = proprio.len() / s;
        self.dec_in.resize(b * (s + z), 0.0);
        for r in 0..b {
            let row = &mut self.dec_in[r * (s + z)..(r + 1) * (s + z)];
            normalize_into(
                &proprio[r * s..(r + 1) * s],
                &self.norm.proprio_mean,
                &self.norm.proprio_std,
                &mut row[..s],
            );
            row[s..].copy_from_slice(&z_batch[r * z..(r + 1) * z]);
        }
        self.decoder.forward(&self.dec_in, actions);
    }

    /// Checks that this model can drive the character of `model`: same body and rates, and a
    /// proprioceptive layout there that matches the decoder's.
    pub fn check_fits(&self, model: &WorldModel, path: &Path) -> Result<()> {
        let m = &self.manifest;
        let mismatch = |message: String| Err(LatentError::Mismatch { path: path.to_path_buf(), message });
        let hash = model.body.content_hash();
        if hash != m.body_hash {
            return mismatch(format!(
                "the latent model was trained on body {}, this scene's body is {hash}",
                m.body_hash
            ));
        }
        if model.scenario.scenario.rates.control_hz != m.control_hz {
            return mismatch(format!(
                "the latent model runs at {} Hz, this scene at {} Hz",
                m.control_hz, model.scenario.scenario.rates.control_hz
            ));
        }
        let here = ObservationLayout::new(model, &m.decoder_features)?;
        let expected: Vec<LayoutEntry> = m.decoder_input.iter().filter(|e| e.name != "z").cloned().collect();
        if here.entries != expected {
            return mismatch("the decoder's proprioceptive layout differs in this scene".into());
        }
        Ok(())
    }

    /// Writes `dir/latent.safetensors`, then `dir/latent.ron` vouching for it, each atomically.
    pub fn save(&mut self, dir: &Path) -> Result<PathBuf> {
        std::fs::create_dir_all(dir).map_err(|e| LatentError::io(dir, "cannot create the model folder", e))?;
        let mut entries = Vec::new();
        weight_entries("encoder", &self.encoder, &mut entries);
        weight_entries("decoder", &self.decoder, &mut entries);
        let n = &self.norm;
        for (name, v) in [
            ("norm.proprio_mean", &n.proprio_mean),
            ("norm.proprio_std", &n.proprio_std),
            ("norm.reference_mean", &n.reference_mean),
            ("norm.reference_std", &n.reference_std),
        ] {
            entries.push((name.to_string(), vec![v.len()], v.clone()));
        }
        let bytes: Vec<Vec<u8>> =
            entries.iter().map(|(_, _, v)| v.iter().flat_map(|x| x.to_le_bytes()).collect()).collect();
        let views: Vec<(String, TensorView<'_>)> = entries
            .iter()
            .zip(&bytes)
            .map(|((name, shape, _), data)| {
                (name.clone(), TensorView::new(Dtype::F32, shape.clone(), data).expect("sizes match"))
            })
            .collect();
        let weights = dir.join("latent.safetensors");
        let meta = HashMap::from([("format".to_string(), format!("repertoire-latent-{MODEL_FORMAT}"))]);
        let data = safetensors::serialize(views, Some(meta))
            .map_err(|e| LatentError::corrupt(&weights, format!("cannot serialise: {e}")))?;
        write_atomic(&weights, &data)?;
        self.manifest.weights_fnv1a = fnv1a(&data);
        let text = ron::ser::to_string_pretty(&self.manifest, ron::ser::PrettyConfig::new().depth_limit(3))
            .map_err(|e| LatentError::Invalid(format!("cannot serialise the latent manifest: {e}")))?;
        let path = dir.join("latent.ron");
        write_atomic(&path, text.as_bytes())?;
        Ok(path)
    }

    /// Loads a model from `dir` (or its `latent.ron`): checks the weights' checksum and
    /// shapes against the manifest, and refuses a decoder that reads a prop feature.
    pub fn load(path: &Path) -> Result<Self> {
        let is_ron = path.extension().is_some_and(|e| e == "ron");
        let manifest_path = if path.is_dir() || !is_ron { path.join("latent.ron") } else { path.to_path_buf() };
        let dir = manifest_path.parent().unwrap_or(Path::new("."));
        let text = std::fs::read_to_string(&manifest_path)
            .map_err(|e| LatentError::io(&manifest_path, "cannot read the latent manifest", e))?;
        let manifest: LatentManifest = ron::from_str(&text).map_err(|e| LatentError::ron(&manifest_path, e))?;
        if manifest.format != MODEL_FORMAT {
            return Err(LatentError::Mismatch {
                path: manifest_path,
                message: format!("latent model format {} (this build reads {MODEL_FORMAT})", manifest.format),
            });
        }
        manifest.check_decoder_is_proprioceptive(&manifest_path)?;
        let weights = dir.join("latent.safetensors");
        let bytes =
            std::fs::read(&weights).map_err(|e| LatentError::io(&weights, "cannot read the latent weights", e))?;
        if fnv1a(&bytes) != manifest.weights_fnv1a {
            return Err(LatentError::corrupt(
                &weights,
                "the weights do not match their manifest's checksum (modified or truncated)",
            ));
        }
        let st = SafeTensors::deserialize(&bytes).map_err(|e| LatentError::corrupt(&weights, e.to_string()))?;
        let encoder = read_mlp(&weights, &st, "encoder")?;
        let decoder = read_mlp(&weights, &st, "decoder")?;
        let (z, f, s, a) = (manifest.latent_dim, manifest.reference_size(), manifest.proprio_size(), manifest.act_dim);
        let shapes = [
            (encoder.inputs(), f + z, "encoder input"),
            (encoder.outputs(), 2 * z, "encoder output"),
            (decoder.inputs(), s + z, "decoder input"),
            (decoder.outputs(), a, "decoder output"),
        ];
        for (got, want, what) in shapes {
            if got != want {
                return Err(LatentError::Mismatch {
                    path: manifest_path,
                    message: format!("the {what} has {got} values, the manifest says {want}"),
                });
            }
        }
        let vec = |name: &str, len: usize| -> Result<Vec<f32>> {
            let (_, v) = read_f32(&weights, &st, name)?;
            if v.len() != len {
                return Err(LatentError::corrupt(&weights, format!("`{name}` has {} values, expected {len}", v.len())));
            }
            Ok(v)
        };
        let norm = InputNorm {
            proprio_mean: vec("norm.proprio_mean", s)?,
            proprio_std: vec("norm.proprio_std", s)?,
            reference_mean: vec("norm.reference_mean", f)?,
            reference_std: vec("norm.reference_std", f)?,
        };
        if norm.proprio_std.iter().chain(&norm.reference_std).any(|&v| v <= 0.0) {
            return Err(LatentError::corrupt(&weights, "an input standard deviation is not positive"));
        }
        Ok(LatentPolicy::new(manifest, encoder, decoder, norm))
    }
}

/// The latent model as a controller: each step it encodes the coming reference frames into
/// `z_t = μ` (given `z_{t−1}`, zero at an episode start) and decodes `z_t` with
/// proprioception into the action.
impl Controller for LatentPolicy {
    fn begin(&mut self, i: usize) {
        let z = self.latent_dim();
        if self.z_prev.len() < (i + 1) * z {
            self.z_prev.resize((i + 1) * z, 0.0);
        }
        self.z_prev[i * z..(i + 1) * z].fill(0.0);
    }

    fn act(&mut self, _obs: &[f32], proprio: &[f32], reference: &[f32], actions: &mut [f32]) {
        let z = self.latent_dim();
        let b = actions.len() / self.manifest.act_dim;
        self.z_prev.resize(b * z, 0.0);
        let mut mu = std::mem::take(&mut self.mu);
        let mut log_std = std::mem::take(&mut self.log_std);
        mu.resize(b * z, 0.0);
        log_std.resize(b * z, 0.0);
        let z_prev = std::mem::take(&mut self.z_prev);
        self.encode(reference, &z_prev, &mut mu, &mut log_std);
        self.decode(proprio, &mu, actions);
        // z_t becomes the next step's z_{t−1}; the old buffer is reused for the next μ.
        self.z_prev = mu;
        self.mu = z_prev;
        self.log_std = log_std;
    }
}
