//! The latent low level against real MuJoCo, the real clip pack and the committed skill
//! library: the AR(1) KL against closed forms computed here independently, reference features
//! on the clip, a tiny collect → train → save → reload → one-shot pass, and damaged files.

use std::path::{Path, PathBuf};
use std::sync::OnceLock;

use rand::{Rng, SeedableRng};
use repertoire_latent::LatentError;
use repertoire_latent::dataset::{CollectOptions, Dataset, collect};
use repertoire_latent::eval::one_shot;
use repertoire_latent::model::{AWR_MIN_CELL, LatentConfig, LatentPolicy, Weighting, kl_ar1};
use repertoire_latent::reference::{ROOT_VALUES, reference_features, reference_size};
use repertoire_latent::train::{TrainOptions, Trainer, phase_baseline, train, transition_weights};
use repertoire_skill::imitation::ImitationTask;
use repertoire_skill::{SkillSetup, SpecFile};

fn root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../..")
}

fn specs(names: &[&str]) -> Vec<PathBuf> {
    names.iter().map(|n| root().join(format!("specs/{n}.ron"))).collect()
}

fn temp(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("repertoire-latent-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).expect("temp dir");
    dir
}

/// 600 noisy expert steps from walk and turn_left, saved once for every test here.
fn tiny_dataset() -> &'static (PathBuf, Dataset) {
    static DATA: OnceLock<(PathBuf, Dataset)> = OnceLock::new();
    DATA.get_or_init(|| {
        let opts = CollectOptions {
            library: root().join("library"),
            specs: specs(&["walk", "turn_left"]),
            steps_per_skill: 300,
            k: 5,
            noise_std: 0.1,
            batch: 4,
            seed: 7,
            progress: false,
            command: "test".into(),
        };
        let mut data = collect(&opts).expect("the committed walk and turn_left collect");
        let dir = temp("data");
        data.save(&dir).expect("saves");
        (dir, data)
    })
}

fn tiny_config() -> LatentConfig {
    LatentConfig {
        latent_dim: 8,
        encoder_hidden: vec![32],
        decoder_hidden: vec![32],
        seq_len: 8,
        batch_sequences: 8,
        learning_rate: 3e-3,
        ..LatentConfig::default()
    }
}

/// `∫ q ln(q/p)` on a fine grid (Simpson), for 1-D Gaussians: no closed form involved.
fn kl_by_quadrature(mq: f64, sq: f64, mp: f64, sp: f64) -> f64 {
    let pdf = |x: f64, m: f64, s: f64| (-(x - m).powi(2) / (2.0 * s * s)).exp() / (s * (std::f64::consts::TAU).sqrt());
    let (lo, hi, n) = (mq - 12.0 * sq, mq + 12.0 * sq, 20_000);
    let h = (hi - lo) / n as f64;
    let f = |x: f64| {
        let q = pdf(x, mq, sq);
        if q < 1e-300 { 0.0 } else { q * (q / pdf(x, mp, sp)).ln() }
    };
    let mut s = f(lo) + f(hi);
    for i in 1..n {
        s += f(lo + i as f64 * h) * if i % 2 == 1 { 4.0 } else { 2.0 };
    }
    s * h / 3.0
}

