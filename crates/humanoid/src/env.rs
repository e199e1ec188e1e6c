//! [`HumanoidEnv`]: a [`World`] behind the learning core's [`Env`] trait, with a pluggable [`Task`].

use std::sync::Arc;

use repertoire_learn::env::{Env, EnvRng, MAX_TERMS, StateError, StepOutcome};
use repertoire_scenes::{Feature, ObservationLayout, Result, World, WorldModel};

/// What a task says about one control step.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct TaskStep {
    /// The scalar reward.
    pub reward: f32,
    /// The episode ended in a terminal state (a fall, a dropped box...).
    pub terminated: bool,
    /// The task's own time limit ended the episode (e.g. its reference clip ran out).
    pub truncated: bool,
    /// Values of the task's [`Task::term_names`], in order.
    pub terms: [f32; MAX_TERMS],
}

/// How episodes start, what is rewarded and when an episode ends.
pub trait Task: Send {
    /// Names of the reward terms and metrics reported in [`TaskStep::terms`].
    fn term_names(&self) -> &[&'static str];
    /// Number of observation values the task appends after the layout's (targets, phase...).
    fn extra_obs_dim(&self) -> usize {
        0
    }
    /// Writes the task's extra observation values (`extra_obs_dim` of them).
    fn observe_extra(&self, _world: &World, _out: &mut [f32]) {}
    /// Puts `world` in the initial state of a new episode.
    fn reset(&mut self, world: &mut World, rng: &mut EnvRng);
    /// Scores the control step just taken with normalised `action` (each in `[-1, 1]`); it may
    /// move props for what comes next (an obstacle put in the way of a new target).
    fn step(&mut self, world: &mut World, action: &[f32]) -> TaskStep;
    /// The task's own state, for checkpoints (empty by default).
    fn snapshot(&self, _out: &mut Vec<f64>) {}
    /// Restores [`Task::snapshot`]'s output; `state` is exactly what it wrote.
    fn restore(&mut self, _state: &[f64]) -> std::result::Result<(), StateError> {
        Ok(())
    }
}

/// The character of a scene as an environment: normalised actions in `[-1, 1]` become PD
/// targets over each actuator's control range, piecewise linearly with 0 at the standing pose
/// (−1 and 1 at the range's ends), so an untrained policy starts near a stable pose instead of
/// at the ranges' midpoints (a knee bent 80°); observations follow an
/// [`ObservationLayout`] plus the task's extra values, episodes are cut after `max_steps`
/// control steps.
pub struct HumanoidEnv<T: Task> {
    world: World,
    layout: Arc<ObservationLayout>,
    task: T,
    max_steps: u32,
    steps: u32,
    map: ActionMap,
    targets: Vec<f64>,
    lo: Vec<f32>,
    hi: Vec<f32>,
}

/// How normalised actions in `[-1, 1]` become PD targets: piecewise linearly per actuated
/// joint, 0 at the standing pose, ±1 at the ends of the actuator's control range. Shared by
/// skill training and by the meta-controller, which runs the same frozen skills.
#[derive(Debug, Clone, PartialEq)]
pub struct ActionMap {
    /// Per actuated joint (map order): the standing angle and the spans above and below it.
    mid: Vec<f64>,
    up: Vec<f64>,
    down: Vec<f64>,
}

impl ActionMap {
    /// The map of `model`'s character.
    pub fn new(model: &WorldModel) -> Self {
        let joints = &model.index.joints;
        let q0 = model.mj_model().qpos0();
        let mid: Vec<f64> = joints.iter().map(|j| q0[j.qpos].clamp(j.ctrl_range[0], j.ctrl_range[1])).collect();
        let up = joints.iter().zip(&mid).map(|(j, m)| j.ctrl_range[1] - m).collect();
        let down = joints.iter().zip(&mid).map(|(j, m)| m - j.ctrl_range[0]).collect();
        ActionMap { mid, up, down }
    }

    /// Number of actuated joints.
    pub fn len(&self) -> usize {
        self.mid.len()
    }

    /// Whether the body has no actuated joint.
    pub fn is_empty(&self) -> bool {
        self.mid.is_empty()
    }

    /// The PD target of normalised action value `a` for actuated joint `j`.
    pub fn target(&self, j: usize, a: f32) -> f64 {
        let a = f64::from(a.clamp(-1.0, 1.0));
        self.mid[j] + if a >= 0.0 { a * self.up[j] } else { a * self.down[j] }
    }

    /// The normalised action whose PD target is `angle` for actuated joint `j` (clamped).
    pub fn action_for(&self, j: usize, angle: f64) -> f32 {
        let d = angle - self.mid[j];
        let a = if d >= 0.0 { d / self.up[j].max(1e-9) } else { d / self.down[j].max(1e-9) };
        a.clamp(-1.0, 1.0) as f32
    }

