//! [`MetaEnv`]: the sitting task at the meta rate. Each decision picks a skill (masked by the
//! skill graph) and a continuous 2-D target; the chosen skill's frozen policy then drives the
//! character for `control_hz / meta_hz` control ticks. Reward: 1 while the pelvis touches the
//! seat, else `0.5·(−V_sit)` with `V_sit` the rate of change of the pelvis-to-seat distance.
//! The episode ends on success (3 s of unbroken seat contact), a fall, or the time limit.
//!
//! Episodes start mid-motion in the first start skill's successful end states (e.g. walking),
//! at the spawn point and heading the zone draws; without such a pool, standing still.
//!
//! A skill whose clip does not loop (a turn cycle, the sit-down) is never run past its clip's
//! end, where its policy was never trained: the decision ends early there, and choosing the
//! same skill again plays its clip once more from the start.

use std::f64::consts::TAU;
use std::path::Path;
use std::sync::{Arc, RwLock};

use rand::Rng;
use repertoire_humanoid::ActionMap;
use repertoire_learn::acting::ActingPolicy;
use repertoire_learn::env::{Env, EnvRng, MAX_TERMS, StepOutcome};
use repertoire_scenes::scenario::Task as ScenarioTask;
use repertoire_scenes::{
    Annotation, Feature, ObservationLayout, RecordOptions, Recorder, Recording, World, WorldModel,
};
use repertoire_skill::library::{self, LibrarySkill};
use repertoire_skill::pool::Pool;
use repertoire_skill::reference::to_heading;
use repertoire_skill::spec::Goal;

use crate::error::{MetaError, Result};
use crate::graph::SkillGraph;
use crate::judge::SitJudge;

/// Names of the per-episode figures in [`StepOutcome::terms`] (reported on the last step).
pub const TERM_NAMES: [&str; 5] = ["success", "min_distance", "fell", "seconds", "switches"];

/// One skill as the meta-controller runs it.
#[derive(Debug, Clone)]
pub struct MetaSkill {
    /// Its name.
    pub name: String,
    /// Its frozen policy.
    pub policy: ActingPolicy,
    /// Its observation layout on this scene.
    pub layout: ObservationLayout,
    /// Frames of its clip at the control rate.
    pub frames: usize,
    /// Whether its clip loops.
    pub looping: bool,
    /// Whether it observes a 2-D target (walk, stage 2).
    pub uses_target: bool,
}

/// The scene, the skills and the graph, shared by every meta environment.
pub struct MetaSetup {
    /// The scene.
    pub model: Arc<WorldModel>,
    /// Skills in option order.
    pub skills: Vec<MetaSkill>,
    /// Allowed transitions.
    pub graph: SkillGraph,
    /// The meta observation layout (proprioception and the seat's pose), before the one-hot
    /// current skill and its phase.
    pub layout: ObservationLayout,
    /// The seat prop.
    pub seat: usize,
    /// Seconds of seat contact that count as success.
    pub hold_s: f64,
    /// Episode limit in decisions.
    pub max_decisions: u32,
    /// Episode limit in simulated seconds.
    pub time_limit_s: f64,
    /// Control ticks per decision.
    pub ticks: usize,
    /// Spawn zones episodes start in (the curriculum changes them between iterations).
    pub zones: Arc<RwLock<Vec<String>>>,
    /// Where episodes start: mid-motion in a start skill's successful end states (its
    /// `end_poses.ron`), so the first skill runs from a state it knows; `None`: standing still.
    pub start_pool: Option<(usize, Pool)>,
}

