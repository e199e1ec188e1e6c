//! `repertoire recipe plan|run|stage FILE`: the stages that make a library and its controllers,
//! run here or through Slurm (the `repertoire-recipe` crate).

use std::path::{Path, PathBuf};

use anyhow::{Context, Result, bail};
use clap::{Args, Subcommand};
use repertoire_recipe::run::{Runner, Standing};
use repertoire_recipe::slurm::{self, SlurmOptions};
use repertoire_recipe::{Keep, Plan};

#[derive(Debug, Subcommand)]
pub enum RecipeCommand {
    /// Print the recipe's stages, which each follows, their identities and what a run would do
    /// (done, resume, run, queued, stopped, or undecided until a round ends).
    Plan {
        #[command(flatten)]
        recipe: RecipeArgs,
        /// Print the graph in Graphviz's dot language instead.
        #[arg(long)]
        dot: bool,
    },
    /// Run every stage that is not done, in order: here, or as Slurm jobs (--slurm).
    Run {
        #[command(flatten)]
        recipe: RecipeArgs,
        /// Submit each stage as a Slurm batch job, after the jobs of the stages it follows.
        #[arg(long)]
        slurm: bool,
        #[command(flatten)]
        sbatch: SbatchArgs,
        /// With --slurm: wait until every job of the recipe has ended, then check they all
        /// finished.
        #[arg(long, requires = "slurm")]
        wait: bool,
    },
    /// Keep what the stages made for their current inputs: each stage that finished (or
    /// started) with another identity is given its current one, so a run skips (or resumes) it.
    /// For a change that does not change what the stages make (code tidied, files moved), after
    /// checking it does not; the old identities stay in the records.
    Adopt {
        #[command(flatten)]
        recipe: RecipeArgs,
        /// Adopt the stages up to this one only (`name`, or `group/rK/name`).
        #[arg(long, value_name = "STAGE")]
        through: Option<String>,
    },
    /// Run one stage, with what the stages before it left (what each Slurm job runs).
    Stage {
        #[command(flatten)]
        recipe: RecipeArgs,
        /// The stage (`name`, or `group/rK/name` inside rounds).
        id: String,
    },
}

/// The recipe and its work folder.
#[derive(Debug, Args)]
pub struct RecipeArgs {
    /// The recipe (RON), e.g. recipes/sit.ron.
    file: PathBuf,
    /// Another work folder than the recipe's `work`.
    #[arg(long)]
    work: Option<PathBuf>,
    /// Set one of the recipe's `vars` (repeat): `--var skills=runs/recipe-library/library`
    /// starts recipes/sit.ron from the skills recipes/library.ron made.
    #[arg(long = "var", value_name = "NAME=VALUE", value_parser = parse_var)]
    vars: Vec<(String, String)>,
}

fn parse_var(s: &str) -> std::result::Result<(String, String), String> {
    match s.split_once('=') {
        Some((k, v)) if !k.is_empty() => Ok((k.to_string(), v.to_string())),
        _ => Err(format!("`{s}`: expected NAME=VALUE")),
    }
}

impl RecipeArgs {
    fn args(&self) -> Vec<String> {
        let mut a = vec![self.file.display().to_string()];
        if let Some(w) = &self.work {
            a.extend(["--work".into(), w.display().to_string()]);
        }
        for (k, v) in &self.vars {
            a.push(format!("--var={k}={v}"));
        }
        a
    }
}

/// `sbatch` options (`--slurm`).
#[derive(Debug, Args)]
pub struct SbatchArgs {
    /// A RON profile of sbatch options (partition, time, cpus_per_task, mem, extra); the
    /// options below override it.
    #[arg(long, requires = "slurm")]
    profile: Option<PathBuf>,
    /// sbatch --partition.
    #[arg(long, requires = "slurm")]
    partition: Option<String>,
    /// sbatch --time (e.g. 04:00:00).
    #[arg(long, requires = "slurm")]
    time: Option<String>,
    /// sbatch --cpus-per-task for stages that do not set `cpus`.
    #[arg(long, requires = "slurm")]
    cpus_per_task: Option<usize>,
    /// sbatch --mem (e.g. 8G).
    #[arg(long, requires = "slurm")]
    mem: Option<String>,
    /// More sbatch arguments, as they are (repeat: --sbatch-arg=--account=lab).
    #[arg(long, requires = "slurm", allow_hyphen_values = true)]
    sbatch_arg: Vec<String>,
}

