//! `repertoire meta train [FILE]` and `repertoire meta eval [FILE]`: the meta-controller of a
//! scenario (sitting, the warehouse, the toss) over the skill library.

use std::path::{Path, PathBuf};
use std::sync::Arc;

use anyhow::{Context, Result, bail};
use clap::Subcommand;
use repertoire_learn::classify::ClassifierConfig;
use repertoire_learn::env::Env as _;
use repertoire_learn::ppo::IterationMetrics;
use repertoire_meta::evaluation::{EvalPlan, Pick, Worst};
use repertoire_meta::handover::deliver::{DeliveryWindow, deliver};
use repertoire_meta::handover::distill::{DistillOptions, Teacher, distill};
use repertoire_meta::handover::readiness::{ReadinessOptions, learn};
use repertoire_meta::handover::refine::RefineSetup;
use repertoire_meta::latent::{self, LatentSetup};
use repertoire_meta::search::lookahead::LookaheadConfig;
use repertoire_meta::search::planner::PlannerConfig;
use repertoire_meta::train::{CHECKPOINT_EVERY, MetaTrainOptions, default_ppo, load, train};
use repertoire_meta::{Advance, MetaSetup, SkillGraph, TaskSpec};
use repertoire_scenes::WorldModel;

use super::controller::{GraphArgs, ScenarioArgs};

pub mod eval;

/// The committed skill library and meta-controller.
pub const DEFAULT_LIBRARY: &str = "library";

/// The meta-controller folder of a scenario when none is given, inside the skill library it
/// runs over: `LIBRARY/meta` for sitting (the committed `library/meta`),
/// `LIBRARY/meta-<scenario name>` for other tasks (so they never overwrite it). A controller
/// trained over a copy of the library stays with that copy.
pub fn default_meta(library: &Path, task: &repertoire_scenes::scenario::Task, name: &str) -> PathBuf {
    match task {
        repertoire_scenes::scenario::Task::Sit { .. } => library.join("meta"),
        _ => library.join(format!("meta-{name}")),
    }
}

/// [`default_meta`] of a loaded setup.
pub(crate) fn setup_meta(library: &Path, setup: &MetaSetup) -> PathBuf {
    let s = &setup.model.scenario.scenario;
    default_meta(library, &s.task, &s.name)
}

/// The search-based planner's settings (`meta eval --planner`, `meta distill`, `meta deliver
/// --planner`).
#[derive(Debug, Clone, clap::Args)]
pub struct PlannerArgs {
    /// Planner: most decisions one plan is simulated for.
    #[arg(long, default_value_t = PlannerConfig::default().horizon)]
    horizon: u32,
    /// Planner: most extra decisions an option is held before a terminal skill (sit) is tried
    /// after it.
    #[arg(long, default_value_t = PlannerConfig::default().repeats)]
    repeats: u32,
}

impl PlannerArgs {
    /// The planner these settings ask for; a horizon of 0 is refused.
    pub(crate) fn config(&self) -> Result<PlannerConfig> {
        if self.horizon == 0 {
            bail!("--horizon must be at least 1 decision");
        }
        Ok(PlannerConfig { horizon: self.horizon, repeats: self.repeats })
    }
}

/// `meta train`'s options for the run itself, for either low level: PPO settings, where the
/// run goes, and whether it continues a checkpoint.
#[derive(Debug, clap::Args)]
pub struct RunArgs {
    /// Run directory (default: runs/meta-<time>-s<seed>; resuming: the checkpoint's run).
    #[arg(long)]
    run_dir: Option<PathBuf>,
    /// PPO iterations in all [default: 200; resuming: the checkpoint's total]. Resuming with
    /// more extends the run: learning-rate annealing then runs to the new total. 0 only with
    /// --warm-start: the controller copied as it is, pinned to the library's skills (a re-pin
    /// after a skill was retrained).
    #[arg(long)]
    iterations: Option<usize>,
    /// Parallel environments [default: 16; resuming: the checkpoint's].
    #[arg(long)]
    envs: Option<usize>,
    /// Seed [default: 1; resuming: the checkpoint's].
    #[arg(long)]
    seed: Option<u64>,
    /// Entropy bonus of the PPO loss (skill choice and targets together; default 0 over the
    /// skills, the latent low level's own otherwise, the checkpoint's when resuming).
    /// Without one the controller settles on one sequence as soon as it finds one that pays.
    #[arg(long, value_parser = crate::cli::non_negative)]
    ent_coef: Option<f32>,
    /// Continue a run from its checkpoint (a stem: RUN/checkpoints/iter-000600): learner,
    /// optimiser, environments and curriculum as they were; refused over other skills, another
    /// curriculum or other PPO settings.
    #[arg(long)]
    resume: Option<PathBuf>,
    /// Write a checkpoint every N iterations into the run directory (0: only after the last).
    #[arg(long, default_value_t = CHECKPOINT_EVERY)]
    checkpoint_every: usize,
    /// Open every zone from the start (the "no curriculum" ablation).
    #[arg(long)]
    no_curriculum: bool,
    /// Start from a trained controller (a folder with meta.ron, e.g. library/meta)
    /// instead of fresh networks: a new run over the same skills, with a fresh optimiser,
    /// learning-rate schedule and curriculum (add --no-curriculum to keep every zone open).
    /// Its critic comes along when it saved one (meta.critic.safetensors).
    #[arg(long, conflicts_with = "resume")]
    warm_start: Option<PathBuf>,
    /// With --warm-start: OLD=NEW, the scenario has skill NEW where the controller had OLD
    /// (same place in the skill list); the option it learned for OLD becomes NEW's (e.g.
    /// walk_to=walk_around). Repeat for more.
    #[arg(long, requires = "warm_start", value_parser = parse_replace)]
    replace: Vec<(String, String)>,
    /// Adam's learning rate (annealed to 0 over the run) [default: 3e-4].
    #[arg(long, conflicts_with = "resume", value_parser = crate::cli::positive_f64)]
    learning_rate: Option<f64>,
    /// Train the value network alone for the first N iterations [default: 0; 100 when
    /// --warm-start's controller saved no critic].
    #[arg(long, conflicts_with = "resume")]
    critic_warmup: Option<usize>,
}