impl MetaSetup {
    /// The sitting scenario of `model` with the skills of its graph loaded from `library`.
    pub fn new(model: Arc<WorldModel>, library: &Path, graph: SkillGraph) -> Result<Self> {
        let sc = model.scenario.scenario.clone();
        let ScenarioTask::Sit { seat, hold_s, time_limit_s } = &sc.task else {
            return Err(MetaError::Invalid(format!(
                "{}: the meta-controller needs a Sit task, found {:?}",
                model.scenario.path.display(),
                sc.task
            )));
        };
        let seat_id = model.prop_id(seat).ok_or_else(|| MetaError::Invalid(format!("no seat prop `{seat}`")))?;
        let mut skills = Vec::new();
        let mut start_pool = None;
        for (k, name) in graph.names().into_iter().enumerate() {
            let pool_path = library::skill_dir(library, name).join("end_poses.ron");
            if start_pool.is_none() && graph.is_allowed(None, k) && pool_path.exists() {
                let pool = Pool::load(&pool_path)?;
                if !pool.states.is_empty() && pool.body_hash == model.body.content_hash() {
                    start_pool = Some((k, pool));
                }
            }
            let s: LibrarySkill = library::load(library, name)?;
            s.check_fits(&model)?;
            let layout = ObservationLayout::new(&model, &s.manifest.observation.features)?;
            let uses_target = matches!(s.manifest.spec.goal, Goal::Target { .. });
            skills.push(MetaSkill {
                name: name.to_string(),
                frames: s.manifest.clip.frames,
                looping: s.manifest.spec.clip.looping,
                uses_target,
                layout,
                policy: s.policy,
            });
        }
        let mut features = Feature::proprioception();
        features.push(Feature::PropPose(seat.clone()));
        let layout = ObservationLayout::new(&model, &features)?;
        let rates = sc.rates;
        let ticks = (rates.control_hz / rates.meta_hz.max(1)).max(1) as usize;
        let zones = sc.spawn.iter().map(|z| z.name.clone()).collect();
        Ok(MetaSetup {
            max_decisions: (time_limit_s * f64::from(rates.meta_hz)).round().max(1.0) as u32,
            time_limit_s: *time_limit_s,
            model,
            skills,
            graph,
            layout,
            seat: seat_id,
            hold_s: *hold_s,
            ticks,
            zones: Arc::new(RwLock::new(zones)),
            start_pool,
        })
    }

    /// Observation width of the meta-controller.
    pub fn obs_dim(&self) -> usize {
        self.layout.size + self.skills.len() + 1
    }
}

/// One meta environment.
pub struct MetaEnv {
    setup: Arc<MetaSetup>,
    world: World,
    policies: Vec<ActingPolicy>,
    map: ActionMap,
    current: Option<usize>,
    phase: usize,
    target: [f64; 2],
    judge: SitJudge,
    last_distance: f64,
    decisions: u32,
    switches: u32,
    skill_obs: Vec<f32>,
    skill_act: Vec<f32>,
    targets: Vec<f64>,
    lo: Vec<f32>,
    hi: Vec<f32>,
    /// Start pose of the current episode `(x, y, yaw)` and its zone.
    pub start: (f64, f64, f64),
    /// Zone of the current episode.
    pub zone: String,
    /// Skills chosen this episode, in order (transition matrices).
    pub chosen: Vec<usize>,
    /// When set, each episode is recorded at the control rate (see [`MetaEnv::record_episodes`]).
    record: Option<(RecordOptions, Recorder)>,
}

/// Names of the terms a recorded meta episode carries per control tick.
pub const RECORDED_TERMS: [&str; 4] = ["seat_distance", "on_seat", "seat_contact_s", "min_distance"];

