//! `repertoire ablate SPEC.ron`: the sitting paper's ablation tables. Each variant × seed is an
//! independent run described by a file (`runs/<variant>-s<seed>/plan.ron`: the two commands it
//! consists of), run as child processes of this binary, skipped when its report exists, so a
//! scheduler can spread the plan files over machines instead. The reports are gathered into
//! `table.md` and `table.csv`: success rate and minimum distance per zone and falls, mean ± sd over
//! seeds, with a chart of success per zone and variant (`ablation.png` / `.svg`).

use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::process::Command;
use std::sync::Mutex;
use std::sync::atomic::{AtomicUsize, Ordering};

use anyhow::{Context, Result, bail};
use repertoire_meta::eval::MetaReport;
use repertoire_report::{BarRow, grouped_bars};
use serde::{Deserialize, Serialize};

/// One variant of the full model.
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Variant {
    /// Row label.
    pub name: String,
    /// A fixed-order chain instead of the scenario's graph.
    #[serde(default)]
    pub chain: Vec<String>,
    /// The scenario's graph restricted to these skills.
    #[serde(default)]
    pub skills: Vec<String>,
    /// Another skill library (e.g. one without transition fine-tuning).
    #[serde(default)]
    pub library: Option<String>,
    /// Use the zone curriculum.
    #[serde(default = "yes")]
    pub curriculum: bool,
    /// Drive this latent model's decoder instead of the skills (`meta train --latent`; the
    /// skills' `chain`/`skills` do not apply then).
    #[serde(default)]
    pub low_level: Option<String>,
    /// Another scenario file (relative to the spec) instead of the study's, e.g. the same task
    /// with another reward; training and evaluation both run on it.
    #[serde(default)]
    pub scenario: Option<String>,
}

fn yes() -> bool {
    true
}

/// An ablation study.
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Ablation {
    /// Scenario file (relative to the spec), or omitted for the built-in default.
    #[serde(default)]
    pub scenario: Option<String>,
    /// The skill library (relative to the current directory).
    #[serde(default = "default_library")]
    pub library: String,
    /// Seeds per variant.
    pub seeds: Vec<u64>,
    /// Meta-controller PPO iterations per run.
    pub iterations: usize,
    /// Evaluation trials per zone.
    pub trials: usize,
    /// The variants.
    pub variants: Vec<Variant>,
}

fn default_library() -> String {
    super::meta::DEFAULT_LIBRARY.to_string()
}

/// What one run consists of (`plan.ron`).
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct Plan {
    /// Variant name.
    pub variant: String,
    /// Seed.
    pub seed: u64,
    /// Arguments of `repertoire` for training, then for evaluation.
    pub commands: Vec<Vec<String>>,
    /// Where the evaluation report lands.
    pub report: PathBuf,
}

fn slug(name: &str) -> String {
    name.chars().map(|c| if c.is_ascii_alphanumeric() { c.to_ascii_lowercase() } else { '-' }).collect()
}

/// Plans every run of `ab` under `out`.
pub fn plan(ab: &Ablation, spec_dir: &Path, out: &Path) -> Vec<Plan> {
    let mut plans = Vec::new();
    for v in &ab.variants {
        for &seed in &ab.seeds {
            let dir = out.join("runs").join(format!("{}-s{seed}", slug(&v.name)));
            let mut common: Vec<String> = Vec::new();
            if let Some(s) = v.scenario.as_ref().or(ab.scenario.as_ref()) {
                common.push(spec_dir.join(s).display().to_string());
            }
            common.extend(["--library".into(), v.library.clone().unwrap_or_else(|| ab.library.clone())]);
            if let Some(latent) = &v.low_level {
                common.extend(["--latent".into(), latent.clone()]);
            }
            if !v.chain.is_empty() {
                common.extend(["--chain".into(), v.chain.join(",")]);
            }
            if !v.skills.is_empty() {
                common.extend(["--skills".into(), v.skills.join(",")]);
            }
            let meta = dir.join("meta").display().to_string();
            let mut train: Vec<String> = vec!["meta".into(), "train".into()];
            train.extend(common.clone());
            train.extend(["--out".into(), meta.clone(), "--run-dir".into(), dir.join("train").display().to_string()]);
            train.extend(["--iterations".into(), ab.iterations.to_string(), "--seed".into(), seed.to_string()]);
            if !v.curriculum {
                train.push("--no-curriculum".into());
            }
            let mut eval: Vec<String> = vec!["meta".into(), "eval".into()];
            eval.extend(common);
            eval.extend(["--meta".into(), meta, "--trials".into(), ab.trials.to_string()]);
            eval.extend([
                "--seed".into(),
                (10_000 + seed).to_string(),
                "--out".into(),
                dir.join("eval").display().to_string(),
            ]);
            plans.push(Plan {
                variant: v.name.clone(),
                seed,
                commands: vec![train, eval],
                report: dir.join("eval").join("report.json"),
            });
        }
    }
    plans
}

