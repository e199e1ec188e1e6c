//! `repertoire skill train SPEC`, `skill finetune SPEC --from A,B`, `skill eval SPEC`,
//! `skill play SPEC --record OUT.rec`.

use std::path::{Path, PathBuf};

use anyhow::{Context, Result, bail};
use clap::{Args, Subcommand, ValueEnum};
use repertoire_skill::eval::{StartFrom, evaluate, pool_of};
use repertoire_skill::library;
use repertoire_skill::motion::{MotionQuality, reference_quality};
use repertoire_skill::spec::Init;
use repertoire_skill::train::{TrainOptions, TrainOutcome, default_run_dir, train};
use repertoire_skill::{SkillSetup, SpecFile};

/// Where trained skills go unless `--library` says otherwise (committed with the repository).
const DEFAULT_LIBRARY: &str = "library";

#[derive(Debug, Subcommand)]
pub enum SkillCommand {
    /// Train a skill from its spec (stage one: reference-state initialisation) into the library.
    Train {
        /// The skill spec (e.g. specs/walk.ron).
        spec: PathBuf,
        /// Start from the library's skill of this name instead of a fresh policy: the skill's
        /// next training stage (walk stage 2, `walk_stage2.ron`, from the stage-1 walk).
        /// Observation values the spec adds after the old ones (walk's target) enter with zero
        /// weight, so training starts from the old behaviour.
        #[arg(long)]
        warm_start: bool,
        /// Start from this other library skill instead (a new skill grown from one it
        /// extends: carry from walk). Its observation features must begin the spec's; the
        /// features the spec adds (carry's box) enter with zero weight.
        #[arg(long, conflicts_with = "warm_start")]
        warm_start_from: Option<String>,
        #[command(flatten)]
        common: TrainArgs,
    },
    /// Fine-tune a library skill from the end poses of the skills that precede it.
    Finetune {
        /// The skill spec.
        spec: PathBuf,
        /// Predecessor skills whose end-pose pools (from `skill eval`) start the episodes.
        #[arg(long, value_delimiter = ',', required = true)]
        from: Vec<String>,
        /// Share of episodes started from the pools (the rest use reference-state init).
        #[arg(long, default_value_t = 0.7)]
        fraction: f64,
        /// Scale the pool states' velocities by a factor drawn uniformly from LO,HI per
        /// episode (a curriculum towards the predecessors' momentum); default 1,1.
        #[arg(long, value_delimiter = ',', value_name = "LO,HI")]
        speed: Option<Vec<f64>>,
        #[command(flatten)]
        common: TrainArgs,
    },
    /// Play one episode of a library skill with its mean action and record it, with the
    /// reference clip as a ghost (for `repertoire replay` and `repertoire export`).
    Play {
        /// The skill spec (the library entry of the same name is played).
        spec: PathBuf,
        /// Where the recording goes.
        #[arg(long)]
        record: PathBuf,
        /// Also write the replay page here.
        #[arg(long)]
        html: Option<PathBuf>,
        /// Skill library folder.
        #[arg(long, default_value = DEFAULT_LIBRARY)]
        library: PathBuf,
        /// Seed of the episode.
        #[arg(long, default_value_t = 1)]
        seed: u64,
        /// Start from an end pose of one of these predecessors (their `skill eval` pools)
        /// instead of the clip start.
        #[arg(long, value_delimiter = ',')]
        from: Vec<String>,
        /// The folder holding node_modules/three (for --html).
        #[arg(long)]
        web: Option<PathBuf>,
    },
    /// Evaluate a library skill: success from the clip start and from predecessors' end poses,
    /// normalised episode length and return; writes its end-pose pool.
    Eval {
        /// The skill spec (the library entry of the same name is evaluated).
        spec: PathBuf,
        /// Skill library folder.
        #[arg(long, default_value = DEFAULT_LIBRARY)]
        library: PathBuf,
        /// Trials per start condition.
        #[arg(long, default_value_t = 1000)]
        trials: usize,
        /// Environments stepped together.
        #[arg(long, default_value_t = 32)]
        batch: usize,
        /// Seed of the trials.
        #[arg(long, default_value_t = 12345)]
        seed: u64,
        /// Also evaluate from these predecessors' end poses (default: the spec's Pools, if any).
        #[arg(long, value_delimiter = ',')]
        from: Vec<String>,
        /// Do not write the end-pose pool.
        #[arg(long)]
        no_pool: bool,
        /// Most end poses kept in the pool (an even spread over the successful trials).
        #[arg(long, default_value_t = 200)]
        pool_size: usize,
        /// Which trials' successful end states make the pool: those started at the clip
        /// (the paper's end poses), or those started from the predecessors' end poses (a
        /// skill whose clip start is trivial, like `stand`, whose point is where the chain
        /// before it leaves the character).
        #[arg(long, value_enum, default_value_t = PoolFrom::ClipStart)]
        pool_from: PoolFrom,
    },
}

