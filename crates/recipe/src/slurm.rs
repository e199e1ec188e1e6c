//! Handing a recipe to Slurm: each stage that is not done becomes a batch job (`sbatch`) that
//! runs `repertoire recipe stage FILE ID`, with `--dependency=afterok` on the jobs of the
//! stages it follows. Rounds whose running depends on what the round before gains are not known
//! at submission: a last job, after the ones submitted, runs `recipe run --slurm` again, which
//! decides and submits the next round. Running the command again picks up what is done and
//! leaves queued jobs as they are.

use std::path::{Path, PathBuf};
use std::process::Command;

use serde::{Deserialize, Serialize};
use sha2::{Digest, Sha256};

use crate::run::{Runner, shell_quote};
use crate::store::{Record, Status, hex};
use crate::{RecipeError, Result};

/// Where and how jobs run: `sbatch` options, from the command line or a RON profile.
#[derive(Debug, Clone, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SlurmOptions {
    /// `--partition`.
    #[serde(default)]
    pub partition: Option<String>,
    /// `--time` (e.g. `04:00:00`).
    #[serde(default)]
    pub time: Option<String>,
    /// `--cpus-per-task` of a stage that does not set its own `cpus`.
    #[serde(default)]
    pub cpus_per_task: Option<usize>,
    /// `--mem` (e.g. `8G`).
    #[serde(default)]
    pub mem: Option<String>,
    /// More `sbatch` arguments, as they are (`--account=…`, `--qos=…`).
    #[serde(default)]
    pub extra: Vec<String>,
}

impl SlurmOptions {
    /// Loads a profile (RON).
    pub fn load(path: &Path) -> Result<SlurmOptions> {
        let text = std::fs::read_to_string(path).map_err(crate::io_err(path, "cannot read the Slurm profile"))?;
        ron::Options::default()
            .with_default_extension(ron::extensions::Extensions::IMPLICIT_SOME)
            .from_str(&text)
            .map_err(|e| RecipeError::Parse {
                path: path.display().to_string(),
                line: e.span.start.line,
                col: e.span.start.col,
                message: e.code.to_string(),
            })
    }

    /// These options with `over`'s where it sets them.
    pub fn merged(mut self, over: &SlurmOptions) -> SlurmOptions {
        self.partition = over.partition.clone().or(self.partition);
        self.time = over.time.clone().or(self.time);
        self.cpus_per_task = over.cpus_per_task.or(self.cpus_per_task);
        self.mem = over.mem.clone().or(self.mem);
        self.extra.extend(over.extra.iter().cloned());
        self
    }

    /// The sbatch arguments of these options; `cpus`: a stage's own, over `cpus_per_task`.
    pub fn args(&self, cpus: Option<usize>) -> Vec<String> {
        let mut a = Vec::new();
        if let Some(p) = &self.partition {
            a.push(format!("--partition={p}"));
        }
        if let Some(t) = &self.time {
            a.push(format!("--time={t}"));
        }
        if let Some(c) = cpus.or(self.cpus_per_task) {
            a.push(format!("--cpus-per-task={c}"));
        }
        if let Some(m) = &self.mem {
            a.push(format!("--mem={m}"));
        }
        a.extend(self.extra.iter().cloned());
        a
    }
}

/// What one submission did.
#[derive(Debug, Clone, Default)]
pub struct Submitted {
    /// (stage, job) of each job submitted now.
    pub jobs: Vec<(String, u64)>,
    /// Stages whose job from before is still queued or running.
    pub queued: usize,
    /// Stages already done.
    pub done: usize,
    /// The job that submits the rounds not decided yet.
    pub continuation: Option<u64>,
}

/// The job-name prefix of every job of the recipe working in `work` (so `--wait` and `squeue`
/// can find them).
pub fn job_prefix(work: &Path) -> String {
    let abs = std::fs::canonicalize(work).unwrap_or_else(|_| work.to_path_buf());
    let mut h = Sha256::new();
    h.update(abs.to_string_lossy().as_bytes());
    format!("rp-{}", &hex(&h.finalize())[..8])
}

/// Whether Slurm job `job` is still pending or running.
pub fn alive(job: u64) -> bool {
    Command::new("squeue")
        .args(["-h", "-o", "%T", "-j", &job.to_string()])
        .output()
        .is_ok_and(|o| o.status.success() && !String::from_utf8_lossy(&o.stdout).trim().is_empty())
}

