//! `repertoire bench world [FILE]` and `repertoire bench ppo [FILE]`.

use anyhow::Result;
use clap::Subcommand;
use repertoire_humanoid::{HumanoidEnv, Locomotion};
use repertoire_learn::bench::bench_ppo;
use repertoire_learn::policy::PolicyConfig;
use repertoire_learn::ppo::PpoConfig;
use repertoire_scenes::bench::bench_world;
use repertoire_scenes::{Feature, ObservationLayout, WorldModel};
use std::path::PathBuf;
use std::sync::Arc;

#[derive(Debug, Subcommand)]
pub enum BenchCommand {
    /// Physics steps per second: raw mj_step loop, the World step path, and N threads.
    World(WorldArgs),
    /// End-to-end PPO samples/s on the humanoid (Humanoid-v5's locomotion reward), beside the
    /// raw mj_step ceiling of the same model and the SB3 reference.
    Ppo(PpoArgs),
}

/// `bench world`'s arguments.
#[derive(Debug, clap::Args)]
pub struct WorldArgs {
    /// Scenario RON file (default: the built-in scenarios/sit.ron).
    pub file: Option<PathBuf>,
    /// Physics steps per measurement.
    #[arg(long, default_value_t = 48_000)]
    pub steps: usize,
    /// Repeats of each measurement; the fastest is reported.
    #[arg(long, default_value_t = 3)]
    pub repeats: usize,
    /// Thread counts to measure (default: 1, 2, ... up to the number of cores).
    #[arg(long, value_delimiter = ',')]
    pub threads: Vec<usize>,
}

/// `bench ppo`'s arguments.
#[derive(Debug, clap::Args)]
pub struct PpoArgs {
    /// Scenario RON file (default: the built-in scenarios/sit.ron).
    pub file: Option<PathBuf>,
    /// Parallel environments.
    #[arg(long, default_value_t = 32)]
    pub envs: usize,
    /// Rollout length per environment per iteration.
    #[arg(long, default_value_t = 64)]
    pub steps: usize,
    /// Timed PPO iterations (after one warm-up iteration).
    #[arg(long, default_value_t = 5)]
    pub iters: usize,
    /// Hidden widths of the policy and value MLPs (default: the sitting paper's 2×64 skill MLP).
    #[arg(long, value_delimiter = ',', default_value = "64,64")]
    pub hidden: Vec<usize>,
    /// Epochs over each rollout.
    #[arg(long, default_value_t = 5)]
    pub epochs: usize,
    /// Minibatches per epoch.
    #[arg(long, default_value_t = 4)]
    pub minibatches: usize,
    /// Physics steps for the raw mj_step ceiling measurement.
    #[arg(long, default_value_t = 24_000)]
    pub physics_steps: usize,
    /// Also measure PPO end to end on thread pools of these sizes (e.g. 1,2,4,8,16) and
    /// print each against one thread: how training scales with cores.
    #[arg(long, value_delimiter = ',')]
    pub threads: Vec<usize>,
}

/// SB3 PPO on Gymnasium Humanoid-v5, measured on this machine class (samples/s, low and high).
const SB3_HUMANOID: (f64, f64) = (770.0, 894.0);

pub fn run(cmd: BenchCommand) -> Result<()> {
    match cmd {
        BenchCommand::World(args) => world_cmd(args),
        BenchCommand::Ppo(args) => ppo_cmd(args),
    }
}

/// `bench world`.
fn world_cmd(WorldArgs { file, steps, repeats, threads }: WorldArgs) -> Result<()> {
    let model = Arc::new(WorldModel::build(super::load_scenario(file.as_ref())?)?);
    let cores = std::thread::available_parallelism().map_or(1, |n| n.get());
    let threads = if threads.is_empty() {
        let mut t: Vec<usize> = std::iter::successors(Some(1), |k| Some(k * 2)).take_while(|&k| k < cores).collect();
        t.push(cores);
        t
    } else {
        threads
    };
    let b = bench_world(&model, steps, repeats, &threads);
    println!(
        "bench world: {} ({} physics steps per measurement, best of {repeats}, {} substeps per control tick, {cores} cores)",
        model.scenario.path.display(),
        steps,
        b.substeps
    );
    println!("| path | threads | physics steps/s | vs raw 1-thread |");
    println!("|---|---:|---:|---:|");
    println!("| raw mj_step loop | 1 | {:.0} | 1.00 |", b.raw);
    println!("| World::step | 1 | {:.0} | {:.2} |", b.world, b.world / b.raw);
    for (k, rate) in &b.threads {
        println!("| World::step, one world per thread | {k} | {rate:.0} | {:.2} |", rate / b.raw);
    }
    if let Some((_, one)) = b.threads.iter().find(|(k, _)| *k == 1) {
        for (k, rate) in b.threads.iter().filter(|(k, _)| *k > 1) {
            println!("scaling {k} threads / 1 thread: {:.2}×", rate / one);
        }
    }
    Ok(())
}

