//! Evaluating a meta-controller on the warehouse and the toss (Catch & Carry's figures):
//! warehouse phases completed per episode by start phase, and a pick-up success map over a grid
//! of start positions around the box's pedestal; toss catch rate and return over a grid of ball
//! speeds (the paper's "strike zone"). Every episode is seeded by its index, so a report is
//! reproducible; each is written as Markdown, CSV, JSON and PNG/SVG maps. The worst episodes
//! (fewest phases, or no catch, then the lowest return) can be run again recorded
//! ([`save_worst_warehouse`], [`save_worst_toss`]) and watched in the browser replay.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::sync::Arc;

use rand::SeedableRng;
use rayon::prelude::*;
use repertoire_learn::env::{Env, EnvRng};
use repertoire_report::grid_map;
use repertoire_scenes::Recording;
use repertoire_scenes::scenario::WarehousePhase;
use serde::{Deserialize, Serialize};

use crate::controller::Controller;
use crate::env::{MetaEnv, MetaSetup};
use crate::error::{MetaError, Result};
use crate::task::{EpisodeOverride, TaskSpec, TaskState};

/// How one episode ended.
#[derive(Debug, Clone)]
struct Ended {
    task: TaskState,
    fell: bool,
    fall_cause: Option<String>,
    seconds: f64,
    episode_return: f64,
}

/// Runs one episode with `controller`, starting as `over` says, on rng
/// stream `stream` of `seed`.
fn run_episode(
    setup: &Arc<MetaSetup>,
    controller: &dyn Controller,
    over: EpisodeOverride,
    seed: u64,
    stream: u64,
) -> Ended {
    run_recorded(setup, controller, over, seed, stream, None).0
}

/// [`run_episode`], recorded at the control rate under `title` when one is given.
fn run_recorded(
    setup: &Arc<MetaSetup>,
    controller: &dyn Controller,
    over: EpisodeOverride,
    seed: u64,
    stream: u64,
    title: Option<String>,
) -> (Ended, Option<Recording>) {
    let mut env = MetaEnv::new(Arc::clone(setup));
    if let Some(title) = title {
        env.record_episodes(title);
    }
    env.set_override(over);
    let mut ctl = controller.start(setup);
    let mut rng = EnvRng::seed_from_u64(seed);
    rng.set_stream(stream);
    let mut obs = vec![0.0; env.obs_dim()];
    let mut act = vec![0.0; env.act_dim()];
    let mut mask = vec![true; setup.skills.len()];
    env.reset(&mut rng, &mut obs);
    let mut episode_return = 0.0;
    loop {
        ctl.act(&env, &obs, &mut mask, &mut act);
        let out = env.step(&act, &mut obs);
        episode_return += f64::from(out.reward);
        if out.terminated || out.truncated {
            let ended = Ended {
                task: env.task().clone(),
                fell: out.terms[2] > 0.5,
                fall_cause: crate::eval::fall_cause(out.terms[2]),
                seconds: f64::from(out.terms[3]),
                episode_return,
            };
            return (ended, env.recording());
        }
    }
}

/// Centres of `n` equal cells spanning `[lo, hi]`.
fn centres(lo: f64, hi: f64, n: usize) -> Vec<f64> {
    (0..n).map(|i| lo + (hi - lo) * (i as f64 + 0.5) / n as f64).collect()
}

fn mean_sd(values: &[f64]) -> (f64, f64) {
    let n = values.len().max(1) as f64;
    let mean = values.iter().sum::<f64>() / n;
    let var = values.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / (n - 1.0).max(1.0);
    (mean, var.sqrt())
}

fn write_files(dir: &Path, files: &[(&str, String)]) -> Result<()> {
    let err = |e: std::io::Error| MetaError::Invalid(format!("{}: {e}", dir.display()));
    std::fs::create_dir_all(dir).map_err(err)?;
    for (name, text) in files {
        repertoire_files::write_atomic(&dir.join(name), text.as_bytes())
            .map_err(|e| MetaError::Invalid(e.to_string()))?;
    }
    Ok(())
}