impl SbatchArgs {
    pub fn options(&self) -> Result<SlurmOptions> {
        let base = match &self.profile {
            Some(p) => SlurmOptions::load(p)?,
            None => SlurmOptions::default(),
        };
        Ok(base.merged(&SlurmOptions {
            partition: self.partition.clone(),
            time: self.time.clone(),
            cpus_per_task: self.cpus_per_task,
            mem: self.mem.clone(),
            extra: self.sbatch_arg.clone(),
        }))
    }

    /// These options as `recipe run` arguments (for the job that submits later rounds).
    pub fn args(&self) -> Vec<String> {
        let mut a = Vec::new();
        if let Some(p) = &self.profile {
            a.extend(["--profile".into(), p.display().to_string()]);
        }
        for (flag, v) in [("--partition", &self.partition), ("--time", &self.time), ("--mem", &self.mem)] {
            if let Some(v) = v {
                a.extend([flag.to_string(), v.clone()]);
            }
        }
        if let Some(c) = self.cpus_per_task {
            a.extend(["--cpus-per-task".into(), c.to_string()]);
        }
        for x in &self.sbatch_arg {
            a.push(format!("--sbatch-arg={x}"));
        }
        a
    }
}

pub fn run(cmd: RecipeCommand) -> Result<()> {
    let exe = std::env::current_exe().context("locating the repertoire binary")?;
    match cmd {
        RecipeCommand::Plan { recipe, dot } => plan(&recipe, dot, exe),
        RecipeCommand::Run { recipe, slurm: false, .. } => run_here(&recipe, exe),
        RecipeCommand::Run { recipe, slurm: true, sbatch, wait } => run_slurm(&recipe, &sbatch, wait, exe),
        RecipeCommand::Adopt { recipe, through } => adopt(&recipe, through.as_deref(), exe),
        RecipeCommand::Stage { recipe, id } => stage(&recipe, &id, exe),
    }
}

fn load(recipe: &RecipeArgs) -> Result<Plan> {
    Ok(Plan::load_with(&recipe.file, recipe.work.as_deref(), &recipe.vars)?)
}

/// `recipe plan`: the table, or the graph in dot.
fn plan(recipe: &RecipeArgs, dot: bool, exe: PathBuf) -> Result<()> {
    let plan = load(recipe)?;
    if dot {
        print!("{:?}", petgraph::dot::Dot::with_config(&plan.graph(), &[petgraph::dot::Config::EdgeNoLabel]));
        return Ok(());
    }
    let mut runner = Runner::new(&plan, exe);
    runner.settle_all()?;
    print!("{}", plan_table(&runner)?);
    Ok(())
}

/// `recipe run`: every stage not done, in order, here.
fn run_here(recipe: &RecipeArgs, exe: PathBuf) -> Result<()> {
    let plan = load(recipe)?;
    let mut runner = Runner::new(&plan, exe);
    let t = std::time::Instant::now();
    let s = runner.run_local()?;
    println!(
        "recipe {}: {} stages run, {} done before, {} in rounds that stopped; {:.1} min; work folder {}",
        recipe.file.display(),
        s.ran,
        s.skipped,
        s.stopped,
        t.elapsed().as_secs_f64() / 60.0,
        plan.work.display()
    );
    Ok(())
}

/// `recipe run --slurm [--wait]`: each stage not done as a batch job.
fn run_slurm(recipe: &RecipeArgs, sbatch: &SbatchArgs, wait: bool, exe: PathBuf) -> Result<()> {
    let plan = load(recipe)?;
    let opts = sbatch.options()?;
    let mut again = vec!["recipe".to_string(), "run".into()];
    again.extend(recipe.args());
    again.push("--slurm".into());
    again.extend(sbatch.args());
    let mut runner = Runner::new(&plan, exe.clone());
    let s = slurm::submit(&mut runner, &recipe.args(), &again, &opts)?;
    println!(
        "recipe {}: {} jobs submitted, {} still queued from before, {} stages done{}",
        recipe.file.display(),
        s.jobs.len(),
        s.queued,
        s.done,
        s.continuation.map_or(String::new(), |j| format!("; job {j} submits the rounds after"))
    );
    if !wait {
        return Ok(());
    }
    slurm::wait(&plan.work, std::time::Duration::from_secs(2))?;
    let mut runner = Runner::new(&plan, exe);
    runner.settle_all()?;
    let mut unfinished = Vec::new();
    for (i, st) in plan.stages.iter().enumerate() {
        if runner.active(i) != Some(false) && !runner.done(i)? {
            unfinished.push(st.id.clone());
        }
    }
    if !unfinished.is_empty() {
        bail!(
            "the jobs ended but these stages did not finish: {} (their logs: {})",
            unfinished.join(", "),
            runner.store.log_dir().display()
        );
    }
    println!("every stage of {} finished", recipe.file.display());
    Ok(())
}

