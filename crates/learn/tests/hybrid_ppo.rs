//! PPO with the hybrid head learns a contextual choice with a continuous target, and never
//! picks an option the environment masks out.

use repertoire_learn::env::{Env, EnvRng, MAX_TERMS, StateError, StepOutcome};
use repertoire_learn::policy::PolicyConfig;
use repertoire_learn::ppo::{Ppo, PpoConfig};

use rand::Rng;

/// One-step episodes. Context A (obs [1, 0]): options 0 and 1 allowed; option 1 reads the
/// continuous value `c` and pays `1 − (c − 0.5)²`, option 0 pays 0. Context B (obs [0, 1]):
/// options 0 and 2 allowed; option 2 pays 1, option 0 pays 0, and option 1 (forbidden)
/// panics if chosen. The best expected return is 1.
struct Choice {
    context_b: bool,
}

const LO: [f32; 2] = [0.0, -3.0];
const HI: [f32; 2] = [2.0, 3.0];

impl Env for Choice {
    fn obs_dim(&self) -> usize {
        2
    }
    fn act_dim(&self) -> usize {
        2
    }
    fn action_bounds(&self) -> (&[f32], &[f32]) {
        (&LO, &HI)
    }
    fn options(&self) -> Option<Vec<bool>> {
        Some(vec![false, true, false])
    }
    fn option_mask(&self, mask: &mut [bool]) {
        mask.copy_from_slice(if self.context_b { &[true, false, true] } else { &[true, true, false] });
    }
    fn reset(&mut self, rng: &mut EnvRng, obs: &mut [f32]) {
        self.context_b = rng.random_bool(0.5);
        obs.copy_from_slice(if self.context_b { &[0.0, 1.0] } else { &[1.0, 0.0] });
    }
    fn step(&mut self, action: &[f32], obs: &mut [f32]) -> StepOutcome {
        let option = action[0] as usize;
        let reward = match (self.context_b, option) {
            (_, 0) => 0.0,
            (false, 1) => 1.0 - (action[1] - 0.5).powi(2),
            (true, 2) => 1.0,
            _ => panic!("option {option} was chosen although the mask forbids it"),
        };
        obs.fill(0.0);
        StepOutcome { reward, terminated: true, truncated: false, terms: [0.0; MAX_TERMS] }
    }
    fn snapshot(&self) -> Vec<f64> {
        vec![f64::from(u8::from(self.context_b))]
    }
    fn restore(&mut self, state: &[f64]) -> Result<(), StateError> {
        self.context_b = state.first().copied().unwrap_or(0.0) != 0.0;
        Ok(())
    }
}

/// One hidden layer of 16 for both networks, action std e⁻¹ to start.
fn small_policy() -> PolicyConfig {
    PolicyConfig { policy_hidden: vec![16], value_hidden: vec![16], init_log_std: -1.0, learn_log_std: true }
}

#[test]
fn hybrid_ppo_learns_the_choice_and_the_target_within_the_mask() {
    let cfg = PpoConfig {
        seed: 3,
        num_envs: 8,
        num_steps: 32,
        num_iterations: 150,
        learning_rate: 3e-3,
        gamma: 0.0,
        num_minibatches: 4,
        update_epochs: 4,
        normalize_obs: false,
        normalize_reward: false,
        policy: small_policy(),
        ..PpoConfig::default()
    };
    let envs = (0..8).map(|_| Choice { context_b: false }).collect();
    let mut ppo = Ppo::new(cfg, envs);
    let mut first = None;
    let mut last = 0.0;
    ppo.train(150, |m| {
        first.get_or_insert(m.mean_return);
        last = m.mean_return;
    });
    let first = first.unwrap();
    assert!(first < 0.7, "an untrained head pays less ({first})");
    assert!(last > 0.8, "learned return {last} (best 1.0)");
    let mut h = ppo.hybrid_inference().expect("hybrid head");
    let mut a = [0.0f32; 2];
    h.mode(&[1.0, 0.0], &[true, true, false], &mut a);
    assert_eq!(a[0], 1.0, "context A: option 1");
    assert!((a[1] - 0.5).abs() < 0.15, "context A: continuous target ≈ 0.5, got {}", a[1]);
    h.mode(&[0.0, 1.0], &[true, false, true], &mut a);
    assert_eq!(a[0], 2.0, "context B: option 2");
}

#[test]
fn behaviour_cloning_fits_demonstrated_choices_and_targets_within_the_mask() {
    // Demonstrations of the best play: context A takes option 1 with target 0.5, context B
    // option 2. After fitting, the head's mode reproduces them (normalised observations,
    // as the meta-controller uses), and its likelihood of them went up.
    let cfg = PpoConfig {
        seed: 5,
        num_envs: 2,
        num_steps: 8,
        learning_rate: 3e-3,
        policy: small_policy(),
        ..PpoConfig::default()
    };
    let mut ppo = Ppo::new(cfg, (0..2).map(|_| Choice { context_b: false }).collect());
    let (mut obs, mut actions, mut masks) = (Vec::new(), Vec::new(), Vec::new());
    for i in 0..64 {
        if i % 2 == 0 {
            obs.extend_from_slice(&[1.0, 0.0]);
            actions.extend_from_slice(&[1.0, 0.5]);
            masks.extend_from_slice(&[true, true, false]);
        } else {
            obs.extend_from_slice(&[0.0, 1.0]);
            actions.extend_from_slice(&[2.0, 0.0]);
            masks.extend_from_slice(&[true, false, true]);
        }
    }
    let losses = ppo.behaviour_clone(&obs, &actions, &masks, 200, 16).expect("fit");
    assert_eq!(losses.len(), 200);
    assert!(losses[199] < losses[0] - 0.5, "the likelihood went up: {} → {}", losses[0], losses[199]);
    let mut h = ppo.hybrid_inference().expect("hybrid head");
    let mut a = [0.0f32; 2];
    let mut raw = [0.0f32; 2];
    ppo.obs_rms.normalize(&[1.0, 0.0], &mut raw, repertoire_learn::ppo::OBS_CLIP);
    h.mode(&raw, &[true, true, false], &mut a);
    assert_eq!(a[0], 1.0, "context A: option 1");
    assert!((a[1] - 0.5).abs() < 0.15, "context A: target ≈ 0.5, got {}", a[1]);
    ppo.obs_rms.normalize(&[0.0, 1.0], &mut raw, repertoire_learn::ppo::OBS_CLIP);
    h.mode(&raw, &[true, false, true], &mut a);
    assert_eq!(a[0], 2.0, "context B: option 2");

    // Rows of the wrong width, or an option the head does not have, are refused.
    assert!(ppo.behaviour_clone(&obs[..63], &actions, &masks, 1, 16).is_err());
    let mut bad = actions.clone();
    bad[0] = 7.0;
    let err = ppo.behaviour_clone(&obs, &bad, &masks, 1, 16).expect_err("option 7 of 3");
    assert!(err.contains("option 7"), "{err}");
}