#[test]
fn ar1_kl_matches_quadrature_and_the_closed_form() {
    let alpha = 0.95f32;
    // 1-D, later step: prior N(0.95·1.0, 1 − 0.95²).
    let (mu, sigma, z_prev) = (0.3f32, 0.5f32, 1.0f32);
    let kl = kl_ar1(&[mu], &[sigma.ln()], &[z_prev], &[false], alpha)[0];
    let want = kl_by_quadrature(0.3, 0.5, 0.95, (1.0f64 - 0.95 * 0.95).sqrt());
    assert!((f64::from(kl) - want).abs() < 1e-4 * want.max(1.0), "KL {kl} vs quadrature {want}");
    // 1-D, sequence start: the stationary prior N(0, 1); by hand −ln 0.5 + (0.25 + 0.09)/2 − ½.
    let kl0 = kl_ar1(&[mu], &[sigma.ln()], &[z_prev], &[true], alpha)[0];
    let by_hand = -(0.5f64).ln() + (0.25 + 0.09) / 2.0 - 0.5;
    assert!((f64::from(kl0) - by_hand).abs() < 1e-5, "KL at the start {kl0} vs {by_hand}");
    assert!((by_hand - kl_by_quadrature(0.3, 0.5, 0.0, 1.0)).abs() < 1e-6);
    // A posterior equal to the prior costs nothing.
    let same = kl_ar1(&[alpha * 0.4], &[(1.0 - alpha * alpha).sqrt().ln()], &[0.4], &[false], alpha)[0];
    assert!(same.abs() < 1e-5, "KL(p ‖ p) = {same}");

    // Many dimensions and rows with random numbers against an f64 formula.
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(3);
    let (rows, z) = (5, 60);
    let mu: Vec<f32> = (0..rows * z).map(|_| rng.random_range(-2.0..2.0)).collect();
    let ls: Vec<f32> = (0..rows * z).map(|_| rng.random_range(-3.0..0.5)).collect();
    let zp: Vec<f32> = (0..rows * z).map(|_| rng.random_range(-2.0..2.0)).collect();
    let first = [true, false, false, true, false];
    let got = kl_ar1(&mu, &ls, &zp, &first, alpha);
    for r in 0..rows {
        let a = f64::from(alpha);
        let (pv, want): (f64, f64) = if first[r] { (1.0, 0.0) } else { (1.0 - a * a, 0.0) };
        let mut want = want;
        for d in 0..z {
            let i = r * z + d;
            let pm = if first[r] { 0.0 } else { a * f64::from(zp[i]) };
            let sq = f64::from(ls[i]).exp();
            want += (pv.sqrt() / sq).ln() + (sq * sq + (f64::from(mu[i]) - pm).powi(2)) / (2.0 * pv) - 0.5;
        }
        assert!((f64::from(got[r]) - want).abs() < 1e-4 * want.abs().max(1.0), "row {r}: {} vs {want}", got[r]);
        assert!(got[r] > 0.0);
    }
}

#[test]
fn reference_features_follow_the_clip_relative_to_the_body() {
    for name in ["walk", "turn_left"] {
        let spec = SpecFile::load(&specs(&[name])[0]).expect("spec");
        let setup = SkillSetup::new(spec, &root().join("library")).expect("setup");
        let mut env = setup.env();
        let mut task = ImitationTask::new(setup.settings.clone());
        let r = &setup.settings.reference;
        let (k, dof) = (5, r.dof);
        let mut out = vec![0.0f32; reference_size(k, dof)];
        // Frames near the clip's end too: a looping clip carries on into its next cycle.
        for f in [0, r.frames() / 2, r.frames() - 3] {
            task.place_at_frame(env.world_mut(), f, 1.5, -0.5, 2.0);
            // The frame the body stands in lies where the body is.
            let (f0, p0, h0) = task.reference_ahead(0);
            let pelvis = env.world().pelvis_frame().pos;
            assert_eq!(f0, f);
            assert!((0..3).all(|i| (p0[i] - pelvis[i]).abs() < 1e-6), "{name} frame {f}: {p0:?} vs {pelvis:?}");
            assert!(repertoire_scenes::math::wrap_angle(h0 - env.world().heading()).abs() < 1e-6);
            reference_features(&task, env.world(), k, &mut out);
            let mut last = [0.0f32; 3];
            for j in 0..k {
                let row = &out[j * (dof + ROOT_VALUES)..(j + 1) * (dof + ROOT_VALUES)];
                let (fj, _, _) = task.reference_ahead(j + 1);
                let joints: Vec<f32> = r.joints_at(fj).iter().map(|&a| a as f32).collect();
                assert_eq!(&row[..dof], &joints[..], "{name}: joints of frame {fj}");
                let offset = [row[dof], row[dof + 1], row[dof + 2]];
                let step = ((offset[0] - last[0]).powi(2) + (offset[1] - last[1]).powi(2)).sqrt();
                // One control step (1/60 s) of walking or turning moves the root a few cm at most.
                assert!(step < 0.08, "{name} frame {f} + {}: the reference root jumps {step} m", j + 1);
                let (s, c) = (row[dof + 3], row[dof + 4]);
                assert!((s * s + c * c - 1.0).abs() < 1e-5 && c > 0.9, "{name}: heading change sin {s} cos {c}");
                last = offset;
            }
        }
    }
}

