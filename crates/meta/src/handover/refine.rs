//! Fine-tuning one skill inside a trained meta-controller's episodes (`repertoire meta refine`).
//!
//! Skills are trained alone, from their clip's poses and their predecessors' end poses, towards
//! targets drawn from a range; under a controller they meet other states: the targets the
//! controller gives, the chair where it stands, the poses the other skills hand over. A walk
//! that is good alone can still bump into the chair and fall under the controller (stop 44).
//! [`RefineEnv`] is the skill's own environment in the controller's episodes: the frozen
//! controller decides at its rate as in evaluation (its mode), the other skills play frozen, and
//! whenever the controller chooses the refined skill the learner's actions drive the character
//! in its place, one control tick per step, observing what the skill observes (the target the
//! controller gave it).
//!
//! The learner's reward per tick is `skill_weight` times the skill's own (its imitation terms
//! and its goal towards the controller's target, as its spec weighs them; an arrival within the
//! spec's `reach_m` pays the goal's 1 and keeps the controller's target), plus `task_weight`
//! times the task's
//! decision rewards (the approach to the seat, seated time), each added on the step that ends
//! the decision, with everything the frozen skills earn before the skill is chosen again added
//! on its last step before them. A fall, the learner's or a later skill's, ends the episode
//! as a terminal state: what the walk hands over counts. Success and the time limit end it as a
//! truncation (bootstrapped), so that finishing the task never costs the skill the reward it
//! would have earned playing on.

use std::sync::Arc;

use repertoire_humanoid::Task as _;
use repertoire_learn::acting::ActingHybrid;
use repertoire_learn::env::{Env, EnvRng, MAX_TERMS, StateError, StepOutcome};
use repertoire_skill::imitation::{ImitationTask, TaskSettings};

use crate::env::{DECISION_VALUES, MetaEnv, MetaSetup};
use crate::error::{MetaError, Result};

/// Names of the figures a [`RefineEnv`] reports (sums over an episode; the last three once, at
/// its end).
pub const REFINE_TERMS: [&str; 8] =
    ["pose", "velocity", "end_effector", "root", "goal", "task_reward", "success", "skill_fell"];

/// Most episodes [`RefineEnv::reset`] plays through looking for one in which the controller
/// chooses the refined skill.
const MAX_SKIPPED_EPISODES: usize = 1000;

/// What every [`RefineEnv`] shares.
pub struct RefineSetup {
    /// The scenario, the skills and the graph.
    pub meta: Arc<MetaSetup>,
    /// The frozen controller.
    pub controller: ActingHybrid,
    /// The refined skill's option index.
    pub skill: usize,
    /// The refined skill's reward (its spec's imitation and goal).
    pub settings: Arc<TaskSettings>,
    /// Weight of the task's decision rewards in the learner's.
    pub task_weight: f32,
    /// Weight of the skill's own reward (imitation and goal) in the learner's.
    pub skill_weight: f32,
    lo: Vec<f32>,
    hi: Vec<f32>,
}

impl RefineSetup {
    /// The skill `name` of `meta`'s graph refined under `controller`, scored by `settings` (its
    /// spec's reward, built on the spec's own scene) within action bounds `lo`..`hi` (its
    /// training environment's), its own reward weighed by `skill_weight` and the task's by
    /// `task_weight`. Refused: a skill the graph lacks, a goal that reads props (a seat, a box),
    /// a reward whose clip has another length than the library skill's, bounds of another width
    /// than its policy's actions, a weight that is not finite or a negative skill weight.
    pub fn new(
        meta: Arc<MetaSetup>,
        controller: ActingHybrid,
        name: &str,
        settings: Arc<TaskSettings>,
        bounds: (&[f32], &[f32]),
        (skill_weight, task_weight): (f32, f32),
    ) -> Result<Self> {
        let scenario = meta.model.scenario.path.display().to_string();
        let skill = meta.skills.iter().position(|s| s.name == name).ok_or_else(|| {
            let names: Vec<&str> = meta.skills.iter().map(|s| s.name.as_str()).collect();
            MetaError::Invalid(format!(
                "{scenario}: the skill graph has no skill `{name}` (it has: {})",
                names.join(", ")
            ))
        })?;
        if settings.seat.is_some() || settings.object.is_some() || settings.obstacle.is_some() {
            // Their goals read props by the index in the skill's own training scene.
            return Err(MetaError::Invalid(format!(
                "`{name}`: its goal reads a prop of its training scene (a seat, a box, an obstacle); refining \
                 such a skill in the scenario's episodes is not supported yet (walk_to, the turns and the stand are)"
            )));
        }
        let s = &meta.skills[skill];
        let frames = settings.reference.frames();
        if frames != s.frames {
            return Err(MetaError::Invalid(format!(
                "`{name}`: its spec's clip has {frames} frames at the control rate, the library skill's {}: the spec \
                 is not the one the skill was trained on",
                s.frames
            )));
        }
        let act = s.policy.act_dim();
        if bounds.0.len() != act || bounds.1.len() != act {
            return Err(MetaError::Invalid(format!(
                "`{name}`: its environment has {} actions, its policy {act}",
                bounds.0.len()
            )));
        }
        if !(task_weight.is_finite() && skill_weight.is_finite() && skill_weight >= 0.0) {
            return Err(MetaError::Invalid(format!(
                "the task weight must be finite and the skill weight finite and at least 0, not {task_weight} and \
                 {skill_weight}"
            )));
        }
        Ok(RefineSetup {
            meta,
            controller,
            skill,
            settings,
            task_weight,
            skill_weight,
            lo: bounds.0.to_vec(),
            hi: bounds.1.to_vec(),
        })
    }