/// Start cells closer than this to the pedestal's centre are on it and not run (m).
pub const PEDESTAL_CLEARANCE_M: f64 = 0.5;

/// A square grid of start positions around a prop: `n × n` cells over ±`half_m` metres.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct StartGrid {
    /// Cells per side.
    pub n: usize,
    /// Half the side length (m).
    pub half_m: f64,
    /// Trials per cell.
    pub trials: usize,
}

/// One warehouse episode.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct WarehouseTrial {
    /// Episode index (its seed stream).
    pub index: usize,
    /// Phase it started in.
    pub start_phase: String,
    /// Phases completed.
    pub phases: u32,
    /// Ended by a fall.
    pub fell: bool,
    /// Why, by the fall test.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub fall_cause: Option<String>,
    /// Ended by the box touching the floor.
    pub dropped: bool,
    /// Seconds simulated.
    pub seconds: f64,
    /// Sum of rewards.
    pub episode_return: f64,
}

/// Phases per episode for one start phase (or `all`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct PhaseRow {
    /// Start phase (`GOTO`, …, `all`).
    pub start_phase: String,
    /// Episodes.
    pub episodes: usize,
    /// Mean phases completed per episode.
    pub phases_mean: f64,
    /// Their standard deviation.
    pub phases_sd: f64,
    /// Fall rate.
    pub fall_rate: f64,
    /// Box-drop rate.
    pub drop_rate: f64,
}

/// Pick-up success (GOTO and LIFT completed from a GOTO start) per start cell.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct PickupMap {
    /// The grid.
    pub grid: StartGrid,
    /// Cell centres along the pedestal's x (its front), m.
    pub xs: Vec<f64>,
    /// Cell centres along its y (its left), m.
    pub ys: Vec<f64>,
    /// `successes[i][j]`: pick-ups at `ys[i]`, `xs[j]` out of `grid.trials`; `None` for cells
    /// on the pedestal itself (closer than [`PEDESTAL_CLEARANCE_M`] to its centre), not run.
    pub successes: Vec<Vec<Option<usize>>>,
    /// `reached[i][j]`: episodes from that cell that completed GOTO (came within reach of the
    /// pedestal), the first half of a pick-up.
    pub reached: Vec<Vec<Option<usize>>>,
}

/// The warehouse evaluation.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct WarehouseReport {
    /// Rows per start phase, then `all`.
    pub rows: Vec<PhaseRow>,
    /// Every episode of the phase table.
    pub trials: Vec<WarehouseTrial>,
    /// The pick-up map, when asked for.
    pub pickup: Option<PickupMap>,
    /// Recordings of the worst episodes, relative to the report's folder (see
    /// [`save_worst_warehouse`]).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub recorded: Vec<String>,
}

