//! Training the meta-controller: PPO with the hybrid head over [`MetaEnv`]s, the zone
//! curriculum advancing between iterations, a run directory, and the trained head saved with a
//! manifest of what it was trained on.

use std::io::Write as _;
use std::path::{Path, PathBuf};
use std::sync::{Arc, RwLock};
use std::time::Instant;

use repertoire_curriculum::{Advance, ZoneCurriculum};
use repertoire_learn::acting::ActingHybrid;
use repertoire_learn::checkpoint;
use repertoire_learn::env::{Env, EpisodeStats};
use repertoire_learn::ppo::{IterationMetrics, Ppo, PpoConfig};
use repertoire_learn::run_dir::{RunDir, git_hash};
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
    /// The command that trained it.
    pub command: String,
    /// Git commit.
    pub git_hash: Option<String>,
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
}

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
    let mut schedule = Schedule::start(&setup.model, &setup.zones, opts)?;
    let envs = (0..opts.ppo.num_envs).map(|_| MetaEnv::new(Arc::clone(&setup))).collect();
    let mut ppo = Ppo::new(opts.ppo.clone(), envs);
    let started = Instant::now();
    let history = run_iterations(&mut ppo, &mut schedule, opts, "skills")?;
    let run = TrainedRun {
        samples: ppo.global_step,
        seconds: started.elapsed().as_secs_f64(),
        curriculum: schedule.is_on(),
        advances: schedule.into_history(),
        command: &opts.command,
    };
    let manifest = save_controller(&setup, &ppo, &opts.out, run)?;
    Ok((manifest, history))
}

/// What a controller's manifest records of the run that made it.
pub(crate) struct TrainedRun<'a> {
    /// Decisions it learned from.
    pub samples: u64,
    /// Wall-clock seconds.
    pub seconds: f64,
    /// Whether the zone curriculum was on, and its switches.
    pub curriculum: bool,
    pub advances: Vec<Advance>,
    /// The command line.
    pub command: &'a str,
}

/// Writes `ppo`'s hybrid head (`meta.safetensors`) and its manifest (`meta.ron`, pinning the
/// setup's skills) into `out`.
pub(crate) fn save_controller<E: Env>(
    setup: &MetaSetup,
    ppo: &Ppo<E>,
    out: &Path,
    run: TrainedRun<'_>,
) -> Result<MetaManifest> {
    std::fs::create_dir_all(out).map_err(|e| MetaError::Invalid(format!("{}: {e}", out.display())))?;
    let head = ActingHybrid::from_ppo(ppo).expect("the meta environment has hybrid actions");
    head.save(&out.join("meta.safetensors")).map_err(|e| MetaError::Invalid(e.to_string()))?;
    let manifest = MetaManifest {
        scenario: setup.model.scenario.path.display().to_string(),
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
        command: run.command.to_string(),
        git_hash: git_hash(),
    };
    let text = ron::ser::to_string_pretty(&manifest, ron::ser::PrettyConfig::new().depth_limit(2))
        .map_err(|e| MetaError::Invalid(e.to_string()))?;
    repertoire_skill::library::write_atomic(&out.join("meta.ron"), text.as_bytes())?;
    Ok(manifest)
}

/// Runs `ppo` to its iteration count with the zone curriculum `schedule`, logging every
/// iteration to the run directory and saving the last checkpoint there; returns each
/// iteration's metrics. `low_level` names the controller in the logs (`skills`, `latent`).
pub(crate) fn run_iterations<E: Env>(
    ppo: &mut Ppo<E>,
    schedule: &mut Schedule,
    opts: &MetaTrainOptions,
    low_level: &str,
) -> Result<Vec<IterationMetrics>> {
    let io = |e| MetaError::Invalid(format!("{}: {e}", opts.run_dir.display()));
    let mut run = RunDir::create(&opts.run_dir, &ppo.cfg).map_err(io)?;
    let mut history = Vec::new();
    while ppo.iteration < ppo.cfg.num_iterations {
        let m = ppo.iterate();
        run.log(&m).map_err(io)?;
        schedule.after_iteration(m.iteration, &ppo.last_episodes)?;
        tracing::info!(
            low_level,
            iteration = m.iteration,
            mean_return = m.mean_return,
            success = m.terms.first().map_or(f32::NAN, |t| t.1),
            zone = schedule.zone(),
            "meta iteration"
        );
        history.push(m);
    }
    let last = run.checkpoint_stem(ppo.iteration);
    checkpoint::save(ppo, &last).map_err(|e| MetaError::Invalid(e.to_string()))?;
    Ok(history)
}

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
            let mut f = std::fs::File::create(&path).map_err(fail)?;
            writeln!(f, "iteration,episodes,zone,zone_index,success_window,advance_at").map_err(fail)?;
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
    let path = dir.join("meta.ron");
    let text = std::fs::read_to_string(&path).map_err(|e| MetaError::Invalid(format!("{}: {e}", path.display())))?;
    let manifest: MetaManifest = ron::from_str(&text)
        .map_err(|e| MetaError::Invalid(format!("{}:{}: {}", path.display(), e.span.start.line, e.code)))?;
    let names: Vec<String> = setup.skills.iter().map(|s| s.name.clone()).collect();
    if manifest.skills != names
        || manifest.body_hash != setup.model.body.content_hash()
        || manifest.obs_dim != setup.obs_dim()
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
    check_skill_weights(&path, &manifest, setup)?;
    let head = ActingHybrid::load(&dir.join("meta.safetensors")).map_err(|e| MetaError::Invalid(e.to_string()))?;
    Ok((manifest, head))
}

/// Refuses a controller whose manifest pins other skill weights than the library's.
fn check_skill_weights(path: &Path, manifest: &MetaManifest, setup: &MetaSetup) -> Result<()> {
    if manifest.skill_weights.is_empty() {
        tracing::warn!(
            manifest = %path.display(),
            "the controller records no skill weights (trained before skills were pinned): \
             cannot check that the library holds the skills it was trained over"
        );
        return Ok(());
    }
    if manifest.skill_weights.len() != setup.skills.len() {
        return Err(MetaError::Invalid(format!(
            "{}: records {} skill weights for {} skills",
            path.display(),
            manifest.skill_weights.len(),
            setup.skills.len()
        )));
    }
    for (skill, &trained) in setup.skills.iter().zip(&manifest.skill_weights) {
        if skill.policy_fnv1a != trained {
            return Err(MetaError::Invalid(format!(
                "{}: trained over skill `{}` with weights {trained:016x}, but the library's `{}` has \
                 weights {:016x} (it was retrained since): retrain the controller, or point \
                 --library at the library it was trained over",
                path.display(),
                skill.name,
                skill.name,
                skill.policy_fnv1a
            )));
        }
    }
    Ok(())
}
