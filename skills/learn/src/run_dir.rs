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
        std::fs::write(path.join("run.ron"), text)?;
        let open = |name: &str| OpenOptions::new().create(true).append(true).open(path.join(name));
        let csv = open("metrics.csv")?;
        let wrote_header = csv.metadata()?.len() > 0;
        Ok(RunDir { path: path.to_path_buf(), jsonl: open("metrics.jsonl")?, csv, wrote_header })
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