/// Command-line overrides of a study's budget.
#[derive(Debug, Clone, Default)]
pub struct Overrides {
    /// Seeds instead of the study's (when not empty).
    pub seeds: Vec<u64>,
    /// Meta-controller iterations per run.
    pub iterations: Option<usize>,
    /// Evaluation trials per zone.
    pub trials: Option<usize>,
}

/// How `ablate` runs the study.
#[derive(Debug, Clone)]
pub enum How {
    /// Only write the plan files.
    PlanOnly,
    /// Run the plans without a report here, `jobs` at a time, then write the table.
    Here { jobs: usize },
    /// Run plan `i` only (a task of the Slurm array).
    One(usize),
    /// Submit the plans without a report as a Slurm job array and the table as a job after it;
    /// `wait` for them.
    Slurm { options: repertoire_recipe::slurm::SlurmOptions, wait: bool },
}

/// Runs (or only plans) the study in `spec` into `out` as `how` says, then writes the table and
/// its chart.
pub fn run(spec: &Path, out: &Path, overrides: &Overrides, how: How) -> Result<()> {
    let plan_only = matches!(how, How::PlanOnly);
    let ab: Ablation = repertoire_files::parse_ron(spec, &repertoire_files::read_text(spec)?)?;
    let mut ab = ab;
    if !overrides.seeds.is_empty() {
        ab.seeds = overrides.seeds.clone();
    }
    ab.iterations = overrides.iterations.unwrap_or(ab.iterations);
    ab.trials = overrides.trials.unwrap_or(ab.trials);
    if ab.seeds.is_empty() || ab.variants.is_empty() {
        bail!("{}: an ablation needs at least one seed and one variant", spec.display());
    }
    if let Some(v) = ab.variants.iter().find(|v| v.low_level.is_some() && (!v.chain.is_empty() || !v.skills.is_empty()))
    {
        bail!(
            "{}: variant `{}` drives a latent low level, so it cannot also restrict the skills (`chain`, `skills`)",
            spec.display(),
            v.name
        );
    }
    let plans = plan(&ab, spec.parent().unwrap_or(Path::new(".")), out);
    let exe = std::env::current_exe().context("locating the repertoire binary")?;
    let mut todo = Vec::new();
    for p in &plans {
        let dir = run_dir(p);
        std::fs::create_dir_all(dir).with_context(|| format!("{}: cannot create", dir.display()))?;
        let text = ron::ser::to_string_pretty(p, ron::ser::PrettyConfig::new())?;
        repertoire_report::write_atomic(&dir.join("plan.ron"), text.as_bytes())?;
        if !plan_only && !p.report.exists() {
            todo.push(p);
        }
    }
    match how {
        How::PlanOnly | How::Here { .. } => {}
        How::One(i) => {
            let p =
                plans.get(i).with_context(|| format!("{}: no run {i} (it plans {})", spec.display(), plans.len()))?;
            return run_plan(&exe, p, false, None);
        }
        How::Slurm { options, wait } => {
            return submit(&exe, spec, out, overrides, &plans, &options, wait);
        }
    }
    if let How::Here { jobs } = how {
        run_plans(&exe, &todo, jobs)?;
    }
    if plan_only {
        println!("{} runs planned under {}", plans.len(), out.join("runs").display());
        return Ok(());
    }
    let (md, csv, zones, bars) = table(&ab, &plans)?;
    repertoire_report::write_atomic(&out.join("table.md"), md.as_bytes())?;
    repertoire_report::write_atomic(&out.join("table.csv"), csv.as_bytes())?;
    let seeds = ab.seeds.iter().map(u64::to_string).collect::<Vec<_>>().join(", ");
    let title = format!(
        "success by zone ({} iterations per run, {} trials per zone; seed{} {seeds})",
        ab.iterations,
        ab.trials,
        if ab.seeds.len() > 1 { "s" } else { "" }
    );
    grouped_bars(&out.join("ablation"), &title, &zones, &bars)?;
    print!("{md}");
    println!("\ntable.md, table.csv and ablation.png/.svg written to {}", out.display());
    Ok(())
}

