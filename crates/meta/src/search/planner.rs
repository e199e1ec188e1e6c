//! A search-based reference controller over the frozen skills: what the skill library allows
//! at the meta rate, with the learned meta-controller taken out of the question.
//!
//! At a decision the planner copies the episode into a private environment
//! ([`MetaEnv::snapshot`] / [`MetaEnv::restore`]) and simulates skill plans from there: each
//! option the episode allows there (the graph's, less skills whose guards fail) held for 1 to
//! `repeats + 1` decisions, each such prefix also followed by every *terminal* skill allowed after
//! it (one with no way out but itself: sit), run until
//! the episode ends or `horizon` decisions pass. A skill that takes a target (walk, stage 2) is
//! tried with each of [`TARGETS`] (2 m ahead, and 30° and 60° to either side, held in the
//! pelvis' frame, so a held walk curves along an arc). The physics is deterministic, so a plan that
//! the task judges a success in the copy succeeds in the episode: the planner commits to the
//! shortest such plan and plays it out. With none, it takes the first option of the plan with
//! the highest return (a fall costs 1) and searches again at the next decision.
//!
//! It reads the true state and pays for a search at every decision (tens of simulated seconds
//! per real one), so it is a reference for tables (`repertoire meta eval --planner`), not a
//! controller to ship.

use std::sync::Arc;

use repertoire_learn::env::Env;

use crate::env::{MetaEnv, MetaSetup, terminal_skills};

/// How far the planner searches.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct PlannerConfig {
    /// Most decisions one plan is simulated for.
    pub horizon: u32,
    /// Most extra decisions an option is held before a terminal skill is tried after it.
    pub repeats: u32,
}

impl Default for PlannerConfig {
    fn default() -> Self {
        PlannerConfig { horizon: 16, repeats: 4 }
    }
}

/// Targets tried for a skill that takes one, in the pelvis' heading frame, as (azimuth in
/// degrees, distance in m): 2 m away, straight ahead and 30° and 60° to either side. Skills
/// without a target get the first.
pub const TARGETS: [(f64, f64); 5] = [(0.0, 2.0), (30.0, 2.0), (-30.0, 2.0), (60.0, 2.0), (-60.0, 2.0)];

/// One decision of a plan: the option and the index of its target in [`TARGETS`].
pub type Move = (usize, usize);

/// The meta environment's action for a move over `setup`'s skills.
pub fn write_action(setup: &MetaSetup, (option, target): Move, act: &mut [f32]) {
    act[0] = option as f32;
    let (azimuth, distance) = TARGETS[target];
    let [a, b] = setup.skills[option].target_action(azimuth, distance);
    act[1] = a;
    act[2] = b;
}

/// A plan's simulated outcome.
#[derive(Debug, Clone, PartialEq)]
struct Outcome {
    /// The moves, one per decision.
    options: Vec<Move>,
    success: bool,
    score: f64,
}

impl Outcome {
    /// Successes first (the shortest wins), then the highest score.
    fn better_than(&self, other: &Outcome) -> bool {
        match (self.success, other.success) {
            (true, false) => true,
            (false, true) => false,
            (true, true) => self.options.len() < other.options.len(),
            (false, false) => self.score > other.score,
        }
    }
}

/// What [`Planner::simulate`] saw.
#[derive(Debug, Clone, PartialEq)]
pub struct Simulated {
    /// Decisions played (fewer than asked when the episode ended).
    pub played: usize,
    /// The episode ended (success, fall, failure or time).
    pub ended: bool,
    /// It ended in success.
    pub success: bool,
    /// The environment's snapshot after the last decision played.
    pub snapshot: Vec<f64>,
}

