//! Motor skills: a policy that imitates a reference clip while reaching a goal.
//!
//! - [`spec`]: the skill spec in RON (clip, observation, rewards, initial states, PPO).
//! - [`reference`]: a clip at the control rate, laid out as the rewards read it.
//! - [`imitation`]: the task: imitation + goal rewards, reference-state initialisation, early
//!   termination, starts from predecessors' end poses.
//! - [`skill`]: a spec made concrete (scene, clip, pools) that makes environments.
//! - [`pool`]: end-pose pools; [`library`]: the skill library on disk.
//! - [`train`]: `skill train` / `skill finetune`; [`eval`]: `skill eval`.

pub mod error;
pub mod eval;
pub mod imitation;
pub mod library;
pub mod motion;
pub mod play;
pub mod pool;
pub mod quat;
pub mod reference;
pub mod skill;
pub mod spec;
pub mod train;

pub use error::{Result, SkillError};
pub use skill::{SkillEnv, SkillSetup, load_clip};
pub use spec::{SkillSpec, SpecFile};