/// The trials `skill eval` takes its end-pose pool from.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum PoolFrom {
    /// Trials started at the clip (reference-state initialisation).
    ClipStart,
    /// Trials started from the predecessors' end poses (`--from` or the spec's pools).
    Predecessors,
}

/// Options shared by `train` and `finetune` (and `meta refine`).
#[derive(Debug, Args)]
pub struct TrainArgs {
    /// Skill library folder.
    #[arg(long, default_value = DEFAULT_LIBRARY)]
    library: PathBuf,
    /// Run directory (default: runs/<skill>-<time>-s<seed>).
    #[arg(long)]
    run_dir: Option<PathBuf>,
    /// PPO iterations (default: the spec's).
    #[arg(long, value_parser = crate::cli::at_least_one)]
    iterations: Option<usize>,
    /// Parallel environments (default: the spec's).
    #[arg(long)]
    envs: Option<usize>,
    /// Starting from a library skill, raise its policy's log standard deviation to at least
    /// this (per action dimension), so a stage that must learn something new (walk stage 2's
    /// steering) explores more than the converged stage before it did.
    #[arg(long, allow_hyphen_values = true)]
    explore_log_std: Option<f32>,
    /// Starting from a library skill, lower its policy's log standard deviation to at most
    /// this (per action dimension): less exploration noise than it converged to.
    #[arg(long, allow_hyphen_values = true)]
    max_log_std: Option<f32>,
    /// Starting from the library's skill of the spec's own name (`finetune`, `--warm-start`),
    /// train a fresh value network instead of continuing the critic saved with its policy.
    #[arg(long)]
    fresh_critic: bool,
    /// Train only the value network for the first N iterations, the policy held as it starts
    /// (default: the spec's `ppo.critic_warmup`): a fine-tune with a fresh critic, or from
    /// starts the saved critic never saw, otherwise lets the critic's first errors push a
    /// converged policy off what it knew.
    #[arg(long)]
    critic_warmup: Option<usize>,
    /// Adam's learning rate, annealed to 0 over the iterations (default: the spec's).
    #[arg(long, value_parser = crate::cli::positive_f64)]
    learning_rate: Option<f64>,
    /// Seed (default: the spec's).
    #[arg(long)]
    seed: Option<u64>,
    /// Resume from a checkpoint stem (…/checkpoints/iter-000100); --iterations more than the run
    /// had extends it (the learning rate then anneals to the new total).
    #[arg(long)]
    resume: Option<PathBuf>,
    /// Write a checkpoint every N iterations.
    #[arg(long, default_value_t = 100)]
    checkpoint_every: usize,
    /// Step environments on one thread (same numbers, fixed thread use).
    #[arg(long)]
    serial: bool,
}

