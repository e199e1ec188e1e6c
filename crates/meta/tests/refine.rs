//! `meta refine`'s environment on the committed library and controller: with the skill's own
//! frozen policy acting, it replays the controller's episode exactly; a learner that falls ends
//! the episode as a terminal state; snapshots round-trip mid-decision; bad setups are refused;
//! a tiny fine-tune writes the skill back.

use std::path::{Path, PathBuf};
use std::sync::Arc;

use rand::SeedableRng;
use repertoire_learn::acting::ActingPolicy;
use repertoire_learn::env::{Env, EnvRng, StepOutcome};
use repertoire_meta::handover::refine::{REFINE_TERMS, RefineEnv, RefineSetup};
use repertoire_meta::train::load;
use repertoire_meta::{MetaEnv, MetaSetup, SkillGraph};
use repertoire_scenes::{ScenarioFile, WorldModel};
use repertoire_skill::imitation::TaskSettings;
use repertoire_skill::train::{TrainOptions, train_in};
use repertoire_skill::{SkillSetup, SpecFile, library};

fn root() -> &'static Path {
    Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/../.."))
}

fn committed() -> PathBuf {
    root().join("library")
}

fn meta_setup(lib: &Path) -> Arc<MetaSetup> {
    let model = Arc::new(WorldModel::build(ScenarioFile::builtin_default()).expect("the default scene builds"));
    let graph = SkillGraph::of(&model.scenario.scenario);
    Arc::new(MetaSetup::new(model, lib, graph).expect("the committed library fits the default scenario"))
}

fn skill(spec: &str, lib: &Path) -> SkillSetup {
    let spec = SpecFile::load(&root().join("specs").join(spec)).expect("spec");
    SkillSetup::new(spec, lib).expect("skill setup (needs the clip pack)")
}

fn refine_setup(lib: &Path, task_weight: f32) -> Arc<RefineSetup> {
    let meta = meta_setup(lib);
    let (_, head) = load(&lib.join("meta"), &meta).expect("the committed controller loads");
    let walk = skill("walk_to.ron", lib);
    let bounds = walk.env();
    Arc::new(
        RefineSetup::new(meta, head, "walk_to", Arc::clone(&walk.settings), bounds.action_bounds(), (1.0, task_weight))
            .expect("walk_to refines under the controller"),
    )
}

/// The controller's episode from `seed` as `meta eval` plays it: the world time it ended at,
/// the skills chosen, success, fall, and whether a decision played walk_to (an episode that
/// starts walking in walk_to's end poses may never choose it).
fn reference_episode(setup: &Arc<RefineSetup>, seed: u64) -> (f64, Vec<usize>, bool, bool, bool) {
    let (_, mut head) = load(&committed().join("meta"), &setup.meta).expect("controller");
    let mut env = MetaEnv::new(Arc::clone(&setup.meta));
    let mut rng = EnvRng::seed_from_u64(seed);
    let mut obs = vec![0.0; env.obs_dim()];
    let mut mask = vec![true; setup.meta.skills.len()];
    let mut act = vec![0.0; 3];
    env.reset(&mut rng, &mut obs);
    let mut walked = false;
    loop {
        env.option_mask(&mut mask);
        head.act(&obs, &mask, &mut act);
        walked |= env.begin_decision(&act) == 0;
        while !env.decision_tick(None) {}
        let out = env.end_decision(&mut obs);
        if out.terminated || out.truncated {
            return (env.world().time(), env.chosen.clone(), out.terms[0] > 0.5, out.terms[2] > 0.5, walked);
        }
    }
}

