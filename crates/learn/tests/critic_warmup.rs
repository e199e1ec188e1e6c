//! The critic's warm-up: the policy holds still while the value network learns, then both learn
//! with a fresh Adam.

mod common;

use repertoire_learn::nn::Parameters;
use repertoire_learn::ppo::{Ppo, PpoConfig};

fn values(m: &mut impl Parameters) -> Vec<f32> {
    m.params_mut().iter().flat_map(|(_, p)| p.values()).collect()
}

#[test]
fn the_policy_holds_still_through_the_critics_warm_up_then_learns_with_a_fresh_adam() {
    let cfg = PpoConfig { critic_warmup: 3, ..common::tiny_config(2) };
    let mut ppo = Ppo::new(cfg, common::cartpoles(2));
    let (policy0, value0) = (values(&mut ppo.agent.policy), values(&mut ppo.agent.value));
    let mut steps = 0;
    for _ in 0..3 {
        let m = ppo.iterate();
        steps += m.epochs * ppo.cfg.num_minibatches;
        assert_eq!(m.approx_kl, 0.0, "the policy did not move, so its ratios are 1");
    }
    assert_eq!(values(&mut ppo.agent.policy), policy0, "the policy moved during the warm-up");
    assert_ne!(values(&mut ppo.agent.value), value0, "the critic did not learn during the warm-up");
    assert_eq!(ppo.optimizer.t as usize, steps, "one Adam step per minibatch");

    let m = ppo.iterate();
    assert_ne!(values(&mut ppo.agent.policy), policy0, "the policy did not learn after the warm-up");
    assert_eq!(
        ppo.optimizer.t as usize,
        m.epochs * ppo.cfg.num_minibatches,
        "Adam restarts when the policy starts: only this iteration's steps are counted"
    );

    // Without a warm-up the same seed moves the policy in the first iteration.
    let mut plain = Ppo::new(common::tiny_config(2), common::cartpoles(2));
    let before = values(&mut plain.agent.policy);
    assert_eq!(before, policy0, "the same seed starts from the same policy");
    plain.iterate();
    assert_ne!(values(&mut plain.agent.policy), before);
}