impl MetaEnv {
    /// A meta environment over `setup`.
    pub fn new(setup: Arc<MetaSetup>) -> Self {
        let k = setup.skills.len();
        let dof = setup.model.index.dof();
        let widest = setup.skills.iter().map(|s| s.policy.obs_dim()).max().unwrap_or(0);
        MetaEnv {
            world: setup.model.new_world(),
            policies: setup.skills.iter().map(|s| s.policy.clone()).collect(),
            map: ActionMap::new(&setup.model),
            current: None,
            phase: 0,
            target: [0.0; 2],
            judge: SitJudge::new(setup.hold_s, f64::from(setup.model.scenario.scenario.rates.control_hz)),
            last_distance: 0.0,
            decisions: 0,
            switches: 0,
            skill_obs: vec![0.0; widest],
            skill_act: vec![0.0; dof],
            targets: vec![0.0; dof],
            lo: vec![0.0, -3.0, -3.0],
            hi: vec![(k.max(1) - 1) as f32, 3.0, 3.0],
            start: (0.0, 0.0, 0.0),
            zone: String::new(),
            chosen: Vec::new(),
            record: None,
            setup,
        }
    }

    /// Records every following episode (from its reset, one frame per control tick, with the
    /// active skill and its phase); `title` heads each recording. [`MetaEnv::recording`] hands
    /// out the current one.
    pub fn record_episodes(&mut self, title: impl Into<String>) {
        let options = RecordOptions {
            title: title.into(),
            skills: self.setup.skills.iter().map(|s| s.name.clone()).collect(),
            terms: RECORDED_TERMS.iter().map(|s| s.to_string()).collect(),
            phase: "skill frame".into(),
            ghost: None,
            capacity: (self.setup.time_limit_s * f64::from(self.setup.model.scenario.scenario.rates.control_hz))
                as usize
                + 2,
        };
        let recorder = Recorder::new(&self.setup.model, options.clone());
        self.record = Some((options, recorder));
    }

    /// The recording of the current episode so far (when recording), leaving an empty one.
    pub fn recording(&mut self) -> Option<Recording> {
        let (options, recorder) = self.record.as_mut()?;
        let fresh = Recorder::new(&self.setup.model, RecordOptions { capacity: 0, ..options.clone() });
        Some(std::mem::replace(recorder, fresh).finish())
    }

    /// Records the current state (when recording).
    fn record_frame(&mut self) {
        if self.record.is_none() {
            return;
        }
        let on = self.world.contacts().pelvis_on_prop(self.setup.seat);
        let control_dt = 1.0 / f64::from(self.setup.model.scenario.scenario.rates.control_hz);
        let terms = [
            self.seat_distance() as f32,
            f32::from(u8::from(on)),
            (f64::from(self.judge.streak()) * control_dt) as f32,
            self.judge.min_distance as f32,
        ];
        let a = Annotation { skill: self.current, phase: self.phase as f64, terms: &terms, ghost_qpos: None };
        if let Some((_, recorder)) = self.record.as_mut() {
            recorder.record(&self.world, &a);
        }
    }

    /// The world.
    pub fn world(&self) -> &World {
        &self.world
    }

    /// The success judge of the current episode.
    pub fn judge(&self) -> &SitJudge {
        &self.judge
    }

    /// Distance from the pelvis to the seat's top centre.
    fn seat_distance(&self) -> f64 {
        let p = self.world.pelvis_frame().pos;
        let pl = self.world.placements()[self.setup.seat];
        ((p[0] - pl.pos[0]).powi(2) + (p[1] - pl.pos[1]).powi(2) + (p[2] - pl.top).powi(2)).sqrt()
    }

    fn observe(&self, obs: &mut [f32]) {
        let n = self.setup.layout.size;
        self.world.observe(&self.setup.layout, &mut obs[..n]);
        let k = self.setup.skills.len();
        obs[n..n + k].fill(0.0);
        obs[n + k] = 0.0;
        if let Some(c) = self.current {
            obs[n + c] = 1.0;
            obs[n + k] = self.phi(c) as f32;
        }
    }

    fn phi(&self, skill: usize) -> f64 {
        self.phase as f64 / (self.setup.skills[skill].frames.max(2) - 1) as f64
    }

