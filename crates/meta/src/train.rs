//! Training the meta-controller: PPO with the hybrid head over [`MetaEnv`]s, the zone
//! curriculum advancing between iterations, a run directory, and the trained head saved with a
//! manifest of what it was trained on.

use std::io::Write as _;
use std::path::{Path, PathBuf};
use std::sync::{Arc, RwLock};
use std::time::Instant;

use indicatif::{ProgressBar, ProgressStyle};
use repertoire_curriculum::{Advance, ZoneCurriculum};
use repertoire_learn::acting::{ActingCritic, ActingHybrid};
use repertoire_learn::checkpoint;
use repertoire_learn::env::{Env, EpisodeStats};
use repertoire_learn::ppo::{IterationMetrics, Ppo, PpoConfig};
use repertoire_learn::run_dir::{RunDir, drop_rows_after, git_hash};
use repertoire_scenes::WorldModel;
use serde::{Deserialize, Serialize};

use crate::env::{MetaEnv, MetaSetup};
use crate::error::{MetaError, Result};

/// What is recorded beside a trained meta-controller (`meta.ron`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct MetaManifest {
    /// The scenario it was trained on.
    pub scenario: String,
    /// Skills in option order.
    pub skills: Vec<String>,
    /// Each skill's policy checksum (`policy_fnv1a` of its library manifest), in option order:
    /// a controller is refused over a library whose skills were retrained since. Empty in
    /// manifests written before skills were pinned (loaded with a warning).
    #[serde(default)]
    pub skill_weights: Vec<u64>,
    /// Body content hash.
    pub body_hash: String,
    /// Observation width.
    pub obs_dim: usize,
    /// PPO settings.
    pub ppo: PpoConfig,
    /// Iterations and environment steps (decisions).
    pub iterations: usize,
    /// Decisions taken.
    pub samples: u64,
    /// Wall-clock seconds.
    pub seconds: f64,
    /// Whether the zone curriculum was on, and its switches.
    pub curriculum: bool,
    /// Zone switches.
    pub advances: Vec<Advance>,
    /// The command that trained it (that started the run, when it was resumed).
    pub command: String,
    /// Where the run was continued from its checkpoints (`meta train --resume`), oldest first.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub resumed: Vec<Resume>,
    /// The trained controller this run started from (`meta train --warm-start`), if any.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub warm_start: Option<WarmStart>,
    /// Git commit.
    pub git_hash: Option<String>,
}

impl MetaManifest {
    /// Iterations over the whole warm-start chain: this run's and those of every controller it
    /// started from, as far as the chain was recorded.
    pub fn total_iterations(&self) -> usize {
        let mut total = self.iterations;
        let mut link = self.warm_start.as_ref();
        while let Some(w) = link {
            total += w.iterations;
            link = w.before.as_deref();
        }
        total
    }

    /// "N iterations", or "N iterations, M in its last run" for a warm-started controller.
    pub fn iterations_label(&self) -> String {
        match self.total_iterations() {
            t if t == self.iterations => format!("{t} iterations"),
            t => format!("{t} iterations, {} in its last run", self.iterations),
        }
    }
}

/// The trained controller a run started from (`meta train --warm-start DIR`): its option and
/// continuous networks and observation statistics, and its critic when it saved one.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct WarmStart {
    /// The controller's folder.
    pub from: String,
    /// Its iterations and decisions (this run's `iterations` and `samples` count its own only).
    pub iterations: usize,
    pub samples: u64,
    /// Whether its critic came along (`meta.critic.safetensors`); without one the value network
    /// starts fresh and the first `critic_warmup` iterations train it alone.
    pub critic: bool,
    /// Skills of the library retrained since that controller was trained (their weights differ
    /// from those its manifest pins): the run goes on over the library's.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub retrained: Vec<String>,
    /// Skills that took another's place in the graph (`meta train --replace OLD=NEW`): the
    /// controller's option for OLD became this run's option for NEW.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub replaced: Vec<(String, String)>,
    /// The command that trained it.
    pub command: String,
    /// Where that controller itself started from, when it was warm-started too.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub before: Option<Box<WarmStart>>,
}