/// Submits every stage of `runner`'s plan that is not done, each after the jobs of the stages it
/// follows. `recipe_args`: the arguments of `repertoire` that name the recipe (`FILE [--work
/// W]`), for the jobs; `again`: the arguments of the `recipe run --slurm` that submits the
/// rounds not decided yet.
pub fn submit(runner: &mut Runner, recipe_args: &[String], again: &[String], opts: &SlurmOptions) -> Result<Submitted> {
    let plan = runner.plan;
    let cwd = std::env::current_dir().map_err(crate::io_err(Path::new("."), "cannot read the working folder"))?;
    let logs = runner.store.log_dir();
    std::fs::create_dir_all(&logs).map_err(crate::io_err(&logs, "cannot create"))?;
    let prefix = job_prefix(&plan.work);
    let mut jobs: Vec<Option<u64>> = vec![None; plan.stages.len()];
    let mut out = Submitted::default();
    for i in 0..plan.stages.len() {
        runner.settle(i)?;
        let stage = &plan.stages[i];
        match runner.active(i) {
            Some(false) => continue,
            None => {
                let after: Vec<u64> = jobs.iter().flatten().copied().collect();
                let wrap = format!(
                    "exec {} {}",
                    shell_quote(&runner.exe.to_string_lossy()),
                    again.iter().map(|a| shell_quote(a)).collect::<Vec<_>>().join(" ")
                );
                let job = sbatch(
                    &format!("{prefix}:continue"),
                    &cwd,
                    &logs.join("continue-%j.out"),
                    &after,
                    &opts.args(Some(1)),
                    &wrap,
                )?;
                println!("── rounds after this submission are decided by job {job} (`recipe run --slurm` again)");
                out.continuation = Some(job);
                break;
            }
            Some(true) => {}
        }
        if runner.done(i)? {
            out.done += 1;
            continue;
        }
        let identity = runner.identity(i).expect("active").to_string();
        if let Some(rec) = runner.store.record(&stage.id)? {
            let job = match rec.status {
                Status::Queued { job } => Some(job),
                Status::Started => rec.ran.strip_prefix("slurm job ").and_then(|j| j.parse().ok()),
                Status::Done => None,
            };
            if let Some(job) = job.filter(|&j| rec.identity == identity && alive(j)) {
                jobs[i] = Some(job);
                out.queued += 1;
                continue;
            }
        }
        let mut after = Vec::new();
        for &d in &stage.deps {
            if runner.active(d) != Some(true) {
                continue;
            }
            match jobs[d] {
                Some(j) => after.push(j),
                None if runner.done(d)? => {}
                None => {
                    return Err(RecipeError::Stage {
                        stage: stage.id.clone(),
                        message: format!("follows `{}`, which is neither done nor submitted", plan.stages[d].id),
                    });
                }
            }
        }
        let mut args = vec!["recipe".to_string(), "stage".into()];
        args.extend(recipe_args.iter().cloned());
        args.push(stage.id.clone());
        let wrap = format!(
            "exec {} {}",
            shell_quote(&runner.exe.to_string_lossy()),
            args.iter().map(|a| shell_quote(a)).collect::<Vec<_>>().join(" ")
        );
        let log = logs.join(format!("{}-%j.out", stage.id.replace('/', "~")));
        let job = sbatch(&format!("{prefix}:{}", stage.id), &cwd, &log, &after, &opts.args(stage.cpus), &wrap)?;
        runner.store.put(&Record {
            id: stage.id.clone(),
            identity,
            status: Status::Queued { job },
            outputs: Default::default(),
            command: runner.command(i),
            seconds: 0.0,
            ran: format!("slurm job {job}"),
            adopted: Vec::new(),
        })?;
        println!(
            "── {}: job {job}{}",
            stage.id,
            if after.is_empty() {
                String::new()
            } else {
                format!(" after {}", after.iter().map(u64::to_string).collect::<Vec<_>>().join(", "))
            }
        );
        jobs[i] = Some(job);
        out.jobs.push((stage.id.clone(), job));
    }
    Ok(out)
}

/// Submits `wrap` (a shell line) as job `name` working in `cwd`, its output in `log`, after the
/// jobs `after` (afterok), with more sbatch arguments `opts` (an `--array=…` among them makes it
/// a job array); returns the job id.
pub fn sbatch(name: &str, cwd: &Path, log: &Path, after: &[u64], opts: &[String], wrap: &str) -> Result<u64> {
    let mut cmd = Command::new("sbatch");
    cmd.arg("--parsable").arg(format!("--job-name={name}")).arg(format!("--chdir={}", cwd.display()));
    cmd.arg(format!("--output={}", absolute(cwd, log).display()));
    if !after.is_empty() {
        let ids = after.iter().map(u64::to_string).collect::<Vec<_>>().join(":");
        cmd.arg(format!("--dependency=afterok:{ids}")).arg("--kill-on-invalid-dep=yes");
    }
    cmd.args(opts).arg(format!("--wrap={wrap}"));
    let out = cmd.output().map_err(|e| RecipeError::Invalid {
        path: "sbatch".into(),
        message: format!("cannot run sbatch ({e}); is Slurm installed and SLURM_CONF set? (scripts/slurm-local.sh starts a one-node cluster)"),
    })?;
    let text = String::from_utf8_lossy(&out.stdout);
    if !out.status.success() {
        return Err(RecipeError::Invalid {
            path: "sbatch".into(),
            message: format!("refused job {name}: {}", String::from_utf8_lossy(&out.stderr).trim()),
        });
    }
    text.trim().split(';').next().and_then(|j| j.parse().ok()).ok_or_else(|| RecipeError::Invalid {
        path: "sbatch".into(),
        message: format!("answered `{}` instead of a job id", text.trim()),
    })
}

fn absolute(cwd: &Path, p: &Path) -> PathBuf {
    if p.is_absolute() { p.to_path_buf() } else { cwd.join(p) }
}

/// Waits until no job of the recipe working in `work` is queued or running (polling `squeue`
/// every `every`).
pub fn wait(work: &Path, every: std::time::Duration) -> Result<()> {
    let prefix = job_prefix(work);
    loop {
        let out = Command::new("squeue")
            .args(["-h", "-o", "%j"])
            .output()
            .map_err(|e| RecipeError::Invalid { path: "squeue".into(), message: format!("cannot run squeue: {e}") })?;
        let listed = String::from_utf8_lossy(&out.stdout);
        if out.status.success() && !listed.lines().any(|l| l.starts_with(&prefix)) {
            return Ok(());
        }
        std::thread::sleep(every);
    }
}
