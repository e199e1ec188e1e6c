//! Distilling a search into a meta-controller: a teacher that looks ahead in copies of the
//! episode plays seeded episodes from the scenario's zones; its decisions, with the observation
//! and the options the graph allowed, are the demonstrations a hybrid policy is fitted to by
//! behaviour cloning ([`Ppo::behaviour_clone`]). The teacher is the search-based planner
//! ([`crate::search::planner`]; the fit starts from a fresh policy) or a trained controller's own
//! lookahead ([`crate::search::lookahead`]; the fit starts from that controller, so what it learns is
//! the decisions its lookahead changed: expert iteration). The result is an ordinary
//! meta-controller (`meta.ron` + `meta.safetensors`): it acts from its observation alone, at no
//! search cost, and `meta eval --meta DIR` evaluates it.

use std::path::PathBuf;
use std::sync::Arc;
use std::time::Instant;

use rand::SeedableRng;
use rayon::prelude::*;
use repertoire_learn::acting::ActingHybrid;
use repertoire_learn::env::{Env, EnvRng};
use repertoire_learn::ppo::{Ppo, PpoConfig};

use crate::controller::{Controller, LookingAhead};
use crate::env::{MetaEnv, MetaSetup};
use crate::error::{MetaError, Result};
use crate::search::lookahead::LookaheadConfig;
use crate::search::planner::PlannerConfig;
use crate::train::{MetaManifest, MetaTrainOptions, Session, TrainedRun, save_controller, warm_start};

/// Whose decisions a distillation fits.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Teacher {
    /// The search-based planner; the fit starts from a fresh policy.
    Planner(PlannerConfig),
    /// The warm-start controller's lookahead; the fit starts from that controller.
    Lookahead(LookaheadConfig),
}

/// Options of a distillation.
#[derive(Debug, Clone)]
pub struct DistillOptions {
    /// Where the controller and its manifest go.
    pub out: PathBuf,
    /// Teacher episodes per zone.
    pub episodes: usize,
    /// Zones the episodes start in.
    pub zones: Vec<String>,
    /// Who decides in those episodes.
    pub teacher: Teacher,
    /// The trained controller the fit starts from (its head, observation statistics and
    /// critic; refused where it does not fit the setup); required by a lookahead teacher,
    /// whose controller it is. `None`: a fresh policy.
    pub warm_start: Option<PathBuf>,
    /// Keep only the decisions of episodes that succeeded.
    pub successful_only: bool,
    /// Times each decision the teacher changed (a lookahead's search took another than the
    /// controller's own) counts in the fit; at least 1. The others count once.
    pub changed_weight: usize,
    /// Passes over the demonstrations, and rows per gradient step.
    pub epochs: usize,
    /// Rows per gradient step.
    pub batch: usize,
    /// The network and optimiser (`default_ppo()`; its seed seeds the fit).
    pub ppo: PpoConfig,
    /// Seed of the teacher's episodes.
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
    /// Per decision: the teacher changed the controller's own.
    changed: Vec<bool>,
    success: bool,
}

/// What a distillation did.
#[derive(Debug, Clone, PartialEq)]
pub struct DistillFigures {
    /// Teacher episodes run.
    pub episodes: usize,
    /// Successful teacher episodes.
    pub successes: usize,
    /// Decisions fitted (the manifest's `samples` adds PPO's decisions after the fit).
    pub demonstrations: usize,
    /// Of those, the ones the teacher changed (each counted `changed_weight` times).
    pub changed: usize,
    /// Mean negative log-likelihood per epoch.
    pub losses: Vec<f32>,
    /// Seconds spent running the teacher.
    pub planning_s: f64,
    /// Seconds fitting.
    pub fitting_s: f64,
}

fn run_episode(setup: &Arc<MetaSetup>, teacher: &dyn Controller, seed: u64, stream: u64) -> Episode {
    let mut env = MetaEnv::new(Arc::clone(setup));
    let mut acting = teacher.start(setup);
    let mut rng = EnvRng::seed_from_u64(seed);
    rng.set_stream(stream);
    let (od, ad, k) = (env.obs_dim(), env.act_dim(), setup.skills.len());
    let mut obs = vec![0.0; od];
    let mut act = vec![0.0; ad];
    let mut mask = vec![false; k];
    let mut scratch = vec![false; k];
    let mut ep =
        Episode { obs: Vec::new(), actions: Vec::new(), masks: Vec::new(), changed: Vec::new(), success: false };
    env.reset(&mut rng, &mut obs);
    loop {
        env.option_mask(&mut mask);
        acting.act(&env, &obs, &mut scratch, &mut act);
        ep.obs.extend_from_slice(&obs);
        ep.actions.extend_from_slice(&act);
        ep.masks.extend_from_slice(&mask);
        ep.changed.push(acting.changed());
        let out = env.step(&act, &mut obs);
        if out.terminated || out.truncated {
            ep.success = out.terms[0] > 0.5;
            return ep;
        }
    }
}

