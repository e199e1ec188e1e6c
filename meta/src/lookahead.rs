//! Lookahead over a trained meta-controller: the controller, checked in a copy of the episode
//! before it commits.
//!
//! At a decision the lookahead copies the episode into a private environment
//! ([`MetaEnv::snapshot`] / [`MetaEnv::restore`]) and plays candidate decisions there, each
//! followed by the controller acting by its mode until the episode ends: the controller's own
//! choice first, then `candidates - 1` drawn from its policy (the option distribution and the
//! Gaussian over targets that PPO trained). The physics is deterministic, so a candidate the copy
//! sees succeed succeeds in the episode when it is played and the controller acts after it:
//! the lookahead takes the first such candidate and searches no more. With none, it plays the
//! candidate whose copy scored best (its decision rewards, a fall costing 1; the controller's own
//! on a tie) and searches again at the next decision, at most `searches` times an episode; after
//! that the controller acts alone.
//!
//! It never seats fewer than the controller: a trial the controller seats is one whose first
//! search finds the controller's own choice succeeding. It reads the true state and pays
//! `candidates` simulated episodes per search, so it is what the controller's skills and
//! decisions allow with foresight (`repertoire meta eval --lookahead K`), not the product's
//! learned controller; the decisions it changes are what expert iteration would teach it.

use std::sync::Arc;

use rand::SeedableRng;
use repertoire_learn::acting::ActingHybrid;
use repertoire_learn::env::{Env, EnvRng};

use crate::env::{MetaEnv, MetaSetup};

/// How much the lookahead searches.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct LookaheadConfig {
    /// Decisions tried per search, the controller's own first; 1 is the controller alone.
    pub candidates: usize,
    /// Most searches in one episode.
    pub searches: u32,
    /// Seed of the candidates drawn from the controller's policy.
    pub seed: u64,
}

impl Default for LookaheadConfig {
    fn default() -> Self {
        LookaheadConfig { candidates: 8, searches: 4, seed: 0 }
    }
}

/// What a candidate's copy of the episode came to.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Rollout {
    /// The episode ended in success.
    pub success: bool,
    /// It ended in a fall.
    pub fell: bool,
    /// Decisions played, the candidate's included.
    pub decisions: u32,
    /// Simulated seconds at its end.
    pub seconds: f64,
    /// The decisions' rewards, less 1 for a fall.
    pub score: f64,
}

/// The lookahead of one episode.
pub struct Lookahead {
    cfg: LookaheadConfig,
    head: ActingHybrid,
    scratch: MetaEnv,
    rng: EnvRng,
    obs: Vec<f32>,
    /// The episode's allowed options at the decision, and the copy's during a rollout.
    mask: Vec<bool>,
    roll_mask: Vec<bool>,
    candidate: Vec<f32>,
    best: Vec<f32>,
    /// Searches made this episode.
    pub searches: u32,
    /// Decisions simulated in the copy (its cost).
    pub simulated: u64,
    /// Whether the last decision differs from the controller's own (a search took another).
    pub changed: bool,
    /// What the copy showed for the candidate taken at the last search that found a success;
    /// `None` until one did. The episode ends exactly so.
    pub committed: Option<Rollout>,
}

impl Lookahead {
    /// The lookahead over `head` (cloned) in `setup`'s episodes.
    pub fn new(setup: Arc<MetaSetup>, head: &ActingHybrid, cfg: LookaheadConfig) -> Self {
        let k = setup.skills.len();
        let scratch = MetaEnv::new(setup);
        let (obs_dim, act_dim) = (scratch.obs_dim(), scratch.act_dim());
        Lookahead {
            cfg,
            head: head.clone(),
            rng: EnvRng::seed_from_u64(cfg.seed),
            obs: vec![0.0; obs_dim],
            mask: vec![true; k],
            roll_mask: vec![true; k],
            candidate: vec![0.0; act_dim],
            best: vec![0.0; act_dim],
            scratch,
            searches: 0,
            simulated: 0,
            changed: false,
            committed: None,
        }
    }

    /// The decision for `env`, whose observation is `obs`, into `act`.
    pub fn act(&mut self, env: &MetaEnv, obs: &[f32], act: &mut [f32]) {
        env.option_mask(&mut self.mask);
        self.head.act(obs, &self.mask, act);
        self.changed = false;
        if self.committed.is_some() || self.searches >= self.cfg.searches || self.cfg.candidates <= 1 {
            return;
        }
        self.searches += 1;
        let now = env.snapshot();
        let mut best_score = f64::NEG_INFINITY;
        self.best.copy_from_slice(act);
        for i in 0..self.cfg.candidates {
            if i == 0 {
                self.candidate.copy_from_slice(act);
            } else {
                self.head.sample(obs, &self.mask, &mut self.rng, &mut self.candidate);
            }
            let candidate = std::mem::take(&mut self.candidate);
            let out = self.rollout(&now, &candidate);
            self.candidate = candidate;
            if out.success {
                self.changed = act != self.candidate.as_slice();
                act.copy_from_slice(&self.candidate);
                self.committed = Some(out);
                return;
            }
            if out.score > best_score {
                best_score = out.score;
                self.best.copy_from_slice(&self.candidate);
            }
        }
        self.changed = act != self.best.as_slice();
        act.copy_from_slice(&self.best);
    }

    /// Plays `first` in the copy from the episode's snapshot `state`, then the controller by
    /// its mode until the episode ends.
    pub fn rollout(&mut self, state: &[f64], first: &[f32]) -> Rollout {
        self.scratch.restore(state).expect("a snapshot of an environment over the same setup");
        let mut out = Rollout { success: false, fell: false, decisions: 0, seconds: 0.0, score: 0.0 };
        let mut obs = std::mem::take(&mut self.obs);
        let mut act = first.to_vec();
        loop {
            let step = self.scratch.step(&act, &mut obs);
            self.simulated += 1;
            out.decisions += 1;
            out.score += f64::from(step.reward);
            if step.terminated || step.truncated {
                out.success = step.terms[0] > 0.5;
                out.fell = step.terms[2] > 0.5;
                out.seconds = f64::from(step.terms[3]);
                if out.fell {
                    out.score -= 1.0;
                }
                break;
            }
            self.scratch.option_mask(&mut self.roll_mask);
            self.head.act(&obs, &self.roll_mask, &mut act);
        }
        self.obs = obs;
        out
    }
}