pub fn run(cmd: SkillCommand) -> Result<()> {
    let command = super::invocation();
    match cmd {
        SkillCommand::Train { spec, warm_start, warm_start_from, common } => {
            let prior = (warm_start || warm_start_from.is_some()).then_some(warm_start_from);
            train_cmd(&spec, None, prior, common, command)
        }
        SkillCommand::Finetune { spec, from, fraction, speed, common } => {
            let speed = match speed.as_deref() {
                None => (1.0, 1.0),
                Some(&[lo, hi]) => (lo, hi),
                Some(v) => bail!("--speed takes two numbers LO,HI, got {v:?}"),
            };
            train_cmd(&spec, Some((from, fraction, speed)), Some(None), common, command)
        }
        SkillCommand::Play { spec, record, html, library, seed, from, web } => {
            play_cmd(&spec, &record, html.as_deref(), &library, seed, from, web.as_deref())
        }
        SkillCommand::Eval { spec, library, trials, batch, seed, from, no_pool, pool_size, pool_from } => {
            eval_cmd(&spec, &library, trials, batch, seed, from, (!no_pool).then_some((pool_from, pool_size)))
        }
    }
}

/// Trains `spec_path`'s skill; `finetune`: predecessors, pool share and speed range; `prior`:
/// `None` a fresh policy, `Some(None)` the library's skill of the spec's name, `Some(Some(n))`
/// the library's skill `n` grown to the spec's observation.
fn train_cmd(
    spec_path: &Path,
    finetune: Option<(Vec<String>, f64, (f64, f64))>,
    prior: Option<Option<String>>,
    a: TrainArgs,
    command: String,
) -> Result<()> {
    let (setup, opts) = prepare(spec_path, finetune, prior, a, command)?;
    let out = train(&setup, &opts).with_context(|| format!("training {}", spec_path.display()))?;
    print_outcome(&setup, &out);
    Ok(())
}

/// The skill setup and training options of `train_cmd`'s arguments (see there).
pub fn prepare(
    spec_path: &Path,
    finetune: Option<(Vec<String>, f64, (f64, f64))>,
    prior: Option<Option<String>>,
    a: TrainArgs,
    command: String,
) -> Result<(SkillSetup, TrainOptions)> {
    if a.fresh_critic && prior.is_none() {
        bail!("--fresh-critic concerns a library skill's critic: use it with --warm-start or finetune");
    }
    if a.max_log_std.is_some() && prior.is_none() {
        bail!("--max-log-std lowers a library skill's spread: use it with --warm-start, --warm-start-from or finetune");
    }
    if a.explore_log_std.is_some() && prior.is_none() {
        bail!(
            "--explore-log-std raises a library skill's spread: use it with --warm-start, --warm-start-from or finetune"
        );
    }
    let mut spec = SpecFile::load(spec_path)?;
    let started = RunStart::of(&spec, spec_path, finetune.as_ref(), prior.as_ref(), &a)?;
    let mut a = a;
    let resumed_run = match &a.resume {
        Some(stem) => {
            let (run, was) = started.check_resume(stem, &a)?;
            // Flags left out take the run's.
            if let Some(was) = was {
                a.seed.get_or_insert(was.seed);
                a.envs.get_or_insert(was.envs);
                a.learning_rate.get_or_insert(was.learning_rate);
                a.critic_warmup.get_or_insert(was.critic_warmup);
                a.explore_log_std = a.explore_log_std.or(was.explore_log_std);
                a.max_log_std = a.max_log_std.or(was.max_log_std);
                a.fresh_critic |= was.fresh_critic;
            }
            Some(run)
        }
        None => None,
    };
    if let Some(lr) = a.learning_rate {
        spec.spec.ppo.learning_rate = lr;
    }
    if let Some(n) = a.critic_warmup {
        spec.spec.ppo.critic_warmup = n;
    }
    if let Some((from, fraction, speed)) = finetune {
        // Pools named by path are recorded relative to the working folder (manifests name no
        // folder of the machine).
        let from = from.iter().map(|f| repertoire_files::portable(f)).collect();
        spec.spec.init = Init::Pools { from, fraction, speed };
        spec.spec.init.check().map_err(|m| anyhow::anyhow!("skill finetune --from/--fraction/--speed: {m}"))?;
    }
    let setup = SkillSetup::new(spec, &a.library)?;
    let s = &setup.spec.spec;
    let seed = a.seed.unwrap_or(s.ppo.seed);
    // A resumed run goes on in the checkpoint's run directory.
    let run_dir = a.run_dir.or(resumed_run).unwrap_or_else(|| default_run_dir(Path::new("runs"), &s.name, seed));
    if a.resume.is_none() {
        started.write(&run_dir)?;
    }
    tracing::info!(
        skill = %s.name,
        clip = %setup.clip.origin,
        frames = setup.settings.reference.frames(),
        run_dir = %run_dir.display(),
        "training"
    );
    let opts = TrainOptions {
        library: a.library.clone(),
        run_dir,
        iterations: a.iterations,
        envs: a.envs,
        seed: a.seed,
        resume: a.resume,
        init_from_library: prior.is_some(),
        prior_skill: prior.flatten(),
        explore_log_std: a.explore_log_std,
        max_log_std: a.max_log_std,
        fresh_critic: a.fresh_critic,
        checkpoint_every: a.checkpoint_every,
        serial: a.serial,
        progress: true,
        command,
    };
    Ok((setup, opts))
}

