//! [`MetaEnv`]: a scenario's task at the meta rate. Each decision picks a skill (masked by the
//! skill graph) and a continuous 2-D target (its azimuth and distance, in units of the range the
//! skill was trained on); the chosen skill's frozen policy then drives the character for
//! `control_hz / meta_hz` control ticks. The task ([`crate::task`]) decides the reward, success
//! and failure: sitting rewards 1 while the pelvis touches the seat, else the approach
//! `0.5·(−dΦ/dt)` ([`crate::task::sit_potential`]), and ends on success (3 s of unbroken seat
//! contact); the warehouse rewards 1 per completed phase; the toss rewards the ball's time in
//! the bucket. Every episode ends on a fall, a task failure or the time limit.
//!
//! Episodes start mid-motion in the first start skill's successful end states (e.g. walking),
//! at the spawn point and heading the zone draws; without such a pool, standing still. A task
//! may place the character itself (a warehouse episode starting in LIFT, CARRY or PUTDOWN).
//!
//! The props a skill observes are named after its training scene; the scenario's `bind` map
//! resolves them here ([`crate::bind`]): a warehouse binds lift's `"pedestal"` to the focal
//! pedestal, read when the skill starts playing and held while it plays.
//!
//! A skill whose clip does not loop (a turn cycle, the sit-down) is never run past its clip's
//! end, where its policy was never trained: the decision ends early there, and choosing the
//! same skill again plays its clip once more from the start.

use std::f64::consts::{FRAC_PI_2, FRAC_PI_4, TAU};
use std::path::Path;
use std::sync::{Arc, RwLock};

use rand::Rng;
use repertoire_humanoid::ActionMap;
use repertoire_learn::acting::ActingPolicy;
use repertoire_learn::env::{Env, EnvRng, MAX_TERMS, StateError, StepOutcome};
use repertoire_scenes::math::wrap_angle;
use repertoire_scenes::scenario::{PropBinding, WarehousePhase};
use repertoire_scenes::{
    Annotation, Feature, ObservationLayout, RecordOptions, Recorder, Recording, World, WorldModel,
};
use repertoire_skill::library::{self, LibrarySkill};
use repertoire_skill::pool::Pool;
use repertoire_skill::reference::to_heading;
use repertoire_skill::spec::Goal;

use crate::bind::SkillProps;
use crate::error::{MetaError, Result};
use crate::graph::SkillGraph;
use crate::task::{EpisodeOverride, TaskSpec, TaskState};

/// Names of the sitting task's per-episode figures in [`StepOutcome::terms`] (reported on the
/// last step); other tasks name theirs in [`TaskSpec::term_names`].
pub const TERM_NAMES: [&str; 5] = crate::task::SIT_TERMS;

/// The prop a skill's guard measures from.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum GuardProp {
    /// A prop of the scene.
    Prop(usize),
    /// The warehouse's focal pedestal at the decision.
    Focal,
}

/// One skill as the meta-controller runs it.
#[derive(Debug, Clone)]
pub struct MetaSkill {
    /// Its name.
    pub name: String,
    /// Its frozen policy.
    pub policy: ActingPolicy,
    /// Its policy file's checksum (`policy_fnv1a` of its library manifest).
    pub policy_fnv1a: u64,
    /// Its observation layout on this scene.
    pub layout: ObservationLayout,
    /// The scene's props its prop features read (bound by the scenario's `bind` map).
    pub props: SkillProps,
    /// Frames of its clip at the control rate.
    pub frames: usize,
    /// Whether its clip loops.
    pub looping: bool,
    /// Whether it holds its clip's last frame while chosen again (a sit stays seated) rather
    /// than replaying the clip (a second turn).
    pub holds: bool,
    /// Whether it observes a 2-D target (walk, stage 2).
    pub uses_target: bool,
    /// The range its targets were drawn from in training (for [`MetaSkill::target_offset`]).
    pub target_range: TargetRange,
    /// A cycle's joint angles and velocities per frame (`frames × dof`; from the manifest's
    /// clip record, empty when it has none): choosing the skill picks the cycle up at the frame
    /// nearest the character's pose instead of its first frame.
    pub cycle: (Vec<f32>, Vec<f32>),
    /// The scenario's precondition on switching to it (`skill_graph.guards`): the prop and the
    /// largest pelvis–prop distance (m) at which it may be chosen.
    pub guard: Option<(GuardProp, f64)>,
    /// The hands' grip level while it plays (its spec's `grip`).
    pub grip: f64,
}

/// Where a target-taking skill's training targets lay, in its heading frame: `distance_m` away,
/// within ±`azimuth_deg` of the heading.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TargetRange {
    /// Distance range (m).
    pub distance_m: (f64, f64),
    /// Azimuth either side of the heading (degrees).
    pub azimuth_deg: f64,
}

impl TargetRange {
    /// The range of a skill's goal (the walk stage 2's), or a 2 m ± 90° default.
    pub fn of(goal: &Goal) -> TargetRange {
        match goal.steering() {
            Some(st) => TargetRange { distance_m: st.distance_m, azimuth_deg: st.azimuth_deg },
            None => TargetRange { distance_m: (2.0, 2.0), azimuth_deg: 90.0 },
        }
    }
}

impl MetaSkill {
    /// The target offset, in the pelvis' heading frame (m), of the meta-controller's continuous
    /// action `a`: `a[0]` is the azimuth and `a[1]` the distance, each in units of the skill's
    /// training range (−1 … 1, clamped): `[0, 0]` is the middle distance straight ahead. So the
    /// controller's initial Gaussian already asks for targets like the ones the skill learned
    /// to walk to, never one at its feet or behind it.
    pub fn target_offset(&self, a: [f32; 2]) -> [f64; 2] {
        let r = self.target_range;
        let psi = (f64::from(a[0]).clamp(-1.0, 1.0) * r.azimuth_deg).to_radians();
        let (lo, hi) = r.distance_m;
        let d = lo + (hi - lo) * 0.5 * (f64::from(a[1]).clamp(-1.0, 1.0) + 1.0);
        [d * psi.cos(), d * psi.sin()]
    }