/// Runs `episodes` warehouse episodes drawn as in training (start phases included) and, with
/// `grid`, the pick-up map: GOTO starts at each cell's centre in the box pedestal's frame, facing
/// it turned at random.
pub fn evaluate_warehouse(
    setup: &Arc<MetaSetup>,
    controller: &dyn Controller,
    episodes: usize,
    grid: Option<StartGrid>,
    seed: u64,
) -> Result<WarehouseReport> {
    let TaskSpec::Warehouse(_) = &setup.task else {
        return Err(MetaError::Invalid(format!("{} is not a warehouse scenario", setup.model.scenario.path.display())));
    };
    let trials: Vec<WarehouseTrial> = (0..episodes)
        .into_par_iter()
        .map(|i| {
            let e = run_episode(setup, controller, EpisodeOverride::default(), seed, i as u64 + 1);
            let TaskState::Warehouse(j) = &e.task else { unreachable!("a warehouse setup") };
            WarehouseTrial {
                index: i,
                start_phase: j.start_phase.label().to_string(),
                phases: j.completed,
                fell: e.fell,
                fall_cause: e.fall_cause.clone(),
                dropped: j.dropped,
                seconds: e.seconds,
                episode_return: e.episode_return,
            }
        })
        .collect();
    let row = |label: &str, ts: &[&WarehouseTrial]| {
        let n = ts.len().max(1) as f64;
        let (phases_mean, phases_sd) = mean_sd(&ts.iter().map(|t| f64::from(t.phases)).collect::<Vec<_>>());
        PhaseRow {
            start_phase: label.to_string(),
            episodes: ts.len(),
            phases_mean,
            phases_sd,
            fall_rate: ts.iter().filter(|t| t.fell).count() as f64 / n,
            drop_rate: ts.iter().filter(|t| t.dropped).count() as f64 / n,
        }
    };
    let mut rows: Vec<PhaseRow> = WarehousePhase::ALL
        .iter()
        .map(|p| row(p.label(), &trials.iter().filter(|t| t.start_phase == p.label()).collect::<Vec<_>>()))
        .filter(|r| r.episodes > 0)
        .collect();
    rows.push(row("all", &trials.iter().collect::<Vec<_>>()));

    let pickup = grid.map(|g| {
        let xs = centres(-g.half_m, g.half_m, g.n);
        let ys = xs.clone();
        let open = |i: usize, j: usize| xs[j].hypot(ys[i]) >= PEDESTAL_CLEARANCE_M;
        let cells: Vec<(usize, usize, usize)> = (0..g.n)
            .flat_map(|i| (0..g.n).flat_map(move |j| (0..g.trials).map(move |k| (i, j, k))))
            .filter(|&(i, j, _)| open(i, j))
            .collect();
        let outcomes: Vec<(usize, usize, u32)> = cells
            .into_par_iter()
            .map(|(i, j, k)| {
                let stream = 1_000_000 + ((i * g.n + j) * g.trials + k) as u64;
                // A random turn away from facing the pedestal, drawn from the episode's stream.
                let turn = {
                    let mut r = EnvRng::seed_from_u64(seed ^ 0x9e37_79b9);
                    r.set_stream(stream);
                    rand::Rng::random_range(&mut r, -std::f64::consts::PI..std::f64::consts::PI)
                };
                let over = EpisodeOverride {
                    start: Some((xs[j], ys[i], turn)),
                    phase: Some(WarehousePhase::Goto),
                    throw: None,
                };
                let e = run_episode(setup, controller, over, seed, stream);
                let TaskState::Warehouse(judge) = &e.task else { unreachable!("a warehouse setup") };
                (i, j, judge.completed)
            })
            .collect();
        let mut successes: Vec<Vec<Option<usize>>> =
            (0..g.n).map(|i| (0..g.n).map(|j| open(i, j).then_some(0)).collect()).collect();
        let mut reached = successes.clone();
        for (i, j, phases) in outcomes {
            if let Some(k) = successes[i][j].as_mut() {
                *k += usize::from(phases >= 2);
            }
            if let Some(k) = reached[i][j].as_mut() {
                *k += usize::from(phases >= 1);
            }
        }
        PickupMap { grid: g, xs, ys, successes, reached }
    });
    Ok(WarehouseReport { rows, trials, pickup, recorded: Vec::new() })
}

/// The `n` worst episodes of the phase table: fewest phases completed, then the lowest return
/// (then the lowest index).
pub fn worst_warehouse(report: &WarehouseReport, n: usize) -> Vec<&WarehouseTrial> {
    let mut sorted: Vec<&WarehouseTrial> = report.trials.iter().collect();
    sorted.sort_by(|a, b| {
        a.phases.cmp(&b.phases).then(a.episode_return.total_cmp(&b.episode_return)).then(a.index.cmp(&b.index))
    });
    sorted.truncate(n);
    sorted
}

