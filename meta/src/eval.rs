//! Evaluating a meta-controller: seeded trials in parallel from chosen zones; success rate and
//! minimum pelvis-to-seat distance (mean ± sd) per zone; skill transition matrices split by the
//! side of the chair the character started on; Markdown, CSV and JSON reports.

use std::fmt::Write as _;
use std::path::Path;
use std::sync::Arc;

use rand::SeedableRng;
use rayon::prelude::*;
use repertoire_learn::acting::ActingHybrid;
use repertoire_learn::env::{Env, EnvRng};
use repertoire_report::{StartPoint, success_map, transition_matrix};
use serde::{Deserialize, Serialize};

use crate::env::{MetaEnv, MetaSetup};
use crate::error::{MetaError, Result};

/// One trial's outcome.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Trial {
    /// Trial index (its seed stream).
    pub index: usize,
    /// Spawn zone.
    pub zone: String,
    /// Start position and heading.
    pub start: (f64, f64, f64),
    /// Start position in the chair's frame (x: in front of it, y: its left).
    pub local_start: (f64, f64),
    /// Which side of the chair it started on (`left`, `right`, seen from the chair).
    pub side: String,
    /// 3 s of unbroken seat contact reached.
    pub success: bool,
    /// Ended by a fall.
    pub fell: bool,
    /// Smallest pelvis-to-seat distance (m).
    pub min_distance: f64,
    /// Seconds simulated.
    pub seconds: f64,
    /// Skills in the order chosen.
    pub skills: Vec<String>,
}

/// Per-zone figures.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ZoneRow {
    /// Zone.
    pub zone: String,
    /// Trials.
    pub trials: usize,
    /// Success rate.
    pub success_rate: f64,
    /// Fall rate.
    pub fall_rate: f64,
    /// Mean minimum distance (m).
    pub min_distance_mean: f64,
    /// Its standard deviation.
    pub min_distance_sd: f64,
}

/// The whole evaluation.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct MetaReport {
    /// Rows per zone, then `all`.
    pub zones: Vec<ZoneRow>,
    /// Skill names, in matrix order (`start` is the extra first row).
    pub skills: Vec<String>,
    /// Transition counts per side: `[from (start first)][to]`.
    pub transitions: Vec<(String, Vec<Vec<u32>>)>,
    /// Every trial.
    pub trials: Vec<Trial>,
}

/// Runs `trials` trials per zone in `zones` with `controller`, `batch` environments in parallel.
pub fn evaluate(
    setup: &Arc<MetaSetup>,
    controller: &ActingHybrid,
    zones: &[String],
    trials: usize,
    batch: usize,
    seed: u64,
) -> Result<MetaReport> {
    for z in zones {
        if !setup.model.scenario.scenario.spawn.iter().any(|s| &s.name == z) {
            return Err(MetaError::Invalid(format!("no spawn zone `{z}` in {}", setup.model.scenario.path.display())));
        }
    }
    let names: Vec<String> = setup.skills.iter().map(|s| s.name.clone()).collect();
    let k = names.len();
    let mut all = Vec::new();
    for (zi, zone) in zones.iter().enumerate() {
        *setup.zones.write().expect("never poisoned") = vec![zone.clone()];
        let chunks: Vec<Vec<Trial>> = (0..trials)
            .collect::<Vec<_>>()
            .chunks(batch.max(1))
            .map(|chunk| {
                chunk
                    .par_iter()
                    .map(|&i| {
                        let mut env = MetaEnv::new(Arc::clone(setup));
                        let mut ctl = controller.clone();
                        let mut rng = EnvRng::seed_from_u64(seed);
                        rng.set_stream((zi * trials + i) as u64 + 1);
                        let mut obs = vec![0.0; env.obs_dim()];
                        let mut act = vec![0.0; env.act_dim()];
                        let mut mask = vec![true; k];
                        env.reset(&mut rng, &mut obs);
                        loop {
                            env.option_mask(&mut mask);
                            ctl.act(&obs, &mask, &mut act);
                            let out = env.step(&act, &mut obs);
                            if out.terminated || out.truncated {
                                return trial_of(setup, &env, i, zone, &out.terms, &names);
                            }
                        }
                    })
                    .collect()
            })
            .collect();
        all.extend(chunks.into_iter().flatten());
    }
    Ok(report(zones, names, all))
}

fn trial_of(setup: &MetaSetup, env: &MetaEnv, index: usize, zone: &str, terms: &[f32], names: &[String]) -> Trial {
    let chair = env.world().placements()[setup.seat];
    let (x, y, _) = env.start;
    // Side in the chair's frame: +y of the chair is its left.
    let (s, c) = chair.yaw.sin_cos();
    let local_x = c * (x - chair.pos[0]) + s * (y - chair.pos[1]);
    let local_y = -s * (x - chair.pos[0]) + c * (y - chair.pos[1]);
    Trial {
        index,
        zone: zone.to_string(),
        start: env.start,
        local_start: (local_x, local_y),
        side: if local_y >= 0.0 { "left".into() } else { "right".into() },
        success: terms[0] > 0.5,
        fell: terms[2] > 0.5,
        min_distance: f64::from(terms[1]),
        seconds: f64::from(terms[3]),
        skills: env.chosen.iter().map(|&c| names[c].clone()).collect(),
    }
}

