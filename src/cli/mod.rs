//! Command-line interface: argument parsing and one function per command.

mod ablate;
mod bench;
mod clip;
mod controller;
mod latent;
mod meta;
mod recipe;
pub mod replay;
mod report;
mod run;
mod scene;
mod skill;

use anyhow::Result;
use clap::{Parser, Subcommand};
use repertoire_scenes::ScenarioFile;
use std::path::PathBuf;

/// Physics-based humanoid characters that compose learned motor skills.
#[derive(Debug, Parser)]
#[command(name = "repertoire", version, about)]
pub struct Cli {
    /// More log output (or set RUST_LOG).
    #[arg(short, long, global = true)]
    pub verbose: bool,
    #[command(subcommand)]
    pub command: Command,
}

#[derive(Debug, Subcommand)]
pub enum Command {
    /// Run the main job on a scenario (default: the built-in scenarios/sit.ron).
    Run(run::RunArgs),
    /// Inspect scenario files.
    #[command(subcommand)]
    Scene(scene::SceneCommand),
    /// Measure throughput.
    #[command(subcommand)]
    Bench(bench::BenchCommand),
    /// Reference clips: import, retarget, check.
    #[command(subcommand)]
    Clip(clip::ClipCommand),
    /// Train, fine-tune and evaluate skills.
    #[command(subcommand)]
    Skill(skill::SkillCommand),
    /// The NPMP latent low level: collect expert rollouts, train the encoder/decoder, one-shot
    /// imitation.
    #[command(subcommand)]
    Latent(latent::LatentCommand),
    /// Train and evaluate the meta-controller of a scenario (sitting, warehouse, toss).
    #[command(subcommand)]
    Meta(meta::MetaCommand),
    /// Recipes: the stages that make a library and its controllers (train, fine-tune on
    /// handovers, re-pin, evaluate, in rounds), each skipped when done, resumed when
    /// interrupted, run here or as Slurm jobs.
    #[command(subcommand)]
    Recipe(recipe::RecipeCommand),
    /// Write a recording (or every recording in a folder) as a self-contained HTML replay page.
    Replay(replay::ReplayArgs),
    /// Export a recording's motion: BVH (Blender, Maya, game engines) and/or qpos as .npy.
    Export(replay::ExportArgs),
    /// Judge recordings again by a scenario's fall test (from their poses), beside what was
    /// recorded: re-checks recordings made before the shared fall test or under another rule.
    FallCheck(replay::FallCheckArgs),
    /// Run an ablation study (variants × seeds of the meta-controller) and write its table.
    Ablate {
        /// The study (RON): scenario, library, seeds, iterations, trials, variants.
        spec: PathBuf,
        /// Output folder (plans, runs, table).
        #[arg(long, default_value = "runs/ablation")]
        out: PathBuf,
        /// Only write the plan files (for a scheduler), run nothing.
        #[arg(long)]
        plan_only: bool,
        /// Override the study's seeds (e.g. 1 for a quick pass).
        #[arg(long, value_delimiter = ',')]
        seeds: Vec<u64>,
        /// Override the study's meta-controller iterations per run.
        #[arg(long, value_parser = crate::cli::at_least_one)]
        iterations: Option<usize>,
        /// Override the study's evaluation trials per zone.
        #[arg(long)]
        trials: Option<usize>,
        /// Runs at a time (each then logs into its folder's log.txt and gets an equal share of
        /// the cores for its rayon pool, unless RAYON_NUM_THREADS is set).
        #[arg(long, default_value_t = 1, value_parser = crate::cli::at_least_one)]
        jobs: usize,
        /// Submit the runs that have no report as one Slurm job array (a task per variant ×
        /// seed), and a job after it that gathers the table.
        #[arg(long, conflicts_with = "plan_only")]
        slurm: bool,
        #[command(flatten)]
        sbatch: recipe::SbatchArgs,
        /// With --slurm: wait until the jobs have ended, then check the table was written.
        #[arg(long, requires = "slurm")]
        wait: bool,
        /// Run only the plan with this index (what each task of the Slurm array runs).
        #[arg(long, hide = true)]
        run_index: Option<usize>,
    },
    /// Gather a run's charts (PNG + SVG) and tables into DIR/report/index.md and index.html:
    /// learning curves, curriculum schedule, success map, transition matrices, ablation table.
    Report {
        /// A training run, meta-controller run, evaluation or ablation folder.
        dir: PathBuf,
    },
}