    /// Plays `episodes` of the controller's episodes (seeded by `seed`) with the frozen skills
    /// and counts those in which it chooses the refined skill; an error when none does, since
    /// training would then find no step to take.
    pub fn probe(self: &Arc<Self>, episodes: usize, seed: u64) -> Result<usize> {
        let mut env = self.env();
        let mut rng = <EnvRng as rand::SeedableRng>::seed_from_u64(seed);
        let mut chosen = 0;
        for _ in 0..episodes {
            env.meta.reset(&mut rng, &mut env.meta_obs);
            let mut ignored = 0.0;
            chosen += usize::from(matches!(env.reach_skill(&mut ignored), Reached::Skill));
        }
        if chosen == 0 && episodes > 0 {
            return Err(MetaError::Invalid(format!(
                "{}: the controller chose `{}` in none of {episodes} episodes: there is nothing to refine it in",
                self.meta.model.scenario.path.display(),
                self.meta.skills[self.skill].name
            )));
        }
        Ok(chosen)
    }

    /// One environment.
    pub fn env(self: &Arc<Self>) -> RefineEnv {
        let meta = MetaEnv::new(Arc::clone(&self.meta));
        let k = self.meta.skills.len();
        RefineEnv {
            meta_obs: vec![0.0; self.meta.obs_dim()],
            mask: vec![true; k],
            act: vec![0.0; 3],
            controller: self.controller.clone(),
            score: ImitationTask::new(Arc::clone(&self.settings)),
            meta,
            setup: Arc::clone(self),
        }
    }

    /// `n` environments.
    pub fn envs(self: &Arc<Self>, n: usize) -> Vec<RefineEnv> {
        (0..n).map(|_| self.env()).collect()
    }
}

/// How playing the controller's decisions up to the refined skill ended.
enum Reached {
    /// The controller chose the refined skill: its decision has begun.
    Skill,
    /// The episode ended first, with this outcome.
    Ended(StepOutcome),
}

/// One skill's environment inside the controller's episodes (see the module's documentation).
pub struct RefineEnv {
    setup: Arc<RefineSetup>,
    meta: MetaEnv,
    controller: ActingHybrid,
    score: ImitationTask,
    meta_obs: Vec<f32>,
    mask: Vec<bool>,
    act: Vec<f32>,
}

impl RefineEnv {
    /// The meta environment underneath (tests, diagnostics).
    pub fn meta(&self) -> &MetaEnv {
        &self.meta
    }

    /// Plays the controller's decisions (the other skills frozen) until it chooses the refined
    /// skill or the episode ends; the task's rewards of the decisions played go into `reward`.
    fn reach_skill(&mut self, reward: &mut f32) -> Reached {
        loop {
            self.meta.option_mask(&mut self.mask);
            self.controller.act(&self.meta_obs, &self.mask, &mut self.act);
            if self.meta.begin_decision(&self.act) == self.setup.skill {
                self.score.set_target(self.meta.target(), self.meta.world());
                return Reached::Skill;
            }
            while !self.meta.decision_tick(None) {}
            let out = self.meta.end_decision(&mut self.meta_obs);
            *reward += self.setup.task_weight * out.reward;
            if out.terminated || out.truncated {
                return Reached::Ended(out);
            }
        }
    }