/// `bench ppo`.
fn ppo_cmd(
    PpoArgs { file, envs, steps, iters, hidden, epochs, minibatches, physics_steps, threads }: PpoArgs,
) -> Result<()> {
    if threads.contains(&0) {
        anyhow::bail!("--threads: a pool has at least one thread");
    }
    let model = Arc::new(WorldModel::build(super::load_scenario(file.as_ref())?)?);
    let cores = std::thread::available_parallelism().map_or(1, |n| n.get());
    let layout = Arc::new(ObservationLayout::new(&model, &Feature::proprioception())?);
    let make = |_| HumanoidEnv::with_layout(&model, Arc::clone(&layout), Locomotion::default(), 1000);
    let cfg = PpoConfig {
        num_envs: envs,
        num_steps: steps,
        num_iterations: iters + 1,
        update_epochs: epochs,
        num_minibatches: minibatches,
        policy: PolicyConfig { policy_hidden: hidden.clone(), value_hidden: hidden.clone(), ..Default::default() },
        ..PpoConfig::default()
    };
    let ceiling = bench_world(&model, physics_steps, 3, &[1, cores]);
    let r = bench_ppo(cfg.clone(), (0..envs).map(make).collect(), iters);
    let per_tick = ceiling.substeps as f64;
    let raw_ctrl = ceiling.raw / per_tick;
    let all_ctrl = ceiling.threads.last().map_or(raw_ctrl, |(_, s)| s / per_tick);
    let od = layout.size;
    println!(
        "bench ppo: {} | humanoid, {} actuated joints, obs {od}, MLP {hidden:?} (policy and value) | {envs} envs × {steps} steps, {epochs} epochs × {minibatches} minibatches | {} timed iterations, {cores} cores",
        model.scenario.path.display(),
        model.index.dof(),
        r.iterations
    );
    println!(
        "| measure | samples/s (control steps) | vs SB3 Humanoid-v5 ({:.0}–{:.0}) |",
        SB3_HUMANOID.0, SB3_HUMANOID.1
    );
    println!("|---|---:|---:|");
    let vs = |x: f64| format!("{:.1}–{:.1}×", x / SB3_HUMANOID.1, x / SB3_HUMANOID.0);
    println!(
        "| raw mj_step ceiling, 1 thread ({} physics steps per sample) | {raw_ctrl:.0} | {} |",
        ceiling.substeps,
        vs(raw_ctrl)
    );
    println!("| World::step ceiling, {cores} threads | {all_ctrl:.0} | {} |", vs(all_ctrl));
    println!("| PPO end to end (rollout + update) | {:.0} | {} |", r.samples_per_sec, vs(r.samples_per_sec));
    println!(
        "physics share of PPO wall time: {:.0}% (env stepping on {cores} threads); PPO reaches {:.0}% of the {cores}-thread stepping ceiling",
        100.0 * r.env_time_fraction,
        100.0 * r.samples_per_sec / all_ctrl
    );
    println!(
        "rollout forward pass [{} × {od}]: {:.0} µs plain f32, {:.0} µs dfdx ({:.1}×)",
        r.batch,
        r.forward_plain_us,
        r.forward_dfdx_us,
        r.forward_dfdx_us / r.forward_plain_us
    );
    if !threads.is_empty() {
        thread_scaling(&cfg, &threads, || (0..envs).map(make).collect(), iters, cores)?;
    }
    Ok(())
}

/// PPO end to end on pools of each size in `threads`, against one thread.
fn thread_scaling<E: repertoire_learn::env::Env + Send>(
    cfg: &PpoConfig,
    threads: &[usize],
    envs: impl Fn() -> Vec<E> + Sync,
    iters: usize,
    cores: usize,
) -> Result<()> {
    let mut rates = Vec::new();
    for &t in threads {
        let pool = rayon::ThreadPoolBuilder::new().num_threads(t).build()?;
        let r = pool.install(|| bench_ppo(cfg.clone(), envs(), iters));
        rates.push((t, r.samples_per_sec));
    }
    let base = rates.iter().find(|(t, _)| *t == 1).or(rates.first()).map_or(1.0, |&(_, s)| s);
    let base_t = rates.iter().find(|(t, _)| *t == 1).or(rates.first()).map_or(1, |&(t, _)| t);
    println!("\n| threads | PPO samples/s | vs {base_t} thread{} |", if base_t == 1 { "" } else { "s" });
    println!("|---:|---:|---:|");
    for (t, s) in &rates {
        println!("| {t} | {s:.0} | {:.2}× |", s / base);
    }
    if threads.iter().any(|&t| t > cores) {
        println!("(this machine has {cores} cores: pools larger than that share them)");
    }
    Ok(())
}