/// What a skill training run was started with (`RUN/skill.ron`), so that `--resume` can refuse a
/// checkpoint of another skill or spec, or flags that differ from the run's.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
struct RunStart {
    skill: String,
    /// The spec file (portable path) and the FNV-1a hash of its text.
    spec: String,
    spec_fnv1a: u64,
    /// `train`, `train --warm-start`, `train --warm-start-from NAME` or `finetune`.
    start: String,
    /// A fine-tune's pools, share and speed range.
    pools: Option<(Vec<String>, f64, (f64, f64))>,
    seed: u64,
    envs: usize,
    learning_rate: f64,
    critic_warmup: usize,
    explore_log_std: Option<f32>,
    max_log_std: Option<f32>,
    fresh_critic: bool,
}

impl RunStart {
    fn of(
        spec: &SpecFile,
        path: &Path,
        finetune: Option<&(Vec<String>, f64, (f64, f64))>,
        prior: Option<&Option<String>>,
        a: &TrainArgs,
    ) -> Result<RunStart> {
        let text = std::fs::read(path).with_context(|| format!("reading {}", path.display()))?;
        let spec_fnv1a = text.iter().fold(0xcbf29ce484222325u64, |h, &b| (h ^ b as u64).wrapping_mul(0x100000001b3));
        let s = &spec.spec;
        let start = match (finetune, prior) {
            (Some(_), _) => "finetune".to_string(),
            (None, Some(Some(n))) => format!("train --warm-start-from {n}"),
            (None, Some(None)) => "train --warm-start".into(),
            (None, None) => "train".into(),
        };
        Ok(RunStart {
            skill: s.name.clone(),
            spec: repertoire_files::portable_path(path),
            spec_fnv1a,
            start,
            pools: finetune.map(|(f, x, v)| (f.iter().map(|p| repertoire_files::portable(p)).collect(), *x, *v)),
            seed: a.seed.unwrap_or(s.ppo.seed),
            envs: a.envs.unwrap_or(s.ppo.num_envs),
            learning_rate: a.learning_rate.unwrap_or(s.ppo.learning_rate),
            critic_warmup: a.critic_warmup.unwrap_or(s.ppo.critic_warmup),
            explore_log_std: a.explore_log_std,
            max_log_std: a.max_log_std,
            fresh_critic: a.fresh_critic,
        })
    }

    fn write(&self, run_dir: &Path) -> Result<()> {
        std::fs::create_dir_all(run_dir).with_context(|| format!("{}: cannot create", run_dir.display()))?;
        let text = ron::ser::to_string_pretty(self, ron::ser::PrettyConfig::default())?;
        repertoire_files::write_atomic(&run_dir.join("skill.ron"), text.as_bytes())?;
        Ok(())
    }

