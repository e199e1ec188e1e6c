//! The latent low level (NPMP) as an alternative to the discrete skills: a scenario's task
//! ([`TaskSpec`]/[`TaskState`], the same judges as [`crate::MetaEnv`]) driven by a high-level
//! Gaussian policy whose action is a latent `z ∈ (−2, 2)^d`, which the frozen decoder of a
//! latent model ([`repertoire_latent::high::LatentEnv`]) turns into joint actions each control
//! tick. The high level observes proprioception, the task's props and its extra values (the
//! decoder reads proprioception only); it chooses a new `z` every `hold` control ticks.
//!
//! Episodes start as the skills' meta environment starts them: in a spawn zone drawn from the
//! setup's (curriculum) zones, the task prepared the same way, mid-motion in the start skill's
//! successful end states when the library has them (`end_poses.ron`), else standing.
//!
//! Reward: the task's decision reward computed per control tick. For sitting it is scaled by
//! `control_dt · meta_hz`, so that the sum over one meta decision's ticks equals what the skills'
//! meta environment pays for that decision (1 per decision on the seat, `0.5·(−V_sit)` while
//! approaching): both controllers are trained on the same return per simulated second. The
//! warehouse's and the toss's rewards are events (a phase done, time in the bucket) and are paid
//! unscaled at the tick they happen. The discount is per high-level step; [`default_ppo`] sets
//! it so that it matches the skills' `0.95` per half second.

use std::path::{Path, PathBuf};
use std::sync::{Arc, RwLock};

use rand::Rng;
use repertoire_curriculum::Advance;
use repertoire_humanoid::{HumanoidEnv, Task, TaskStep};
use repertoire_latent::high::{LatentEnv, Z_BOUND};
use repertoire_latent::model::LatentPolicy;
use repertoire_learn::acting::ActingPolicy;
use repertoire_learn::env::{Env, EnvRng, MAX_TERMS, StateError, StepOutcome};
use repertoire_learn::ppo::{IterationMetrics, PpoConfig};
use repertoire_learn::run_dir::git_hash;
use repertoire_scenes::math::wrap_angle;
use repertoire_scenes::{
    Annotation, Feature, ObservationLayout, RecordOptions, Recorder, Recording, World, WorldModel,
};
use repertoire_skill::library;
use repertoire_skill::pool::Pool;
use serde::{Deserialize, Serialize};

use crate::controller::{Arena, Controller, Decider};
use crate::env::MetaSetup;
use crate::error::{MetaError, Result};
use crate::graph::SkillGraph;
use crate::task::{EpisodeOverride, TaskSpec, TaskState};
use crate::trial::Trial;
use repertoire_scenes::world::PropPlacement;

/// The scene, the task and the frozen latent model, shared by every latent meta environment.
pub struct LatentSetup {
    /// The scene.
    pub model: Arc<WorldModel>,
    /// The task: its props, reward, success and failure.
    pub task: TaskSpec,
    /// The high level's observation layout (proprioception and the task's props), before the
    /// task's own values.
    pub layout: Arc<ObservationLayout>,
    /// The frozen latent model.
    pub policy: LatentPolicy,
    /// Its folder.
    pub latent_dir: PathBuf,
    /// Control ticks each `z` is held for (1: a new `z` every tick).
    pub hold: usize,
    /// Episode limit in control ticks.
    pub max_ticks: u32,
    /// Spawn zones episodes start in (the curriculum changes them between iterations).
    pub zones: Arc<RwLock<Vec<String>>>,
    /// Where episodes start: the start skill's successful end states; `None`: standing still.
    pub start_pool: Option<Pool>,
}

