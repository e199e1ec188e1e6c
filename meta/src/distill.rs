//! Distilling the planner into a meta-controller: the search-based reference
//! ([`crate::planner`]) plays seeded episodes from the scenario's zones; its decisions, with the
//! observation and the options the graph allowed, are the demonstrations a fresh hybrid policy
//! is fitted to by behaviour cloning ([`Ppo::behaviour_clone`]). The result is an ordinary
//! meta-controller (`meta.ron` + `meta.safetensors`): it acts from its observation alone, at no
//! search cost, and `meta eval --meta DIR` evaluates it.

use std::path::PathBuf;
use std::sync::Arc;
use std::time::Instant;

use rand::SeedableRng;
use rayon::prelude::*;
use repertoire_learn::env::{Env, EnvRng};
use repertoire_learn::ppo::{Ppo, PpoConfig};

use crate::env::{MetaEnv, MetaSetup};
use crate::error::{MetaError, Result};
use crate::planner::{Planner, PlannerConfig};
use crate::train::{MetaManifest, MetaTrainOptions, Session, TrainedRun, save_controller};

/// Options of a distillation.
#[derive(Debug, Clone)]
pub struct DistillOptions {
    /// Where the controller and its manifest go.
    pub out: PathBuf,
    /// Planner episodes per zone.
    pub episodes: usize,
    /// Zones the episodes start in.
    pub zones: Vec<String>,
    /// The planner's search.
    pub planner: PlannerConfig,
    /// Keep only the decisions of episodes that succeeded.
    pub successful_only: bool,
    /// Passes over the demonstrations, and rows per gradient step.
    pub epochs: usize,
    /// Rows per gradient step.
    pub batch: usize,
    /// The network and optimiser (`default_ppo()`; its seed seeds the fit).
    pub ppo: PpoConfig,
    /// Seed of the planner episodes.
    pub seed: u64,
    /// The command line.
    pub command: String,
    /// PPO after the fit, from the fitted policy (its `ppo.num_iterations`, run directory and
    /// curriculum); `None`: the fit alone. The fitted controller is then also kept, in
    /// `out/fitted`, so the two can be compared.
    pub then_train: Option<MetaTrainOptions>,
}

/// The demonstrations one planner episode left.
struct Episode {
    obs: Vec<f32>,
    actions: Vec<f32>,
    masks: Vec<bool>,
    success: bool,
}

/// What a distillation did.
#[derive(Debug, Clone, PartialEq)]
pub struct DistillFigures {
    /// Planner episodes run, and how many succeeded.
    pub episodes: usize,
    /// Successful planner episodes.
    pub successes: usize,
    /// Decisions fitted (the manifest's `samples` adds PPO's decisions after the fit).
    pub demonstrations: usize,
    /// Mean negative log-likelihood per epoch.
    pub losses: Vec<f32>,
    /// Seconds spent running the planner, and fitting.
    pub planning_s: f64,
    /// Seconds fitting.
    pub fitting_s: f64,
}

fn run_episode(setup: &Arc<MetaSetup>, cfg: PlannerConfig, seed: u64, stream: u64) -> Episode {
    let mut env = MetaEnv::new(Arc::clone(setup));
    let mut planner = Planner::new(Arc::clone(setup), cfg);
    let mut rng = EnvRng::seed_from_u64(seed);
    rng.set_stream(stream);
    let (od, ad, k) = (env.obs_dim(), env.act_dim(), setup.skills.len());
    let mut obs = vec![0.0; od];
    let mut act = vec![0.0; ad];
    let mut mask = vec![false; k];
    let mut ep = Episode { obs: Vec::new(), actions: Vec::new(), masks: Vec::new(), success: false };
    env.reset(&mut rng, &mut obs);
    loop {
        env.option_mask(&mut mask);
        planner.act(&env, &mut act);
        ep.obs.extend_from_slice(&obs);
        ep.actions.extend_from_slice(&act);
        ep.masks.extend_from_slice(&mask);
        let out = env.step(&act, &mut obs);
        if out.terminated || out.truncated {
            ep.success = out.terms[0] > 0.5;
            return ep;
        }
    }
}

/// Runs the planner's episodes and fits a controller to them; writes it to `opts.out`.
pub fn distill(setup: Arc<MetaSetup>, opts: &DistillOptions) -> Result<(MetaManifest, DistillFigures)> {
    setup.check_zones(&opts.zones)?;
    let started = Instant::now();
    let mut episodes = Vec::new();
    for (zi, zone) in opts.zones.iter().enumerate() {
        *setup.zones.write().expect("never poisoned") = vec![zone.clone()];
        let batch: Vec<Episode> = (0..opts.episodes)
            .into_par_iter()
            .map(|i| run_episode(&setup, opts.planner, opts.seed, (zi * opts.episodes + i) as u64 + 1))
            .collect();
        tracing::info!(
            zone = %zone,
            episodes = batch.len(),
            successes = batch.iter().filter(|e| e.success).count(),
            "planner episodes"
        );
        episodes.extend(batch);
    }
    *setup.zones.write().expect("never poisoned") =
        setup.model.scenario.scenario.spawn.iter().map(|z| z.name.clone()).collect();
    let planning_s = started.elapsed().as_secs_f64();
    let successes = episodes.iter().filter(|e| e.success).count();
    let kept: Vec<&Episode> = episodes.iter().filter(|e| e.success || !opts.successful_only).collect();
    let obs: Vec<f32> = kept.iter().flat_map(|e| e.obs.iter().copied()).collect();
    let actions: Vec<f32> = kept.iter().flat_map(|e| e.actions.iter().copied()).collect();
    let masks: Vec<bool> = kept.iter().flat_map(|e| e.masks.iter().copied()).collect();
    let demonstrations = obs.len() / setup.obs_dim().max(1);
    if demonstrations == 0 {
        return Err(MetaError::Invalid(format!(
            "the planner left no demonstrations to fit ({} episodes, {successes} successful{})",
            episodes.len(),
            if opts.successful_only { "; --successful-only keeps only those" } else { "" }
        )));
    }

    let fit_started = Instant::now();
    let envs = (0..opts.ppo.num_envs.max(1)).map(|_| MetaEnv::new(Arc::clone(&setup))).collect();
    let mut ppo = Ppo::new(opts.ppo.clone(), envs);
    let losses = ppo.behaviour_clone(&obs, &actions, &masks, opts.epochs, opts.batch).map_err(MetaError::Invalid)?;
    let fitting_s = fit_started.elapsed().as_secs_f64();
    let fitted = |samples: u64, seconds: f64| TrainedRun {
        samples,
        seconds,
        curriculum: false,
        advances: Vec::new(),
        command: opts.command.clone(),
        resumed: Vec::new(),
        warm_start: None,
    };
    let (ppo, mut run) = match &opts.then_train {
        Some(train) => {
            let seconds = started.elapsed().as_secs_f64();
            save_controller(&setup, &ppo, &opts.out.join("fitted"), fitted(demonstrations as u64, seconds))?;
            ppo.cfg.num_iterations = train.ppo.num_iterations;
            let mut session = Session::fresh(ppo, &setup.model, &setup.zones, train, setup.low_level())?;
            session.run(train, "skills, from the planner")?;
            session.finish()
        }
        None => (ppo, fitted(0, 0.0)),
    };
    run.samples += demonstrations as u64;
    run.seconds = started.elapsed().as_secs_f64();
    let manifest = save_controller(&setup, &ppo, &opts.out, run)?;
    let figures = DistillFigures { episodes: episodes.len(), successes, demonstrations, losses, planning_s, fitting_s };
    Ok((manifest, figures))
}
