//! A binary classifier: an MLP on normalised inputs giving the log-odds of a yes, fitted by
//! minibatch Adam on the logistic loss. The meta-controller's readiness (will the terminal
//! skill succeed from here?) is one; anything that labels states yes or no can use it.
//!
//! [`fit`] returns the trained [`Classifier`] (plain `f32` weights and the frozen input
//! statistics, as the acting policies keep them); [`Classifier::save`] writes one safetensors
//! file atomically and [`Classifier::load`] refuses a truncated, corrupt or ill-shaped one.

use std::path::Path;

use dfdx::prelude::*;
use rand::SeedableRng;
use rand::rngs::StdRng;
use safetensors::SafeTensors;

use crate::acting::{Entry, bytes64, corrupt, f64s, layer_entries, read_mlp, write_entries};
use crate::checkpoint::CheckpointError;
use crate::nn::{Mlp, MlpInference};
use crate::normalize::RunningMeanStd;
use crate::optim::{Adam, clip_grad_norm};
use crate::ppo::OBS_CLIP;

/// How a classifier is fitted.
#[derive(Debug, Clone, PartialEq)]
pub struct ClassifierConfig {
    /// Hidden widths (tanh).
    pub hidden: Vec<usize>,
    /// Adam's learning rate.
    pub lr: f64,
    /// Passes over the data.
    pub epochs: usize,
    /// Rows per gradient step.
    pub batch: usize,
    /// Seeds the weights and the minibatch order.
    pub seed: u64,
}

impl Default for ClassifierConfig {
    fn default() -> Self {
        ClassifierConfig { hidden: vec![128, 128], lr: 1e-3, epochs: 40, batch: 256, seed: 1 }
    }
}

/// A fitted classifier: input statistics and the network giving the log-odds.
#[derive(Clone, Debug)]
pub struct Classifier {
    /// Normalised input → log-odds (one output).
    pub net: MlpInference,
    /// Input statistics of the data it was fitted on.
    pub input_rms: RunningMeanStd,
    scratch: Vec<f32>,
    out: Vec<f32>,
}

/// The logistic function.
pub fn sigmoid(z: f32) -> f32 {
    1.0 / (1.0 + (-z).exp())
}

impl Classifier {
    /// Input width.
    pub fn inputs(&self) -> usize {
        self.net.inputs()
    }

    /// The probability of a yes for each row of `x` (`[B × inputs]`), into `probs` (`[B]`).
    pub fn probabilities(&mut self, x: &[f32], probs: &mut [f32]) {
        self.scratch.resize(x.len(), 0.0);
        self.input_rms.normalize(x, &mut self.scratch, OBS_CLIP);
        self.net.forward(&self.scratch, probs);
        for p in probs.iter_mut() {
            *p = sigmoid(*p);
        }
    }

    /// The probability of a yes for one input row.
    pub fn probability(&mut self, x: &[f32]) -> f32 {
        let mut out = std::mem::take(&mut self.out);
        out.resize(1, 0.0);
        self.probabilities(x, &mut out);
        let p = out[0];
        self.out = out;
        p
    }

    /// Writes the classifier to `path` (safetensors) via a temporary sibling and a rename.
    pub fn save(&self, path: &Path) -> Result<(), CheckpointError> {
        let mut entries: Vec<Entry> = layer_entries("logit", &self.net);
        let d = self.input_rms.dim();
        entries.push(("input.mean".into(), safetensors::Dtype::F64, vec![d], bytes64(&self.input_rms.mean)));
        entries.push(("input.var".into(), safetensors::Dtype::F64, vec![d], bytes64(&self.input_rms.var)));
        entries.push(("input.count".into(), safetensors::Dtype::F64, vec![1], bytes64(&[self.input_rms.count])));
        write_entries(path, &entries, "repertoire-classifier-1")
    }

    /// Reads a classifier written by [`Classifier::save`].
    pub fn load(path: &Path) -> Result<Self, CheckpointError> {
        let bytes = std::fs::read(path).map_err(|source| CheckpointError::Io { path: path.to_path_buf(), source })?;
        let st = SafeTensors::deserialize(&bytes).map_err(|e| corrupt(path, e.to_string()))?;
        let net = read_mlp(path, &st, "logit")?;
        if net.outputs() != 1 {
            return Err(corrupt(path, format!("the network gives {} outputs, a classifier one", net.outputs())));
        }
        let mean = f64s(path, &st, "input.mean")?;
        let var = f64s(path, &st, "input.var")?;
        let count = f64s(path, &st, "input.count")?;
        if mean.len() != net.inputs() || var.len() != net.inputs() || count.len() != 1 {
            return Err(corrupt(path, format!("input statistics do not fit {} inputs", net.inputs())));
        }
        if mean.iter().chain(&var).any(|v| !v.is_finite()) || var.iter().any(|&v| v < 0.0) {
            return Err(corrupt(path, "input statistics hold a NaN, infinite or negative variance"));
        }
        Ok(Classifier {
            net,
            input_rms: RunningMeanStd { mean, var, count: count[0] },
            scratch: Vec::new(),
            out: Vec::new(),
        })
    }
}

