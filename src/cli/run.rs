//! `repertoire run [FILE]`: the main job on a scenario.
//!
//! With a trained meta-controller (default: the committed `skills/library/meta`) this runs it
//! with the skill library on the scenario and evaluates a quick number of trials per spawn
//! zone, printing the sitting table. A scenario driven through the latent low level
//! (`low_level: Latent(..)`) runs its latent high level instead (default
//! `skills/library/latent-meta-<scenario name>`). Without a trained controller it says how to
//! train one and shows the scene with the character holding its standing pose under PD control.

use anyhow::Result;
use clap::Args;
use rand::SeedableRng;
use rand::rngs::StdRng;
use repertoire_meta::eval::Controller;
use repertoire_meta::lookahead::LookaheadConfig;
use repertoire_meta::task_eval::{evaluate_toss, evaluate_warehouse, save_worst_toss, save_worst_warehouse};
use repertoire_meta::{MetaSetup, TaskSpec};
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
    /// Skill library.
    #[arg(long, default_value = super::meta::DEFAULT_LIBRARY)]
    pub library: PathBuf,
    /// Trained meta-controller (default: LIBRARY/meta for sitting,
    /// LIBRARY/meta-<scenario name> otherwise; LIBRARY is --library).
    #[arg(long)]
    pub meta: Option<PathBuf>,
    /// Trials per spawn zone.
    #[arg(long, default_value_t = 20)]
    pub trials: usize,
    /// Sitting: the controller checked in a copy of each episode before it commits, K
    /// candidates a search (`meta eval --lookahead K`); it never seats fewer and costs K
    /// simulated episodes a search.
    #[arg(long, value_parser = clap::value_parser!(u32).range(1..))]
    pub lookahead: Option<u32>,
    /// Most searches per episode with --lookahead.
    #[arg(long, default_value_t = LookaheadConfig::default().searches, requires = "lookahead")]
    pub lookahead_searches: u32,
    /// Where the evaluation's reports and the worst trial of each zone (recording and replay
    /// page) go (default: runs/run-<time>-s<seed>).
    #[arg(long)]
    pub out: Option<PathBuf>,
}