impl LatentSetup {
    /// The task of `model`'s scenario driven through the latent model in `latent_dir` (checked
    /// to fit the body and rates), `z` held for `hold` ticks; episodes start in the end states
    /// of the scenario's first start skill found in `library` (when it has them).
    pub fn new(model: Arc<WorldModel>, latent_dir: &Path, library: &Path, hold: usize) -> Result<Self> {
        let sc = model.scenario.scenario.clone();
        let mut task = TaskSpec::of(&model)?;
        task.load_from_library(&model, library)?;
        if sc.spawn.is_empty() {
            return Err(MetaError::Invalid(format!(
                "{}: the latent high level needs at least one spawn zone (`spawn: [Zone(...)]`)",
                model.scenario.path.display()
            )));
        }
        if hold == 0 {
            return Err(MetaError::Invalid("the latent high level must hold each z for at least 1 tick".into()));
        }
        if !latent_dir.join("latent.ron").is_file() {
            return Err(MetaError::Invalid(format!(
                "{}: low_level names the latent model {}, which has no latent.ron",
                model.scenario.path.display(),
                latent_dir.display()
            )));
        }
        let policy = LatentPolicy::load(latent_dir)?;
        policy.check_fits(&model, latent_dir)?;
        let graph = SkillGraph::of(&sc);
        let mut start_pool = None;
        for (k, name) in graph.names().into_iter().enumerate() {
            let path = library::skill_dir(library, name).join("end_poses.ron");
            if graph.is_allowed(None, k) && path.exists() {
                let pool = Pool::load(&path)?;
                if !pool.states.is_empty() && pool.body_hash == model.body.content_hash() {
                    start_pool = Some(pool);
                    break;
                }
            }
        }
        let mut features = Feature::proprioception();
        features.extend(task.features(&model));
        let layout = Arc::new(ObservationLayout::new(&model, &features)?);
        let time_limit_s = sc.task.time_limit_s();
        let zones = sc.spawn.iter().map(|z| z.name.clone()).collect();
        Ok(LatentSetup {
            max_ticks: (time_limit_s * f64::from(sc.rates.control_hz)).round().max(1.0) as u32,
            model,
            task,
            layout,
            policy,
            latent_dir: latent_dir.to_path_buf(),
            hold,
            zones: Arc::new(RwLock::new(zones)),
            start_pool,
        })
    }

    /// Observation width of the high level.
    pub fn obs_dim(&self) -> usize {
        self.layout.size + self.task.extra_dim()
    }

    /// Width of `z`.
    pub fn latent_dim(&self) -> usize {
        self.policy.latent_dim()
    }

    /// Control ticks per second.
    pub fn control_hz(&self) -> f64 {
        f64::from(self.model.scenario.scenario.rates.control_hz)
    }

    /// High-level steps per second.
    pub fn steps_per_s(&self) -> f64 {
        self.control_hz() / self.hold as f64
    }
}

/// The task of a [`LatentSetup`] as a humanoid [`Task`]: starts, judges and rewards one
/// control tick at a time.
pub struct LatentTask {
    setup: Arc<LatentSetup>,
    state: TaskState,
    over: EpisodeOverride,
    reward_scale: f32,
    ticks: u32,
    /// Start pose of the current episode `(x, y, yaw)`.
    pub start: (f64, f64, f64),
    /// Zone of the current episode.
    pub zone: String,
}

impl LatentTask {
    /// A task over `setup`.
    pub fn new(setup: Arc<LatentSetup>) -> Self {
        let hz = setup.control_hz();
        let reward_scale = match setup.task {
            TaskSpec::Sit { .. } => (f64::from(setup.model.scenario.scenario.rates.meta_hz) / hz) as f32,
            _ => 1.0,
        };
        LatentTask {
            state: setup.task.new_state(hz),
            over: EpisodeOverride::default(),
            reward_scale,
            ticks: 0,
            start: (0.0, 0.0, 0.0),
            zone: String::new(),
            setup,
        }
    }

    /// The task state of the current episode (the judges).
    pub fn state(&self) -> &TaskState {
        &self.state
    }
}

impl Task for LatentTask {
    fn term_names(&self) -> &[&'static str] {
        self.setup.task.term_names()
    }

    fn extra_obs_dim(&self) -> usize {
        self.setup.task.extra_dim()
    }

    fn observe_extra(&self, world: &World, out: &mut [f32]) {
        self.state.observe(&self.setup.task, world, out);
    }

