//! `latent train`: the encoder and decoder fitted to a dataset by Adam on `−log π + β·KL` over
//! short sequences along which `z` is carried (each batch first rolls `z` forward with the
//! current encoder, then takes one taped step per row: backpropagation truncated to one step).

use std::path::{Path, PathBuf};
use std::time::Instant;

use dfdx::prelude::*;
use indicatif::{ProgressBar, ProgressStyle};
use rand::{Rng, SeedableRng};
use repertoire_learn::env::EnvRng;
use repertoire_learn::optim::{Adam, clip_grad_norm};
use repertoire_learn::policy::standard_normal;
use repertoire_scenes::obs::LayoutEntry;

use crate::dataset::Dataset;
use crate::error::{LatentError, Result, write_atomic};
use crate::model::{
    AWR_MIN_CELL, ActionTarget, Batch, DatasetRecord, InputNorm, LatentConfig, LatentManifest, LatentNet, LatentPolicy,
    LossStats, MODEL_FORMAT, TrainingFigures, Weighting, ar1_prior, column_stats, normalize_into,
};

/// Per-transition loss weights of `weighting` for `data` (mean 1).
pub fn transition_weights(data: &Dataset, weighting: Weighting) -> Vec<f32> {
    let n = data.len();
    match weighting {
        Weighting::Bc => vec![1.0; n],
        Weighting::ClipBalanced => {
            let k = data.manifest.skills.len().max(1);
            let mut count = vec![0usize; k];
            for &s in &data.skill {
                count[s as usize] += 1;
            }
            let used = count.iter().filter(|&&c| c > 0).count().max(1);
            data.skill.iter().map(|&s| n as f32 / (used as f32 * count[s as usize] as f32)).collect()
        }
        Weighting::Rwr { temperature, gamma, max_weight } => {
            exp_weights(&returns_to_go(data, gamma), temperature, max_weight)
        }
        Weighting::Awr { temperature, gamma, max_weight } => {
            let g = returns_to_go(data, gamma);
            let baseline = phase_baseline(data, &g);
            let advantage: Vec<f64> = g.iter().zip(&baseline).map(|(g, v)| g - v).collect();
            exp_weights(&advantage, temperature, max_weight)
        }
    }
}

/// The discounted imitation return-to-go of every transition, within its episode.
fn returns_to_go(data: &Dataset, gamma: f32) -> Vec<f64> {
    let n = data.len();
    let mut g = vec![0.0f64; n];
    let mut next = 0.0f64;
    for i in (0..n).rev() {
        let same = i + 1 < n && data.episode[i + 1] == data.episode[i];
        next = f64::from(data.reward[i]) + if same { f64::from(gamma) * next } else { 0.0 };
        g[i] = next;
    }
    g
}

/// AWR's value baseline: the mean of `g` over the transitions of the same skill at the same
/// reference frame, or over the skill's where that frame holds fewer than [`AWR_MIN_CELL`].
pub fn phase_baseline(data: &Dataset, g: &[f64]) -> Vec<f64> {
    use std::collections::HashMap;
    let mut cell: HashMap<(u32, u32), (f64, usize)> = HashMap::new();
    let mut skill: HashMap<u32, (f64, usize)> = HashMap::new();
    for ((&k, &f), &g) in data.skill.iter().zip(&data.frame).zip(g) {
        let c = cell.entry((k, f)).or_default();
        c.0 += g;
        c.1 += 1;
        let s = skill.entry(k).or_default();
        s.0 += g;
        s.1 += 1;
    }
    (0..data.len())
        .map(|i| {
            let (sum, count) = cell[&(data.skill[i], data.frame[i])];
            if count >= AWR_MIN_CELL {
                sum / count as f64
            } else {
                let (sum, count) = skill[&data.skill[i]];
                sum / count as f64
            }
        })
        .collect()
}