#[derive(Debug, Subcommand)]
pub enum MetaCommand {
    /// Train the meta-controller (hybrid PPO at the meta rate, zone curriculum).
    Train(TrainArgs),
    /// Distil a search into a meta-controller (sitting scenarios): the search-based planner
    /// (`meta eval --planner`), or with --lookahead K a trained controller's own lookahead
    /// (`meta eval --lookahead K`, over --warm-start), plays seeded episodes from each zone and
    /// a hybrid policy is fitted to its decisions by behaviour cloning: a fresh one for the
    /// planner, the --warm-start controller for its lookahead (expert iteration). The result is
    /// an ordinary controller that acts from its observation alone: evaluate it with
    /// `meta eval --meta OUT`.
    Distill(DistillArgs),
    /// Learn when the terminal skill (sit) will succeed (sitting scenarios): the controller plays
    /// seeded episodes without sitting, and every decision where it could have sat is labelled
    /// with whether the sit would have succeeded (played out in a copy of the episode); a
    /// classifier of the meta observation is fitted to the labels. Writes
    /// OUT/readiness.{ron,safetensors}; `meta eval --readiness OUT` gates the controller's sit
    /// by it.
    Readiness(ReadinessArgs),
    /// Record where a controller delivers the character to a skill (sitting scenarios): at
    /// every decision the skill is not running, the state with the seat's pose, kept when the
    /// seat lies within --max-offset / --max-turn of where the skill's clip expects it. The
    /// result is a pool: fine-tune the skill from it with `repertoire skill finetune SPEC
    /// --from OUT.ron`, so it starts where the controller hands over, chair and all. A skill
    /// without a seat goal (the stand before the sit) has no window: every decision before it
    /// is kept, with the seat's pose, which its spec's `delivered_seat` puts the chair at.
    Deliver(DeliverArgs),
    /// Fine-tune one skill inside a trained controller's episodes (sitting and the other
    /// tasks): the frozen controller decides as in evaluation, the other skills play frozen,
    /// and the skill learns wherever the controller chooses it, from the states and towards the
    /// targets it meets there, on its own reward (its spec's imitation and goal) plus
    /// --task-weight times the task's; a fall, its own or a later skill's, ends the episode.
    /// Starts from the library's skill and its critic and writes it back into --library
    /// (`skill train`'s options). The controller then needs re-pinning to the new weights:
    /// `meta train --library LIB --warm-start CTRL --iterations 0 --out NEW`.
    Refine(RefineArgs),
    /// Compare two sitting evaluations of the same trials (the same scenario, seed and trial
    /// count) trial by trial: per zone both success rates, the trials seated only by each,
    /// the difference in points and McNemar's test on those (z and the exact p-value).
    Compare(CompareArgs),
    Eval(eval::EvalArgs),
}

/// `meta train`'s arguments.
#[derive(Debug, clap::Args)]
pub struct TrainArgs {
    #[command(flatten)]
    pub scenario: ScenarioArgs,
    /// Where the trained controller goes (default: LIBRARY/meta for sitting,
    /// LIBRARY/meta-<scenario name> otherwise; LIBRARY is --library).
    #[arg(long)]
    pub out: Option<PathBuf>,
    #[command(flatten)]
    pub run: RunArgs,
    #[command(flatten)]
    pub graph: GraphArgs,
    /// Drive this latent model's decoder instead of the skills (overrides the scenario's
    /// `low_level`; e.g. library/latent).
    #[arg(long)]
    pub latent: Option<PathBuf>,
    /// Latent low level: control ticks each z is held.
    #[arg(long, default_value_t = 1)]
    pub hold: usize,
}

