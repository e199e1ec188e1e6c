//! PPO throughput on the MuJoCo cart-pole, with environments stepped serially and on rayon.
//!
//! `cargo run -p repertoire-learn --release --example bench_cartpole [iterations] [num_envs]`

use std::sync::Arc;

use mujoco_rs::prelude::MjModel;
use repertoire_learn::bench::bench_ppo;
use repertoire_learn::envs::cartpole::{CARTPOLE_XML, CartPole, ppo_config};
use repertoire_learn::ppo::PpoConfig;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let mut args = std::env::args().skip(1);
    let iterations: usize = args.next().map_or(Ok(10), |s| s.parse())?;
    let num_envs: usize = args.next().map_or(Ok(8), |s| s.parse())?;
    let model = Arc::new(MjModel::from_xml_string(CARTPOLE_XML)?);
    for parallel in [false, true] {
        let cfg = PpoConfig { num_envs, parallel_envs: parallel, num_iterations: iterations + 1, ..ppo_config() };
        let envs = (0..num_envs).map(|_| CartPole::with_model(model.clone(), 200)).collect();
        let r = bench_ppo(cfg, envs, iterations);
        println!(
            "parallel={parallel} envs={num_envs}: {:.0} samples/s ({} samples in {:.2} s), env stepping {:.1}% of wall time; \
             policy forward [{} x obs]: plain f32 {:.1} us, dfdx {:.1} us",
            r.samples_per_sec,
            r.samples,
            r.seconds,
            100.0 * r.env_time_fraction,
            r.batch,
            r.forward_plain_us,
            r.forward_dfdx_us
        );
    }
    Ok(())
}
