//! The NPMP latent low level: expert rollouts into a compact dataset, an encoder/decoder over
//! a learned motor-intention space with an AR(1) prior, and one-shot imitation through it.
//!
//! - [`reference`]: the encoder's input, the next `k` reference frames relative to the body.
//! - [`rollout`]: batched episodes of a skill's task under any [`rollout::Controller`].
//! - [`dataset`]: `latent collect`: library skills with action noise → safetensors + RON.
//! - [`model`]: the encoder, the proprioceptive decoder, the AR(1) KL, save/load.
//! - [`train`]: `latent train`: `−log π + β·KL` over short sequences, BC or RWR weights.
//! - [`eval`]: `latent eval`: one-shot imitation against the experts (MoCapAct Table 2).
//! - [`high`]: the latent space as a low level ([`high::LatentEnv`], `z` bounded to ±2) and a
//!   go-to-target task trained on it with the PPO core.

pub mod dataset;
pub mod error;
pub mod eval;
pub mod high;
pub mod model;
pub mod reference;
pub mod rollout;
pub mod train;

pub use error::{LatentError, Result};