/// `meta distill`'s arguments.
#[derive(Debug, clap::Args)]
pub struct DistillArgs {
    #[command(flatten)]
    pub scenario: ScenarioArgs,
    /// Where the controller goes (default: runs/meta-distill-<scenario>).
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// Teacher episodes per zone.
    #[arg(long, default_value_t = 200)]
    pub episodes: usize,
    /// Zones (default: all of the scenario's).
    #[arg(long, value_delimiter = ',')]
    pub zones: Vec<String>,
    #[command(flatten)]
    pub plan: PlannerArgs,
    /// The teacher is the --warm-start controller's lookahead with K candidates a search
    /// (as `meta eval --lookahead K`) instead of the planner.
    #[arg(long, value_parser = clap::value_parser!(u32).range(1..), requires = "warm_start")]
    pub lookahead: Option<u32>,
    /// Most searches per episode with --lookahead.
    #[arg(long, default_value_t = LookaheadConfig::default().searches, requires = "lookahead")]
    pub lookahead_searches: u32,
    /// Start the fit from this trained controller (head, observation statistics, critic)
    /// instead of a fresh policy; required by --lookahead, whose controller it is.
    #[arg(long)]
    pub warm_start: Option<PathBuf>,
    /// Learning rate of the fit (and of the PPO iterations after it).
    #[arg(long)]
    pub learning_rate: Option<f64>,
    /// With --lookahead: times each decision the lookahead changed (took another than the
    /// controller's own) counts in the fit; the others count once.
    #[arg(long, default_value_t = 1, value_parser = clap::value_parser!(u32).range(1..), requires = "lookahead")]
    pub changed_weight: u32,
    /// Fit only the decisions of the teacher's successful episodes.
    #[arg(long)]
    pub successful_only: bool,
    /// Passes over the demonstrations.
    #[arg(long, default_value_t = 100)]
    pub epochs: usize,
    /// Rows per gradient step.
    #[arg(long, default_value_t = 256)]
    pub batch: usize,
    /// Seed of the planner's episodes and of the fit.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Then this many PPO iterations from the fitted policy (as `meta train`, with the
    /// zone curriculum unless --no-curriculum); 0: the fit alone.
    #[arg(long, default_value_t = 0)]
    pub iterations: usize,
    /// Run directory of those iterations (default: runs/meta-distill-<time>-s<seed>).
    #[arg(long)]
    pub run_dir: Option<PathBuf>,
    /// Open every zone from the start in those iterations.
    #[arg(long)]
    pub no_curriculum: bool,
}

/// `meta readiness`'s arguments.
#[derive(Debug, clap::Args)]
pub struct ReadinessArgs {
    #[command(flatten)]
    pub scenario: ScenarioArgs,
    /// The controller that plays the episodes (default: as `meta train` writes it).
    #[arg(long)]
    pub meta: Option<PathBuf>,
    /// Where it goes (default: <meta>/readiness).
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// Episodes per zone.
    #[arg(long, default_value_t = 1000)]
    pub trials: usize,
    /// Zones (default: all of the scenario's).
    #[arg(long, value_delimiter = ',')]
    pub zones: Vec<String>,
    /// Seed of the episodes (apart from evaluation's 2024, so evaluation meets new starts).
    #[arg(long, default_value_t = 11)]
    pub seed: u64,
    /// Every Nth episode is held out of the fit and measures it (0: none).
    #[arg(long, default_value_t = 5)]
    pub holdout: usize,
    /// Passes over the labelled decisions.
    #[arg(long, default_value_t = ClassifierConfig::default().epochs)]
    pub epochs: usize,
    /// Hidden widths of the classifier.
    #[arg(long, value_delimiter = ',', default_values_t = ClassifierConfig::default().hidden)]
    pub hidden: Vec<usize>,
    /// The probability at or above which the gated controller sits (recorded; `meta eval
    /// --ready-at` overrides it).
    #[arg(long, default_value_t = 0.5, value_parser = probability)]
    pub ready_at: f32,
    #[command(flatten)]
    pub plan: PlannerArgs,
}

/// `meta deliver`'s arguments.
#[derive(Debug, clap::Args)]
pub struct DeliverArgs {
    #[command(flatten)]
    pub scenario: ScenarioArgs,
    /// The skill's spec (for a sit, its clip says where the seat is expected).
    #[arg(long, default_value = "specs/sit.ron")]
    pub spec: PathBuf,
    /// The controller (default: as `meta train` writes it).
    #[arg(long)]
    pub meta: Option<PathBuf>,
    /// Use the search-based planner (`meta eval --planner`) as the controller instead.
    #[arg(long)]
    pub planner: bool,
    #[command(flatten)]
    pub plan: PlannerArgs,
    /// Episodes per zone.
    #[arg(long, default_value_t = 200)]
    pub trials: usize,
    /// Zones (default: all of the scenario's).
    #[arg(long, value_delimiter = ',')]
    pub zones: Vec<String>,
    /// Seed (a different one from evaluation's default keeps the pool apart from the
    /// evaluated trials).
    #[arg(long, default_value_t = 7)]
    pub seed: u64,
    /// Farthest the seat may stand from where the skill expects it (m).
    #[arg(long, default_value_t = 0.5)]
    pub max_offset: f64,
    /// Largest turn of the seat away from where the skill expects it (degrees).
    #[arg(long, default_value_t = 45.0)]
    pub max_turn: f64,
    /// Most states kept (an even spread).
    #[arg(long, default_value_t = 1000)]
    pub max_states: usize,
    /// The pool file (default: runs/delivered-<skill>.ron).
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// Also write the states at which the controller did switch to the skill, in or out of
    /// the window, as a pool (default: <out> with `-handovers` before `.ron`).
    #[arg(long)]
    pub handovers_out: Option<PathBuf>,
}

