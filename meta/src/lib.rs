//! The high level: the skill graph, the tasks' success tests (sitting, the warehouse, the toss),
//! the meta-controller environment over frozen skills, its training and evaluation, and the
//! latent low level ([`latent`]) as the alternative to the skills.

pub mod bind;
pub mod compare;
pub mod deliver;
pub mod distill;
pub mod env;
pub mod error;
pub mod eval;
pub mod graph;
pub mod judge;
pub mod latent;
pub mod lookahead;
pub mod planner;
pub mod readiness;
pub mod refine;
pub mod task;
pub mod task_eval;
pub mod toss;
pub mod train;
pub mod warehouse;

pub use env::{MetaEnv, MetaSetup};
pub use error::{MetaError, Result};
pub use graph::SkillGraph;
pub use judge::SitJudge;
pub use repertoire_curriculum::{Advance, AdvanceReason};
pub use task::{EpisodeOverride, TaskSpec, TaskState};