/// The study's runs without a report as one Slurm job array (task `i` runs plan `i`), then a job
/// after the whole array that runs `ablate` again to gather the table (nothing is left to run
/// by then).
fn submit(
    exe: &Path,
    spec: &Path,
    out: &Path,
    overrides: &Overrides,
    plans: &[Plan],
    options: &repertoire_recipe::slurm::SlurmOptions,
    wait: bool,
) -> Result<()> {
    use repertoire_recipe::run::shell_quote;
    use repertoire_recipe::slurm;
    let mut args: Vec<String> =
        vec!["ablate".into(), spec.display().to_string(), "--out".into(), out.display().to_string()];
    if !overrides.seeds.is_empty() {
        args.push(format!("--seeds={}", overrides.seeds.iter().map(u64::to_string).collect::<Vec<_>>().join(",")));
    }
    if let Some(n) = overrides.iterations {
        args.push(format!("--iterations={n}"));
    }
    if let Some(n) = overrides.trials {
        args.push(format!("--trials={n}"));
    }
    let line = |extra: &[String]| {
        std::iter::once(exe.display().to_string())
            .chain(args.iter().cloned())
            .chain(extra.iter().cloned())
            .map(|a| shell_quote(&a))
            .collect::<Vec<_>>()
            .join(" ")
    };
    let todo: Vec<String> =
        plans.iter().enumerate().filter(|(_, p)| !p.report.exists()).map(|(i, _)| i.to_string()).collect();
    let cwd = std::env::current_dir().context("reading the working folder")?;
    let logs = cwd.join(out).join("slurm");
    std::fs::create_dir_all(&logs).with_context(|| format!("{}: cannot create", logs.display()))?;
    let name = slurm::job_prefix(out);
    let mut after = Vec::new();
    if !todo.is_empty() {
        let mut extra = vec![format!("--array={}", todo.join(","))];
        extra.extend(options.args(None));
        let wrap = format!("exec {} --run-index \"$SLURM_ARRAY_TASK_ID\"", line(&[]));
        let array = slurm::sbatch(&name, &cwd, &logs.join("run-%a-%A.out"), &[], &extra, &wrap)?;
        println!("{} runs submitted as job array {array} (logs in {})", todo.len(), logs.display());
        after.push(array);
    }
    let table = slurm::sbatch(
        &name,
        &cwd,
        &logs.join("table-%j.out"),
        &after,
        &options.args(Some(1)),
        &format!("exec {}", line(&[])),
    )?;
    println!("job {table} gathers the table into {}", out.display());
    if wait {
        slurm::wait(out, std::time::Duration::from_secs(2))?;
        if !out.join("table.md").exists() {
            bail!("the ablation's jobs ended without a table; their logs are in {}", logs.display());
        }
        print!(
            "{}",
            std::fs::read_to_string(out.join("table.md"))
                .with_context(|| out.join("table.md").display().to_string())?
        );
    }
    Ok(())
}

/// A run's folder (`runs/<variant>-s<seed>`, the one its plan file lies in).
fn run_dir(p: &Plan) -> &Path {
    p.report.parent().and_then(Path::parent).expect("runs/<name>/eval/report.json")
}

/// Runs `plans` (each its commands in order), `jobs` at a time. One job shares this process's
/// terminal with its run; with more, each run writes its output to `log.txt` in its folder, its
/// rayon pool gets an equal share of the cores (unless `RAYON_NUM_THREADS` is set) and a line is
/// printed as each ends. Every run is tried; the ones that failed are listed at the end.
fn run_plans(exe: &Path, plans: &[&Plan], jobs: usize) -> Result<()> {
    let jobs = jobs.clamp(1, plans.len().max(1));
    let threads = (jobs > 1 && std::env::var_os("RAYON_NUM_THREADS").is_none())
        .then(|| (std::thread::available_parallelism().map_or(1, |n| n.get()) / jobs).max(1));
    let next = AtomicUsize::new(0);
    let failures = Mutex::new(Vec::new());
    std::thread::scope(|s| {
        for _ in 0..jobs {
            s.spawn(|| {
                while let Some(p) = plans.get(next.fetch_add(1, Ordering::Relaxed)) {
                    match run_plan(exe, p, jobs > 1, threads) {
                        Ok(()) if jobs > 1 => println!("{} (seed {}): done", p.variant, p.seed),
                        Ok(()) => {}
                        Err(e) => failures.lock().expect("never poisoned").push(format!("{e:#}")),
                    }
                }
            });
        }
    });
    let failures = failures.into_inner().expect("never poisoned");
    if !failures.is_empty() {
        bail!("{} of {} runs failed:\n{}", failures.len(), plans.len(), failures.join("\n"));
    }
    Ok(())
}

