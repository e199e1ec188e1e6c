//! The character in a scene world as a [`repertoire_learn::env::Env`].
//!
//! [`HumanoidEnv`] owns one [`World`] and does what every humanoid task shares: maps normalised
//! actions in `[-1, 1]` to PD targets across each actuator's range, writes the observation the
//! task's [`ObservationLayout`] describes, cuts episodes at the time limit, and snapshots the
//! world for checkpoints. A [`Task`] decides how episodes start, what is rewarded and when an
//! episode ends; [`Locomotion`] (Gymnasium Humanoid-v5's reward on our body) is the first, used
//! by `repertoire bench ppo`, and the skills add imitation tasks.

mod env;
mod locomotion;

pub use env::{ActionMap, HumanoidEnv, Task, TaskStep};
pub use locomotion::Locomotion;