/// The critic a controller is saved with, beside `meta.safetensors`, so that a warm start
/// (`meta train --warm-start`) goes on with a value network that knows the task.
pub const CRITIC_FILE: &str = "meta.critic.safetensors";

/// A training run continued from one of its checkpoints.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Resume {
    /// Iterations done when it was continued.
    pub iteration: usize,
    /// The command that continued it.
    pub command: String,
}

/// Options of a meta-controller training run.
#[derive(Debug, Clone)]
pub struct MetaTrainOptions {
    /// Where the trained head and manifest go.
    pub out: PathBuf,
    /// The run directory.
    pub run_dir: PathBuf,
    /// PPO settings (their `num_envs`, `num_iterations` are used).
    pub ppo: PpoConfig,
    /// Use the scenario's zone curriculum (else all zones from the start).
    pub curriculum: bool,
    /// The command line.
    pub command: String,
    /// Continue the run whose checkpoint this is (a stem, `RUN/checkpoints/iter-000600`):
    /// learner, optimiser, environments and curriculum as they were, up to `ppo.num_iterations`
    /// in all (see [`resumed_ppo`]).
    pub resume: Option<PathBuf>,
    /// Write a checkpoint every this many iterations (0: only after the last).
    pub checkpoint_every: usize,
    /// Start from this trained controller's networks (a folder with `meta.ron`) instead of
    /// fresh ones: a new run (fresh optimiser, learning-rate schedule and curriculum) over the
    /// same skills. Not with `resume`.
    pub warm_start: Option<PathBuf>,
    /// With `warm_start`: skills of that controller replaced in this scenario, `(old, new)`:
    /// the option it learned for `old` (at the same place in the skill list) becomes `new`'s
    /// (a chair-aware walk in walk_to's place). Every other skill must match as usual.
    pub replace: Vec<(String, String)>,
}

/// Iterations between a training run's checkpoints unless asked otherwise.
pub const CHECKPOINT_EVERY: usize = 100;

/// PPO defaults for the meta-controller: decisions at 2 Hz are few and costly (30 control
/// ticks with a skill each), so rollouts are short and the discount is per decision.
pub fn default_ppo() -> PpoConfig {
    PpoConfig {
        num_envs: 16,
        num_steps: 32,
        num_iterations: 200,
        gamma: 0.95,
        num_minibatches: 4,
        update_epochs: 8,
        learning_rate: 3e-4,
        ..PpoConfig::default()
    }
}

/// Trains the meta-controller of `setup`; returns the manifest and each iteration's metrics.
pub fn train(setup: Arc<MetaSetup>, opts: &MetaTrainOptions) -> Result<(MetaManifest, Vec<IterationMetrics>)> {
    let envs: Vec<MetaEnv> = (0..opts.ppo.num_envs).map(|_| MetaEnv::new(Arc::clone(&setup))).collect();
    let mut session = match &opts.warm_start {
        Some(dir) => {
            if opts.resume.is_some() {
                return Err(MetaError::Invalid(
                    "a run either continues its checkpoint (--resume) or starts from a controller (--warm-start)"
                        .into(),
                ));
            }
            let mut ppo = Ppo::new(opts.ppo.clone(), envs);
            let from = warm_start(dir, &opts.replace, &setup, &mut ppo)?;
            let mut session = Session::fresh(ppo, &setup.model, &setup.zones, opts, setup.low_level())?;
            session.started_from(Some(from));
            session
        }
        None => Session::open(&setup.model, &setup.zones, envs, opts, setup.low_level())?,
    };
    let history = session.run(opts, "skills")?;
    let (ppo, run) = session.finish();
    let manifest = save_controller(&setup, &ppo, &opts.out, run)?;
    Ok((manifest, history))
}

