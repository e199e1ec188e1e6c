//! PPO learns MuJoCo cart-pole balance within a small CPU budget, far above a random policy.

mod common;

use rand::{Rng, SeedableRng};
use repertoire_learn::env::VecEnv;
use repertoire_learn::envs::cartpole::ppo_config;
use repertoire_learn::ppo::{Ppo, PpoConfig};

/// Mean return of uniformly random actions over the first `episodes` episodes.
fn random_policy_return(episodes: usize) -> f32 {
    let mut envs = VecEnv::new(common::cartpoles(8), 1234, true);
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(99);
    let mut actions = vec![0.0f32; envs.len()];
    while envs.finished.len() < episodes {
        actions.iter_mut().for_each(|a| *a = rng.random_range(-1.0..=1.0));
        envs.step(&actions);
    }
    envs.finished[..episodes].iter().map(|e| e.ret).sum::<f32>() / episodes as f32
}

#[test]
fn ppo_balances_the_cartpole() {
    let start = std::time::Instant::now();
    let random = random_policy_return(64);

    let cfg = PpoConfig { num_iterations: 15, ..ppo_config() };
    let mut ppo = Ppo::new(cfg.clone(), common::cartpoles(cfg.num_envs));
    let mut last = None;
    ppo.train(cfg.num_iterations, |m| last = Some(m.clone()));
    let last = last.expect("at least one iteration ran");

    // Deterministic evaluation on fresh, differently seeded envs with frozen normalisation.
    let mut eval_envs = VecEnv::new(common::cartpoles(8), 4321, true);
    let learned = ppo.evaluate(&mut eval_envs, 16);
    eprintln!(
        "cart-pole: random {random:.1}, learned {learned:.1} (training return {:.1}), \
         {} steps, {:.0} samples/s, env fraction {:.2}, {:.2} s",
        last.mean_return,
        last.global_step,
        last.samples_per_sec,
        last.env_time_fraction,
        start.elapsed().as_secs_f32()
    );
    assert!(random < 60.0, "random policy should fall quickly, got {random}");
    assert!(learned >= 150.0, "learned return {learned} (max 200)");
    assert!(learned - random >= 100.0, "margin {learned} vs {random}");
}
