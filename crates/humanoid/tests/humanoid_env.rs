//! The humanoid environment: observations, rewards and terminations from real MuJoCo physics,
//! snapshots that reproduce the future exactly, and PPO checkpoints that resume bit for bit.

use std::sync::Arc;

use rand::SeedableRng;
use repertoire_humanoid::{HumanoidEnv, Locomotion};
use repertoire_learn::checkpoint;
use repertoire_learn::env::{Env, EnvRng, StateError};
use repertoire_learn::policy::PolicyConfig;
use repertoire_learn::ppo::{Ppo, PpoConfig};
use repertoire_scenes::{Feature, ScenarioFile, WorldModel};

fn model() -> Arc<WorldModel> {
    Arc::new(WorldModel::build(ScenarioFile::builtin_default()).expect("the default scenario builds"))
}

fn env(model: &Arc<WorldModel>) -> HumanoidEnv<Locomotion> {
    HumanoidEnv::new(model, &Feature::proprioception(), Locomotion::default(), 200).expect("layout")
}

#[test]
fn standing_is_healthy_and_falling_terminates() {
    let model = model();
    let mut e = env(&model);
    let mut rng = EnvRng::seed_from_u64(3);
    let mut obs = vec![0.0; e.obs_dim()];
    e.reset(&mut rng, &mut obs);
    assert_eq!(
        obs.len(),
        61,
        "25 angles + 25 velocities + height + 3 velocity + pitch/roll + 3 angular velocity + 2 feet"
    );
    assert!(obs.iter().all(|v| v.is_finite()));

    // Action 0 is the standing pose; `action_for` inverts the mapping.
    let q0 = model.mj_model().qpos0();
    let hold: Vec<f32> = model.index.joints.iter().enumerate().map(|(k, j)| e.action_for(k, q0[j.qpos])).collect();
    assert!(hold.iter().all(|a| a.abs() < 1e-6), "the standing pose is action 0: {hold:?}");
    for k in 0..e.act_dim() {
        // A joint standing at a range end (the elbows) has no span on that side.
        for a in [-1.0f32, -0.3, 0.4, 1.0].into_iter().filter(|&a| e.target(k, a) != e.target(k, 0.0)) {
            let back = e.action_for(k, e.target(k, a));
            assert!((back - a).abs() < 1e-5, "joint {k}: action {a} → target → action {back}");
        }
    }
    for _ in 0..120 {
        let out = e.step(&hold, &mut obs);
        assert!(!out.terminated, "holding the standing pose must not fall within 2 s");
        assert_eq!(out.terms[0], 5.0, "healthy reward while up");
    }
    let height = obs[50];
    assert!((0.85..1.05).contains(&height), "pelvis height {height}");

    // Every joint slammed to one end of its range folds the body: it must fall and terminate.
    let slam = vec![1.0f32; e.act_dim()];
    let mut terminated_at = None;
    for t in 0..200 {
        let out = e.step(&slam, &mut obs);
        assert!(obs.iter().all(|v| v.is_finite()));
        if out.terminated {
            assert_eq!(out.terms[0], 0.0, "no healthy reward on the terminal step");
            terminated_at = Some(t);
            break;
        }
    }
    assert!(terminated_at.is_some(), "slamming every joint to its limit must end in a fall");
}

#[test]
fn snapshot_restore_reproduces_the_future() {
    let model = model();
    let mut a = env(&model);
    let mut b = env(&model);
    let mut rng = EnvRng::seed_from_u64(9);
    let (mut oa, mut ob) = (vec![0.0; a.obs_dim()], vec![0.0; b.obs_dim()]);
    a.reset(&mut rng, &mut oa);
    let wave = |t: usize, k: usize| (0.3 * ((t * 7 + k * 3) as f32).sin()).clamp(-1.0, 1.0);
    let act = |t: usize| (0..25).map(|k| wave(t, k)).collect::<Vec<f32>>();
    for t in 0..15 {
        a.step(&act(t), &mut oa);
    }
    b.restore(&a.snapshot()).expect("same scene");
    assert_eq!(b.steps(), a.steps());
    for t in 15..40 {
        let (ra, rb) = (a.step(&act(t), &mut oa), b.step(&act(t), &mut ob));
        assert_eq!(ra, rb, "step {t}");
        assert_eq!(oa, ob, "observation after step {t}");
    }
    let short = &a.snapshot()[..10];
    let err = b.restore(short).expect_err("a truncated snapshot is refused");
    assert!(matches!(err, StateError::Length { got: 10, .. }), "{err}");
}

#[test]
fn ppo_on_the_humanoid_resumes_bit_for_bit() {
    let model = model();
    let envs = || (0..3).map(|_| env(&model)).collect::<Vec<_>>();
    let cfg = PpoConfig {
        num_envs: 3,
        num_steps: 16,
        num_iterations: 4,
        num_minibatches: 2,
        update_epochs: 2,
        parallel_envs: true,
        policy: PolicyConfig { policy_hidden: vec![32], value_hidden: vec![32], ..Default::default() },
        ..PpoConfig::default()
    };
    let weights = |p: &mut Ppo<HumanoidEnv<Locomotion>>| {
        use repertoire_learn::nn::Parameters;
        p.agent.params_mut().iter().map(|(_, t)| t.values()).collect::<Vec<_>>()
    };
    let mut straight = Ppo::new(cfg.clone(), envs());
    let mut returns = Vec::new();
    straight.train(4, |m| returns.push(m.mean_return));

    let mut first = Ppo::new(cfg, envs());
    first.train(2, |_| {});
    let dir = std::env::temp_dir().join(format!("repertoire-humanoid-resume-{}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("temp dir");
    let stem = dir.join("ckpt");
    checkpoint::save(&mut first, &stem).expect("save");
    let mut resumed = checkpoint::load(&stem, envs()).expect("load");
    resumed.train(2, |_| {});
    assert_eq!(resumed.global_step, straight.global_step);
    assert_eq!(resumed.next_obs, straight.next_obs, "the worlds continued identically");
    assert_eq!(weights(&mut resumed), weights(&mut straight), "the weights match bit for bit");
    assert!(returns.iter().any(|r| r.is_finite()), "episodes finished and were scored: {returns:?}");
    let _ = std::fs::remove_dir_all(&dir);
}