    /// The action [`MetaSkill::target_offset`] maps to a target `distance` m away at
    /// `azimuth_deg` from the heading (both clamped to the skill's range).
    pub fn target_action(&self, azimuth_deg: f64, distance: f64) -> [f32; 2] {
        let r = self.target_range;
        let (lo, hi) = r.distance_m;
        let a0 = if r.azimuth_deg > 0.0 { (azimuth_deg / r.azimuth_deg).clamp(-1.0, 1.0) } else { 0.0 };
        let a1 = if hi > lo { (2.0 * (distance - lo) / (hi - lo) - 1.0).clamp(-1.0, 1.0) } else { 0.0 };
        [a0 as f32, a1 as f32]
    }

    /// The clip frame after `phase`: a looping clip wraps, a holding one stays on its last
    /// frame, and any other stops there too (until [`MetaSkill::ended`] lets a new choice
    /// restart it).
    pub fn advance(&self, phase: usize) -> usize {
        let frames = self.frames.max(2);
        if self.looping { (phase + 1) % (frames - 1) } else { (phase + 1).min(frames - 1) }
    }

    /// Whether the skill's clip has played out at `phase`: the decision ends there, and
    /// choosing the skill again replays it from its first frame. Never for looping clips, nor
    /// for holding ones (a sit chosen again stays seated).
    pub fn ended(&self, phase: usize) -> bool {
        !self.looping && !self.holds && phase + 1 >= self.frames.max(2)
    }

    /// The frame the skill starts at when chosen with the body at joint angles `q` and
    /// velocities `v`: the nearest frame of a cycle it has a table for, else the first.
    pub fn entry_frame(&self, q: &[f64], v: &[f64]) -> usize {
        let dof = q.len();
        if !self.looping
            || dof == 0
            || self.cycle.0.len() != self.frames * dof
            || self.cycle.1.len() != self.cycle.0.len()
        {
            return 0;
        }
        repertoire_skill::reference::nearest_pose(
            &self.cycle.0,
            &self.cycle.1,
            dof,
            self.frames.saturating_sub(1).max(1),
            q,
            v,
        )
    }
}

/// The scene, the skills and the graph, shared by every meta environment.
pub struct MetaSetup {
    /// The scene.
    pub model: Arc<WorldModel>,
    /// Skills in option order.
    pub skills: Vec<MetaSkill>,
    /// Allowed transitions.
    pub graph: SkillGraph,
    /// The meta observation layout (proprioception and the task's props, e.g. the seat's
    /// pose), before the task's own values, the one-hot current skill and its phase.
    pub layout: ObservationLayout,
    /// The task: its props, reward, success and failure.
    pub task: TaskSpec,
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
    /// The option of the warehouse's `hold_from` skill (lift), when the graph has it: a CARRY
    /// or PUTDOWN episode starts in that skill's end states, so it starts as if that skill had
    /// just played (the graph's successors of it are what may follow).
    pub hold_skill: Option<usize>,
    /// The scenario's `detour`: the props a target-taking skill's target steers around and the
    /// radius kept clear of their centres (see [`detour_target`]).
    pub detour: Option<(Vec<usize>, f64)>,
}

impl MetaSetup {
    /// The option a meta action names: its first value rounded to a skill index, clamped to
    /// the skills (before the graph's mask, which [`MetaEnv::begin_decision`] applies).
    pub fn option_of(&self, action: &[f32]) -> usize {
        (action[0].round().max(0.0) as usize).min(self.skills.len() - 1)
    }

