//! [`HumanoidEnv`]: a [`World`] behind the learning core's [`Env`] trait, with a pluggable [`Task`].

use std::sync::Arc;

use repertoire_learn::env::{Env, EnvRng, MAX_TERMS, StepOutcome};
use repertoire_scenes::{Feature, ObservationLayout, Result, World, WorldModel};

/// What a task says about one control step.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct TaskStep {
    /// The scalar reward.
    pub reward: f32,
    /// The episode ended in a terminal state (a fall, a dropped box...).
    pub terminated: bool,
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
    /// Scores the control step just taken with normalised `action` (each in `[-1, 1]`).
    fn step(&mut self, world: &World, action: &[f32]) -> TaskStep;
    /// The task's own state, for checkpoints (empty by default).
    fn snapshot(&self, _out: &mut Vec<f64>) {}
    /// Restores [`Task::snapshot`]'s output; `state` is exactly what it wrote.
    fn restore(&mut self, _state: &[f64]) -> std::result::Result<(), String> {
        Ok(())
    }
}

/// The character of a scene as an environment: normalised actions in `[-1, 1]` become PD
/// targets spread over each actuator's control range, observations follow an
/// [`ObservationLayout`] plus the task's extra values, episodes are cut after `max_steps`
/// control steps.
pub struct HumanoidEnv<T: Task> {
    world: World,
    layout: Arc<ObservationLayout>,
    task: T,
    max_steps: u32,
    steps: u32,
    /// Centre and half-width of each actuator's control range, map order.
    ctrl_mid: Vec<f64>,
    ctrl_half: Vec<f64>,
    targets: Vec<f64>,
    lo: Vec<f32>,
    hi: Vec<f32>,
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
        let joints = &model.index.joints;
        let ctrl_mid = joints.iter().map(|j| 0.5 * (j.ctrl_range[0] + j.ctrl_range[1])).collect();
        let ctrl_half = joints.iter().map(|j| 0.5 * (j.ctrl_range[1] - j.ctrl_range[0])).collect();
        let n = joints.len();
        HumanoidEnv {
            world: model.new_world(),
            layout,
            task,
            max_steps,
            steps: 0,
            ctrl_mid,
            ctrl_half,
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

    /// Control steps taken in the current episode.
    pub fn steps(&self) -> u32 {
        self.steps
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
        for (j, (t, &a)) in self.targets.iter_mut().zip(action).enumerate() {
            *t = self.ctrl_mid[j] + self.ctrl_half[j] * f64::from(a);
        }
        // The wrapper clips actions to [-1, 1] and the policy's outputs are finite, so the
        // targets are always valid; a NaN from a diverged policy ends the episode instead.
        let stepped = self.world.step(&self.targets).is_ok();
        self.steps += 1;
        self.observe(obs);
        let out = self.task.step(&self.world, action);
        let diverged = !stepped || obs.iter().any(|v| !v.is_finite());
        if diverged {
            obs.fill(0.0);
        }
        StepOutcome {
            reward: if diverged { 0.0 } else { out.reward },
            terminated: out.terminated || diverged,
            truncated: self.steps >= self.max_steps,
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

    fn restore(&mut self, state: &[f64]) -> std::result::Result<(), String> {
        let w = self.world.snapshot_len();
        let task_len = state.last().map_or(0, |&n| n as usize);
        if state.len() != w + 2 + task_len {
            return Err(format!(
                "humanoid snapshot has {} values, expected {} (world) + 1 (step count) + {task_len} (task) + 1",
                state.len(),
                w
            ));
        }
        self.world.restore(&state[..w]).map_err(|e| e.to_string())?;
        self.steps = state[w] as u32;
        self.task.restore(&state[w + 1..w + 1 + task_len])
    }
}
