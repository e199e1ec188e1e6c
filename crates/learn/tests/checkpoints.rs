//! Checkpoints round-trip, resume bit-for-bit, and refuse damaged or mismatched files.

mod common;

use std::path::PathBuf;

use repertoire_learn::acting::ShapeError;
use repertoire_learn::checkpoint::{self, CheckpointError};
use repertoire_learn::env::Env;
use repertoire_learn::nn::Parameters;
use repertoire_learn::ppo::{IterationMetrics, Ppo, PpoConfig};
use repertoire_learn::run_dir::RunDir;

fn temp_dir(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("repertoire-learn-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).expect("create temp dir");
    dir
}

/// Weights, Adam moments, observation mean, next observations.
type Fingerprint = (Vec<Vec<f32>>, Vec<(Vec<f32>, Vec<f32>)>, Vec<f64>, Vec<f32>);

/// Every number that defines where training stands.
fn fingerprint<E: Env>(ppo: &mut Ppo<E>) -> Fingerprint {
    let weights = ppo.agent.params_mut().iter().map(|(_, p)| p.values()).collect();
    (weights, ppo.optimizer.moments(), ppo.obs_rms.mean.clone(), ppo.next_obs.clone())
}

/// Metrics without the wall-clock fields.
fn comparable(m: &IterationMetrics) -> IterationMetrics {
    IterationMetrics { samples_per_sec: 0.0, env_time_fraction: 0.0, ..m.clone() }
}

#[test]
fn resume_continues_bit_for_bit() {
    let dir = temp_dir("resume");
    let cfg = common::tiny_config(4);
    let k = 3;

    let mut straight = Ppo::new(cfg.clone(), common::cartpoles(4));
    let mut straight_metrics = Vec::new();
    straight.train(2 * k, |m| straight_metrics.push(comparable(m)));

    let mut first = Ppo::new(cfg.clone(), common::cartpoles(4));
    first.train(k, |_| {});
    let stem = dir.join("ckpt");
    checkpoint::save(&mut first, &stem).expect("save");
    drop(first);
    let mut resumed = checkpoint::load(&stem, common::cartpoles(4)).expect("load");
    let mut resumed_metrics = Vec::new();
    resumed.train(k, |m| resumed_metrics.push(comparable(m)));

    assert_eq!(resumed.iteration, 2 * k);
    assert_eq!(resumed.global_step, straight.global_step);
    assert_eq!(fingerprint(&mut resumed), fingerprint(&mut straight));
    // NaN-free comparison of the metrics of the last k iterations.
    let as_text = |v: &[IterationMetrics]| format!("{v:?}");
    assert_eq!(as_text(&resumed_metrics), as_text(&straight_metrics[k..]));
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn parallel_and_serial_stepping_agree() {
    let mut cfg = common::tiny_config(4);
    cfg.parallel_envs = true;
    let mut par = Ppo::new(cfg.clone(), common::cartpoles(4));
    par.train(2, |_| {});
    cfg.parallel_envs = false;
    let mut ser = Ppo::new(cfg, common::cartpoles(4));
    ser.train(2, |_| {});
    assert_eq!(fingerprint(&mut par), fingerprint(&mut ser));
}

#[test]
fn round_trip_and_refusals() {
    let dir = temp_dir("refuse");
    let cfg = common::tiny_config(2);
    let drift = |d| (0..2).map(|_| common::Drift::new(d)).collect::<Vec<_>>();
    let mut ppo = Ppo::new(cfg.clone(), drift(3));
    ppo.train(1, |_| {});
    let stem = dir.join("ok");
    let manifest = checkpoint::save(&mut ppo, &stem).expect("save");
    let leftovers: Vec<_> = std::fs::read_dir(&dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .filter(|n| n.contains("partial"))
        .collect();
    assert!(leftovers.is_empty(), "temporary files left behind: {leftovers:?}");

    // Round trip.
    let mut back = checkpoint::load(&stem, drift(3)).expect("load");
    assert_eq!(fingerprint(&mut back), fingerprint(&mut ppo));
    assert_eq!(back.iteration, 1);
    let m = checkpoint::read_manifest(&manifest).expect("manifest");
    assert_eq!((m.obs_dim, m.act_dim, m.num_envs), (3, 1, 2));

    // Different observation size.
    let err = checkpoint::load(&stem, drift(4)).err().expect("refused");
    assert!(matches!(err, CheckpointError::Mismatch { .. }), "{err}");
    eprintln!("mismatch: {err}");
    let text = err.to_string();
    assert!(
        text.contains("ok.ron") && text.contains("observation size") && text.contains('3') && text.contains('4'),
        "{text}"
    );

    // Truncated weights.
    let weights = dir.join("ok.safetensors");
    let good = std::fs::read(&weights).expect("read");
    std::fs::write(&weights, &good[..good.len() / 2]).expect("write");
    let err = checkpoint::load(&stem, drift(3)).err().expect("refused");
    assert!(matches!(err, CheckpointError::Corrupt { .. }), "{err}");
    assert!(err.to_string().contains("ok.safetensors"), "{err}");
    eprintln!("truncated: {err}");

    // One flipped byte.
    let mut bad = good.clone();
    let last = bad.len() - 1;
    bad[last] ^= 0x40;
    std::fs::write(&weights, &bad).expect("write");
    let err = checkpoint::load(&stem, drift(3)).err().expect("refused");
    assert!(matches!(err, CheckpointError::Corrupt { .. }), "{err}");
    std::fs::write(&weights, &good).expect("write");

    // Truncated manifest.
    let text = std::fs::read_to_string(&manifest).expect("read");
    std::fs::write(&manifest, &text[..text.len() / 2]).expect("write");
    let err = checkpoint::load(&stem, drift(3)).err().expect("refused");
    assert!(matches!(err, CheckpointError::Manifest { .. }), "{err}");
    assert!(err.to_string().contains("ok.ron"), "{err}");
    eprintln!("manifest: {err}");

    // Missing file.
    let err = checkpoint::load(&dir.join("absent"), drift(3)).err().expect("refused");
    assert!(matches!(err, CheckpointError::Io { .. }), "{err}");
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn run_directory_records_config_and_metrics() {
    let dir = temp_dir("run");
    let cfg = common::tiny_config(2);
    let mut run = RunDir::create(&dir, &cfg).expect("run dir");
    let mut ppo = Ppo::new(cfg, common::cartpoles(2));
    ppo.train(2, |m| run.log(m).expect("log"));
    let stem = run.checkpoint_stem(ppo.iteration);
    checkpoint::save(&mut ppo, &stem).expect("save");

    let info = std::fs::read_to_string(dir.join("run.ron")).expect("run.ron");
    assert!(info.contains("seed: 7") && info.contains("git_hash"), "{info}");
    let csv = std::fs::read_to_string(dir.join("metrics.csv")).expect("csv");
    let lines: Vec<&str> = csv.lines().collect();
    assert_eq!(lines.len(), 3);
    assert!(lines[0].starts_with("iteration,global_step") && lines[0].ends_with("term_alive,term_effort"));
    assert_eq!(lines[0].split(',').count(), lines[1].split(',').count());
    let jsonl = std::fs::read_to_string(dir.join("metrics.jsonl")).expect("jsonl");
    assert_eq!(jsonl.lines().count(), 2);
    let row: serde_json::Value = serde_json::from_str(jsonl.lines().nth(1).expect("line")).expect("json");
    assert_eq!(row["iteration"], 2);
    assert!(dir.join("checkpoints/iter-000002.ron").exists());
    assert!(dir.join("checkpoints/iter-000002.safetensors").exists());
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn sharded_gradients_match_the_whole_minibatch() {
    // The same iteration with the minibatch gradient taken whole and in three shards: the
    // weights may differ only by float rounding of the sum.
    let mut whole = Ppo::new(PpoConfig { grad_shards: 1, ..common::tiny_config(4) }, common::cartpoles(4));
    let mut sharded = Ppo::new(PpoConfig { grad_shards: 3, ..common::tiny_config(4) }, common::cartpoles(4));
    whole.train(1, |_| {});
    sharded.train(1, |_| {});
    let (a, b) = (fingerprint(&mut whole).0, fingerprint(&mut sharded).0);
    let mut max_diff = 0.0f32;
    let mut moved = 0.0f32;
    let start = fingerprint(&mut Ppo::new(common::tiny_config(4), common::cartpoles(4))).0;
    for ((x, y), s) in a.iter().flatten().zip(b.iter().flatten()).zip(start.iter().flatten()) {
        max_diff = max_diff.max((x - y).abs());
        moved = moved.max((x - s).abs());
    }
    assert!(moved > 1e-4, "the update moved the weights ({moved})");
    assert!(max_diff < 1e-5 * moved.max(1.0), "sharded and whole updates differ by {max_diff}");
}

#[test]
fn a_widened_policy_acts_as_before_whatever_its_new_inputs_say() {
    // A skill's next training stage may observe more (walk's target): the old policy widened
    // with zero weights for the appended inputs must act exactly as it did, and load into a
    // learner of the wider observation.
    use repertoire_learn::acting::ActingPolicy;
    let mut ppo = Ppo::new(common::tiny_config(2), common::cartpoles(2));
    ppo.iterate();
    let mut old = ActingPolicy::from_ppo(&ppo);
    assert!(old.obs_rms.mean.iter().any(|m| *m != 0.0), "training moved the statistics");
    let mut wide = old.widened(7).expect("widen 4 → 7");
    assert_eq!((wide.obs_dim(), wide.act_dim()), (7, old.act_dim()));
    let mut a = vec![0.0; old.act_dim()];
    let mut b = vec![0.0; old.act_dim()];
    for (k, extra) in [[0.0, 0.0, 0.0], [5.0, -3.0, 100.0], [-1e3, 0.5, 7.0]].iter().enumerate() {
        let obs = [0.1 * k as f32, -0.2, 0.05, 0.3];
        old.act(&obs, &mut a);
        let mut wider = obs.to_vec();
        wider.extend_from_slice(extra);
        wide.act(&wider, &mut b);
        assert_eq!(a, b, "extra inputs {extra:?} changed the action");
    }
    assert_ne!(a, vec![0.0; a.len()], "a trained policy acts");
    assert_eq!(old.widened(3).expect_err("narrowing"), ShapeError::Narrow { have: 4, want: 3 });

    let mut wider_ppo = Ppo::new(common::tiny_config(2), vec![common::Drift::new(7), common::Drift::new(7)]);
    let err = old.load_into(&mut wider_ppo).expect_err("4 inputs into a 7-input learner");
    assert!(matches!(err, ShapeError::Layer { what: "policy", layer: 0, saved: (4, _), config: (7, _) }), "{err}");
    // Both envs take one action: only the observation width differs.
    assert_eq!(common::Drift::new(7).act_dim(), old.act_dim());
    wide.load_into(&mut wider_ppo).expect("the widened policy fits");
}

#[test]
fn inputs_inserted_mid_observation_change_nothing_until_trained() {
    // A new skill grown from another sees more features before the task values (carry sees
    // the box walk never saw): inserted inputs enter with zero weight wherever they go.
    use repertoire_learn::acting::ActingPolicy;
    let mut ppo = Ppo::new(common::tiny_config(2), common::cartpoles(2));
    ppo.iterate();
    let mut old = ActingPolicy::from_ppo(&ppo);
    let mut a = vec![0.0; old.act_dim()];
    let mut b = vec![0.0; old.act_dim()];
    for at in 0..=4 {
        let mut grown = old.with_inputs_at(at, 2).expect("insert 2 inputs");
        assert_eq!(grown.obs_dim(), 6);
        for (k, extra) in [[0.0, 0.0], [9.0, -4.0], [-1e3, 2.5]].iter().enumerate() {
            let obs = [0.1 * k as f32, -0.2, 0.05, 0.3];
            old.act(&obs, &mut a);
            let mut wider = obs.to_vec();
            wider.splice(at..at, extra.iter().copied());
            grown.act(&wider, &mut b);
            assert_eq!(a, b, "inputs {extra:?} inserted at {at} changed the action");
        }
        // The statistics moved with their inputs: old input j is now at j or j + 2.
        for j in 0..4 {
            let k = if j < at { j } else { j + 2 };
            assert_eq!(grown.obs_rms.mean[k], old.obs_rms.mean[j], "input {j} inserted at {at}");
        }
    }
    assert_eq!(old.with_inputs_at(5, 1).expect_err("past the end"), ShapeError::InsertPast { at: 5, inputs: 4 });
}

#[test]
fn a_critic_round_trips_continues_a_learner_and_refuses_damage() {
    // The critic a skill is saved with: its value network and the reward normaliser's return
    // statistics, which the skill's next training stage starts from.
    use repertoire_learn::acting::ActingCritic;
    let dir = temp_dir("critic");
    let mut ppo = Ppo::new(common::tiny_config(2), common::cartpoles(2));
    ppo.iterate();
    ppo.iterate();
    let critic = ActingCritic::from_ppo(&ppo);
    assert!(critic.returns.count > 0.0, "two iterations fed the reward normaliser");
    let path = dir.join("value.safetensors");
    critic.save(&path).expect("save the critic");
    let back = ActingCritic::load(&path).expect("load the critic");
    assert_eq!(back.value.layers(), critic.value.layers());
    assert_eq!(back.returns, critic.returns);

    // A fresh learner (another seed) takes it over exactly.
    let mut fresh = Ppo::new(PpoConfig { seed: 99, ..common::tiny_config(2) }, common::cartpoles(2));
    assert_ne!(ActingCritic::from_ppo(&fresh).value.layers(), critic.value.layers());
    back.load_into(&mut fresh).expect("same shapes");
    let taken = ActingCritic::from_ppo(&fresh);
    assert_eq!(taken.value.layers(), critic.value.layers());
    assert_eq!(taken.returns, critic.returns);

    // Inputs inserted before the task values enter with zero weight: same values.
    let mut grown = back.with_inputs_at(2, 3).expect("insert three inputs");
    assert_eq!(grown.obs_dim(), critic.obs_dim() + 3);
    let obs: Vec<f32> = (0..critic.obs_dim()).map(|i| 0.3 * i as f32 - 0.4).collect();
    let mut wide = obs.clone();
    wide.splice(2..2, [7.0, -2.0, 50.0]);
    let (mut a, mut b) = ([0.0f32], [0.0f32]);
    let mut value = critic.value.clone();
    value.forward(&obs, &mut a);
    grown.value.forward(&wide, &mut b);
    assert_eq!(a, b, "zero-weight inputs changed the value");
    assert!(back.with_inputs_at(critic.obs_dim() + 1, 1).is_err(), "past the last input");

    // A learner observing something else is refused, naming the widths.
    let mut other = Ppo::new(common::tiny_config(2), vec![common::Drift::new(7), common::Drift::new(7)]);
    let err = back.load_into(&mut other).expect_err("a 4-input critic into a 7-input learner");
    assert_eq!(err, ShapeError::Width { what: "value network's input", saved: 4, learner: 7 }, "{err}");

    // Truncated or poisoned files name the file.
    let bytes = std::fs::read(&path).expect("read");
    std::fs::write(&path, &bytes[..bytes.len() / 2]).expect("truncate");
    match ActingCritic::load(&path) {
        Err(CheckpointError::Corrupt { path: p, .. }) => assert_eq!(p, path),
        other => panic!("a truncated critic loaded: {other:?}"),
    }
    let mut nan = critic.clone();
    nan.returns.var[0] = f64::NAN;
    nan.save(&path).expect("save");
    let err = ActingCritic::load(&path).expect_err("a NaN variance");
    assert!(err.to_string().contains("NaN"), "{err}");
    std::fs::remove_dir_all(&dir).ok();
}