/// Starts `ppo` from the controller in `dir` (refused, naming the file, when it was trained over
/// other skills, body or observations than `setup`'s; skills retrained since are named in the
/// record): its head and observation statistics, and its critic when it saved one. Returns what
/// the new controller's manifest records of it.
pub(crate) fn warm_start(
    dir: &Path,
    replace: &[(String, String)],
    setup: &MetaSetup,
    ppo: &mut Ppo<MetaEnv>,
) -> Result<WarmStart> {
    let (prior, head) = load_replacing(dir, replace, setup)?;
    let replaced_now = |name: &str| replace.iter().any(|(_, new)| new == name);
    let retrained: Vec<String> = if prior.skill_weights.len() == setup.skills.len() {
        let changed = setup
            .skills
            .iter()
            .zip(&prior.skill_weights)
            .filter(|(s, w)| s.policy_fnv1a != **w && !replaced_now(&s.name));
        changed.map(|(s, _)| s.name.clone()).collect()
    } else {
        Vec::new()
    };
    if !retrained.is_empty() {
        tracing::warn!(
            controller = %dir.display(),
            ?retrained,
            "the controller was trained over other weights of these skills: it goes on over the library's"
        );
    }
    let invalid =
        |path: &Path, e: repertoire_learn::acting::ShapeError| MetaError::Invalid(format!("{}: {e}", path.display()));
    head.load_into(ppo).map_err(|e| invalid(&dir.join("meta.safetensors"), e))?;
    let critic_path = dir.join(CRITIC_FILE);
    let critic = critic_path.exists();
    if critic {
        let c = ActingCritic::load(&critic_path).map_err(|e| MetaError::Invalid(e.to_string()))?;
        c.load_into(ppo).map_err(|e| invalid(&critic_path, e))?;
    } else if ppo.cfg.critic_warmup == 0 {
        tracing::warn!(
            controller = %dir.display(),
            "the controller saved no critic: its value network starts fresh with no warm-up \
             (--critic-warmup N trains it alone first)"
        );
    }
    tracing::info!(from = %dir.display(), iterations = prior.iterations, critic, "warm start");
    Ok(WarmStart {
        from: dir.display().to_string(),
        iterations: prior.iterations,
        samples: prior.samples,
        critic,
        retrained,
        replaced: replace.to_vec(),
        command: prior.command,
        before: prior.warm_start.map(Box::new),
    })
}

/// What a controller's manifest records of the run that made it.
pub(crate) struct TrainedRun {
    /// Decisions it learned from.
    pub samples: u64,
    /// Wall-clock seconds, over every session of a resumed run.
    pub seconds: f64,
    /// Whether the zone curriculum was on, and its switches.
    pub curriculum: bool,
    pub advances: Vec<Advance>,
    /// The command that started the run.
    pub command: String,
    /// The commands that continued it.
    pub resumed: Vec<Resume>,
    /// The controller it started from.
    pub warm_start: Option<WarmStart>,
}

/// Writes `ppo`'s hybrid head (`meta.safetensors`) and its manifest (`meta.ron`, pinning the
/// setup's skills) into `out`.
pub(crate) fn save_controller<E: Env>(
    setup: &MetaSetup,
    ppo: &Ppo<E>,
    out: &Path,
    run: TrainedRun,
) -> Result<MetaManifest> {
    std::fs::create_dir_all(out).map_err(|e| MetaError::Invalid(format!("{}: {e}", out.display())))?;
    let head = ActingHybrid::from_ppo(ppo).expect("the meta environment has hybrid actions");
    head.save(&out.join("meta.safetensors")).map_err(|e| MetaError::Invalid(e.to_string()))?;
    // The critic goes along only where PPO trained it or a warm start brought one; a stale
    // critic of an earlier controller in `out` is removed rather than paired with this head.
    let critic = out.join(CRITIC_FILE);
    if ppo.iteration > 0 || run.warm_start.as_ref().is_some_and(|w| w.critic) {
        ActingCritic::from_ppo(ppo).save(&critic).map_err(|e| MetaError::Invalid(e.to_string()))?;
    } else if critic.exists() {
        std::fs::remove_file(&critic).map_err(|e| MetaError::Invalid(format!("{}: {e}", critic.display())))?;
    }
    let manifest = MetaManifest {
        scenario: repertoire_files::portable_path(&setup.model.scenario.path),
        skills: setup.skills.iter().map(|s| s.name.clone()).collect(),
        skill_weights: setup.skills.iter().map(|s| s.policy_fnv1a).collect(),
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
        warm_start: run.warm_start,
        git_hash: git_hash(),
    };
    let text = ron::ser::to_string_pretty(&manifest, ron::ser::PrettyConfig::new().depth_limit(2))
        .map_err(|e| MetaError::Invalid(e.to_string()))?;
    repertoire_skill::library::write_atomic(&out.join("meta.ron"), text.as_bytes())?;
    Ok(manifest)
}