/// The planner of one episode (create one per episode, or keep one and it replans whenever the
/// episode departs from what it expected).
pub struct Planner {
    cfg: PlannerConfig,
    setup: Arc<MetaSetup>,
    scratch: MetaEnv,
    /// Moves still to play of a plan that succeeds, last first.
    plan: Vec<Move>,
    /// The episode's snapshot the next planned option expects (a check that the copy and the
    /// episode agree; any difference drops the plan).
    expected: Vec<f64>,
    terminal: Vec<bool>,
    obs: Vec<f32>,
    act: Vec<f32>,
    mask: Vec<bool>,
    /// Decisions simulated so far (its cost).
    pub simulated: u64,
    /// Times the episode was not where a committed plan expected it (the copy and the episode
    /// disagreed; the plan was dropped and searched again). Zero while the physics is
    /// deterministic.
    pub mismatches: u32,
    /// Whether it has committed to a plan the copy judged a success.
    pub committed: bool,
}

impl Planner {
    /// A planner over `setup`'s skills and graph.
    pub fn new(setup: Arc<MetaSetup>, cfg: PlannerConfig) -> Self {
        let mask = vec![false; setup.skills.len()];
        let terminal = terminal_skills(&setup);
        let scratch = MetaEnv::new(Arc::clone(&setup));
        Planner {
            cfg,
            obs: vec![0.0; scratch.obs_dim()],
            act: vec![0.0; scratch.act_dim()],
            scratch,
            setup,
            plan: Vec::new(),
            expected: Vec::new(),
            terminal,
            mask,
            simulated: 0,
            mismatches: 0,
            committed: false,
        }
    }

    /// Writes the next decision for `env` into `act` (`[option, target azimuth, target
    /// distance]`, as the meta environment reads it).
    pub fn act(&mut self, env: &MetaEnv, act: &mut [f32]) {
        let now = env.snapshot();
        if !self.plan.is_empty() && now != self.expected {
            self.mismatches += 1;
            self.plan.clear();
        }
        if self.plan.is_empty() {
            let best = self.search(&now);
            if best.success {
                self.committed = true;
                self.plan = best.options.iter().rev().copied().collect();
            } else {
                self.plan = vec![best.options[0]];
            }
        }
        let option = self.plan.pop().expect("a search gives at least one move");
        write_action(&self.setup, option, act);
        // What the episode will look like after this option, for the next call's check.
        self.expected.clear();
        if !self.plan.is_empty() {
            self.restore(&now);
            self.step(option);
            self.expected = self.scratch.snapshot();
        }
    }

    /// Plays `options` (one per decision, as [`Planner::act`] would hand them out) in the copy
    /// from `env`'s present state, stopping early if the episode ends: whether it ended, whether
    /// in success, and the copy's snapshot after the last decision played. The real episode
    /// given the same decisions ends in the same state.
    pub fn simulate(&mut self, env: &MetaEnv, options: &[Move]) -> Simulated {
        self.restore(&env.snapshot());
        let mut out = Simulated { played: 0, ended: false, success: false, snapshot: Vec::new() };
        for &o in options {
            let (_, done, success) = self.step(o);
            out.played += 1;
            if done {
                out.ended = true;
                out.success = success;
                break;
            }
        }
        out.snapshot = self.scratch.snapshot();
        out
    }

    /// The skills and graph it plans over.
    pub fn setup(&self) -> &MetaSetup {
        &self.setup
    }

    /// Which skills are terminal ([`crate::env::terminal_skills`]).
    pub fn terminal(&self) -> &[bool] {
        &self.terminal
    }

    /// The first terminal skill `env` allows now that, held from its present state until the
    /// episode ends (at most `horizon` decisions), ends it in success in the copy, so in the
    /// episode too; `None` when none does.
    pub fn terminal_that_succeeds(&mut self, env: &MetaEnv) -> Option<usize> {
        let now = env.snapshot();
        self.restore(&now);
        self.scratch.allowed_now(&mut self.mask);
        let candidates: Vec<usize> = (0..self.mask.len()).filter(|&c| self.mask[c] && self.terminal[c]).collect();
        candidates.into_iter().find(|&c| {
            self.restore(&now);
            self.run_on((c, 0), &mut Vec::new(), 0.0).success
        })
    }