/// `exp(x / temperature)` of each `x`, normalised to mean 1 and capped at `max_weight`. The
/// exponents are shifted by the largest `x` (the normalisation cancels it) so that none overflows.
fn exp_weights(x: &[f64], temperature: f32, max_weight: f32) -> Vec<f32> {
    let top = x.iter().copied().fold(f64::NEG_INFINITY, f64::max);
    let w: Vec<f64> = x.iter().map(|x| ((x - top) / f64::from(temperature)).exp()).collect();
    let mean = w.iter().sum::<f64>() / w.len().max(1) as f64;
    w.iter().map(|x| ((x / mean.max(1e-300)) as f32).min(max_weight)).collect()
}

/// A training run in progress: the network, Adam, the normalised data and the sampler.
pub struct Trainer {
    /// Settings.
    pub cfg: LatentConfig,
    /// The network.
    pub net: LatentNet,
    adam: Adam,
    norm: InputNorm,
    proprio: Vec<f32>,
    reference: Vec<f32>,
    target: Vec<f32>,
    episode: Vec<u32>,
    weight: Vec<f32>,
    dims: (usize, usize, usize),
    rng: EnvRng,
    /// Updates taken.
    pub updates: usize,
    /// Rows seen.
    pub rows: u64,
}

impl Trainer {
    /// A fresh network for `data` (whose inputs are normalised here, once).
    pub fn new(data: &Dataset, cfg: LatentConfig) -> Result<Self> {
        cfg.validate()?;
        if data.len() < 2 {
            return Err(LatentError::Invalid(format!(
                "the dataset holds {} transitions; training needs more",
                data.len()
            )));
        }
        let (f, s, a) = (data.reference_dim(), data.proprio_dim(), data.act_dim());
        let (proprio_mean, proprio_std) = column_stats(&data.proprio, s);
        let (reference_mean, reference_std) = column_stats(&data.reference, f);
        let norm = InputNorm { proprio_mean, proprio_std, reference_mean, reference_std };
        let mut proprio = vec![0.0f32; data.proprio.len()];
        for (src, dst) in data.proprio.chunks_exact(s).zip(proprio.chunks_exact_mut(s)) {
            normalize_into(src, &norm.proprio_mean, &norm.proprio_std, dst);
        }
        let mut reference = vec![0.0f32; data.reference.len()];
        for (src, dst) in data.reference.chunks_exact(f).zip(reference.chunks_exact_mut(f)) {
            normalize_into(src, &norm.reference_mean, &norm.reference_std, dst);
        }
        let target = match cfg.target {
            ActionTarget::Mean => data.mean_action.clone(),
            ActionTarget::Noisy => data.noisy_action.clone(),
        };
        let mut rng = EnvRng::seed_from_u64(cfg.seed);
        let dev = Cpu::default();
        let mut net = LatentNet::new(&dev, &cfg, f, s, a, &mut rng);
        let adam = Adam::new(&mut net, cfg.learning_rate);
        let weight = transition_weights(data, cfg.weighting);
        Ok(Trainer {
            cfg,
            net,
            adam,
            norm,
            proprio,
            reference,
            target,
            episode: data.episode.clone(),
            weight,
            dims: (f, s, a),
            rng,
            updates: 0,
            rows: 0,
        })
    }