    /// The scenario of `model` (a Sit, Warehouse or Toss task) with the skills of its graph
    /// loaded from `library`. Skills the library lacks are named in the error.
    pub fn new(model: Arc<WorldModel>, library: &Path, graph: SkillGraph) -> Result<Self> {
        let sc = model.scenario.scenario.clone();
        let mut task = TaskSpec::of(&model)?;
        if sc.spawn.is_empty() {
            return Err(MetaError::Invalid(format!(
                "{}: the meta-controller needs at least one spawn zone (`spawn: [Zone(...)]`)",
                model.scenario.path.display()
            )));
        }
        let time_limit_s = sc.task.time_limit_s();
        let missing: Vec<&str> = graph
            .names()
            .into_iter()
            .filter(|name| !library::skill_dir(library, name).join("manifest.ron").exists())
            .collect();
        if !missing.is_empty() {
            let mut have: Vec<String> = std::fs::read_dir(library)
                .map(|dir| {
                    dir.filter_map(|e| e.ok())
                        .filter(|e| e.path().join("manifest.ron").exists())
                        .map(|e| e.file_name().to_string_lossy().into_owned())
                        .collect()
                })
                .unwrap_or_default();
            have.sort();
            return Err(MetaError::Invalid(format!(
                "{}: the {} task needs skill{} {} that the library {} does not have (it has: {}); train \
                 them with `repertoire skill train`, or restrict the scenario's skills with `--skills`",
                model.scenario.path.display(),
                task.name(),
                if missing.len() == 1 { "" } else { "s" },
                missing.join(", "),
                library.display(),
                if have.is_empty() { "none".to_string() } else { have.join(", ") }
            )));
        }
        task.load_from_library(&model, library)?;
        let mut skills = Vec::new();
        let mut start_pool = None;
        let mut observed: Vec<String> = Vec::new();
        for (k, name) in graph.names().into_iter().enumerate() {
            let pool_path = library::skill_dir(library, name).join("end_poses.ron");
            if start_pool.is_none() && graph.is_allowed(None, k) && pool_path.exists() {
                let pool = Pool::load(&pool_path)?;
                if !pool.states.is_empty() && pool.body_hash == model.body.content_hash() {
                    start_pool = Some((k, pool));
                }
            }
            let s: LibrarySkill = library::load(library, name)?;
            let (layout, props) = SkillProps::resolve(&model, &task, name, &s.manifest.observation.features)?;
            observed.extend(crate::bind::observed_props(&s.manifest.observation.features).map(String::from));
            s.check_fits_layout(&model, &layout)?;
            let uses_target = s.manifest.spec.goal.steering().is_some();
            let guard = sc.skill_graph.iter().flat_map(|g| &g.guards).find(|g| g.skill == name).map(|g| {
                let prop = match (model.prop_id(&g.near), sc.bind.get(&g.near)) {
                    (Some(p), _) => GuardProp::Prop(p),
                    (None, Some(PropBinding::Prop(other))) => {
                        GuardProp::Prop(model.prop_id(other).expect("bindings are validated with the scenario"))
                    }
                    (None, Some(PropBinding::Focal)) => GuardProp::Focal,
                    (None, None) => unreachable!("guards are validated with the scenario"),
                };
                (prop, g.within_m)
            });
            skills.push(MetaSkill {
                name: name.to_string(),
                frames: s.manifest.clip.frames,
                looping: s.manifest.spec.clip.looping,
                holds: s.manifest.spec.clip.hold_s > 0.0,
                uses_target,
                target_range: TargetRange::of(&s.manifest.spec.goal),
                cycle: (s.manifest.clip.cycle_joints.clone(), s.manifest.clip.cycle_joint_vel.clone()),
                policy_fnv1a: s.manifest.policy_fnv1a,
                layout,
                props,
                grip: s.manifest.spec.grip,
                policy: s.policy,
                guard,
            });
        }
        // Episodes start in the first start skill's end poses; one without a pool silently
        // hands the start to a later skill's (a new walk not yet evaluated: stop 40).
        let first_start = (0..graph.len()).find(|&k| graph.is_allowed(None, k));
        if let (Some(first), Some((k, _))) = (first_start, &start_pool)
            && first != *k
        {
            let names = graph.names();
            tracing::warn!(
                skill = names[first],
                instead = names[*k],
                "the graph's first start skill has no usable end-pose pool (run `repertoire skill eval` on it \
                 without --no-pool): episodes start in the end poses of the next start skill that has one"
            );
        }
        let observed: Vec<&str> = observed.iter().map(String::as_str).collect();
        for key in crate::bind::unused_bindings(&sc.bind, &observed) {
            tracing::warn!(
                scenario = %model.scenario.path.display(),
                "`bind` entry `{key}` is read by none of the graph's skills (they observe: {}); it does nothing",
                if observed.is_empty() { "no props".to_string() } else { observed.join(", ") }
            );
        }
        let hold_skill = match &task {
            TaskSpec::Warehouse(w) => w.hold_from.as_deref().and_then(|name| graph.index(name)),
            _ => None,
        };
        let mut features = Feature::proprioception();
        features.extend(task.features(&model));
        let layout = ObservationLayout::new(&model, &features)?;
        let rates = sc.rates;
        let ticks = (rates.control_hz / rates.meta_hz.max(1)).max(1) as usize;
        let zones = sc.spawn.iter().map(|z| z.name.clone()).collect();
        let detour = sc.detour.as_ref().map(|d| {
            let props =
                d.around.iter().map(|n| model.prop_id(n).expect("detour props are validated with the scenario"));
            (props.collect(), d.radius_m)
        });
        Ok(MetaSetup {
            max_decisions: (time_limit_s * f64::from(rates.meta_hz)).round().max(1.0) as u32,
            time_limit_s,
            model,
            skills,
            graph,
            layout,
            task,
            ticks,
            zones: Arc::new(RwLock::new(zones)),
            start_pool,
            hold_skill,
            detour,
        })
    }

    /// An error naming the first of `zones` the scenario does not declare.
    pub fn check_zones(&self, zones: &[String]) -> Result<()> {
        check_zones(&self.model, zones)
    }

    /// What a controller trained here drives, one entry per skill in option order (`name`
    /// and its policy checksum): a training checkpoint continues only over the same.
    pub fn low_level(&self) -> Vec<String> {
        self.skills.iter().map(|s| format!("{} {:016x}", s.name, s.policy_fnv1a)).collect()
    }

    /// Observation width of the meta-controller.
    pub fn obs_dim(&self) -> usize {
        self.layout.size + self.task.extra_dim() + self.skills.len() + 1
    }

    /// Control ticks per second.
    pub fn control_hz(&self) -> f64 {
        f64::from(self.model.scenario.scenario.rates.control_hz)
    }
}

