//! Proximal Policy Optimisation (Schulman et al. 2017) with GAE, in the shape of CleanRL's
//! `ppo_continuous_action.py`: hyper-parameters in [`PpoConfig`], one rollout loop in
//! [`Ppo::collect`], [`gae`] in ten lines, and the clipped loss term by term in [`Ppo::update`].

use std::time::Instant;

use dfdx::prelude::*;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use crate::env::{Env, EpisodeStats, VecEnv};
use crate::nn::{ParamMut, Parameters, prefixed};
use crate::normalize::{RewardScaler, RunningMeanStd};
use crate::optim::{Adam, clip_grad_norm};
use crate::policy::{GaussianInference, GaussianPolicy, HybridInference, HybridPolicy, PolicyConfig, ValueNet};

/// Observations are clipped to ±this many standard deviations after normalisation.
pub const OBS_CLIP: f32 = 10.0;

/// Every PPO hyper-parameter, in one RON-serialisable struct (names follow CleanRL).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct PpoConfig {
    /// Seed of every random stream (weights, actions, minibatches, environments).
    pub seed: u64,
    /// Number of parallel environments `N`.
    pub num_envs: usize,
    /// Rollout length `T` per environment per iteration.
    pub num_steps: usize,
    /// Planned number of iterations (the horizon of learning-rate annealing).
    pub num_iterations: usize,
    /// Adam learning rate.
    pub learning_rate: f64,
    /// Anneal the learning rate linearly to 0 over `num_iterations`.
    pub anneal_lr: bool,
    /// Discount `γ`.
    pub gamma: f32,
    /// GAE `λ`.
    pub gae_lambda: f32,
    /// Minibatches per epoch.
    pub num_minibatches: usize,
    /// Epochs `K` over each rollout.
    pub update_epochs: usize,
    /// Normalise advantages per minibatch.
    pub norm_adv: bool,
    /// Surrogate clipping `ε`.
    pub clip_coef: f32,
    /// Clip the value loss around the old values with the same `ε`.
    pub clip_vloss: bool,
    /// Entropy bonus coefficient.
    pub ent_coef: f32,
    /// Value loss coefficient.
    pub vf_coef: f32,
    /// Global gradient-norm limit.
    pub max_grad_norm: f32,
    /// Stop the epochs early when the approximate KL exceeds this.
    pub target_kl: Option<f32>,
    /// The first this many iterations train the value network only, the policy held as it is;
    /// Adam then starts afresh for both. A policy fine-tuned with a fresh critic (or on new
    /// starts its old critic never saw) is otherwise pushed by advantages that are mostly the
    /// critic's error, and a converged policy can unlearn in those first iterations what the
    /// fine-tune meant to build on. 0: none.
    pub critic_warmup: usize,
    /// Normalise observations with running statistics.
    pub normalize_obs: bool,
    /// Scale rewards by the running std of the discounted return.
    pub normalize_reward: bool,
    /// Step environments on rayon's pool (results are identical either way).
    pub parallel_envs: bool,
    /// Each minibatch's gradient is computed in this many shards on rayon's pool and summed in
    /// a fixed order, so results depend on this number but not on the number of threads.
    pub grad_shards: usize,
    /// Network sizes.
    pub policy: PolicyConfig,
}

impl Default for PpoConfig {
    fn default() -> Self {
        PpoConfig {
            seed: 1,
            num_envs: 8,
            num_steps: 256,
            num_iterations: 100,
            learning_rate: 3e-4,
            anneal_lr: true,
            gamma: 0.99,
            gae_lambda: 0.95,
            num_minibatches: 32,
            update_epochs: 10,
            norm_adv: true,
            clip_coef: 0.2,
            clip_vloss: true,
            ent_coef: 0.0,
            vf_coef: 0.5,
            max_grad_norm: 0.5,
            target_kl: None,
            critic_warmup: 0,
            normalize_obs: true,
            normalize_reward: true,
            parallel_envs: true,
            grad_shards: 2,
            policy: PolicyConfig::default(),
        }
    }
}

