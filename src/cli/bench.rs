//! `repertoire bench world FILE`.

use anyhow::Result;
use clap::Subcommand;
use repertoire_scenes::WorldModel;
use repertoire_scenes::bench::bench_world;
use std::path::PathBuf;
use std::sync::Arc;

#[derive(Debug, Subcommand)]
pub enum BenchCommand {
    /// Physics steps per second: raw mj_step loop, the World step path, and N threads.
    World {
        /// Scenario RON file (default: the built-in scenes/sit.ron).
        file: Option<PathBuf>,
        /// Physics steps per measurement.
        #[arg(long, default_value_t = 48_000)]
        steps: usize,
        /// Repeats of each measurement; the fastest is reported.
        #[arg(long, default_value_t = 3)]
        repeats: usize,
        /// Thread counts to measure (default: 1, 2, ... up to the number of cores).
        #[arg(long, value_delimiter = ',')]
        threads: Vec<usize>,
    },
}

pub fn run(cmd: BenchCommand) -> Result<()> {
    match cmd {
        BenchCommand::World { file, steps, repeats, threads } => {
            let model = Arc::new(WorldModel::build(super::load_scenario(file.as_ref())?)?);
            let cores = std::thread::available_parallelism().map_or(1, |n| n.get());
            let threads = if threads.is_empty() {
                let mut t: Vec<usize> =
                    std::iter::successors(Some(1), |k| Some(k * 2)).take_while(|&k| k < cores).collect();
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
    }
}
