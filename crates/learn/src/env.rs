//! The environment trait and the vectorised wrapper that steps many copies in parallel.
//!
//! Like Brax, an environment is `reset(rng) → observation` and `step(action) → outcome`; unlike
//! Brax it mutates itself and writes observations into a caller's buffer, so stepping allocates
//! nothing. [`VecEnv`] owns `N` of them, each with its own RNG stream, so parallel stepping gives
//! the same numbers as serial stepping whatever the thread schedule.

use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

/// The RNG every environment draws from (portable and serialisable, so runs can be resumed).
pub type EnvRng = ChaCha8Rng;

/// The most named reward terms / metrics one step can report.
pub const MAX_TERMS: usize = 8;

/// What one step produced; `terms[i]` is the value of the env's `term_names()[i]`.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct StepOutcome {
    /// The scalar reward.
    pub reward: f32,
    /// The episode ended in a terminal state (no bootstrapping past it).
    pub terminated: bool,
    /// The episode was cut by a time limit (bootstrap from the final observation).
    pub truncated: bool,
    /// Named reward terms or metrics of this step, in `term_names()` order.
    pub terms: [f32; MAX_TERMS],
}

/// A reinforcement-learning environment with continuous actions.
pub trait Env: Send {
    /// Length of the observation vector.
    fn obs_dim(&self) -> usize;
    /// Length of the action vector.
    fn act_dim(&self) -> usize;
    /// Lower and upper action bounds (each `act_dim` long); the wrapper clips actions to them.
    fn action_bounds(&self) -> (&[f32], &[f32]);
    /// Names of the reward terms / metrics reported in [`StepOutcome::terms`] (at most [`MAX_TERMS`]).
    fn term_names(&self) -> &[&'static str] {
        &[]
    }
    /// For a hybrid action (a meta-controller's): per discrete option, whether it reads the
    /// continuous part. Then `action[0]` is the option index and `action[1..]` the continuous
    /// part. `None` (the default): every action value is continuous.
    fn options(&self) -> Option<Vec<bool>> {
        None
    }
    /// Which options may be chosen now (hybrid actions only; all by default).
    fn option_mask(&self, mask: &mut [bool]) {
        mask.fill(true);
    }
    /// Start a new episode and write its first observation into `obs`.
    fn reset(&mut self, rng: &mut EnvRng, obs: &mut [f32]);
    /// Apply `action` (already within bounds), advance one control step, write the new
    /// observation into `obs`.
    fn step(&mut self, action: &[f32], obs: &mut [f32]) -> StepOutcome;
    /// The full dynamic state as numbers (for checkpoints); `restore(snapshot())` must make the
    /// next steps identical.
    fn snapshot(&self) -> Vec<f64>;
    /// Restore a state from [`Env::snapshot`]; `Err` names what did not fit.
    fn restore(&mut self, state: &[f64]) -> Result<(), StateError>;
}

/// Why a saved state does not fit an environment ([`Env::restore`], [`VecEnv::set_state`]).
#[derive(Debug, thiserror::Error)]
pub enum StateError {
    /// Another number of values than the environment saves.
    #[error("{what} has {got} values, expected {expected}")]
    Length {
        /// What the values are (`meta snapshot`).
        what: &'static str,
        /// How many the environment saves.
        expected: usize,
        /// How many it was given.
        got: usize,
    },
    /// A value that names nothing here: an index past a list, an unknown code.
    #[error("{what} is {value}, not one of the {count} {of}")]
    OutOfRange {
        /// Which value (`meta snapshot's skill`).
        what: String,
        /// The value given.
        value: f64,
        /// How many there are.
        count: usize,
        /// Of what (`skills`).
        of: &'static str,
    },
    /// What the environment is built on (the MuJoCo world) refused its part.
    #[error("{0}")]
    Below(#[source] Box<dyn std::error::Error + Send + Sync>),
    /// One environment of a [`VecEnv`].
    #[error("env {index}: {source}")]
    Env {
        /// Its slot.
        index: usize,
        /// Why.
        #[source]
        source: Box<StateError>,
    },
    /// A [`VecEnvState`] of another size than the [`VecEnv`].
    #[error("saved state holds {envs} envs / {obs} observation values, this VecEnv has {want_envs} / {want_obs}")]
    Shape {
        /// Environments saved.
        envs: usize,
        /// Observation values saved.
        obs: usize,
        /// Environments here.
        want_envs: usize,
        /// Observation values here.
        want_obs: usize,
    },
}

impl StateError {
    /// `got` values where `expected` fit (`what`: what the values are).
    pub fn length(what: &'static str, expected: usize, got: usize) -> StateError {
        StateError::Length { what, expected, got }
    }