/// Runs the `n` worst episodes of `report` (an [`evaluate_warehouse`] with `seed`) again,
/// recorded, into `dir` as `<start phase>_<index>.rec`, and lists them in the report
/// (`recorded`, relative to `report_dir`); a rerun that ends differently is an error. Returns
/// the files written.
pub fn save_worst_warehouse(
    setup: &Arc<MetaSetup>,
    controller: &dyn Controller,
    report: &mut WarehouseReport,
    seed: u64,
    n: usize,
    dir: &Path,
    report_dir: &Path,
) -> Result<Vec<PathBuf>> {
    let worst: Vec<usize> = worst_warehouse(report, n).into_iter().map(|t| t.index).collect();
    let written = record_warehouse(setup, controller, report, seed, &worst, dir)?;
    report.recorded = relative(&written, report_dir);
    Ok(written)
}

/// Runs the episodes `indices` of `report` (an [`evaluate_warehouse`] with `seed`) again,
/// recorded, into `dir` as `<start phase>_<index>.rec`; a rerun that ends differently is an
/// error. Returns the files written.
pub fn record_warehouse(
    setup: &Arc<MetaSetup>,
    controller: &dyn Controller,
    report: &WarehouseReport,
    seed: u64,
    indices: &[usize],
    dir: &Path,
) -> Result<Vec<PathBuf>> {
    let mut written = Vec::new();
    for t in indices.iter().filter_map(|&i| report.trials.iter().find(|t| t.index == i)) {
        let title = format!(
            "warehouse, episode {} from {} (seed {seed}): {} phase{}",
            t.index,
            t.start_phase,
            t.phases,
            if t.phases == 1 { "" } else { "s" }
        );
        let stream = t.index as u64 + 1;
        let (e, rec) = run_recorded(setup, controller, EpisodeOverride::default(), seed, stream, Some(title));
        let TaskState::Warehouse(j) = &e.task else { unreachable!("a warehouse setup") };
        if j.completed != t.phases || e.fell != t.fell || (e.episode_return - t.episode_return).abs() > 1e-6 {
            return Err(MetaError::Invalid(format!(
                "warehouse episode {} did not replay the same ({} phases, return {:.3}; then {}, {:.3})",
                t.index, t.phases, t.episode_return, j.completed, e.episode_return
            )));
        }
        let rec = rec.ok_or_else(|| MetaError::Invalid("the rerun was not recorded".into()))?;
        written.push(save_recording(rec, dir, &format!("{}_{}.rec", t.start_phase.to_lowercase(), t.index))?);
    }
    Ok(written)
}

/// Saves `rec` as `dir/name` (created when missing; written atomically).
fn save_recording(rec: Recording, dir: &Path, name: &str) -> Result<PathBuf> {
    std::fs::create_dir_all(dir).map_err(|e| MetaError::Invalid(format!("{}: cannot create: {e}", dir.display())))?;
    let path = dir.join(name);
    rec.save(&path)?;
    Ok(path)
}

/// `files` relative to `base` where they lie under it, else as given.
pub fn relative(files: &[PathBuf], base: &Path) -> Vec<String> {
    files.iter().map(|f| f.strip_prefix(base).unwrap_or(f).display().to_string()).collect()
}

