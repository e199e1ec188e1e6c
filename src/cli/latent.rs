//! `repertoire latent collect | train | eval`: the NPMP latent low level: expert rollouts into a
//! dataset, the encoder/decoder trained on it, one-shot imitation against the experts.

use std::path::{Path, PathBuf};

use anyhow::{Context, Result, bail};
use clap::{Subcommand, ValueEnum};
use repertoire_latent::dataset::{CollectOptions, Dataset, collect};
use repertoire_latent::eval::{
    ClipRow, OneShotRow, clips_markdown, comparison_markdown, csv, markdown, one_shot_many, track_clips,
};
use repertoire_latent::model::{LatentConfig, LatentPolicy, Weighting};
use repertoire_latent::train::{TrainOptions, train};
use repertoire_skill::train::default_run_dir;

const DEFAULT_LIBRARY: &str = "library";
const DEFAULT_SPECS: &str = "specs";
const DEFAULT_SKILLS: [&str; 4] = ["walk", "turn_left", "turn_right", "sit"];

/// Loss weighting on the command line.
#[derive(Debug, Clone, Copy, ValueEnum)]
pub enum WeightingArg {
    /// Behaviour cloning (every transition the same).
    Bc,
    /// Every skill's transitions together the same.
    Clip,
    /// Reward-weighted regression on the imitation return-to-go.
    Rwr,
    /// Advantage-weighted regression: the return-to-go against its mean at the same clip phase.
    Awr,
}

#[derive(Debug, Subcommand)]
pub enum LatentCommand {
    /// Run library skills with action noise from random clip frames and store their
    /// transitions (proprioception, the next k reference frames, mean and noisy actions,
    /// imitation reward) as a dataset: dataset.safetensors + dataset.ron.
    Collect(CollectArgs),
    /// Train the encoder and decoder on a dataset into a model folder (latent.ron +
    /// latent.safetensors, metrics.csv).
    Train(TrainArgs),
    /// One-shot imitation: track each skill's clip from random frames with the expert and with
    /// the latent model; normalised episode length and return side by side (one_shot.md/.csv).
    Eval(EvalArgs),
    /// Train a high-level policy whose action is the latent z (bounded to ±2) on a go-to-target
    /// task through the frozen decoder (PPO), and evaluate it beside a constant z = 0.
    Goto {
        /// The model folder (from `latent train`).
        model: PathBuf,
        /// The skill spec whose clip frames episodes start from (and whose scene is used).
        #[arg(long, default_value = "specs/walk.ron")]
        start: PathBuf,
        /// Skill library folder (for the spec's pools, if any).
        #[arg(long, default_value = DEFAULT_LIBRARY)]
        library: PathBuf,
        /// PPO iterations.
        #[arg(long, default_value_t = 1500, value_parser = crate::cli::at_least_one)]
        iterations: usize,
        /// Parallel environments.
        #[arg(long, default_value_t = 16)]
        envs: usize,
        /// Steps per environment per iteration.
        #[arg(long, default_value_t = 128)]
        steps: usize,
        /// Seed of training.
        #[arg(long, default_value_t = 1)]
        seed: u64,
        /// Evaluation trials (before and after training, on the same starts).
        #[arg(long, default_value_t = 100)]
        trials: usize,
        /// Initial log standard deviation of the high level's Gaussian over z.
        #[arg(long, default_value_t = -1.0, allow_hyphen_values = true)]
        init_log_std: f32,
        /// Output folder of the table and the trained high level (default: MODEL/goto); training
        /// metrics go to --run-dir.
        #[arg(long)]
        out: Option<PathBuf>,
        /// Run folder of the training metrics (default: runs/latent-goto-<time>-s<seed>).
        #[arg(long)]
        run_dir: Option<PathBuf>,
    },
}

/// The expert skills `latent collect` runs and `latent eval` tracks the clips of.
#[derive(Debug, clap::Args)]
pub struct Experts {
    /// Skills (their specs in --specs, their policies in --library).
    #[arg(long, value_delimiter = ',', default_values_t = DEFAULT_SKILLS.map(String::from))]
    pub skills: Vec<String>,
    /// Folder of the skill specs.
    #[arg(long, default_value = DEFAULT_SPECS)]
    pub specs: PathBuf,
    /// Skill library folder.
    #[arg(long, default_value = DEFAULT_LIBRARY)]
    pub library: PathBuf,
}