    /// The learner's ending of an episode that ended with `out`.
    fn ending(out: &StepOutcome, reward: f32, terms: &mut [f32; MAX_TERMS]) -> StepOutcome {
        let success = out.terms[0] > 0.5;
        terms[6] = if success { 1.0 } else { 0.0 };
        let terminated = out.terminated && !success;
        StepOutcome { reward, terminated, truncated: !terminated, terms: *terms }
    }
}

impl Env for RefineEnv {
    fn obs_dim(&self) -> usize {
        self.setup.meta.skills[self.setup.skill].policy.obs_dim()
    }

    fn act_dim(&self) -> usize {
        self.setup.lo.len()
    }

    fn action_bounds(&self) -> (&[f32], &[f32]) {
        (&self.setup.lo, &self.setup.hi)
    }

    fn term_names(&self) -> &[&'static str] {
        &REFINE_TERMS
    }

    /// Starts the controller's episodes until one reaches the refined skill (the controller
    /// may finish an episode without it: a start facing the seat's spot, a fall in a turn).
    fn reset(&mut self, rng: &mut EnvRng, obs: &mut [f32]) {
        for _ in 0..MAX_SKIPPED_EPISODES {
            self.meta.reset(rng, &mut self.meta_obs);
            let mut ignored = 0.0;
            if let Reached::Skill = self.reach_skill(&mut ignored) {
                self.meta.skill_observation(self.setup.skill, obs);
                return;
            }
        }
        // `meta refine` checks that the controller chooses the skill before it trains.
        panic!(
            "the controller did not choose `{}` in {MAX_SKIPPED_EPISODES} episodes in a row",
            self.setup.meta.skills[self.setup.skill].name
        );
    }

    fn step(&mut self, action: &[f32], obs: &mut [f32]) -> StepOutcome {
        let over = self.meta.decision_tick(Some(action));
        let scored = self.score.score(self.meta.world(), self.meta.phase());
        // An arrival draws the skill's next target in training; here the controller's stands.
        if self.score.target() != self.meta.target() {
            self.score.set_target(self.meta.target(), self.meta.world());
        }
        let mut terms = [0.0; MAX_TERMS];
        terms[..5].copy_from_slice(&scored.terms[..5]);
        let mut reward = self.setup.skill_weight * scored.reward;
        if !over {
            self.meta.skill_observation(self.setup.skill, obs);
            return StepOutcome { reward, terminated: false, truncated: false, terms };
        }
        let out = self.meta.end_decision(&mut self.meta_obs);
        reward += self.setup.task_weight * out.reward;
        terms[5] = self.setup.task_weight * out.reward;
        let out = if out.terminated || out.truncated {
            terms[7] = f32::from(u8::from(out.terms[2] > 0.5));
            out
        } else {
            let before = reward;
            match self.reach_skill(&mut reward) {
                Reached::Skill => {
                    terms[5] += reward - before;
                    self.meta.skill_observation(self.setup.skill, obs);
                    return StepOutcome { reward, terminated: false, truncated: false, terms };
                }
                Reached::Ended(out) => {
                    terms[5] += reward - before;
                    out
                }
            }
        };
        self.meta.skill_observation(self.setup.skill, obs);
        if obs.iter().any(|v| !v.is_finite()) {
            obs.fill(0.0);
        }
        Self::ending(&out, reward, &mut terms)
    }

    /// The meta environment's snapshot, its decision in progress, then the skill reward's state.
    fn snapshot(&self) -> Vec<f64> {
        let mut out = self.meta.snapshot();
        out.extend_from_slice(&self.meta.decision_snapshot());
        self.score.snapshot(&mut out);
        out
    }

    fn restore(&mut self, state: &[f64]) -> std::result::Result<(), StateError> {
        let mut score = Vec::new();
        self.score.snapshot(&mut score);
        let tail = DECISION_VALUES + score.len();
        let Some(split) = state.len().checked_sub(tail) else {
            // At least its tail (the decision and the score); the meta snapshot's own length is
            // checked below.
            return Err(StateError::length("refine snapshot", tail, state.len()));
        };
        self.meta.restore(&state[..split])?;
        self.meta.restore_decision(&state[split..split + DECISION_VALUES])?;
        self.score.restore(&state[split + DECISION_VALUES..])
    }
}