impl WarehouseReport {
    /// The report as Markdown: phases per episode by start phase, then the pick-up grid.
    pub fn markdown(&self) -> String {
        let mut s = String::new();
        let _ = writeln!(s, "| start phase | episodes | phases completed per episode | falls | box drops |");
        let _ = writeln!(s, "|---|---:|---:|---:|---:|");
        for r in &self.rows {
            let _ = writeln!(
                s,
                "| {} | {} | {:.2} ± {:.2} | {:.1}% | {:.1}% |",
                r.start_phase,
                r.episodes,
                r.phases_mean,
                r.phases_sd,
                100.0 * r.fall_rate,
                100.0 * r.drop_rate
            );
        }
        if let Some(causes) = crate::eval::fall_causes(self.trials.iter().map(|t| t.fall_cause.as_deref())) {
            let _ = writeln!(s, "\nfalls by cause (the shared fall test): {causes}");
        }
        if let Some(p) = &self.pickup {
            for (what, counts) in [
                ("pick-up success (GOTO + LIFT from a GOTO start)", &p.successes),
                ("GOTO reached (within reach of the pedestal)", &p.reached),
            ] {
                let total: usize = counts.iter().flatten().flatten().sum();
                let n = counts.iter().flatten().flatten().count() * p.grid.trials;
                let _ = writeln!(
                    s,
                    "\n{what} by start position in the pedestal's frame: {total}/{n} ({:.1}%); rows: y (its \
                     left, m), columns: x (its front, m)\n",
                    100.0 * total as f64 / n.max(1) as f64
                );
                let _ = writeln!(
                    s,
                    "| y \\ x | {} |",
                    p.xs.iter().map(|x| format!("{x:.2}")).collect::<Vec<_>>().join(" | ")
                );
                let _ = writeln!(s, "|---|{}", "---:|".repeat(p.xs.len()));
                for (i, y) in p.ys.iter().enumerate().rev() {
                    let cells: Vec<String> = counts[i]
                        .iter()
                        .map(|k| k.map_or_else(|| "pedestal".to_string(), |k| format!("{k}/{}", p.grid.trials)))
                        .collect();
                    let _ = writeln!(s, "| {y:.2} | {} |", cells.join(" | "));
                }
            }
        }
        if !self.recorded.is_empty() {
            let _ = writeln!(
                s,
                "\nworst episodes (fewest phases, then lowest return), recorded (watch: `repertoire replay FILE`):\n"
            );
            let _ = writeln!(s, "| recording | start phase | phases | return | seconds | fell | box dropped |");
            let _ = writeln!(s, "|---|---|---:|---:|---:|---|---|");
            for (file, t) in self.recorded.iter().zip(worst_warehouse(self, self.recorded.len())) {
                let _ = writeln!(
                    s,
                    "| {file} | {} | {} | {:.2} | {:.2} | {} | {} |",
                    t.start_phase, t.phases, t.episode_return, t.seconds, t.fell, t.dropped
                );
            }
        }
        s
    }

    /// Writes `report.md`, `trials.csv`, `report.json` and, with a pick-up map,
    /// `pickup.png`/`.svg` and `goto.png`/`.svg` into `dir`.
    pub fn write(&self, dir: &Path) -> Result<()> {
        let mut csv = String::from("index,start_phase,phases,fell,dropped,seconds,return,fall_cause\n");
        for t in &self.trials {
            let _ = writeln!(
                csv,
                "{},{},{},{},{},{:.2},{:.3},{}",
                t.index,
                t.start_phase,
                t.phases,
                t.fell,
                t.dropped,
                t.seconds,
                t.episode_return,
                t.fall_cause.as_deref().unwrap_or("")
            );
        }
        let json = serde_json::to_string_pretty(self).expect("a report is plain data");
        write_files(dir, &[("report.md", self.markdown()), ("trials.csv", csv), ("report.json", json)])?;
        self.plot(dir).map(|_| ())
    }

    /// Draws the pick-up and GOTO maps (`pickup`, `goto` as PNG + SVG) into `dir`; returns the
    /// stems drawn (none without a pick-up map).
    pub fn plot(&self, dir: &Path) -> Result<Vec<std::path::PathBuf>> {
        let mut stems = Vec::new();
        if let Some(p) = &self.pickup {
            for (stem, title, counts) in [
                ("pickup", "pick-up success by start position (pedestal at the origin, facing +x)", &p.successes),
                ("goto", "GOTO reached by start position (pedestal at the origin, facing +x)", &p.reached),
            ] {
                let cells: Vec<Vec<(Option<f64>, usize)>> = counts
                    .iter()
                    .map(|row| {
                        row.iter()
                            .map(|k| match k {
                                Some(k) => (Some(*k as f64 / p.grid.trials.max(1) as f64), p.grid.trials),
                                None => (None, 0),
                            })
                            .collect()
                    })
                    .collect();
                grid_map(
                    &dir.join(stem),
                    title,
                    "x: in front of the pedestal (m)",
                    "y: to its left (m)",
                    &p.xs,
                    &p.ys,
                    &cells,
                )
                .map_err(|e| MetaError::Invalid(e.to_string()))?;
                stems.push(dir.join(stem));
            }
        }
        Ok(stems)
    }
}