/// What a checkpoint of a controller's training run keeps beside the learner's own files
/// (`<stem>.run.ron`): what the controller drives, the curriculum, and the run's history.
#[derive(Debug, Clone, Serialize, Deserialize)]
struct RunState {
    /// The low level, one entry per skill (`name weights`) or the latent model: a checkpoint
    /// continues only over the low level it was trained over.
    low_level: Vec<String>,
    /// The zone curriculum as it stood (`None`: every zone open).
    curriculum: Option<ZoneCurriculum>,
    /// Wall-clock seconds trained so far.
    seconds: f64,
    /// The command that started the run.
    command: String,
    /// The commands that continued it.
    resumed: Vec<Resume>,
    /// The controller the run started from.
    #[serde(default)]
    warm_start: Option<WarmStart>,
}

/// `<stem>.run.ron`, beside the checkpoint's [`checkpoint::manifest_path`].
fn state_path(stem: &Path) -> PathBuf {
    stem.with_extension("run.ron")
}

/// The run directory a checkpoint stem lies in (`RUN` of `RUN/checkpoints/iter-000600`).
pub fn run_of_checkpoint(stem: &Path) -> Option<PathBuf> {
    let dir = stem.parent()?;
    (dir.file_name()? == "checkpoints").then(|| dir.parent().map(Path::to_path_buf)).flatten()
}

/// The PPO settings of a run that continues the checkpoint `stem`: the checkpoint's own, with
/// the total iterations (`iterations`; learning-rate annealing then runs to the new total from
/// where it stands) and entropy bonus (`ent_coef`) the command line asks for. A seed or an
/// environment count other than the checkpoint's is refused by [`train`], naming both.
pub fn resumed_ppo(
    stem: &Path,
    iterations: Option<usize>,
    envs: Option<usize>,
    seed: Option<u64>,
    ent_coef: Option<f32>,
) -> Result<PpoConfig> {
    let saved = checkpoint::read_manifest(&checkpoint::manifest_path(stem))
        .map_err(|e| MetaError::Invalid(e.to_string()))?
        .config;
    Ok(PpoConfig {
        num_iterations: iterations.unwrap_or(saved.num_iterations),
        num_envs: envs.unwrap_or(saved.num_envs),
        seed: seed.unwrap_or(saved.seed),
        ent_coef: ent_coef.unwrap_or(saved.ent_coef),
        ..saved
    })
}

/// A training run in this process: the learner, the zone curriculum and the run's history, fresh
/// or continued from a checkpoint; [`Session::run`] trains to the learner's iteration count,
/// logging every iteration and writing checkpoints, and [`Session::finish`] hands over the
/// learner and what its manifest records. Shared by the skills' and the latent high level's
/// trainers and by distillation.
pub(crate) struct Session<'z, E: Env> {
    ppo: Ppo<E>,
    schedule: Schedule<'z>,
    /// `seconds`: trained before this process.
    state: RunState,
    started: Instant,
}

impl<'z, E: Env> Session<'z, E> {
    /// Records the trained controller this run started from (its manifest's `warm_start`).
    pub(crate) fn started_from(&mut self, from: Option<WarmStart>) {
        self.state.warm_start = from;
    }