    /// The error of what the environment is built on.
    pub fn below(e: impl std::error::Error + Send + Sync + 'static) -> StateError {
        StateError::Below(Box::new(e))
    }
}

/// Statistics of one finished episode.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct EpisodeStats {
    /// Undiscounted sum of rewards.
    pub ret: f32,
    /// Number of steps.
    pub len: u32,
    /// Whether it ended by termination (rather than by the time limit).
    pub terminated: bool,
    /// Per-term sums over the episode, in `term_names()` order.
    pub terms: [f32; MAX_TERMS],
}

/// One environment with its RNG, scratch buffers and running episode statistics.
struct Slot<E> {
    env: E,
    rng: EnvRng,
    clipped: Vec<f32>,
    running: EpisodeStats,
    last: StepOutcome,
}

impl<E: Env> Slot<E> {
    /// Clip `action`, step, update the episode statistics, and reset when the episode ends
    /// (copying the final observation to `fin` first).
    fn step(&mut self, action: &[f32], obs: &mut [f32], fin: &mut [f32]) {
        let (lo, hi) = self.env.action_bounds();
        for (((c, &x), &l), &h) in self.clipped.iter_mut().zip(action).zip(lo).zip(hi) {
            *c = x.clamp(l, h);
        }
        let out = self.env.step(&self.clipped, obs);
        self.running.ret += out.reward;
        self.running.len += 1;
        for (s, t) in self.running.terms.iter_mut().zip(out.terms) {
            *s += t;
        }
        if out.terminated || out.truncated {
            self.running.terminated = out.terminated;
            fin.copy_from_slice(obs);
            self.env.reset(&mut self.rng, obs);
        }
        self.last = out;
    }
}

/// Saved state of a [`VecEnv`] (for checkpoints).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct VecEnvState {
    /// Each env's [`Env::snapshot`].
    pub envs: Vec<Vec<f64>>,
    /// Each env's RNG.
    pub rngs: Vec<EnvRng>,
    /// Each env's running `(return, length, terms)`.
    pub running: Vec<(f32, u32, Vec<f32>)>,
    /// The current observation batch.
    pub obs: Vec<f32>,
}

/// `N` environments stepped together: one contiguous observation batch `[N × obs_dim]` per tick,
/// automatic reset when an episode ends (the final observation is kept for bootstrapping).
pub struct VecEnv<E: Env> {
    slots: Vec<Slot<E>>,
    obs_dim: usize,
    act_dim: usize,
    parallel: bool,
    /// Current observations `[N × obs_dim]` (after any automatic reset).
    pub obs: Vec<f32>,
    /// Final observations `[N × obs_dim]` of episodes that ended on the last tick (rows of other
    /// envs hold stale data).
    pub final_obs: Vec<f32>,
    /// Rewards of the last tick.
    pub rewards: Vec<f32>,
    /// Termination flags of the last tick.
    pub terminated: Vec<bool>,
    /// Truncation flags of the last tick.
    pub truncated: Vec<bool>,
    /// Episodes finished since the caller last cleared this list.
    pub finished: Vec<EpisodeStats>,
    /// Options allowed now, `[N × K]` (hybrid actions only; empty otherwise).
    pub masks: Vec<bool>,
    options: usize,
}

impl<E: Env> VecEnv<E> {
    /// Wrap `envs`; env `i` draws from stream `i` of a ChaCha8 generator seeded with `seed`, and
    /// `parallel` chooses rayon or a plain loop (the results are identical).
    pub fn new(envs: Vec<E>, seed: u64, parallel: bool) -> Self {
        let n = envs.len();
        let obs_dim = envs.first().map_or(0, Env::obs_dim);
        let act_dim = envs.first().map_or(0, Env::act_dim);
        let slots = envs
            .into_iter()
            .enumerate()
            .map(|(i, env)| {
                let mut rng = EnvRng::seed_from_u64(seed);
                rng.set_stream(i as u64 + 1);
                Slot {
                    env,
                    rng,
                    clipped: vec![0.0; act_dim],
                    running: EpisodeStats::default(),
                    last: StepOutcome::default(),
                }
            })
            .collect();
        let mut v = VecEnv {
            slots,
            obs_dim,
            act_dim,
            parallel,
            obs: vec![0.0; n * obs_dim],
            final_obs: vec![0.0; n * obs_dim],
            rewards: vec![0.0; n],
            terminated: vec![false; n],
            truncated: vec![false; n],
            finished: Vec::new(),
            masks: Vec::new(),
            options: 0,
        };
        v.options = v.slots.first().and_then(|s| s.env.options()).map_or(0, |o| o.len());
        v.masks = vec![true; n * v.options];
        v.reset();
        v
    }