/// Generalised advantage estimation over a rollout laid out `[T × N]` (row `t`, env `i` at
/// `t·N + i`). A terminated step has no future; a truncated one bootstraps from
/// `final_values` (the value of its final observation); either way the trace is cut there.
/// Returns `(advantages, returns)` with `returns = advantages + values`.
#[allow(clippy::too_many_arguments)]
pub fn gae(
    rewards: &[f32],
    values: &[f32],
    terminated: &[bool],
    truncated: &[bool],
    final_values: &[f32],
    last_values: &[f32],
    gamma: f32,
    lambda: f32,
) -> (Vec<f32>, Vec<f32>) {
    let n = last_values.len();
    let t_len = rewards.len() / n;
    let mut adv = vec![0.0; rewards.len()];
    let mut running = vec![0.0; n];
    for t in (0..t_len).rev() {
        for i in 0..n {
            let k = t * n + i;
            let (next_value, carry) = if terminated[k] {
                (0.0, 0.0)
            } else if truncated[k] {
                (final_values[k], 0.0)
            } else if t + 1 == t_len {
                (last_values[i], 1.0)
            } else {
                (values[k + n], 1.0)
            };
            let delta = rewards[k] + gamma * next_value - values[k];
            running[i] = delta + gamma * lambda * carry * running[i];
            adv[k] = running[i];
        }
    }
    let returns = adv.iter().zip(values).map(|(a, v)| a + v).collect();
    (adv, returns)
}

/// The policy and value networks, listed together so one Adam and one gradient norm cover both.
#[derive(Clone, Debug)]
pub struct ActorCritic {
    /// `π(a|s)` for continuous actions.
    pub policy: GaussianPolicy,
    /// `π(option, continuous | s)` when the environment's actions are hybrid
    /// ([`Env::options`]); it then replaces `policy`, which is neither trained nor saved.
    pub hybrid: Option<HybridPolicy>,
    /// `V(s)`.
    pub value: ValueNet,
}

impl Parameters for ActorCritic {
    fn params_mut(&mut self) -> Vec<(String, ParamMut<'_>)> {
        let mut out = match &mut self.hybrid {
            Some(h) => prefixed("hybrid", h.params_mut()),
            None => prefixed("policy", self.policy.params_mut()),
        };
        out.extend(prefixed("value", self.value.params_mut()));
        out
    }
}

/// What one iteration measured (one CSV row / JSONL line).
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct IterationMetrics {
    /// Iterations completed, this one included.
    pub iteration: usize,
    /// Environment steps taken so far (all envs).
    pub global_step: u64,
    /// Episodes that ended during this iteration.
    pub episodes: usize,
    /// Mean undiscounted return of those episodes (NaN when none ended).
    pub mean_return: f32,
    /// Mean length of those episodes.
    pub mean_length: f32,
    /// Fraction of those episodes that terminated early (rather than reaching the time limit).
    pub termination_rate: f32,
    /// Per-episode mean of each named reward term.
    pub terms: Vec<(String, f32)>,
    /// Approximate KL `E[(r − 1) − log r]` of the last minibatch.
    pub approx_kl: f32,
    /// Fraction of samples whose ratio left `[1 − ε, 1 + ε]`.
    pub clip_fraction: f32,
    /// Mean policy entropy.
    pub entropy: f32,
    /// `1 − Var(R − V) / Var(R)` of the rollout.
    pub explained_variance: f32,
    /// Mean clipped-surrogate loss.
    pub policy_loss: f32,
    /// Mean value loss.
    pub value_loss: f32,
    /// Mean gradient norm before clipping.
    pub grad_norm: f32,
    /// Learning rate used.
    pub learning_rate: f64,
    /// Epochs run (fewer than configured after a KL early stop).
    pub epochs: usize,
    /// Environment steps per second of wall time, update included.
    pub samples_per_sec: f32,
    /// Fraction of the iteration's wall time spent stepping environments.
    pub env_time_fraction: f32,
}

/// Rollout storage `[T × N]`, allocated once.
#[derive(Clone, Debug)]
struct Rollout {
    obs: Vec<f32>,
    actions: Vec<f32>,
    log_probs: Vec<f32>,
    rewards: Vec<f32>,
    values: Vec<f32>,
    terminated: Vec<bool>,
    truncated: Vec<bool>,
    final_values: Vec<f32>,
    last_values: Vec<f32>,
    /// Allowed options per sample, `[T·N × K]` (hybrid actions only).
    masks: Vec<bool>,
}