    /// `opts.ppo` over `envs` from scratch, or the checkpoint `opts.resume` continued: refused
    /// when it was trained over another low level than `low_level`, with(out) the curriculum
    /// when `opts` asks otherwise, under another curriculum schedule, with other PPO settings
    /// than `opts.ppo` (but for the iteration total and the entropy bonus), or past
    /// `opts.ppo.num_iterations` already.
    pub(crate) fn open(
        model: &WorldModel,
        zones: &'z RwLock<Vec<String>>,
        envs: Vec<E>,
        opts: &MetaTrainOptions,
        low_level: Vec<String>,
    ) -> Result<Self> {
        let Some(stem) = &opts.resume else {
            return Self::fresh(Ppo::new(opts.ppo.clone(), envs), model, zones, opts, low_level);
        };
        let path = state_path(stem);
        let invalid = |m: String| MetaError::Invalid(format!("{}: {m}", path.display()));
        let text = std::fs::read_to_string(&path).map_err(|e| {
            invalid(format!("{e} (a checkpoint of `meta train` has one beside `{}.ron`)", stem.display()))
        })?;
        let mut state: RunState =
            ron::from_str(&text).map_err(|e| invalid(format!("line {}: {}", e.span.start.line, e.code)))?;
        if state.low_level != low_level {
            return Err(invalid(format!(
                "trained over {:?}; this setup has {:?} (a checkpoint continues only over the low level it \
                 was trained over)",
                state.low_level, low_level
            )));
        }
        let spec = model.scenario.scenario.curriculum.as_ref();
        let wanted = opts.curriculum && spec.is_some();
        match (&state.curriculum, spec) {
            (saved, _) if saved.is_some() != wanted => {
                return Err(invalid(format!(
                    "trained {} the zone curriculum; continue it {}",
                    if saved.is_some() { "with" } else { "without" },
                    if saved.is_some() { "without --no-curriculum" } else { "with --no-curriculum" }
                )));
            }
            (Some(c), Some(spec)) => {
                if let Some(d) = c.differs_from(spec) {
                    return Err(invalid(format!("the scenario's curriculum changed since: {d}")));
                }
            }
            _ => {}
        }
        let mut ppo = checkpoint::load(stem, envs).map_err(|e| MetaError::Invalid(e.to_string()))?;
        let mut wanted_cfg = opts.ppo.clone();
        (wanted_cfg.num_iterations, wanted_cfg.ent_coef) = (ppo.cfg.num_iterations, ppo.cfg.ent_coef);
        if let Some((saved, now)) = first_difference(&ppo.cfg, &wanted_cfg) {
            return Err(invalid(format!("trained with `{saved}`, asked for `{now}`")));
        }
        if ppo.iteration > opts.ppo.num_iterations {
            return Err(invalid(format!(
                "already {} iterations in; ask for at least that many (--iterations)",
                ppo.iteration
            )));
        }
        (ppo.cfg.num_iterations, ppo.cfg.ent_coef) = (opts.ppo.num_iterations, opts.ppo.ent_coef);
        let schedule = Schedule::resume(zones, state.curriculum.take(), opts, ppo.iteration)?;
        state.resumed.push(Resume { iteration: ppo.iteration, command: opts.command.clone() });
        tracing::info!(checkpoint = %stem.display(), iteration = ppo.iteration, to = opts.ppo.num_iterations, "resuming");
        Ok(Session { ppo, schedule, state, started: Instant::now() })
    }

    /// A fresh run of `ppo` (built by the caller, e.g. fitted to demonstrations first).
    pub(crate) fn fresh(
        ppo: Ppo<E>,
        model: &WorldModel,
        zones: &'z RwLock<Vec<String>>,
        opts: &MetaTrainOptions,
        low_level: Vec<String>,
    ) -> Result<Self> {
        let schedule = Schedule::start(model, zones, opts)?;
        let state = RunState {
            low_level,
            curriculum: None,
            seconds: 0.0,
            command: opts.command.clone(),
            resumed: Vec::new(),
            warm_start: None,
        };
        Ok(Session { ppo, schedule, state, started: Instant::now() })
    }