/// Fits a classifier to rows `x` (`[N × dim]`) labelled `labels` (`N` of 0 or 1); returns it
/// with the mean logistic loss of each epoch. `Err` when the rows and labels do not match, a
/// label is not 0 or 1, or a value is not finite.
pub fn fit(x: &[f32], labels: &[f32], cfg: &ClassifierConfig) -> Result<(Classifier, Vec<f32>), String> {
    let n = labels.len();
    if n == 0 || !x.len().is_multiple_of(n) {
        return Err(format!("{} input values do not make {n} rows", x.len()));
    }
    let dim = x.len() / n;
    if let Some(i) = labels.iter().position(|&y| y != 0.0 && y != 1.0) {
        return Err(format!("label {i} is {}, not 0 or 1", labels[i]));
    }
    if let Some(i) = x.iter().position(|v| !v.is_finite()) {
        return Err(format!("row {} holds a NaN or infinite value at input {}", i / dim, i % dim));
    }
    let dev = Cpu::default();
    let mut rng = StdRng::seed_from_u64(cfg.seed);
    let mut net = Mlp::new(&dev, dim, &cfg.hidden, 1, 0.01, &mut rng);
    let mut adam = Adam::new(&mut net, cfg.lr);
    let mut input_rms = RunningMeanStd::new(dim);
    input_rms.update(x);
    let mut normalised = vec![0.0; x.len()];
    input_rms.normalize(x, &mut normalised, OBS_CLIP);
    let mut order: Vec<usize> = (0..n).collect();
    let mut losses = Vec::with_capacity(cfg.epochs);
    for _ in 0..cfg.epochs {
        crate::ppo::shuffle(&mut order, &mut rng);
        let mut total = 0.0;
        for mb in order.chunks(cfg.batch.max(1)) {
            let m = mb.len();
            let rows: Vec<f32> = mb.iter().flat_map(|&r| &normalised[r * dim..(r + 1) * dim]).copied().collect();
            let ys: Vec<f32> = mb.iter().map(|&r| labels[r]).collect();
            let xs = dev.tensor_from_vec(rows, (m, dim));
            let ys = dev.tensor_from_vec(ys, (m, 1));
            let logits = net.forward(xs.leaky_trace());
            let loss = dfdx::losses::binary_cross_entropy_with_logits_loss(logits, ys);
            total += loss.as_vec()[0] * m as f32;
            let mut grads = loss.backward();
            clip_grad_norm(&mut net, &mut grads, 1.0);
            adam.update(&mut net, &mut grads);
        }
        losses.push(total / n as f32);
    }
    Ok((Classifier { net: net.inference(), input_rms, scratch: Vec::new(), out: Vec::new() }, losses))
}

/// How well probabilities `probs` separate `labels` (0 or 1).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Separation {
    /// Rows, and of them labelled 1.
    pub rows: usize,
    /// Rows labelled 1.
    pub positives: usize,
    /// Mean logistic loss.
    pub loss: f64,
    /// Area under the ROC curve (0.5: no better than chance; ties count half).
    pub auc: f64,
    /// Of the rows at or above `threshold`, the share labelled 1 (0 when none is).
    pub precision: f64,
    /// Of the rows labelled 1, the share at or above `threshold`.
    pub recall: f64,
    /// The threshold `precision` and `recall` are for.
    pub threshold: f32,
}