    fn reset(&mut self, world: &mut World, rng: &mut EnvRng) {
        let zone = {
            let zones = self.setup.zones.read().expect("the zone list is never poisoned");
            zones[rng.random_range(0..zones.len())].clone()
        };
        self.start = world.reset_in_zone(&zone, rng).expect("zones come from the scenario");
        if let Some((lx, ly, turn)) = self.over.start {
            let f = world.placements()[self.setup.task.frame_prop()];
            let (s, c) = f.yaw.sin_cos();
            let (x, y) = (f.pos[0] + c * lx - s * ly, f.pos[1] + s * lx + c * ly);
            let yaw = wrap_angle((f.pos[1] - y).atan2(f.pos[0] - x) + turn);
            world.place_standing(x, y, yaw);
            self.start = (x, y, yaw);
        }
        self.zone = zone;
        self.ticks = 0;
        let hz = self.setup.control_hz();
        let moved = self.state.prepare(&self.setup.task, world, rng, hz, self.start, &self.over);
        if moved {
            let f = world.pelvis_frame();
            self.start = (f.pos[0], f.pos[1], f.yaw());
        }
        if let Some(pool) = self.setup.start_pool.as_ref().filter(|_| !moved) {
            let state = &pool.states[rng.random_range(0..pool.states.len())];
            let (x, y, yaw) = self.start;
            state.apply(world, x, y, yaw).expect("pool states are validated on load");
        }
        self.state.begin(&self.setup.task, world, rng, &self.over);
    }

    fn step(&mut self, world: &mut World, _action: &[f32]) -> TaskStep {
        let dt = 1.0 / self.setup.control_hz();
        self.ticks += 1;
        let failed = self.state.tick(&self.setup.task, world, dt);
        let fell = world.has_fallen() || !world.root_height().is_finite();
        let success = self.state.succeeded();
        // No skills here, so a bump is any touch of the chair while not seated.
        let bumped = match self.setup.task {
            TaskSpec::Sit { seat, facing, touch_penalty, .. } if touch_penalty > 0.0 => {
                world.contacts().character_on_prop(seat) && !world.seated_on(seat, facing)
            }
            _ => false,
        };
        let reward = self.state.decision_reward(&self.setup.task, world, fell, bumped, dt) * self.reward_scale;
        let ended = (self.setup.task.ends_on_success() && success) || fell || failed;
        let truncated = !ended && self.ticks >= self.setup.max_ticks;
        // The per-episode figures, on the last tick only (the learning core sums terms over an
        // episode).
        let mut terms = [0.0; MAX_TERMS];
        if ended || truncated {
            terms[0] = f32::from(u8::from(success));
            terms[2] = crate::env::fall_term(fell, world);
            // Seconds since the episode's start, counted (a diverged world's clock is not read).
            terms[3] = (f64::from(self.ticks) * dt) as f32;
            self.state.terms(&mut terms);
        }
        TaskStep { reward: if reward.is_finite() { reward } else { 0.0 }, terminated: ended, truncated, terms }
    }

    fn snapshot(&self, out: &mut Vec<f64>) {
        out.extend(self.state.snapshot());
    }

    fn restore(&mut self, state: &[f64]) -> std::result::Result<(), StateError> {
        if state.len() != self.state.snapshot_len() {
            return Err(StateError::length("latent task snapshot", self.state.snapshot_len(), state.len()));
        }
        self.state.restore(state);
        Ok(())
    }
}

/// One latent meta environment: the action is `z`, held for the setup's `hold` ticks (the
/// rewards of those ticks summed).
pub struct LatentMetaEnv {
    env: LatentEnv<LatentTask>,
    hold: usize,
    setup: Arc<LatentSetup>,
    record: Option<Recorder>,
}

impl LatentMetaEnv {
    /// An environment over `setup`.
    pub fn new(setup: &Arc<LatentSetup>) -> Result<Self> {
        let inner = HumanoidEnv::with_layout(
            &setup.model,
            Arc::clone(&setup.layout),
            LatentTask::new(Arc::clone(setup)),
            setup.max_ticks,
        );
        let env = LatentEnv::new(inner, &setup.policy, &setup.latent_dir)?;
        Ok(LatentMetaEnv { env, hold: setup.hold, setup: Arc::clone(setup), record: None })
    }

    /// Records every following episode (from its reset, one frame per control tick; the
    /// phase is the tick within the held `z`); `title` heads each recording.
    pub fn record_episodes(&mut self, title: impl Into<String>) {
        let options = RecordOptions {
            title: title.into(),
            skills: vec!["latent".into()],
            terms: self.setup.task.recorded_terms().iter().map(|s| s.to_string()).collect(),
            phase: "tick of z".into(),
            ghost: None,
            capacity: self.setup.max_ticks as usize + 2,
        };
        self.record = Some(Recorder::new(&self.setup.model, options));
    }