/// `meta refine`'s arguments.
#[derive(Debug, clap::Args)]
pub struct RefineArgs {
    /// Scenario RON file (default: the built-in scenarios/sit.ron).
    pub file: Option<PathBuf>,
    /// The skill's spec (its reward, actions and training settings).
    #[arg(long)]
    pub spec: PathBuf,
    /// The controller (default: as `meta train` writes it, in --library).
    #[arg(long)]
    pub meta: Option<PathBuf>,
    /// Weight of the task's decision rewards (approach, seated time) in the learner's.
    #[arg(long, default_value_t = 1.0, allow_hyphen_values = true)]
    pub task_weight: f32,
    /// Weight of the skill's own reward (its spec's imitation and goal) in the learner's.
    #[arg(long, default_value_t = 1.0, allow_hyphen_values = true, value_parser = crate::cli::non_negative)]
    pub skill_weight: f32,
    #[command(flatten)]
    pub common: super::skill::TrainArgs,
}

/// `meta compare`'s arguments.
#[derive(Debug, clap::Args)]
pub struct CompareArgs {
    /// Evaluation A: a `meta eval` folder, or its trials.csv.
    pub a: PathBuf,
    /// Evaluation B, the same trials.
    pub b: PathBuf,
    /// Also write the table here (Markdown).
    #[arg(long)]
    pub out: Option<PathBuf>,
}

/// The scene and skills of `file` with its graph, or a fixed-order `chain`, or its graph
/// restricted to `skills`.
pub fn setup(file: Option<&PathBuf>, library: &Path, chain: &[String], skills: &[String]) -> Result<Arc<MetaSetup>> {
    let model = Arc::new(WorldModel::build(super::load_scenario(file)?)?);
    let graph = if !chain.is_empty() {
        SkillGraph::chain(&chain.iter().map(String::as_str).collect::<Vec<_>>())
    } else if !skills.is_empty() {
        SkillGraph::of(&model.scenario.scenario)
            .restricted(skills)
            .map_err(|e| anyhow::anyhow!("{}: --skills: {e}", model.scenario.path.display()))?
    } else {
        SkillGraph::of(&model.scenario.scenario)
    };
    Ok(Arc::new(MetaSetup::new(model, library, graph)?))
}

pub fn run(cmd: MetaCommand) -> Result<()> {
    let command = super::invocation();
    match cmd {
        MetaCommand::Compare(args) => compare_cmd(args),
        MetaCommand::Train(args) => train_cmd(args, command),
        MetaCommand::Distill(args) => distill_cmd(args, command),
        MetaCommand::Readiness(args) => readiness_cmd(args, command),
        MetaCommand::Deliver(args) => deliver_cmd(args),
        MetaCommand::Refine(args) => refine_cmd(args, command),
        MetaCommand::Eval(args) => eval::eval(args),
    }
}

/// `meta compare`.
fn compare_cmd(CompareArgs { a, b, out }: CompareArgs) -> Result<()> {
    use repertoire_meta::compare::{compare, read_trials, trials_file};
    let names = [trials_file(&a).display().to_string(), trials_file(&b).display().to_string()];
    let table = compare(names, &read_trials(&a)?, &read_trials(&b)?)?.markdown();
    print!("{table}");
    if let Some(out) = out {
        repertoire_report::write_atomic(&out, table.as_bytes())?;
        println!("\nwritten to {}", out.display());
    }
    Ok(())
}

/// `meta train`.
fn train_cmd(
    TrainArgs { scenario: ScenarioArgs { file, library }, out, run, graph: GraphArgs { chain, skills }, latent, hold }: TrainArgs,
    command: String,
) -> Result<()> {
    if run.iterations == Some(0) && run.warm_start.is_none() {
        bail!(
            "--iterations: must be at least 1 (0 only with --warm-start, which copies that \
             controller pinned to the library's skills)"
        );
    }
    let run = TrainRun { args: run, command };
    if let Some((model, dir)) = latent_low_level(file.as_ref(), latent)? {
        no_skill_options(&chain, &skills)?;
        return train_latent(model, &dir, &library, out, hold, run);
    }
    let setup = setup(file.as_ref(), &library, &chain, &skills)?;
    let out = out.unwrap_or_else(|| setup_meta(&library, &setup));
    let opts = run.options(default_ppo(), out.clone(), "meta")?;
    let run_dir = opts.run_dir.clone();
    let (manifest, history) = train(setup, &opts).context("training the meta-controller")?;
    if let (0, Some(w)) = (manifest.iterations, &manifest.warm_start) {
        let retrained = if w.retrained.is_empty() { "none".to_string() } else { w.retrained.join(", ") };
        println!(
            "the controller of {} copied as it is ({}), pinned to the library's skills \
             (retrained since: {retrained})",
            w.from,
            manifest.iterations_label()
        );
    } else {
        print_training(
            "decisions",
            manifest.iterations,
            manifest.samples,
            manifest.seconds,
            &history,
            &manifest.advances,
        );
    }
    println!("meta-controller written to {}; run in {}", out.display(), run_dir.display());
    Ok(())
}