    /// Number of environments.
    pub fn len(&self) -> usize {
        self.slots.len()
    }

    /// Whether there are no environments.
    pub fn is_empty(&self) -> bool {
        self.slots.is_empty()
    }

    /// Observation width.
    pub fn obs_dim(&self) -> usize {
        self.obs_dim
    }

    /// Action width.
    pub fn act_dim(&self) -> usize {
        self.act_dim
    }

    /// Names of the reward terms the envs report.
    pub fn term_names(&self) -> Vec<&'static str> {
        self.slots.first().map_or(Vec::new(), |s| s.env.term_names().to_vec())
    }

    /// Reset every env and its episode statistics.
    pub fn reset(&mut self) {
        let d = self.obs_dim;
        for (slot, obs) in self.slots.iter_mut().zip(self.obs.chunks_exact_mut(d)) {
            slot.env.reset(&mut slot.rng, obs);
            slot.running = EpisodeStats::default();
        }
        self.update_masks();
    }

    /// Number of discrete options of a hybrid action (0 for continuous actions).
    pub fn options(&self) -> usize {
        self.options
    }

    fn update_masks(&mut self) {
        let k = self.options;
        if k == 0 {
            return;
        }
        for (slot, m) in self.slots.iter().zip(self.masks.chunks_exact_mut(k)) {
            slot.env.option_mask(m);
        }
    }

    /// Step every env with its row of `actions: [N × act_dim]` (clipped to the bounds); fills
    /// `obs`, `rewards`, `terminated`, `truncated`, `final_obs`, and appends to `finished`.
    pub fn step(&mut self, actions: &[f32]) {
        let (d, a) = (self.obs_dim, self.act_dim);
        let slots = self.slots.iter_mut().zip(actions.chunks_exact(a));
        let rows = self.obs.chunks_exact_mut(d).zip(self.final_obs.chunks_exact_mut(d));
        if self.parallel {
            let slots = self.slots.par_iter_mut().zip(actions.par_chunks_exact(a));
            let rows = self.obs.par_chunks_exact_mut(d).zip(self.final_obs.par_chunks_exact_mut(d));
            slots.zip(rows).for_each(|((s, act), (obs, fin))| s.step(act, obs, fin));
        } else {
            slots.zip(rows).for_each(|((s, act), (obs, fin))| s.step(act, obs, fin));
        }
        for (i, slot) in self.slots.iter_mut().enumerate() {
            let out = slot.last;
            self.rewards[i] = out.reward;
            self.terminated[i] = out.terminated;
            self.truncated[i] = out.truncated && !out.terminated;
            if out.terminated || out.truncated {
                self.finished.push(std::mem::take(&mut slot.running));
            }
        }
        self.update_masks();
    }

    /// Everything needed to continue stepping exactly where this left off.
    pub fn state(&self) -> VecEnvState {
        VecEnvState {
            envs: self.slots.iter().map(|s| s.env.snapshot()).collect(),
            rngs: self.slots.iter().map(|s| s.rng.clone()).collect(),
            running: self.slots.iter().map(|s| (s.running.ret, s.running.len, s.running.terms.to_vec())).collect(),
            obs: self.obs.clone(),
        }
    }

    /// Restore a [`VecEnvState`]; `Err` says what did not fit.
    pub fn set_state(&mut self, state: &VecEnvState) -> Result<(), StateError> {
        let n = self.slots.len();
        if state.envs.len() != n
            || state.rngs.len() != n
            || state.running.len() != n
            || state.obs.len() != self.obs.len()
        {
            return Err(StateError::Shape {
                envs: state.envs.len(),
                obs: state.obs.len(),
                want_envs: n,
                want_obs: self.obs.len(),
            });
        }
        for (i, slot) in self.slots.iter_mut().enumerate() {
            slot.env.restore(&state.envs[i]).map_err(|e| StateError::Env { index: i, source: Box::new(e) })?;
            slot.rng = state.rngs[i].clone();
            let (ret, len, terms) = &state.running[i];
            slot.running = EpisodeStats {
                ret: *ret,
                len: *len,
                terminated: false,
                terms: std::array::from_fn(|k| terms.get(k).copied().unwrap_or(0.0)),
            };
        }
        self.obs.copy_from_slice(&state.obs);
        self.update_masks();
        Ok(())
    }
}