/// One toss episode.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct TossTrial {
    /// Episode index (its seed stream).
    pub index: usize,
    /// Forward ball speed (m/s).
    pub v_x: f64,
    /// Sideways ball speed (m/s).
    pub lateral: f64,
    /// Caught (both hands on the ball, off the floor).
    pub caught: bool,
    /// The ball reached the bucket.
    pub delivered: bool,
    /// The ball touched the floor.
    pub dropped: bool,
    /// Ended by a fall.
    pub fell: bool,
    /// Why, by the fall test.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub fall_cause: Option<String>,
    /// Sum of rewards.
    pub episode_return: f64,
}

/// The toss evaluation: a grid of throw speeds, `trials` throws per cell.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct TossReport {
    /// Forward speeds, cell centres (m/s).
    pub v_x: Vec<f64>,
    /// Sideways speeds, cell centres (m/s).
    pub lateral: Vec<f64>,
    /// Throws per cell.
    pub trials: usize,
    /// Every throw.
    pub throws: Vec<TossTrial>,
    /// Recordings of the worst throws, relative to the report's folder (see
    /// [`save_worst_toss`]).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub recorded: Vec<String>,
}

/// Throws `trials` balls at each of `n_vx × n_lateral` speed cells spanning the scenario's
/// ranges (the strike zone), the rest of each throw drawn.
pub fn evaluate_toss(
    setup: &Arc<MetaSetup>,
    controller: &dyn Controller,
    n_vx: usize,
    n_lateral: usize,
    trials: usize,
    seed: u64,
) -> Result<TossReport> {
    let TaskSpec::Toss(t) = &setup.task else {
        return Err(MetaError::Invalid(format!("{} is not a toss scenario", setup.model.scenario.path.display())));
    };
    let v_x = centres(t.throw.v_x.min(), t.throw.v_x.max(), n_vx.max(1));
    let lateral = centres(t.throw.lateral.min(), t.throw.lateral.max(), n_lateral.max(1));
    let cells: Vec<(usize, f64, f64)> = v_x
        .iter()
        .flat_map(|&v| lateral.iter().map(move |&l| (v, l)))
        .flat_map(|(v, l)| (0..trials).map(move |k| (k, v, l)))
        .enumerate()
        .map(|(i, (_, v, l))| (i, v, l))
        .collect();
    let throws = cells
        .into_par_iter()
        .map(|(i, v, l)| {
            let over = EpisodeOverride { throw: Some((v, l)), ..Default::default() };
            let e = run_episode(setup, controller, over, seed, i as u64 + 1);
            let TaskState::Toss(j) = &e.task else { unreachable!("a toss setup") };
            TossTrial {
                index: i,
                v_x: v,
                lateral: l,
                caught: j.caught,
                delivered: j.delivered(),
                dropped: j.dropped,
                fell: e.fell,
                fall_cause: e.fall_cause.clone(),
                episode_return: e.episode_return,
            }
        })
        .collect();
    Ok(TossReport { v_x, lateral, trials, throws, recorded: Vec::new() })
}

/// The `n` worst throws: not caught before caught, then the lowest return (then the lowest
/// index).
pub fn worst_toss(report: &TossReport, n: usize) -> Vec<&TossTrial> {
    let mut sorted: Vec<&TossTrial> = report.throws.iter().collect();
    sorted.sort_by(|a, b| {
        a.caught.cmp(&b.caught).then(a.episode_return.total_cmp(&b.episode_return)).then(a.index.cmp(&b.index))
    });
    sorted.truncate(n);
    sorted
}