/// `meta distill`.
fn distill_cmd(
    DistillArgs {
        scenario: ScenarioArgs { file, library },
        out,
        episodes,
        zones,
        plan,
        lookahead,
        lookahead_searches,
        warm_start,
        learning_rate,
        changed_weight,
        successful_only,
        epochs,
        batch,
        seed,
        iterations,
        run_dir,
        no_curriculum,
    }: DistillArgs,
    command: String,
) -> Result<()> {
    let setup = setup(file.as_ref(), &library, &[], &[])?;
    sitting_only(&setup, "the planner and the lookahead, and so `meta distill`, handle")?;
    let teacher = match lookahead {
        Some(k) => Teacher::Lookahead(LookaheadConfig {
            candidates: k as usize,
            searches: lookahead_searches,
            seed,
            ..LookaheadConfig::default()
        }),
        None => Teacher::Planner(plan.config()?),
    };
    if let Some(lr) = learning_rate
        && !(lr > 0.0 && lr.is_finite())
    {
        bail!("--learning-rate {lr}: must be a positive number");
    }
    if episodes == 0 || epochs == 0 {
        bail!("--episodes and --epochs must each be at least 1");
    }
    let out = out
        .unwrap_or_else(|| PathBuf::from("runs").join(format!("meta-distill-{}", setup.model.scenario.scenario.name)));
    let zones = zones_or_all(zones, &setup.model.scenario.scenario);
    let opts = DistillOptions {
        out: out.clone(),
        episodes,
        zones,
        teacher,
        warm_start,
        successful_only,
        changed_weight: changed_weight as usize,
        epochs,
        batch,
        ppo: {
            let ppo = default_ppo();
            repertoire_learn::ppo::PpoConfig { seed, learning_rate: learning_rate.unwrap_or(ppo.learning_rate), ..ppo }
        },
        seed,
        then_train: (iterations > 0)
            .then(|| distill_training(iterations, seed, learning_rate, no_curriculum, run_dir, &out, &command))
            .transpose()?,
        command,
    };
    let trained = opts.then_train.is_some();
    let (_, f) = distill(setup, &opts)?;
    print_distilled(&f, &out, trained);
    Ok(())
}

/// The PPO run `meta distill --iterations N` trains the distilled controller on with.
fn distill_training(
    iterations: usize,
    seed: u64,
    learning_rate: Option<f64>,
    no_curriculum: bool,
    run_dir: Option<PathBuf>,
    out: &Path,
    command: &str,
) -> Result<MetaTrainOptions> {
    let args = RunArgs {
        run_dir,
        iterations: Some(iterations),
        envs: None,
        seed: Some(seed),
        ent_coef: None,
        resume: None,
        checkpoint_every: CHECKPOINT_EVERY,
        no_curriculum,
        warm_start: None,
        replace: Vec::new(),
        learning_rate,
        critic_warmup: None,
    };
    let run = TrainRun { args, command: command.to_string() };
    run.options(default_ppo(), out.to_path_buf(), "meta-distill")
}

/// What `meta distill` ends with: the teacher's figures and the fit's, and where it went.
fn print_distilled(f: &repertoire_meta::handover::distill::DistillFigures, out: &Path, trained: bool) {
    println!(
        "| teacher episodes | successful | decisions fitted | changed by the teacher | teacher (min) | fitting (min) | NLL first → last epoch |"
    );
    println!("|---:|---:|---:|---:|---:|---:|---|");
    println!(
        "| {} | {} | {} | {} | {:.1} | {:.1} | {:.3} → {:.3} |",
        f.episodes,
        f.successes,
        f.demonstrations,
        f.changed,
        f.planning_s / 60.0,
        f.fitting_s / 60.0,
        f.losses.first().copied().unwrap_or(f32::NAN),
        f.losses.last().copied().unwrap_or(f32::NAN)
    );
    println!("meta-controller written to {} (evaluate: repertoire meta eval --meta {})", out.display(), out.display());
    if trained {
        println!("the fitted controller before PPO: {}", out.join("fitted").display());
    }
}

/// `meta readiness`.
fn readiness_cmd(
    ReadinessArgs {
        scenario: ScenarioArgs { file, library },
        meta,
        out,
        trials,
        zones,
        seed,
        holdout,
        epochs,
        hidden,
        ready_at,
        plan,
    }: ReadinessArgs,
    command: String,
) -> Result<()> {
    let setup = setup(file.as_ref(), &library, &[], &[])?;
    sitting_only(&setup, "readiness is learned for")?;
    let meta = meta.unwrap_or_else(|| setup_meta(&library, &setup));
    let (_, head) = load(&meta, &setup)?;
    let out = out.unwrap_or_else(|| meta.join("readiness"));
    let opts = ReadinessOptions {
        out: out.clone(),
        zones: zones_or_all(zones, &setup.model.scenario.scenario),
        trials,
        seed,
        planner: plan.config()?,
        holdout,
        classifier: ClassifierConfig { hidden, epochs, seed, ..ClassifierConfig::default() },
        threshold: ready_at,
        controller: meta.display().to_string(),
        command,
    };
    let manifest = learn(setup, &head, &opts).context("learning the sit's readiness")?;
    print!("{}", manifest.markdown());
    println!(
        "\nreadiness written to {} (evaluate the gated controller: repertoire meta eval --readiness {})",
        out.display(),
        out.display()
    );
    Ok(())
}

