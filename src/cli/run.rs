//! `repertoire run [FILE]`: the main job on a scenario.
//!
//! With a trained meta-controller (default: the committed `library/meta`) this runs it
//! with the skill library on the scenario and evaluates a quick number of trials per spawn
//! zone, printing the sitting table. A scenario driven through the latent low level
//! (`low_level: Latent(..)`) runs its latent high level instead (default
//! `library/latent-meta-<scenario name>`). Without a trained controller it says how to
//! train one and shows the scene with the character holding its standing pose under PD control.

use anyhow::Result;
use clap::Args;
use rand::SeedableRng;
use rand::rngs::StdRng;
use repertoire_meta::evaluation::{EvalPlan, Worst};
use repertoire_meta::{MetaSetup, TaskSpec};
use repertoire_scenes::WorldModel;
use std::path::PathBuf;
use std::sync::Arc;
use std::time::Instant;

use super::controller::{Choice, ControllerArgs, Loaded, ScenarioArgs};

#[derive(Debug, Args)]
pub struct RunArgs {
    #[command(flatten)]
    pub scenario: ScenarioArgs,
    #[command(flatten)]
    pub controller: ControllerArgs,
    /// Simulated seconds per episode.
    #[arg(long, default_value_t = 5.0)]
    pub seconds: f64,
    /// Random seed.
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    /// Trials per spawn zone.
    #[arg(long, default_value_t = 20)]
    pub trials: usize,
    /// Where the evaluation's reports and the worst trial of each zone (recording and replay
    /// page) go (default: runs/run-<time>-s<seed>).
    #[arg(long)]
    pub out: Option<PathBuf>,
}

pub fn run(args: RunArgs) -> Result<()> {
    if let Some((model, dir)) = super::meta::latent_low_level(args.scenario.file.as_ref(), None)? {
        return run_latent(model, &dir, args);
    }
    let choice = args.controller.choice()?;
    let meta = match &args.controller.meta {
        Some(m) => m.clone(),
        None => default_meta(&args.scenario.library, args.scenario.file.as_ref())?,
    };
    if choice == Choice::Planner {
        return run_controller(&args, Vec::new());
    }
    if meta.join("meta.ron").exists() {
        // The skills the controller was trained over (a warehouse controller may have been
        // trained on walk and the turns only); its manifest is checked in full when it loads.
        let skills: Vec<String> = std::fs::read_to_string(meta.join("meta.ron"))
            .ok()
            .and_then(|text| ron::from_str::<repertoire_meta::train::MetaManifest>(&text).ok())
            .map(|m| m.skills)
            .unwrap_or_default();
        return run_controller(&args, skills);
    }
    println!(
        "no trained meta-controller at {} (train one with `repertoire meta train`); showing the scene instead",
        meta.display()
    );
    show_scene(&args)
}

/// A quick evaluation of the scenario's controller over `skills` (all of the scenario's when
/// empty): `trials` per zone with the worst of each recorded (sitting), `trials` episodes
/// (warehouse) or a 3 × 3 strike zone with `trials / 9` throws per cell (toss), the worst
/// three recorded.
fn run_controller(args: &RunArgs, skills: Vec<String>) -> Result<()> {
    let setup = super::meta::setup(args.scenario.file.as_ref(), &args.scenario.library, &[], &skills)?;
    let loaded = Loaded::load(&args.controller, &setup, &args.scenario.library, args.seed)?;
    let sitting = matches!(setup.task, TaskSpec::Sit { .. });
    println!(
        "scenario {} — {} over skills {}{}",
        setup.model.scenario.scenario.name,
        loaded.describe()?,
        setup.skills.iter().map(|s| s.name.as_str()).collect::<Vec<_>>().join(", "),
        if sitting { format!("; {} trials per zone", args.trials) } else { String::new() }
    );
    let (plan, worst) = quick_plan(&setup, args);
    let secs = std::time::SystemTime::now().duration_since(std::time::UNIX_EPOCH).map_or(0, |d| d.as_secs());
    let out = args.out.clone().unwrap_or_else(|| PathBuf::from(format!("runs/run-{secs}-s{}", args.seed)));
    super::meta::eval::evaluate_and_report(&setup, loaded.controller()?.as_ref(), &plan, (worst, &[]), &out)?;
    println!("`repertoire meta eval` runs the full evaluation");
    Ok(())
}

/// Worst warehouse episodes or toss throws `run` records.
const WORST_TASK_EPISODES: usize = 3;

/// `run`'s quick evaluation of `setup`'s task and the episodes it records.
fn quick_plan(setup: &MetaSetup, args: &RunArgs) -> (EvalPlan, Worst) {
    let s = &setup.model.scenario.scenario;
    let plan = EvalPlan {
        zones: s.spawn.iter().map(|z| z.name.clone()).collect(),
        trials: args.trials,
        batch: 64,
        seed: args.seed,
        pickup: None,
        strike_zone: (3, 3, (args.trials / 9).max(1)),
    };
    let worst = match setup.task {
        TaskSpec::Sit { .. } => Worst::PerZone(1),
        _ => Worst::Overall(WORST_TASK_EPISODES),
    };
    (plan, worst)
}

/// No trained controller: the scene with the character holding its standing pose.
fn show_scene(args: &RunArgs) -> Result<()> {
    let scenario = super::load_scenario(args.scenario.file.as_ref())?;
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

/// `run` on a scenario whose low level is a latent model: a quick evaluation of its trained
/// latent high level, or, without one, how to train it.
fn run_latent(model: Arc<WorldModel>, dir: &std::path::Path, args: RunArgs) -> Result<()> {
    if args.controller.choice()? != Choice::Learned {
        anyhow::bail!("--controller chooses among the skills: a latent low level has only its trained high level");
    }
    let library = args.scenario.library;
    let meta = args.controller.meta.clone().unwrap_or_else(|| super::meta::default_latent_meta(&library, &model));
    let name = model.scenario.scenario.name.clone();
    if !meta.join(repertoire_meta::latent::MANIFEST_FILE).exists() {
        println!(
            "scenario {name} runs through the latent model {}, but no latent high level is trained in {}: \
             train one with `repertoire meta train {}`",
            dir.display(),
            meta.display(),
            model.scenario.path.display()
        );
        return Ok(());
    }
    println!(
        "scenario {name} — latent high level {} through {}; {} trials per zone",
        meta.display(),
        dir.display(),
        args.trials
    );
    let zones = model.scenario.scenario.spawn.iter().map(|z| z.name.clone()).collect();
    let secs = std::time::SystemTime::now().duration_since(std::time::UNIX_EPOCH).map_or(0, |d| d.as_secs());
    let out = args.out.unwrap_or_else(|| PathBuf::from(format!("runs/run-{secs}-s{}", args.seed)));
    let plan =
        EvalPlan { zones, trials: args.trials, batch: 64, seed: args.seed, pickup: None, strike_zone: (0, 0, 0) };
    let eval = super::meta::LatentEval { library, meta: Some(meta), out: Some(out) };
    super::meta::eval_latent(model, dir, eval, &plan, (Worst::PerZone(1), &[]))
}

/// The meta-controller folder `run` looks in for `file`'s scenario (see
/// [`super::meta::default_meta`]), read from the scenario's task without loading skills.
fn default_meta(library: &std::path::Path, file: Option<&PathBuf>) -> Result<PathBuf> {
    let scenario = super::load_scenario(file)?;
    let s = &scenario.scenario;
    Ok(super::meta::default_meta(library, &s.task, &s.name))
}
