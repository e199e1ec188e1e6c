//! `skill train` and `skill finetune`: PPO on a skill's environments, a run directory with
//! metrics and checkpoints, and a library entry at the end.

use std::path::{Path, PathBuf};
use std::time::Instant;

use indicatif::{ProgressBar, ProgressStyle};
use repertoire_learn::acting::{ActingCritic, ActingPolicy, ShapeError};
use repertoire_learn::checkpoint;
use repertoire_learn::env::Env;
use repertoire_learn::ppo::{IterationMetrics, Ppo};
use repertoire_learn::run_dir::{RunDir, git_hash};

use crate::error::{Result, SkillError};
use crate::library::{self, LIBRARY_FORMAT, LibrarySkill, SkillManifest, Stage, TrainingFigures};
use crate::skill::SkillSetup;

/// Options of one training run.
#[derive(Debug, Clone)]
pub struct TrainOptions {
    /// The skill library the result is written to (and pools / fine-tuning sources read from).
    pub library: PathBuf,
    /// The run directory (metrics, checkpoints).
    pub run_dir: PathBuf,
    /// Override of the spec's iteration count.
    pub iterations: Option<usize>,
    /// Override of the spec's number of environments.
    pub envs: Option<usize>,
    /// Override of the spec's seed.
    pub seed: Option<u64>,
    /// Continue from this checkpoint stem (`.../checkpoints/iter-000100`); with `iterations`,
    /// up to that many in all (more than the run had extends it).
    pub resume: Option<PathBuf>,
    /// Start from the library's policy of this skill (transition fine-tuning).
    pub init_from_library: bool,
    /// With `init_from_library`, start from this library skill instead of the spec's own
    /// name: a new skill grown from one it extends (carry from walk). Its observation features
    /// must begin the spec's; the values the spec adds enter with zero weight.
    pub prior_skill: Option<String>,
    /// With `init_from_library`, raise the prior policy's log standard deviation to at least
    /// this per action dimension (more exploration for a stage that learns something new).
    pub explore_log_std: Option<f32>,
    /// With `init_from_library`, lower the prior policy's log standard deviation to at most
    /// this per action dimension (less noise in what it meets: a skill refined in a
    /// controller's episodes, which evaluation plays by the mean).
    pub max_log_std: Option<f32>,
    /// With `init_from_library` and the same skill, start the value network afresh instead of
    /// from the critic saved with the policy.
    pub fresh_critic: bool,
    /// Write a checkpoint every this many iterations (0: only at the end).
    pub checkpoint_every: usize,
    /// Step environments sequentially (deterministic timing-independent mode; results are
    /// identical either way, this only pins the thread use).
    pub serial: bool,
    /// Show a progress bar.
    pub progress: bool,
    /// The command line, recorded in the manifest.
    pub command: String,
}

impl TrainOptions {
    /// A short, quiet run (tests and tools): `iterations` PPO iterations over `envs`
    /// environments with `seed`, into `library`, with its run directory at `run_dir`; no
    /// progress bar, one checkpoint at the end, the spec's own policy as the start.
    pub fn quick(library: &Path, run_dir: &Path, iterations: usize, envs: usize, seed: u64) -> Self {
        TrainOptions {
            library: library.to_path_buf(),
            run_dir: run_dir.to_path_buf(),
            iterations: Some(iterations),
            envs: Some(envs),
            seed: Some(seed),
            resume: None,
            init_from_library: false,
            prior_skill: None,
            explore_log_std: None,
            max_log_std: None,
            fresh_critic: false,
            checkpoint_every: 0,
            serial: false,
            progress: false,
            command: format!("quick run: {iterations} iterations, {envs} envs, seed {seed}"),
        }
    }
}

/// What a training run produced.
#[derive(Debug, Clone)]
pub struct TrainOutcome {
    /// The library folder of the skill.
    pub skill_dir: PathBuf,
    /// The run directory.
    pub run_dir: PathBuf,
    /// Figures recorded in the manifest.
    pub figures: TrainingFigures,
    /// Metrics of every iteration run here.
    pub history: Vec<IterationMetrics>,
}