    /// Draws `batch_sequences` sequences of `seq_len` steps from random transitions and rolls
    /// `z` along each with the current encoder (rows past an episode's end get weight 0).
    pub fn sample_batch(&mut self) -> Batch {
        let (f, s, a) = self.dims;
        let (t_len, b) = (self.cfg.seq_len, self.cfg.batch_sequences);
        let z = self.cfg.latent_dim;
        let rows = t_len * b;
        let n = self.episode.len();
        let starts: Vec<usize> = (0..b).map(|_| self.rng.random_range(0..n)).collect();
        let mut encoder = self.net.encoder_inference();
        let mut batch = Batch {
            rows,
            enc_in: vec![0.0; rows * (f + z)],
            proprio: vec![0.0; rows * s],
            target: vec![0.0; rows * a],
            eps: vec![0.0; rows * z],
            prior_mean: vec![0.0; rows * z],
            prior_var: vec![1.0; rows],
            weight: vec![0.0; rows],
        };
        let mut z_prev = vec![0.0f32; b * z];
        let mut out = vec![0.0f32; b * 2 * z];
        for t in 0..t_len {
            let base = t * b;
            for (j, &start) in starts.iter().enumerate() {
                let r = base + j;
                let i = start + t;
                let valid = i < n && self.episode[i] == self.episode[start];
                let row = &mut batch.enc_in[r * (f + z)..(r + 1) * (f + z)];
                if valid {
                    row[..f].copy_from_slice(&self.reference[i * f..(i + 1) * f]);
                    batch.proprio[r * s..(r + 1) * s].copy_from_slice(&self.proprio[i * s..(i + 1) * s]);
                    batch.target[r * a..(r + 1) * a].copy_from_slice(&self.target[i * a..(i + 1) * a]);
                    batch.weight[r] = self.weight[i];
                }
                row[f..].copy_from_slice(&z_prev[j * z..(j + 1) * z]);
                for d in 0..z {
                    let (m, v) = ar1_prior(z_prev[j * z + d], self.cfg.alpha, t == 0);
                    batch.prior_mean[r * z + d] = m;
                    batch.prior_var[r] = v;
                }
                for e in &mut batch.eps[r * z..(r + 1) * z] {
                    *e = standard_normal(&mut self.rng);
                }
            }
            encoder.forward(&batch.enc_in[base * (f + z)..(base + b) * (f + z)], &mut out);
            for j in 0..b {
                let r = base + j;
                for d in 0..z {
                    let (mu, ls) = (out[j * 2 * z + d], out[j * 2 * z + z + d]);
                    z_prev[j * z + d] = mu + ls.exp() * batch.eps[r * z + d];
                }
            }
        }
        batch
    }

    /// The loss figures of `batch` under the current weights (no update).
    pub fn loss_on(&self, batch: &Batch) -> LossStats {
        self.net.loss(&self.cfg, batch).1
    }

    /// One Adam step on a fresh batch; an error if the loss is not finite.
    pub fn update(&mut self) -> Result<LossStats> {
        let batch = self.sample_batch();
        let (loss, stats) = self.net.loss(&self.cfg, &batch);
        if !stats.loss.is_finite() {
            return Err(LatentError::Invalid(format!(
                "the loss became {} at update {} (nll {}, kl {}); lower the learning rate",
                stats.loss, self.updates, stats.nll, stats.kl
            )));
        }
        let mut grads = loss.backward();
        clip_grad_norm(&mut self.net, &mut grads, self.cfg.max_grad_norm);
        self.adam.update(&mut self.net, &mut grads);
        self.updates += 1;
        self.rows += batch.weight.iter().filter(|&&w| w > 0.0).count() as u64;
        Ok(stats)
    }

    /// The frozen policy of the current weights, with a manifest describing `data`.
    pub fn policy(&self, data: &Dataset, data_path: &Path, training: TrainingFigures, command: &str) -> LatentPolicy {
        let (f, s, _) = self.dims;
        let z = self.cfg.latent_dim;
        let mut encoder_input = data.manifest.reference.clone();
        encoder_input.push(LayoutEntry { name: "z_prev".into(), offset: f, len: z });
        let mut decoder_input = data.manifest.proprio.entries.clone();
        decoder_input.push(LayoutEntry { name: "z".into(), offset: s, len: z });
        let manifest = LatentManifest {
            format: MODEL_FORMAT,
            latent_dim: z,
            alpha: self.cfg.alpha,
            beta: self.cfg.beta,
            k: data.manifest.k,
            act_dim: data.act_dim(),
            encoder_input,
            decoder_features: data.manifest.proprio.features.clone(),
            decoder_input,
            body_hash: data.manifest.body_hash.clone(),
            control_hz: data.manifest.control_hz,
            config: self.cfg.clone(),
            training,
            dataset: DatasetRecord {
                path: data_path.display().to_string(),
                data_fnv1a: data.manifest.data_fnv1a,
                steps: data.len(),
                skills: data.manifest.skills.iter().map(|s| s.name.clone()).collect(),
            },
            weights_fnv1a: 0,
            command: command.to_string(),
            git_hash: repertoire_learn::run_dir::git_hash(),
        };
        LatentPolicy::new(manifest, self.net.encoder_inference(), self.net.decoder_inference(), self.norm.clone())
    }
}

