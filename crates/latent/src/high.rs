//! The latent space as a low level (NPMP's reuse): [`LatentEnv`] wraps any humanoid task so
//! that its action is a latent `z ∈ (−2, 2)^Z` which the frozen decoder, reading
//! proprioception only, turns into the body's actions; the same PPO core trains the high level.
//! [`GoToTarget`] is the go-to-target task it is shown on: start mid-stride from a clip frame,
//! reach a point on the floor 2–4 m away.

use std::f64::consts::PI;
use std::path::Path;
use std::sync::Arc;

use rand::Rng;
use repertoire_humanoid::{HumanoidEnv, Task, TaskStep};
use repertoire_learn::env::{Env, EnvRng, MAX_TERMS, StateError, StepOutcome};
use repertoire_scenes::{ObservationLayout, World};
use repertoire_skill::imitation::{ImitationTask, TaskSettings};
use repertoire_skill::reference::to_heading;

use crate::error::{LatentError, Result};
use crate::model::LatentPolicy;

/// The high level's latents are bounded to `(−Z_BOUND, Z_BOUND)` per value (NPMP: 2).
pub const Z_BOUND: f32 = 2.0;

/// A humanoid task driven through a frozen latent decoder: the action is `z`.
pub struct LatentEnv<T: Task> {
    inner: HumanoidEnv<T>,
    decoder: LatentPolicy,
    proprio_layout: Arc<ObservationLayout>,
    lo: Vec<f32>,
    hi: Vec<f32>,
    proprio: Vec<f32>,
    action: Vec<f32>,
}

impl<T: Task> LatentEnv<T> {
    /// Wraps `inner` with the decoder of `policy` (loaded from `path`, named in errors), checked
    /// to fit `inner`'s body, rates and proprioceptive layout.
    pub fn new(inner: HumanoidEnv<T>, policy: &LatentPolicy, path: &Path) -> Result<Self> {
        policy.check_fits(inner.world().model(), path)?;
        let proprio_layout =
            Arc::new(ObservationLayout::new(inner.world().model(), &policy.manifest.decoder_features)?);
        let z = policy.latent_dim();
        Ok(LatentEnv {
            proprio: vec![0.0; proprio_layout.size],
            action: vec![0.0; policy.manifest.act_dim],
            inner,
            decoder: policy.clone(),
            proprio_layout,
            lo: vec![-Z_BOUND; z],
            hi: vec![Z_BOUND; z],
        })
    }

    /// The wrapped environment.
    pub fn inner(&self) -> &HumanoidEnv<T> {
        &self.inner
    }

    /// The wrapped environment, mutably (a task's evaluation settings).
    pub fn inner_mut(&mut self) -> &mut HumanoidEnv<T> {
        &mut self.inner
    }
}

impl<T: Task> Env for LatentEnv<T> {
    fn obs_dim(&self) -> usize {
        self.inner.obs_dim()
    }

    fn act_dim(&self) -> usize {
        self.lo.len()
    }

    fn action_bounds(&self) -> (&[f32], &[f32]) {
        (&self.lo, &self.hi)
    }

    fn term_names(&self) -> &[&'static str] {
        self.inner.term_names()
    }

    fn reset(&mut self, rng: &mut EnvRng, obs: &mut [f32]) {
        self.inner.reset(rng, obs);
    }

    fn step(&mut self, z: &[f32], obs: &mut [f32]) -> StepOutcome {
        self.inner.world().observe(&self.proprio_layout, &mut self.proprio);
        self.decoder.decode(&self.proprio, z, &mut self.action);
        for a in &mut self.action {
            *a = if a.is_finite() { a.clamp(-1.0, 1.0) } else { 0.0 };
        }
        self.inner.step(&self.action, obs)
    }

    fn snapshot(&self) -> Vec<f64> {
        self.inner.snapshot()
    }

    fn restore(&mut self, state: &[f64]) -> std::result::Result<(), StateError> {
        self.inner.restore(state)
    }
}