/// A PPO learner owning its environments, networks, optimiser, normalisers and random streams.
pub struct Ppo<E: Env> {
    /// Hyper-parameters.
    pub cfg: PpoConfig,
    /// The vectorised environments.
    pub envs: VecEnv<E>,
    /// Policy and value networks.
    pub agent: ActorCritic,
    /// Adam over `agent`.
    pub optimizer: Adam,
    /// Observation statistics (updated during rollouts only; frozen in [`Ppo::evaluate`]).
    pub obs_rms: RunningMeanStd,
    /// Reward scaler (used when `normalize_reward`).
    pub reward_scaler: RewardScaler,
    /// Random stream for action noise and minibatch shuffling.
    pub rng: ChaCha8Rng,
    /// Iterations completed.
    pub iteration: usize,
    /// Environment steps taken.
    pub global_step: u64,
    /// Normalised current observations `[N × obs_dim]`, the policy's next input.
    pub next_obs: Vec<f32>,
    /// The episodes that finished during the last iteration (curricula read their outcomes).
    pub last_episodes: Vec<EpisodeStats>,
    buf: Rollout,
    dev: Cpu,
}

impl<E: Env> Ppo<E> {
    /// A learner over `envs` (one per `cfg.num_envs`), initialised from `cfg.seed`.
    pub fn new(cfg: PpoConfig, envs: Vec<E>) -> Self {
        let dev = Cpu::default();
        let mut rng = ChaCha8Rng::seed_from_u64(cfg.seed);
        let options = envs.first().and_then(Env::options);
        let envs = VecEnv::new(envs, cfg.seed, cfg.parallel_envs);
        let (n, od, ad) = (envs.len(), envs.obs_dim(), envs.act_dim());
        let policy = GaussianPolicy::new(&dev, od, ad, &cfg.policy, &mut rng);
        let hybrid = options.map(|uses| HybridPolicy::new(&dev, od, uses, ad.saturating_sub(1), &cfg.policy, &mut rng));
        let mut agent = ActorCritic { policy, hybrid, value: ValueNet::new(&dev, od, &cfg.policy, &mut rng) };
        let optimizer = Adam::new(&mut agent, cfg.learning_rate);
        let tn = cfg.num_steps * n;
        let buf = Rollout {
            obs: vec![0.0; tn * od],
            actions: vec![0.0; tn * ad],
            log_probs: vec![0.0; tn],
            rewards: vec![0.0; tn],
            values: vec![0.0; tn],
            terminated: vec![false; tn],
            truncated: vec![false; tn],
            final_values: vec![0.0; tn],
            last_values: vec![0.0; n],
            masks: vec![true; tn * envs.options()],
        };
        let mut ppo = Ppo {
            obs_rms: RunningMeanStd::new(od),
            reward_scaler: RewardScaler::new(n, f64::from(cfg.gamma)),
            next_obs: vec![0.0; n * od],
            cfg,
            envs,
            agent,
            optimizer,
            rng,
            iteration: 0,
            global_step: 0,
            buf,
            dev,
            last_episodes: Vec::new(),
        };
        ppo.observe();
        ppo
    }

    /// Fold the envs' current observations into the statistics and normalise them into `next_obs`.
    fn observe(&mut self) {
        if self.cfg.normalize_obs {
            self.obs_rms.update(&self.envs.obs);
            self.obs_rms.normalize(&self.envs.obs, &mut self.next_obs, OBS_CLIP);
        } else {
            self.next_obs.copy_from_slice(&self.envs.obs);
        }
    }

    /// Run `iterations` more iterations, calling `on_iteration` after each.
    pub fn train(&mut self, iterations: usize, mut on_iteration: impl FnMut(&IterationMetrics)) {
        for _ in 0..iterations {
            let m = self.iterate();
            on_iteration(&m);
        }
    }

    /// One iteration: collect `T × N` steps, then update on them.
    pub fn iterate(&mut self) -> IterationMetrics {
        let start = Instant::now();
        let lr = if self.cfg.anneal_lr {
            let frac = 1.0 - self.iteration as f64 / self.cfg.num_iterations.max(1) as f64;
            self.cfg.learning_rate * frac.max(0.0)
        } else {
            self.cfg.learning_rate
        };
        self.optimizer.cfg.lr = lr;

        let env_secs = self.collect();
        let episodes = std::mem::take(&mut self.envs.finished);
        let mut m = self.update();

        let secs = start.elapsed().as_secs_f32();
        self.iteration += 1;
        m.iteration = self.iteration;
        m.global_step = self.global_step;
        m.learning_rate = lr;
        m.samples_per_sec = self.buf.rewards.len() as f32 / secs;
        m.env_time_fraction = env_secs / secs;
        self.episode_metrics(&episodes, &mut m);
        self.last_episodes = episodes;
        m
    }