/// Logged training figures: `(update, seconds, mean figures since the last log)`.
pub type History = Vec<(usize, f64, LossStats)>;

/// Limits and outputs of a training run.
#[derive(Debug, Clone)]
pub struct TrainOptions {
    /// Most Adam updates.
    pub max_updates: usize,
    /// Most wall-clock seconds.
    pub max_seconds: f64,
    /// Figures are averaged and logged every this many updates.
    pub log_every: usize,
    /// Show a progress bar.
    pub progress: bool,
    /// Where the per-log-interval figures go (CSV, written at the end).
    pub metrics_csv: Option<PathBuf>,
    /// The command line, recorded in the manifest.
    pub command: String,
}

/// Trains a latent model on `data` (read from `data_path`) until either limit; returns the
/// policy and the logged figures `(update, seconds, mean figures since the last log)`.
pub fn train(
    data: &Dataset,
    data_path: &Path,
    cfg: LatentConfig,
    opts: &TrainOptions,
) -> Result<(LatentPolicy, History)> {
    let mut trainer = Trainer::new(data, cfg)?;
    let begin = Instant::now();
    let bar = if opts.progress { ProgressBar::new(opts.max_updates as u64) } else { ProgressBar::hidden() };
    bar.set_style(
        ProgressStyle::with_template("train [{bar:30}] {pos}/{len} updates ({per_sec}, ETA {eta}) {msg}")
            .expect("valid template")
            .progress_chars("=> "),
    );
    let every = opts.log_every.max(1);
    let mut history = Vec::new();
    let mut acc = LossStats::default();
    let mut in_acc = 0usize;
    let mut first = None;
    let mut last = LossStats::default();
    while trainer.updates < opts.max_updates && begin.elapsed().as_secs_f64() < opts.max_seconds {
        let st = trainer.update()?;
        first.get_or_insert(st);
        acc.nll += st.nll;
        acc.kl += st.kl;
        acc.action_mse += st.action_mse;
        acc.loss += st.loss;
        in_acc += 1;
        bar.inc(1);
        if in_acc == every {
            let k = in_acc as f32;
            last = LossStats { nll: acc.nll / k, kl: acc.kl / k, action_mse: acc.action_mse / k, loss: acc.loss / k };
            let secs = begin.elapsed().as_secs_f64();
            tracing::info!(
                update = trainer.updates,
                seconds = secs,
                loss = last.loss,
                nll = last.nll,
                kl = last.kl,
                action_mse = last.action_mse,
                "latent train"
            );
            bar.set_message(format!("loss {:.2} kl {:.2} mse {:.4}", last.loss, last.kl, last.action_mse));
            history.push((trainer.updates, secs, last));
            acc = LossStats::default();
            in_acc = 0;
        }
    }
    if in_acc > 0 {
        let k = in_acc as f32;
        last = LossStats { nll: acc.nll / k, kl: acc.kl / k, action_mse: acc.action_mse / k, loss: acc.loss / k };
        history.push((trainer.updates, begin.elapsed().as_secs_f64(), last));
    }
    bar.finish_and_clear();
    let figures = TrainingFigures {
        updates: trainer.updates,
        rows: trainer.rows,
        seconds: begin.elapsed().as_secs_f64(),
        first: first.unwrap_or_default(),
        last,
    };
    if let Some(path) = &opts.metrics_csv {
        let mut text = String::from("update,seconds,loss,nll,kl,action_mse\n");
        for (u, s, st) in &history {
            text.push_str(&format!("{u},{s:.3},{},{},{},{}\n", st.loss, st.nll, st.kl, st.action_mse));
        }
        write_atomic(path, text.as_bytes())?;
    }
    Ok((trainer.policy(data, data_path, figures, &opts.command), history))
}