/// `meta deliver`.
fn deliver_cmd(
    DeliverArgs {
        scenario: ScenarioArgs { file, library },
        spec,
        meta,
        planner,
        plan,
        trials,
        zones,
        seed,
        max_offset,
        max_turn,
        max_states,
        out,
        handovers_out,
    }: DeliverArgs,
) -> Result<()> {
    let skill = repertoire_skill::SkillSetup::new(repertoire_skill::spec::SpecFile::load(&spec)?, &library)?;
    let name = skill.spec.spec.name.clone();
    if !(max_offset >= 0.0 && max_turn >= 0.0) {
        bail!("--max-offset and --max-turn must be at least 0");
    }
    // A skill without a seat goal (the stand) has no window: every decision is kept.
    let expected = skill.seat_at_start();
    let setup = setup(file.as_ref(), &library, &[], &[])?;
    let zones = zones_or_all(zones, &setup.model.scenario.scenario);
    let window = expected.map(|expected| DeliveryWindow { expected, max_offset_m: max_offset, max_turn_deg: max_turn });
    // Both output paths are settled before the episodes are played.
    let out = out.unwrap_or_else(|| PathBuf::from("runs").join(format!("delivered-{name}.ron")));
    let handovers_out = handovers_out.unwrap_or_else(|| {
        let stem = out.file_stem().map(|s| s.to_string_lossy().into_owned()).unwrap_or_default();
        out.with_file_name(format!("{stem}-handovers.ron"))
    });
    if handovers_out == out {
        bail!("--handovers-out {} is the --out file", out.display());
    }
    for dir in [&out, &handovers_out].into_iter().filter_map(|p| p.parent()).filter(|d| !d.as_os_str().is_empty()) {
        std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
    }
    let started = std::time::Instant::now();
    let delivery = if planner {
        if meta.is_some() {
            bail!("--planner chooses the skills itself: it takes no --meta");
        }
        let cfg = plan.config()?;
        deliver(&setup, &cfg, &name, &zones, trials, seed, window, max_states)?
    } else {
        let meta = meta.unwrap_or_else(|| setup_meta(&library, &setup));
        let (_, head) = load(&meta, &setup)?;
        deliver(&setup, &head, &name, &zones, trials, seed, window, max_states)?
    };
    delivery.pool.save(&out)?;
    delivery.handover_pool.save(&handovers_out)?;
    let seconds = started.elapsed().as_secs_f64();
    print_delivery(&delivery, &name, expected, (max_offset, max_turn), [&spec, &out, &handovers_out], seconds);
    Ok(())
}

/// What `meta deliver` ends with: the states kept against the window (`expected`, within
/// `limits`: metres and degrees), the handovers, and how to fine-tune from the pools
/// (`files`: the spec, the pool, the handovers' pool).
fn print_delivery(
    d: &repertoire_meta::handover::deliver::Delivery,
    name: &str,
    expected: Option<[f64; 3]>,
    (max_offset, max_turn): (f64, f64),
    [spec, out, handovers_out]: [&Path; 3],
    seconds: f64,
) {
    match expected {
        Some(expected) => println!(
            "{} episodes, {} decisions before `{name}`, {} with the seat within {max_offset} m / {max_turn}° of \
             where `{name}` expects it ({:+.2}, {:+.2} m, {:+.0}°); {} states written to {} in {:.1} s",
            d.episodes,
            d.decisions,
            d.in_window,
            expected[0],
            expected[1],
            expected[2].to_degrees(),
            d.pool.states.len(),
            out.display(),
            seconds
        ),
        None => println!(
            "{} episodes, {} decisions before `{name}` (it has no seat goal, so no window: every one is \
             kept, with the seat's pose); {} states written to {} in {:.1} s",
            d.episodes,
            d.decisions,
            d.pool.states.len(),
            out.display(),
            seconds
        ),
    }
    if expected.is_some() {
        println!(
            "the controller switched to `{name}` {} times, {} of them ({:.1} %) with the seat in the window",
            d.handovers,
            d.handovers_in_window,
            100.0 * d.handovers_in_window as f64 / d.handovers.max(1) as f64
        );
        println!(
            "{} episodes succeeded, {} of them after a handover with the seat in the window",
            d.successes, d.successes_in_window
        );
    } else {
        println!("the controller switched to `{name}` {} times; {} episodes succeeded", d.handovers, d.successes);
    }
    println!(
        "the {} states at the handovers, in the window or not, written to {}",
        d.handover_pool.states.len(),
        handovers_out.display()
    );
    println!(
        "fine-tune from either: repertoire skill finetune {} --from {} (or {})",
        spec.display(),
        out.display(),
        handovers_out.display()
    );
}

