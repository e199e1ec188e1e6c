//! Evaluating a meta-controller: seeded trials in parallel from chosen zones; success rate and
//! minimum pelvis-to-seat distance (mean ± sd) per zone; skill transition matrices split by the
//! side of the chair the character started on; Markdown, CSV and JSON reports.

use std::fmt::Write as _;
use std::path::Path;
use std::sync::Arc;

use rayon::prelude::*;
use repertoire_learn::env::Env;
use repertoire_report::{StartPoint, success_map, transition_matrix};
use serde::{Deserialize, Serialize};

use repertoire_scenes::{FallCause, Recording};

use crate::controller::{Arena, Controller};
use crate::env::trial_rng;
use crate::error::{MetaError, Result};
use crate::task::TaskSpec;
pub use crate::trial::{Trial, fall_cause};

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

/// How the trials whose last skill was one skill ended.
#[derive(Debug, Clone, PartialEq)]
pub struct Ending {
    /// The skill playing when the trial ended (`none` when none was chosen).
    pub skill: String,
    /// Trials that ended in it.
    pub trials: usize,
    /// Of those, successes.
    pub successes: usize,
    /// Falls.
    pub falls: usize,
    /// Neither (the time limit).
    pub timeouts: usize,
    /// Mean minimum pelvis-to-seat distance of those trials (m).
    pub min_distance_mean: f64,
    /// Of the falls, those after the character had touched the chair (a walk or turn that
    /// bumped into it; in the sit, most falls).
    pub falls_touched: usize,
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

/// Runs `trials` trials per zone in `zones` with `controller`, `batch` environments in
/// parallel, in any [`Arena`] (the skills or the latent low level).
pub fn evaluate<A: Arena>(
    setup: &Arc<A>,
    controller: &dyn Controller<A>,
    zones: &[String],
    trials: usize,
    batch: usize,
    seed: u64,
) -> Result<MetaReport> {
    if !matches!(setup.task(), TaskSpec::Sit { .. }) {
        return Err(MetaError::Invalid(format!(
            "{}: sitting trials need a sitting scenario (this one is {}; `evaluate_task` plays every task)",
            setup.model().scenario.path.display(),
            setup.task().name()
        )));
    }
    crate::env::check_zones(setup.model(), zones)?;
    let mut all = Vec::new();
    for (zi, zone) in zones.iter().enumerate() {
        *setup.zones().write().expect("never poisoned") = vec![zone.clone()];
        for chunk in (0..trials).collect::<Vec<_>>().chunks(batch.max(1)) {
            let played: Result<Vec<Trial>> = chunk
                .par_iter()
                .map(|&i| Ok(run_trial(setup, controller, zi, zone, trials, i, seed, false)?.0))
                .collect();
            all.extend(played?);
        }
    }
    Ok(report(zones, setup.options(), all))
}

/// Runs trial `i` of zone `zone` (the `zi`-th of the evaluation's zones, `trials` per zone),
/// seeded exactly as [`evaluate`] seeds it; with `record`, also its recording.
#[allow(clippy::too_many_arguments)]
fn run_trial<A: Arena>(
    setup: &Arc<A>,
    controller: &dyn Controller<A>,
    zi: usize,
    zone: &str,
    trials: usize,
    i: usize,
    seed: u64,
    record: bool,
) -> Result<(Trial, Option<Recording>)> {
    let mut env = setup.env()?;
    if record {
        A::record(&mut env, format!("{}, zone {zone}, trial {i} (seed {seed})", setup.decider()));
    }
    let mut ctl = controller.start(setup);
    let mut rng = trial_rng(seed, zi, trials, i);
    let mut obs = vec![0.0; env.obs_dim()];
    let mut act = vec![0.0; env.act_dim()];
    let mut mask = vec![true; setup.options().len()];
    env.reset(&mut rng, &mut obs);
    loop {
        ctl.act(&env, &obs, &mut mask, &mut act);
        let out = env.step(&act, &mut obs);
        if out.terminated || out.truncated {
            let mut trial = setup.trial(&env, i, zone, &out.terms);
            trial.simulated = ctl.simulated();
            return Ok((trial, A::recording(&mut env)));
        }
    }
}

/// The `n` worst trials of `report` (failures first, then the largest minimum distance), or
/// with `per_zone`, the `n` worst of each zone.
pub fn worst_trials(report: &MetaReport, n: usize, per_zone: bool) -> Vec<&Trial> {
    let mut sorted: Vec<&Trial> = report.trials.iter().collect();
    sorted.sort_by(|a, b| a.success.cmp(&b.success).then(b.min_distance.total_cmp(&a.min_distance)));
    if !per_zone {
        sorted.truncate(n);
        return sorted;
    }
    let mut out = Vec::new();
    for row in report.zones.iter().filter(|r| r.zone != "all") {
        out.extend(sorted.iter().filter(|t| t.zone == row.zone).take(n));
    }
    out
}

/// Runs `trial` of an evaluation over `zones` (`trials` per zone, `seed`) again, recorded. The
/// controller acts by its mode, so the rerun is the same trial; an error if it is not.
pub fn record_trial<A: Arena>(
    setup: &Arc<A>,
    controller: &dyn Controller<A>,
    zones: &[String],
    trials: usize,
    seed: u64,
    trial: &Trial,
) -> Result<Recording> {
    let zi = zones.iter().position(|z| *z == trial.zone).ok_or_else(|| {
        MetaError::Invalid(format!("trial {} is of zone `{}`, not evaluated here", trial.index, trial.zone))
    })?;
    // Episodes draw their zone from the setup's list, as in the evaluation (one zone at a time).
    *setup.zones().write().expect("never poisoned") = vec![trial.zone.clone()];
    let (again, rec) = run_trial(setup, controller, zi, &trial.zone, trials, trial.index, seed, true)?;
    if again.min_distance != trial.min_distance || again.success != trial.success {
        return Err(MetaError::Invalid(format!(
            "trial {} of zone `{}` did not replay the same (min distance {} then {})",
            trial.index, trial.zone, trial.min_distance, again.min_distance
        )));
    }
    rec.ok_or_else(|| MetaError::Invalid("the rerun was not recorded".into()))
}

/// Records the worst trials of `report` into `dir` as `trial_<zone>_<index>.rec`; returns the
/// files written.
#[allow(clippy::too_many_arguments)]
pub fn save_worst<A: Arena>(
    setup: &Arc<A>,
    controller: &dyn Controller<A>,
    report: &MetaReport,
    zones: &[String],
    trials: usize,
    seed: u64,
    n: usize,
    per_zone: bool,
    dir: &Path,
) -> Result<Vec<std::path::PathBuf>> {
    let worst = worst_trials(report, n, per_zone);
    if worst.is_empty() {
        return Ok(Vec::new());
    }
    std::fs::create_dir_all(dir).map_err(|e| MetaError::Invalid(format!("{}: cannot create: {e}", dir.display())))?;
    let mut written = Vec::new();
    for t in worst {
        let path = dir.join(format!("trial_{}_{}.rec", t.zone, t.index));
        record_trial(setup, controller, zones, trials, seed, t)?.save(&path)?;
        written.push(path);
    }
    Ok(written)
}

/// "floor 12, pelvis low 3" over the trials that fell, causes in code order; `None` without falls.
pub fn fall_causes<'a>(causes: impl Iterator<Item = Option<&'a str>>) -> Option<String> {
    let mut counts: Vec<(String, usize)> = Vec::new();
    for c in causes.flatten() {
        match counts.iter_mut().find(|(n, _)| n == c) {
            Some((_, k)) => *k += 1,
            None => counts.push((c.to_string(), 1)),
        }
    }
    let order = |n: &str| FallCause::ALL.iter().position(|c| c.name() == n).unwrap_or(FallCause::ALL.len());
    counts.sort_by_key(|(n, _)| order(n));
    (!counts.is_empty()).then(|| counts.iter().map(|(n, k)| format!("{n} {k}")).collect::<Vec<_>>().join(", "))
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

/// The report of `trials` over `zones`; with no `skills` (the latent low level), no transition
/// matrices.
pub(crate) fn report(zones: &[String], skills: Vec<String>, trials: Vec<Trial>) -> MetaReport {
    let mut rows: Vec<ZoneRow> =
        zones.iter().map(|z| row(z, &trials.iter().filter(|t| &t.zone == z).collect::<Vec<_>>())).collect();
    rows.push(row("all", &trials.iter().collect::<Vec<_>>()));
    let k = skills.len();
    let index = |name: &str| skills.iter().position(|s| s == name).expect("a known skill");
    let sides: &[&str] = if skills.is_empty() { &[] } else { &["left", "right"] };
    let transitions = sides
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
    /// How trials ended, grouped by the skill playing at the end (where the falls happen), in
    /// the order of [`MetaReport::skills`].
    pub fn endings(&self) -> Vec<Ending> {
        fn last(t: &Trial) -> &str {
            t.skills.last().map_or("none", String::as_str)
        }
        self.skills
            .iter()
            .map(String::as_str)
            .chain(std::iter::once("none"))
            .filter_map(|skill| {
                let ts: Vec<&Trial> = self.trials.iter().filter(|t| last(t) == skill).collect();
                if ts.is_empty() {
                    return None;
                }
                let successes = ts.iter().filter(|t| t.success).count();
                let falls = ts.iter().filter(|t| t.fell && !t.success).count();
                let falls_touched = ts.iter().filter(|t| t.fell && !t.success && t.touched.is_some()).count();
                Some(Ending {
                    trials: ts.len(),
                    successes,
                    falls,
                    timeouts: ts.len() - successes - falls,
                    min_distance_mean: ts.iter().map(|t| t.min_distance).sum::<f64>() / ts.len() as f64,
                    falls_touched,
                    skill: skill.to_string(),
                })
            })
            .collect()
    }

    /// The report as Markdown: the per-zone table, how trials ended by their last skill, then a
    /// transition matrix per side.
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
        if let Some(causes) = fall_causes(self.trials.iter().map(|t| t.fall_cause.as_deref())) {
            let _ = writeln!(s, "\nfalls by cause (the shared fall test; all zones): {causes}");
        }
        let searched: Vec<u64> = self.trials.iter().map(|t| t.simulated).collect();
        if searched.iter().any(|&n| n > 0) {
            let mean = searched.iter().sum::<u64>() as f64 / searched.len() as f64;
            let _ = writeln!(
                s,
                "\nsearch cost: {mean:.0} decisions simulated per trial in copies of the episode (most {})",
                searched.iter().max().copied().unwrap_or(0)
            );
        }
        let endings = self.endings();
        if !self.skills.is_empty() && !endings.is_empty() {
            let _ = writeln!(s, "\nhow trials ended, by the skill playing at the end (all zones)\n");
            let _ = writeln!(
                s,
                "| last skill | trials | success | falls | of them after touching the chair | time limit | min distance (m) |"
            );
            let _ = writeln!(s, "|---|---:|---:|---:|---:|---:|---:|");
            for e in &endings {
                let _ = writeln!(
                    s,
                    "| {} | {} | {} | {} | {} | {} | {:.2} |",
                    e.skill, e.trials, e.successes, e.falls, e.falls_touched, e.timeouts, e.min_distance_mean
                );
            }
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
        let mut csv =
            String::from("index,zone,x,y,yaw,side,success,fell,min_distance,seconds,skills,touched,fall_cause\n");
        for t in &self.trials {
            let _ = writeln!(
                csv,
                "{},{},{:.4},{:.4},{:.4},{},{},{},{:.4},{:.2},{},{},{}",
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
                t.skills.join(">"),
                t.touched.as_deref().unwrap_or(""),
                t.fall_cause.as_deref().unwrap_or("")
            );
        }
        let json = serde_json_string(self);
        let files = [("report.md", self.markdown()), ("trials.csv", csv), ("report.json", json)];
        for (name, text) in files {
            repertoire_files::write_atomic(&dir.join(name), text.as_bytes())
                .map_err(|e| MetaError::Invalid(e.to_string()))?;
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

#[cfg(test)]
mod tests {
    use super::*;

    fn trial(index: usize, skills: &[&str], success: bool, fell: bool, min_distance: f64) -> Trial {
        Trial {
            index,
            zone: "front".into(),
            start: (2.0, 0.0, 0.0),
            local_start: (2.0, 0.0),
            side: "left".into(),
            success,
            fell,
            fall_cause: fell.then(|| "floor".to_string()),
            min_distance,
            seconds: 5.0,
            skills: skills.iter().map(|s| s.to_string()).collect(),
            touched: None,
            simulated: 0,
        }
    }

    #[test]
    fn falls_are_counted_by_cause_in_the_fall_tests_order() {
        assert_eq!(fall_cause(0.0), None);
        assert_eq!(fall_cause(1.0).as_deref(), Some("floor"));
        assert_eq!(fall_cause(4.0).as_deref(), Some("upside down"));
        assert_eq!(fall_cause(crate::env::DIVERGED).as_deref(), Some("diverged"));
        let causes = [Some("diverged"), None, Some("pelvis low"), Some("floor"), Some("pelvis low")];
        assert_eq!(fall_causes(causes.into_iter()).as_deref(), Some("floor 1, pelvis low 2, diverged 1"));
        assert_eq!(fall_causes([None, None].into_iter()), None);
    }

    #[test]
    fn endings_count_how_trials_ended_by_their_last_skill() {
        let skills: Vec<String> = ["walk_to", "turn_left", "sit"].iter().map(|s| s.to_string()).collect();
        let trials = vec![
            trial(0, &["walk_to", "turn_left", "sit"], true, false, 0.1),
            trial(1, &["walk_to", "turn_left", "sit"], false, true, 0.5),
            trial(2, &["walk_to", "turn_left", "sit"], false, false, 0.3),
            trial(3, &["walk_to"], false, true, 1.5),
            Trial {
                touched: Some("walk_to".into()),
                ..trial(4, &["walk_to", "turn_left", "walk_to"], false, true, 0.6)
            },
            Trial { touched: Some("sit".into()), ..trial(5, &["walk_to", "turn_left", "sit"], false, true, 0.3) },
        ];
        let r = report(&["front".to_string()], skills, trials);
        let e = r.endings();
        assert_eq!(e.len(), 2, "turn_left ended no trial: {e:?}");
        assert_eq!(
            (e[0].skill.as_str(), e[0].trials, e[0].successes, e[0].falls, e[0].falls_touched, e[0].timeouts),
            ("walk_to", 2, 0, 2, 1, 0)
        );
        assert_eq!(
            (e[1].skill.as_str(), e[1].trials, e[1].successes, e[1].falls, e[1].falls_touched, e[1].timeouts),
            ("sit", 4, 1, 2, 1, 1)
        );
        assert!((e[1].min_distance_mean - 0.3).abs() < 1e-12);
        let md = r.markdown();
        assert!(md.contains("| sit | 4 | 1 | 2 | 1 | 1 | 0.30 |"), "{md}");
        assert!(md.contains("| walk_to | 2 | 0 | 2 | 1 | 0 | 1.05 |"), "{md}");
    }
}
