//! What chooses the skills in an episode: the [`Controller`] trait that every decision maker
//! implements (the trained controller, the search-based planner, the controller with its sit
//! timed by the planner's copy, the readiness-gated controller, the lookahead, and the latent
//! high level over the latent low level), and the per-episode [`Decider`] it starts. A
//! controller plays its episodes in an [`Arena`]: the skills' [`MetaSetup`] (a decision is a
//! skill and its target, twice a second) or the latent model's
//! [`LatentSetup`](crate::latent::LatentSetup) (a decision is a latent `z`). Evaluation and worst-episode recordings take a `&dyn Controller<A>` for any
//! arena; deliveries, distillation and the object tasks take the skills' (`&dyn Controller`).

use std::sync::{Arc, RwLock};

use repertoire_learn::acting::ActingHybrid;
use repertoire_learn::classify::Classifier;
use repertoire_learn::env::Env;
use repertoire_scenes::world::PropPlacement;
use repertoire_scenes::{Recording, WorldModel};

use crate::env::{MetaEnv, MetaSetup, terminal_skills};
use crate::error::Result;
use crate::handover::readiness::{Gate, Readiness, checked_act, terminal_choice};
use crate::search::lookahead::{Lookahead, LookaheadConfig};
use crate::search::planner::{Planner, PlannerConfig};
use crate::task::TaskSpec;
use crate::trial::Trial;

/// Where a controller's episodes are played: the scene, the task and the low level its
/// decisions drive, and the environment of one episode.
pub trait Arena: Send + Sync + Sized + 'static {
    /// One episode's environment: the observation a controller reads, its decision the action.
    type Env: Env;

    /// A new environment.
    fn env(self: &Arc<Self>) -> Result<Self::Env>;

    /// The scene.
    fn model(&self) -> &WorldModel;

    /// The task.
    fn task(&self) -> &TaskSpec;

    /// The spawn zones episodes start in (an evaluation sets one zone at a time).
    fn zones(&self) -> &RwLock<Vec<String>>;

    /// What decides here, for the titles of recordings.
    fn decider(&self) -> &'static str;

    /// The names of the options a decision chooses among, in option order (the skills; none
    /// for a continuous low level).
    fn options(&self) -> Vec<String>;

    /// The finished episode of `env` as a sitting trial (`terms`: the episode's figures).
    fn trial(&self, env: &Self::Env, index: usize, zone: &str, terms: &[f32]) -> Trial;

    /// Makes `env` record its following episodes, `title` heading each.
    fn record(env: &mut Self::Env, title: String);

    /// This arena and `controller` as the skills' (the object tasks are played over the
    /// skills only); `None` for another low level.
    #[allow(clippy::type_complexity)]
    fn skills<'a>(
        self: &'a Arc<Self>,
        controller: &'a dyn Controller<Self>,
    ) -> Option<(&'a Arc<MetaSetup>, &'a dyn Controller<MetaSetup>)>;

    /// The recording of `env`'s current episode (when it records).
    fn recording(env: &mut Self::Env) -> Option<Recording>;
}

impl Arena for MetaSetup {
    type Env = MetaEnv;

    fn env(self: &Arc<Self>) -> Result<MetaEnv> {
        Ok(MetaEnv::new(Arc::clone(self)))
    }

    fn task(&self) -> &TaskSpec {
        &self.task
    }

    fn zones(&self) -> &RwLock<Vec<String>> {
        &self.zones
    }

    fn model(&self) -> &WorldModel {
        &self.model
    }

    fn decider(&self) -> &'static str {
        "meta-controller"
    }

    fn options(&self) -> Vec<String> {
        self.skills.iter().map(|s| s.name.clone()).collect()
    }

    fn trial(&self, env: &MetaEnv, index: usize, zone: &str, terms: &[f32]) -> Trial {
        let names = self.options();
        let skills = env.chosen.iter().map(|&c| names[c].clone()).collect();
        let frame: PropPlacement = env.world().placements()[self.task.frame_prop()];
        let mut trial = Trial::from_episode(index, zone, env.start, frame, terms, skills);
        trial.touched = env.touched.map(|c| names[c].clone());
        trial
    }

    fn record(env: &mut MetaEnv, title: String) {
        env.record_episodes(title);
    }

    fn skills<'a>(
        self: &'a Arc<Self>,
        controller: &'a dyn Controller<Self>,
    ) -> Option<(&'a Arc<MetaSetup>, &'a dyn Controller<MetaSetup>)> {
        Some((self, controller))
    }

    fn recording(env: &mut MetaEnv) -> Option<Recording> {
        env.recording()
    }
}

/// A decision maker over an [`Arena`] (by default the skills' [`MetaSetup`]). It is shared by
/// the episodes of an evaluation played in parallel; each episode gets its own [`Decider`]
/// from [`start`].
///
/// [`start`]: Controller::start
pub trait Controller<A: Arena = MetaSetup>: Sync {
    /// The decider of one episode in `setup`.
    fn start(&self, setup: &Arc<A>) -> Box<dyn Decider<A::Env>>;

    /// Whether it decides in sitting scenarios only (it looks for a terminal skill, the sit,
    /// that succeeds).
    fn sitting_only(&self) -> bool {
        true
    }
}

