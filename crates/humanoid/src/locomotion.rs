//! [`Locomotion`]: Gymnasium Humanoid-v5's reward on our body, the workload of `bench ppo`.
//!
//! Reward per step = `healthy` while the character is up + `forward_weight` × forward speed of
//! the pelvis in its heading frame − `ctrl_weight` × Σ a² over the normalised actions; the
//! episode terminates when a body part other than the feet touches the floor or the pelvis
//! drops below `min_height`. Episodes start standing in the scenario's first spawn zone with
//! small uniform noise on joint angles and velocities (Gymnasium's `reset_noise_scale`).

use rand::Rng;
use repertoire_learn::env::{EnvRng, MAX_TERMS};
use repertoire_scenes::World;

use crate::env::{Task, TaskStep};

/// Stand up and move forward, as in Gymnasium's Humanoid-v5.
#[derive(Clone, Debug)]
pub struct Locomotion {
    /// Reward per step while up (Humanoid-v5: 5).
    pub healthy: f32,
    /// Weight of forward speed in m/s (Humanoid-v5: 1.25).
    pub forward_weight: f32,
    /// Weight of the squared normalised action (Humanoid-v5: 0.1).
    pub ctrl_weight: f32,
    /// The episode ends when the pelvis is lower than this (m).
    pub min_height: f64,
    /// Half-width of the uniform noise on initial joint angles (rad) and velocities (rad/s).
    pub reset_noise: f64,
    qpos: Vec<f64>,
    qvel: Vec<f64>,
}

impl Default for Locomotion {
    fn default() -> Self {
        Locomotion {
            healthy: 5.0,
            forward_weight: 1.25,
            ctrl_weight: 0.1,
            min_height: 0.6,
            reset_noise: 0.01,
            qpos: Vec::new(),
            qvel: Vec::new(),
        }
    }
}

const TERMS: [&str; 3] = ["healthy", "forward", "ctrl_cost"];

impl Task for Locomotion {
    fn term_names(&self) -> &[&'static str] {
        &TERMS
    }

    fn reset(&mut self, world: &mut World, rng: &mut EnvRng) {
        let model = std::sync::Arc::clone(world.model());
        let zone = model.scenario.scenario.spawn.first().map(|z| z.name.as_str());
        match zone {
            Some(z) => {
                world.reset_in_zone(z, rng).expect("the zone is one of the scenario's own");
            }
            None => world.reset(rng, 0.0, 0.0, 0.0),
        }
        let d = world.data();
        self.qpos.clear();
        self.qpos.extend_from_slice(d.qpos());
        self.qvel.clear();
        self.qvel.extend_from_slice(d.qvel());
        let r = self.reset_noise;
        if r > 0.0 {
            for j in &model.index.joints {
                self.qpos[j.qpos] += rng.random_range(-r..=r);
                self.qvel[j.dof] += rng.random_range(-r..=r);
            }
        }
        world.set_state(&self.qpos, &self.qvel).expect("a noisy standing pose is a valid state");
    }

    fn step(&mut self, world: &mut World, action: &[f32]) -> TaskStep {
        let fallen = world.has_fallen() || world.root_height() < self.min_height;
        let forward = world.root_velocity_heading()[0] as f32;
        let ctrl: f32 = action.iter().map(|a| a * a).sum();
        let mut terms = [0.0; MAX_TERMS];
        terms[0] = if fallen { 0.0 } else { self.healthy };
        terms[1] = self.forward_weight * forward;
        terms[2] = -self.ctrl_weight * ctrl;
        TaskStep { reward: terms[0] + terms[1] + terms[2], terminated: fallen, truncated: false, terms }
    }
}