/// `latent collect`'s arguments.
#[derive(Debug, clap::Args)]
pub struct CollectArgs {
    #[command(flatten)]
    pub experts: Experts,
    /// Transitions per skill.
    #[arg(long, default_value_t = 25_000)]
    pub steps: u64,
    /// Reference frames ahead in the encoder's input.
    #[arg(long, default_value_t = 5)]
    pub k: usize,
    /// Standard deviation of the action noise.
    #[arg(long, default_value_t = 0.1)]
    pub noise: f32,
    /// Environments stepped together.
    #[arg(long, default_value_t = 16)]
    pub batch: usize,
    /// Seed.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Output folder (default: runs/latent-data-<time>-s<seed>).
    #[arg(long)]
    pub out: Option<PathBuf>,
}

/// `latent train`'s arguments.
#[derive(Debug, clap::Args)]
pub struct TrainArgs {
    /// The dataset folder (from `latent collect`).
    pub data: PathBuf,
    /// A LatentConfig in RON (defaults: 60-D latent, α 0.95, β 0.01, 2×256 MLPs).
    #[arg(long)]
    pub config: Option<PathBuf>,
    /// Override the latent width.
    #[arg(long)]
    pub latent_dim: Option<usize>,
    /// Override the KL weight β.
    #[arg(long)]
    pub beta: Option<f32>,
    /// Loss weighting.
    #[arg(long, value_enum)]
    pub weighting: Option<WeightingArg>,
    /// Temperature of RWR's and AWR's exponent (on the imitation return-to-go, discount 0.95).
    #[arg(long, alias = "rwr-temperature", default_value_t = 1.0)]
    pub temperature: f32,
    /// Most Adam updates.
    #[arg(long, default_value_t = 1_000_000)]
    pub updates: usize,
    /// Most minutes of training.
    #[arg(long, default_value_t = 20.0)]
    pub minutes: f64,
    /// Seed (default: the config's).
    #[arg(long)]
    pub seed: Option<u64>,
    /// Output folder (default: runs/latent-<time>-s<seed>).
    #[arg(long)]
    pub out: Option<PathBuf>,
}

/// `latent eval`'s arguments.
#[derive(Debug, clap::Args)]
pub struct EvalArgs {
    /// The model folder (from `latent train`); several compare them on the same starts
    /// (`--out` then required: each model's table in a folder of its name, and comparison.md).
    #[arg(required = true, num_args = 1..)]
    pub models: Vec<PathBuf>,
    #[command(flatten)]
    pub experts: Experts,
    /// Episodes per skill and controller.
    #[arg(long, default_value_t = 100)]
    pub episodes: usize,
    /// Environments stepped together.
    #[arg(long, default_value_t = 16)]
    pub batch: usize,
    /// Seed of the start states (the same for both controllers).
    #[arg(long, default_value_t = 12345)]
    pub seed: u64,
    /// A clip no expert was trained on (any clip file a skill spec takes), tracked by the latent
    /// model alone: its normalised length and return (repeatable).
    #[arg(long = "clip")]
    pub clips: Vec<PathBuf>,
    /// The skill spec whose body, rates and imitation terms a `--clip` is tracked with.
    #[arg(long, default_value = "specs/walk.ron")]
    pub clip_spec: PathBuf,
    /// Output folder (default: MODEL/eval).
    #[arg(long)]
    pub out: Option<PathBuf>,
}

fn spec_paths(specs: &Path, skills: &[String]) -> Result<Vec<PathBuf>> {
    if skills.is_empty() {
        bail!("no skill named");
    }
    skills
        .iter()
        .map(|s| {
            let p = specs.join(format!("{s}.ron"));
            if p.exists() { Ok(p) } else { bail!("no spec for skill `{s}`: {} does not exist", p.display()) }
        })
        .collect()
}