/// Settings of [`GoToTarget`].
#[derive(Debug, Clone)]
pub struct GoToSettings {
    /// The clip whose frames episodes start from (with their velocities), e.g. walk's.
    pub start: Arc<TaskSettings>,
    /// Distance range of the target (m).
    pub distance_m: (f64, f64),
    /// The target lies within this many degrees either side of the start heading.
    pub azimuth_deg: f64,
    /// The target counts as reached within this distance of the pelvis (m, on the floor).
    pub reach_m: f64,
    /// Reward once on reaching the target (the episode then ends).
    pub reach_bonus: f32,
    /// The episode ends when the pelvis is lower than this (m).
    pub min_height: f64,
}

/// Names of [`GoToTarget`]'s terms.
pub const GOTO_TERMS: [&str; 3] = ["progress", "distance", "reached"];

/// Go to a target on the floor: reward `1 / (1 + exp(10·V))` per step with `V` the rate of
/// change of the pelvis–target distance (the sitting paper's walk, stage 2), a bonus on
/// reaching it (which ends the episode, a success), 0 and the end on a fall. The policy
/// observes the target in the heading frame as `[sin ψ, cos ψ, distance]`.
pub struct GoToTarget {
    settings: Arc<GoToSettings>,
    placer: ImitationTask,
    target: [f64; 2],
    last_distance: f64,
    min_distance: f64,
}

impl GoToTarget {
    /// A task over shared settings.
    pub fn new(settings: Arc<GoToSettings>) -> Self {
        let placer = ImitationTask::new(Arc::clone(&settings.start));
        GoToTarget { settings, placer, target: [0.0; 2], last_distance: 0.0, min_distance: f64::INFINITY }
    }

    /// The closest the pelvis came to the target this episode (m).
    pub fn min_distance(&self) -> f64 {
        self.min_distance
    }

    fn distance(&self, world: &World) -> f64 {
        let p = world.pelvis_frame().pos;
        ((p[0] - self.target[0]).powi(2) + (p[1] - self.target[1]).powi(2)).sqrt()
    }
}

impl Task for GoToTarget {
    fn term_names(&self) -> &[&'static str] {
        &GOTO_TERMS
    }

    fn extra_obs_dim(&self) -> usize {
        3
    }

    fn observe_extra(&self, world: &World, out: &mut [f32]) {
        let p = world.pelvis_frame().pos;
        let d = to_heading(world.heading(), [self.target[0] - p[0], self.target[1] - p[1], 0.0]);
        let psi = d[1].atan2(d[0]);
        out[0] = psi.sin() as f32;
        out[1] = psi.cos() as f32;
        out[2] = (d[0] * d[0] + d[1] * d[1]).sqrt() as f32;
    }

    fn reset(&mut self, world: &mut World, rng: &mut EnvRng) {
        let heading = rng.random_range(-PI..PI);
        world.reset(rng, 0.0, 0.0, heading);
        let frames = self.settings.start.reference.frames();
        let f = rng.random_range(0..frames - 1);
        self.placer.place_at_frame(world, f, 0.0, 0.0, heading);
        let s = &self.settings;
        let d = rng.random_range(s.distance_m.0..=s.distance_m.1.max(s.distance_m.0));
        let a = world.heading() + rng.random_range(-s.azimuth_deg..=s.azimuth_deg.max(-s.azimuth_deg)).to_radians();
        let p = world.pelvis_frame().pos;
        self.target = [p[0] + d * a.cos(), p[1] + d * a.sin()];
        self.last_distance = self.distance(world);
        self.min_distance = self.last_distance;
    }

    fn step(&mut self, world: &mut World, _action: &[f32]) -> TaskStep {
        let d = self.distance(world);
        let speed = (d - self.last_distance) / world.model().control_dt();
        self.last_distance = d;
        self.min_distance = self.min_distance.min(d);
        let fell = world.has_fallen() || world.root_height() < self.settings.min_height;
        let reached = !fell && d < self.settings.reach_m;
        let progress = (1.0 / (1.0 + (10.0 * speed).exp())) as f32;
        let mut terms = [0.0; MAX_TERMS];
        terms[0] = progress;
        terms[1] = d as f32;
        terms[2] = if reached { 1.0 } else { 0.0 };
        let reward = if fell { 0.0 } else { progress + if reached { self.settings.reach_bonus } else { 0.0 } };
        TaskStep { reward, terminated: fell, truncated: reached, terms }
    }

    fn snapshot(&self, out: &mut Vec<f64>) {
        out.extend_from_slice(&[self.target[0], self.target[1], self.last_distance, self.min_distance]);
    }