    /// The run directory of checkpoint `stem` and what the run started with, once that allows this
    /// command to resume it: the same skill, spec and start, and no flag set to another value
    /// than the run's (flags left out take the run's). A run from before runs recorded this
    /// (no `skill.ron`) is resumed unchecked, with a warning.
    fn check_resume(&self, stem: &Path, a: &TrainArgs) -> Result<(PathBuf, Option<RunStart>)> {
        let run = stem.parent().and_then(Path::parent).filter(|p| !p.as_os_str().is_empty()).unwrap_or(Path::new("."));
        if let Some(dir) = &a.run_dir
            && std::fs::canonicalize(dir).ok() != std::fs::canonicalize(run).ok()
        {
            bail!(
                "--resume {}: its run directory is {}, not --run-dir {} (leave --run-dir out to go on there)",
                stem.display(),
                run.display(),
                dir.display()
            );
        }
        let file = run.join("skill.ron");
        let Ok(text) = std::fs::read_to_string(&file) else {
            tracing::warn!(run = %run.display(), "the run has no skill.ron (made before runs recorded what they started with): resuming unchecked");
            return Ok((run.to_path_buf(), None));
        };
        let was: RunStart = ron::from_str(&text)
            .map_err(|e| anyhow::anyhow!("{}:{}: {}", file.display(), e.span.start.line, e.code))?;
        let refuse = |what: String| -> Result<(PathBuf, Option<RunStart>)> {
            bail!("--resume {}: {what} ({}); start a new run instead", stem.display(), file.display())
        };
        if was.skill != self.skill {
            return refuse(format!("the checkpoint trains `{}`, not `{}`", was.skill, self.skill));
        }
        if was.spec_fnv1a != self.spec_fnv1a {
            return refuse(format!(
                "it was started from another spec ({} as it was then), not {} as it is now",
                was.spec, self.spec
            ));
        }
        if was.start != self.start || was.pools != self.pools {
            return refuse(format!(
                "it was started as `{}`{}, not `{}`{}",
                was.start,
                was.pools.as_ref().map_or(String::new(), |p| format!(" from {}", p.0.join(","))),
                self.start,
                self.pools.as_ref().map_or(String::new(), |p| format!(" from {}", p.0.join(",")))
            ));
        }
        let mut clash = Vec::new();
        if a.seed.is_some_and(|s| s != was.seed) {
            clash.push(format!("--seed {} (the run's: {})", self.seed, was.seed));
        }
        if a.envs.is_some_and(|n| n != was.envs) {
            clash.push(format!("--envs {} (the run's: {})", self.envs, was.envs));
        }
        if a.learning_rate.is_some_and(|x| x != was.learning_rate) {
            clash.push(format!("--learning-rate {} (the run's: {})", self.learning_rate, was.learning_rate));
        }
        if a.critic_warmup.is_some_and(|n| n != was.critic_warmup) {
            clash.push(format!("--critic-warmup {} (the run's: {})", self.critic_warmup, was.critic_warmup));
        }
        if a.explore_log_std.is_some() && a.explore_log_std != was.explore_log_std {
            clash.push(format!("--explore-log-std {:?} (the run's: {:?})", a.explore_log_std, was.explore_log_std));
        }
        if a.max_log_std.is_some() && a.max_log_std != was.max_log_std {
            clash.push(format!("--max-log-std {:?} (the run's: {:?})", a.max_log_std, was.max_log_std));
        }
        if a.fresh_critic != was.fresh_critic && a.fresh_critic {
            clash.push("--fresh-critic (the run continued its critic)".into());
        }
        if !clash.is_empty() {
            return refuse(format!("{} differ from the run's; leave them out to resume", clash.join(", ")));
        }
        Ok((run.to_path_buf(), Some(was)))
    }
}

