//! Paired comparison of two sitting evaluations over the same trials (`repertoire meta compare`).
//!
//! Two evaluations with the same scenario, seed and trial count start every trial in the same
//! place, so their difference is best read trial by trial: the trials only one of them seats
//! carry it all. Per zone and over all zones the comparison gives both success rates, the
//! trials seated only by each, the difference in points and McNemar's test on those discordant
//! trials: z = (only B − only A) / √(only A + only B) and the exact two-sided p-value
//! (a binomial test of the discordant trials against one half). Trials are matched by zone and
//! index and must start alike (position and heading as `trials.csv` writes them); evaluations
//! of different trials are refused, since their difference would not be paired.

use std::collections::HashMap;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use crate::error::{MetaError, Result};

/// One trial of a `trials.csv`: what the comparison reads.
#[derive(Debug, Clone, PartialEq)]
pub struct TrialRow {
    /// Trial index within its zone.
    pub index: usize,
    /// Spawn zone.
    pub zone: String,
    /// Start position and heading, as written (4 decimals).
    pub start: [String; 3],
    /// Seated for 3 s.
    pub success: bool,
    /// Ended by a fall.
    pub fell: bool,
}

/// The `trials.csv` of an evaluation: `path` itself, or `path/trials.csv` for a folder.
pub fn trials_file(path: &Path) -> PathBuf {
    if path.is_dir() { path.join("trials.csv") } else { path.to_path_buf() }
}

/// Reads a sitting evaluation's `trials.csv` (a folder's, or the file); an error names the file
/// and the line.
pub fn read_trials(path: &Path) -> Result<Vec<TrialRow>> {
    let file = trials_file(path);
    let text = std::fs::read_to_string(&file).map_err(|e| MetaError::Invalid(format!("{}: {e}", file.display())))?;
    let bad = |line: usize, what: String| MetaError::Invalid(format!("{}:{line}: {what}", file.display()));
    let mut lines = text.lines();
    let header: Vec<&str> = lines.next().ok_or_else(|| bad(1, "empty, no header".into()))?.split(',').collect();
    let column = |name: &str| {
        header.iter().position(|h| h.trim() == name).ok_or_else(|| {
            bad(
                1,
                format!(
                    "no `{name}` column (a sitting evaluation's trials.csv has index, zone, x, y, yaw, success, fell)"
                ),
            )
        })
    };
    let cols = [
        column("index")?,
        column("zone")?,
        column("x")?,
        column("y")?,
        column("yaw")?,
        column("success")?,
        column("fell")?,
    ];
    let flag = |line: usize, name: &str, v: &str| match v {
        "true" => Ok(true),
        "false" => Ok(false),
        _ => Err(bad(line, format!("{name} is `{v}`, not true or false"))),
    };
    let mut rows = Vec::new();
    for (i, l) in lines.enumerate() {
        let line = i + 2;
        if l.trim().is_empty() {
            continue;
        }
        let f: Vec<&str> = l.split(',').collect();
        if f.len() != header.len() {
            return Err(bad(line, format!("{} fields, the header has {}", f.len(), header.len())));
        }
        let index =
            f[cols[0]].parse().map_err(|_| bad(line, format!("index is `{}`, not a trial number", f[cols[0]])))?;
        rows.push(TrialRow {
            index,
            zone: f[cols[1]].to_string(),
            start: [f[cols[2]].to_string(), f[cols[3]].to_string(), f[cols[4]].to_string()],
            success: flag(line, "success", f[cols[5]])?,
            fell: flag(line, "fell", f[cols[6]])?,
        });
    }
    if rows.is_empty() {
        return Err(bad(2, "no trials".into()));
    }
    Ok(rows)
}

/// The paired figures of one zone (or all zones).
#[derive(Debug, Clone, PartialEq)]
pub struct Paired {
    /// Zone (`all` for the whole).
    pub zone: String,
    /// Trials.
    pub trials: usize,
    /// Trials seated by A, by B.
    pub seated: [usize; 2],
    /// Trials seated only by A, only by B.
    pub only: [usize; 2],
    /// Trials ending in a fall with A, with B.
    pub falls: [usize; 2],
}

impl Paired {
    /// B's success rate less A's, in points.
    pub fn difference(&self) -> f64 {
        100.0 * (self.only[1] as f64 - self.only[0] as f64) / self.trials.max(1) as f64
    }

    /// McNemar's z: (only B − only A) / √(only A + only B); 0 with no discordant trial.
    pub fn z(&self) -> f64 {
        let n = self.only[0] + self.only[1];
        if n == 0 { 0.0 } else { (self.only[1] as f64 - self.only[0] as f64) / (n as f64).sqrt() }
    }

    /// The exact two-sided p-value of McNemar's test: the chance, were A and B alike, of
    /// discordant trials split at least this unevenly.
    pub fn p_value(&self) -> f64 {
        binomial_two_sided(self.only[0] + self.only[1], self.only[0].min(self.only[1]))
    }
}

/// Two evaluations, trial by trial.
#[derive(Debug, Clone, PartialEq)]
pub struct Comparison {
    /// What A and B are (as given).
    pub names: [String; 2],
    /// Per zone in A's order, then `all`.
    pub rows: Vec<Paired>,
}