/// Runs one plan's commands in order; `to_log`: their output into the run's `log.txt`.
fn run_plan(exe: &Path, p: &Plan, to_log: bool, threads: Option<usize>) -> Result<()> {
    let dir = run_dir(p);
    let log = dir.join("log.txt");
    for args in &p.commands {
        tracing::info!(variant = %p.variant, seed = p.seed, command = %args.join(" "), "ablation run");
        let mut cmd = Command::new(exe);
        cmd.args(args);
        if let Some(t) = threads {
            cmd.env("RAYON_NUM_THREADS", t.to_string());
        }
        if to_log {
            let file = std::fs::OpenOptions::new()
                .create(true)
                .append(true)
                .open(&log)
                .with_context(|| format!("{}: cannot open", log.display()))?;
            cmd.stdout(file.try_clone().with_context(|| log.display().to_string())?).stderr(file);
        }
        let status = cmd.status().with_context(|| format!("running {}", args.join(" ")))?;
        if !status.success() {
            let output = if to_log { format!(", its output in {}", log.display()) } else { String::new() };
            bail!(
                "`repertoire {}` failed ({status}); the plan is in {}{output}",
                args.join(" "),
                dir.join("plan.ron").display()
            );
        }
    }
    Ok(())
}

/// "m ± s%" over `seeds` runs; a spread needs two seeds or more, so one run gives "m%".
fn percent(m: f64, s: f64, seeds: usize) -> String {
    if seeds > 1 { format!("{m:.1} ± {s:.1}%") } else { format!("{m:.1}%") }
}

/// Mean and sample standard deviation.
fn mean_sd(v: &[f64]) -> (f64, f64) {
    let n = v.len().max(1) as f64;
    let m = v.iter().sum::<f64>() / n;
    let var = v.iter().map(|x| (x - m).powi(2)).sum::<f64>() / (n - 1.0).max(1.0);
    (m, var.sqrt())
}

/// The study's table (Markdown and CSV) and its chart's rows (success per zone, mean ± sd).
fn table(ab: &Ablation, plans: &[Plan]) -> Result<(String, String, Vec<String>, Vec<BarRow>)> {
    let mut reports: Vec<(String, MetaReport)> = Vec::new();
    for p in plans {
        let text = std::fs::read_to_string(&p.report).with_context(|| format!("reading {}", p.report.display()))?;
        reports.push((p.variant.clone(), serde_json::from_str(&text).with_context(|| p.report.display().to_string())?));
    }
    let zones: Vec<String> =
        reports.first().map(|(_, r)| r.zones.iter().map(|z| z.zone.clone()).collect()).unwrap_or_default();
    let mut md = format!(
        "| variant | seeds | {} | falls, all zones |\n",
        zones.iter().map(|z| format!("{z}: success / min dist (m)")).collect::<Vec<_>>().join(" | ")
    );
    let _ = writeln!(md, "|---|---:|{}---:|", "---:|".repeat(zones.len()));
    let mut csv = String::from(
        "variant,zone,seeds,success_mean,success_sd,min_distance_mean,min_distance_sd,fall_rate_mean,fall_rate_sd\n",
    );
    let mut bars = Vec::new();
    for v in &ab.variants {
        let mine: Vec<&MetaReport> = reports.iter().filter(|(n, _)| n == &v.name).map(|(_, r)| r).collect();
        let mut cells = Vec::new();
        let mut values = Vec::new();
        let mut falls = Vec::new();
        for z in &zones {
            let rows: Vec<_> = mine.iter().filter_map(|r| r.zones.iter().find(|row| &row.zone == z)).collect();
            let (sm, ss) = mean_sd(&rows.iter().map(|r| 100.0 * r.success_rate).collect::<Vec<_>>());
            let (dm, ds) = mean_sd(&rows.iter().map(|r| r.min_distance_mean).collect::<Vec<_>>());
            let (fm, fs) = mean_sd(&rows.iter().map(|r| 100.0 * r.fall_rate).collect::<Vec<_>>());
            let distance = if rows.len() > 1 { format!("{dm:.2} ± {ds:.2}") } else { format!("{dm:.2}") };
            cells.push(format!("{} / {distance}", percent(sm, ss, rows.len())));
            values.push((sm, if rows.len() > 1 { ss } else { 0.0 }));
            falls.push(percent(fm, fs, rows.len()));
            let _ = writeln!(csv, "{},{z},{},{sm:.3},{ss:.3},{dm:.4},{ds:.4},{fm:.3},{fs:.3}", v.name, mine.len());
        }
        // The last zone is "all" where the evaluation covers several.
        let falls = falls.pop().unwrap_or_default();
        let _ = writeln!(md, "| {} | {} | {} | {falls} |", v.name, mine.len(), cells.join(" | "));
        bars.push(BarRow { label: v.name.clone(), values });
    }
    Ok((md, csv, zones, bars))
}
