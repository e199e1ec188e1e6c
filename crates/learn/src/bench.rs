//! End-to-end PPO throughput: samples per second, the share of wall time spent stepping
//! environments, and the cost of the rollout forward pass on plain `f32` versus dfdx.

use std::time::Instant;

use dfdx::prelude::{Cpu, TensorFromVec};
use serde::{Deserialize, Serialize};

use crate::env::Env;
use crate::ppo::{Ppo, PpoConfig};

/// What [`bench_ppo`] measured.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct BenchReport {
    /// Timed iterations (one warm-up iteration is run first and not counted).
    pub iterations: usize,
    /// Environment steps in the timed iterations.
    pub samples: u64,
    /// Wall time of the timed iterations.
    pub seconds: f64,
    /// `samples / seconds`, rollout and update together.
    pub samples_per_sec: f64,
    /// Fraction of the wall time spent inside environment stepping.
    pub env_time_fraction: f64,
    /// Rollout batch size `N` used for the forward-pass timings.
    pub batch: usize,
    /// Microseconds per policy-mean forward pass of `[N × obs]` on plain `f32` ([`crate::nn::MlpInference`]).
    pub forward_plain_us: f64,
    /// Microseconds per policy-mean forward pass of `[N × obs]` on dfdx without a tape.
    pub forward_dfdx_us: f64,
}

/// Train `iterations` PPO iterations on `envs` (after one warm-up iteration) and report
/// throughput; also times the rollout forward pass both ways.
pub fn bench_ppo<E: Env>(cfg: PpoConfig, envs: Vec<E>, iterations: usize) -> BenchReport {
    let mut ppo = Ppo::new(cfg, envs);
    ppo.iterate();
    let (mut samples, mut seconds, mut env_seconds) = (0u64, 0.0f64, 0.0f64);
    for _ in 0..iterations {
        let before = ppo.global_step;
        let m = ppo.iterate();
        let n = ppo.global_step - before;
        let secs = n as f64 / f64::from(m.samples_per_sec);
        samples += n;
        seconds += secs;
        env_seconds += secs * f64::from(m.env_time_fraction);
    }

    let (batch, od) = (ppo.envs.len(), ppo.envs.obs_dim());
    let obs = ppo.next_obs.clone();
    let mlp = &ppo.agent.policy.mean;
    let mut plain = mlp.inference();
    let mut out = vec![0.0; batch * mlp.outputs()];
    let reps = 2000;
    let t = Instant::now();
    for _ in 0..reps {
        plain.forward(&obs, &mut out);
    }
    let forward_plain_us = t.elapsed().as_secs_f64() * 1e6 / f64::from(reps);
    let dev = Cpu::default();
    let t = Instant::now();
    for _ in 0..reps {
        let x = dev.tensor_from_vec(obs.clone(), (batch, od));
        std::hint::black_box(mlp.forward(x).as_vec());
    }
    let forward_dfdx_us = t.elapsed().as_secs_f64() * 1e6 / f64::from(reps);

    BenchReport {
        iterations,
        samples,
        seconds,
        samples_per_sec: samples as f64 / seconds,
        env_time_fraction: env_seconds / seconds,
        batch,
        forward_plain_us,
        forward_dfdx_us,
    }
}