/// The target a walker at `from` is given for `target` when it must keep `radius` m from each
/// of `centres` (the scenario's `detour`). The straight way to the target meets a circle when
/// its closest point to the centre lies inside the circle and short of the target; the first
/// circle met turns the target, at the same distance, onto that circle's tangent from `from`
/// on the side the way passed the centre (from inside the circle: square to the centre and
/// turned outwards the more the deeper in, so the walker skirts it and leaves the circle). A
/// way that clears every circle, or ends before its closest point (a target in front of the
/// prop, approached from that side), keeps its target.
pub fn detour_target(
    from: [f64; 2],
    target: [f64; 2],
    centres: impl Iterator<Item = [f64; 2]>,
    radius: f64,
) -> [f64; 2] {
    let v = [target[0] - from[0], target[1] - from[1]];
    let len2 = v[0] * v[0] + v[1] * v[1];
    if len2 < 1e-12 {
        return target;
    }
    // (along the way, centre offset) of the first circle met
    let mut first: Option<(f64, [f64; 2])> = None;
    for c in centres {
        let w = [c[0] - from[0], c[1] - from[1]];
        let s = (w[0] * v[0] + w[1] * v[1]) / len2;
        if s <= 0.0 || s >= 1.0 {
            continue;
        }
        let closest = (w[0] - s * v[0]).hypot(w[1] - s * v[1]);
        if closest < radius && first.is_none_or(|(t, _)| s < t) {
            first = Some((s, w));
        }
    }
    let Some((_, w)) = first else { return target };
    // Outside: the tangent. Inside: square to the centre and turned out by up to 45° more the
    // deeper in, so the walker leaves the circle as it goes round.
    let depth = w[0].hypot(w[1]) / radius;
    let beta = if depth > 1.0 { (1.0 / depth).asin() } else { FRAC_PI_2 + (1.0 - depth) * FRAC_PI_4 };
    // The centre left of the way (counter-clockwise of it): pass it on the right.
    let left = v[0] * w[1] - v[1] * w[0] > 0.0;
    let heading = w[1].atan2(w[0]) + if left { -beta } else { beta };
    let distance = len2.sqrt();
    [from[0] + distance * heading.cos(), from[1] + distance * heading.sin()]
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
    task: TaskState,
    over: EpisodeOverride,
    decisions: u32,
    switches: u32,
    skill_obs: Vec<f32>,
    /// Per skill: the props its prop features read in this episode (see [`SkillProps`]).
    bound: Vec<Vec<usize>>,
    skill_act: Vec<f32>,
    /// The body's joint angles and velocities when a skill is chosen (its entry frame).
    entry_q: Vec<f64>,
    entry_v: Vec<f64>,
    targets: Vec<f64>,
    lo: Vec<f32>,
    hi: Vec<f32>,
    /// Start pose of the current episode `(x, y, yaw)` and its zone.
    pub start: (f64, f64, f64),
    /// Zone of the current episode.
    pub zone: String,
    /// Skills chosen this episode, in order (transition matrices).
    pub chosen: Vec<usize>,
    /// The skill that was playing when the character first touched the task's frame prop (the
    /// chair) this episode; `None` while it has not. Diagnostics (`meta eval`'s `touched`):
    /// a walk that ends in a fall after touching the chair bumped into it.
    pub touched: Option<usize>,
    /// Per skill: whether the graph lets nothing follow it (the sit), so touching the chair
    /// while it plays is not a bump ([`TaskSpec::touch_penalty`]).
    terminal: Vec<bool>,
    /// When set, each episode is recorded at the control rate (see [`MetaEnv::record_episodes`]).
    record: Option<Recorder>,
    /// The decision in progress (between [`MetaEnv::begin_decision`] and
    /// [`MetaEnv::end_decision`]).
    decision: Decision,
}

/// The decision in progress: its skill and how its control ticks went.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
struct Decision {
    option: usize,
    /// Control ticks run.
    ran: usize,
    fell: bool,
    /// The task failed (its own test, e.g. a dropped box).
    failed: bool,
    /// The character touched the chair while a non-terminal skill played (touch penalty).
    bumped: bool,
    /// Whether bumps are watched in this decision.
    watch_bumps: bool,
}

/// How many values [`MetaEnv::decision_snapshot`] writes.
pub const DECISION_VALUES: usize = 6;