/// The table of a finished training run and where it went.
pub fn print_outcome(setup: &SkillSetup, out: &TrainOutcome) {
    let s = &setup.spec.spec;
    let f = &out.figures;
    println!("| skill | iterations | samples | minutes | mean return | mean length (steps) | falls |");
    println!("|---|---:|---:|---:|---:|---:|---:|");
    println!(
        "| {} | {} | {} | {:.1} | {:.2} | {:.1} | {:.0}% |",
        s.name,
        f.iterations,
        f.samples,
        f.seconds / 60.0,
        f.mean_return,
        f.mean_length,
        100.0 * f.termination_rate
    );
    println!("skill written to {}; run in {}", out.skill_dir.display(), out.run_dir.display());
}

#[allow(clippy::too_many_arguments)]
fn eval_cmd(
    spec_path: &Path,
    library: &Path,
    trials: usize,
    batch: usize,
    seed: u64,
    from: Vec<String>,
    pool: Option<(PoolFrom, usize)>,
) -> Result<()> {
    let mut spec = SpecFile::load(spec_path)?;
    let predecessors = if from.is_empty() {
        match &spec.spec.init {
            Init::Pools { from, .. } => from.clone(),
            _ => Vec::new(),
        }
    } else {
        from
    };
    let pool_from_predecessors = matches!(pool, Some((PoolFrom::Predecessors, _)));
    if !predecessors.is_empty() {
        spec.spec.init = Init::pools(predecessors.clone());
    } else if pool_from_predecessors {
        bail!(
            "{}: --pool-from predecessors needs predecessors (--from, or init Pools in the spec)",
            spec_path.display()
        );
    }
    let setup = SkillSetup::new(spec, library)?;
    let name = setup.spec.spec.name.clone();
    let mut skill = library::load(library, &name)?;
    let mut rows = Vec::new();
    let (report, mut ends) = evaluate(&setup, &mut skill, StartFrom::ClipStart, trials, batch, seed)?;
    rows.push(report);
    if !predecessors.is_empty() {
        match evaluate(&setup, &mut skill, StartFrom::Predecessors, trials, batch, seed + 1) {
            Ok((report, from_ends)) => {
                rows.push(report);
                if pool_from_predecessors {
                    ends = from_ends;
                }
            }
            Err(e) if pool_from_predecessors => return Err(e.into()),
            Err(e) => println!("not evaluated from predecessors' end poses: {e}"),
        }
    }
    print_eval_rows(&setup, &rows, &predecessors);
    if let Some((_, pool_size)) = pool {
        let step = ends.len().div_ceil(pool_size.max(1)).max(1);
        let kept: Vec<_> = ends.into_iter().step_by(step).collect();
        let pool = pool_of(&setup, kept);
        let path = library::skill_dir(library, &name).join("end_poses.ron");
        pool.save(&path)?;
        println!("{} successful end poses written to {}", pool.states.len(), path.display());
    }
    Ok(())
}

/// `skill eval`'s table, motion figures, and the per-start lines (targets reached, obstacle
/// touches).
fn print_eval_rows(setup: &SkillSetup, rows: &[repertoire_skill::eval::EvalReport], predecessors: &[String]) {
    println!("| skill | start | trials | success | falls | normalised length | normalised return |");
    println!("|---|---|---:|---:|---:|---:|---:|");
    for r in rows {
        let start = match r.start {
            StartFrom::ClipStart => "clip start".to_string(),
            StartFrom::Predecessors => format!("end poses of {}", predecessors.join(", ")),
        };
        println!(
            "| {} | {start} | {} | {:.1}% | {:.1}% | {:.3} | {:.3} |",
            r.skill,
            r.trials,
            100.0 * r.success_rate,
            100.0 * r.falls as f64 / r.trials.max(1) as f64,
            r.normalized_length,
            r.normalized_return
        );
    }
    print_motion(setup, rows, predecessors);
    for r in rows {
        let start = if r.start == StartFrom::ClipStart { "the clip start" } else { "the predecessors' end poses" };
        if let Some(targets) = r.targets_per_trial {
            println!(
                "{}: {targets:.2} targets reached per {:.0} s trial from {start}",
                r.skill, setup.spec.spec.episode_s
            );
        }
        if let (Some(touches), Some(o)) = (r.touches, setup.spec.spec.obstacle.as_ref()) {
            println!(
                "{}: {touches} of the {} falls from {start} were touches of `{}` (they end the episode)",
                r.skill, r.falls, o.prop
            );
        }
    }
}