pub fn run(cmd: LatentCommand) -> Result<()> {
    let command = super::invocation();
    match cmd {
        LatentCommand::Collect(args) => collect_cmd(args, command),
        LatentCommand::Train(args) => train_cmd(args, command),
        LatentCommand::Eval(args) => eval_cmd(args, command),
        LatentCommand::Goto {
            model,
            start,
            library,
            iterations,
            envs,
            steps,
            seed,
            trials,
            init_log_std,
            out,
            run_dir,
        } => goto_cmd(&model, &start, &library, iterations, envs, steps, seed, trials, init_log_std, out, run_dir),
    }
}

/// `latent collect`.
fn collect_cmd(
    CollectArgs { experts: Experts { skills, specs, library }, steps, k, noise, batch, seed, out }: CollectArgs,
    command: String,
) -> Result<()> {
    let out = out.unwrap_or_else(|| default_run_dir(Path::new("runs"), "latent-data", seed));
    let opts = CollectOptions {
        library,
        specs: spec_paths(&specs, &skills)?,
        steps_per_skill: steps,
        k,
        noise_std: noise,
        batch,
        seed,
        progress: true,
        command,
    };
    let begin = std::time::Instant::now();
    let mut data = collect(&opts).context("collecting expert rollouts")?;
    let bytes = data.save(&out)?;
    let m = &data.manifest;
    println!("| skill | transitions | episodes | falls |");
    println!("|---|---:|---:|---:|");
    for s in &m.skills {
        println!("| {} | {} | {} | {} |", s.name, s.steps, s.episodes, s.falls);
    }
    println!(
        "{} transitions in {:.1} s; {} written ({:.1} MB, {:.1} MB per 10^5 steps; {} values per step)",
        m.steps,
        begin.elapsed().as_secs_f64(),
        out.display(),
        bytes as f64 / 1e6,
        bytes as f64 / 1e6 * 1e5 / m.steps.max(1) as f64,
        m.proprio.size + m.reference_size + 2 * m.act_dim + 1
    );
    Ok(())
}

/// `latent train`.
fn train_cmd(
    TrainArgs { data, config, latent_dim, beta, weighting, temperature, updates, minutes, seed, out }: TrainArgs,
    command: String,
) -> Result<()> {
    let mut cfg = match &config {
        Some(p) => {
            let text = std::fs::read_to_string(p).with_context(|| format!("reading {}", p.display()))?;
            ron::from_str::<LatentConfig>(&text).map_err(|e| {
                anyhow::anyhow!("{}:{}:{}: {}", p.display(), e.span.start.line, e.span.start.col, e.code)
            })?
        }
        None => LatentConfig::default(),
    };
    if let Some(z) = latent_dim {
        cfg.latent_dim = z;
    }
    if let Some(b) = beta {
        cfg.beta = b;
    }
    if let Some(s) = seed {
        cfg.seed = s;
    }
    match weighting {
        Some(WeightingArg::Bc) => cfg.weighting = Weighting::Bc,
        Some(WeightingArg::Clip) => cfg.weighting = Weighting::ClipBalanced,
        Some(WeightingArg::Rwr) => cfg.weighting = Weighting::Rwr { temperature, gamma: 0.95, max_weight: 20.0 },
        Some(WeightingArg::Awr) => cfg.weighting = Weighting::Awr { temperature, gamma: 0.95, max_weight: 20.0 },
        None => {}
    }
    let dataset = Dataset::load(&data)?;
    let out = out.unwrap_or_else(|| default_run_dir(Path::new("runs"), "latent", cfg.seed));
    std::fs::create_dir_all(&out).with_context(|| format!("creating {}", out.display()))?;
    tracing::info!(transitions = dataset.len(), out = %out.display(), "training the latent model");
    let opts = TrainOptions {
        max_updates: updates,
        max_seconds: minutes * 60.0,
        log_every: 50,
        progress: true,
        metrics_csv: Some(out.join("metrics.csv")),
        command,
    };
    let (mut policy, _) = train(&dataset, &data, cfg, &opts)?;
    let path = policy.save(&out)?;
    let t = &policy.manifest.training;
    println!("| updates | rows | minutes | loss | −log π | KL | action MSE |");
    println!("|---:|---:|---:|---:|---:|---:|---:|");
    println!(
        "| {} | {} | {:.1} | {:.2} → {:.2} | {:.2} → {:.2} | {:.2} → {:.2} | {:.4} → {:.4} |",
        t.updates,
        t.rows,
        t.seconds / 60.0,
        t.first.loss,
        t.last.loss,
        t.first.nll,
        t.last.nll,
        t.first.kl,
        t.last.kl,
        t.first.action_mse,
        t.last.action_mse
    );
    println!("model written to {}", path.display());
    Ok(())
}