#[test]
fn collect_writes_a_dataset_that_reloads_and_refuses_damage() {
    let (dir, data) = tiny_dataset();
    let m = &data.manifest;
    assert_eq!(data.len(), 600);
    assert_eq!(m.k, 5);
    assert_eq!(m.skills.iter().map(|s| s.name.as_str()).collect::<Vec<_>>(), ["walk", "turn_left"]);
    assert_eq!(m.reference_size, 5 * (m.act_dim + ROOT_VALUES));
    assert!(m.proprio.features.iter().all(|f| !matches!(f, repertoire_scenes::Feature::PropPose(_))));
    assert_eq!(data.proprio.len(), 600 * m.proprio.size);
    // Noise moved the actions off the mean, within [-1, 1]; rewards are imitation rewards.
    let diff: f32 = data.mean_action.iter().zip(&data.noisy_action).map(|(a, b)| (a - b).abs()).sum::<f32>()
        / data.mean_action.len() as f32;
    assert!(diff > 0.03 && diff < 0.2, "mean |noisy − mean| = {diff}");
    assert!(data.noisy_action.iter().all(|a| a.abs() <= 1.0));
    assert!(data.reward.iter().all(|&r| (0.0..=0.8 + 1e-6).contains(&r)));
    // Episodes are contiguous with consecutive steps.
    for i in 1..data.len() {
        if data.episode[i] == data.episode[i - 1] {
            assert_eq!(data.step[i], data.step[i - 1] + 1, "transition {i}");
        } else {
            assert!(data.episode[i] > data.episode[i - 1]);
        }
    }
    let back = Dataset::load(dir).expect("reloads");
    assert_eq!(&back, data);

    // A flipped byte in the data, a broken manifest, a prop feature in the proprioception.
    let bad = temp("bad-data");
    for f in ["dataset.ron", "dataset.safetensors"] {
        std::fs::copy(dir.join(f), bad.join(f)).unwrap();
    }
    let path = bad.join("dataset.safetensors");
    let mut bytes = std::fs::read(&path).unwrap();
    let n = bytes.len();
    bytes[n - 5] ^= 0x40;
    std::fs::write(&path, &bytes).unwrap();
    let err = Dataset::load(&bad).expect_err("a flipped byte is refused").to_string();
    assert!(err.contains("dataset.safetensors") && err.contains("checksum"), "{err}");
    std::fs::write(&path, &bytes[..n / 2]).unwrap();
    assert!(Dataset::load(&bad).expect_err("truncated").to_string().contains("dataset.safetensors"));

    let text = std::fs::read_to_string(dir.join("dataset.ron")).unwrap();
    std::fs::write(bad.join("dataset.ron"), &text[..text.len() / 3]).unwrap();
    let err = Dataset::load(&bad).expect_err("a cut manifest is refused");
    assert!(
        matches!(err, LatentError::File(repertoire_files::FileError::Ron { .. }))
            && err.to_string().contains("dataset.ron:"),
        "{err}"
    );
    let with_prop = text.replacen("FootContacts,", "FootContacts,\n            PropPose(\"chair\"),", 1);
    assert_ne!(with_prop, text);
    std::fs::write(bad.join("dataset.ron"), with_prop).unwrap();
    let err = Dataset::load(&bad).expect_err("a prop in the proprioception is refused").to_string();
    assert!(err.contains("dataset.ron") && err.contains("prop_pose:chair"), "{err}");
}

#[test]
fn weights_bc_clip_balanced_and_rwr() {
    let (_, data) = tiny_dataset();
    let bc = transition_weights(data, Weighting::Bc);
    assert!(bc.iter().all(|&w| w == 1.0));
    let clip = transition_weights(data, Weighting::ClipBalanced);
    let per_skill =
        |w: &[f32], s: u32| -> f32 { w.iter().zip(&data.skill).filter(|(_, k)| **k == s).map(|(w, _)| w).sum() };
    assert!((per_skill(&clip, 0) - per_skill(&clip, 1)).abs() < 1e-2 * per_skill(&clip, 0));
    // Normalised to mean 1, then capped: uncapped the mean is 1 exactly; the cap only lowers
    // weights, and every weight under it is the uncapped one.
    let uncapped = transition_weights(data, Weighting::Rwr { temperature: 1.0, gamma: 0.95, max_weight: f32::MAX });
    let mean_of = |w: &[f32]| w.iter().map(|&x| f64::from(x)).sum::<f64>() / w.len() as f64;
    assert!((mean_of(&uncapped) - 1.0).abs() < 1e-4, "uncapped mean RWR weight {}", mean_of(&uncapped));
    let rwr = transition_weights(data, Weighting::Rwr { temperature: 1.0, gamma: 0.95, max_weight: 20.0 });
    assert!(rwr.iter().all(|&w| w > 0.0 && w <= 20.0), "RWR weights outside (0, 20]");
    for (&w, &u) in rwr.iter().zip(&uncapped) {
        assert_eq!(w, u.min(20.0));
    }
    assert!(mean_of(&rwr) <= 1.0 + 1e-4);
    // Steps with more imitation return ahead of them weigh more.
    let spread =
        rwr.iter().copied().fold(f32::NEG_INFINITY, f32::max) / rwr.iter().copied().fold(f32::INFINITY, f32::min);
    assert!(spread > 1.5, "RWR weights barely differ ({spread})");
}

