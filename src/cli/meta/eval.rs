//! `repertoire meta eval [FILE]`: any controller (`--controller`) on any task, through one
//! evaluation ([`repertoire_meta::evaluation`]); also what `repertoire run` evaluates with.

use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::time::Instant;

use anyhow::{Result, bail};
use repertoire_meta::evaluation::{EvalPlan, Pick, TaskReport, Worst, evaluate_task};
use repertoire_meta::tasks::task_eval::StartGrid;
use repertoire_meta::{Arena, Controller, MetaSetup, TaskSpec};

use crate::cli::controller::{Choice, ControllerArgs, GraphArgs, Loaded, ScenarioArgs};

/// Evaluate a controller. Sitting: success, falls and minimum distance per zone, transition
/// matrices. Warehouse: phases completed per episode by start phase and a pick-up map over a
/// start grid. Toss: catch rate and return over a grid of throw speeds (the strike zone). Writes
/// report.md, a CSV, report.json and pictures, and records the worst episodes.
#[derive(Debug, clap::Args)]
pub struct EvalArgs {
    #[command(flatten)]
    scenario: ScenarioArgs,
    #[command(flatten)]
    graph: GraphArgs,
    #[command(flatten)]
    controller: ControllerArgs,
    /// Trials per zone (sitting, default 10000; the planner 100) or episodes (warehouse,
    /// default 200).
    #[arg(long)]
    trials: Option<usize>,
    /// Cells per side of the warehouse's pick-up map (default 9; 0: none) or of the toss's
    /// strike zone (default 7).
    #[arg(long)]
    grid: Option<usize>,
    /// Trials per grid cell.
    #[arg(long, default_value_t = 10)]
    grid_trials: usize,
    /// Half the side of the warehouse's start grid around the box's pedestal (m).
    #[arg(long, default_value_t = 4.0)]
    grid_half_m: f64,
    /// Zones (default: all of the scenario's).
    #[arg(long, value_delimiter = ',')]
    zones: Vec<String>,
    /// Trials run in parallel per batch.
    #[arg(long, default_value_t = 64)]
    batch: usize,
    /// Seed.
    #[arg(long, default_value_t = 2024)]
    seed: u64,
    /// Report folder (default: CONTROLLER/eval; CONTROLLER/eval-<choice> for a search or a gate;
    /// runs/planner-<scenario> for the planner).
    #[arg(long)]
    out: Option<PathBuf>,
    /// Record this many of the worst trials into <out>/worst/ (with replay pages when three.js
    /// is installed): sitting's failures with the largest distance, the warehouse's fewest
    /// phases, the toss's uncaught throws, then the lowest return; 0 records none.
    #[arg(long, default_value_t = 3)]
    worst: usize,
    /// Also record other episodes into <out>/successes/ or <out>/random/: `successes:N` (seated;
    /// the warehouse's most phases; the toss's catches) or `random:N` (drawn with the seed).
    /// Repeat for both.
    #[arg(long, value_parser = parse_pick)]
    record: Vec<Pick>,
    /// Evaluate a high level trained through this latent model (overrides the scenario's
    /// `low_level`).
    #[arg(long)]
    latent: Option<PathBuf>,
}

impl EvalArgs {
    /// The episodes to play in `setup`'s task, with each task's defaults.
    fn plan(&self, setup: &MetaSetup, choice: &Choice) -> EvalPlan {
        let per_cell = self.grid_trials;
        let (trials, pickup, strike_zone) = match setup.task {
            TaskSpec::Sit { .. } => {
                let default = if *choice == Choice::Planner { 100 } else { 10_000 };
                (self.trials.unwrap_or(default), None, (0, 0, 0))
            }
            TaskSpec::Warehouse(_) => {
                let n = self.grid.unwrap_or(9);
                let pickup = (n > 0).then_some(StartGrid { n, half_m: self.grid_half_m, trials: per_cell });
                (self.trials.unwrap_or(200), pickup, (0, 0, 0))
            }
            TaskSpec::Toss(_) => {
                let n = self.grid.unwrap_or(7).max(1);
                (0, None, (n, n, per_cell))
            }
        };
        EvalPlan {
            zones: super::zones_or_all(self.zones.clone(), &setup.model.scenario.scenario),
            trials,
            batch: self.batch,
            seed: self.seed,
            pickup,
            strike_zone,
        }
    }
}

