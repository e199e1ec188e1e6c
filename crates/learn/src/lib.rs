//! The learning core: environments, policies on dfdx, PPO, checkpoints.
pub mod acting;
pub mod bench;
pub mod checkpoint;
pub mod classify;
pub mod env;
pub mod envs;
pub mod nn;
pub mod normalize;
pub mod optim;
pub mod policy;
pub mod ppo;
pub mod run_dir;