    /// The rollout: `T` ticks of all `N` envs. Returns seconds spent inside env stepping.
    fn collect(&mut self) -> f32 {
        let (n, od, ad) = (self.envs.len(), self.envs.obs_dim(), self.envs.act_dim());
        let k = self.envs.options();
        let mut policy = self.agent.policy.inference();
        let mut hybrid = self.agent.hybrid.as_ref().map(HybridPolicy::inference);
        let mut value = self.agent.value.net.inference();
        let mut final_obs = vec![0.0; od];
        let mut env_secs = 0.0;
        for t in 0..self.cfg.num_steps {
            let rows = t * n..(t + 1) * n;
            let obs = &mut self.buf.obs[t * n * od..(t + 1) * n * od];
            obs.copy_from_slice(&self.next_obs);
            let actions = &mut self.buf.actions[t * n * ad..(t + 1) * n * ad];
            match &mut hybrid {
                Some(h) => {
                    self.buf.masks[t * n * k..(t + 1) * n * k].copy_from_slice(&self.envs.masks);
                    h.sample(obs, &self.envs.masks, &mut self.rng, actions, &mut self.buf.log_probs[rows.clone()]);
                }
                None => policy.sample(obs, &mut self.rng, actions, &mut self.buf.log_probs[rows.clone()]),
            }
            value.forward(obs, &mut self.buf.values[rows.clone()]);

            let tick = Instant::now();
            self.envs.step(actions);
            env_secs += tick.elapsed().as_secs_f32();
            self.global_step += n as u64;

            let rewards = &mut self.buf.rewards[rows.clone()];
            rewards.copy_from_slice(&self.envs.rewards);
            if self.cfg.normalize_reward {
                let done = self.envs.terminated.iter().zip(&self.envs.truncated);
                self.reward_scaler.scale(rewards, done.map(|(a, b)| *a || *b));
            }
            self.buf.terminated[rows.clone()].copy_from_slice(&self.envs.terminated);
            self.buf.truncated[rows.clone()].copy_from_slice(&self.envs.truncated);
            for i in 0..n {
                if self.envs.truncated[i] {
                    let raw = &self.envs.final_obs[i * od..(i + 1) * od];
                    if self.cfg.normalize_obs {
                        self.obs_rms.normalize(raw, &mut final_obs, OBS_CLIP);
                    } else {
                        final_obs.copy_from_slice(raw);
                    }
                    let k = t * n + i;
                    value.forward(&final_obs, &mut self.buf.final_values[k..k + 1]);
                }
            }
            self.observe();
        }
        value.forward(&self.next_obs, &mut self.buf.last_values);
        env_secs
    }