    /// PD targets for a whole action vector.
    pub fn targets(&self, action: &[f32], out: &mut [f64]) {
        for (j, (t, &a)) in out.iter_mut().zip(action).enumerate() {
            *t = self.target(j, a);
        }
    }
}

impl<T: Task> HumanoidEnv<T> {
    /// An environment in a new world of `model`, observing `features` (then the task's extra
    /// values); a feature naming an unknown prop is an error.
    pub fn new(model: &Arc<WorldModel>, features: &[Feature], task: T, max_steps: u32) -> Result<Self> {
        let layout = Arc::new(ObservationLayout::new(model, features)?);
        Ok(Self::with_layout(model, layout, task, max_steps))
    }

    /// Like [`HumanoidEnv::new`] with a layout shared by many environments.
    pub fn with_layout(model: &Arc<WorldModel>, layout: Arc<ObservationLayout>, task: T, max_steps: u32) -> Self {
        let map = ActionMap::new(model);
        let n = map.len();
        HumanoidEnv {
            world: model.new_world(),
            layout,
            task,
            max_steps,
            steps: 0,
            map,
            targets: vec![0.0; n],
            lo: vec![-1.0; n],
            hi: vec![1.0; n],
        }
    }

    /// The world (for viewers, evaluation and tests).
    pub fn world(&self) -> &World {
        &self.world
    }

    /// The task.
    pub fn task(&self) -> &T {
        &self.task
    }

    /// The observation layout (without the task's extra values).
    pub fn layout(&self) -> &Arc<ObservationLayout> {
        &self.layout
    }

    /// The world, mutably (evaluation tools that reposition props or the character).
    pub fn world_mut(&mut self) -> &mut World {
        &mut self.world
    }

    /// The task, mutably.
    pub fn task_mut(&mut self) -> &mut T {
        &mut self.task
    }

    /// Control steps taken in the current episode.
    pub fn steps(&self) -> u32 {
        self.steps
    }

    /// The PD target of normalised action value `a` for actuated joint `j`.
    pub fn target(&self, j: usize, a: f32) -> f64 {
        self.map.target(j, a)
    }

    /// The normalised action whose PD target is `angle` for actuated joint `j` (clamped).
    pub fn action_for(&self, j: usize, angle: f64) -> f32 {
        self.map.action_for(j, angle)
    }

    fn observe(&self, obs: &mut [f32]) {
        let (base, extra) = obs.split_at_mut(self.layout.size);
        self.world.observe(&self.layout, base);
        self.task.observe_extra(&self.world, extra);
    }
}

impl<T: Task> Env for HumanoidEnv<T> {
    fn obs_dim(&self) -> usize {
        self.layout.size + self.task.extra_obs_dim()
    }

    fn act_dim(&self) -> usize {
        self.lo.len()
    }

    fn action_bounds(&self) -> (&[f32], &[f32]) {
        (&self.lo, &self.hi)
    }

    fn term_names(&self) -> &[&'static str] {
        self.task.term_names()
    }

    fn reset(&mut self, rng: &mut EnvRng, obs: &mut [f32]) {
        self.steps = 0;
        self.task.reset(&mut self.world, rng);
        self.observe(obs);
    }

    fn step(&mut self, action: &[f32], obs: &mut [f32]) -> StepOutcome {
        self.map.targets(action, &mut self.targets);
        // The wrapper clips actions to [-1, 1] and the policy's outputs are finite, so the
        // targets are always valid; a NaN from a diverged policy ends the episode instead.
        let stepped = self.world.step(&self.targets).is_ok();
        self.steps += 1;
        self.observe(obs);
        let out = self.task.step(&mut self.world, action);
        let diverged = !stepped || obs.iter().any(|v| !v.is_finite());
        if diverged {
            obs.fill(0.0);
        }
        StepOutcome {
            reward: if diverged { 0.0 } else { out.reward },
            terminated: out.terminated || diverged,
            truncated: out.truncated || self.steps >= self.max_steps,
            terms: out.terms,
        }
    }

    fn snapshot(&self) -> Vec<f64> {
        let mut out = Vec::with_capacity(self.world.snapshot_len() + 8);
        self.world.snapshot(&mut out);
        out.push(f64::from(self.steps));
        let n = out.len();
        self.task.snapshot(&mut out);
        out.push((out.len() - n) as f64);
        out
    }

    fn restore(&mut self, state: &[f64]) -> std::result::Result<(), StateError> {
        let w = self.world.snapshot_len();
        let task_len = state.last().map_or(0, |&n| n as usize);
        if state.len() != w + 2 + task_len {
            // The world's values, the step count, the task's and their count.
            return Err(StateError::length("humanoid snapshot", w + 2 + task_len, state.len()));
        }
        self.world.restore(&state[..w]).map_err(StateError::below)?;
        self.steps = state[w] as u32;
        self.task.restore(&state[w + 1..w + 1 + task_len])
    }
}