    /// Trains to the learner's iteration count with the zone curriculum, logging every
    /// iteration to the run directory (`opts.run_dir`), showing progress, and writing a
    /// checkpoint every `opts.checkpoint_every` iterations and after the last; returns each
    /// iteration's metrics. `low_level` names the controller in the logs (`skills`, `latent`).
    pub(crate) fn run(&mut self, opts: &MetaTrainOptions, low_level: &str) -> Result<Vec<IterationMetrics>> {
        let io = |e| MetaError::Invalid(format!("{}: {e}", opts.run_dir.display()));
        let mut run = match opts.resume {
            Some(_) => RunDir::resume(&opts.run_dir, &self.ppo.cfg, self.ppo.iteration),
            None => RunDir::create(&opts.run_dir, &self.ppo.cfg),
        }
        .map_err(io)?;
        let total = self.ppo.cfg.num_iterations;
        let bar = ProgressBar::new(total as u64).with_position(self.ppo.iteration as u64);
        bar.set_style(
            ProgressStyle::with_template("{prefix} [{bar:30}] {pos}/{len} it, {elapsed} < {eta} | {msg}")
                .expect("a valid template")
                .progress_chars("=> "),
        );
        bar.set_prefix(format!("meta train ({low_level})"));
        let mut history = Vec::new();
        while self.ppo.iteration < total {
            let m = self.ppo.iterate();
            run.log(&m).map_err(io)?;
            self.schedule.after_iteration(m.iteration, &self.ppo.last_episodes)?;
            let success = m.terms.first().map_or(f32::NAN, |t| t.1);
            bar.suspend(|| {
                tracing::info!(
                    low_level,
                    iteration = m.iteration,
                    mean_return = m.mean_return,
                    success,
                    zone = self.schedule.zone(),
                    "meta iteration"
                )
            });
            bar.set_message(format!(
                "return {:.2}, success {:.1}%, zone {}",
                m.mean_return,
                100.0 * success,
                self.schedule.zone()
            ));
            bar.inc(1);
            if opts.checkpoint_every > 0 && m.iteration.is_multiple_of(opts.checkpoint_every) && m.iteration < total {
                self.checkpoint(&run)?;
            }
            history.push(m);
        }
        bar.finish_and_clear();
        self.checkpoint(&run)?;
        Ok(history)
    }

    /// Saves the learner at its iteration in `run`'s checkpoints, with the [`RunState`].
    fn checkpoint(&mut self, run: &RunDir) -> Result<()> {
        let stem = run.checkpoint_stem(self.ppo.iteration);
        checkpoint::save(&mut self.ppo, &stem).map_err(|e| MetaError::Invalid(e.to_string()))?;
        let state = RunState {
            curriculum: self.schedule.curriculum.clone(),
            seconds: self.state.seconds + self.started.elapsed().as_secs_f64(),
            ..self.state.clone()
        };
        let text = ron::ser::to_string_pretty(&state, ron::ser::PrettyConfig::new().depth_limit(2))
            .map_err(|e| MetaError::Invalid(e.to_string()))?;
        repertoire_skill::library::write_atomic(&state_path(&stem), text.as_bytes())?;
        Ok(())
    }

    /// The trained learner and what its controller's manifest records of the run.
    pub(crate) fn finish(self) -> (Ppo<E>, TrainedRun) {
        let run = TrainedRun {
            samples: self.ppo.global_step,
            seconds: self.state.seconds + self.started.elapsed().as_secs_f64(),
            // A run that took no decision (`--iterations 0`, the re-pin) ran no curriculum.
            curriculum: self.schedule.is_on() && self.ppo.global_step > 0,
            advances: self.schedule.into_history(),
            command: self.state.command,
            resumed: self.state.resumed,
            warm_start: self.state.warm_start,
        };
        (self.ppo, run)
    }
}

/// The first line in which two PPO settings differ, as RON (`None`: equal).
fn first_difference(saved: &PpoConfig, now: &PpoConfig) -> Option<(String, String)> {
    let ron = |c: &PpoConfig| ron::ser::to_string_pretty(c, ron::ser::PrettyConfig::default()).unwrap_or_default();
    let (a, b) = (ron(saved), ron(now));
    let trim = |l: &str| l.trim().trim_end_matches(',').to_string();
    a.lines().zip(b.lines()).find(|(x, y)| x != y).map(|(x, y)| (trim(x), trim(y)))
}

/// The columns of a run's `curriculum.csv`.
const CURRICULUM_HEADER: &str = "iteration,episodes,zone,zone_index,success_window,advance_at";