/// Plays one episode of `env` from `seed` with `act` choosing the learner's actions; the last
/// outcome, the per-episode sums of the terms and the steps taken.
fn play(env: &mut RefineEnv, seed: u64, mut act: impl FnMut(&[f32], &mut [f32])) -> (StepOutcome, Vec<f32>, usize) {
    let mut rng = EnvRng::seed_from_u64(seed);
    let mut obs = vec![0.0; env.obs_dim()];
    let mut action = vec![0.0; env.act_dim()];
    let mut sums = vec![0.0; REFINE_TERMS.len()];
    env.reset(&mut rng, &mut obs);
    for steps in 1..=5000 {
        assert_eq!(env.meta().current(), Some(0), "the learner acts only while walk_to plays");
        act(&obs, &mut action);
        let out = env.step(&action, &mut obs);
        for (s, t) in sums.iter_mut().zip(out.terms) {
            *s += t;
        }
        if out.terminated || out.truncated {
            return (out, sums, steps);
        }
    }
    panic!("a 20 s episode ran past 5000 of walk_to's ticks");
}

#[test]
fn with_the_skills_own_policy_it_replays_the_controllers_episode() {
    let setup = refine_setup(&committed(), 1.0);
    let mut walk: ActingPolicy = library::load(&committed(), "walk_to").expect("walk_to").policy;
    let mut checked = 0;
    for seed in [3, 4, 5, 6, 7] {
        let (time, chosen, success, fell, walked) = reference_episode(&setup, seed);
        if !walked {
            continue; // RefineEnv skips episodes without walk_to; the reference would differ.
        }
        let mut env = setup.env();
        let (out, sums, steps) = play(&mut env, seed, |obs, a| walk.act(obs, a));
        let meta = env.meta();
        assert_eq!(meta.chosen, chosen, "seed {seed}: the same skills in the same order");
        assert!(
            (meta.world().time() - time).abs() < 1e-9,
            "seed {seed}: ended at {} s, not {time} s",
            meta.world().time()
        );
        assert_eq!(sums[6] > 0.5, success, "seed {seed}: success");
        // Success and the time limit are truncations; only a fall is terminal.
        assert_eq!(out.terminated, fell, "seed {seed}: {out:?}");
        assert_eq!(out.truncated, !fell, "seed {seed}: {out:?}");
        assert!(steps > 0 && sums[0] > 0.0, "seed {seed}: the pose term pays while walk_to imitates its clip");
        checked += 1;
    }
    assert!(checked >= 2, "walk_to played in only {checked} of 5 episodes");
}

#[test]
fn a_learner_that_falls_ends_the_episode_as_its_own_fall() {
    let setup = refine_setup(&committed(), 1.0);
    let mut env = setup.env();
    // Every joint driven to the end of its range: the character folds up and falls.
    let (out, sums, steps) = play(&mut env, 3, |_, a| a.fill(1.0));
    assert!(out.terminated && !out.truncated, "{out:?}");
    assert_eq!(sums[7], 1.0, "counted as walk_to's fall: {sums:?}");
    assert_eq!(sums[6], 0.0, "not a success");
    assert!(steps < 600, "a folded character falls within 10 s, not after {steps} ticks");
    assert_eq!(out.reward, 0.0, "a fall pays no imitation reward and the task keeps its approach: {out:?}");
}

#[test]
fn a_snapshot_taken_mid_decision_replays_the_same_steps() {
    let setup = refine_setup(&committed(), 1.0);
    let mut walk: ActingPolicy = library::load(&committed(), "walk_to").expect("walk_to").policy;
    let mut env = setup.env();
    let mut rng = EnvRng::seed_from_u64(4);
    let mut obs = vec![0.0; env.obs_dim()];
    let mut action = vec![0.0; env.act_dim()];
    env.reset(&mut rng, &mut obs);
    // 40 ticks in: 10 ticks into walk_to's second decision.
    for _ in 0..40 {
        walk.act(&obs, &mut action);
        let out = env.step(&action, &mut obs);
        assert!(!(out.terminated || out.truncated), "the episode lasts more than 40 ticks");
    }
    let state = env.snapshot();
    let run = |env: &mut RefineEnv, mut obs: Vec<f32>, walk: &mut ActingPolicy| {
        let mut action = vec![0.0; env.act_dim()];
        (0..45)
            .map(|_| {
                walk.act(&obs, &mut action);
                let out = env.step(&action, &mut obs);
                (out.reward, out.terminated, env.meta().world().time())
            })
            .collect::<Vec<_>>()
    };
    let first = run(&mut env, obs.clone(), &mut walk);
    let mut other = setup.env();
    other.restore(&state).expect("the snapshot restores");
    let second = run(&mut other, obs, &mut walk);
    assert_eq!(first, second);
    assert!(other.restore(&state[..state.len() - 3]).is_err(), "a short snapshot is refused");
}

