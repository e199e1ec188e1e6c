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
//! A candidate whose copy the search can already tell is not played
//! ([`LookaheadConfig::skip_known`]): one with the same effect as an earlier candidate of the
//! same search (a skill without a target ignores the action's target values, so every draw of
//! it is one copy), and, after a search that found no success, the controller's own decision
//! at the next search, which is the rollout taken then from its second decision on (checked
//! against the observation and the action). Neither can change what is taken.
//!
//! It never seats fewer than the controller: a trial the controller seats is one whose first
//! search finds the controller's own choice succeeding. It reads the true state and pays up to
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
    /// Skip the candidates whose copy the search can already tell: one with the same effect as
    /// an earlier candidate of the search (the same option, and the same target where the skill
    /// takes one), and the controller's own when the last search played it out (the candidate
    /// taken then, followed by the controller, is this decision onwards). The decisions are the
    /// same either way; `false` simulates every candidate (for checking that).
    pub skip_known: bool,
}

impl Default for LookaheadConfig {
    fn default() -> Self {
        LookaheadConfig { candidates: 8, searches: 8, seed: 0, skip_known: true }
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

/// A rollout's decisions as the copy played them, from `start` on: the action of each, the
/// observation after it and its reward, and whether it ended in a fall.
#[derive(Debug, Default)]
struct Trace {
    acts: Vec<f32>,
    obs: Vec<f32>,
    rewards: Vec<f32>,
    fell: bool,
    start: usize,
}

impl Trace {
    fn clear(&mut self) {
        self.acts.clear();
        self.obs.clear();
        self.rewards.clear();
        self.fell = false;
        self.start = 0;
    }

    /// The score of the rollout's decisions after `start` (what a rollout from the next decision
    /// sums, in the same order), when the episode, seeing `obs`, is at that next decision and
    /// the controller acts `act` there, as the copy did.
    fn next_score(&self, obs: &[f32], act: &[f32]) -> Option<f64> {
        let (o, a) = (obs.len(), act.len());
        let next = self.start + 1;
        if next >= self.rewards.len()
            || self.obs[self.start * o..next * o] != *obs
            || self.acts[next * a..(next + 1) * a] != *act
        {
            return None;
        }
        let mut score = 0.0;
        for r in &self.rewards[next..] {
            score += f64::from(*r);
        }
        if self.fell {
            score -= 1.0;
        }
        Some(score)
    }
}

/// The lookahead of one episode.
pub struct Lookahead {
    cfg: LookaheadConfig,
    setup: Arc<MetaSetup>,
    head: ActingHybrid,
    scratch: MetaEnv,
    rng: EnvRng,
    obs: Vec<f32>,
    /// The episode's allowed options at the decision, and the copy's during a rollout.
    mask: Vec<bool>,
    roll_mask: Vec<bool>,
    candidate: Vec<f32>,
    best: Vec<f32>,
    roll_act: Vec<f32>,
    /// The rollout being played, the best of this search, and the one the episode follows
    /// since the last search (valid while `following`).
    trace: Trace,
    best_trace: Trace,
    followed: Trace,
    following: bool,
    /// The effects (option, and target bits for a skill that takes one) tried this search.
    tried: Vec<(usize, Option<[u32; 2]>)>,
    /// Searches made this episode.
    pub searches: u32,
    /// Decisions simulated in the copy (its cost).
    pub simulated: u64,
    /// Candidates whose copy the search could tell without playing it ([`LookaheadConfig::skip_known`]).
    pub skipped: u64,
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
        let scratch = MetaEnv::new(Arc::clone(&setup));
        let (obs_dim, act_dim) = (scratch.obs_dim(), scratch.act_dim());
        Lookahead {
            cfg,
            setup,
            head: head.clone(),
            rng: EnvRng::seed_from_u64(cfg.seed),
            obs: vec![0.0; obs_dim],
            mask: vec![true; k],
            roll_mask: vec![true; k],
            candidate: vec![0.0; act_dim],
            best: vec![0.0; act_dim],
            roll_act: vec![0.0; act_dim],
            scratch,
            trace: Trace::default(),
            best_trace: Trace::default(),
            followed: Trace::default(),
            following: false,
            tried: Vec::with_capacity(cfg.candidates),
            searches: 0,
            simulated: 0,
            skipped: 0,
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
            self.following = false;
            return;
        }
        self.searches += 1;
        let now = env.snapshot();
        let mut best_score = f64::NEG_INFINITY;
        self.best.copy_from_slice(act);
        self.tried.clear();
        for i in 0..self.cfg.candidates {
            if i == 0 {
                self.candidate.copy_from_slice(act);
            } else {
                self.head.sample(obs, &self.mask, &mut self.rng, &mut self.candidate);
            }
            if self.cfg.skip_known {
                let effect = self.effect(&self.candidate);
                if self.tried.contains(&effect) {
                    // The same effect as an earlier candidate: the same copy, neither a success
                    // nor better than the best (ties keep the earlier).
                    self.skipped += 1;
                    continue;
                }
                self.tried.push(effect);
                if i == 0
                    && self.following
                    && let Some(score) = self.followed.next_score(obs, act)
                {
                    // The last search's rollout, from here on: no success (it would have
                    // been taken), and its score is known.
                    self.skipped += 1;
                    best_score = score;
                    std::mem::swap(&mut self.best_trace, &mut self.followed);
                    self.best_trace.start += 1;
                    continue;
                }
            }
            let candidate = std::mem::take(&mut self.candidate);
            let out = self.rollout(&now, &candidate);
            self.candidate = candidate;
            if out.success {
                self.changed = act != self.candidate.as_slice();
                act.copy_from_slice(&self.candidate);
                self.committed = Some(out);
                self.following = false;
                return;
            }
            if out.score > best_score {
                best_score = out.score;
                self.best.copy_from_slice(&self.candidate);
                std::mem::swap(&mut self.best_trace, &mut self.trace);
            }
        }
        self.changed = act != self.best.as_slice();
        act.copy_from_slice(&self.best);
        // The controller's own candidate is never a repeat, so it was played or known: the best
        // has a trace, which the episode now follows.
        std::mem::swap(&mut self.followed, &mut self.best_trace);
        self.following = true;
    }

    /// What a decision does: its option, and its target where that skill takes one (a skill
    /// without one ignores the action's target values).
    fn effect(&self, a: &[f32]) -> (usize, Option<[u32; 2]>) {
        let option = self.setup.option_of(a);
        let target = self.setup.skills[option].uses_target.then(|| [a[1].to_bits(), a[2].to_bits()]);
        (option, target)
    }

    /// Plays `first` in the copy from the episode's snapshot `state`, then the controller by
    /// its mode until the episode ends.
    pub fn rollout(&mut self, state: &[f64], first: &[f32]) -> Rollout {
        self.scratch.restore(state).expect("a snapshot of an environment over the same setup");
        let mut out = Rollout { success: false, fell: false, decisions: 0, seconds: 0.0, score: 0.0 };
        let mut obs = std::mem::take(&mut self.obs);
        let mut act = std::mem::take(&mut self.roll_act);
        act.copy_from_slice(first);
        self.trace.clear();
        loop {
            let step = self.scratch.step(&act, &mut obs);
            self.simulated += 1;
            out.decisions += 1;
            out.score += f64::from(step.reward);
            self.trace.acts.extend_from_slice(&act);
            self.trace.obs.extend_from_slice(&obs);
            self.trace.rewards.push(step.reward);
            if step.terminated || step.truncated {
                out.success = step.terms[0] > 0.5;
                out.fell = step.terms[2] > 0.5;
                out.seconds = f64::from(step.terms[3]);
                if out.fell {
                    out.score -= 1.0;
                }
                self.trace.fell = out.fell;
                break;
            }
            self.scratch.option_mask(&mut self.roll_mask);
            self.head.act(&obs, &self.roll_mask, &mut act);
        }
        self.obs = obs;
        self.roll_act = act;
        out
    }
}