    /// `K` epochs of minibatch updates of the clipped surrogate, value loss and entropy bonus.
    /// Fits the hybrid policy to demonstrations (behaviour cloning, a supervised start before
    /// or instead of PPO): maximises `log π(option, continuous | s)` of `actions` (`[N × ad]`,
    /// the option then the continuous part, which counts only for options that use it) under
    /// `masks` (`[N × K]`) for raw observations `obs` (`[N × od]`), `epochs` passes in shuffled
    /// minibatches of `batch` rows with the learner's Adam and gradient clipping. The
    /// observation statistics are first updated with the demonstrations (when observations are
    /// normalised), so the learner acts on them as the fit saw them. The value network is left
    /// as it is. Returns the mean negative log-likelihood of each epoch; `Err` for a learner
    /// without hybrid actions or demonstrations of the wrong widths.
    pub fn behaviour_clone(
        &mut self,
        obs: &[f32],
        actions: &[f32],
        masks: &[bool],
        epochs: usize,
        batch: usize,
    ) -> Result<Vec<f32>, String> {
        let Some(k) = self.agent.hybrid.as_ref().map(|h| h.uses_continuous.len()) else {
            return Err("behaviour cloning fits hybrid policies only".into());
        };
        let (od, ad) = (self.obs_rms.dim(), self.envs.act_dim());
        let n = obs.len() / od.max(1);
        if n == 0 || obs.len() != n * od || actions.len() != n * ad || masks.len() != n * k {
            return Err(format!(
                "demonstrations of {} observation values, {} action values and {} mask entries do not make rows of {od}, {ad} and {k}",
                obs.len(),
                actions.len(),
                masks.len()
            ));
        }
        if let Some(row) = actions.chunks_exact(ad).position(|a| !(a[0] >= 0.0 && (a[0] as usize) < k)) {
            return Err(format!("demonstration {row} chooses option {}, not one of the {k}", actions[row * ad]));
        }
        let mut x = obs.to_vec();
        if self.cfg.normalize_obs {
            self.obs_rms.update(obs);
            self.obs_rms.normalize(obs, &mut x, OBS_CLIP);
            self.obs_rms.normalize(&self.envs.obs, &mut self.next_obs, OBS_CLIP);
        }
        let mut order: Vec<usize> = (0..n).collect();
        let mut losses = Vec::with_capacity(epochs);
        for _ in 0..epochs {
            shuffle(&mut order, &mut self.rng);
            let mut total = 0.0;
            for mb in order.chunks(batch.max(1)) {
                let m = mb.len();
                let gather = |src: &[f32], w: usize| -> Vec<f32> {
                    mb.iter().flat_map(|&r| &src[r * w..(r + 1) * w]).copied().collect()
                };
                let raw = gather(actions, ad);
                let options: Vec<usize> = raw.chunks_exact(ad).map(|a| a[0] as usize).collect();
                let cont: Vec<f32> = raw.chunks_exact(ad).flat_map(|a| a[1..].iter().copied()).collect();
                let mb_masks: Vec<bool> = mb.iter().flat_map(|&r| &masks[r * k..(r + 1) * k]).copied().collect();
                let obs_t = self.dev.tensor_from_vec(gather(&x, od), (m, od));
                let cont = self.dev.tensor_from_vec(cont, (m, ad - 1));
                let h = self.agent.hybrid.as_ref().expect("checked above");
                let (log_prob, _) = h.log_prob_entropy(obs_t.leaky_trace(), &options, &cont, &mb_masks);
                let loss = log_prob.mean().negate();
                total += loss.as_vec()[0] * m as f32;
                let mut grads = loss.backward();
                clip_grad_norm(&mut self.agent, &mut grads, self.cfg.max_grad_norm);
                self.optimizer.update(&mut self.agent, &mut grads);
            }
            losses.push(total / n as f32);
        }
        Ok(losses)
    }

    fn update(&mut self) -> IterationMetrics {
        let cfg = self.cfg.clone();
        let b = &self.buf;
        let (od, ad) = (self.envs.obs_dim(), self.envs.act_dim());
        let (advantages, returns) = gae(
            &b.rewards,
            &b.values,
            &b.terminated,
            &b.truncated,
            &b.final_values,
            &b.last_values,
            cfg.gamma,
            cfg.gae_lambda,
        );

        // The policy starts learning after the critic's warm-up: with Adam's moments and step
        // count reset, so its first steps are bias-corrected as a fresh optimiser's are.
        let policy_on = self.iteration >= cfg.critic_warmup;
        if cfg.critic_warmup > 0 && self.iteration == cfg.critic_warmup {
            self.optimizer.reset();
        }
        let batch = b.rewards.len();
        let mb_size = (batch / cfg.num_minibatches.max(1)).max(1);
        let mut indices: Vec<usize> = (0..batch).collect();
        let (mut sums, mut count) = ([0.0f32; 6], 0.0f32);
        let mut approx_kl = 0.0;
        let mut epochs = 0;
        for _ in 0..cfg.update_epochs {
            epochs += 1;
            shuffle(&mut indices, &mut self.rng);
            for mb in indices.chunks(mb_size) {
                let s = self.minibatch_step(mb, &advantages, &returns, od, ad, policy_on);
                for (acc, v) in sums.iter_mut().zip(s) {
                    *acc += v;
                }
                count += 1.0;
                approx_kl = s[2];
            }
            if cfg.target_kl.is_some_and(|kl| approx_kl > kl) {
                break;
            }
        }
        let [policy_loss, value_loss, _, clip_fraction, entropy, grad_norm] = sums.map(|s| s / count.max(1.0));
        IterationMetrics {
            approx_kl,
            clip_fraction,
            entropy,
            explained_variance: explained_variance(&self.buf.values, &returns),
            policy_loss,
            value_loss,
            grad_norm,
            epochs,
            ..IterationMetrics::default()
        }
    }