/// Names of the terms a recorded sitting episode carries per control tick (other tasks: see
/// [`TaskSpec::recorded_terms`]).
pub const RECORDED_TERMS: [&str; 4] = ["seat_distance", "seated", "seated_s", "min_distance"];

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
            task: setup.task.new_state(setup.control_hz()),
            over: EpisodeOverride::default(),
            decisions: 0,
            switches: 0,
            skill_obs: vec![0.0; widest],
            bound: setup.skills.iter().map(|s| s.props.ids.clone()).collect(),
            skill_act: vec![0.0; dof],
            entry_q: vec![0.0; setup.model.index.joints.len()],
            entry_v: vec![0.0; setup.model.index.joints.len()],
            targets: vec![0.0; dof],
            lo: vec![0.0, -3.0, -3.0],
            hi: vec![(k.max(1) - 1) as f32, 3.0, 3.0],
            start: (0.0, 0.0, 0.0),
            zone: String::new(),
            chosen: Vec::new(),
            touched: None,
            terminal: terminal_skills(&setup),
            record: None,
            decision: Decision::default(),
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
            terms: self.setup.task.recorded_terms().iter().map(|s| s.to_string()).collect(),
            phase: "skill frame".into(),
            ghost: None,
            capacity: (self.setup.time_limit_s * f64::from(self.setup.model.scenario.scenario.rates.control_hz))
                as usize
                + 2,
        };
        self.record = Some(Recorder::new(&self.setup.model, options));
    }

    /// The recording of the current episode so far (when recording), leaving an empty one.
    pub fn recording(&mut self) -> Option<Recording> {
        self.record.as_mut().map(Recorder::take)
    }

    /// Records the current state (when recording).
    fn record_frame(&mut self) {
        if self.record.is_none() {
            return;
        }
        let control_dt = 1.0 / self.setup.control_hz();
        let terms = self.task.recorded(&self.setup.task, &self.world, control_dt);
        let a = Annotation { skill: self.current, phase: self.phase as f64, terms: &terms, ghost_qpos: None };
        if let Some(recorder) = self.record.as_mut() {
            recorder.record(&self.world, &a);
        }
    }

    /// The world.
    pub fn world(&self) -> &World {
        &self.world
    }

    /// The world, for tests that place the character or props by hand.
    pub fn world_mut(&mut self) -> &mut World {
        &mut self.world
    }

    /// The skill playing now (None before the first decision).
    pub fn current(&self) -> Option<usize> {
        self.current
    }

    /// Which options the next decision may choose: the graph's successors of the current skill
    /// (or its start skills), less guarded skills whose guard fails now (the pelvis farther
    /// from the guard's prop than allowed). The current skill may always continue; were every
    /// start skill guarded off at an episode's start, the graph's own mask stands.
    pub fn allowed_now(&self, mask: &mut [bool]) {
        self.setup.graph.allowed(self.current, mask);
        for (k, skill) in self.setup.skills.iter().enumerate() {
            let Some((prop, within)) = skill.guard else { continue };
            if !mask[k] || self.current == Some(k) {
                continue;
            }
            let prop = match prop {
                GuardProp::Prop(p) => p,
                GuardProp::Focal => match self.task.focal_prop(&self.setup.task) {
                    Some(p) => p,
                    None => continue,
                },
            };
            let d = self.world.prop_relative(prop);
            if d[0].hypot(d[1]) > within {
                mask[k] = false;
            }
        }
        if !mask.iter().any(|&m| m) {
            self.setup.graph.allowed(self.current, mask);
        }
    }

    /// The task state of the current episode (the judges).
    pub fn task(&self) -> &TaskState {
        &self.task
    }

    /// Makes the following episodes start as `over` says (evaluation grids); the default
    /// draws everything.
    pub fn set_override(&mut self, over: EpisodeOverride) {
        self.over = over;
    }

    fn observe(&self, obs: &mut [f32]) {
        let n = self.setup.layout.size;
        self.world.observe(&self.setup.layout, &mut obs[..n]);
        let e = self.setup.task.extra_dim();
        self.task.observe(&self.setup.task, &self.world, &mut obs[n..n + e]);
        let n = n + e;
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

    /// The props skill `c`'s prop features read now, in feature order (its `bind`ings).
    pub fn bound_props(&self, c: usize) -> &[usize] {
        &self.bound[c]
    }

    /// Re-reads skill `c`'s role-bound props from the task state (when it starts playing).
    fn bind_props(&mut self, c: usize) {
        let props = &self.setup.skills[c].props;
        if props.has_roles() {
            props.refresh(&self.setup.task, &self.task, &mut self.bound[c]);
        }
    }

    /// Writes what skill `c`'s policy observes now into `obs` (its policy's input width): its
    /// layout over its bound props, its clip phase, and the target when it takes one.
    pub fn skill_observation(&self, c: usize, obs: &mut [f32]) {
        let skill = &self.setup.skills[c];
        let n = skill.layout.size;
        self.world.observe_props(&skill.layout, &self.bound[c], &mut obs[..n]);
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
    }

    /// One control tick of skill `c`: its frozen policy acts, or `external` (normalised
    /// actions, its policy's width) does in its place.
    fn tick(&mut self, c: usize, external: Option<&[f32]>) {
        match external {
            Some(a) => self.skill_act.copy_from_slice(a),
            None => {
                let width = self.setup.skills[c].policy.obs_dim();
                let mut obs = std::mem::take(&mut self.skill_obs);
                self.skill_observation(c, &mut obs[..width]);
                self.policies[c].act(&obs[..width], &mut self.skill_act);
                self.skill_obs = obs;
            }
        }
        let skill = &self.setup.skills[c];
        self.map.targets(&self.skill_act, &mut self.targets);
        self.world.set_grip(skill.grip);
        // Skills are finite networks on finite observations; a diverged world ends the episode
        // through the fall test below.
        let _ = self.world.step(&self.targets);
        self.phase = skill.advance(self.phase);
    }

    /// The current skill's clip phase (its reference frame at the control rate).
    pub fn phase(&self) -> usize {
        self.phase
    }

    /// The walking target (world x, y) the current decision gave a target-taking skill.
    pub fn target(&self) -> [f64; 2] {
        self.target
    }

    /// Starts a decision on the meta action `action` (option, then the 2-D target): the option
    /// is masked by the graph and the guards (a forbidden one keeps the current skill), a
    /// switch picks the new skill's clip up at its entry frame, and a target-taking skill gets
    /// this decision's target. Returns the option that plays. [`Env::step`] is this, then
    /// [`MetaEnv::decision_tick`] until it says the decision is over, then
    /// [`MetaEnv::end_decision`]; a caller may drive the ticks itself (a skill fine-tuned in
    /// the controller's episodes, [`crate::handover::refine`]).
    pub fn begin_decision(&mut self, action: &[f32]) -> usize {
        let k = self.setup.skills.len();
        let option = self.setup.option_of(action);
        let mut mask = vec![false; k];
        self.allowed_now(&mut mask);
        // The policy masks forbidden options; a forbidden choice from elsewhere keeps the
        // current skill (or takes the first allowed one at the start).
        let option = if mask[option] {
            option
        } else {
            self.current.unwrap_or_else(|| mask.iter().position(|&m| m).unwrap_or(0))
        };
        if self.current == Some(option) && self.setup.skills[option].ended(self.phase) {
            self.phase = 0;
            self.bind_props(option);
        }
        let switched = self.current != Some(option);
        if switched {
            self.world.joint_angles(&mut self.entry_q);
            self.world.joint_velocities(&mut self.entry_v);
            self.phase = self.setup.skills[option].entry_frame(&self.entry_q, &self.entry_v);
            self.bind_props(option);
            self.switches += u32::from(self.current.is_some());
            self.current = Some(option);
            self.chosen.push(option);
        }
        // A skill that takes a target (walk, stage 2) gets the one of this decision, in the
        // pelvis' heading frame and the skill's training range: the meta-controller steers it
        // every decision.
        if switched || self.setup.skills[option].uses_target {
            let p = self.world.pelvis_frame().pos;
            let yaw = self.world.heading();
            let [dx, dy] = self.setup.skills[option].target_offset([action[1], action[2]]);
            self.target = [p[0] + yaw.cos() * dx - yaw.sin() * dy, p[1] + yaw.sin() * dx + yaw.cos() * dy];
            if let Some((props, radius)) = &self.setup.detour {
                let placements = self.world.placements();
                let centres = props.iter().map(|&i| [placements[i].pos[0], placements[i].pos[1]]);
                self.target = detour_target([p[0], p[1]], self.target, centres, *radius);
            }
        }
        let watch_bumps = self.setup.task.touch_penalty() > 0.0 && !self.terminal[option];
        self.decision = Decision { option, watch_bumps, ..Decision::default() };
        option
    }

    /// One control tick of the decision's skill: its frozen policy acts, or `external` does
    /// (normalised actions, the skill's action width). Returns whether the decision is over: a
    /// fall, a task failure, success (tasks that end on it), the clip's end, or its ticks run.
    pub fn decision_tick(&mut self, external: Option<&[f32]>) -> bool {
        let option = self.decision.option;
        self.tick(option, external);
        self.decision.ran += 1;
        let control_dt = 1.0 / self.setup.control_hz();
        self.decision.failed = self.task.tick(&self.setup.task, &self.world, control_dt);
        let d = &mut self.decision;
        if (self.touched.is_none() || (d.watch_bumps && !d.bumped))
            && self.world.contacts().character_on_prop(self.setup.task.frame_prop())
        {
            self.touched.get_or_insert(option);
            d.bumped = d.watch_bumps;
        }
        self.record_frame();
        if self.world.has_fallen() || !self.world.root_height().is_finite() {
            self.decision.fell = true;
            return true;
        }
        self.decision.failed
            || (self.setup.task.ends_on_success() && self.task.succeeded())
            || self.setup.skills[option].ended(self.phase)
            || self.decision.ran >= self.setup.ticks
    }

    /// Ends the decision: its reward, whether the episode ended (success, a fall, a failure)
    /// or ran out of time, the episode's figures when it did, and the next meta observation
    /// into `obs`.
    pub fn end_decision(&mut self, obs: &mut [f32]) -> StepOutcome {
        let Decision { ran, fell, failed, bumped, .. } = self.decision;
        let control_dt = 1.0 / self.setup.control_hz();
        self.decisions += 1;
        let dt = ran as f64 * control_dt;
        let reward = self.task.decision_reward(&self.setup.task, &self.world, fell, bumped, dt);
        let success = self.task.succeeded();
        // Decisions can end early (a clip's end), so the limit is in simulated time, with a
        // decision count as a backstop.
        let out_of_time =
            self.world.time() >= self.setup.time_limit_s - 1e-9 || self.decisions >= 4 * self.setup.max_decisions;
        let ended = (self.setup.task.ends_on_success() && success) || fell || failed;
        let truncated = !ended && out_of_time;
        let done = ended || truncated;
        let mut terms = [0.0; MAX_TERMS];
        if done {
            terms[0] = f32::from(u8::from(success));
            terms[2] = fall_term(fell, &self.world);
            terms[3] = self.world.time() as f32;
            terms[4] = self.switches as f32;
            self.task.terms(&mut terms);
        }
        self.observe(obs);
        if obs.iter().any(|v| !v.is_finite()) {
            obs.fill(0.0);
            return StepOutcome { reward: 0.0, terminated: true, truncated: false, terms };
        }
        StepOutcome { reward, terminated: ended, truncated, terms }
    }

    /// The decision in progress as [`DECISION_VALUES`] numbers (with [`Env::snapshot`], the
    /// state mid-decision).
    pub fn decision_snapshot(&self) -> [f64; DECISION_VALUES] {
        let d = &self.decision;
        let b = |v: bool| f64::from(u8::from(v));
        [d.option as f64, d.ran as f64, b(d.fell), b(d.failed), b(d.bumped), b(d.watch_bumps)]
    }

    /// Restores [`MetaEnv::decision_snapshot`]; `Err` names a skill out of range.
    pub fn restore_decision(&mut self, s: &[f64]) -> std::result::Result<(), StateError> {
        let skills = self.setup.skills.len();
        if s.len() != DECISION_VALUES {
            return Err(StateError::length("decision snapshot", DECISION_VALUES, s.len()));
        }
        if !(s[0] >= 0.0 && s[0].fract() == 0.0 && (s[0] as usize) < skills && s[1] >= 0.0) {
            return Err(StateError::OutOfRange {
                what: "decision snapshot's skill".into(),
                value: s[0],
                count: skills,
                of: "skills",
            });
        }
        self.decision = Decision {
            option: s[0] as usize,
            ran: s[1] as usize,
            fell: s[2] != 0.0,
            failed: s[3] != 0.0,
            bumped: s[4] != 0.0,
            watch_bumps: s[5] != 0.0,
        };
        Ok(())
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
        self.setup.task.term_names()
    }

    fn options(&self) -> Option<Vec<bool>> {
        Some(self.setup.skills.iter().map(|s| s.uses_target).collect())
    }

    fn option_mask(&self, mask: &mut [bool]) {
        self.allowed_now(mask);
    }

    fn reset(&mut self, rng: &mut EnvRng, obs: &mut [f32]) {
        let zone = {
            let zones = self.setup.zones.read().expect("the zone list is never poisoned");
            zones[rng.random_range(0..zones.len())].clone()
        };
        // Hands open until a skill plays (each tick sets its own level), not the level the last
        // episode ended with.
        self.world.set_grip(0.0);
        self.start = self.world.reset_in_zone(&zone, rng).expect("zones come from the scenario");
        if let Some((lx, ly, turn)) = self.over.start {
            let f = self.world.placements()[self.setup.task.frame_prop()];
            let (s, c) = f.yaw.sin_cos();
            let (x, y) = (f.pos[0] + c * lx - s * ly, f.pos[1] + s * lx + c * ly);
            let yaw = wrap_angle((f.pos[1] - y).atan2(f.pos[0] - x) + turn);
            self.world.place_standing(x, y, yaw);
            self.start = (x, y, yaw);
        }
        self.zone = zone;
        self.current = None;
        self.phase = 0;
        self.decisions = 0;
        self.switches = 0;
        self.chosen.clear();
        self.touched = None;
        let hz = self.setup.control_hz();
        let moved = self.task.prepare(&self.setup.task, &mut self.world, rng, hz, self.start, &self.over);
        if moved {
            let f = self.world.pelvis_frame();
            self.start = (f.pos[0], f.pos[1], f.yaw());
            // Placed in the hold_from skill's end states: that skill has just played to its end.
            if let (Some(k), TaskSpec::Warehouse(w), TaskState::Warehouse(j)) =
                (self.setup.hold_skill, &self.setup.task, &self.task)
                && w.hold_pool.is_some()
                && matches!(j.start_phase, WarehousePhase::Carry | WarehousePhase::PutDown)
            {
                self.current = Some(k);
                self.phase = self.setup.skills[k].frames.saturating_sub(1);
                self.chosen.push(k);
            }
        }
        if let Some((k, pool)) = self.setup.start_pool.as_ref().filter(|_| !moved) {
            let state = &pool.states[rng.random_range(0..pool.states.len())];
            let (x, y, yaw) = self.start;
            state.apply(&mut self.world, x, y, yaw).expect("pool states are validated on load");
            self.current = Some(*k);
            self.phase = state.phase.min(self.setup.skills[*k].frames.saturating_sub(1));
            self.chosen.push(*k);
        }
        self.task.begin(&self.setup.task, &mut self.world, rng, &self.over);
        for c in 0..self.setup.skills.len() {
            self.bind_props(c);
        }
        if let Some(recorder) = self.record.as_mut() {
            recorder.restart();
        }
        self.record_frame();
        self.observe(obs);
    }

    fn step(&mut self, action: &[f32], obs: &mut [f32]) -> StepOutcome {
        self.begin_decision(action);
        while !self.decision_tick(None) {}
        self.end_decision(obs)
    }

    /// The world's state, then the episode's [`EPISODE_VALUES`] (the current skill, its phase,
    /// the walk's target, decisions, switches, the skill that first touched the chair), the
    /// task's state and the props bound to skills' roles.
    fn snapshot(&self) -> Vec<f64> {
        let mut out = Vec::new();
        self.world.snapshot(&mut out);
        out.extend_from_slice(&[
            self.current.map_or(-1.0, |c| c as f64),
            self.phase as f64,
            self.target[0],
            self.target[1],
            f64::from(self.decisions),
            f64::from(self.switches),
            self.touched.map_or(-1.0, |c| c as f64),
        ]);
        out.extend(self.task.snapshot());
        for (c, ids) in self.bound.iter().enumerate() {
            if self.setup.skills[c].props.has_roles() {
                out.extend(ids.iter().map(|&p| p as f64));
            }
        }
        out
    }

    fn restore(&mut self, state: &[f64]) -> std::result::Result<(), StateError> {
        let w = self.world.snapshot_len();
        let roles: usize = self.setup.skills.iter().filter(|s| s.props.has_roles()).map(|s| s.props.ids.len()).sum();
        let want = w + EPISODE_VALUES + self.task.snapshot_len() + roles;
        if state.len() != want {
            return Err(StateError::length("meta snapshot", want, state.len()));
        }
        let props = self.setup.model.props.len();
        let tail = w + EPISODE_VALUES + self.task.snapshot_len();
        if let Some(v) = state[tail..].iter().find(|v| !(v.is_finite() && **v >= 0.0 && (**v as usize) < props)) {
            return Err(StateError::OutOfRange {
                what: "the prop a meta snapshot binds a skill's role to".into(),
                value: *v,
                count: props,
                of: "props",
            });
        }
        let skills = self.setup.skills.len();
        for (i, what) in [(0, "current skill"), (6, "skill that first touched the chair")] {
            let v = state[w + i];
            if !(v == -1.0 || (v >= 0.0 && v.fract() == 0.0 && (v as usize) < skills)) {
                return Err(StateError::OutOfRange {
                    what: format!("meta snapshot's {what}"),
                    value: v,
                    count: skills,
                    of: "skills",
                });
            }
        }
        self.world.restore(&state[..w]).map_err(StateError::below)?;
        let s = &state[w..];
        self.current = (s[0] >= 0.0).then_some(s[0] as usize);
        self.phase = s[1] as usize;
        self.target = [s[2], s[3]];
        self.decisions = s[4] as u32;
        self.switches = s[5] as u32;
        self.touched = (s[6] >= 0.0).then_some(s[6] as usize);
        let t = self.task.snapshot_len();
        self.task.restore(&s[EPISODE_VALUES..EPISODE_VALUES + t]);
        let mut bound = s[EPISODE_VALUES + t..].iter();
        for (c, ids) in self.bound.iter_mut().enumerate() {
            if self.setup.skills[c].props.has_roles() {
                for (id, v) in ids.iter_mut().zip(bound.by_ref()) {
                    *id = *v as usize;
                }
            }
        }
        Ok(())
    }
}