/// The PPO state to train from and, for a fine-tune, the lineage the result inherits (the
/// prior's stages and the prior itself).
fn ppo_for<E: Env>(
    setup: &SkillSetup,
    opts: &TrainOptions,
    make: &dyn Fn(usize) -> Vec<E>,
) -> Result<(Ppo<E>, Vec<Stage>)> {
    let mut cfg = setup.spec.spec.ppo.clone();
    if let Some(n) = opts.envs {
        cfg.num_envs = n;
    }
    if let Some(s) = opts.seed {
        cfg.seed = s;
    }
    if opts.serial {
        cfg.parallel_envs = false;
    }
    cfg.num_iterations = opts.iterations.unwrap_or(setup.spec.spec.iterations).max(1);
    if cfg.critic_warmup >= cfg.num_iterations {
        return Err(SkillError::Invalid(format!(
            "{}: a critic warm-up of {} iterations (`ppo.critic_warmup`, --critic-warmup) leaves none of the {} \
             for the policy: lower the warm-up or raise the iterations",
            setup.spec.path.display(),
            cfg.critic_warmup,
            cfg.num_iterations
        )));
    }
    // A fine-tune inherits the lineage of the skill it starts from (also when it resumes from
    // one of its own checkpoints: the library still holds that skill until the fine-tune ends).
    let mut lineage = Vec::new();
    let prior = if opts.init_from_library {
        let name = opts.prior_skill.as_deref().unwrap_or(&setup.spec.spec.name);
        let prior = library::load(&opts.library, name)?;
        prior.check_fits(&setup.model)?;
        lineage = prior.manifest.lineage.clone();
        lineage.push(prior.manifest.stage());
        Some(prior)
    } else {
        None
    };
    if let Some(stem) = &opts.resume {
        let mut ppo = checkpoint::load(stem, make(cfg.num_envs))?;
        // More iterations than the run had extend it (the learning rate then anneals to the
        // new total), as `meta train --resume` does.
        if let Some(n) = opts.iterations {
            if ppo.iteration > n {
                return Err(SkillError::Invalid(format!(
                    "{}: already {} iterations in; ask for at least that many (--iterations)",
                    stem.display(),
                    ppo.iteration
                )));
            }
            ppo.cfg.num_iterations = n.max(1);
        }
        return Ok((ppo, lineage));
    }
    let n = cfg.num_envs;
    let mut ppo = Ppo::new(cfg, make(n));
    if let Some(prior) = prior {
        let mut policy = grown_prior(setup, &prior, ppo.obs_rms.dim())?;
        if let Some(floor) = opts.explore_log_std {
            policy.log_std.iter_mut().for_each(|l| *l = l.max(floor));
        }
        if let Some(ceiling) = opts.max_log_std {
            policy.log_std.iter_mut().for_each(|l| *l = l.min(ceiling));
        }
        policy.load_into(&mut ppo).map_err(|m| SkillError::Mismatch {
            path: prior.dir.join("policy.safetensors"),
            message: format!("cannot fine-tune `{}` from it: {m}", setup.spec.spec.name),
        })?;
        // The critic continues with the policy when the skill continues itself (a fine-tune or
        // its next stage); a new skill grown from another (carry from walk) earns other
        // rewards, and starts with a fresh one.
        let same_skill = prior.manifest.name == setup.spec.spec.name;
        let critic =
            if same_skill && !opts.fresh_critic { grown_critic(setup, &prior, ppo.obs_rms.dim())? } else { None };
        if let Some(critic) = critic {
            critic.load_into(&mut ppo).map_err(|m| critic_mismatch(setup, &prior, m))?;
            tracing::info!(skill = %setup.spec.spec.name, "continuing the critic saved with the policy");
        }
    }
    Ok((ppo, lineage))
}

/// How a prior's inputs grow to what a spec observes: `count` zero-weight inputs inserted
/// before input `at`, then `append` more after the last.
#[derive(Debug, Clone, Copy)]
struct Growth {
    at: usize,
    count: usize,
    append: usize,
}