/// A count that must be at least 1 (`--iterations`): 0 would silently run one iteration.
pub fn at_least_one(s: &str) -> std::result::Result<usize, String> {
    match s.parse::<usize>() {
        Ok(0) => Err("must be at least 1".to_string()),
        Ok(n) => Ok(n),
        Err(e) => Err(e.to_string()),
    }
}

/// A finite number that must not be negative (`--ent-coef`).
pub fn non_negative(s: &str) -> std::result::Result<f32, String> {
    match s.parse::<f32>() {
        Ok(x) if x.is_finite() && x >= 0.0 => Ok(x),
        Ok(_) => Err("must be a finite number, 0 or more".to_string()),
        Err(e) => Err(e.to_string()),
    }
}

/// A finite number above 0 (`--learning-rate` of `skill train` and `meta train`).
pub fn positive_f64(s: &str) -> std::result::Result<f64, String> {
    match s.parse::<f64>() {
        Ok(x) if x.is_finite() && x > 0.0 => Ok(x),
        Ok(_) => Err("must be a finite number above 0".to_string()),
        Err(e) => Err(e.to_string()),
    }
}

/// The command line as a manifest records it: `repertoire` and the arguments, each quoted for
/// a POSIX shell where it needs it, so that it re-runs as written whatever the binary was called
/// or where it lay (`target/release/repertoire`, a copy in `/tmp`).
///
/// Paths in the working folder or the repository are written relative to it
/// ([`repertoire_files::portable`]), and a command a recipe stage runs names the stage after a
/// shell comment (`  # recipe recipes/sit.ron#handover/r2/finetune`).
pub fn invocation() -> String {
    let mut line = invocation_of(std::env::args().skip(1).map(|a| repertoire_files::portable(&a)));
    if let Ok(stage) = std::env::var(repertoire_recipe::run::STAGE_ENV) {
        line.push_str("  # recipe ");
        line.push_str(&repertoire_files::portable(&stage));
    }
    line
}

fn invocation_of(args: impl Iterator<Item = String>) -> String {
    let mut out = String::from("repertoire");
    for a in args {
        out.push(' ');
        out.push_str(&repertoire_recipe::run::shell_quote(&a));
    }
    out
}

/// Dispatches one parsed command line.
pub fn run(cli: Cli) -> Result<()> {
    match cli.command {
        Command::Run(args) => run::run(args),
        Command::Scene(cmd) => scene::run(cmd),
        Command::Bench(cmd) => bench::run(cmd),
        Command::Clip(cmd) => clip::run(cmd),
        Command::Skill(cmd) => skill::run(cmd),
        Command::Meta(cmd) => meta::run(cmd),
        Command::Latent(cmd) => latent::run(cmd),
        Command::Recipe(cmd) => recipe::run(cmd),
        Command::Replay(args) => replay::replay(args),
        Command::Export(args) => replay::export(args),
        Command::FallCheck(args) => replay::fall_check(args),
        Command::Ablate { spec, out, plan_only, seeds, iterations, trials, jobs, slurm, sbatch, wait, run_index } => {
            let overrides = ablate::Overrides { seeds, iterations, trials };
            let how = match (slurm, run_index) {
                (true, _) => ablate::How::Slurm { options: sbatch.options()?, wait },
                (false, Some(i)) => ablate::How::One(i),
                (false, None) if plan_only => ablate::How::PlanOnly,
                (false, None) => ablate::How::Here { jobs },
            };
            ablate::run(&spec, &out, &overrides, how)
        }
        Command::Report { dir } => {
            let page = report::run(&dir)?;
            println!("report written to {}", page.display());
            Ok(())
        }
    }
}

/// Loads the scenario at `path`, or the built-in default when none is given.
pub fn load_scenario(path: Option<&PathBuf>) -> Result<ScenarioFile> {
    Ok(match path {
        Some(p) => ScenarioFile::load(p)?,
        None => ScenarioFile::builtin_default(),
    })
}

#[cfg(test)]
mod tests {
    use super::invocation_of;

    #[test]
    fn the_recorded_command_names_repertoire_and_quotes_what_a_shell_would_split() {
        let args = ["meta", "train", "--out", "/tmp/my run", "--chain", "walk,sit", "it's", ""];
        let got = invocation_of(args.iter().map(|s| s.to_string()));
        assert_eq!(got, "repertoire meta train --out '/tmp/my run' --chain walk,sit 'it'\\''s' ''");
    }
}