/// How many values of a [`MetaEnv`] snapshot describe the episode, between the world's and the
/// task's.
const EPISODE_VALUES: usize = 7;

/// An error naming the first of `zones` that `model`'s scenario does not declare.
pub fn check_zones(model: &WorldModel, zones: &[String]) -> Result<()> {
    match zones.iter().find(|z| !model.scenario.scenario.spawn.iter().any(|s| &s.name == *z)) {
        Some(z) => Err(MetaError::Invalid(format!("no spawn zone `{z}` in {}", model.scenario.path.display()))),
        None => Ok(()),
    }
}

/// The episode figure `fell` (`terms[2]`): 0 without a fall, else the fall test's cause code
/// ([`repertoire_scenes::FallCause::code`], 1–4), or [`DIVERGED`] for a world whose state
/// stopped being finite. Read it as a flag with `> 0.5`.
pub fn fall_term(fell: bool, world: &World) -> f32 {
    match (fell, world.fall()) {
        (false, _) => 0.0,
        (true, Some(f)) => f32::from(f.cause.code()),
        (true, None) => DIVERGED,
    }
}

/// `fell`'s value for a world whose state stopped being finite (no fall the test could name).
pub const DIVERGED: f32 = 9.0;

/// The seed stream of trial `i` of the `zi`-th zone of an evaluation with `trials` per zone:
/// the same trial starts the same way in every tool that plays it.
pub(crate) fn trial_rng(seed: u64, zi: usize, trials: usize, i: usize) -> EnvRng {
    let mut rng = <EnvRng as rand::SeedableRng>::seed_from_u64(seed);
    rng.set_stream((zi * trials + i) as u64 + 1);
    rng
}