/// Runs the teacher's episodes and fits a controller to them; writes it to `opts.out`.
pub fn distill(setup: Arc<MetaSetup>, opts: &DistillOptions) -> Result<(MetaManifest, DistillFigures)> {
    setup.check_zones(&opts.zones)?;
    let started = Instant::now();
    // The learner first: a warm start loads the controller once, and its lookahead teaches
    // with exactly the head the fit starts from.
    let envs = (0..opts.ppo.num_envs.max(1)).map(|_| MetaEnv::new(Arc::clone(&setup))).collect();
    let mut ppo = Ppo::new(opts.ppo.clone(), envs);
    let from = opts.warm_start.as_ref().map(|dir| warm_start(dir, &[], &setup, &mut ppo)).transpose()?;
    let head = ActingHybrid::from_ppo(&ppo).expect("the meta environment has hybrid actions");
    let (planner, looking);
    let teacher: &dyn Controller = match (opts.teacher, &from) {
        (Teacher::Planner(cfg), _) => {
            planner = cfg;
            &planner
        }
        (Teacher::Lookahead(cfg), Some(_)) => {
            looking = LookingAhead { head: &head, lookahead: cfg };
            &looking
        }
        (Teacher::Lookahead(_), None) => {
            return Err(MetaError::Invalid(
                "a lookahead teacher looks ahead with a trained controller: name it as the warm start".into(),
            ));
        }
    };
    let mut episodes = Vec::new();
    for (zi, zone) in opts.zones.iter().enumerate() {
        *setup.zones.write().expect("never poisoned") = vec![zone.clone()];
        let batch: Vec<Episode> = (0..opts.episodes)
            .into_par_iter()
            .map(|i| run_episode(&setup, teacher, opts.seed, (zi * opts.episodes + i) as u64 + 1))
            .collect();
        tracing::info!(
            zone = %zone,
            episodes = batch.len(),
            successes = batch.iter().filter(|e| e.success).count(),
            "teacher episodes"
        );
        episodes.extend(batch);
    }
    *setup.zones.write().expect("never poisoned") =
        setup.model.scenario.scenario.spawn.iter().map(|z| z.name.clone()).collect();
    let planning_s = started.elapsed().as_secs_f64();
    let successes = episodes.iter().filter(|e| e.success).count();
    let kept: Vec<&Episode> = episodes.iter().filter(|e| e.success || !opts.successful_only).collect();
    let (mut obs, mut actions, mut masks) = (Vec::new(), Vec::new(), Vec::new());
    let mut changed = 0;
    for e in &kept {
        let n = e.changed.len().max(1);
        let (od, ad, k) = (e.obs.len() / n, e.actions.len() / n, e.masks.len() / n);
        for (i, &c) in e.changed.iter().enumerate() {
            changed += usize::from(c);
            for _ in 0..if c { opts.changed_weight.max(1) } else { 1 } {
                obs.extend_from_slice(&e.obs[i * od..(i + 1) * od]);
                actions.extend_from_slice(&e.actions[i * ad..(i + 1) * ad]);
                masks.extend_from_slice(&e.masks[i * k..(i + 1) * k]);
            }
        }
    }
    let demonstrations = kept.iter().map(|e| e.changed.len()).sum::<usize>();
    if demonstrations == 0 {
        return Err(MetaError::Invalid(format!(
            "the teacher left no demonstrations to fit ({} episodes, {successes} successful{})",
            episodes.len(),
            if opts.successful_only { "; --successful-only keeps only those" } else { "" }
        )));
    }

    let fit_started = Instant::now();
    let losses = ppo.behaviour_clone(&obs, &actions, &masks, opts.epochs, opts.batch).map_err(MetaError::Invalid)?;
    let fitting_s = fit_started.elapsed().as_secs_f64();
    let fitted = |samples: u64, seconds: f64| TrainedRun {
        samples,
        seconds,
        curriculum: false,
        advances: Vec::new(),
        command: opts.command.clone(),
        resumed: Vec::new(),
        warm_start: from.clone(),
    };
    let (ppo, mut run) = match &opts.then_train {
        Some(train) => {
            let seconds = started.elapsed().as_secs_f64();
            save_controller(&setup, &ppo, &opts.out.join("fitted"), fitted(demonstrations as u64, seconds))?;
            ppo.cfg.num_iterations = train.ppo.num_iterations;
            let mut session = Session::fresh(ppo, &setup.model, &setup.zones, train, setup.low_level())?;
            session.started_from(from.clone());
            session.run(train, "skills, from the planner")?;
            session.finish()
        }
        None => (ppo, fitted(0, 0.0)),
    };
    run.samples += demonstrations as u64;
    run.seconds = started.elapsed().as_secs_f64();
    let manifest = save_controller(&setup, &ppo, &opts.out, run)?;
    let figures =
        DistillFigures { episodes: episodes.len(), successes, demonstrations, changed, losses, planning_s, fitting_s };
    Ok((manifest, figures))
}