    fn restore(&mut self, state: &[f64]) {
        self.scratch.restore(state).expect("a snapshot of an environment over the same setup");
    }

    /// One decision of `option` in the copy: its reward and whether the episode ended.
    fn step(&mut self, option: Move) -> (f32, bool, bool) {
        write_action(&self.setup, option, &mut self.act);
        self.simulated += 1;
        let out = self.scratch.step(&self.act, &mut self.obs);
        let fell = out.terms[2] > 0.5;
        let done = out.terminated || out.truncated;
        (out.reward - if fell { 1.0 } else { 0.0 }, done, done && out.terms[0] > 0.5)
    }

    /// Runs `option` from the copy's state until the episode ends or the plan is `horizon`
    /// decisions long; extends `plan`.
    fn run_on(&mut self, option: Move, plan: &mut Vec<Move>, mut score: f64) -> Outcome {
        while (plan.len() as u32) < self.cfg.horizon {
            let (r, done, success) = self.step(option);
            plan.push(option);
            score += f64::from(r);
            if done {
                return Outcome { options: plan.clone(), success, score };
            }
        }
        Outcome { options: plan.clone(), success: false, score }
    }

    /// The best plan from `state` (the episode's snapshot). Options are what the episode would
    /// allow where each is tried: the graph's successors less the skills whose guards fail
    /// there ([`MetaEnv::allowed_now`]).
    fn search(&mut self, state: &[f64]) -> Outcome {
        let k = self.setup.skills.len();
        self.restore(state);
        self.scratch.allowed_now(&mut self.mask);
        // Terminal skills right away first: the shortest plans.
        let mut order: Vec<usize> = (0..k).filter(|&c| self.mask[c]).collect();
        order.sort_by_key(|&c| !self.terminal[c]);
        let mut best: Option<Outcome> = None;
        let consider = |o: Outcome, best: &mut Option<Outcome>| {
            if best.as_ref().is_none_or(|b| o.better_than(b)) {
                *best = Some(o);
            }
        };
        for &o in &order {
            if self.terminal[o] {
                self.restore(state);
                let out = self.run_on((o, 0), &mut Vec::new(), 0.0);
                let found = out.success;
                consider(out, &mut best);
                if found {
                    return best.expect("just set");
                }
                continue;
            }
            let targets = if self.setup.skills[o].uses_target { TARGETS.len() } else { 1 };
            for t in 0..targets {
                let mv = (o, t);
                self.restore(state);
                // Hold the move for 1..=repeats+1 decisions; after each, try every terminal skill.
                let mut prefix = Vec::new();
                let mut score = 0.0;
                let mut ended = None;
                for _ in 0..=self.cfg.repeats {
                    let (r, done, success) = self.step(mv);
                    prefix.push(mv);
                    score += f64::from(r);
                    if done {
                        ended = Some(Outcome { options: prefix.clone(), success, score });
                        break;
                    }
                    let mid = self.scratch.snapshot();
                    self.scratch.allowed_now(&mut self.mask);
                    let after: Vec<usize> = (0..k).filter(|&c| c != o && self.mask[c] && self.terminal[c]).collect();
                    for c in after {
                        self.restore(&mid);
                        let out = self.run_on((c, 0), &mut prefix.clone(), score);
                        let found = out.success;
                        consider(out, &mut best);
                        if found {
                            return best.expect("just set");
                        }
                    }
                    self.restore(&mid);
                }
                // And the move held on to the horizon (walking on).
                let held = match ended {
                    Some(out) => out,
                    None => self.run_on(mv, &mut prefix, score),
                };
                let found = held.success;
                consider(held, &mut best);
                if found {
                    return best.expect("just set");
                }
            }
        }
        best.expect("the graph allows at least one option")
    }
}