    fn restore(&mut self, s: &[f64]) -> std::result::Result<(), StateError> {
        if s.len() != 4 {
            return Err(StateError::length("go-to-target snapshot", 4, s.len()));
        }
        self.target = [s[0], s[1]];
        self.last_distance = s[2];
        self.min_distance = s[3];
        Ok(())
    }
}

/// Settings of `latent goto`: training a high-level policy on [`GoToTarget`] through a frozen
/// decoder, and evaluating it.
#[derive(Debug, Clone)]
pub struct GoToOptions {
    /// PPO iterations.
    pub iterations: usize,
    /// Parallel environments.
    pub envs: usize,
    /// Steps per environment per iteration.
    pub steps: usize,
    /// Seed of training.
    pub seed: u64,
    /// Evaluation trials.
    pub trials: usize,
    /// Seed of the evaluation's start states.
    pub eval_seed: u64,
    /// Episode limit (s).
    pub episode_s: f64,
    /// Initial log standard deviation of the high level's Gaussian over `z`.
    pub init_log_std: f32,
    /// Show a progress bar.
    pub progress: bool,
}

/// What an evaluation of the go-to-target task measured.
#[derive(Debug, Clone, Copy, Default, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct GoToReport {
    /// Trials run.
    pub trials: usize,
    /// Share that reached the target.
    pub success_rate: f64,
    /// Share that fell.
    pub fall_rate: f64,
    /// Mean of each trial's closest pelvis–target distance (m).
    pub mean_min_distance: f64,
    /// Mean episode length (s).
    pub mean_seconds: f64,
}

/// `n` go-to-target environments in `model`'s scene, starting from `start`'s clip, the high
/// level observing proprioception and the target, driving `policy`'s decoder.
pub fn goto_envs(
    model: &Arc<repertoire_scenes::WorldModel>,
    settings: &Arc<GoToSettings>,
    policy: &LatentPolicy,
    path: &Path,
    episode_s: f64,
    n: usize,
) -> Result<Vec<LatentEnv<GoToTarget>>> {
    let layout = Arc::new(ObservationLayout::new(model, &policy.manifest.decoder_features)?);
    let max_steps = (episode_s / model.control_dt()).round().max(1.0) as u32;
    (0..n)
        .map(|_| {
            let inner =
                HumanoidEnv::with_layout(model, Arc::clone(&layout), GoToTarget::new(Arc::clone(settings)), max_steps);
            LatentEnv::new(inner, policy, path)
        })
        .collect()
}

/// Runs `trials` episodes of `envs` with `act` choosing latents (episode `e` starts from stream
/// `e` of `seed`, so two high levels meet the same starts and targets).
pub fn evaluate_goto(
    envs: &mut [LatentEnv<GoToTarget>],
    act: &mut dyn FnMut(&[f32], &mut [f32]),
    trials: usize,
    seed: u64,
) -> GoToReport {
    use rand::SeedableRng;
    let b = envs.len().min(trials.max(1));
    let (od, ad) = (envs[0].obs_dim(), envs[0].act_dim());
    let dt = envs[0].inner().world().model().control_dt();
    let mut obs = vec![0.0f32; b * od];
    let mut z = vec![0.0f32; b * ad];
    let mut active = vec![false; b];
    let mut started = 0usize;
    let mut report = GoToReport::default();
    let start = |env: &mut LatentEnv<GoToTarget>, o: &mut [f32], started: &mut usize| {
        let mut rng = EnvRng::seed_from_u64(seed);
        rng.set_stream(*started as u64 + 1);
        env.reset(&mut rng, o);
        *started += 1;
    };
    for i in 0..b {
        start(&mut envs[i], &mut obs[i * od..(i + 1) * od], &mut started);
        active[i] = true;
    }
    while active.iter().any(|&a| a) {
        act(&obs, &mut z);
        for v in &mut z {
            *v = v.clamp(-Z_BOUND, Z_BOUND);
        }
        for i in 0..b {
            if !active[i] {
                continue;
            }
            let out = envs[i].step(&z[i * ad..(i + 1) * ad], &mut obs[i * od..(i + 1) * od]);
            if out.terminated || out.truncated {
                let env = &envs[i];
                report.trials += 1;
                report.success_rate += f64::from(out.terms[2]);
                report.fall_rate += f64::from(u8::from(out.terminated));
                report.mean_min_distance += env.inner().task().min_distance();
                report.mean_seconds += f64::from(env.inner().steps()) * dt;
                if started < trials {
                    start(&mut envs[i], &mut obs[i * od..(i + 1) * od], &mut started);
                } else {
                    active[i] = false;
                }
            }
        }
    }
    let n = report.trials.max(1) as f64;
    report.success_rate /= n;
    report.fall_rate /= n;
    report.mean_min_distance /= n;
    report.mean_seconds /= n;
    report
}

