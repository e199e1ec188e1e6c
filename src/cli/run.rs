//! `repertoire run [FILE]`: the main job on a scenario.
//!
//! Until trained skills exist this loads the scenario, starts an episode in each spawn zone with
//! the character holding its standing pose under PD control, simulates a few seconds and prints
//! a summary (the trained sitting demo replaces the hold once the skill library lands).

use anyhow::Result;
use clap::Args;
use rand::SeedableRng;
use rand::rngs::StdRng;
use repertoire_scenes::WorldModel;
use std::path::PathBuf;
use std::sync::Arc;
use std::time::Instant;

#[derive(Debug, Args)]
pub struct RunArgs {
    /// Scenario RON file (default: the built-in scenes/sit.ron).
    pub file: Option<PathBuf>,
    /// Simulated seconds per episode.
    #[arg(long, default_value_t = 5.0)]
    pub seconds: f64,
    /// Random seed.
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
}

pub fn run(args: RunArgs) -> Result<()> {
    let scenario = super::load_scenario(args.file.as_ref())?;
    let model = Arc::new(WorldModel::build(scenario)?);
    let s = &model.scenario.scenario;
    tracing::info!(scenario = %s.name, dof = model.index.dof(), props = s.props.len(), "scene compiled");
    let mut rng = StdRng::seed_from_u64(args.seed);
    let ticks = (args.seconds / model.control_dt()).round() as usize;
    let zones: Vec<String> =
        if s.spawn.is_empty() { vec![String::new()] } else { s.spawn.iter().map(|z| z.name.clone()).collect() };

    println!(
        "scenario {} — {} s per episode, character holding its standing pose (no skills trained yet)",
        s.name, args.seconds
    );
    println!("| zone | start x | start y | heading° | pelvis height end (m) | fell | distance to first prop (m) |");
    println!("|---|---:|---:|---:|---:|---|---:|");
    let t0 = Instant::now();
    let mut steps = 0usize;
    for zone in &zones {
        let mut world = model.new_world();
        let (x, y, yaw) = if zone.is_empty() {
            world.reset(&mut rng, 0.0, 0.0, 0.0);
            (0.0, 0.0, 0.0)
        } else {
            world.reset_in_zone(zone, &mut rng)?
        };
        let mut hold = vec![0.0; model.index.dof()];
        world.joint_angles(&mut hold);
        let mut fell = false;
        for _ in 0..ticks {
            world.step(&hold)?;
            fell |= world.has_fallen();
            steps += model.substeps();
        }
        let dist = if model.props.is_empty() {
            "-".to_string()
        } else {
            let r = world.prop_relative(0);
            format!("{:.2}", (r[0] * r[0] + r[1] * r[1]).sqrt())
        };
        println!(
            "| {} | {x:.2} | {y:.2} | {:.0} | {:.3} | {} | {dist} |",
            if zone.is_empty() { "origin" } else { zone },
            yaw.to_degrees(),
            world.root_height(),
            if fell { "yes" } else { "no" }
        );
    }
    let wall = t0.elapsed().as_secs_f64();
    println!("simulated {steps} physics steps in {wall:.2} s ({:.0} steps/s)", steps as f64 / wall);
    Ok(())
}