/// Throws the `n` worst throws of `report` (an [`evaluate_toss`] with `seed`) again, recorded,
/// into `dir` as `throw_<index>.rec`, and lists them in the report (`recorded`, relative to
/// `report_dir`); a rerun that ends differently is an error. Returns the files written.
pub fn save_worst_toss(
    setup: &Arc<MetaSetup>,
    controller: &dyn Controller,
    report: &mut TossReport,
    seed: u64,
    n: usize,
    dir: &Path,
    report_dir: &Path,
) -> Result<Vec<PathBuf>> {
    let worst: Vec<usize> = worst_toss(report, n).into_iter().map(|t| t.index).collect();
    let written = record_toss(setup, controller, report, seed, &worst, dir)?;
    report.recorded = relative(&written, report_dir);
    Ok(written)
}

/// Throws the throws `indices` of `report` (an [`evaluate_toss`] with `seed`) again, recorded,
/// into `dir` as `throw_<index>.rec`; a rerun that ends differently is an error. Returns the
/// files written.
pub fn record_toss(
    setup: &Arc<MetaSetup>,
    controller: &dyn Controller,
    report: &TossReport,
    seed: u64,
    indices: &[usize],
    dir: &Path,
) -> Result<Vec<PathBuf>> {
    let mut written = Vec::new();
    for t in indices.iter().filter_map(|&i| report.throws.iter().find(|t| t.index == i)) {
        let title =
            format!("toss, throw {} (seed {seed}): v_x {:.2} m/s, lateral {:.2} m/s", t.index, t.v_x, t.lateral);
        let over = EpisodeOverride { throw: Some((t.v_x, t.lateral)), ..Default::default() };
        let (e, rec) = run_recorded(setup, controller, over, seed, t.index as u64 + 1, Some(title));
        let TaskState::Toss(j) = &e.task else { unreachable!("a toss setup") };
        if j.caught != t.caught || e.fell != t.fell || (e.episode_return - t.episode_return).abs() > 1e-6 {
            return Err(MetaError::Invalid(format!(
                "throw {} did not replay the same (return {:.3}, then {:.3})",
                t.index, t.episode_return, e.episode_return
            )));
        }
        let rec = rec.ok_or_else(|| MetaError::Invalid("the rerun was not recorded".into()))?;
        written.push(save_recording(rec, dir, &format!("throw_{}.rec", t.index))?);
    }
    Ok(written)
}

impl TossReport {
    /// Throws of cell (`v_x[a]`, `lateral[b]`).
    fn cell(&self, a: usize, b: usize) -> Vec<&TossTrial> {
        self.throws.iter().filter(|t| t.v_x == self.v_x[a] && t.lateral == self.lateral[b]).collect()
    }

    fn rate(ts: &[&TossTrial], f: impl Fn(&TossTrial) -> bool) -> f64 {
        ts.iter().filter(|t| f(t)).count() as f64 / ts.len().max(1) as f64
    }

