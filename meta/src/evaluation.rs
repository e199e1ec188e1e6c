//! One evaluation for every task: [`evaluate_task`] plays a [`Controller`]'s episodes as the
//! scenario's task asks (sitting: trials per spawn zone; the warehouse: episodes by start phase
//! and a pick-up map; the toss: a strike zone of throw speeds) and returns the task's report as
//! a [`TaskReport`], which writes itself, prints itself and records its worst episodes again
//! ([`TaskReport::record_worst`]) for the replay page.

use std::path::{Path, PathBuf};
use std::sync::Arc;

use crate::controller::Controller;
use crate::env::MetaSetup;
use crate::error::{MetaError, Result};
use crate::eval::{MetaReport, evaluate, save_worst};
use crate::task::TaskSpec;
use crate::tasks::task_eval::{
    StartGrid, TossReport, WarehouseReport, evaluate_toss, evaluate_warehouse, save_worst_toss, save_worst_warehouse,
};

/// Which episodes an evaluation plays. Each task reads its own fields.
#[derive(Debug, Clone, PartialEq)]
pub struct EvalPlan {
    /// Sitting: the spawn zones, one after another.
    pub zones: Vec<String>,
    /// Sitting: trials per zone. The warehouse: episodes drawn as in training.
    pub trials: usize,
    /// Sitting: trials played in parallel per batch.
    pub batch: usize,
    /// The seed every episode's stream is drawn from.
    pub seed: u64,
    /// The warehouse: the pick-up map's start grid (`None`: no map).
    pub pickup: Option<StartGrid>,
    /// The toss: throw-speed cells along the throw, across it, and throws per cell.
    pub strike_zone: (usize, usize, usize),
}

/// Which of an evaluation's episodes are recorded again for watching.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Worst {
    /// The `n` worst of the whole evaluation.
    Overall(usize),
    /// Sitting: the `n` worst of each zone (the other tasks: the `n` worst).
    PerZone(usize),
}

impl Worst {
    fn count(self) -> usize {
        match self {
            Worst::Overall(n) | Worst::PerZone(n) => n,
        }
    }
}

/// An evaluation's report, as its task writes it.
#[derive(Debug, Clone)]
pub enum TaskReport {
    /// Sitting: success, falls and distance per zone, transitions, every trial.
    Sit(MetaReport),
    /// The warehouse: phases per episode by start phase, the pick-up map.
    Warehouse(WarehouseReport),
    /// The toss: catches and returns over the strike zone.
    Toss(TossReport),
}

/// Plays `controller`'s episodes in `setup`'s task as `plan` says. A controller that decides
/// in sitting scenarios only is refused on the others, naming the scenario.
pub fn evaluate_task(setup: &Arc<MetaSetup>, controller: &dyn Controller, plan: &EvalPlan) -> Result<TaskReport> {
    if controller.sitting_only() && !matches!(setup.task, TaskSpec::Sit { .. }) {
        return Err(MetaError::Invalid(format!(
            "{}: this controller decides in sitting scenarios only (this one is {})",
            setup.model.scenario.path.display(),
            setup.task.name()
        )));
    }
    Ok(match setup.task {
        TaskSpec::Sit { .. } => {
            TaskReport::Sit(evaluate(setup, controller, &plan.zones, plan.trials, plan.batch, plan.seed)?)
        }
        TaskSpec::Warehouse(_) => {
            TaskReport::Warehouse(evaluate_warehouse(setup, controller, plan.trials, plan.pickup, plan.seed)?)
        }
        TaskSpec::Toss(_) => {
            let (n_vx, n_lateral, per_cell) = plan.strike_zone;
            TaskReport::Toss(evaluate_toss(setup, controller, n_vx, n_lateral, per_cell, plan.seed)?)
        }
    })
}

impl TaskReport {
    /// Runs the `worst` episodes again, recorded, into `out/worst/`, checked to end as they
    /// did; the warehouse and toss reports list them (relative to `out`). Returns the files.
    pub fn record_worst(
        &mut self,
        setup: &Arc<MetaSetup>,
        controller: &dyn Controller,
        plan: &EvalPlan,
        worst: Worst,
        out: &Path,
    ) -> Result<Vec<PathBuf>> {
        let dir = out.join("worst");
        let (n, seed) = (worst.count(), plan.seed);
        match self {
            TaskReport::Sit(report) => {
                let per_zone = matches!(worst, Worst::PerZone(_));
                save_worst(setup, controller, report, &plan.zones, plan.trials, seed, n, per_zone, &dir)
            }
            TaskReport::Warehouse(report) => save_worst_warehouse(setup, controller, report, seed, n, &dir, out),
            TaskReport::Toss(report) => save_worst_toss(setup, controller, report, seed, n, &dir, out),
        }
    }

    /// The report as Markdown tables.
    pub fn markdown(&self) -> String {
        match self {
            TaskReport::Sit(r) => r.markdown(),
            TaskReport::Warehouse(r) => r.markdown(),
            TaskReport::Toss(r) => r.markdown(),
        }
    }

    /// Writes the report's files into `dir` (see [`TaskReport::files`]).
    pub fn write(&self, dir: &Path) -> Result<()> {
        match self {
            TaskReport::Sit(r) => r.write(dir),
            TaskReport::Warehouse(r) => r.write(dir),
            TaskReport::Toss(r) => r.write(dir),
        }
    }

    /// The files [`TaskReport::write`] writes, for a message.
    pub fn files(&self) -> &'static str {
        match self {
            TaskReport::Sit(_) => "report.md, trials.csv and report.json",
            TaskReport::Warehouse(_) => "report.md, trials.csv, report.json, pickup.png and goto.png",
            TaskReport::Toss(_) => "report.md, throws.csv, report.json and strike_zone.png",
        }
    }

    /// Episodes played.
    pub fn episodes(&self) -> usize {
        match self {
            TaskReport::Sit(r) => r.trials.len(),
            TaskReport::Warehouse(r) => r.trials.len(),
            TaskReport::Toss(r) => r.throws.len(),
        }
    }
}