/// Which of `setup`'s skills are terminal: the graph leaves no way out of them but themselves
/// (sit), so once chosen they play to the episode's end.
pub fn terminal_skills(setup: &MetaSetup) -> Vec<bool> {
    let k = setup.skills.len();
    let mut mask = vec![false; k];
    (0..k)
        .map(|c| {
            setup.graph.allowed(Some(c), &mut mask);
            mask.iter().enumerate().all(|(j, &m)| !m || j == c)
        })
        .collect()
}

#[cfg(test)]
mod detour_tests {
    use super::detour_target;

    /// Closest distance from `c` to the segment `a`–`b`.
    fn clearance(a: [f64; 2], b: [f64; 2], c: [f64; 2]) -> f64 {
        let v = [b[0] - a[0], b[1] - a[1]];
        let w = [c[0] - a[0], c[1] - a[1]];
        let s = ((w[0] * v[0] + w[1] * v[1]) / (v[0] * v[0] + v[1] * v[1])).clamp(0.0, 1.0);
        (w[0] - s * v[0]).hypot(w[1] - s * v[1])
    }

    fn dist(a: [f64; 2], b: [f64; 2]) -> f64 {
        (a[0] - b[0]).hypot(a[1] - b[1])
    }

    #[test]
    fn a_way_through_the_prop_turns_onto_the_tangent_at_the_same_distance() {
        let (from, target, chair) = ([-2.0, 0.1], [2.0, 0.1], [0.0, 0.0]);
        let t = detour_target(from, target, [chair].into_iter(), 0.7);
        assert!((dist(from, t) - 4.0).abs() < 1e-9, "{t:?}");
        // The tangent grazes the circle: the new way clears it by the radius, no more.
        assert!((clearance(from, t, chair) - 0.7).abs() < 1e-9, "{t:?}");
        // The chair lay right of the way (y 0.1 > 0): it passes on the left, round the far side.
        assert!(t[1] > 0.1, "{t:?}");
        let mirrored = detour_target([-2.0, -0.1], [2.0, -0.1], [chair].into_iter(), 0.7);
        assert!(mirrored[1] < -0.1, "{mirrored:?}");
    }