#[test]
fn a_skill_outside_the_graph_a_spec_of_another_clip_or_a_prop_goal_is_refused() {
    let lib = committed();
    let meta = meta_setup(&lib);
    let (_, head) = load(&lib.join("meta"), &meta).expect("controller");
    let walk = skill("walk_to.ron", &lib);
    let env = walk.env();
    let refused = |name: &str, settings: &Arc<TaskSettings>, weights: (f32, f32), why: &str| {
        RefineSetup::new(Arc::clone(&meta), head.clone(), name, Arc::clone(settings), env.action_bounds(), weights)
            .err()
            .expect(why)
            .to_string()
    };
    let err = refused("catch", &walk.settings, (1.0, 1.0), "catch is not in the sitting graph");
    assert!(err.contains("no skill `catch`") && err.contains("walk_to"), "{err}");
    let stand = skill("stand.ron", &lib);
    let err = refused("walk_to", &stand.settings, (1.0, 1.0), "the stand's clip is not walk_to's");
    assert!(err.contains("frames"), "{err}");
    let sit = skill("sit.ron", &lib);
    let err = refused("sit", &sit.settings, (1.0, 1.0), "the sit's seat goal reads a prop of its own scene");
    assert!(err.contains("`sit`") && err.contains("not supported"), "{err}");
    let err = refused("walk_to", &walk.settings, (1.0, f32::NAN), "a NaN weight");
    assert!(err.contains("task weight"), "{err}");
}

#[test]
fn a_tiny_refine_writes_the_skill_back_with_its_lineage() {
    let lib = std::env::temp_dir().join(format!("repertoire-refine-lib-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&lib);
    let names = ["walk_to", "turn_left", "turn_right", "turn_left_wide", "turn_right_wide", "stand", "sit", "meta"];
    for name in names {
        let (from, to) = (committed().join(name), lib.join(name));
        std::fs::create_dir_all(&to).unwrap();
        for f in std::fs::read_dir(&from).unwrap() {
            let f = f.unwrap();
            if f.file_type().unwrap().is_file() {
                std::fs::copy(f.path(), to.join(f.file_name())).unwrap();
            }
        }
    }
    let setup = refine_setup(&lib, 1.0);
    assert!(setup.probe(8, 1).expect("the controller walks") >= 4);
    let walk = skill("walk_to.ron", &lib);
    let before = library::load(&lib, "walk_to").expect("walk_to");
    let mut opts = TrainOptions::quick(&lib, &lib.join("run"), 1, 2, 1);
    opts.init_from_library = true;
    let out = train_in(&walk, &opts, &|n| setup.envs(n)).expect("a refine iteration");
    assert_eq!(out.history.len(), 1);
    let names: Vec<&str> = out.history[0].terms.iter().map(|(k, _)| k.as_str()).collect();
    assert_eq!(names, REFINE_TERMS);
    let after = library::load(&lib, "walk_to").expect("the refined walk_to loads");
    assert_ne!(after.manifest.policy_fnv1a, before.manifest.policy_fnv1a, "the weights moved");
    assert_eq!(after.manifest.lineage.len(), before.manifest.lineage.len() + 1, "the prior's stage is kept");
    // The controller was pinned to the old weights: it must be re-pinned before it runs over them.
    let err = load(&lib.join("meta"), &meta_setup(&lib)).expect_err("pinned to the old walk_to").to_string();
    assert!(err.contains("walk_to"), "{err}");
    let _ = std::fs::remove_dir_all(&lib);
}