/// Pairs `a` and `b` trial by trial; refuses evaluations of different trials.
pub fn compare(names: [String; 2], a: &[TrialRow], b: &[TrialRow]) -> Result<Comparison> {
    let refuse =
        |what: String| MetaError::Invalid(format!("{} and {} are not the same trials: {what}", names[0], names[1]));
    if a.len() != b.len() {
        return Err(refuse(format!("{} trials against {}", a.len(), b.len())));
    }
    let by_trial: HashMap<(&str, usize), &TrialRow> = b.iter().map(|t| ((t.zone.as_str(), t.index), t)).collect();
    let mut rows: Vec<Paired> = Vec::new();
    let empty = |zone: &str| Paired { zone: zone.into(), trials: 0, seated: [0; 2], only: [0; 2], falls: [0; 2] };
    let mut all = empty("all");
    for ta in a {
        let tb = by_trial
            .get(&(ta.zone.as_str(), ta.index))
            .ok_or_else(|| refuse(format!("B has no trial {} in zone {}", ta.index, ta.zone)))?;
        if ta.start != tb.start {
            return Err(refuse(format!(
                "trial {} of zone {} starts at ({}) in A and at ({}) in B",
                ta.index,
                ta.zone,
                ta.start.join(", "),
                tb.start.join(", ")
            )));
        }
        let zi = match rows.iter().position(|r| r.zone == ta.zone) {
            Some(i) => i,
            None => {
                rows.push(empty(&ta.zone));
                rows.len() - 1
            }
        };
        for r in [&mut rows[zi], &mut all] {
            r.trials += 1;
            for (k, t) in [ta, tb].into_iter().enumerate() {
                r.seated[k] += usize::from(t.success);
                r.falls[k] += usize::from(t.fell);
            }
            r.only[0] += usize::from(ta.success && !tb.success);
            r.only[1] += usize::from(tb.success && !ta.success);
        }
    }
    if rows.iter().any(|r| r.zone == "all") {
        return Err(MetaError::Invalid(format!(
            "{}: a zone is named `all`, which the comparison's total uses",
            names[0]
        )));
    }
    rows.push(all);
    Ok(Comparison { names, rows })
}

impl Comparison {
    /// The comparison as Markdown: a line naming A and B, then one row per zone and the total.
    pub fn markdown(&self) -> String {
        let mut s = format!("A: {}\nB: {}\n\n", self.names[0], self.names[1]);
        s.push_str("| zone | trials | A seated | B seated | only A | only B | B − A | McNemar z | p (exact) | A falls | B falls |\n");
        s.push_str("|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|\n");
        for r in &self.rows {
            let pct = |n: usize| 100.0 * n as f64 / r.trials.max(1) as f64;
            let _ = writeln!(
                s,
                "| {} | {} | {:.1}% | {:.1}% | {} | {} | {:+.1} | {:+.2} | {} | {:.1}% | {:.1}% |",
                r.zone,
                r.trials,
                pct(r.seated[0]),
                pct(r.seated[1]),
                r.only[0],
                r.only[1],
                r.difference(),
                r.z(),
                p_text(r.p_value()),
                pct(r.falls[0]),
                pct(r.falls[1]),
            );
        }
        s
    }
}

fn p_text(p: f64) -> String {
    if p < 1e-300 {
        "< 1e-300".into()
    } else if p < 1e-4 {
        format!("{p:.1e}")
    } else {
        format!("{p:.4}")
    }
}

/// P(|X − n/2| ≥ n/2 − k) for X ~ Binomial(n, 1/2) and k ≤ n/2: twice the lower tail up to k,
/// at most 1. Summed in logarithms, so exact to rounding for any n.
fn binomial_two_sided(n: usize, k: usize) -> f64 {
    if n == 0 {
        return 1.0;
    }
    // log C(n, j) / 2^n for j = 0..=k by the ratio C(n, j+1) / C(n, j) = (n − j) / (j + 1).
    let mut log_term = -(n as f64) * std::f64::consts::LN_2;
    let mut terms = Vec::with_capacity(k + 1);
    for j in 0..=k {
        terms.push(log_term);
        log_term += ((n - j) as f64).ln() - ((j + 1) as f64).ln();
    }
    let top = terms.iter().cloned().fold(f64::NEG_INFINITY, f64::max);
    let tail = top.exp() * terms.iter().map(|t| (t - top).exp()).sum::<f64>();
    (2.0 * tail).min(1.0)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_exact_test_matches_the_binomial_by_hand() {
        // n = 10, k = 1: 2 · (1 + 10) / 1024.
        assert!((binomial_two_sided(10, 1) - 22.0 / 1024.0).abs() < 1e-12);
        // An even split is no evidence: p = 1.
        assert_eq!(binomial_two_sided(10, 5), 1.0);
        assert_eq!(binomial_two_sided(0, 0), 1.0);
        // n = 20, k = 0: 2 / 2^20.
        assert!((binomial_two_sided(20, 0) - 2.0 / 1_048_576.0).abs() < 1e-15);
        // Large n stays finite and small: 0 of 1000 discordant trials one way.
        let p = binomial_two_sided(1000, 0);
        assert!(p > 0.0 && p < 1e-290, "{p}");
    }
}