fn row(zone: &str, trials: &[&Trial]) -> ZoneRow {
    let n = trials.len().max(1) as f64;
    let mean = trials.iter().map(|t| t.min_distance).sum::<f64>() / n;
    let var = trials.iter().map(|t| (t.min_distance - mean).powi(2)).sum::<f64>() / (n - 1.0).max(1.0);
    ZoneRow {
        zone: zone.to_string(),
        trials: trials.len(),
        success_rate: trials.iter().filter(|t| t.success).count() as f64 / n,
        fall_rate: trials.iter().filter(|t| t.fell).count() as f64 / n,
        min_distance_mean: mean,
        min_distance_sd: var.sqrt(),
    }
}

fn report(zones: &[String], skills: Vec<String>, trials: Vec<Trial>) -> MetaReport {
    let mut rows: Vec<ZoneRow> =
        zones.iter().map(|z| row(z, &trials.iter().filter(|t| &t.zone == z).collect::<Vec<_>>())).collect();
    rows.push(row("all", &trials.iter().collect::<Vec<_>>()));
    let k = skills.len();
    let index = |name: &str| skills.iter().position(|s| s == name).expect("a known skill");
    let transitions = ["left", "right"]
        .iter()
        .map(|side| {
            let mut m = vec![vec![0u32; k]; k + 1];
            for t in trials.iter().filter(|t| t.side == *side) {
                let mut from = 0; // the start row
                for s in &t.skills {
                    let to = index(s);
                    m[from][to] += 1;
                    from = to + 1;
                }
            }
            (side.to_string(), m)
        })
        .collect();
    MetaReport { zones: rows, skills, transitions, trials }
}

impl MetaReport {
    /// The report as Markdown: the per-zone table, then a transition matrix per side.
    pub fn markdown(&self) -> String {
        let mut s = String::new();
        let _ = writeln!(s, "| zone | trials | success | falls | min distance (m) |");
        let _ = writeln!(s, "|---|---:|---:|---:|---:|");
        for r in &self.zones {
            let _ = writeln!(
                s,
                "| {} | {} | {:.1}% | {:.1}% | {:.2} ± {:.2} |",
                r.zone,
                r.trials,
                100.0 * r.success_rate,
                100.0 * r.fall_rate,
                r.min_distance_mean,
                r.min_distance_sd
            );
        }
        for (side, m) in &self.transitions {
            let _ = writeln!(s, "\nskill transitions, started on the chair's {side} (row: from, column: to)\n");
            let _ = writeln!(s, "| from \\ to | {} |", self.skills.join(" | "));
            let _ = writeln!(s, "|---|{}", "---:|".repeat(self.skills.len()));
            for (i, counts) in m.iter().enumerate() {
                let from = if i == 0 { "start" } else { &self.skills[i - 1] };
                let cells: Vec<String> = counts.iter().map(u32::to_string).collect();
                let _ = writeln!(s, "| {from} | {} |", cells.join(" | "));
            }
        }
        s
    }

    /// Writes `report.md`, `trials.csv` and `report.json` into `dir` (each atomically).
    pub fn write(&self, dir: &Path) -> Result<()> {
        let err = |e: std::io::Error| MetaError::Invalid(format!("{}: {e}", dir.display()));
        std::fs::create_dir_all(dir).map_err(err)?;
        let mut csv = String::from("index,zone,x,y,yaw,side,success,fell,min_distance,seconds,skills\n");
        for t in &self.trials {
            let _ = writeln!(
                csv,
                "{},{},{:.4},{:.4},{:.4},{},{},{},{:.4},{:.2},{}",
                t.index,
                t.zone,
                t.start.0,
                t.start.1,
                t.start.2,
                t.side,
                t.success,
                t.fell,
                t.min_distance,
                t.seconds,
                t.skills.join(">")
            );
        }
        let json = serde_json_string(self);
        let files = [
            ("report.md", self.markdown()),
            ("trials.csv", csv),
            ("report.json", json),
        ];
        for (name, text) in files {
            let path = dir.join(name);
            let partial = dir.join(format!("{name}.partial"));
            std::fs::write(&partial, text).map_err(err)?;
            std::fs::rename(&partial, &path).map_err(err)?;
        }
        self.plot(dir)
    }

    /// Draws the success map over start positions (`heatmap.png`/`.svg`) and one transition
    /// matrix per start side (`transitions-<side>.png`/`.svg`) into `dir`.
    pub fn plot(&self, dir: &Path) -> Result<()> {
        let plot_err = |e: repertoire_report::ReportError| MetaError::Invalid(e.to_string());
        let points: Vec<StartPoint> = self
            .trials
            .iter()
            .map(|t| StartPoint { x: t.local_start.0, y: t.local_start.1, success: t.success })
            .collect();
        let all = self.zones.last().map_or(0.0, |z| z.success_rate);
        let title = format!("success by start position ({} trials, {:.1}%)", self.trials.len(), 100.0 * all);
        success_map(&dir.join("heatmap"), &title, &points).map_err(plot_err)?;
        let rows: Vec<String> = std::iter::once("start".to_string()).chain(self.skills.iter().cloned()).collect();
        for (side, counts) in &self.transitions {
            let title = format!("skill transitions, starts on the chair's {side}");
            transition_matrix(&dir.join(format!("transitions-{side}")), &title, &rows, &self.skills, counts)
                .map_err(plot_err)?;
        }
        Ok(())
    }
}

fn serde_json_string(r: &MetaReport) -> String {
    serde_json::to_string_pretty(r).expect("a report is plain data")
}
