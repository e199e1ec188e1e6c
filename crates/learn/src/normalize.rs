//! Running statistics for observation normalisation and reward scaling.

use serde::{Deserialize, Serialize};

/// Running per-dimension mean and variance (Chan et al.'s parallel merge of batch statistics).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct RunningMeanStd {
    /// Per-dimension mean.
    pub mean: Vec<f64>,
    /// Per-dimension (population) variance.
    pub var: Vec<f64>,
    /// Number of samples seen (starts at a tiny ε, as in Gym/CleanRL, to avoid dividing by 0).
    pub count: f64,
}

impl RunningMeanStd {
    /// Zero mean, unit variance, for vectors of `dim` values.
    pub fn new(dim: usize) -> Self {
        RunningMeanStd { mean: vec![0.0; dim], var: vec![1.0; dim], count: 1e-4 }
    }

    /// Vector width.
    pub fn dim(&self) -> usize {
        self.mean.len()
    }

    /// Fold in a batch of rows `[B × dim]`.
    pub fn update(&mut self, batch: &[f32]) {
        let d = self.dim();
        let n = (batch.len() / d) as f64;
        if n == 0.0 {
            return;
        }
        for j in 0..d {
            let col = batch.iter().skip(j).step_by(d).map(|&x| f64::from(x));
            let mean = col.clone().sum::<f64>() / n;
            let var = col.map(|x| (x - mean) * (x - mean)).sum::<f64>() / n;
            self.merge_dim(j, mean, var, n);
        }
        self.count += n;
    }

    /// Merge another set of statistics into this one.
    pub fn merge(&mut self, other: &RunningMeanStd) {
        for j in 0..self.dim() {
            self.merge_dim(j, other.mean[j], other.var[j], other.count);
        }
        self.count += other.count;
    }

    /// Merge `n` samples with `mean` and `var` into dimension `j` (count is updated by the caller).
    fn merge_dim(&mut self, j: usize, mean: f64, var: f64, n: f64) {
        let total = self.count + n;
        let delta = mean - self.mean[j];
        let m2 = self.var[j] * self.count + var * n + delta * delta * self.count * n / total;
        self.mean[j] += delta * n / total;
        self.var[j] = m2 / total;
    }

    /// Write `clip((x − μ) / √(σ² + ε), −clip, clip)` of `x` into `out` (same length, rows of dim).
    pub fn normalize(&self, x: &[f32], out: &mut [f32], clip: f32) {
        let d = self.dim();
        for (o, (i, &v)) in out.iter_mut().zip(x.iter().enumerate()) {
            let j = i % d;
            let z = (f64::from(v) - self.mean[j]) / (self.var[j] + 1e-8).sqrt();
            *o = (z as f32).clamp(-clip, clip);
        }
    }
}

/// Scales rewards by the running standard deviation of each env's discounted return (as Gym's
/// `NormalizeReward` and CleanRL do).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct RewardScaler {
    /// Statistics of the discounted returns.
    pub rms: RunningMeanStd,
    /// Each env's running discounted return.
    pub returns: Vec<f64>,
    /// Discount factor.
    pub gamma: f64,
}

impl RewardScaler {
    /// A scaler for `n_envs` environments.
    pub fn new(n_envs: usize, gamma: f64) -> Self {
        RewardScaler { rms: RunningMeanStd::new(1), returns: vec![0.0; n_envs], gamma }
    }

    /// Scale one tick's `rewards` in place; `done[i]` restarts env `i`'s return afterwards.
    pub fn scale(&mut self, rewards: &mut [f32], done: impl Iterator<Item = bool>) {
        for (ret, &r) in self.returns.iter_mut().zip(rewards.iter()) {
            *ret = *ret * self.gamma + f64::from(r);
        }
        let n = self.returns.len() as f64;
        let mean = self.returns.iter().sum::<f64>() / n;
        let var = self.returns.iter().map(|r| (r - mean).powi(2)).sum::<f64>() / n;
        self.rms.merge_dim(0, mean, var, n);
        self.rms.count += n;
        let std = (self.rms.var[0] + 1e-8).sqrt();
        for ((r, ret), d) in rewards.iter_mut().zip(self.returns.iter_mut()).zip(done) {
            *r = (f64::from(*r) / std) as f32;
            if d {
                *ret = 0.0;
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn merged_statistics_equal_batch_statistics() {
        let data: Vec<f32> = (0..60).map(|i| ((i * 37 % 17) as f32 - 3.0) * 0.7).collect();
        // Whole batch at once, 3 dims.
        let mut whole = RunningMeanStd::new(3);
        whole.count = 0.0;
        whole.update(&data);
        // Same data in three uneven pieces, merged.
        let mut parts = RunningMeanStd::new(3);
        parts.count = 0.0;
        let mut other = RunningMeanStd::new(3);
        other.count = 0.0;
        parts.update(&data[..9]);
        other.update(&data[9..30]);
        parts.merge(&other);
        parts.update(&data[30..]);
        for j in 0..3 {
            let col: Vec<f64> = data.iter().skip(j).step_by(3).map(|&x| f64::from(x)).collect();
            let n = col.len() as f64;
            let mean = col.iter().sum::<f64>() / n;
            let var = col.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / n;
            for s in [&whole, &parts] {
                assert!((s.mean[j] - mean).abs() < 1e-9, "{} vs {mean}", s.mean[j]);
                assert!((s.var[j] - var).abs() < 1e-9, "{} vs {var}", s.var[j]);
            }
        }
        assert_eq!(parts.count, 20.0);
    }

    #[test]
    fn normalize_standardises_and_clips() {
        let mut s = RunningMeanStd::new(1);
        s.count = 0.0;
        s.update(&[1.0, 3.0]);
        let mut out = [0.0; 3];
        s.normalize(&[2.0, 3.0, 100.0], &mut out, 5.0);
        assert!(out[0].abs() < 1e-6 && (out[1] - 1.0).abs() < 1e-4 && out[2] == 5.0);
    }
}
