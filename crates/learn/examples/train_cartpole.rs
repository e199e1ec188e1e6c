//! Train PPO on the MuJoCo cart-pole and print one line per iteration.
//!
//! `cargo run -p repertoire-learn --release --example train_cartpole [iterations]`

use std::sync::Arc;

use mujoco_rs::prelude::MjModel;
use repertoire_learn::envs::cartpole::{CARTPOLE_XML, CartPole};
use repertoire_learn::ppo::{Ppo, PpoConfig};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let iterations: usize = std::env::args().nth(1).map_or(Ok(30), |s| s.parse())?;
    let cfg = PpoConfig { num_iterations: iterations, ..repertoire_learn::envs::cartpole::ppo_config() };
    let model = Arc::new(MjModel::from_xml_string(CARTPOLE_XML)?);
    let envs = (0..cfg.num_envs).map(|_| CartPole::with_model(model.clone(), 200)).collect();
    let mut ppo = Ppo::new(cfg, envs);
    ppo.train(iterations, |m| {
        println!(
            "it {:3} step {:6} return {:7.1} len {:6.1} term {:.2} kl {:.4} clip {:.3} ent {:.3} ev {:.3} sps {:7.0} env {:.2}",
            m.iteration, m.global_step, m.mean_return, m.mean_length, m.termination_rate,
            m.approx_kl, m.clip_fraction, m.entropy, m.explained_variance, m.samples_per_sec,
            m.env_time_fraction
        );
    });
    Ok(())
}