    #[test]
    fn ways_that_clear_the_prop_or_stop_short_of_it_keep_their_target() {
        let chair = [0.0, 0.0];
        // Passes 1 m away.
        assert_eq!(detour_target([-2.0, 1.0], [2.0, 1.0], [chair].into_iter(), 0.7), [2.0, 1.0]);
        // Stops short of the chair.
        assert_eq!(detour_target([-3.0, 0.0], [-1.0, 0.0], [chair].into_iter(), 0.7), [-1.0, 0.0]);
        // Walks away from it.
        assert_eq!(detour_target([-1.0, 0.0], [-3.0, 0.0], [chair].into_iter(), 0.7), [-3.0, 0.0]);
        // Approaches the spot 0.4 m in front of the seat from the front: the target lies before
        // the way's closest point to the chair, inside the circle, and stands.
        assert_eq!(detour_target([2.0, 0.2], [0.4, 0.0], [chair].into_iter(), 0.7), [0.4, 0.0]);
        // No props, or a target at the walker's feet.
        assert_eq!(detour_target([-2.0, 0.0], [2.0, 0.0], std::iter::empty(), 0.7), [2.0, 0.0]);
        assert_eq!(detour_target([0.5, 0.5], [0.5, 0.5], [chair].into_iter(), 0.7), [0.5, 0.5]);
    }

    #[test]
    fn from_inside_the_circle_the_walker_is_sent_round_and_out() {
        let chair = [0.0, 0.0];
        // Beside the chair, heading past its far side to the spot in front.
        let from = [-0.3, 0.5];
        let t = detour_target(from, [0.4, -0.1], [chair].into_iter(), 0.7);
        let heading = [t[0] - from[0], t[1] - from[1]];
        let outward = [from[0] - chair[0], from[1] - chair[1]];
        // Square to the centre or outwards, never towards it.
        assert!(heading[0] * outward[0] + heading[1] * outward[1] > 0.0, "{t:?}");
        // And on round towards the front (x grows).
        assert!(heading[0] > 0.0, "{t:?}");
    }

    #[test]
    fn of_two_props_the_first_met_turns_the_way() {
        let near = [1.0, 0.05];
        let far = [3.0, -0.05];
        let t = detour_target([0.0, 0.0], [5.0, 0.0], [far, near].into_iter(), 0.5);
        assert!((clearance([0.0, 0.0], t, near) - 0.5).abs() < 1e-9, "{t:?}");
    }
}