/// [`Separation`] of `probs` against `labels` at `threshold`.
pub fn separation(probs: &[f32], labels: &[f32], threshold: f32) -> Separation {
    let n = labels.len();
    let positives = labels.iter().filter(|&&y| y > 0.5).count();
    let eps = 1e-7f64;
    let loss = probs
        .iter()
        .zip(labels)
        .map(|(&p, &y)| {
            let p = f64::from(p).clamp(eps, 1.0 - eps);
            if y > 0.5 { -p.ln() } else { -(1.0 - p).ln() }
        })
        .sum::<f64>()
        / n.max(1) as f64;
    // AUC by ranks (Mann–Whitney U), ties given their mean rank.
    let mut idx: Vec<usize> = (0..n).collect();
    idx.sort_by(|&a, &b| probs[a].total_cmp(&probs[b]));
    let mut ranks = vec![0.0f64; n];
    let mut i = 0;
    while i < n {
        let mut j = i;
        while j + 1 < n && probs[idx[j + 1]] == probs[idx[i]] {
            j += 1;
        }
        let mean_rank = (i + j) as f64 / 2.0 + 1.0;
        for k in i..=j {
            ranks[idx[k]] = mean_rank;
        }
        i = j + 1;
    }
    let negatives = n - positives;
    let auc = if positives == 0 || negatives == 0 {
        0.5
    } else {
        let rank_sum: f64 = (0..n).filter(|&r| labels[r] > 0.5).map(|r| ranks[r]).sum();
        (rank_sum - (positives * (positives + 1)) as f64 / 2.0) / (positives * negatives) as f64
    };
    let called = probs.iter().filter(|&&p| p >= threshold).count();
    let hits = probs.iter().zip(labels).filter(|&(&p, &y)| p >= threshold && y > 0.5).count();
    Separation {
        rows: n,
        positives,
        loss,
        auc,
        precision: if called == 0 { 0.0 } else { hits as f64 / called as f64 },
        recall: if positives == 0 { 0.0 } else { hits as f64 / positives as f64 },
        threshold,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::Rng;

    /// Points in the plane labelled by which side of a circle they fall: an MLP separates them,
    /// a linear model could not.
    fn circle(n: usize, seed: u64) -> (Vec<f32>, Vec<f32>) {
        let mut rng = StdRng::seed_from_u64(seed);
        let mut x = Vec::new();
        let mut y = Vec::new();
        for _ in 0..n {
            let (a, b): (f32, f32) = (rng.random_range(-2.0..2.0), rng.random_range(-2.0..2.0));
            x.extend([a * 3.0 + 10.0, b]);
            y.push(if a * a + b * b < 1.0 { 1.0 } else { 0.0 });
        }
        (x, y)
    }

    #[test]
    fn a_fitted_classifier_separates_held_out_points_and_survives_a_save() {
        let (x, y) = circle(4000, 1);
        let cfg = ClassifierConfig { epochs: 30, ..ClassifierConfig::default() };
        let (mut c, losses) = fit(&x, &y, &cfg).unwrap();
        assert!(losses.last().unwrap() < &(losses[0] * 0.5), "losses {losses:?}");
        let (tx, ty) = circle(1000, 2);
        let mut probs = vec![0.0; ty.len()];
        c.probabilities(&tx, &mut probs);
        let s = separation(&probs, &ty, 0.5);
        assert!(s.auc > 0.97, "{s:?}");
        assert!(s.precision > 0.85 && s.recall > 0.85, "{s:?}");

        let dir = std::env::temp_dir().join(format!("repertoire-classify-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("c.safetensors");
        c.save(&path).unwrap();
        let mut back = Classifier::load(&path).unwrap();
        assert_eq!(back.probability(&tx[..2]), c.probability(&tx[..2]));

        std::fs::write(&path, &std::fs::read(&path).unwrap()[..100]).unwrap();
        let err = Classifier::load(&path).unwrap_err().to_string();
        assert!(err.contains("c.safetensors"), "{err}");
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn separation_counts_ranks_and_thresholds() {
        let s = separation(&[0.1, 0.4, 0.35, 0.8], &[0.0, 0.0, 1.0, 1.0], 0.5);
        assert_eq!((s.rows, s.positives), (4, 2));
        assert!((s.auc - 0.75).abs() < 1e-12, "{s:?}");
        assert_eq!((s.precision, s.recall), (1.0, 0.5));
        let chance = separation(&[0.5; 4], &[0.0, 1.0, 0.0, 1.0], 0.5);
        assert_eq!(chance.auc, 0.5);
    }

    #[test]
    fn bad_labels_and_ragged_rows_are_refused() {
        assert!(fit(&[1.0, 2.0, 3.0], &[0.0, 1.0], &ClassifierConfig::default()).unwrap_err().contains("rows"));
        assert!(fit(&[1.0, 2.0], &[0.0, 0.5], &ClassifierConfig::default()).unwrap_err().contains("label 1"));
        assert!(fit(&[1.0, f32::NAN], &[0.0, 1.0], &ClassifierConfig::default()).unwrap_err().contains("row 1"));
    }
}