    /// The recording of the current episode so far (when recording), leaving an empty one.
    pub fn recording(&mut self) -> Option<Recording> {
        self.record.as_mut().map(Recorder::take)
    }

    fn record_frame(&mut self, tick: usize) {
        let Some(recorder) = self.record.as_mut() else { return };
        let world = self.env.inner().world();
        let dt = 1.0 / self.setup.control_hz();
        let terms = self.env.inner().task().state.recorded(&self.setup.task, world, dt);
        recorder.record(world, &Annotation { skill: Some(0), phase: tick as f64, terms: &terms, ghost_qpos: None });
    }

    /// `n` environments over `setup`.
    pub fn many(setup: &Arc<LatentSetup>, n: usize) -> Result<Vec<Self>> {
        (0..n).map(|_| Self::new(setup)).collect()
    }

    /// The task of the current episode.
    pub fn task(&self) -> &LatentTask {
        self.env.inner().task()
    }

    /// The world.
    pub fn world(&self) -> &World {
        self.env.inner().world()
    }

    /// Makes the following episodes start as `over` says (evaluation grids).
    pub fn set_override(&mut self, over: EpisodeOverride) {
        self.env.inner_mut().task_mut().over = over;
    }
}

impl Env for LatentMetaEnv {
    fn obs_dim(&self) -> usize {
        self.env.obs_dim()
    }

    fn act_dim(&self) -> usize {
        self.env.act_dim()
    }

    fn action_bounds(&self) -> (&[f32], &[f32]) {
        self.env.action_bounds()
    }

    fn term_names(&self) -> &[&'static str] {
        self.env.term_names()
    }

    fn reset(&mut self, rng: &mut EnvRng, obs: &mut [f32]) {
        self.env.reset(rng, obs);
        if let Some(recorder) = self.record.as_mut() {
            recorder.restart();
        }
        self.record_frame(0);
    }

    fn step(&mut self, z: &[f32], obs: &mut [f32]) -> StepOutcome {
        let mut reward = 0.0;
        let mut out = StepOutcome::default();
        for tick in 0..self.hold {
            out = self.env.step(z, obs);
            self.record_frame(tick + 1);
            reward += out.reward;
            if out.terminated || out.truncated {
                break;
            }
        }
        out.reward = reward;
        out
    }

    fn snapshot(&self) -> Vec<f64> {
        self.env.snapshot()
    }

    fn restore(&mut self, state: &[f64]) -> std::result::Result<(), StateError> {
        self.env.restore(state)
    }
}

/// What is recorded beside a trained latent high level (`latent_meta.ron`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct LatentMetaManifest {
    /// The scenario it was trained on.
    pub scenario: String,
    /// The latent model's folder, as given at training.
    pub latent_model: String,
    /// Its weights' checksum (`weights_fnv1a` of its `latent.ron`): a retrained model is refused.
    pub latent_fnv1a: u64,
    /// Width of `z`.
    pub latent_dim: usize,
    /// Control ticks each `z` is held.
    pub hold: usize,
    /// Body content hash.
    pub body_hash: String,
    /// Observation width.
    pub obs_dim: usize,
    /// PPO settings.
    pub ppo: PpoConfig,
    /// Iterations.
    pub iterations: usize,
    /// High-level steps taken.
    pub samples: u64,
    /// Wall-clock seconds.
    pub seconds: f64,
    /// Whether the zone curriculum was on.
    pub curriculum: bool,
    /// Zone switches.
    pub advances: Vec<Advance>,
    /// The command that trained it (that started the run, when it was resumed).
    pub command: String,
    /// Where the run was continued from its checkpoints (`meta train --resume`), oldest first.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub resumed: Vec<crate::train::Resume>,
    /// Git commit.
    pub git_hash: Option<String>,
}

/// File names of a trained latent high level.
pub const MANIFEST_FILE: &str = "latent_meta.ron";
/// The policy's weights beside [`MANIFEST_FILE`].
pub const WEIGHTS_FILE: &str = "latent_meta.safetensors";