/// AWR weighs a transition by how much better it did than the others at the same point of the
/// same clip, where RWR weighs it by the return itself: a reward that depends only on the clip
/// phase spreads RWR's weights and leaves AWR's flat, while the one episode that earned more
/// than its peers at every phase is the one AWR favours.
#[test]
fn awr_weighs_the_return_against_the_same_clip_phase() {
    let (_, tiny) = tiny_dataset();
    let mut data = tiny.clone();
    let n = data.len();
    assert!(n >= 400, "{n} transitions");
    // Episodes of 10 steps, alternating skills, each starting at frame 0; the reward grows with
    // the frame, and episode 0 earns 0.3 more at every step.
    for i in 0..n {
        let (episode, step) = (i / 10, i % 10);
        data.episode[i] = episode as u32;
        data.skill[i] = (episode % 2) as u32;
        data.step[i] = step as u32;
        data.frame[i] = step as u32;
        data.reward[i] = step as f32 / 10.0 + if episode == 0 { 0.3 } else { 0.0 };
    }
    // The last transition alone at its frame: its baseline is its skill's mean.
    data.frame[n - 1] = 999;
    let awr = |max_weight| transition_weights(&data, Weighting::Awr { temperature: 0.5, gamma: 0.95, max_weight });
    let uncapped = awr(f32::MAX);
    let mean_of = |w: &[f32]| w.iter().map(|&x| f64::from(x)).sum::<f64>() / w.len() as f64;
    assert!((mean_of(&uncapped) - 1.0).abs() < 1e-4, "uncapped mean AWR weight {}", mean_of(&uncapped));
    for (&w, &u) in awr(1.5).iter().zip(&uncapped) {
        assert_eq!(w, u.min(1.5));
    }
    let rwr = transition_weights(&data, Weighting::Rwr { temperature: 0.5, gamma: 0.95, max_weight: f32::MAX });
    let spread = |w: &[f32], pick: &dyn Fn(usize) -> bool| {
        let v: Vec<f32> = (0..n).filter(|&i| pick(i)).map(|i| w[i]).collect();
        v.iter().copied().fold(f32::NEG_INFINITY, f32::max) / v.iter().copied().fold(f32::INFINITY, f32::min)
    };
    // Skill 1 (odd episodes, none bumped, none alone at a frame): every phase the same to AWR.
    let skill1 = |i: usize| data.skill[i] == 1 && i != n - 1;
    assert!(spread(&rwr, &skill1) > 2.0, "RWR spread {} over a phase-only reward", spread(&rwr, &skill1));
    assert!(spread(&uncapped, &skill1) < 1.0 + 1e-4, "AWR spread {}", spread(&uncapped, &skill1));
    // Episode 0 outweighs every other transition of its skill.
    let best_other = (10..n).filter(|&i| data.skill[i] == 0).map(|i| uncapped[i]).fold(0.0f32, f32::max);
    assert!(uncapped[..10].iter().all(|&w| w > best_other), "{:?} against {best_other}", &uncapped[..10]);

    // The baseline itself: a cell's mean, or the skill's for a cell under AWR_MIN_CELL.
    assert!((10..n).filter(|&i| data.skill[i] == 0 && data.frame[i] == 3).count() + 1 >= AWR_MIN_CELL);
    let g: Vec<f64> = (0..n).map(|i| i as f64).collect();
    let v = phase_baseline(&data, &g);
    let mean = |pick: &dyn Fn(usize) -> bool| {
        let idx: Vec<usize> = (0..n).filter(|&i| pick(i)).collect();
        idx.iter().map(|&i| g[i]).sum::<f64>() / idx.len() as f64
    };
    let cell = mean(&|i| data.skill[i] == 0 && data.frame[i] == 3);
    assert!((v[3] - cell).abs() < 1e-9, "{} against {cell}", v[3]);
    let skill = mean(&|i| data.skill[i] == data.skill[n - 1]);
    assert!((v[n - 1] - skill).abs() < 1e-9, "{} against {skill}", v[n - 1]);
}