/// `meta refine`.
fn refine_cmd(
    RefineArgs { file, spec, meta, task_weight, skill_weight, common }: RefineArgs,
    command: String,
) -> Result<()> {
    let (skill, opts) = super::skill::prepare(&spec, None, Some(None), common, command)?;
    let setup = setup(file.as_ref(), &opts.library, &[], &[])?;
    let meta = meta.unwrap_or_else(|| setup_meta(&opts.library, &setup));
    let (_, head) = load(&meta, &setup)?;
    let name = skill.spec.spec.name.clone();
    let probe_env = skill.env();
    let refine = Arc::new(RefineSetup::new(
        Arc::clone(&setup),
        head,
        &name,
        Arc::clone(&skill.settings),
        probe_env.action_bounds(),
        (skill_weight, task_weight),
    )?);
    let chosen = refine.probe(16, opts.seed.unwrap_or(1))?;
    tracing::info!(skill = %name, controller = %meta.display(), chosen, of = 16, "refining in the controller's episodes");
    let out = repertoire_skill::train::train_in(&skill, &opts, &|n| refine.envs(n))
        .with_context(|| format!("refining {} under {}", spec.display(), meta.display()))?;
    super::skill::print_outcome(&skill, &out);
    if let Some(last) = out.history.last() {
        let term = |n: &str| last.terms.iter().find(|(k, _)| k == n).map_or(f32::NAN, |(_, v)| *v);
        println!(
            "last iteration: {} episodes, success {:.1}%, `{name}` fell in {:.1}%, task reward {:.2} per episode",
            last.episodes,
            100.0 * term("success"),
            100.0 * term("skill_fell"),
            term("task_reward")
        );
    }
    println!(
        "re-pin the controller to it: repertoire meta train --library {} --warm-start {} --iterations 0 --out NEW",
        opts.library.display(),
        meta.display()
    );
    Ok(())
}

/// Refuses a scenario that is not a sitting one: "FILE: WHAT sitting scenarios only (this one
/// is TASK)".
fn sitting_only(setup: &MetaSetup, what: &str) -> Result<()> {
    if !matches!(setup.task, TaskSpec::Sit { .. }) {
        bail!(
            "{}: {what} sitting scenarios only (this one is {})",
            setup.model.scenario.path.display(),
            setup.task.name()
        );
    }
    Ok(())
}

/// A probability: a number from 0 to 1.
pub(crate) fn probability(s: &str) -> std::result::Result<f32, String> {
    let p: f32 = s.parse().map_err(|e| format!("{s}: {e}"))?;
    if (0.0..=1.0).contains(&p) { Ok(p) } else { Err(format!("{s} is not a probability (0 to 1)")) }
}

/// `zones`, or every spawn zone of `scenario` when none are named.
fn zones_or_all(zones: Vec<String>, scenario: &repertoire_scenes::Scenario) -> Vec<String> {
    if zones.is_empty() { scenario.spawn.iter().map(|z| z.name.clone()).collect() } else { zones }
}

/// The scenario of `file` as a built scene and its latent model folder when it is driven
/// through one: `--latent` when given, else the scenario's `low_level: Latent(..)`; `None` for
/// the skills.
pub(super) fn latent_low_level(
    file: Option<&PathBuf>,
    flag: Option<PathBuf>,
) -> Result<Option<(Arc<WorldModel>, PathBuf)>> {
    let scenario = super::load_scenario(file)?;
    let Some(dir) = flag.or_else(|| scenario.latent_dir()) else {
        return Ok(None);
    };
    Ok(Some((Arc::new(WorldModel::build(scenario)?), dir)))
}

/// The skills' graph options mean nothing to a latent low level: refused rather than ignored.
fn no_skill_options(chain: &[String], skills: &[String]) -> Result<()> {
    if !chain.is_empty() || !skills.is_empty() {
        anyhow::bail!("--chain and --skills restrict the skill graph; a latent low level has none");
    }
    Ok(())
}

/// Where a latent high level goes when no `--out`/`--meta` is given:
/// `LIBRARY/latent-meta-<scenario name>`.
pub fn default_latent_meta(library: &Path, model: &WorldModel) -> PathBuf {
    library.join(format!("latent-meta-{}", model.scenario.scenario.name))
}

/// Iterations the value network trains alone when `--warm-start`'s controller saved no critic.
const WARM_START_CRITIC_WARMUP: usize = 100;

/// A run `meta train` asks for ([`RunArgs`]) and the command line that asked.
struct TrainRun {
    args: RunArgs,
    command: String,
}

