//! The high level of the sitting method: the skill graph, the success test, and (in progress)
//! the meta-controller environment over frozen skills, its training and evaluation.

pub mod env;
pub mod error;
pub mod eval;
pub mod graph;
pub mod judge;
pub mod train;

pub use env::{MetaEnv, MetaSetup};
pub use error::{MetaError, Result};
pub use graph::SkillGraph;
pub use judge::SitJudge;