#[test]
fn training_lowers_the_loss_and_the_model_reloads_identically() {
    let (dir, data) = tiny_dataset();
    let mut trainer = Trainer::new(data, tiny_config()).expect("trainer");
    let fixed = trainer.sample_batch();
    let before = trainer.loss_on(&fixed);
    for _ in 0..150 {
        trainer.update().expect("finite loss");
    }
    let after = trainer.loss_on(&fixed);
    assert!(after.action_mse < 0.6 * before.action_mse, "action MSE {} → {}", before.action_mse, after.action_mse);
    assert!(after.loss < before.loss - 1.0, "loss {} → {}", before.loss, after.loss);

    let opts = TrainOptions {
        max_updates: 20,
        max_seconds: 60.0,
        log_every: 10,
        progress: false,
        metrics_csv: None,
        command: "test".into(),
    };
    let (mut policy, history) = train(data, dir, tiny_config(), &opts).expect("trains");
    assert_eq!(history.len(), 2);
    let m = &policy.manifest;
    assert_eq!((m.latent_dim, m.k, m.alpha, m.act_dim), (8, 5, 0.95, data.act_dim()));
    // The decoder reads proprioception, then z: nothing about props.
    let names: Vec<&str> = m.decoder_input.iter().map(|e| e.name.as_str()).collect();
    assert_eq!(names.last(), Some(&"z"));
    assert!(names.iter().all(|n| !n.starts_with("prop_pose")), "{names:?}");
    assert_eq!(m.decoder_features, repertoire_scenes::Feature::proprioception());

    let out = temp("model");
    policy.save(&out).expect("saves");
    let mut back = LatentPolicy::load(&out).expect("reloads");
    let (f, s, z, a) = (data.reference_dim(), data.proprio_dim(), 8, data.act_dim());
    let rows = 7;
    let zp: Vec<f32> = (0..rows * z).map(|i| (i as f32 * 0.37).sin()).collect();
    let (mut mu1, mut ls1, mut mu2, mut ls2) =
        (vec![0.0; rows * z], vec![0.0; rows * z], vec![0.0; rows * z], vec![0.0; rows * z]);
    policy.encode(&data.reference[..rows * f], &zp, &mut mu1, &mut ls1);
    back.encode(&data.reference[..rows * f], &zp, &mut mu2, &mut ls2);
    assert_eq!((mu1, ls1), (mu2, ls2));
    let (mut a1, mut a2) = (vec![0.0; rows * a], vec![0.0; rows * a]);
    policy.decode(&data.proprio[..rows * s], &zp, &mut a1);
    back.decode(&data.proprio[..rows * s], &zp, &mut a2);
    assert_eq!(a1, a2);
    assert!(a1.iter().all(|v| v.is_finite()));

    // As a controller it carries z: step 2 encodes with step 1's μ as z_{t−1} (zero at the start).
    use repertoire_latent::rollout::Controller;
    let b = 3;
    let (refs, props) = (&data.reference[..b * f], &data.proprio[..b * s]);
    let mut acts = vec![0.0; b * a];
    for i in 0..b {
        back.begin(i);
    }
    back.act(&[], props, refs, &mut acts);
    back.act(&[], props, refs, &mut acts);
    let (mut m0, mut l0, mut m1, mut l1) = (vec![0.0; b * z], vec![0.0; b * z], vec![0.0; b * z], vec![0.0; b * z]);
    policy.encode(refs, &vec![0.0; b * z], &mut m0, &mut l0);
    policy.encode(refs, &m0, &mut m1, &mut l1);
    let mut want = vec![0.0; b * a];
    policy.decode(props, &m1, &mut want);
    assert_eq!(acts, want);

    // A decoder that would read a prop, and damaged weights, are refused naming the file.
    let text = std::fs::read_to_string(out.join("latent.ron")).unwrap();
    let with_prop = text.replacen("FootContacts,", "FootContacts,\n        PropPose(\"chair\"),", 1);
    assert_ne!(with_prop, text);
    std::fs::write(out.join("latent.ron"), with_prop).unwrap();
    let err = LatentPolicy::load(&out).expect_err("a prop in the decoder is refused").to_string();
    assert!(err.contains("latent.ron") && err.contains("prop_pose:chair"), "{err}");
    std::fs::write(out.join("latent.ron"), &text).unwrap();
    let w = out.join("latent.safetensors");
    let mut bytes = std::fs::read(&w).unwrap();
    let n = bytes.len();
    bytes[n - 3] ^= 1;
    std::fs::write(&w, &bytes).unwrap();
    let err = LatentPolicy::load(&out).expect_err("damaged weights are refused").to_string();
    assert!(err.contains("latent.safetensors"), "{err}");

    // One-shot imitation runs both controllers on the same starts and reports in range.
    let rows = one_shot(&mut policy, &out, &root().join("library"), &specs(&["turn_left"]), 4, 4, 3)
        .expect("one-shot evaluation");
    assert_eq!(rows.len(), 1);
    let r = &rows[0];
    assert_eq!(r.episodes, 4);
    assert!(r.expert.normalized_length > 0.9, "the committed turn_left completes its clip: {r:?}");
    for v in [r.expert.normalized_return, r.latent.normalized_length, r.latent.normalized_return] {
        assert!((0.0..=1.0 + 1e-9).contains(&v), "{r:?}");
    }
}