    /// One control tick of skill `c`.
    fn tick(&mut self, c: usize) {
        let skill = &self.setup.skills[c];
        let n = skill.layout.size;
        let obs = &mut self.skill_obs[..skill.policy.obs_dim()];
        self.world.observe(&skill.layout, &mut obs[..n]);
        let phi = self.phase as f64 / (skill.frames.max(2) - 1) as f64;
        obs[n] = (TAU * phi).sin() as f32;
        obs[n + 1] = (TAU * phi).cos() as f32;
        obs[n + 2] = phi as f32;
        if skill.uses_target && obs.len() >= n + 6 {
            let p = self.world.pelvis_frame().pos;
            let d = to_heading(self.world.heading(), [self.target[0] - p[0], self.target[1] - p[1], 0.0]);
            let psi = d[1].atan2(d[0]);
            obs[n + 3] = psi.sin() as f32;
            obs[n + 4] = psi.cos() as f32;
            obs[n + 5] = (d[0] * d[0] + d[1] * d[1]).sqrt() as f32;
        }
        self.policies[c].act(obs, &mut self.skill_act);
        self.map.targets(&self.skill_act, &mut self.targets);
        // Skills are finite networks on finite observations; a diverged world ends the episode
        // through the fall test below.
        let _ = self.world.step(&self.targets);
        let frames = skill.frames.max(2);
        self.phase = if skill.looping { (self.phase + 1) % (frames - 1) } else { (self.phase + 1).min(frames - 1) };
    }
}

impl Env for MetaEnv {
    fn obs_dim(&self) -> usize {
        self.setup.obs_dim()
    }

    fn act_dim(&self) -> usize {
        3
    }

    fn action_bounds(&self) -> (&[f32], &[f32]) {
        (&self.lo, &self.hi)
    }

    fn term_names(&self) -> &[&'static str] {
        &TERM_NAMES
    }

    fn options(&self) -> Option<Vec<bool>> {
        Some(self.setup.skills.iter().map(|s| s.uses_target).collect())
    }

    fn option_mask(&self, mask: &mut [bool]) {
        self.setup.graph.allowed(self.current, mask);
    }

    fn reset(&mut self, rng: &mut EnvRng, obs: &mut [f32]) {
        let zone = {
            let zones = self.setup.zones.read().expect("the zone list is never poisoned");
            zones[rng.random_range(0..zones.len())].clone()
        };
        self.start = self.world.reset_in_zone(&zone, rng).expect("zones come from the scenario");
        self.zone = zone;
        self.current = None;
        self.phase = 0;
        self.decisions = 0;
        self.switches = 0;
        self.chosen.clear();
        self.judge = SitJudge::new(self.setup.hold_s, f64::from(self.setup.model.scenario.scenario.rates.control_hz));
        if let Some((k, pool)) = &self.setup.start_pool {
            let state = &pool.states[rng.random_range(0..pool.states.len())];
            let (x, y, yaw) = self.start;
            state.apply(&mut self.world, x, y, yaw).expect("pool states are validated on load");
            self.current = Some(*k);
            self.phase = state.phase.min(self.setup.skills[*k].frames.saturating_sub(1));
            self.chosen.push(*k);
        }
        self.last_distance = self.seat_distance();
        self.judge.tick(false, self.last_distance);
        if let Some((options, recorder)) = self.record.as_mut() {
            *recorder = Recorder::new(&self.setup.model, options.clone());
        }
        self.record_frame();
        self.observe(obs);
    }