/// What `latent goto` produced.
#[derive(Debug, Clone)]
pub struct GoToOutcome {
    /// The trained high level.
    pub policy: repertoire_learn::acting::ActingPolicy,
    /// The evaluation with a constant `z = 0` (the prior's mean), before training.
    pub zero: GoToReport,
    /// The evaluation of the trained high level on the same starts.
    pub trained: GoToReport,
    /// Environment steps of training.
    pub samples: u64,
    /// Minutes of training.
    pub minutes: f64,
}

/// Trains a high-level policy over `z` on [`GoToTarget`] with the PPO core (metrics in
/// `run_dir`), evaluating a constant `z = 0` before and the trained policy after on the same
/// starts.
pub fn train_goto(
    model: &Arc<repertoire_scenes::WorldModel>,
    settings: &Arc<GoToSettings>,
    policy: &LatentPolicy,
    path: &Path,
    opts: &GoToOptions,
    run_dir: &Path,
) -> Result<GoToOutcome> {
    use indicatif::{ProgressBar, ProgressStyle};
    use repertoire_learn::acting::ActingPolicy;
    use repertoire_learn::policy::PolicyConfig;
    use repertoire_learn::ppo::{Ppo, PpoConfig};
    use repertoire_learn::run_dir::RunDir;

    let mut eval_envs = goto_envs(model, settings, policy, path, opts.episode_s, 16)?;
    let zero = evaluate_goto(&mut eval_envs, &mut |_, z| z.fill(0.0), opts.trials, opts.eval_seed);
    tracing::info!(success = zero.success_rate, falls = zero.fall_rate, "go-to-target with z = 0");
    let cfg = PpoConfig {
        seed: opts.seed,
        num_envs: opts.envs,
        num_steps: opts.steps,
        num_iterations: opts.iterations.max(1),
        num_minibatches: 8,
        update_epochs: 5,
        target_kl: Some(0.05),
        policy: PolicyConfig {
            policy_hidden: vec![64, 64],
            value_hidden: vec![64, 64],
            init_log_std: opts.init_log_std,
            learn_log_std: true,
        },
        ..PpoConfig::default()
    };
    let envs = goto_envs(model, settings, policy, path, opts.episode_s, opts.envs)?;
    let mut run =
        RunDir::create(run_dir, &cfg).map_err(|e| LatentError::io(run_dir, "cannot create the run folder", e))?;
    let mut ppo = Ppo::new(cfg, envs);
    let bar = if opts.progress { ProgressBar::new(opts.iterations as u64) } else { ProgressBar::hidden() };
    bar.set_style(
        ProgressStyle::with_template("goto [{bar:30}] {pos}/{len} iterations (ETA {eta}) {msg}")
            .expect("valid template")
            .progress_chars("=> "),
    );
    let begin = std::time::Instant::now();
    let mut samples = 0;
    for _ in 0..opts.iterations {
        let m = ppo.iterate();
        run.log(&m).map_err(|e| LatentError::io(run_dir, "cannot write the metrics", e))?;
        samples = m.global_step;
        tracing::debug!(iteration = m.iteration, ret = m.mean_return, length = m.mean_length, "goto");
        bar.set_message(format!(
            "return {:.1}, length {:.0}, falls {:.0}%",
            m.mean_return,
            m.mean_length,
            100.0 * m.termination_rate
        ));
        bar.inc(1);
    }
    bar.finish_and_clear();
    let minutes = begin.elapsed().as_secs_f64() / 60.0;
    let mut acting = ActingPolicy::from_ppo(&ppo);
    let trained = evaluate_goto(&mut eval_envs, &mut |obs, z| acting.act(obs, z), opts.trials, opts.eval_seed);
    Ok(GoToOutcome { policy: acting, zero, trained, samples, minutes })
}
