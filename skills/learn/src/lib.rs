//! The learning core: environments, policies on dfdx, PPO, checkpoints.