/// `latent eval`.
fn eval_cmd(
    EvalArgs { models, experts: Experts { skills, specs, library }, episodes, batch, seed, clips, clip_spec, out }: EvalArgs,
    command: String,
) -> Result<()> {
    if models.len() > 1 && out.is_none() {
        // Before any rollout: the comparison has nowhere to go.
        bail!("several models are compared into one folder: name it with --out");
    }
    let spec_files = spec_paths(&specs, &skills)?;
    let mut policies = models.iter().map(|m| LatentPolicy::load(m)).collect::<std::result::Result<Vec<_>, _>>()?;
    let results = one_shot_many(&mut policies, &models, &library, &spec_files, episodes, batch, seed)?;
    let tracked = if clips.is_empty() {
        vec![Vec::new(); models.len()]
    } else {
        track_clips(&mut policies, &models, &clip_spec, &library, &clips, episodes, batch, seed)?
    };
    let labels = model_labels(&models);
    let clip_table = |pick: &dyn Fn(usize) -> bool| {
        let chosen: Vec<(String, Vec<ClipRow>)> =
            (0..models.len()).filter(|&i| pick(i)).map(|i| (labels[i].clone(), tracked[i].clone())).collect();
        if clips.is_empty() {
            String::new()
        } else {
            format!(
                "\nClips no expert was trained on, tracked by the latent model alone in the environment of `{}`:\n\n{}",
                clip_spec.display(),
                clips_markdown(&chosen)
            )
        }
    };
    let about = |what: &str| {
        format!(
            "One-shot imitation through {what} ({episodes} episodes per clip from random reference frames, start \
             seed {seed}, the same starts for the expert and the latent model; lengths and returns normalised \
             as in MoCapAct Table 2; a clip whose skill is not in the model's dataset is marked held out). \
             Command: `{command}`\n\n"
        )
    };
    let write_table = |dir: &Path, model: &Path, rows: &[OneShotRow], i: usize| -> Result<()> {
        std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
        let md = format!("{}{}", markdown(rows), clip_table(&|j| j == i));
        let page = format!("{}{md}", about(&model.display().to_string()));
        repertoire_latent::error::write_atomic(&dir.join("one_shot.md"), page.as_bytes())?;
        repertoire_latent::error::write_atomic(&dir.join("one_shot.csv"), csv(rows).as_bytes())?;
        Ok(())
    };
    if let [model] = models.as_slice() {
        let rows = &results[0];
        let dir = if model.is_dir() { model.clone() } else { model.parent().unwrap_or(Path::new(".")).to_path_buf() };
        let out = out.unwrap_or_else(|| dir.join("eval"));
        write_table(&out, model, rows, 0)?;
        print!("{}{}", markdown(rows), clip_table(&|_| true));
        println!("written to {}", out.join("one_shot.md").display());
        return Ok(());
    }
    let Some(out) = out else { bail!("several models are compared into one folder: name it with --out") };
    let mut compared = Vec::new();
    for (i, ((model, label), (rows, policy))) in
        models.iter().zip(&labels).zip(results.into_iter().zip(&policies)).enumerate()
    {
        write_table(&out.join(label), model, &rows, i)?;
        let weighting = policy.manifest.config.weighting.label();
        compared.push((label.clone(), weighting, policy.manifest.training.updates, rows));
    }
    let table = format!("{}{}", comparison_markdown(&compared), clip_table(&|_| true));
    let page = format!(
        "{}The latent model's return as a share of the expert's, per clip; each model's full table is in \
         the folder of its name.\n\n{table}",
        about(&format!("{} models", models.len()))
    );
    repertoire_latent::error::write_atomic(&out.join("comparison.md"), page.as_bytes())?;
    print!("{table}");
    println!("written to {}", out.join("comparison.md").display());
    Ok(())
}