/// The zone curriculum during a training run, shared by the skills' and the latent high level's
/// trainers: it opens zones in `zones` (read by every environment at reset), records each
/// finished episode's success (term 0) and writes one row per iteration to the run's
/// `curriculum.csv` for `repertoire report`. Without a curriculum every call does nothing.
pub(crate) struct Schedule<'a> {
    curriculum: Option<ZoneCurriculum>,
    zones: &'a RwLock<Vec<String>>,
    file: Option<(std::fs::File, PathBuf)>,
}

impl<'a> Schedule<'a> {
    /// Starts the scenario's curriculum of `model` when `opts.curriculum` asks for it.
    pub(crate) fn start(model: &WorldModel, zones: &'a RwLock<Vec<String>>, opts: &MetaTrainOptions) -> Result<Self> {
        let curriculum = match (&model.scenario.scenario.curriculum, opts.curriculum) {
            (Some(c), true) => Some(ZoneCurriculum::new(c, true)),
            _ => None,
        };
        let mut file = None;
        if let Some(c) = &curriculum {
            *zones.write().expect("never poisoned") = c.open_zones().to_vec();
            let path = opts.run_dir.join("curriculum.csv");
            let fail = |e: std::io::Error| MetaError::Invalid(format!("{}: {e}", path.display()));
            std::fs::create_dir_all(&opts.run_dir).map_err(fail)?;
            // The header lands whole (temporary file renamed into place); rows are appended.
            repertoire_files::write_atomic(&path, format!("{CURRICULUM_HEADER}\n").as_bytes())
                .map_err(|e| fail(e.source))?;
            let f = std::fs::OpenOptions::new().append(true).open(&path).map_err(fail)?;
            file = Some((f, path));
        }
        Ok(Schedule { curriculum, zones, file })
    }

    /// Continues `curriculum` (a checkpoint's, `None`: every zone open) at `iteration`: opens
    /// its zones and appends to the run's `curriculum.csv`, less any rows logged after
    /// `iteration`.
    pub(crate) fn resume(
        zones: &'a RwLock<Vec<String>>,
        curriculum: Option<ZoneCurriculum>,
        opts: &MetaTrainOptions,
        iteration: usize,
    ) -> Result<Self> {
        let mut file = None;
        if let Some(c) = &curriculum {
            *zones.write().expect("never poisoned") = c.open_zones().to_vec();
            let path = opts.run_dir.join("curriculum.csv");
            let fail = |e: std::io::Error| MetaError::Invalid(format!("{}: {e}", path.display()));
            std::fs::create_dir_all(&opts.run_dir).map_err(fail)?;
            drop_rows_after(&path, iteration).map_err(fail)?;
            let mut f = std::fs::OpenOptions::new().create(true).append(true).open(&path).map_err(fail)?;
            if f.metadata().map_err(fail)?.len() == 0 {
                writeln!(f, "{CURRICULUM_HEADER}").map_err(fail)?;
            }
            file = Some((f, path));
        }
        Ok(Schedule { curriculum, zones, file })
    }

    /// Records the episodes an iteration finished and logs the iteration's row.
    pub(crate) fn after_iteration(&mut self, iteration: usize, episodes: &[EpisodeStats]) -> Result<()> {
        let Some(c) = &mut self.curriculum else { return Ok(()) };
        for e in episodes {
            if let Some(a) = c.record(e.terms[0] > 0.5) {
                tracing::info!(from = %a.from, to = %a.to, episode = a.episode, rate = a.success_rate, reason = a.reason.as_str(), "curriculum advances");
                *self.zones.write().expect("never poisoned") = c.open_zones().to_vec();
            }
        }
        if let Some((f, path)) = &mut self.file {
            let rate = c.window_rate().map_or_else(String::new, |r| format!("{r:.4}"));
            writeln!(f, "{iteration},{},{},{},{rate},{}", c.episodes(), c.current(), c.current_index(), c.advance_at())
                .map_err(|e| MetaError::Invalid(format!("{}: {e}", path.display())))?;
        }
        Ok(())
    }

    /// The current zone, or `all` without a curriculum.
    pub(crate) fn zone(&self) -> &str {
        self.curriculum.as_ref().map_or("all", |c| c.current())
    }

    /// Whether a curriculum runs.
    pub(crate) fn is_on(&self) -> bool {
        self.curriculum.is_some()
    }