    /// One gradient step on the samples `mb`. The minibatch is cut into `grad_shards` equal
    /// parts whose losses (each weighted by its share of the rows) are differentiated on rayon's
    /// pool and whose gradients are summed in shard order, so the result does not depend on the
    /// number of threads. Without `policy_on` only the value loss is differentiated (the
    /// critic's warm-up). Returns `[policy loss, value loss, approx KL, clip fraction, entropy,
    /// grad norm]`.
    fn minibatch_step(
        &mut self,
        mb: &[usize],
        advantages: &[f32],
        returns: &[f32],
        od: usize,
        ad: usize,
        policy_on: bool,
    ) -> [f32; 6] {
        let m = mb.len();
        let mut adv: Vec<f32> = mb.iter().map(|&k| advantages[k]).collect();
        if self.cfg.norm_adv && m > 1 {
            let mean = adv.iter().sum::<f32>() / m as f32;
            let var = adv.iter().map(|a| (a - mean).powi(2)).sum::<f32>() / (m - 1) as f32;
            adv.iter_mut().for_each(|a| *a = (*a - mean) / (var.sqrt() + 1e-8));
        }
        let shard_len = m.div_ceil(self.cfg.grad_shards.clamp(1, m.max(1)));
        let shards: Vec<(&[usize], &[f32])> = mb.chunks(shard_len).zip(adv.chunks(shard_len)).collect();
        let (agent, cfg, buf, dev) = (&self.agent, &self.cfg, &self.buf, &self.dev);
        let results: Vec<(Gradients<f32, Cpu>, [f32; 5])> = shards
            .par_iter()
            .map(|(rows, adv)| {
                let batch = Shard { rows, adv, returns, od, ad, weight: rows.len() as f32 / m as f32, policy_on };
                shard_loss(agent, cfg, buf, dev, &batch)
            })
            .collect();
        let mut results = results.into_iter();
        let (mut grads, mut stats) = results.next().expect("a minibatch has at least one shard");
        for (mut g, s) in results {
            add_grads(&mut self.agent, &mut grads, &mut g);
            for (acc, v) in stats.iter_mut().zip(s) {
                *acc += v;
            }
        }
        let grad_norm = clip_grad_norm(&mut self.agent, &mut grads, self.cfg.max_grad_norm);
        self.optimizer.update(&mut self.agent, &mut grads);
        [stats[0], stats[1], stats[3], stats[4], stats[2], grad_norm]
    }

    /// Fill the episode statistics of `m` from the episodes that ended.
    fn episode_metrics(&self, episodes: &[EpisodeStats], m: &mut IterationMetrics) {
        let k = episodes.len() as f32;
        m.episodes = episodes.len();
        let mean = |f: &dyn Fn(&EpisodeStats) -> f32| {
            if episodes.is_empty() { f32::NAN } else { episodes.iter().map(f).sum::<f32>() / k }
        };
        m.mean_return = mean(&|e| e.ret);
        m.mean_length = mean(&|e| e.len as f32);
        m.termination_rate = mean(&|e| if e.terminated { 1.0 } else { 0.0 });
        m.terms = self
            .envs
            .term_names()
            .iter()
            .enumerate()
            .map(|(j, name)| (name.to_string(), mean(&|e| e.terms[j])))
            .collect();
    }

    /// A tape-free copy of the current policy, for acting outside training.
    pub fn policy_inference(&self) -> GaussianInference {
        self.agent.policy.inference()
    }

    /// A tape-free copy of the hybrid head (environments with hybrid actions only).
    pub fn hybrid_inference(&self) -> Option<HybridInference> {
        self.agent.hybrid.as_ref().map(HybridPolicy::inference)
    }

    /// Mean undiscounted return of the deterministic (mean-action) policy over the first
    /// `episodes` episodes that end in `envs`; observation statistics stay frozen.
    pub fn evaluate(&self, envs: &mut VecEnv<E>, episodes: usize) -> f32 {
        let mut policy = self.agent.policy.inference();
        let mut hybrid = self.hybrid_inference();
        let mut obs = vec![0.0; envs.obs.len()];
        let mut actions = vec![0.0; envs.len() * envs.act_dim()];
        envs.finished.clear();
        while envs.finished.len() < episodes {
            if self.cfg.normalize_obs {
                self.obs_rms.normalize(&envs.obs, &mut obs, OBS_CLIP);
            } else {
                obs.copy_from_slice(&envs.obs);
            }
            match &mut hybrid {
                Some(h) => h.mode(&obs, &envs.masks, &mut actions),
                None => policy.mean(&obs, &mut actions),
            }
            envs.step(&actions);
        }
        let done = &envs.finished[..episodes];
        done.iter().map(|e| e.ret).sum::<f32>() / episodes as f32
    }
}