    /// The report as Markdown: overall rates, then catch rate and mean return per cell.
    pub fn markdown(&self) -> String {
        let all: Vec<&TossTrial> = self.throws.iter().collect();
        let mut s = String::new();
        let _ = writeln!(s, "| throws | caught | in the bucket | ball dropped | falls | mean return |");
        let _ = writeln!(s, "|---:|---:|---:|---:|---:|---:|");
        let (ret, sd) = mean_sd(&all.iter().map(|t| t.episode_return).collect::<Vec<_>>());
        let _ = writeln!(
            s,
            "| {} | {:.1}% | {:.1}% | {:.1}% | {:.1}% | {ret:.2} ± {sd:.2} |",
            all.len(),
            100.0 * Self::rate(&all, |t| t.caught),
            100.0 * Self::rate(&all, |t| t.delivered),
            100.0 * Self::rate(&all, |t| t.dropped),
            100.0 * Self::rate(&all, |t| t.fell)
        );
        if let Some(causes) = crate::eval::fall_causes(all.iter().map(|t| t.fall_cause.as_deref())) {
            let _ = writeln!(s, "\nfalls by cause (the shared fall test): {causes}");
        }
        for (title, value) in [("catch rate", true), ("mean return", false)] {
            let _ = writeln!(
                s,
                "\n{title} by throw (rows: lateral speed m/s, columns: forward speed v_x m/s; {} throws per cell)\n",
                self.trials
            );
            let _ = writeln!(
                s,
                "| lateral \\ v_x | {} |",
                self.v_x.iter().map(|v| format!("{v:.2}")).collect::<Vec<_>>().join(" | ")
            );
            let _ = writeln!(s, "|---|{}", "---:|".repeat(self.v_x.len()));
            for b in (0..self.lateral.len()).rev() {
                let cells: Vec<String> = (0..self.v_x.len())
                    .map(|a| {
                        let ts = self.cell(a, b);
                        if value {
                            format!("{:.0}%", 100.0 * Self::rate(&ts, |t| t.caught))
                        } else {
                            format!("{:.2}", mean_sd(&ts.iter().map(|t| t.episode_return).collect::<Vec<_>>()).0)
                        }
                    })
                    .collect();
                let _ = writeln!(s, "| {:.2} | {} |", self.lateral[b], cells.join(" | "));
            }
        }
        if !self.recorded.is_empty() {
            let _ = writeln!(
                s,
                "\nworst throws (not caught, then lowest return), recorded (watch: `repertoire replay FILE`):\n"
            );
            let _ = writeln!(s, "| recording | v_x | lateral | caught | return | ball dropped | fell |");
            let _ = writeln!(s, "|---|---:|---:|---|---:|---|---|");
            for (file, t) in self.recorded.iter().zip(worst_toss(self, self.recorded.len())) {
                let _ = writeln!(
                    s,
                    "| {file} | {:.2} | {:.2} | {} | {:.2} | {} | {} |",
                    t.v_x, t.lateral, t.caught, t.episode_return, t.dropped, t.fell
                );
            }
        }
        s
    }

    /// Writes `report.md`, `throws.csv`, `report.json` and `strike_zone.png`/`.svg` into `dir`.
    pub fn write(&self, dir: &Path) -> Result<()> {
        let mut csv = String::from("index,v_x,lateral,caught,delivered,dropped,fell,return,fall_cause\n");
        for t in &self.throws {
            let _ = writeln!(
                csv,
                "{},{:.3},{:.3},{},{},{},{},{:.3},{}",
                t.index,
                t.v_x,
                t.lateral,
                t.caught,
                t.delivered,
                t.dropped,
                t.fell,
                t.episode_return,
                t.fall_cause.as_deref().unwrap_or("")
            );
        }
        let json = serde_json::to_string_pretty(self).expect("a report is plain data");
        write_files(dir, &[("report.md", self.markdown()), ("throws.csv", csv), ("report.json", json)])?;
        self.plot(dir).map(|_| ())
    }

    /// Draws the strike zone's catch rates (`strike_zone` as PNG + SVG) into `dir`; returns the
    /// stem drawn.
    pub fn plot(&self, dir: &Path) -> Result<std::path::PathBuf> {
        let cells: Vec<Vec<(Option<f64>, usize)>> = (0..self.lateral.len())
            .map(|b| {
                (0..self.v_x.len())
                    .map(|a| {
                        let ts = self.cell(a, b);
                        ((!ts.is_empty()).then(|| Self::rate(&ts, |t| t.caught)), ts.len())
                    })
                    .collect()
            })
            .collect();
        grid_map(
            &dir.join("strike_zone"),
            "catch rate by throw (the strike zone)",
            "v_x: ball speed towards the walker (m/s)",
            "lateral speed (m/s)",
            &self.v_x,
            &self.lateral,
            &cells,
        )
        .map_err(|e| MetaError::Invalid(e.to_string()))?;
        Ok(dir.join("strike_zone"))
    }
}
