//! Cart-pole balance in MuJoCo: push a cart along a rail to keep a hinged pole upright.
//!
//! Observation `[x, θ, ẋ, θ̇]`; action: one force in `[-1, 1]` (× 10 N). Reward 1 per step alive
//! minus a small effort cost; the episode terminates when `|θ| > 0.2` rad or `|x| > 2.4` m and is
//! truncated after `max_steps` control steps (50 Hz, two 100 Hz physics steps each).

use std::sync::Arc;

use mujoco_rs::prelude::*;
use rand::Rng;

use crate::env::{Env, EnvRng, MAX_TERMS, StateError, StepOutcome};

/// The MJCF model: a 1 kg cart on a frictionless slider and a 1 m, 0.1 kg pole on a hinge.
pub const CARTPOLE_XML: &str = r#"
<mujoco model="cartpole">
  <option timestep="0.01" integrator="Euler">
    <flag contact="disable"/>
  </option>
  <worldbody>
    <body name="cart" pos="0 0 1">
      <joint name="slider" type="slide" axis="1 0 0"/>
      <geom name="cart" type="box" size="0.2 0.1 0.05" mass="1"/>
      <body name="pole">
        <joint name="hinge" type="hinge" axis="0 1 0"/>
        <geom name="pole" type="capsule" fromto="0 0 0 0 0 1" size="0.02" mass="0.1"/>
      </body>
    </body>
  </worldbody>
  <actuator>
    <motor name="push" joint="slider" gear="10" ctrllimited="true" ctrlrange="-1 1"/>
  </actuator>
</mujoco>
"#;

const SUBSTEPS: usize = 2;
const MAX_ANGLE: f64 = 0.2;
const MAX_X: f64 = 2.4;
const EFFORT_COST: f32 = 0.01;
const LOW: [f32; 1] = [-1.0];
const HIGH: [f32; 1] = [1.0];

/// The cart-pole balance task.
pub struct CartPole {
    data: MjData<Arc<MjModel>>,
    steps: u32,
    max_steps: u32,
}

impl CartPole {
    /// Parse the model; `max_steps` is the time limit in control steps.
    pub fn new(max_steps: u32) -> Result<Self, MjModelError> {
        Ok(Self::with_model(Arc::new(MjModel::from_xml_string(CARTPOLE_XML)?), max_steps))
    }

    /// A cart-pole sharing an already parsed model (cheap; one per vectorised env).
    pub fn with_model(model: Arc<MjModel>, max_steps: u32) -> Self {
        CartPole { data: MjData::new(model), steps: 0, max_steps }
    }

    fn observe(&self, obs: &mut [f32]) {
        let (q, v) = (self.data.qpos(), self.data.qvel());
        obs[0] = q[0] as f32;
        obs[1] = q[1] as f32;
        obs[2] = v[0] as f32;
        obs[3] = v[1] as f32;
    }
}

impl Env for CartPole {
    fn obs_dim(&self) -> usize {
        4
    }

    fn act_dim(&self) -> usize {
        1
    }

    fn action_bounds(&self) -> (&[f32], &[f32]) {
        (&LOW, &HIGH)
    }

    fn term_names(&self) -> &[&'static str] {
        &["alive", "effort"]
    }

    fn reset(&mut self, rng: &mut EnvRng, obs: &mut [f32]) {
        self.data.reset();
        for q in self.data.qpos_mut() {
            *q = rng.random_range(-0.05..0.05);
        }
        for v in self.data.qvel_mut() {
            *v = rng.random_range(-0.05..0.05);
        }
        self.data.forward();
        self.steps = 0;
        self.observe(obs);
    }

    fn step(&mut self, action: &[f32], obs: &mut [f32]) -> StepOutcome {
        self.data.ctrl_mut()[0] = f64::from(action[0]);
        for _ in 0..SUBSTEPS {
            self.data.step();
        }
        self.steps += 1;
        self.observe(obs);
        let (x, theta) = (self.data.qpos()[0], self.data.qpos()[1]);
        let terminated = !(x.abs() <= MAX_X && theta.abs() <= MAX_ANGLE);
        let mut terms = [0.0; MAX_TERMS];
        terms[0] = 1.0;
        terms[1] = -EFFORT_COST * action[0] * action[0];
        StepOutcome { reward: terms[0] + terms[1], terminated, truncated: self.steps >= self.max_steps, terms }
    }

    fn snapshot(&self) -> Vec<f64> {
        let mut s = vec![self.data.time(), f64::from(self.steps)];
        s.extend_from_slice(self.data.qpos());
        s.extend_from_slice(self.data.qvel());
        s
    }

    fn restore(&mut self, state: &[f64]) -> Result<(), StateError> {
        if state.len() != 6 {
            return Err(StateError::length("cart-pole state", 6, state.len()));
        }
        self.data.reset();
        self.data.set_time(state[0]);
        self.steps = state[1] as u32;
        self.data.qpos_mut().copy_from_slice(&state[2..4]);
        self.data.qvel_mut().copy_from_slice(&state[4..6]);
        self.data.forward();
        Ok(())
    }
}

/// PPO settings that learn cart-pole balance in a few seconds on two CPU cores.
pub fn ppo_config() -> crate::ppo::PpoConfig {
    crate::ppo::PpoConfig {
        num_envs: 8,
        num_steps: 128,
        num_iterations: 30,
        learning_rate: 1e-3,
        num_minibatches: 8,
        update_epochs: 5,
        policy: crate::policy::PolicyConfig {
            policy_hidden: vec![32, 32],
            value_hidden: vec![32, 32],
            ..crate::policy::PolicyConfig::default()
        },
        ..crate::ppo::PpoConfig::default()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::SeedableRng;

    #[test]
    fn pole_falls_without_control_and_snapshot_replays() {
        let mut env = CartPole::new(1000).expect("model parses");
        let mut rng = EnvRng::seed_from_u64(0);
        let mut obs = [0.0; 4];
        env.reset(&mut rng, &mut obs);
        for _ in 0..5 {
            env.step(&[0.3], &mut obs);
        }
        let snap = env.snapshot();
        let mut a = Vec::new();
        let mut steps = 0;
        loop {
            let out = env.step(&[0.0], &mut obs);
            a.push(obs);
            steps += 1;
            if out.terminated {
                break;
            }
            assert!(steps < 1000, "an uncontrolled pole must fall");
        }
        env.restore(&snap).expect("restore");
        for expected in &a {
            env.step(&[0.0], &mut obs);
            assert_eq!(&obs, expected);
        }
    }
}