/// The rows of one gradient shard and what its loss needs.
struct Shard<'a> {
    rows: &'a [usize],
    /// Normalised advantages of `rows`.
    adv: &'a [f32],
    returns: &'a [f32],
    od: usize,
    ad: usize,
    /// The shard's share of the minibatch's rows (its loss is scaled by it).
    weight: f32,
    /// Whether the policy terms enter the loss (not during the critic's warm-up).
    policy_on: bool,
}

/// The PPO loss on one shard, differentiated: the gradients and, each scaled by the shard's
/// weight, `[policy loss, value loss, entropy, approx KL, clip fraction]`.
fn shard_loss(
    agent: &ActorCritic,
    cfg: &PpoConfig,
    b: &Rollout,
    dev: &Cpu,
    s: &Shard<'_>,
) -> (Gradients<f32, Cpu>, [f32; 5]) {
    let m = s.rows.len();
    let gather = |src: &[f32], w: usize| -> Vec<f32> {
        s.rows.iter().flat_map(|&k| &src[k * w..(k + 1) * w]).copied().collect()
    };
    let obs = dev.tensor_from_vec(gather(&b.obs, s.od), (m, s.od));
    let actions = dev.tensor_from_vec(gather(&b.actions, s.ad), (m, s.ad));
    let old_log_prob = dev.tensor_from_vec(gather(&b.log_probs, 1), (m,));
    let old_values = dev.tensor_from_vec(gather(&b.values, 1), (m,));
    let returns = dev.tensor_from_vec(gather(s.returns, 1), (m,));
    let adv = dev.tensor_from_vec(s.adv.to_vec(), (m,));

    // Policy: ratio r = π(a|s) / π_old(a|s); clipped surrogate max(−A·r, −A·clip(r, 1±ε)).
    let (new_log_prob, entropy) = match &agent.hybrid {
        Some(h) => {
            let raw = gather(&b.actions, s.ad);
            let options: Vec<usize> = raw.chunks_exact(s.ad).map(|a| a[0] as usize).collect();
            let cont: Vec<f32> = raw.chunks_exact(s.ad).flat_map(|a| a[1..].iter().copied()).collect();
            let cont = dev.tensor_from_vec(cont, (m, s.ad - 1));
            let k = h.uses_continuous.len();
            let masks: Vec<bool> = s.rows.iter().flat_map(|&r| &b.masks[r * k..(r + 1) * k]).copied().collect();
            h.log_prob_entropy(obs.leaky_trace(), &options, &cont, &masks)
        }
        None => agent.policy.log_prob_entropy(obs.leaky_trace(), &actions),
    };
    let log_ratio = new_log_prob - old_log_prob;
    let (kl, clip_frac) = ratio_stats(&log_ratio.as_vec(), cfg.clip_coef);
    let ratio = log_ratio.exp();
    let pg1 = ratio.with_empty_tape() * adv.clone().negate();
    let pg2 = ratio.clamp(1.0 - cfg.clip_coef, 1.0 + cfg.clip_coef) * adv.negate();
    let pg_loss = pg1.maximum(pg2).mean();

    // Value: ½(V − R)², optionally the max with the loss of V clipped to V_old ± ε.
    let new_values = agent.value.forward(obs.leaky_trace());
    let v_loss = if cfg.clip_vloss {
        let unclipped = (new_values.with_empty_tape() - returns.clone()).square();
        let clipped = (new_values - old_values.clone()).clamp(-cfg.clip_coef, cfg.clip_coef) + old_values;
        let clipped = (clipped - returns).square();
        unclipped.maximum(clipped).mean() * 0.5
    } else {
        (new_values - returns).square().mean() * 0.5
    };

    let entropy = entropy.mean();
    let w = s.weight;
    let stats = [pg_loss.as_vec()[0] * w, v_loss.as_vec()[0] * w, entropy.as_vec()[0] * w, kl * w, clip_frac * w];
    let loss = if s.policy_on { pg_loss - entropy * cfg.ent_coef + v_loss * cfg.vf_coef } else { v_loss * cfg.vf_coef };
    ((loss * w).backward(), stats)
}