/// PPO defaults for the latent high level: the skills' meta defaults with the discount per
/// high-level step chosen so that it discounts `0.95` per half second as they do, a policy
/// starting narrow around the prior's mean `z = 0`.
pub fn default_ppo(setup: &LatentSetup) -> PpoConfig {
    let steps_per_decision = setup.steps_per_s() / f64::from(setup.model.scenario.scenario.rates.meta_hz.max(1));
    PpoConfig {
        num_envs: 16,
        num_steps: 64,
        num_iterations: 200,
        gamma: 0.95f32.powf(1.0 / steps_per_decision.max(1.0) as f32),
        num_minibatches: 8,
        update_epochs: 5,
        learning_rate: 3e-4,
        target_kl: Some(0.05),
        policy: repertoire_learn::policy::PolicyConfig {
            policy_hidden: vec![128, 128],
            value_hidden: vec![128, 128],
            init_log_std: -1.0,
            learn_log_std: true,
        },
        ..PpoConfig::default()
    }
}

/// Trains the latent high level of `setup` (zone curriculum as the skills' meta-controller);
/// the policy and a manifest naming the latent model and its checksum go to `opts.out`.
pub fn train(
    setup: Arc<LatentSetup>,
    opts: &crate::train::MetaTrainOptions,
) -> Result<(LatentMetaManifest, Vec<IterationMetrics>)> {
    if let Some(dir) = &opts.warm_start {
        return Err(MetaError::Invalid(format!(
            "--warm-start {}: a warm start continues a controller over skills; the latent high level has none",
            dir.display()
        )));
    }
    let envs = LatentMetaEnv::many(&setup, opts.ppo.num_envs)?;
    let low_level = vec![format!(
        "latent {} {:016x}, z held {} ticks",
        setup.latent_dir.display(),
        setup.policy.manifest.weights_fnv1a,
        setup.hold
    )];
    let mut session = crate::train::Session::open(&setup.model, &setup.zones, envs, opts, low_level)?;
    let history = session.run(opts, "latent")?;
    let (ppo, run) = session.finish();
    std::fs::create_dir_all(&opts.out).map_err(|e| MetaError::Invalid(format!("{}: {e}", opts.out.display())))?;
    let policy = ActingPolicy::from_ppo(&ppo);
    policy.save(&opts.out.join(WEIGHTS_FILE)).map_err(|e| MetaError::Invalid(e.to_string()))?;
    let manifest = LatentMetaManifest {
        scenario: repertoire_files::portable_path(&setup.model.scenario.path),
        latent_model: setup.latent_dir.display().to_string(),
        latent_fnv1a: setup.policy.manifest.weights_fnv1a,
        latent_dim: setup.latent_dim(),
        hold: setup.hold,
        body_hash: setup.model.body.content_hash(),
        obs_dim: setup.obs_dim(),
        ppo: ppo.cfg.clone(),
        iterations: ppo.iteration,
        samples: run.samples,
        seconds: run.seconds,
        curriculum: run.curriculum,
        advances: run.advances,
        command: run.command,
        resumed: run.resumed,
        git_hash: git_hash(),
    };
    let text = ron::ser::to_string_pretty(&manifest, ron::ser::PrettyConfig::new().depth_limit(2))
        .map_err(|e| MetaError::Invalid(e.to_string()))?;
    library::write_atomic(&opts.out.join(MANIFEST_FILE), text.as_bytes())?;
    Ok((manifest, history))
}

/// Reads the manifest of a trained latent high level in `dir` (its `hold` is needed to build
/// the setup it is then checked against with [`load`]).
pub fn read_manifest(dir: &Path) -> Result<LatentMetaManifest> {
    let path = dir.join(MANIFEST_FILE);
    let text = std::fs::read_to_string(&path).map_err(|e| MetaError::Invalid(format!("{}: {e}", path.display())))?;
    ron::from_str(&text)
        .map_err(|e| MetaError::Invalid(format!("{}:{}: {}", path.display(), e.span.start.line, e.code)))
}

