//! Skills against real MuJoCo and the real clip pack: the imitation reward is at its maximum
//! when the body replays its clip and falls as it diverges; end-pose pools and library entries
//! round-trip; a library skill refuses a world with another body.

use std::path::{Path, PathBuf};

use rand::SeedableRng;
use repertoire_learn::env::{Env, EnvRng};
use repertoire_skill::eval::{StartFrom, evaluate};
use repertoire_skill::imitation::ImitationTask;
use repertoire_skill::library;
use repertoire_skill::pool::{Pool, PoolState};
use repertoire_skill::spec::Goal;
use repertoire_skill::train::{TrainOptions, train};
use repertoire_skill::{SkillSetup, SpecFile};

fn specs() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../../specs")
}

fn temp(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("repertoire-skill-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).expect("temp dir");
    dir
}

fn setup(spec: &str, library: &Path) -> SkillSetup {
    let spec = SpecFile::load(&specs().join(spec)).expect("the shipped spec parses");
    SkillSetup::new(spec, library).expect("the shipped spec builds (needs scripts/setup.sh's clip pack)")
}

#[test]
fn every_shipped_spec_builds() {
    // Experiments and variants sit beside the library's specs; none may rot. Specs that start
    // from predecessors' pools (sit_from_wide) read them from the committed library.
    let library = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../library");
    let mut built = Vec::new();
    for entry in std::fs::read_dir(specs()).unwrap() {
        let path = entry.unwrap().path();
        let text = std::fs::read_to_string(&path).unwrap_or_default();
        if path.extension().is_some_and(|e| e == "ron") && text.contains("SkillSpec(") {
            let spec = SpecFile::load(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
            SkillSetup::new(spec, &library).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
            built.push(path.file_name().unwrap().to_string_lossy().into_owned());
        }
    }
    assert!(built.len() >= 10 && built.iter().any(|n| n == "walk_to.ron"), "{built:?}");
}

#[test]
fn replaying_the_clip_scores_the_maximum_and_diverging_scores_less() {
    for spec in ["walk.ron", "turn_left.ron", "turn_right.ron", "turn_right_wide.ron", "sit.ron", "sit_mocap.ron"] {
        let s = setup(spec, &temp("replay"));
        let mut env = s.env();
        let mut task = ImitationTask::new(s.settings.clone());
        let r = &s.settings.reference;
        let frames = r.frames();
        for f in (0..frames).step_by((frames / 12).max(1)) {
            task.place_at_frame(env.world_mut(), f, 1.0, -2.0, 0.7);
            let out = task.score(env.world(), f);
            for (k, name) in ["pose", "velocity", "end_effector", "root"].iter().enumerate() {
                assert!(
                    out.terms[k] > 0.999,
                    "{spec} frame {f}: {name} similarity {} on the clip itself",
                    out.terms[k]
                );
            }
            assert!(!out.terminated, "{spec} frame {f}: the clip's own pose counts as a fall");
            // The same pose compared with the clip's most different frame scores lower.
            let gap =
                |g: usize| -> f64 { r.joints_at(f).iter().zip(r.joints_at(g)).map(|(a, b)| (a - b) * (a - b)).sum() };
            let other = (0..frames).max_by(|&a, &b| gap(a).total_cmp(&gap(b))).unwrap();
            let off = task.score(env.world(), other);
            assert!(
                off.terms[0] < out.terms[0] - 0.01,
                "{spec}: pose term does not fall off ({} vs {})",
                off.terms[0],
                out.terms[0]
            );
            assert!(off.reward < out.reward, "{spec}: reward does not fall off");
        }
    }
}

#[test]
fn turn_right_is_the_mirrored_left_turn() {
    let lib = temp("turns");
    let left = setup("turn_left.ron", &lib).settings.reference.heading_change().to_degrees();
    let right = setup("turn_right.ron", &lib).settings.reference.heading_change().to_degrees();
    assert!(left > 40.0, "turn_left turns {left:.1}°");
    assert!((left + right).abs() < 1.0, "turn_right ({right:.1}°) mirrors turn_left ({left:.1}°)");
}

#[test]
fn the_wide_turns_turn_about_a_right_angle_each_way() {
    let lib = temp("wide-turns");
    let right = setup("turn_right_wide.ron", &lib).settings.reference.heading_change().to_degrees();
    let left = setup("turn_left_wide.ron", &lib).settings.reference.heading_change().to_degrees();
    let narrow = setup("turn_right.ron", &lib).settings.reference.heading_change().to_degrees();
    assert!((-110.0..-90.0).contains(&right), "turn_right_wide turns {right:.1}°");
    assert!(right < narrow - 30.0, "turn_right_wide ({right:.1}°) is not wider than turn_right ({narrow:.1}°)");
    assert!((left + right).abs() < 1.0, "turn_left_wide ({left:.1}°) mirrors turn_right_wide ({right:.1}°)");
}

#[test]
fn episodes_start_on_the_clip_and_end_with_it() {
    // turn_left with its gait cycle played once instead of looped.
    let path = specs().join("turn_left.ron");
    let text = std::fs::read_to_string(&path).unwrap().replace(", looping: true", "");
    let spec = SpecFile::parse(&path, &text).expect("parses");
    let s = SkillSetup::new(spec, &temp("episodes")).expect("builds");
    assert!(!s.settings.reference.looping);
    let mut env = s.env();
    let mut rng = EnvRng::seed_from_u64(5);
    let mut obs = vec![0.0; env.obs_dim()];
    env.reset(&mut rng, &mut obs);
    assert!(obs.iter().all(|v| v.is_finite()));
    let start = env.task().phase();
    let frames = s.settings.reference.frames();
    assert!(start < frames - 1);
    // Track the reference open-loop with its own joint angles as PD targets: the episode is
    // cut when the clip ends (truncation), unless the body falls first.
    let mut steps = 0;
    loop {
        let f = (env.task().phase() + 1).min(frames - 1);
        let target = s.settings.reference.joints_at(f).to_vec();
        let action: Vec<f32> = target.iter().enumerate().map(|(k, &q)| env.action_for(k, q)).collect();
        let out = env.step(&action, &mut obs);
        steps += 1;
        if out.terminated || out.truncated {
            if out.truncated {
                assert_eq!(steps, frames - 1 - start, "truncated exactly at the clip's end");
            }
            break;
        }
        assert!(steps < frames, "the episode outlived its clip");
    }
}

#[test]
fn pools_round_trip_and_restore_the_state() {
    let s = setup("walk.ron", &temp("pool"));
    let mut env = s.env();
    let mut rng = EnvRng::seed_from_u64(2);
    let mut obs = vec![0.0; env.obs_dim()];
    env.reset(&mut rng, &mut obs);
    let state = PoolState::capture(env.world());
    let pool = Pool { skill: "walk".into(), body_hash: s.model.body.content_hash(), states: vec![state.clone(); 3] };
    let dir = temp("pool-file");
    let path = dir.join("end_poses.ron");
    pool.save(&path).expect("save");
    let back = Pool::load(&path).expect("load");
    assert_eq!(back, pool);
    // Applying the state elsewhere and capturing it again gives it back.
    state.apply(env.world_mut(), -3.0, 4.0, 2.0).expect("apply");
    let again = PoolState::capture(env.world());
    for (a, b) in again.joints.iter().zip(&state.joints).chain(again.joint_vel.iter().zip(&state.joint_vel)) {
        assert!((a - b).abs() < 1e-9);
    }
    assert!((again.height - state.height).abs() < 1e-9);
    for k in 0..3 {
        assert!((again.velocity[k] - state.velocity[k]).abs() < 1e-9);
    }
    // At a reduced speed (fine-tuning's `speed` curriculum) the pose is the same and every
    // velocity is scaled; at speed 0 the pose is frozen.
    assert!(state.joint_vel.iter().any(|v| v.abs() > 0.1) && state.velocity[0].abs() > 0.1, "walk moves");
    for k in [0.0, 0.4] {
        state.apply_at_speed(env.world_mut(), 1.0, 2.0, -1.0, k).expect("apply at speed");
        let slow = PoolState::capture(env.world());
        for (a, b) in slow.joints.iter().zip(&state.joints) {
            assert!((a - b).abs() < 1e-9);
        }
        for (a, b) in slow.joint_vel.iter().zip(&state.joint_vel).chain(slow.velocity.iter().zip(&state.velocity)) {
            assert!((a - k * b).abs() < 1e-9, "{a} is not {k} × {b}");
        }
        for (a, b) in slow.angular.iter().zip(&state.angular) {
            assert!((a - k * b).abs() < 1e-9);
        }
    }
    // A pool with a NaN is refused, naming the state.
    std::fs::write(&path, std::fs::read_to_string(&path).unwrap().replacen("height: ", "height: NaN, _x: ", 1))
        .unwrap();
    assert!(Pool::load(&path).is_err());
}

#[test]
fn a_trained_skill_round_trips_through_the_library_and_refuses_another_body() {
    let lib = temp("library");
    let s = setup("turn_left.ron", &lib);
    let opts = TrainOptions::quick(&lib, &lib.join("run"), 2, 4, 3);
    let out = train(&s, &opts).expect("train");
    assert_eq!(out.history.len(), 2);
    assert!(out.run_dir.join("metrics.csv").exists());
    let mut skill = library::load(&lib, "turn_left").expect("load");
    assert_eq!(skill.manifest.body_hash, s.model.body.content_hash());
    assert_eq!(skill.manifest.clip.hash, s.clip.content_hash());
    skill.check_fits(&s.model).expect("fits its own scene");
    let (report, ends) = evaluate(&s, &mut skill, StartFrom::ClipStart, 6, 3, 9).expect("evaluate");
    assert_eq!(report.trials, 6);
    assert_eq!(ends.len(), report.successes);
    assert!((0.0..=1.0).contains(&report.normalized_length) && report.normalized_length > 0.0);

    // A scene with a different body: the same humanoid with one joint's range changed.
    let xml = repertoire_scenes::BodyDef::humanoid().mjcf.replacen("kp=\"600\"", "kp=\"610\"", 1);
    let dir = temp("other-body");
    std::fs::write(dir.join("other.xml"), &xml).unwrap();
    let map = repertoire_scenes::BodyDef::humanoid().map_text;
    std::fs::write(dir.join("other.map.ron"), map).unwrap();
    let scenario = std::fs::read_to_string(specs().join("arena.ron")).unwrap().replace(
        "body: Humanoid",
        &format!(
            "body: Mjcf(file: \"{}\", map: \"{}\")",
            dir.join("other.xml").display(),
            dir.join("other.map.ron").display()
        ),
    );
    std::fs::write(dir.join("arena.ron"), scenario).unwrap();
    let other = repertoire_scenes::ScenarioFile::load(dir.join("arena.ron")).expect("scenario with the other body");
    let other = repertoire_scenes::WorldModel::build(other).expect("the other body builds");
    let err = skill.check_fits(&other).expect_err("another body is refused").to_string();
    assert!(err.contains("trained on body") && err.contains("manifest.ron"), "{err}");

    // A corrupted policy file is refused with the file named.
    let policy = lib.join("turn_left").join("policy.safetensors");
    let mut bytes = std::fs::read(&policy).unwrap();
    let n = bytes.len();
    bytes[n - 3] ^= 0x55;
    std::fs::write(&policy, bytes).unwrap();
    let err = library::load(&lib, "turn_left").expect_err("corrupt policy").to_string();
    assert!(err.contains("policy.safetensors"), "{err}");
}

#[test]
fn a_training_run_resumed_from_its_checkpoint_ends_where_the_uninterrupted_run_ends() {
    // The skill's starts and the physics are restored exactly, so the resumed run learns the
    // same weights from the same samples.
    let (straight, resumed) = (temp("straight"), temp("resumed"));
    let s = setup("turn_left.ron", &straight);
    let opts = TrainOptions { checkpoint_every: 2, ..TrainOptions::quick(&straight, &straight.join("run"), 4, 2, 5) };
    train(&s, &opts).expect("train");
    let stem = straight.join("run/checkpoints/iter-000002");
    let again = TrainOptions { resume: Some(stem), ..TrainOptions::quick(&resumed, &resumed.join("run"), 4, 2, 5) };
    let out = train(&setup("turn_left.ron", &resumed), &again).expect("resume");
    assert_eq!(out.history.len(), 2, "iterations 3 and 4");
    let policy = |lib: &Path| std::fs::read(lib.join("turn_left/policy.safetensors")).expect("policy");
    assert!(policy(&resumed) == policy(&straight), "the resumed run's policy differs from the uninterrupted run's");
    let rows = std::fs::read_to_string(resumed.join("run/metrics.csv")).unwrap();
    assert_eq!(rows.lines().skip(1).map(|l| l.split(',').next().unwrap()).collect::<Vec<_>>(), ["3", "4"]);
    // Asking for more iterations than the run had extends it; fewer than it has run is refused.
    let extended = temp("extended");
    let last = straight.join("run/checkpoints/iter-000004");
    let more = |n| TrainOptions {
        resume: Some(last.clone()),
        ..TrainOptions::quick(&extended, &extended.join("run"), n, 2, 5)
    };
    let err = train(&setup("turn_left.ron", &extended), &more(3)).expect_err("3 < 4 run").to_string();
    assert!(err.contains("already 4 iterations"), "{err}");
    let out = train(&setup("turn_left.ron", &extended), &more(5)).expect("extend to 5");
    assert_eq!((out.history.len(), out.figures.iterations), (1, 5), "iteration 5 only");
}

#[test]
fn a_skills_next_stage_continues_the_critic_saved_with_its_policy() {
    let lib = temp("critic");
    let s = setup("turn_left.ron", &lib);
    train(&s, &TrainOptions::quick(&lib, &lib.join("run"), 2, 4, 3)).expect("train");
    let skill = library::load(&lib, "turn_left").expect("load");
    assert!(skill.manifest.value_fnv1a.is_some(), "the manifest vouches for the critic");
    let critic = skill.load_critic().expect("a sound critic").expect("saved with the policy");
    assert_eq!(critic.obs_dim(), skill.policy.obs_dim());
    assert!(critic.returns.count > 0.0, "the reward normaliser's statistics come with it");

    // A fine-tune of the same skill starts from that critic; `fresh_critic` from a new one:
    // the same seed then gives another value loss in the very first update.
    let finetune = |fresh_critic: bool, run: &str| TrainOptions {
        init_from_library: true,
        fresh_critic,
        ..TrainOptions::quick(&lib, &lib.join(run), 1, 4, 5)
    };
    let backup = lib.join("turn_left-before");
    std::fs::create_dir_all(&backup).unwrap();
    for f in ["manifest.ron", "policy.safetensors", library::VALUE_FILE] {
        std::fs::copy(lib.join("turn_left").join(f), backup.join(f)).unwrap();
    }
    let restore = || {
        for f in ["manifest.ron", "policy.safetensors", library::VALUE_FILE] {
            std::fs::copy(backup.join(f), lib.join("turn_left").join(f)).unwrap();
        }
    };
    let continued = train(&s, &finetune(false, "run-continued")).expect("fine-tune, critic continued");
    restore();
    let fresh = train(&s, &finetune(true, "run-fresh")).expect("fine-tune, fresh critic");
    restore();
    assert_ne!(continued.history[0].value_loss, fresh.history[0].value_loss, "the saved critic was not used");

    // A damaged critic stops a fine-tune that would continue it, naming the file; a fresh
    // critic does not read it.
    let value = lib.join("turn_left").join(library::VALUE_FILE);
    let mut bytes = std::fs::read(&value).unwrap();
    let n = bytes.len();
    bytes[n - 2] ^= 0x55;
    std::fs::write(&value, bytes).unwrap();
    let err = train(&s, &finetune(false, "run-damaged")).expect_err("a damaged critic").to_string();
    assert!(err.contains("value.safetensors") && err.contains("checksum"), "{err}");
    train(&s, &finetune(true, "run-damaged-fresh")).expect("a fresh critic ignores the file");

    // A skill saved before critics were kept fine-tunes with a fresh one.
    restore();
    let manifest = lib.join("turn_left").join("manifest.ron");
    let text = std::fs::read_to_string(&manifest).unwrap();
    let old: String =
        text.lines().filter(|l| !l.trim_start().starts_with("value_fnv1a")).collect::<Vec<_>>().join("\n");
    assert_ne!(old, text, "the manifest names its critic");
    std::fs::write(&manifest, old).unwrap();
    std::fs::remove_file(&value).unwrap();
    assert!(library::load(&lib, "turn_left").unwrap().load_critic().unwrap().is_none());
    train(&s, &finetune(false, "run-old")).expect("an old skill fine-tunes");
    assert!(value.exists(), "and is saved with a critic from then on");
}

#[test]
fn the_sit_clip_played_open_loop_from_its_first_frame_sits_on_the_chair_and_holds() {
    // The shipped sit's keyframe clip, fed straight to the PD actuators from an episode start
    // at its first frame with the chair where the skill puts it (no jitter): the clip itself
    // must be a motion this body can make, ending seated, and the episode must hold the last
    // frame until `episode_s` instead of ending with the clip.
    let s = setup("sit.ron", &temp("sit-open-loop"));
    let r = &s.settings.reference;
    assert!(r.hold_steps > 0 && !r.looping);
    let (prop, _) = s.settings.seat.expect("sit has a seat");
    let mut env = s.env();
    let mut task = ImitationTask::new(s.settings.clone());
    task.place_at_frame(env.world_mut(), 0, 0.0, 0.0, 0.0);
    let frames = r.frames();
    let mut seated_from = None;
    for f in 1..frames + 60 {
        let world = env.world_mut();
        world.step(r.joints_at(f.min(frames - 1))).expect("steps");
        let c = world.contacts();
        assert!(!c.fallen, "frame {f}: the open-loop sit fell");
        match (c.pelvis_on_prop(prop), seated_from) {
            (true, None) => seated_from = Some(f),
            (false, Some(from)) => panic!("frame {f}: the pelvis left the seat it reached at frame {from}"),
            _ => {}
        }
    }
    let from = seated_from.expect("the open-loop sit reaches the seat");
    assert!(from < frames - 30, "seated only at frame {from} of {frames}");

    // Episodes of a holding clip run hold_s (1.5 s at 60 Hz) past the clip's end, whatever
    // the start frame, holding its last frame.
    let hold = r.hold_steps;
    assert_eq!(hold, 90);
    assert_eq!(s.max_steps as usize, frames - 1 + hold);
    let mut rng = EnvRng::seed_from_u64(3);
    let mut obs = vec![0.0; env.obs_dim()];
    let mut truncated = 0;
    for _ in 0..3 {
        env.reset(&mut rng, &mut obs);
        let start = env.task().phase();
        let mut steps = 0;
        loop {
            let f = (env.task().phase() + 1).min(frames - 1);
            let target = r.joints_at(f).to_vec();
            let action: Vec<f32> = target.iter().enumerate().map(|(k, &q)| env.action_for(k, q)).collect();
            let out = env.step(&action, &mut obs);
            steps += 1;
            if steps > frames - 1 - start {
                assert_eq!(env.task().phase(), frames - 1, "the last frame is held");
            }
            if out.terminated || out.truncated {
                if out.truncated {
                    assert_eq!(steps, frames - 1 - start + hold, "truncated hold_s past the clip's end");
                    truncated += 1;
                }
                break;
            }
        }
    }
    assert!(truncated > 0, "no open-loop episode from a random frame lasted to its end");
}

#[test]
fn a_lead_in_holds_the_clips_first_frame_still_before_it_plays() {
    // `lead_s` prepends the first frame, held still, to the clip: the episode, the manifest's
    // frame count and the meta-controller's view of the clip grow by it; the rest of the clip,
    // and the seat under its seated frames, are unchanged.
    let lib = temp("lead-in");
    let plain = setup("sit.ron", &lib);
    let mut spec = SpecFile::load(&specs().join("sit.ron")).unwrap();
    spec.spec.clip.lead_s = 1.0;
    let led = SkillSetup::new(spec, &lib).expect("a lead-in builds");
    let (r0, r1) = (&plain.settings.reference, &led.settings.reference);
    let lead = 60;
    assert_eq!(r1.frames(), r0.frames() + lead);
    assert_eq!(led.max_steps, plain.max_steps + lead as u32);
    assert_eq!(led.clip_record().frames, r1.frames());
    assert_ne!(led.clip_record().hash, plain.clip_record().hash, "the clip as used is another clip");
    for k in 0..=lead {
        assert_eq!(r1.joints_at(k), r0.joints_at(0), "frame {k} of the lead-in");
        assert_eq!(r1.root_pos[k], r0.root_pos[0]);
    }
    for k in 0..lead - 1 {
        assert!(r1.joint_vel_at(k).iter().all(|v| v.abs() < 1e-9), "frame {k} of the lead-in moves");
    }
    for f in 0..r0.frames() {
        let (a, b) = (r0.joints_at(f), r1.joints_at(f + lead));
        assert!(a.iter().zip(b).all(|(x, y)| (x - y).abs() < 1e-9), "frame {f} moved by the lead-in");
    }
    assert_eq!(led.settings.seat, plain.settings.seat, "the seat stays under the seated frames");

    let dir = temp("lead-in-bad");
    let text = std::fs::read_to_string(specs().join("sit.ron")).unwrap();
    let bad = text.replace("hold_s: 1.5", "hold_s: 1.5, lead_s: -1.0");
    assert_ne!(bad, text);
    let err = SpecFile::parse(&dir.join("s.ron"), &bad).expect_err("negative lead-in").to_string();
    assert!(err.contains("s.ron") && err.contains("lead_s"), "{err}");
    let walk = std::fs::read_to_string(specs().join("walk.ron")).unwrap();
    let bad = walk.replace("looping: true", "looping: true, lead_s: 0.5");
    assert_ne!(bad, walk);
    let err = SpecFile::parse(&dir.join("w.ron"), &bad).expect_err("loop and lead-in").to_string();
    assert!(err.contains("w.ron") && err.contains("lead_s"), "{err}");
}

#[test]
fn bad_specs_are_refused_with_the_place() {
    let dir = temp("bad-spec");
    let text = std::fs::read_to_string(specs().join("walk.ron")).unwrap();
    let bad = text.replace("name: \"walk\"", "name: \"Moon Walk\"");
    let err = SpecFile::parse(&dir.join("w.ron"), &bad).expect_err("a name that is no folder").to_string();
    assert!(err.contains("skill name `Moon Walk`") && err.contains("w.ron"), "{err}");
    // A new skill needs no list to be in: its name is enough.
    let new = text.replace("name: \"walk\"", "name: \"moonwalk\"");
    assert_eq!(SpecFile::parse(&dir.join("w.ron"), &new).expect("a new skill").spec.name, "moonwalk");
    let bad = text.replace("episode_s: 10.0", "episode_s: 10.0, wobble: 3");
    let err = SpecFile::parse(&dir.join("w.ron"), &bad).expect_err("unknown field").to_string();
    assert!(err.contains("w.ron:") && err.contains("wobble"), "{err}");
    let bad = text.replace("looping: true", "looping: true, hold_s: 1.0");
    assert_ne!(bad, text);
    let err = SpecFile::parse(&dir.join("w.ron"), &bad).expect_err("loop and hold").to_string();
    assert!(err.contains("w.ron") && err.contains("hold"), "{err}");
    let bad = text.replace("init: Reference", "init: Pools(from: [\"turn_left\"], fraction: 0.5, speed: (1.0, 0.5))");
    assert_ne!(bad, text);
    let err = SpecFile::parse(&dir.join("w.ron"), &bad).expect_err("backwards speed range").to_string();
    assert!(err.contains("w.ron") && err.contains("speed"), "{err}");
    let good = text.replace("init: Reference", "init: Pools(from: [\"turn_left\"], fraction: 0.5, speed: (0.0, 1.0))");
    let spec = SpecFile::parse(&dir.join("w.ron"), &good).expect("a speed range parses");
    assert!(matches!(spec.spec.init, repertoire_skill::spec::Init::Pools { speed: (0.0, 1.0), .. }));
    let bad = text.replace("pack:deepmimic/walk_forward.txt", "pack:deepmimic/nope.txt");
    let spec = SpecFile::parse(&specs().join("w.ron"), &bad).expect("parses");
    let err = SkillSetup::new(spec, &dir).err().expect("missing clip").to_string();
    assert!(err.contains("nope.txt") && err.contains("does not exist"), "{err}");
}

#[test]
fn sit_episodes_start_clear_of_the_chair_with_the_seat_jittered_and_the_seated_clip_lifted() {
    // The mocap sit, whose actor sat lower than this body can, with its seated frames lifted
    // 9 cm and the chair jittered by up to 15 cm / 15°.
    let mut spec = SpecFile::load(&specs().join("sit_mocap.ron")).unwrap();
    spec.spec.clip.seat_lift_m = 0.09;
    spec.spec.goal = Goal::Seat {
        weight: 0.3,
        prop: "chair".into(),
        jitter_m: 0.15,
        jitter_deg: 15.0,
        forward_m: 0.05,
        clear_start: true,
    };
    let s = SkillSetup::new(spec.clone(), &temp("sit-starts")).unwrap();
    let r = &s.settings.reference;
    let (prop, seat) = s.settings.seat.expect("sit has a seat");
    // The seated frames are raised by seat_lift_m (0.09 m at the lowest frame), the standing
    // ones are not.
    let mut plain = spec.clone();
    plain.spec.clip.seat_lift_m = 0.0;
    let p = SkillSetup::new(plain, &temp("sit-plain")).unwrap();
    let pr = &p.settings.reference;
    let lowest = (0..pr.frames()).min_by(|&a, &b| pr.height[a].total_cmp(&pr.height[b])).unwrap();
    let highest = (0..pr.frames()).max_by(|&a, &b| pr.height[a].total_cmp(&pr.height[b])).unwrap();
    assert!((r.height[lowest] - pr.height[lowest] - 0.09).abs() < 1e-9);
    assert!((r.height[highest] - pr.height[highest]).abs() < 1e-9);
    assert_eq!(r.joints, pr.joints, "lifting leaves the joint angles alone");

    let mut env = s.env();
    let mut rng = EnvRng::seed_from_u64(5);
    let pelvis = env.world().model().index.pelvis;
    let (mut seated, mut moved) = (0, 0);
    let mut obs = vec![0.0; env.obs_dim()];
    for _ in 0..40 {
        env.reset(&mut rng, &mut obs);
        let task = env.task();
        let f = task.phase();
        let world = env.world();
        let depth = world.penetration_with_key_geom(prop, Some(pelvis));
        assert!(depth < 0.005, "start frame {f}: the pelvis sinks {depth:.3} m into the seat");
        // Where the clip's seat would be for this start (no jitter) versus where it is.
        let pl = world.placements()[prop];
        let frame = world.pelvis_frame();
        let local = repertoire_skill::reference::to_heading(
            frame.yaw(),
            [pl.pos[0] - frame.pos[0], pl.pos[1] - frame.pos[1], 0.0],
        );
        let expected = repertoire_skill::reference::to_heading(
            r.heading[f],
            [seat[0] - r.root_pos[f][0], seat[1] - r.root_pos[f][1], 0.0],
        );
        let off = ((local[0] - expected[0]).powi(2) + (local[1] - expected[1]).powi(2)).sqrt();
        assert!(
            off < 0.15 + 0.2 + 1e-6,
            "start frame {f}: chair {off:.3} m from the clip's seat (jitter 0.15, push-back 0.2)"
        );
        if r.height[f] < 0.65 {
            seated += 1;
        } else if off > 0.02 {
            moved += 1;
        }
    }
    assert!(seated > 0 && moved > 0, "40 starts cover seated frames ({seated}) and jittered standing ones ({moved})");
}

#[test]
fn a_cycle_is_picked_up_at_the_frame_nearest_the_arriving_pose_and_its_pool_covers_the_cycle() {
    let lib = temp("cycle");
    let s = setup("walk.ron", &lib);
    let r = &s.settings.reference;
    assert!(r.looping);
    // Every frame of the cycle (its last repeats its first) is the nearest to itself.
    for f in 0..r.frames() - 1 {
        assert_eq!(r.nearest_frame(r.joints_at(f), r.joint_vel_at(f)), f, "frame {f}");
    }

    // A walk state at frame 23, stored as a predecessor's end pose: a walk fine-tuned from
    // that pool starts its clip at frame 23, not at its first frame.
    let mut env = s.env();
    let mut task = ImitationTask::new(s.settings.clone());
    task.place_at_frame(env.world_mut(), 23, 0.0, 0.0, 0.0);
    let state = PoolState::capture(env.world());
    let pool = Pool { skill: "turn_left".into(), body_hash: s.model.body.content_hash(), states: vec![state] };
    std::fs::create_dir_all(lib.join("turn_left")).unwrap();
    pool.save(&lib.join("turn_left").join("end_poses.ron")).unwrap();
    let mut spec = SpecFile::load(&specs().join("walk.ron")).unwrap();
    spec.spec.init = repertoire_skill::spec::Init::pools(vec!["turn_left".into()]);
    let from_pool = SkillSetup::new(spec, &lib).expect("walk over the turn's pool");
    let mut env = from_pool.env();
    let mut rng = EnvRng::seed_from_u64(4);
    let mut obs = vec![0.0; env.obs_dim()];
    for _ in 0..3 {
        env.reset(&mut rng, &mut obs);
        assert_eq!(env.task().phase(), 23);
    }

    // The manifest of a cycle carries its frame table (for the meta-controller); a clip that
    // ends does not.
    let record = s.clip_record();
    assert_eq!(record.cycle_joints.len(), r.frames() * r.dof);
    assert_eq!(record.cycle_joint_vel.len(), r.frames() * r.dof);
    let f = repertoire_skill::reference::nearest_pose(
        &record.cycle_joints,
        &record.cycle_joint_vel,
        r.dof,
        r.frames() - 1,
        r.joints_at(40),
        r.joint_vel_at(40),
    );
    assert_eq!(f, 40);
    assert!(setup("turn_left.ron", &temp("cycle-turn")).clip_record().cycle_joints.is_empty());

    // A cycle has no end pose (every trial ends at the same phase), so its pool keeps a state
    // from a random moment of each successful trial: the phases spread over the cycle.
    let mut short = SpecFile::load(&specs().join("walk.ron")).unwrap();
    short.spec.episode_s = 0.6;
    let short = SkillSetup::new(short, &lib).unwrap();
    let opts = TrainOptions::quick(&lib, &lib.join("run"), 1, 2, 5);
    train(&short, &opts).expect("train");
    let mut skill = library::load(&lib, "walk").expect("load");
    let (report, ends) = evaluate(&short, &mut skill, StartFrom::ClipStart, 12, 4, 1).expect("evaluate");
    assert_eq!(ends.len(), report.successes);
    assert!(report.successes >= 6, "only {} of 12 short walks stood", report.successes);
    let phases: std::collections::BTreeSet<usize> = ends.iter().map(|e| e.phase).collect();
    assert!(phases.len() >= 4, "pool phases {phases:?} do not spread over the cycle");
}

/// `walk_stage2.ron` with its target goal changed by `edit`, as a task placed in `env` at frame
/// `f`, `(2, -1)`, facing `heading`.
fn stage2_variant(
    name: &str,
    edit: impl FnOnce(&mut Goal),
    env: &mut repertoire_skill::SkillEnv,
    rng: &mut EnvRng,
    f: usize,
    heading: f64,
) -> (SkillSetup, ImitationTask) {
    use repertoire_humanoid::Task;
    let mut spec = SpecFile::load(&specs().join("walk_stage2.ron")).unwrap();
    edit(&mut spec.spec.goal);
    let s = SkillSetup::new(spec, &temp(name)).unwrap();
    let mut task = ImitationTask::new(s.settings.clone());
    task.reset(env.world_mut(), rng);
    task.place_at_frame(env.world_mut(), f, 2.0, -1.0, heading);
    (s, task)
}

#[test]
fn walk_stage_two_reaches_a_target_and_draws_the_next_one_ahead() {
    use repertoire_humanoid::Task;
    let s = setup("walk_stage2.ron", &temp("walk-target"));
    let Goal::Target { distance_m, azimuth_deg, reach_m, .. } = s.spec.spec.goal.clone() else {
        panic!("walk_stage2.ron walks to targets")
    };
    assert!(reach_m > 0.0);
    let mut env = s.env();
    let mut task = ImitationTask::new(s.settings.clone());
    let mut rng = EnvRng::seed_from_u64(3);
    task.reset(env.world_mut(), &mut rng);
    // The first target is drawn in range of the start.
    let p = env.world().pelvis_frame().pos;
    let dist = |t: [f64; 2], p: [f64; 3]| ((t[0] - p[0]).powi(2) + (t[1] - p[1]).powi(2)).sqrt();
    let d0 = dist(task.target(), p);
    assert!(d0 >= distance_m.0 - 0.05 && d0 <= distance_m.1 + 0.05, "first target {d0} m away");
    // The policy observes it: [sin ψ, cos ψ, distance] after the phase.
    let mut obs = vec![0.0f32; 6];
    task.observe_extra(env.world(), &mut obs);
    assert!((f64::from(obs[5]) - d0).abs() < 1e-3, "{obs:?}");
    assert!((obs[3].powi(2) + obs[4].powi(2) - 1.0).abs() < 1e-4);

    // Standing on the target: reached (goal term 1), and a new one is drawn ahead, in range.
    let heading = 0.4;
    let f = 10;
    task.place_at_frame(env.world_mut(), f, 2.0, -1.0, heading);
    let p = env.world().pelvis_frame().pos;
    task.set_target([p[0] + 0.1, p[1]], env.world());
    let out = task.score(env.world(), f);
    assert_eq!(out.terms[4], 1.0, "arrival pays the goal's maximum");
    assert_eq!(task.reached, 1);
    let next = task.target();
    let d = dist(next, p);
    assert!(d >= distance_m.0 - 1e-9 && d <= distance_m.1 + 1e-9, "next target {d} m away");
    let bearing = (next[1] - p[1]).atan2(next[0] - p[0]);
    let off = repertoire_scenes::math::wrap_angle(bearing - env.world().heading()).abs();
    assert!(off <= azimuth_deg.to_radians() + 1e-9, "next target {:.1}° off the heading", off.to_degrees());
    // Not there yet: no second arrival.
    task.score(env.world(), f);
    assert_eq!(task.reached, 1);
    // The target-heading reward (`speed_scale`): walking at the clip's pace (the clip frame's
    // velocities) straight at the target pays nearly all of it, walking past it sideways or
    // away from it almost nothing.
    let h = env.world().heading();
    let at = |a: f64| [p[0] + 3.0 * (h + a).cos(), p[1] + 3.0 * (h + a).sin()];
    task.set_target(at(0.0), env.world());
    let ahead = task.score(env.world(), f).terms[4];
    task.set_target(at(std::f64::consts::FRAC_PI_2), env.world());
    let side = task.score(env.world(), f).terms[4];
    task.set_target(at(std::f64::consts::PI), env.world());
    let behind = task.score(env.world(), f).terms[4];
    assert!(ahead > 0.8 && side < 0.2 && behind < side, "ahead {ahead}, side {side}, behind {behind}");
    // The facing term (`facing_scale`) adds half of `1 − exp(−2ψ²)` to the drop at 30° off.
    let off30 = 30f64.to_radians();
    task.set_target(at(off30), env.world());
    let speed_30 = task.score(env.world(), f).terms[4];
    let facing = |g: &mut Goal| {
        if let Goal::Target { facing_scale, .. } = g {
            *facing_scale = 2.0;
        }
    };
    let (_, mut task_f) = stage2_variant("walk-target-facing", facing, &mut env, &mut rng, f, heading);
    task_f.set_target(at(0.0), env.world());
    let facing_ahead = task_f.score(env.world(), f).terms[4];
    task_f.set_target(at(off30), env.world());
    let facing_30 = task_f.score(env.world(), f).terms[4];
    let psi_term = 0.5 * (-2.0 * off30 * off30).exp() as f32;
    assert!(
        (facing_ahead - facing_30 - (0.5 * (ahead - speed_30) + 0.5 - psi_term)).abs() < 0.02,
        "facing term: ahead {facing_ahead}, 30° off {facing_30}"
    );
    assert!(
        facing_ahead - facing_30 > ahead - speed_30,
        "the facing term tells a 30° miss more: {facing_ahead} − {facing_30} against {ahead} − {speed_30}"
    );

    // Without `reach_m` (one target per episode), standing on it is no arrival.
    let once = |g: &mut Goal| {
        if let Goal::Target { reach_m, .. } = g {
            *reach_m = 0.0;
        }
    };
    let (_, mut task) = stage2_variant("walk-target-once", once, &mut env, &mut rng, f, heading);
    task.set_target([p[0] + 0.1, p[1]], env.world());
    task.score(env.world(), f);
    assert_eq!(task.reached, 0);

    // With `retarget_s`, a target not reached in time is replaced (no pay, no arrival), in range.
    let timeout = |g: &mut Goal| {
        if let Goal::Target { retarget_s, .. } = g {
            *retarget_s = 0.5;
        }
    };
    let (timed, mut task) = stage2_variant("walk-target-timed", timeout, &mut env, &mut rng, f, heading);
    let dt = timed.settings.reference.dt;
    let far = [p[0] - 3.0, p[1] + 1.0];
    task.set_target(far, env.world());
    let due = (0.5 / dt).ceil() as usize;
    for _ in 1..due {
        task.score(env.world(), f);
    }
    assert_eq!(task.target(), far, "kept until {due} steps have passed");
    task.score(env.world(), f);
    let next = task.target();
    assert_ne!(next, far, "replaced after {due} steps");
    assert_eq!(task.reached, 0, "a timeout is no arrival");
    let d = dist(next, p);
    assert!(d >= distance_m.0 - 1e-9 && d <= distance_m.1 + 1e-9, "replacement {d} m away");
}

#[test]
fn a_delivered_state_meets_the_seat_where_the_controller_left_it() {
    // States a meta-controller delivered (`meta deliver`) carry the seat's pose relative to the
    // character; a sit started from them finds the chair there, wherever the episode spawns.
    // Plain end poses carry none, and the chair stands where the clip expects it
    // (`seat_at_start`).
    let lib = temp("delivered");
    let plain = setup("sit.ron", &lib);
    let (prop, _) = plain.settings.seat.expect("sit has a seat");
    let mut env = plain.env();
    ImitationTask::new(plain.settings.clone()).place_at_frame(env.world_mut(), 0, 0.0, 0.0, 0.0);
    let standing = PoolState::capture(env.world());
    assert_eq!(standing.seat, None);
    let recorded = [-0.62, 0.21, 0.35];
    let delivered = PoolState { seat: Some(recorded), ..standing.clone() };
    let body_hash = plain.model.body.content_hash();
    let path = lib.join("delivered-sit.ron");
    Pool { skill: "delivered:sit".into(), body_hash: body_hash.clone(), states: vec![delivered.clone()] }
        .save(&path)
        .expect("save");
    assert_eq!(Pool::load(&path).expect("load").states[0].seat, Some(recorded), "the seat round-trips");
    let ends = lib.join("stand");
    std::fs::create_dir_all(&ends).unwrap();
    Pool { skill: "stand".into(), body_hash, states: vec![standing.clone()] }
        .save(&ends.join("end_poses.ron"))
        .unwrap();

    let seat_after_reset = |from: &str, jitter: bool, seed: u64| {
        let mut spec = SpecFile::load(&specs().join("sit.ron")).unwrap();
        spec.spec.init = repertoire_skill::spec::Init::pools(vec![from.to_string()]);
        if !jitter && let Goal::Seat { jitter_m, jitter_deg, .. } = &mut spec.spec.goal {
            (*jitter_m, *jitter_deg) = (0.0, 0.0);
        }
        let s = SkillSetup::new(spec, &lib).expect("a pool by path or by skill name");
        let mut env = s.env();
        let mut obs = vec![0.0; env.obs_dim()];
        env.reset(&mut EnvRng::seed_from_u64(seed), &mut obs);
        let got = PoolState::capture_with_seat(env.world(), &env.world().placements()[prop]);
        for (a, b) in got.joints.iter().zip(&standing.joints) {
            assert!((a - b).abs() < 1e-9, "the episode starts in the pool's state");
        }
        (got.seat.expect("captured with the seat"), s.seat_at_start().expect("sit has a seat"))
    };
    for seed in [1, 2, 3] {
        // Jitter on: a delivered state's seat is taken as recorded, not jittered.
        let (seat, _) = seat_after_reset(path.to_str().unwrap(), true, seed);
        for k in 0..3 {
            assert!((seat[k] - recorded[k]).abs() < 1e-9, "seed {seed}: seat {seat:?}, recorded {recorded:?}");
        }
        let (seat, expected) = seat_after_reset("stand", false, seed);
        for k in 0..3 {
            assert!((seat[k] - expected[k]).abs() < 1e-9, "seed {seed}: seat {seat:?}, clip expects {expected:?}");
        }
        assert!(expected[0] < -0.2, "the clip sits down backwards onto the seat: {expected:?}");
    }
    // A delivered file that is not there is named, with the command that writes one.
    let mut spec = SpecFile::load(&specs().join("sit.ron")).unwrap();
    spec.spec.init = repertoire_skill::spec::Init::pools(vec![lib.join("missing.ron").display().to_string()]);
    let err = SkillSetup::new(spec, &lib).err().expect("a missing pool file").to_string();
    assert!(err.contains("missing.ron") && err.contains("meta deliver"), "{err}");
}

#[test]
fn a_skill_grown_from_another_acts_as_it_until_trained_and_keeps_its_lineage() {
    // Carry from walk (`skill train carry.ron --warm-start-from walk`): carry observes walk's
    // features and then the box; the grown policy ignores the box until training weighs it.
    let lib = temp("grown");
    let walk = setup("walk.ron", &lib);
    train(&walk, &TrainOptions::quick(&lib, &lib.join("run-walk"), 1, 2, 1)).expect("train walk");
    let prior = library::load(&lib, "walk").expect("walk in the library");
    let carry = setup("carry.ron", &lib);
    let wanted = carry.env().obs_dim();
    let mut grown = repertoire_skill::train::grown_prior(&carry, &prior, wanted).expect("carry grows from walk");
    let (features, box_values) = (prior.manifest.observation.size, carry.layout.size - prior.manifest.observation.size);
    assert!(box_values > 0 && grown.obs_dim() == wanted && wanted == prior.policy.obs_dim() + box_values);
    let mut walk_policy = prior.policy.clone();
    let mut a = vec![0.0; walk_policy.act_dim()];
    let mut b = vec![0.0; walk_policy.act_dim()];
    let mut env = walk.env();
    let mut obs = vec![0.0; env.obs_dim()];
    env.reset(&mut EnvRng::seed_from_u64(3), &mut obs);
    walk_policy.act(&obs, &mut a);
    for fill in [0.0f32, 3.0, -50.0] {
        let mut wide = obs.clone();
        wide.splice(features..features, std::iter::repeat_n(fill, box_values));
        grown.act(&wide, &mut b);
        assert_eq!(a, b, "box values {fill} changed walk's action");
    }
    // `--explore-log-std` raises the prior's spread to a floor (walk starts at the spec's -2).
    let floor = -1.0;
    assert!(prior.policy.log_std.iter().all(|&l| l < floor - 0.5), "{:?}", prior.policy.log_std);
    let opts = TrainOptions {
        init_from_library: true,
        prior_skill: Some("walk".into()),
        explore_log_std: Some(floor),
        ..TrainOptions::quick(&lib, &lib.join("run-carry"), 1, 2, 1)
    };
    train(&carry, &opts).expect("train carry from walk");
    let grown = library::load(&lib, "carry").expect("carry in the library");
    assert!(
        grown.policy.log_std.iter().all(|&l| (l - floor).abs() < 0.05),
        "one iteration from the floor: {:?}",
        grown.policy.log_std
    );
    let lineage: Vec<&str> = grown.manifest.lineage.iter().map(|s| s.command.as_str()).collect();
    assert_eq!(lineage, [prior.manifest.command.as_str()], "carry's lineage starts with walk");
    // `--max-log-std` lowers it to a ceiling instead.
    let ceiling = -4.0;
    assert!(prior.policy.log_std.iter().all(|&l| l > ceiling + 0.5), "{:?}", prior.policy.log_std);
    let opts = TrainOptions {
        max_log_std: Some(ceiling),
        ..TrainOptions { run_dir: lib.join("run-carry-quiet"), explore_log_std: None, ..opts }
    };
    train(&carry, &opts).expect("train carry from walk, quieter");
    let quiet = library::load(&lib, "carry").expect("carry in the library");
    assert!(
        quiet.policy.log_std.iter().all(|&l| (l - ceiling).abs() < 0.05),
        "one iteration from the ceiling: {:?}",
        quiet.policy.log_std
    );

    // A skill whose features do not begin with the prior's is refused, naming both.
    let sit = setup("sit.ron", &lib);
    let err = repertoire_skill::train::grown_prior(&sit, &grown, sit.env().obs_dim()).expect_err("sit from carry");
    let err = err.to_string();
    assert!(err.contains("`sit`") && err.contains("`carry`") && err.contains("policy.safetensors"), "{err}");
}

#[test]
fn the_stand_pays_fully_for_standing_still_and_little_for_moving() {
    // `stand.ron`: a still clip, so walk stage one's root-velocity match pays for being at rest.
    let s = setup("stand.ron", &Path::new(env!("CARGO_MANIFEST_DIR")).join("../../library"));
    let r = &s.settings.reference;
    assert!(r.velocity.iter().all(|v| v.iter().all(|c| c.abs() < 1e-9)), "the stand's clip moves");
    let mut env = s.env();
    let mut task = ImitationTask::new(s.settings.clone());
    task.place_at_frame(env.world_mut(), 60, 0.5, 0.5, 1.0);
    let still = task.score(env.world(), 60);
    assert!(still.terms[4] > 0.999 && still.terms[0] > 0.999, "standing still: {:?}", &still.terms[..5]);
    // The same pose moving forward at 1 m/s (a turn's end pose moves about that fast).
    let qpos = env.world().data().qpos().to_vec();
    let mut qvel = env.world().data().qvel().to_vec();
    qvel[0] = 1.0_f64.cos();
    qvel[1] = 1.0_f64.sin();
    env.world_mut().set_state(&qpos, &qvel).unwrap();
    let moving = task.score(env.world(), 60);
    assert!(moving.terms[4] < 0.05, "moving at 1 m/s still pays {}", moving.terms[4]);
    assert!(moving.reward < still.reward - 0.3, "{} vs {}", moving.reward, still.reward);
}

#[test]
fn walk_around_sees_the_chair_put_in_its_way_and_a_touch_ends_the_episode() {
    let library = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../library");
    let s = setup("walk_around.ron", &library);
    let walk_to = setup("walk_to.ron", &library);
    let chair = s.settings.obstacle.as_ref().expect("walk_around has an obstacle").0;
    let mut env = s.env();
    assert_eq!(env.obs_dim(), walk_to.env().obs_dim() + 5, "the chair's pose: dx, dy, dz, sin, cos of its yaw");
    let mut obs = vec![0.0; env.obs_dim()];
    let zero = vec![0.0; env.act_dim()];
    let mut rng = EnvRng::seed_from_u64(11);
    let (mut in_way, trials) = (0, 60);
    for _ in 0..trials {
        env.reset(&mut rng, &mut obs);
        let p = env.world().pelvis_frame().pos;
        let c = env.world().placements()[chair].pos;
        let t = env.task().target();
        let gap = (c[0] - p[0]).hypot(c[1] - p[1]);
        assert!(gap >= 1.5 - 1e-9, "the chair is put {gap:.2} m from the pelvis, inside the 1.5 m clearance");
        // On the way: 50–80 % of the distance to the target, within 0.3 m of the straight line.
        let (dx, dy) = (t[0] - p[0], t[1] - p[1]);
        let d = dx.hypot(dy);
        let along = ((c[0] - p[0]) * dx + (c[1] - p[1]) * dy) / (d * d);
        let side = ((c[1] - p[1]) * dx - (c[0] - p[0]) * dy).abs() / d;
        if (0.5 - 1e-9..=0.8 + 1e-9).contains(&along) && side <= 0.3 + 1e-9 {
            in_way += 1;
        }
        // One step from a start clear of the chair does not end the episode.
        assert!(!env.step(&zero, &mut obs).terminated);
    }
    // Half by the spec, less the spots inside the clearance (a third of those drawn): about 33 %,
    // and a few chairs put off the way land on it by chance.
    assert!((10..=33).contains(&in_way), "{in_way} of {trials} starts with the chair in the way");
    // The pelvis's view of the chair is in the observation, after walk_to's proprioception.
    env.reset(&mut rng, &mut obs);
    let at = s.layout.entries.iter().find(|e| e.name == "prop_pose:chair").expect("observed").offset;
    let rel = env.world().prop_relative(chair);
    assert!((0..5).all(|k| (obs[at + k] - rel[k] as f32).abs() < 1e-5), "{:?} vs {rel:?}", &obs[at..at + 5]);
    // The chair moved onto the character: the next step touches it and the episode ends.
    let p = env.world().pelvis_frame().pos;
    env.world_mut().move_prop(chair, p[0] + 0.25, p[1], 0.0).unwrap();
    let out = env.step(&zero, &mut obs);
    assert!(out.terminated && out.reward == 0.0, "a touch of the chair ends the episode unpaid");
    assert!(env.task().touched, "the touch is told apart from a fall (skill eval counts it)");
    env.reset(&mut rng, &mut obs);
    assert!(!env.task().touched, "a new episode starts untouched");
    // With `touch_ends: false` the same bump goes on (only a fall would end it).
    let mut spec = s.spec.clone();
    spec.spec.obstacle.as_mut().unwrap().touch_ends = false;
    let bumps = SkillSetup::new(spec, &library).unwrap();
    let mut env = bumps.env();
    env.reset(&mut rng, &mut obs);
    let p = env.world().pelvis_frame().pos;
    env.world_mut().move_prop(chair, p[0] + 0.25, p[1], 0.0).unwrap();
    let out = env.step(&zero, &mut obs);
    assert!(env.world().contacts().character_on_prop(chair), "the chair is touched");
    assert!(!out.terminated && out.reward > 0.0, "a bump alone does not end the episode");
    assert!(!env.task().touched, "only a touch that ends the episode is counted");

    // Bad obstacles are refused with the file: on a goal without a target, out of range, or
    // naming a prop the scene lacks.
    let text = std::fs::read_to_string(specs().join("walk_around.ron")).unwrap();
    let dir = temp("bad-obstacle");
    let path = specs().join("w.ron");
    for (from, to, says) in [
        (
            "goal: Target(weight: 0.5, distance_m: (1.5, 4.0), azimuth_deg: 90.0, reach_m: 0.5, speed_scale: 2.5, facing_scale: 2.0, retarget_s: 4.0)",
            "goal: None",
            "walking target",
        ),
        ("along: (0.5, 0.8)", "along: (0.5, 2.5)", "along"),
        ("chance: 0.5", "chance: 1.5", "chance"),
        ("clearance_m: 1.5", "clearance_m: 0.0", "clearance_m"),
    ] {
        let bad = text.replace(from, to);
        assert_ne!(bad, text, "{from}");
        let err = SpecFile::parse(&path, &bad).expect_err(says).to_string();
        assert!(err.contains("w.ron") && err.contains(says), "{err}");
    }
    let bad = text.replace("prop: \"chair\", chance", "prop: \"sofa\", chance");
    let err = SkillSetup::new(SpecFile::parse(&path, &bad).unwrap(), &dir).err().expect("no sofa").to_string();
    assert!(err.contains("w.ron") && err.contains("`sofa`") && err.contains("arena_chair.ron"), "{err}");
}

#[test]
fn a_delivered_seat_puts_the_chair_where_the_controller_left_it_for_a_skill_without_a_seat_goal() {
    // stand_handover.ron: the stand in the sitting scene, the chair following delivered states.
    let library = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../library");
    let dir = temp("delivered-seat");
    let s = setup("stand_handover.ron", &library);
    let chair = s.settings.delivered_seat.expect("stand_handover names the chair");
    assert!(s.settings.seat.is_none(), "the stand has no seat goal");
    // A state with the seat 0.7 m behind the character and turned 0.5 rad, as `meta deliver` records.
    let mut env = s.env();
    let mut obs = vec![0.0; env.obs_dim()];
    let mut rng = EnvRng::seed_from_u64(5);
    env.reset(&mut rng, &mut obs);
    let mut state = PoolState::capture(env.world());
    state.seat = Some([-0.7, 0.1, 0.5]);
    let pool = Pool { skill: "handed-over:stand".into(), body_hash: s.model.body.content_hash(), states: vec![state] };
    let path = dir.join("stand-handovers.ron");
    pool.save(&path).unwrap();
    let from_pool = |delivered: Option<&str>| {
        let mut spec = s.spec.clone();
        spec.spec.init = repertoire_skill::spec::Init::Pools {
            from: vec![path.to_string_lossy().into_owned()],
            fraction: 1.0,
            speed: (1.0, 1.0),
        };
        spec.spec.delivered_seat = delivered.map(str::to_string);
        SkillSetup::new(spec, &library).unwrap()
    };
    let seat_seen = |setup: &SkillSetup, seed: u64| {
        let mut env = setup.env();
        let mut obs = vec![0.0; env.obs_dim()];
        env.reset(&mut EnvRng::seed_from_u64(seed), &mut obs);
        PoolState::capture_with_seat(env.world(), &env.world().placements()[chair]).seat.unwrap()
    };
    let follows = from_pool(Some("chair"));
    for seed in 0..4 {
        let seat = seat_seen(&follows, seed);
        let want = [-0.7, 0.1, 0.5];
        assert!((0..3).all(|k| (seat[k] - want[k]).abs() < 1e-6), "seed {seed}: the seat at {seat:?}, wanted {want:?}");
    }
    // Without the field the chair stays where the scene puts it, well away from that spot.
    let stays = seat_seen(&from_pool(None), 0);
    assert!((stays[0] + 0.7).hypot(stays[1] - 0.1) > 0.5, "the scene's chair at {stays:?}");

    // Refused, naming the file: a prop the scene lacks, and a skill whose seat goal moves it already.
    let text = std::fs::read_to_string(specs().join("stand_handover.ron")).unwrap();
    let bad = specs().join("s.ron");
    let sofa = text.replace("delivered_seat: Some(\"chair\")", "delivered_seat: Some(\"sofa\")");
    assert_ne!(sofa, text);
    let err = SkillSetup::new(SpecFile::parse(&bad, &sofa).unwrap(), &library).err().expect("no sofa").to_string();
    assert!(err.contains("s.ron") && err.contains("`sofa`"), "{err}");
    let sit = std::fs::read_to_string(specs().join("sit_handover.ron")).unwrap();
    let sit = sit.replacen(
        "    scene: \"builtin:sit\",",
        "    scene: \"builtin:sit\",\n    delivered_seat: Some(\"chair\"),",
        1,
    );
    let err = SkillSetup::new(SpecFile::parse(&bad, &sit).unwrap(), &library).err().expect("a seat goal").to_string();
    assert!(err.contains("s.ron") && err.contains("seat goal"), "{err}");
}