    /// Its zone switches.
    pub(crate) fn into_history(self) -> Vec<Advance> {
        self.curriculum.map(|c| c.history).unwrap_or_default()
    }
}

/// Loads a trained meta-controller and checks it fits `setup`.
pub fn load(dir: &Path, setup: &MetaSetup) -> Result<(MetaManifest, ActingHybrid)> {
    let (manifest, head) = load_unpinned(dir, setup)?;
    check_skill_weights(
        &dir.join("meta.ron"),
        &manifest.skill_weights,
        setup,
        "retrain the controller, or point --library at the library it was trained over",
    )?;
    Ok((manifest, head))
}

/// [`load`] without checking the skills' weights: the skills, body and observations must
/// match, but a skill may have been retrained since (a warm start goes on over it).
fn load_unpinned(dir: &Path, setup: &MetaSetup) -> Result<(MetaManifest, ActingHybrid)> {
    load_replacing(dir, &[], setup)
}

/// [`load_unpinned`], reading the controller's skill list with each `(old, new)` of `replace`
/// as `new`; a pair naming no skill of the controller is refused (a typo would otherwise be
/// reported as a skill-list mismatch far from its cause).
fn load_replacing(dir: &Path, replace: &[(String, String)], setup: &MetaSetup) -> Result<(MetaManifest, ActingHybrid)> {
    let path = dir.join("meta.ron");
    let text = std::fs::read_to_string(&path).map_err(|e| MetaError::Invalid(format!("{}: {e}", path.display())))?;
    let manifest: MetaManifest = ron::from_str(&text)
        .map_err(|e| MetaError::Invalid(format!("{}:{}: {}", path.display(), e.span.start.line, e.code)))?;
    let names: Vec<String> = setup.skills.iter().map(|s| s.name.clone()).collect();
    let mut trained = manifest.skills.clone();
    for (old, new) in replace {
        let Some(slot) = trained.iter_mut().find(|s| *s == old) else {
            return Err(MetaError::Invalid(format!(
                "{}: --replace {old}={new}: the controller has no skill `{old}` (its skills: {:?})",
                path.display(),
                manifest.skills
            )));
        };
        *slot = new.clone();
    }
    if trained != names || manifest.body_hash != setup.model.body.content_hash() || manifest.obs_dim != setup.obs_dim()
    {
        return Err(MetaError::Invalid(format!(
            "{}: trained for skills {:?} on body {} with {} observations; this scenario has {:?}, body {}, {}",
            path.display(),
            manifest.skills,
            manifest.body_hash,
            manifest.obs_dim,
            names,
            setup.model.body.content_hash(),
            setup.obs_dim()
        )));
    }
    let head = ActingHybrid::load(&dir.join("meta.safetensors")).map_err(|e| MetaError::Invalid(e.to_string()))?;
    Ok((manifest, head))
}

/// Refuses a file (`path`: a controller's or readiness' manifest) that pins other skill
/// weights (`pinned`, in option order) than the library's, saying `remedy`. An empty list
/// (written before skills were pinned) loads with a warning.
pub(crate) fn check_skill_weights(path: &Path, pinned: &[u64], setup: &MetaSetup, remedy: &str) -> Result<()> {
    if pinned.is_empty() {
        tracing::warn!(
            manifest = %path.display(),
            "the manifest records no skill weights (written before skills were pinned): \
             cannot check that the library holds the skills it was made over"
        );
        return Ok(());
    }
    if pinned.len() != setup.skills.len() {
        return Err(MetaError::Invalid(format!(
            "{}: records {} skill weights for {} skills",
            path.display(),
            pinned.len(),
            setup.skills.len()
        )));
    }
    for (skill, &trained) in setup.skills.iter().zip(pinned) {
        if skill.policy_fnv1a != trained {
            return Err(MetaError::Invalid(format!(
                "{}: made over skill `{}` with weights {trained:016x}, but the library's `{}` has \
                 weights {:016x} (it was retrained since): {remedy}",
                path.display(),
                skill.name,
                skill.name,
                skill.policy_fnv1a
            )));
        }
    }
    Ok(())
}
