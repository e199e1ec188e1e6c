//! The high level: the skill graph, the tasks' success tests (sitting, the warehouse, the toss),
//! the meta-controller environment over frozen skills, its training and evaluation, and the
//! latent low level ([`latent`]) as the alternative to the skills.

pub mod bind;
pub mod compare;
pub mod controller;
pub mod env;
pub mod error;
pub mod eval;
pub mod evaluation;
pub mod graph;
pub mod handover;
pub mod judge;
pub mod latent;
pub mod search;
pub mod task;
pub mod tasks;
pub mod train;
pub mod trial;

pub use controller::{Arena, Controller, Decider};
pub use env::{MetaEnv, MetaSetup};
pub use error::{MetaError, Result};
pub use graph::SkillGraph;
pub use judge::SitJudge;
pub use repertoire_curriculum::{Advance, AdvanceReason};
pub use task::{EpisodeOverride, TaskSpec, TaskState};
