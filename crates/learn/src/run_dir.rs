//! A run directory: the config, seed and git hash of a run, its metrics per iteration as CSV and
//! JSONL, and its checkpoints, so every result can be traced back to what produced it.

use std::fs::{File, OpenOptions};
use std::io::Write;
use std::path::{Path, PathBuf};

use serde::Serialize;

use crate::ppo::{IterationMetrics, PpoConfig};

/// `git rev-parse HEAD` of the current directory's repository, if git is available.
pub fn git_hash() -> Option<String> {
    let out = std::process::Command::new("git").args(["rev-parse", "HEAD"]).output().ok()?;
    out.status.success().then(|| String::from_utf8_lossy(&out.stdout).trim().to_string())
}

/// What is recorded about a run when it starts (`run.ron`).
#[derive(Clone, Debug, Serialize)]
pub struct RunInfo<'a> {
    /// The configuration (its `seed` is the run's seed).
    pub config: &'a PpoConfig,
    /// The seed, repeated for grep-ability.
    pub seed: u64,
    /// `git rev-parse HEAD`, if available.
    pub git_hash: Option<String>,
    /// Seconds since the Unix epoch at creation.
    pub started_unix: u64,
}

/// An open run directory; [`RunDir::log`] appends one line per iteration.
pub struct RunDir {
    path: PathBuf,
    csv: File,
    jsonl: File,
    wrote_header: bool,
}

impl RunDir {
    /// Create (or reuse) `path`, write `run.ron` and open `metrics.csv` / `metrics.jsonl` for
    /// appending.
    pub fn create(path: &Path, config: &PpoConfig) -> std::io::Result<Self> {
        std::fs::create_dir_all(path.join("checkpoints"))?;
        let info = RunInfo {
            config,
            seed: config.seed,
            git_hash: git_hash(),
            started_unix: std::time::SystemTime::now().duration_since(std::time::UNIX_EPOCH).map_or(0, |d| d.as_secs()),
        };
        let text =
            ron::ser::to_string_pretty(&info, ron::ser::PrettyConfig::default()).map_err(std::io::Error::other)?;
        repertoire_files::write_atomic(&path.join("run.ron"), text.as_bytes()).map_err(|e| e.source)?;
        let open = |name: &str| OpenOptions::new().create(true).append(true).open(path.join(name));
        let csv = open("metrics.csv")?;
        let wrote_header = csv.metadata()?.len() > 0;
        Ok(RunDir { path: path.to_path_buf(), jsonl: open("metrics.jsonl")?, csv, wrote_header })
    }

    /// Reopen `path` to continue a run from its checkpoint at `iteration`: rows of
    /// `metrics.csv` and `metrics.jsonl` logged after that iteration (by a run that went on past
    /// the checkpoint before it stopped) are dropped, so the continued run's rows follow on
    /// without repeats; then as [`RunDir::create`].
    pub fn resume(path: &Path, config: &PpoConfig, iteration: usize) -> std::io::Result<Self> {
        drop_rows_after(&path.join("metrics.csv"), iteration)?;
        drop_rows_after(&path.join("metrics.jsonl"), iteration)?;
        Self::create(path, config)
    }

    /// The directory.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// The checkpoint stem for `iteration` (`checkpoints/iter-000042`).
    pub fn checkpoint_stem(&self, iteration: usize) -> PathBuf {
        self.path.join("checkpoints").join(format!("iter-{iteration:06}"))
    }

    /// Append one iteration's metrics to both files.
    pub fn log(&mut self, m: &IterationMetrics) -> std::io::Result<()> {
        if !self.wrote_header {
            let mut header = CSV_COLUMNS.join(",");
            for (name, _) in &m.terms {
                header.push_str(&format!(",term_{name}"));
            }
            writeln!(self.csv, "{header}")?;
            self.wrote_header = true;
        }
        let mut row = format!(
            "{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{}",
            m.iteration,
            m.global_step,
            m.episodes,
            m.mean_return,
            m.mean_length,
            m.termination_rate,
            m.approx_kl,
            m.clip_fraction,
            m.entropy,
            m.explained_variance,
            m.policy_loss,
            m.value_loss,
            m.grad_norm,
            m.learning_rate,
            m.epochs,
            m.samples_per_sec,
            m.env_time_fraction
        );
        for (_, v) in &m.terms {
            row.push_str(&format!(",{v}"));
        }
        writeln!(self.csv, "{row}")?;
        let line = serde_json::to_string(m).map_err(std::io::Error::other)?;
        writeln!(self.jsonl, "{line}")
    }
}

/// Drops the rows of a per-iteration log logged after `iteration`: a CSV whose first column is
/// the iteration (the header and other rows without one stay), or JSON lines with an
/// `iteration` field (`.jsonl`). The file is rewritten through a temporary sibling; a missing
/// file is left missing.
pub fn drop_rows_after(path: &Path, iteration: usize) -> std::io::Result<()> {
    let text = match std::fs::read_to_string(path) {
        Ok(t) => t,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(()),
        Err(e) => return Err(e),
    };
    let jsonl = path.extension().is_some_and(|e| e == "jsonl");
    let row_iteration = |line: &str| -> Option<u64> {
        if jsonl {
            serde_json::from_str::<serde_json::Value>(line).ok()?.get("iteration")?.as_u64()
        } else {
            line.split(',').next()?.trim().parse().ok()
        }
    };
    let kept: String = text
        .lines()
        .filter(|l| row_iteration(l).is_none_or(|i| i <= iteration as u64))
        .flat_map(|l| [l, "\n"])
        .collect();
    if kept.len() == text.len() {
        return Ok(());
    }
    repertoire_files::write_atomic(path, kept.as_bytes())
        .map_err(|e| std::io::Error::new(e.source.kind(), e.to_string()))
}

/// The fixed CSV columns, in order (named reward terms follow as `term_<name>`).
pub const CSV_COLUMNS: [&str; 17] = [
    "iteration",
    "global_step",
    "episodes",
    "mean_return",
    "mean_length",
    "termination_rate",
    "approx_kl",
    "clip_fraction",
    "entropy",
    "explained_variance",
    "policy_loss",
    "value_loss",
    "grad_norm",
    "learning_rate",
    "epochs",
    "samples_per_sec",
    "env_time_fraction",
];

#[cfg(test)]
mod tests {
    use super::drop_rows_after;

    #[test]
    fn rows_logged_after_a_checkpoint_are_dropped_and_headers_stay() {
        let dir = std::env::temp_dir().join(format!("repertoire-run-rows-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let csv = dir.join("metrics.csv");
        std::fs::write(&csv, "iteration,global_step\n1,10\n2,20\n3,30\n").unwrap();
        let jsonl = dir.join("metrics.jsonl");
        std::fs::write(&jsonl, "{\"iteration\":1,\"x\":0.5}\n{\"iteration\":2}\n{\"iteration\":3}\n").unwrap();
        drop_rows_after(&csv, 2).unwrap();
        drop_rows_after(&jsonl, 1).unwrap();
        assert_eq!(std::fs::read_to_string(&csv).unwrap(), "iteration,global_step\n1,10\n2,20\n");
        assert_eq!(std::fs::read_to_string(&jsonl).unwrap(), "{\"iteration\":1,\"x\":0.5}\n");
        drop_rows_after(&dir.join("absent.csv"), 0).unwrap();
        assert!(!dir.join("absent.csv").exists(), "a missing log stays missing");
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