/// `into += from`, tensor by tensor over `model`'s parameters.
fn add_grads(model: &mut impl Parameters, into: &mut Gradients<f32, Cpu>, from: &mut Gradients<f32, Cpu>) {
    for (_, p) in model.params_mut() {
        let (a, b) = match &p {
            ParamMut::Matrix(t) => (into.get_or_alloc_mut(&**t), from.get_or_alloc_mut(&**t)),
            ParamMut::Vector(t) => (into.get_or_alloc_mut(&**t), from.get_or_alloc_mut(&**t)),
        };
        let (a, b) =
            (a.expect("the CPU device cannot fail to allocate"), b.expect("the CPU device cannot fail to allocate"));
        a.iter_mut().zip(b.iter()).for_each(|(x, y)| *x += y);
    }
}

/// `(approx KL, clip fraction)` from per-sample log-ratios (CleanRL's `approx_kl`, k3 estimator).
fn ratio_stats(log_ratio: &[f32], clip: f32) -> (f32, f32) {
    let n = log_ratio.len().max(1) as f32;
    let kl = log_ratio.iter().map(|lr| (lr.exp() - 1.0) - lr).sum::<f32>() / n;
    let clipped = log_ratio.iter().filter(|lr| (lr.exp() - 1.0).abs() > clip).count();
    (kl, clipped as f32 / n)
}

/// `1 − Var(y − ŷ) / Var(y)` (NaN when `y` is constant).
pub fn explained_variance(predicted: &[f32], target: &[f32]) -> f32 {
    let var = |x: &mut dyn Iterator<Item = f32>| {
        let v: Vec<f32> = x.collect();
        let mean = v.iter().sum::<f32>() / v.len().max(1) as f32;
        v.iter().map(|a| (a - mean).powi(2)).sum::<f32>() / v.len().max(1) as f32
    };
    let var_y = var(&mut target.iter().copied());
    if var_y == 0.0 {
        return f32::NAN;
    }
    1.0 - var(&mut target.iter().zip(predicted).map(|(y, p)| y - p)) / var_y
}

/// Fisher–Yates shuffle driven by `rng` (portable, so minibatches are reproducible).
pub(crate) fn shuffle(v: &mut [usize], rng: &mut impl Rng) {
    for i in (1..v.len()).rev() {
        let j = rng.random_range(0..=i);
        v.swap(i, j);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn gae_by_hand_with_termination_and_truncation() {
        // One env, T = 5, γ = 0.9, λ = 0.8. Step 1 terminates, step 3 is truncated (final-obs value
        // 10), step 4 runs on (bootstrap from last value 2).
        let (g, l) = (0.9f32, 0.8f32);
        let r = [1.0, 2.0, 0.5, 1.0, 3.0];
        let v = [0.5, 1.0, 0.2, 0.4, 1.5];
        let term = [false, true, false, false, false];
        let trunc = [false, false, false, true, false];
        let fin = [0.0, 0.0, 0.0, 10.0, 0.0];
        let (adv, ret) = gae(&r, &v, &term, &trunc, &fin, &[2.0], g, l);
        let a4 = 3.0 + g * 2.0 - 1.5; // bootstrap from the last value
        let a3 = 1.0 + g * 10.0 - 0.4; // truncated: final-obs value, trace cut
        let a2 = (0.5 + g * 0.4 - 0.2) + g * l * a3;
        let a1 = 2.0 - 1.0; // terminated: no future
        let a0 = (1.0 + g * 1.0 - 0.5) + g * l * a1;
        for (got, want) in adv.iter().zip([a0, a1, a2, a3, a4]) {
            assert!((got - want).abs() < 1e-6, "{got} vs {want}");
        }
        for k in 0..5 {
            assert!((ret[k] - (adv[k] + v[k])).abs() < 1e-6);
        }
    }

    #[test]
    fn gae_keeps_envs_apart() {
        // Two envs interleaved [T × N]: env 1 terminates at t = 0, env 0 does not.
        let (adv, _) = gae(
            &[1.0, 1.0, 1.0, 1.0],
            &[0.0; 4],
            &[false, true, false, false],
            &[false; 4],
            &[0.0; 4],
            &[0.0, 0.0],
            1.0,
            1.0,
        );
        assert_eq!(adv, vec![2.0, 1.0, 1.0, 1.0]);
    }

    #[test]
    fn explained_variance_extremes() {
        assert!((explained_variance(&[1.0, 2.0, 3.0], &[1.0, 2.0, 3.0]) - 1.0).abs() < 1e-6);
        assert!(explained_variance(&[0.0, 0.0, 0.0], &[1.0, 2.0, 3.0]).abs() < 1e-6);
    }
}