pub fn run(args: RunArgs) -> Result<()> {
    if let Some((model, dir)) = super::meta::latent_low_level(args.file.as_ref(), None)? {
        return run_latent(model, &dir, args);
    }
    let meta = match &args.meta {
        Some(m) => m.clone(),
        None => default_meta(&args.library, args.file.as_ref())?,
    };
    if meta.join("meta.ron").exists() {
        // The skills the controller was trained over (a warehouse controller may have been
        // trained on walk and the turns only); its manifest is checked in full by `load`.
        let skills: Vec<String> = std::fs::read_to_string(meta.join("meta.ron"))
            .ok()
            .and_then(|text| ron::from_str::<repertoire_meta::train::MetaManifest>(&text).ok())
            .map(|m| m.skills)
            .unwrap_or_default();
        let setup = super::meta::setup(args.file.as_ref(), &args.library, &[], &skills)?;
        let (manifest, head) = repertoire_meta::train::load(&meta, &setup)?;
        if !matches!(setup.task, TaskSpec::Sit { .. }) {
            if args.lookahead.is_some() {
                anyhow::bail!(
                    "{}: --lookahead checks sitting controllers only (this scenario is {})",
                    setup.model.scenario.path.display(),
                    setup.task.name()
                );
            }
            return run_task(&setup, &head, &meta, &manifest.iterations_label(), &args);
        }
        let controller = match args.lookahead {
            Some(k) => Controller::Lookahead(
                &head,
                LookaheadConfig {
                    candidates: k as usize,
                    searches: args.lookahead_searches,
                    seed: args.seed,
                    ..LookaheadConfig::default()
                },
            ),
            None => Controller::Learned(&head),
        };
        let zones: Vec<String> = setup.model.scenario.scenario.spawn.iter().map(|z| z.name.clone()).collect();
        let looking = match args.lookahead {
            Some(k) => format!(", looking ahead {k} candidates a search, at most {} searches", args.lookahead_searches),
            None => String::new(),
        };
        println!(
            "scenario {} — meta-controller {} ({}{looking}) over skills {}; {} trials per zone",
            setup.model.scenario.scenario.name,
            meta.display(),
            manifest.iterations_label(),
            manifest.skills.join(", "),
            args.trials
        );
        let t0 = Instant::now();
        let report = repertoire_meta::eval::evaluate(&setup, controller, &zones, args.trials, 64, args.seed)?;
        print!("{}", report.markdown());
        println!(
            "
{} trials in {:.1} s; `repertoire meta eval` runs the full evaluation",
            report.trials.len(),
            t0.elapsed().as_secs_f64()
        );
        let secs = std::time::SystemTime::now().duration_since(std::time::UNIX_EPOCH).map_or(0, |d| d.as_secs());
        let out = args.out.unwrap_or_else(|| PathBuf::from(format!("runs/run-{secs}-s{}", args.seed)));
        report.write(&out)?;
        let recs = repertoire_meta::eval::save_worst(
            &setup,
            controller,
            &report,
            &zones,
            args.trials,
            args.seed,
            1,
            true,
            &out.join("worst"),
        )?;
        super::replay::pages_beside(&recs);
        println!(
            "reports and the worst trial of each zone written to {} (watch: repertoire replay {})",
            out.display(),
            out.display()
        );
        return Ok(());
    }
    println!(
        "no trained meta-controller at {} (train one with `repertoire meta train`); showing the scene instead",
        meta.display()
    );
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

/// `run` on a scenario whose low level is a latent model: a quick evaluation of its trained
/// latent high level, or, without one, how to train it.
fn run_latent(model: Arc<WorldModel>, dir: &std::path::Path, args: RunArgs) -> Result<()> {
    let meta = args.meta.clone().unwrap_or_else(|| super::meta::default_latent_meta(&args.library, &model));
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
    let eval = super::meta::LatentEval {
        library: args.library,
        meta: Some(meta),
        trials: args.trials,
        zones,
        batch: 64,
        seed: args.seed,
        out: Some(out),
    };
    super::meta::eval_latent(model, dir, eval)
}

/// The meta-controller folder `run` looks in for `file`'s scenario (see
/// [`super::meta::default_meta`]), read from the scenario's task without loading skills.
fn default_meta(library: &std::path::Path, file: Option<&PathBuf>) -> Result<PathBuf> {
    let scenario = super::load_scenario(file)?;
    let s = &scenario.scenario;
    Ok(super::meta::default_meta(library, &s.task, &s.name))
}

/// A quick evaluation of a warehouse or toss meta-controller: `trials` episodes (warehouse) or
/// a 3 × 3 strike zone with `trials / 9` throws per cell (toss).
/// Worst warehouse episodes or toss throws `run` records.
const WORST_TASK_EPISODES: usize = 3;

fn run_task(
    setup: &Arc<MetaSetup>,
    head: &repertoire_learn::acting::ActingHybrid,
    meta: &std::path::Path,
    iterations: &str,
    args: &RunArgs,
) -> Result<()> {
    println!(
        "scenario {} — meta-controller {} ({iterations}) over skills {}",
        setup.model.scenario.scenario.name,
        meta.display(),
        setup.skills.iter().map(|s| s.name.as_str()).collect::<Vec<_>>().join(", ")
    );
    let secs = std::time::SystemTime::now().duration_since(std::time::UNIX_EPOCH).map_or(0, |d| d.as_secs());
    let out = args.out.clone().unwrap_or_else(|| PathBuf::from(format!("runs/run-{secs}-s{}", args.seed)));
    let t0 = Instant::now();
    // The worst episodes are recorded (with replay pages when three.js is installed), as for sitting.
    let worst = out.join("worst");
    let recs = if let TaskSpec::Warehouse(_) = setup.task {
        let mut report = evaluate_warehouse(setup, head, args.trials, None, args.seed)?;
        let recs = save_worst_warehouse(setup, head, &mut report, args.seed, WORST_TASK_EPISODES, &worst, &out)?;
        print!("{}", report.markdown());
        report.write(&out)?;
        recs
    } else {
        let mut report = evaluate_toss(setup, head, 3, 3, (args.trials / 9).max(1), args.seed)?;
        let recs = save_worst_toss(setup, head, &mut report, args.seed, WORST_TASK_EPISODES, &worst, &out)?;
        print!("{}", report.markdown());
        report.write(&out)?;
        recs
    };
    super::replay::pages_beside(&recs);
    println!(
        "\nin {:.1} s; reports written to {}; `repertoire meta eval` runs the full evaluation",
        t0.elapsed().as_secs_f64(),
        out.display()
    );
    Ok(())
}