/// The [`Growth`] from the library skill `prior` to `setup`'s spec (`wanted` values): a next
/// training stage may observe more task values after the last (walk's target after its stage
/// one), appended; a new skill grown from another may observe more features after the other's
/// (carry sees the box walk never saw), inserted after the other's features and before the task
/// values.
fn growth(setup: &SkillSetup, prior: &LibrarySkill, wanted: usize) -> Result<Growth> {
    let name = &setup.spec.spec.name;
    let path = prior.dir.join("policy.safetensors");
    let mismatch = |message: String| SkillError::Mismatch { path: path.clone(), message };
    let (old, new) = (&prior.manifest.observation, &setup.layout);
    if new.features.len() < old.features.len() || new.features[..old.features.len()] != old.features[..] {
        return Err(mismatch(format!(
            "cannot grow `{name}` from `{}`: its features {:?} do not begin `{name}`'s {:?}",
            prior.manifest.name, old.features, new.features
        )));
    }
    let have = prior.policy.obs_dim();
    let old_task = have.checked_sub(old.size).ok_or_else(|| mismatch("policy narrower than its layout".into()))?;
    let new_task = wanted.saturating_sub(new.size);
    if new_task < old_task || new.size < old.size {
        return Err(mismatch(format!(
            "cannot grow `{name}` ({wanted} inputs) from `{}` ({have}): it would lose inputs",
            prior.manifest.name
        )));
    }
    let count = new.size - old.size;
    Ok(Growth { at: old.size, count, append: wanted - have - count })
}

/// The library skill `prior`'s policy, grown to observe what `setup`'s spec observes
/// (`wanted` values, see [`Growth`]). What it adds enters with zero weights, so training starts
/// from the old behaviour.
pub fn grown_prior(setup: &SkillSetup, prior: &LibrarySkill, wanted: usize) -> Result<ActingPolicy> {
    let g = growth(setup, prior, wanted)?;
    if g.count + g.append == 0 {
        return Ok(prior.policy.clone());
    }
    let name = &setup.spec.spec.name;
    tracing::info!(skill = %name, from = %prior.manifest.name, inputs = prior.policy.obs_dim(), to = wanted, "growing the policy's input");
    let grow = |p: &ActingPolicy| -> std::result::Result<ActingPolicy, ShapeError> {
        p.with_inputs_at(g.at, g.count)?.widened(wanted)
    };
    grow(&prior.policy).map_err(|m| SkillError::Mismatch {
        path: prior.dir.join("policy.safetensors"),
        message: format!("cannot continue `{name}` from it: {m}"),
    })
}

/// The critic saved with `prior`, grown like its policy ([`grown_prior`]); `None` when the
/// skill was saved without one.
pub fn grown_critic(setup: &SkillSetup, prior: &LibrarySkill, wanted: usize) -> Result<Option<ActingCritic>> {
    let Some(critic) = prior.load_critic()? else { return Ok(None) };
    let g = growth(setup, prior, wanted)?;
    let grow = |c: &ActingCritic| -> std::result::Result<ActingCritic, ShapeError> {
        let c = c.with_inputs_at(g.at, g.count)?;
        c.with_inputs_at(c.obs_dim(), g.append)
    };
    grow(&critic).map(Some).map_err(|m| critic_mismatch(setup, prior, m))
}

/// A critic of `prior` that `setup`'s skill cannot continue, and why.
fn critic_mismatch(setup: &SkillSetup, prior: &LibrarySkill, why: ShapeError) -> SkillError {
    SkillError::Mismatch {
        path: prior.dir.join(library::VALUE_FILE),
        message: format!("cannot continue `{}`'s critic from it: {why}", setup.spec.spec.name),
    }
}

/// Trains (or fine-tunes) the skill of `setup` and writes it to the library.
pub fn train(setup: &SkillSetup, opts: &TrainOptions) -> Result<TrainOutcome> {
    train_in(setup, opts, &|n| setup.envs(n))
}

