//! One evaluation for every task: [`evaluate_task`] plays a [`Controller`]'s episodes as the
//! scenario's task asks (sitting: trials per spawn zone; the warehouse: episodes by start phase
//! and a pick-up map; the toss: a strike zone of throw speeds) and returns the task's report as
//! a [`TaskReport`], which writes itself, prints itself and records its worst episodes again
//! ([`TaskReport::record_worst`]) for the replay page.

use std::path::{Path, PathBuf};
use std::sync::Arc;

use crate::controller::{Arena, Controller};
use crate::env::MetaSetup;
use crate::error::{MetaError, Result};
use crate::eval::{MetaReport, evaluate, record_trial, save_worst};
use crate::task::TaskSpec;
use crate::tasks::task_eval::{
    StartGrid, TossReport, WarehouseReport, evaluate_toss, evaluate_warehouse, record_toss, record_warehouse,
    save_worst_toss, save_worst_warehouse,
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

/// Episodes recorded again besides the worst: to watch what works, or an unbiased sample.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Pick {
    /// The first `n` that succeeded: seated (sitting), the most phases (the warehouse, at least
    /// one), caught (the toss, balls in the bucket first).
    Successes(usize),
    /// `n` drawn at random without replacement (seeded by the evaluation's seed).
    Random(usize),
}

impl Pick {
    /// The folder under the report folder its recordings go to.
    pub fn folder(self) -> &'static str {
        match self {
            Pick::Successes(_) => "successes",
            Pick::Random(_) => "random",
        }
    }
}

/// `n` of `0..len` drawn without replacement from `seed`, in increasing order.
fn drawn(len: usize, n: usize, seed: u64) -> Vec<usize> {
    use rand::SeedableRng;
    let mut rng = rand::rngs::StdRng::seed_from_u64(seed ^ 0x7265_636f_7264);
    let mut picked = rand::seq::index::sample(&mut rng, len, n.min(len)).into_vec();
    picked.sort_unstable();
    picked
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

/// Plays `controller`'s episodes in `setup`'s task as `plan` says, in any [`Arena`] (the object
/// tasks over the skills only). A controller that decides in sitting scenarios only is refused
/// on the others, naming the scenario.
pub fn evaluate_task<A: Arena>(setup: &Arc<A>, controller: &dyn Controller<A>, plan: &EvalPlan) -> Result<TaskReport> {
    if matches!(setup.task(), TaskSpec::Sit { .. }) {
        return Ok(TaskReport::Sit(evaluate(setup, controller, &plan.zones, plan.trials, plan.batch, plan.seed)?));
    }
    let (setup, controller) = skills_only(setup, controller)?;
    Ok(match setup.task {
        TaskSpec::Sit { .. } => unreachable!("sitting is played above"),
        TaskSpec::Warehouse(_) => {
            TaskReport::Warehouse(evaluate_warehouse(setup, controller, plan.trials, plan.pickup, plan.seed)?)
        }
        TaskSpec::Toss(_) => {
            let (n_vx, n_lateral, per_cell) = plan.strike_zone;
            TaskReport::Toss(evaluate_toss(setup, controller, n_vx, n_lateral, per_cell, plan.seed)?)
        }
    })
}

/// `setup` and `controller` as the skills' for an object task: refused for a controller that
/// decides in sitting scenarios only, or a low level other than the skills.
#[allow(clippy::type_complexity)]
fn skills_only<'a, A: Arena>(
    setup: &'a Arc<A>,
    controller: &'a dyn Controller<A>,
) -> Result<(&'a Arc<MetaSetup>, &'a dyn Controller)> {
    let refuse = |what: &str| {
        MetaError::Invalid(format!(
            "{}: {what} decides in sitting scenarios only (this one is {})",
            setup.model().scenario.path.display(),
            setup.task().name()
        ))
    };
    if controller.sitting_only() {
        return Err(refuse("this controller"));
    }
    A::skills(setup, controller).ok_or_else(|| refuse(&format!("the {}", setup.decider())))
}

impl TaskReport {
    /// Runs the `worst` episodes again, recorded, into `out/worst/`, checked to end as they
    /// did; the warehouse and toss reports list them (relative to `out`). Returns the files.
    pub fn record_worst<A: Arena>(
        &mut self,
        setup: &Arc<A>,
        controller: &dyn Controller<A>,
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
            TaskReport::Warehouse(report) => {
                let (setup, controller) = skills_only(setup, controller)?;
                save_worst_warehouse(setup, controller, report, seed, n, &dir, out)
            }
            TaskReport::Toss(report) => {
                let (setup, controller) = skills_only(setup, controller)?;
                save_worst_toss(setup, controller, report, seed, n, &dir, out)
            }
        }
    }

    /// Runs the episodes `pick` chooses again, recorded, into `out/<pick folder>/`, checked to
    /// end as they did. Returns the files.
    pub fn record_picked<A: Arena>(
        &self,
        setup: &Arc<A>,
        controller: &dyn Controller<A>,
        plan: &EvalPlan,
        pick: Pick,
        out: &Path,
    ) -> Result<Vec<PathBuf>> {
        let dir = out.join(pick.folder());
        let seed = plan.seed;
        match self {
            TaskReport::Sit(report) => {
                let chosen: Vec<&crate::eval::Trial> = match pick {
                    Pick::Successes(n) => report.trials.iter().filter(|t| t.success).take(n).collect(),
                    Pick::Random(n) => {
                        drawn(report.trials.len(), n, seed).into_iter().map(|i| &report.trials[i]).collect()
                    }
                };
                if !chosen.is_empty() {
                    std::fs::create_dir_all(&dir)
                        .map_err(|e| MetaError::Invalid(format!("{}: cannot create: {e}", dir.display())))?;
                }
                let mut written = Vec::new();
                for t in chosen {
                    let path = dir.join(format!("trial_{}_{}.rec", t.zone, t.index));
                    record_trial(setup, controller, &plan.zones, plan.trials, seed, t)?.save(&path)?;
                    written.push(path);
                }
                Ok(written)
            }
            TaskReport::Warehouse(report) => {
                let indices: Vec<usize> = match pick {
                    Pick::Successes(n) => {
                        let mut done: Vec<_> = report.trials.iter().filter(|t| t.phases > 0).collect();
                        done.sort_by(|a, b| b.phases.cmp(&a.phases).then(a.index.cmp(&b.index)));
                        done.iter().take(n).map(|t| t.index).collect()
                    }
                    Pick::Random(n) => {
                        drawn(report.trials.len(), n, seed).into_iter().map(|i| report.trials[i].index).collect()
                    }
                };
                let (setup, controller) = skills_only(setup, controller)?;
                record_warehouse(setup, controller, report, seed, &indices, &dir)
            }
            TaskReport::Toss(report) => {
                let indices: Vec<usize> = match pick {
                    Pick::Successes(n) => {
                        let mut caught: Vec<_> = report.throws.iter().filter(|t| t.caught).collect();
                        caught.sort_by(|a, b| b.delivered.cmp(&a.delivered).then(a.index.cmp(&b.index)));
                        caught.iter().take(n).map(|t| t.index).collect()
                    }
                    Pick::Random(n) => {
                        drawn(report.throws.len(), n, seed).into_iter().map(|i| report.throws[i].index).collect()
                    }
                };
                let (setup, controller) = skills_only(setup, controller)?;
                record_toss(setup, controller, report, seed, &indices, &dir)
            }
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
