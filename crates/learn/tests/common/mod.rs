//! Helpers shared by the integration tests.
#![allow(dead_code)]

use std::sync::Arc;

use mujoco_rs::prelude::MjModel;
use repertoire_learn::env::{Env, EnvRng, MAX_TERMS, StateError, StepOutcome};
use repertoire_learn::envs::cartpole::{CARTPOLE_XML, CartPole};
use repertoire_learn::policy::PolicyConfig;
use repertoire_learn::ppo::PpoConfig;

/// `n` cart-poles sharing one model, 200-step time limit.
pub fn cartpoles(n: usize) -> Vec<CartPole> {
    let model = Arc::new(MjModel::from_xml_string(CARTPOLE_XML).expect("cart-pole MJCF parses"));
    (0..n).map(|_| CartPole::with_model(model.clone(), 200)).collect()
}

/// A tiny, fast configuration for determinism and checkpoint tests.
pub fn tiny_config(num_envs: usize) -> PpoConfig {
    PpoConfig {
        seed: 7,
        num_envs,
        num_steps: 32,
        num_iterations: 8,
        num_minibatches: 2,
        update_epochs: 2,
        target_kl: Some(0.5),
        policy: PolicyConfig { policy_hidden: vec![16], value_hidden: vec![16], ..PolicyConfig::default() },
        ..PpoConfig::default()
    }
}

/// A point on a line pushed by the action, with `obs_dim` observations (position, then zeros);
/// no physics engine, so tests can vary the observation size.
pub struct Drift {
    pub obs_dim: usize,
    x: f64,
    steps: u32,
}

impl Drift {
    pub fn new(obs_dim: usize) -> Self {
        Drift { obs_dim, x: 0.0, steps: 0 }
    }
    fn observe(&self, obs: &mut [f32]) {
        obs.fill(0.0);
        obs[0] = self.x as f32;
    }
}

const LOW: [f32; 1] = [-1.0];
const HIGH: [f32; 1] = [1.0];

impl Env for Drift {
    fn obs_dim(&self) -> usize {
        self.obs_dim
    }
    fn act_dim(&self) -> usize {
        1
    }
    fn action_bounds(&self) -> (&[f32], &[f32]) {
        (&LOW, &HIGH)
    }
    fn reset(&mut self, rng: &mut EnvRng, obs: &mut [f32]) {
        use rand::Rng;
        self.x = rng.random_range(-1.0..1.0);
        self.steps = 0;
        self.observe(obs);
    }
    fn step(&mut self, action: &[f32], obs: &mut [f32]) -> StepOutcome {
        self.x += 0.1 * f64::from(action[0]);
        self.steps += 1;
        self.observe(obs);
        StepOutcome {
            reward: -(self.x.abs() as f32),
            terminated: self.x.abs() > 3.0,
            truncated: self.steps >= 20,
            terms: [0.0; MAX_TERMS],
        }
    }
    fn snapshot(&self) -> Vec<f64> {
        vec![self.x, f64::from(self.steps)]
    }
    fn restore(&mut self, state: &[f64]) -> Result<(), StateError> {
        let [x, s] = state else {
            return Err(StateError::length("drift state", 2, state.len()));
        };
        self.x = *x;
        self.steps = *s as u32;
        Ok(())
    }
}