/// [`train`] in other environments than the skill's own, `make(n)` of them: the same skill
/// (its observations and actions, its library entry) trained where something else decides
/// when it plays (`repertoire meta refine`: in a meta-controller's episodes).
pub fn train_in<E: Env>(
    setup: &SkillSetup,
    opts: &TrainOptions,
    make: &dyn Fn(usize) -> Vec<E>,
) -> Result<TrainOutcome> {
    let (mut ppo, lineage) = ppo_for(setup, opts, make)?;
    let total = ppo.cfg.num_iterations;
    let start_iter = ppo.iteration;
    let run = match opts.resume {
        Some(_) => RunDir::resume(&opts.run_dir, &ppo.cfg, start_iter),
        None => RunDir::create(&opts.run_dir, &ppo.cfg),
    };
    let mut run = run.map_err(|e| SkillError::io(&opts.run_dir, "cannot create the run directory", e))?;
    let bar = if opts.progress {
        let bar = ProgressBar::new(total as u64);
        bar.set_style(
            ProgressStyle::with_template("{prefix} [{bar:30}] {pos}/{len} it, {elapsed} < {eta} | {msg}")
                .expect("a valid template")
                .progress_chars("=> "),
        );
        bar.set_prefix(format!("train {}", setup.spec.spec.name));
        bar.set_position(start_iter as u64);
        bar
    } else {
        ProgressBar::hidden()
    };
    let started = Instant::now();
    let mut history = Vec::new();
    let mut error = None;
    while ppo.iteration < total {
        let m = ppo.iterate();
        if let Err(e) = run.log(&m) {
            error = Some(SkillError::io(&opts.run_dir, "cannot append metrics", e));
            break;
        }
        tracing::debug!(
            skill = %setup.spec.spec.name,
            iteration = m.iteration,
            mean_return = m.mean_return,
            mean_length = m.mean_length,
            termination_rate = m.termination_rate,
            samples_per_sec = m.samples_per_sec,
            "iteration"
        );
        bar.set_message(format!(
            "return {:.1}, length {:.0}, falls {:.0}%, {:.0} samples/s",
            m.mean_return,
            m.mean_length,
            100.0 * m.termination_rate,
            m.samples_per_sec
        ));
        bar.inc(1);
        if opts.checkpoint_every > 0 && m.iteration % opts.checkpoint_every == 0 {
            checkpoint::save(&mut ppo, &run.checkpoint_stem(m.iteration))?;
        }
        history.push(m);
    }
    bar.finish_and_clear();
    if let Some(e) = error {
        return Err(e);
    }
    let last = run.checkpoint_stem(ppo.iteration);
    checkpoint::save(&mut ppo, &last)?;

    // Figures over the last tenth of the iterations that finished episodes.
    let tail: Vec<&IterationMetrics> =
        history.iter().rev().take((history.len() / 10).max(1)).filter(|m| m.episodes > 0).collect();
    let mean = |f: &dyn Fn(&IterationMetrics) -> f32| {
        if tail.is_empty() { f32::NAN } else { tail.iter().map(|m| f(m)).sum::<f32>() / tail.len() as f32 }
    };
    let figures = TrainingFigures {
        iterations: ppo.iteration,
        samples: ppo.global_step,
        seconds: started.elapsed().as_secs_f64(),
        mean_return: mean(&|m| m.mean_return),
        mean_length: mean(&|m| m.mean_length),
        termination_rate: mean(&|m| m.termination_rate),
    };
    let rates = &setup.model.scenario.scenario.rates;
    let mut manifest = SkillManifest {
        format: LIBRARY_FORMAT,
        name: setup.spec.spec.name.clone(),
        body_hash: setup.model.body.content_hash(),
        body_origin: repertoire_files::portable_path(&setup.model.body.mjcf_path),
        observation: (*setup.layout).clone(),
        extra_obs: ppo.envs.obs_dim() - setup.layout.size,
        act_dim: ppo.envs.act_dim(),
        control_hz: rates.control_hz,
        physics_hz: rates.physics_hz,
        mujoco: repertoire_scenes::mujoco_version(),
        clip: setup.clip_record(),
        spec: setup.spec.spec.clone(),
        training: figures.clone(),
        command: opts.command.clone(),
        git_hash: git_hash(),
        policy_fnv1a: 0,
        value_fnv1a: None,
        lineage,
    };
    let skill_dir =
        library::save(&opts.library, &mut manifest, &ActingPolicy::from_ppo(&ppo), &ActingCritic::from_ppo(&ppo))?;
    Ok(TrainOutcome { skill_dir, run_dir: run.path().to_path_buf(), figures, history })
}

/// A fresh run directory under `runs/`: `<skill>-<unix seconds>-s<seed>`.
pub fn default_run_dir(runs: &Path, skill: &str, seed: u64) -> PathBuf {
    let secs = std::time::SystemTime::now().duration_since(std::time::UNIX_EPOCH).map_or(0, |d| d.as_secs());
    runs.join(format!("{skill}-{secs}-s{seed}"))
}