/// One episode's decisions.
pub trait Decider<E = MetaEnv> {
    /// The decision for `env`, whose observation is `obs`, into `act` (`mask`: scratch for the
    /// allowed options).
    fn act(&mut self, env: &E, obs: &[f32], mask: &mut [bool], act: &mut [f32]);

    /// Decisions simulated in copies of the episode so far (a search's cost; 0 for one acting
    /// from its observation alone).
    fn simulated(&self) -> u64 {
        0
    }

    /// Whether the last decision differs from what the trained controller alone would have
    /// chosen (a lookahead's search took another).
    fn changed(&self) -> bool {
        false
    }
}

/// The trained meta-controller, acting by its mode over the skills the graph allows.
impl Controller for ActingHybrid {
    fn start(&self, _setup: &Arc<MetaSetup>) -> Box<dyn Decider> {
        Box::new(self.clone())
    }

    fn sitting_only(&self) -> bool {
        false
    }
}

impl Decider for ActingHybrid {
    fn act(&mut self, env: &MetaEnv, obs: &[f32], mask: &mut [bool], act: &mut [f32]) {
        env.option_mask(mask);
        ActingHybrid::act(self, obs, mask, act);
    }
}

/// The search-based reference over the same skills ([`crate::search::planner`]).
impl Controller for PlannerConfig {
    fn start(&self, setup: &Arc<MetaSetup>) -> Box<dyn Decider> {
        Box::new(Planner::new(Arc::clone(setup), *self))
    }
}

impl Decider for Planner {
    fn act(&mut self, env: &MetaEnv, _obs: &[f32], _mask: &mut [bool], act: &mut [f32]) {
        Planner::act(self, env, act);
    }

    fn simulated(&self) -> u64 {
        self.simulated
    }
}

/// A trained controller whose terminal skills (sit) are checked in a copy of the episode: at
/// each decision a terminal skill that would succeed from here is taken, and otherwise the
/// controller chooses among the rest. An oracle of when to sit, with the controller's own way
/// there: it says how much of the gap to the planner is timing the sit.
#[derive(Clone, Copy)]
pub struct OracleSit<'a> {
    /// The trained controller.
    pub head: &'a ActingHybrid,
    /// The copy's horizon.
    pub planner: PlannerConfig,
}

struct OracleSitting {
    head: ActingHybrid,
    planner: Planner,
}

impl Controller for OracleSit<'_> {
    fn start(&self, setup: &Arc<MetaSetup>) -> Box<dyn Decider> {
        Box::new(OracleSitting { head: self.head.clone(), planner: Planner::new(Arc::clone(setup), self.planner) })
    }
}

impl Decider for OracleSitting {
    fn act(&mut self, env: &MetaEnv, obs: &[f32], mask: &mut [bool], act: &mut [f32]) {
        checked_act(&mut self.head, &mut self.planner, env, obs, mask, act);
    }

    fn simulated(&self) -> u64 {
        self.planner.simulated
    }
}

/// A trained controller gated by a learned readiness ([`crate::handover::readiness`]): a terminal skill
/// (sit) only when the classifier gives it at least the gate's chance of succeeding from here,
/// the other skills otherwise. No search: it acts from the observation alone.
#[derive(Clone, Copy)]
pub struct Gated<'a> {
    /// The trained controller.
    pub head: &'a ActingHybrid,
    /// The readiness classifier.
    pub readiness: &'a Readiness,
    /// Where it sits and where it may not.
    pub gate: Gate,
}

struct GatedActing {
    head: ActingHybrid,
    readiness: Classifier,
    gate: Gate,
    terminal: Vec<bool>,
}

impl Controller for Gated<'_> {
    fn start(&self, setup: &Arc<MetaSetup>) -> Box<dyn Decider> {
        Box::new(GatedActing {
            head: self.head.clone(),
            readiness: self.readiness.classifier.clone(),
            gate: self.gate,
            terminal: terminal_skills(setup),
        })
    }
}

impl Decider for GatedActing {
    fn act(&mut self, env: &MetaEnv, obs: &[f32], mask: &mut [bool], act: &mut [f32]) {
        env.option_mask(mask);
        if terminal_choice(mask, &self.terminal) {
            self.gate.apply(self.readiness.probability(obs), mask, &self.terminal);
        }
        self.head.act(obs, mask, act);
    }
}

/// A trained controller checked in a copy of the episode before it commits
/// ([`crate::search::lookahead`]): its own decision and ones drawn from its policy, each played out
/// with the controller after it; the first that succeeds is taken.
#[derive(Clone, Copy)]
pub struct LookingAhead<'a> {
    /// The trained controller.
    pub head: &'a ActingHybrid,
    /// Candidates and searches.
    pub lookahead: LookaheadConfig,
}

impl Controller for LookingAhead<'_> {
    fn start(&self, setup: &Arc<MetaSetup>) -> Box<dyn Decider> {
        Box::new(Lookahead::new(Arc::clone(setup), self.head, self.lookahead))
    }
}

impl Decider for Lookahead {
    fn act(&mut self, env: &MetaEnv, obs: &[f32], _mask: &mut [bool], act: &mut [f32]) {
        Lookahead::act(self, env, obs, act);
    }

    fn simulated(&self) -> u64 {
        self.simulated
    }

    fn changed(&self) -> bool {
        self.changed
    }
}