/// `recipe adopt`: the stages (up to `through`) given their current identities.
fn adopt(recipe: &RecipeArgs, through: Option<&str>, exe: PathBuf) -> Result<()> {
    let plan = load(recipe)?;
    let last = match through {
        Some(id) => plan.find(id)?,
        None => plan.stages.len().saturating_sub(1),
    };
    let mut runner = Runner::new(&plan, exe);
    let mut n = 0;
    for i in 0..plan.stages.len().min(last + 1) {
        runner.settle(i)?;
        if let Some(old) = runner.adopt(i)? {
            n += 1;
            println!("── {}: adopted (identity {old} → {})", plan.stages[i].id, runner.identity(i).unwrap_or(""));
        }
    }
    println!("recipe {}: {n} stages adopted", recipe.file.display());
    Ok(())
}

/// `recipe stage`: one stage, with what the stages it follows left (what each Slurm job runs).
fn stage(recipe: &RecipeArgs, id: &str, exe: PathBuf) -> Result<()> {
    let plan = load(recipe)?;
    let i = plan.find(id)?;
    let mut runner = Runner::new(&plan, exe);
    for j in 0..=i {
        runner.settle(j)?;
    }
    if runner.done(i)? {
        println!("── {id}: done before (identity {})", runner.identity(i).unwrap_or(""));
        return Ok(());
    }
    let ran = match std::env::var("SLURM_JOB_ID") {
        Ok(j) => format!("slurm job {j}"),
        Err(_) => "local".into(),
    };
    runner.run_stage(i, &ran)?;
    Ok(())
}

/// The `recipe plan` table.
fn plan_table(runner: &Runner) -> Result<String> {
    use std::fmt::Write as _;
    let plan = runner.plan;
    let mut out = format!("recipe {}: {}\nwork folder: {}\n\n", plan.file.display(), plan.about, plan.work.display());
    out.push_str("| # | stage | follows | identity | would | command |\n|---:|---|---|---|---|---|\n");
    let slurm = which("squeue");
    let alive = |j: u64| slurm && slurm::alive(j);
    let mut counts = std::collections::BTreeMap::new();
    for (i, s) in plan.stages.iter().enumerate() {
        let standing = runner.standing(i, &alive)?;
        let would = match standing {
            Standing::Done => match runner.store.record(&s.id)? {
                Some(r) if r.seconds >= 60.0 => format!("done ({:.1} min, {})", r.seconds / 60.0, r.ran),
                Some(r) => format!("done ({:.1} s, {})", r.seconds, r.ran),
                None => "done".to_string(),
            },
            Standing::Resume => "resume".into(),
            Standing::Queued(j) => format!("queued (job {j})"),
            Standing::Run => "run".into(),
            Standing::Stopped => "stopped".into(),
            Standing::Undecided => "after the round before decides".into(),
        };
        *counts.entry(would.split(' ').next().unwrap_or("").to_string()).or_insert(0) += 1;
        let follows = plan.direct(i).iter().map(|&d| plan.stages[d].id.as_str()).collect::<Vec<_>>().join(", ");
        let _ = writeln!(
            out,
            "| {} | {} | {} | {} | {} | `{}` |",
            i + 1,
            s.id,
            follows,
            runner.identity(i).map_or("?", |x| &x[..12]),
            would,
            runner.command(i)
        );
    }
    let _ = writeln!(out, "\n{}", counts.iter().map(|(k, v)| format!("{v} {k}")).collect::<Vec<_>>().join(", "));
    for g in &plan.groups {
        let _ = writeln!(out, "rounds `{}`: at most {}; {}", g.name, g.rounds.len(), group_rule(g));
    }
    Ok(out)
}

/// What a rounds group's rule says, in words.
fn group_rule(g: &repertoire_recipe::Group) -> String {
    let Some(s) = &g.stop else { return "runs every round, keeps the last".into() };
    let stops = match s.gain_below {
        Some(x) => format!("stops when a round gains under {x} points"),
        None => "runs every round".into(),
    };
    let keeps = match s.keep {
        Keep::Last => "keeps the last round",
        Keep::Best => "keeps the best round",
    };
    format!(
        "{stops}, {keeps}, by the success in zone `{}` ({}{})",
        s.zone,
        s.report,
        s.baseline.as_ref().map_or(String::new(), |b| format!("; against {b} before round 1"))
    )
}

fn which(tool: &str) -> bool {
    std::env::var_os("PATH").is_some_and(|p| std::env::split_paths(&p).any(|d| Path::new(&d).join(tool).is_file()))
}