/// `meta eval`.
pub fn eval(a: EvalArgs) -> Result<()> {
    if let Some((model, dir)) = super::latent_low_level(a.scenario.file.as_ref(), a.latent.clone())? {
        if a.controller.choice()? != Choice::Learned {
            bail!("--controller chooses among the skills: a latent low level has only its trained high level");
        }
        super::no_skill_options(&a.graph.chain, &a.graph.skills)?;
        let plan = EvalPlan {
            zones: super::zones_or_all(a.zones, &model.scenario.scenario),
            trials: a.trials.unwrap_or(10_000),
            batch: a.batch,
            seed: a.seed,
            pickup: None,
            strike_zone: (0, 0, 0),
        };
        let eval = super::LatentEval { library: a.scenario.library, meta: a.controller.meta, out: a.out };
        return super::eval_latent(model, &dir, eval, &plan, (Worst::Overall(a.worst), &a.record));
    }
    let setup = super::setup(a.scenario.file.as_ref(), &a.scenario.library, &a.graph.chain, &a.graph.skills)?;
    let loaded = Loaded::load(&a.controller, &setup, &a.scenario.library, a.seed)?;
    let plan = a.plan(&setup, &loaded.choice);
    let out = a.out.clone().unwrap_or_else(|| loaded.default_out(&setup));
    println!("{}\n", loaded.describe()?);
    evaluate_and_report(&setup, loaded.controller()?.as_ref(), &plan, (Worst::Overall(a.worst), &a.record), &out)?;
    Ok(())
}

/// `successes:N` or `random:N` of `--record`.
fn parse_pick(s: &str) -> std::result::Result<Pick, String> {
    let bad = || format!("`{s}`: expected successes:N or random:N (N episodes)");
    let (kind, n) = s.split_once(':').ok_or_else(bad)?;
    let n: usize = n.parse().map_err(|_| bad())?;
    match kind {
        "successes" => Ok(Pick::Successes(n)),
        "random" => Ok(Pick::Random(n)),
        _ => Err(bad()),
    }
}

/// Evaluates `loaded` as `plan` says, records the `worst` episodes and those `picks` choose,
/// prints the report and writes it into `out` (the report first, so a recording that fails
/// loses no evaluation).
pub fn evaluate_and_report<A: Arena>(
    setup: &Arc<A>,
    controller: &dyn Controller<A>,
    plan: &EvalPlan,
    (worst, picks): (Worst, &[Pick]),
    out: &Path,
) -> Result<TaskReport> {
    let started = Instant::now();
    let mut report = evaluate_task(setup, controller, plan)?;
    let seconds = started.elapsed().as_secs_f64();
    report.write(out)?;
    let recs = report.record_worst(setup, controller, plan, worst, out)?;
    if !recs.is_empty() {
        report.write(out)?;
    }
    print!("{}", report.markdown());
    println!("\n{} episodes in {seconds:.1} s; {} written to {}", report.episodes(), report.files(), out.display());
    crate::cli::replay::pages_beside(&recs);
    if !recs.is_empty() {
        println!(
            "{} worst episodes recorded in {} (watch: repertoire replay {})",
            recs.len(),
            out.join("worst").display(),
            out.display()
        );
    }
    for &pick in picks {
        let recs = report.record_picked(setup, controller, plan, pick, out)?;
        crate::cli::replay::pages_beside(&recs);
        let dir = out.join(pick.folder());
        println!("{} {} episodes recorded in {}", recs.len(), pick.folder(), dir.display());
    }
    Ok(report)
}