    fn step(&mut self, action: &[f32], obs: &mut [f32]) -> StepOutcome {
        let k = self.setup.skills.len();
        let option = (action[0].round().max(0.0) as usize).min(k - 1);
        let mut mask = vec![false; k];
        self.setup.graph.allowed(self.current, &mut mask);
        // The policy masks forbidden options; a forbidden choice from elsewhere keeps the
        // current skill (or takes the first allowed one at the start).
        let option = if mask[option] {
            option
        } else {
            self.current.unwrap_or_else(|| mask.iter().position(|&m| m).unwrap_or(0))
        };
        let clip_over = |env: &Self, c: usize| {
            let sk = &env.setup.skills[c];
            !sk.looping && env.phase + 1 >= sk.frames.max(2)
        };
        if self.current == Some(option) && clip_over(self, option) {
            self.phase = 0;
        }
        if self.current != Some(option) {
            self.phase = 0;
            self.switches += u32::from(self.current.is_some());
            self.current = Some(option);
            self.chosen.push(option);
            let p = self.world.pelvis_frame().pos;
            let yaw = self.world.heading();
            let (dx, dy) = (f64::from(action[1]), f64::from(action[2]));
            self.target = [p[0] + yaw.cos() * dx - yaw.sin() * dy, p[1] + yaw.sin() * dx + yaw.cos() * dy];
        }
        let mut fell = false;
        let mut ran = 0usize;
        for _ in 0..self.setup.ticks {
            self.tick(option);
            ran += 1;
            let on = self.world.contacts().pelvis_on_prop(self.setup.seat);
            let d = self.seat_distance();
            self.judge.tick(on, d);
            self.record_frame();
            if self.world.has_fallen() || !self.world.root_height().is_finite() {
                fell = true;
                break;
            }
            if self.judge.succeeded || clip_over(self, option) {
                break;
            }
        }
        self.decisions += 1;
        let d = self.seat_distance();
        let control_dt = 1.0 / f64::from(self.setup.model.scenario.scenario.rates.control_hz);
        let dt = ran as f64 * control_dt;
        let on_seat = self.world.contacts().pelvis_on_prop(self.setup.seat);
        let reward = if fell {
            0.0
        } else if on_seat {
            1.0
        } else {
            (0.5 * -(d - self.last_distance) / dt) as f32
        };
        self.last_distance = d;
        let success = self.judge.succeeded;
        // Decisions can end early (a clip's end), so the limit is in simulated time, with a
        // decision count as a backstop.
        let out_of_time =
            self.world.time() >= self.setup.time_limit_s - 1e-9 || self.decisions >= 4 * self.setup.max_decisions;
        let truncated = !success && !fell && out_of_time;
        let done = success || fell || truncated;
        let mut terms = [0.0; MAX_TERMS];
        if done {
            terms[0] = f32::from(u8::from(success));
            terms[1] = self.judge.min_distance as f32;
            terms[2] = f32::from(u8::from(fell));
            terms[3] = self.world.time() as f32;
            terms[4] = self.switches as f32;
        }
        self.observe(obs);
        if obs.iter().any(|v| !v.is_finite()) {
            obs.fill(0.0);
            return StepOutcome { reward: 0.0, terminated: true, truncated: false, terms };
        }
        StepOutcome { reward, terminated: success || fell, truncated, terms }
    }

    fn snapshot(&self) -> Vec<f64> {
        let mut out = Vec::new();
        self.world.snapshot(&mut out);
        out.extend_from_slice(&[
            self.current.map_or(-1.0, |c| c as f64),
            self.phase as f64,
            self.target[0],
            self.target[1],
            self.last_distance,
            f64::from(self.decisions),
            f64::from(self.switches),
            f64::from(self.judge.streak()),
            f64::from(u8::from(self.judge.succeeded)),
            self.judge.min_distance,
        ]);
        out
    }

    fn restore(&mut self, state: &[f64]) -> std::result::Result<(), String> {
        let w = self.world.snapshot_len();
        if state.len() != w + 10 {
            return Err(format!("meta snapshot has {} values, expected {}", state.len(), w + 10));
        }
        self.world.restore(&state[..w]).map_err(|e| e.to_string())?;
        let s = &state[w..];
        self.current = (s[0] >= 0.0).then_some(s[0] as usize);
        self.phase = s[1] as usize;
        self.target = [s[2], s[3]];
        self.last_distance = s[4];
        self.decisions = s[5] as u32;
        self.switches = s[6] as u32;
        self.judge.restore(s[7] as u32, s[8] != 0.0, s[9]);
        Ok(())
    }
}