fn play_cmd(
    spec_path: &Path,
    record: &Path,
    html: Option<&Path>,
    library: &Path,
    seed: u64,
    from: Vec<String>,
    web: Option<&Path>,
) -> Result<()> {
    let mut spec = SpecFile::load(spec_path)?;
    let start = if from.is_empty() { StartFrom::ClipStart } else { StartFrom::Predecessors };
    if !from.is_empty() {
        spec.spec.init = Init::pools(from);
    }
    let setup = SkillSetup::new(spec, library)?;
    let name = setup.spec.spec.name.clone();
    let mut skill = library::load(library, &name)?;
    let played = repertoire_skill::play::play(&setup, &mut skill, start, seed)?;
    played.recording.save(record)?;
    let size = std::fs::metadata(record).map(|m| m.len()).unwrap_or(0);
    println!(
        "{name}: {} steps ({:.2} s), {}{}{}, return {:.2}; recorded to {} ({:.2} MB)",
        played.steps,
        f64::from(played.steps) * setup.model.control_dt(),
        if played.fell { "fell or dropped its object" } else { "did not fall" },
        if played.on_seat { ", on the seat" } else { "" },
        if played.object_done { ", object goal reached" } else { "" },
        played.episode_return,
        record.display(),
        size as f64 / 1e6
    );
    if let Some(out) = html {
        let web = super::replay::web_dir(web);
        let size = super::replay::replay_file(record, out, &web)?;
        println!("replay page written to {} ({:.1} MB)", out.display(), size as f64 / 1e6);
    }
    Ok(())
}

/// The motion table: each evaluation's means beside the reference clip measured the same way.
fn print_motion(setup: &SkillSetup, rows: &[repertoire_skill::eval::EvalReport], predecessors: &[String]) {
    let reference = reference_quality(&setup.model, &setup.settings.reference);
    let looping = setup.settings.reference.looping;
    println!(
        "\nmotion, means over the trials; the reference clip played on the body without physics{}:\n",
        if looping { " (one cycle, so its turn is per cycle)" } else { "" }
    );
    println!(
        "| skill | rollouts | foot slip in stance (m/s) | swing clearance (cm) | torso tilt (°) | arm swing (cm) | \
         pelvis jerk (m/s³) | turn (°) | pose term | end-effector term |"
    );
    println!("|---|---|---:|---:|---:|---:|---:|---:|---:|---:|");
    let line = |what: &str, m: &MotionQuality| {
        let term = |t: Option<f64>| t.map_or("—".to_string(), |v| format!("{v:.3}"));
        println!(
            "| {} | {what} | {:.3} | {:.1} | {:.1} | {:.1} | {:.0} | {:.1} | {} | {} |",
            setup.spec.spec.name,
            m.foot_slip_m_s,
            100.0 * m.clearance_m,
            m.torso_tilt_deg,
            100.0 * m.arm_swing_m,
            m.jerk_m_s3,
            m.turn_deg,
            term(m.pose_term),
            term(m.end_effector_term)
        );
    };
    line("reference clip", &reference);
    for r in rows {
        if let Some(m) = &r.motion {
            let start = match r.start {
                StartFrom::ClipStart => "from the clip start".to_string(),
                StartFrom::Predecessors => format!("from end poses of {}", predecessors.join(", ")),
            };
            line(&start, m);
        }
    }
}