#[test]
fn a_high_level_over_z_drives_the_frozen_decoder_to_a_target() {
    use repertoire_latent::high::{GoToOptions, GoToSettings, Z_BOUND, goto_envs, train_goto};
    use repertoire_learn::env::{Env, EnvRng};
    use std::sync::Arc;

    let (dir, data) = tiny_dataset();
    let opts = TrainOptions {
        max_updates: 30,
        max_seconds: 60.0,
        log_every: 10,
        progress: false,
        metrics_csv: None,
        command: "test".into(),
    };
    let (policy, _) = train(data, dir, tiny_config(), &opts).expect("trains");
    let spec = SpecFile::load(&specs(&["walk"])[0]).expect("spec");
    let setup = SkillSetup::new(spec, &root().join("library")).expect("setup");
    let settings = Arc::new(GoToSettings {
        start: Arc::clone(&setup.settings),
        distance_m: (2.0, 4.0),
        azimuth_deg: 90.0,
        reach_m: 0.5,
        reach_bonus: 10.0,
        min_height: 0.5,
    });
    let path = PathBuf::from("tiny-model/latent.ron"); // named in errors only
    let mut envs = goto_envs(&setup.model, &settings, &policy, &path, 2.0, 2).expect("envs");
    let env = &mut envs[0];
    assert_eq!(env.act_dim(), 8, "the action is z");
    let (lo, hi) = env.action_bounds();
    assert!(lo.iter().all(|&v| v == -Z_BOUND) && hi.iter().all(|&v| v == Z_BOUND));
    assert_eq!(env.obs_dim(), data.proprio_dim() + 3, "proprioception and the target");
    let mut obs = vec![0.0f32; env.obs_dim()];
    let mut rng = <EnvRng as rand::SeedableRng>::seed_from_u64(5);
    env.reset(&mut rng, &mut obs);
    let dist0 = obs[obs.len() - 1];
    assert!((2.0..=4.0 + 1e-3).contains(&dist0), "target {dist0} m away");
    // Different latents move the body differently: the decoder is in the loop.
    let snap = env.snapshot();
    let mut a = obs.clone();
    let mut b = obs.clone();
    for _ in 0..10 {
        env.step(&[0.0; 8], &mut a);
    }
    env.restore(&snap).expect("restores");
    for _ in 0..10 {
        env.step(&[1.5; 8], &mut b);
    }
    assert!(a.iter().zip(&b).map(|(x, y)| (x - y).abs()).sum::<f32>() > 1e-2, "z changes nothing");

    let out = temp("goto");
    let o = GoToOptions {
        iterations: 1,
        envs: 2,
        steps: 16,
        seed: 1,
        trials: 3,
        eval_seed: 9,
        episode_s: 1.0,
        init_log_std: -1.0,
        progress: false,
    };
    let got = train_goto(&setup.model, &settings, &policy, &path, &o, &out).expect("trains the high level");
    assert_eq!(got.samples, 32);
    for r in [got.zero, got.trained] {
        assert_eq!(r.trials, 3);
        assert!(r.mean_min_distance > 0.0 && r.mean_min_distance < 4.1 && r.mean_seconds <= 1.0 + 1e-9, "{r:?}");
    }
    assert!(out.join("metrics.csv").exists());
}