/// Folder names for compared models: each model's own folder name, or its path with `/` → `-`
/// where two share a name.
fn model_labels(models: &[PathBuf]) -> Vec<String> {
    let name =
        |m: &PathBuf| m.file_name().map_or_else(|| m.display().to_string(), |n| n.to_string_lossy().into_owned());
    let names: Vec<String> = models.iter().map(name).collect();
    models
        .iter()
        .zip(&names)
        .map(|(m, n)| {
            if names.iter().filter(|o| *o == n).count() > 1 {
                m.display().to_string().replace(['/', '\\'], "-").trim_matches('-').to_string()
            } else {
                n.clone()
            }
        })
        .collect()
}

#[allow(clippy::too_many_arguments)]
fn goto_cmd(
    model_path: &Path,
    start: &Path,
    library: &Path,
    iterations: usize,
    envs: usize,
    steps: usize,
    seed: u64,
    trials: usize,
    init_log_std: f32,
    out: Option<PathBuf>,
    run_dir: Option<PathBuf>,
) -> Result<()> {
    use repertoire_latent::high::{GoToOptions, GoToSettings, train_goto};
    use std::sync::Arc;

    let policy = LatentPolicy::load(model_path)?;
    let setup = repertoire_skill::SkillSetup::new(repertoire_skill::SpecFile::load(start)?, library)?;
    let settings = Arc::new(GoToSettings {
        start: Arc::clone(&setup.settings),
        distance_m: (2.0, 4.0),
        azimuth_deg: 90.0,
        reach_m: 0.5,
        reach_bonus: 10.0,
        min_height: 0.5,
    });
    let dir = if model_path.is_dir() {
        model_path.to_path_buf()
    } else {
        model_path.parent().unwrap_or(Path::new(".")).to_path_buf()
    };
    let out = out.unwrap_or_else(|| dir.join("goto"));
    let opts = GoToOptions {
        iterations,
        envs,
        steps,
        seed,
        trials,
        eval_seed: 4242,
        episode_s: 10.0,
        init_log_std,
        progress: true,
    };
    std::fs::create_dir_all(&out).with_context(|| format!("creating {}", out.display()))?;
    // Training metrics go to a run folder under runs/, the table and the policy beside the model.
    let run_dir = run_dir.unwrap_or_else(|| default_run_dir(Path::new("runs"), "latent-goto", seed));
    let outcome = train_goto(&setup.model, &settings, &policy, model_path, &opts, &run_dir)?;
    outcome.policy.save(&out.join("high_level.safetensors"))?;
    let (zero, trained, minutes) = (outcome.zero, outcome.trained, outcome.minutes);
    let mut md = format!(
        "Go to a target 2–4 m away within ±90° of the start heading (reached within 0.5 m, 10 s limit), \
         starting mid-stride from {} frames, through the frozen decoder of {}; {} PPO iterations ({} steps, {:.1} min, initial log-std {init_log_std}).\n\n",
        setup.spec.spec.name,
        model_path.display(),
        iterations,
        outcome.samples,
        minutes
    );
    md.push_str(
        "| high level | trials | reached | falls | min distance (m) | episode (s) |\n|---|---:|---:|---:|---:|---:|\n",
    );
    for (name, r) in [("constant z = 0", zero), ("PPO over z", trained)] {
        md.push_str(&format!(
            "| {name} | {} | {:.1} % | {:.1} % | {:.2} | {:.1} |\n",
            r.trials,
            100.0 * r.success_rate,
            100.0 * r.fall_rate,
            r.mean_min_distance,
            r.mean_seconds
        ));
    }
    repertoire_latent::error::write_atomic(&out.join("goto.md"), md.as_bytes())?;
    print!("{md}");
    println!("written to {}; training metrics in {}", out.join("goto.md").display(), run_dir.display());
    Ok(())
}