/// Loads a trained latent high level from `dir` and checks it fits `setup`: the same latent
/// model (checksum), body, observation width and `z` width.
pub fn load(dir: &Path, setup: &LatentSetup) -> Result<(LatentMetaManifest, ActingPolicy)> {
    let manifest = read_manifest(dir)?;
    let path = dir.join(MANIFEST_FILE);
    if manifest.latent_fnv1a != setup.policy.manifest.weights_fnv1a {
        return Err(MetaError::Invalid(format!(
            "{}: trained through the latent model {} (weights {:016x}); {} holds other weights ({:016x})",
            path.display(),
            manifest.latent_model,
            manifest.latent_fnv1a,
            setup.latent_dir.display(),
            setup.policy.manifest.weights_fnv1a
        )));
    }
    if manifest.body_hash != setup.model.body.content_hash()
        || manifest.obs_dim != setup.obs_dim()
        || manifest.latent_dim != setup.latent_dim()
    {
        return Err(MetaError::Invalid(format!(
            "{}: trained on body {} with {} observations and z of {}; this scenario has body {}, {}, {}",
            path.display(),
            manifest.body_hash,
            manifest.obs_dim,
            manifest.latent_dim,
            setup.model.body.content_hash(),
            setup.obs_dim(),
            setup.latent_dim()
        )));
    }
    let weights = dir.join(WEIGHTS_FILE);
    let policy = ActingPolicy::load(&weights).map_err(|e| MetaError::Invalid(format!("{}: {e}", weights.display())))?;
    if policy.obs_dim() != setup.obs_dim() || policy.act_dim() != setup.latent_dim() {
        return Err(MetaError::Invalid(format!(
            "{}: the policy reads {} values and writes {}, the manifest says {} and {}",
            weights.display(),
            policy.obs_dim(),
            policy.act_dim(),
            setup.obs_dim(),
            setup.latent_dim()
        )));
    }
    Ok((manifest, policy))
}

/// The latent low level as the arena of a controller: episodes of the scenario's task with a
/// `z` for a decision.
impl Arena for LatentSetup {
    type Env = LatentMetaEnv;

    fn env(self: &Arc<Self>) -> Result<LatentMetaEnv> {
        LatentMetaEnv::new(self)
    }

    fn task(&self) -> &TaskSpec {
        &self.task
    }

    fn zones(&self) -> &RwLock<Vec<String>> {
        &self.zones
    }

    fn model(&self) -> &WorldModel {
        &self.model
    }

    fn decider(&self) -> &'static str {
        "latent high level"
    }

    fn options(&self) -> Vec<String> {
        Vec::new()
    }

    fn trial(&self, env: &LatentMetaEnv, index: usize, zone: &str, terms: &[f32]) -> Trial {
        let frame: PropPlacement = env.world().placements()[self.task.frame_prop()];
        Trial::from_episode(index, zone, env.task().start, frame, terms, Vec::new())
    }

    fn record(env: &mut LatentMetaEnv, title: String) {
        env.record_episodes(title);
    }

    fn skills<'a>(
        self: &'a Arc<Self>,
        _controller: &'a dyn Controller<Self>,
    ) -> Option<(&'a Arc<MetaSetup>, &'a dyn Controller<MetaSetup>)> {
        None
    }

    fn recording(env: &mut LatentMetaEnv) -> Option<Recording> {
        env.recording()
    }
}

/// The trained latent high level as a [`Controller`] over the latent low level: each decision
/// is its mean `z`, bounded to the decoder's range (a non-finite value becomes 0). Evaluated
/// and recorded as every controller is ([`crate::eval::evaluate`]); sitting scenarios only.
#[derive(Clone)]
pub struct LatentController {
    /// The high-level policy (observation → `z`).
    pub policy: ActingPolicy,
}

impl Controller<LatentSetup> for LatentController {
    fn start(&self, _setup: &Arc<LatentSetup>) -> Box<dyn Decider<LatentMetaEnv>> {
        Box::new(self.clone())
    }
}

impl Decider<LatentMetaEnv> for LatentController {
    fn act(&mut self, _env: &LatentMetaEnv, obs: &[f32], _mask: &mut [bool], z: &mut [f32]) {
        self.policy.act(obs, z);
        for v in z.iter_mut() {
            *v = if v.is_finite() { v.clamp(-Z_BOUND, Z_BOUND) } else { 0.0 };
        }
    }
}