impl TrainRun {
    /// The training options over `base` (the low level's PPO defaults) writing the controller
    /// to `out`: a fresh run in `runs/<prefix>-<time>-s<seed>` unless `--run-dir` says
    /// otherwise, or the checkpoint's settings and run directory when resuming.
    fn options(self, base: repertoire_learn::ppo::PpoConfig, out: PathBuf, prefix: &str) -> Result<MetaTrainOptions> {
        let TrainRun { args: a, command } = self;
        let (ppo, run_dir) = match &a.resume {
            Some(stem) => {
                let ppo = repertoire_meta::train::resumed_ppo(stem, a.iterations, a.envs, a.seed, a.ent_coef)?;
                let run_dir = match a.run_dir {
                    Some(dir) => dir,
                    None => repertoire_meta::train::run_of_checkpoint(stem).with_context(|| {
                        format!("{} is not in a run's checkpoints folder: give --run-dir", stem.display())
                    })?,
                };
                (ppo, run_dir)
            }
            None => {
                let ppo = repertoire_learn::ppo::PpoConfig {
                    num_envs: a.envs.unwrap_or(base.num_envs),
                    num_iterations: a.iterations.unwrap_or(base.num_iterations),
                    seed: a.seed.unwrap_or(base.seed),
                    ent_coef: a.ent_coef.unwrap_or(base.ent_coef),
                    learning_rate: a.learning_rate.unwrap_or(base.learning_rate),
                    critic_warmup: a.critic_warmup.unwrap_or_else(|| match &a.warm_start {
                        Some(dir) if !dir.join(repertoire_meta::train::CRITIC_FILE).exists() => {
                            WARM_START_CRITIC_WARMUP
                        }
                        _ => base.critic_warmup,
                    }),
                    ..base
                };
                let secs =
                    std::time::SystemTime::now().duration_since(std::time::UNIX_EPOCH).map_or(0, |d| d.as_secs());
                let run_dir = a.run_dir.unwrap_or_else(|| PathBuf::from(format!("runs/{prefix}-{secs}-s{}", ppo.seed)));
                (ppo, run_dir)
            }
        };
        Ok(MetaTrainOptions {
            out,
            run_dir,
            ppo,
            curriculum: !a.no_curriculum,
            command,
            resume: a.resume,
            checkpoint_every: a.checkpoint_every,
            warm_start: a.warm_start,
            replace: a.replace,
        })
    }
}

/// `OLD=NEW` of `meta train --replace`.
fn parse_replace(s: &str) -> std::result::Result<(String, String), String> {
    match s.split_once('=') {
        Some((old, new)) if !old.is_empty() && !new.is_empty() && !new.contains('=') => Ok((old.into(), new.into())),
        _ => Err(format!("expected OLD=NEW (two skill names), got `{s}`")),
    }
}

fn train_latent(
    model: Arc<WorldModel>,
    dir: &Path,
    library: &Path,
    out: Option<PathBuf>,
    hold: usize,
    run: TrainRun,
) -> Result<()> {
    let setup = Arc::new(
        LatentSetup::new(model, dir, library, hold)
            .with_context(|| format!("preparing the latent low level {}", dir.display()))?,
    );
    let out = out.unwrap_or_else(|| default_latent_meta(library, &setup.model));
    let opts = run.options(latent::default_ppo(&setup), out.clone(), "latent-meta")?;
    let run_dir = opts.run_dir.clone();
    let (manifest, history) = latent::train(setup, &opts).context("training the latent high level")?;
    print_training(
        "high-level steps",
        manifest.iterations,
        manifest.samples,
        manifest.seconds,
        &history,
        &manifest.advances,
    );
    println!(
        "latent high level (z of {}, held {} ticks, through {}) written to {}; run in {}",
        manifest.latent_dim,
        manifest.hold,
        manifest.latent_model,
        out.display(),
        run_dir.display()
    );
    Ok(())
}

/// The table a training run ends with, and its zone switches.
fn print_training(
    steps: &str,
    iterations: usize,
    samples: u64,
    seconds: f64,
    history: &[IterationMetrics],
    advances: &[Advance],
) {
    let last = history.last();
    println!("| iterations | {steps} | minutes | mean return | success (last iteration) | zone switches |");
    println!("|---:|---:|---:|---:|---:|---:|");
    println!(
        "| {iterations} | {samples} | {:.1} | {:.2} | {:.1}% | {} |",
        seconds / 60.0,
        last.map_or(f32::NAN, |m| m.mean_return),
        100.0 * last.and_then(|m| m.terms.first()).map_or(f32::NAN, |t| t.1),
        advances.len()
    );
    for a in advances {
        println!(
            "curriculum: {} → {} after {} episodes (success {:.0}%{})",
            a.from,
            a.to,
            a.episode,
            100.0 * a.success_rate,
            match a.reason {
                repertoire_meta::AdvanceReason::Threshold => "",
                repertoire_meta::AdvanceReason::Budget => "; the zone's episode budget was spent",
            }
        );
    }
}

/// `meta eval` through the latent low level: where the latent high level and its evaluation lie.
pub(super) struct LatentEval {
    pub(super) library: PathBuf,
    pub(super) meta: Option<PathBuf>,
    pub(super) out: Option<PathBuf>,
}

/// Evaluates the latent high level of `model`'s scenario (latent model in `dir`) as `plan`
/// says, as every controller is evaluated: report, worst episodes and picks recorded.
pub(super) fn eval_latent(
    model: Arc<WorldModel>,
    dir: &Path,
    a: LatentEval,
    plan: &EvalPlan,
    recorded: (Worst, &[Pick]),
) -> Result<()> {
    let meta = a.meta.unwrap_or_else(|| default_latent_meta(&a.library, &model));
    let manifest = latent::read_manifest(&meta)?;
    let setup = Arc::new(
        LatentSetup::new(model, dir, &a.library, manifest.hold)
            .with_context(|| format!("preparing the latent low level {}", dir.display()))?,
    );
    let (_, policy) = latent::load(&meta, &setup)?;
    let out = a.out.unwrap_or_else(|| meta.join("eval"));
    let controller = latent::LatentController { policy };
    eval::evaluate_and_report(&setup, &controller, plan, recorded, &out)?;
    Ok(())
}
