//! The meta environment: decisions run the chosen skill for control_hz / meta_hz ticks, the
//! graph's mask holds, clips are picked up and held as they should be (under a fall rule that
//! never ends an episode, so a barely trained skill's stumble cannot cut the check short),
//! training writes a controller that loads, and evaluation is reproducible for a seed.

use std::path::{Path, PathBuf};
use std::sync::{Arc, OnceLock};

use rand::SeedableRng;
use repertoire_learn::env::{Env, EnvRng, StateError};
use repertoire_learn::ppo::PpoConfig;
use repertoire_meta::controller::{LookingAhead, OracleSit};
use repertoire_meta::eval::evaluate;
use repertoire_meta::train::{CRITIC_FILE, MetaTrainOptions, Resume, load, train};
use repertoire_meta::{MetaEnv, MetaSetup, SkillGraph};
use repertoire_scenes::{ScenarioFile, WorldModel};
use repertoire_skill::train::TrainOptions;
use repertoire_skill::{SkillSetup, SpecFile};

mod support;

/// A library with walk_to, the four turns and sit, each trained for one tiny iteration.
fn library() -> &'static Path {
    static LIB: OnceLock<PathBuf> = OnceLock::new();
    LIB.get_or_init(|| {
        let lib = std::env::temp_dir().join(format!("repertoire-meta-lib-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&lib);
        let specs = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../specs");
        for name in ["walk_to", "turn_left", "turn_right", "turn_left_wide", "turn_right_wide", "sit"] {
            let spec = SpecFile::load(&specs.join(format!("{name}.ron"))).expect("spec");
            let setup = SkillSetup::new(spec, &lib).expect("skill setup (needs the clip pack)");
            let opts = TrainOptions::quick(&lib, &lib.join(format!("run-{name}")), 1, 2, 1);
            repertoire_skill::train::train(&setup, &opts).expect("train");
        }
        lib
    })
}

/// The default scenario without its stand (`support::without_stand`): the tests' library and
/// option indices are the six skills before it.
fn sit_scenario() -> ScenarioFile {
    let builtin = ScenarioFile::builtin_default();
    ScenarioFile::parse(&builtin.path, support::without_stand(&builtin.text)).expect("the scenario parses")
}

fn setup(graph: Option<SkillGraph>) -> Arc<MetaSetup> {
    let model = Arc::new(WorldModel::build(sit_scenario()).expect("scene"));
    let graph = graph.unwrap_or_else(|| SkillGraph::of(&model.scenario.scenario));
    Arc::new(MetaSetup::new(model, library(), graph).expect("meta setup"))
}

/// The same scenario and library with a fall rule that never counts a fall (the floor, props,
/// a low pelvis and a head below it all given a million seconds): decisions run whatever the
/// barely trained skills do to the body, for the tests of how clips are played, picked up and
/// held, which falls would otherwise cut short.
fn steady() -> Arc<MetaSetup> {
    let text = sit_scenario().text;
    let end = text.rfind(')').expect("the scenario closes");
    let never = "    fall: (floor_s: 1000000.0, prop_s: 1000000.0, pelvis_below: 0.0, inverted_s: 1000000.0),\n";
    let text = format!("{}{never}{}", &text[..end], &text[end..]);
    let file = ScenarioFile::parse(Path::new("sit-steady.ron"), text).expect("the scenario with the rule parses");
    let model = Arc::new(WorldModel::build(file).expect("scene"));
    let graph = SkillGraph::of(&model.scenario.scenario);
    Arc::new(MetaSetup::new(model, library(), graph).expect("meta setup"))
}

#[test]
fn a_decision_runs_the_chosen_skill_and_respects_the_graph() {
    let s = steady();
    assert_eq!(s.ticks, 30, "60 Hz skills under a 2 Hz meta-controller");
    let mut env = MetaEnv::new(Arc::clone(&s));
    let mut rng = EnvRng::seed_from_u64(1);
    let mut obs = vec![0.0; env.obs_dim()];
    env.reset(&mut rng, &mut obs);
    let mut mask = vec![false; 6];
    env.option_mask(&mut mask);
    assert_eq!(mask, [true, true, true, true, true, false], "an episode cannot start by sitting");
    let t0 = env.world().time();
    let out = env.step(&[0.0, 1.0, 0.0], &mut obs); // walk
    let dt = env.world().time() - t0;
    assert!(!out.terminated, "no fall ends a decision under the steady rule");
    assert!((dt - 0.5).abs() < 1e-5, "one decision is 0.5 s of physics, got {dt}");
    assert!(obs.iter().all(|v| v.is_finite()));
    env.option_mask(&mut mask);
    assert_eq!(mask, [true, true, true, true, true, false], "after walk: walk or a turn");
    // Asking for sit straight after walk is refused: the current skill continues.
    env.step(&[5.0, 0.0, 0.0], &mut obs);
    assert_eq!(env.chosen, [0], "sit is not reachable from walk");
}

#[test]
fn a_turn_is_never_run_past_its_clip() {
    let s = steady();
    let frames = s.skills[1].frames;
    assert!(!s.skills[1].looping);
    let mut env = MetaEnv::new(Arc::clone(&s));
    let mut rng = EnvRng::seed_from_u64(3);
    let mut obs = vec![0.0; env.obs_dim()];
    env.reset(&mut rng, &mut obs);
    // turn_left until its clip ends: full decisions, then a short one ending on the last frame.
    let mut ticks = 0usize;
    for _ in 0..10 {
        let t0 = env.world().time();
        let out = env.step(&[1.0, 0.0, 0.0], &mut obs);
        assert!(!out.terminated, "no fall ends a decision under the steady rule");
        let k = ((env.world().time() - t0) * 60.0).round() as usize;
        ticks += k;
        if k < 30 {
            assert_eq!(ticks, frames - 1, "the decision ends exactly at the clip's last frame");
            break;
        }
    }
    assert_eq!(ticks, frames - 1);
    // Choosing the turn again plays its clip again: a full decision.
    let t0 = env.world().time();
    let out = env.step(&[1.0, 0.0, 0.0], &mut obs);
    assert!(!out.terminated, "the turn played again does not fall");
    assert!((env.world().time() - t0 - 0.5).abs() < 1e-5);
    assert_eq!(env.chosen, [1], "re-choosing the current skill is not a switch");
}

#[test]
fn a_sit_chosen_again_holds_its_seated_frame_while_a_turn_replays() {
    let s = steady();
    let sit_index = s.skills.iter().position(|k| k.name == "sit").expect("sit.ron has a sit");
    let (turn, sit) = (&s.skills[1], &s.skills[sit_index]);
    assert_eq!((turn.name.as_str(), sit.name.as_str()), ("turn_left", "sit"));
    assert!(sit.holds && !turn.holds, "sit.ron holds its last frame, turn_left.ron does not");
    let (last_turn, last_sit) = (turn.frames - 1, sit.frames - 1);
    assert!(turn.ended(last_turn) && !turn.ended(last_turn - 1));
    assert!(!sit.ended(last_sit), "a held clip never ends a decision early");
    assert_eq!(sit.advance(last_sit), last_sit, "the seated frame is held");
    assert_eq!(sit.advance(last_sit - 1), last_sit);

    // In the environment: turn to the clip's end, then sit; every sit decision that does not
    // end in a fall runs the full 0.5 s, past the clip's end, with the phase observed at 1.
    let mut env = MetaEnv::new(Arc::clone(&s));
    let mut rng = EnvRng::seed_from_u64(3);
    let mut obs = vec![0.0; env.obs_dim()];
    env.reset(&mut rng, &mut obs);
    let phi = s.layout.size + s.task.extra_dim() + s.skills.len();
    for _ in 0..12 {
        assert!(!env.step(&[1.0, 0.0, 0.0], &mut obs).terminated, "no fall ends a decision under the steady rule");
        if obs[phi] >= 1.0 {
            break;
        }
    }
    assert!(obs[phi] >= 1.0, "the turn reached its clip's end");
    let decisions = (last_sit as f64 / 30.0).ceil() as usize + 2;
    for d in 0..decisions {
        let t0 = env.world().time();
        let out = env.step(&[sit_index as f32, 0.0, 0.0], &mut obs);
        assert!(!out.terminated && !out.truncated, "sit decision {d} ended the episode");
        assert!((env.world().time() - t0 - 0.5).abs() < 1e-5, "sit decision {d} was cut short");
        let expected = ((d + 1) * 30).min(last_sit) as f32 / last_sit as f32;
        assert!((obs[phi] - expected).abs() < 1e-6, "decision {d}: phase {} for {expected}", obs[phi]);
    }
}

#[test]
fn a_walk_chosen_after_a_turn_picks_its_cycle_up_at_the_nearest_frame() {
    let s = steady();
    let (walk, turn) = (&s.skills[0], &s.skills[1]);
    assert_eq!((walk.name.as_str(), turn.name.as_str()), ("walk_to", "turn_left"));
    let dof = s.model.index.joints.len();
    assert!(walk.looping && walk.cycle.0.len() == walk.frames * dof, "walk's manifest carries its cycle");
    assert!(turn.cycle.0.is_empty(), "a clip that ends has no cycle table");
    let row = |t: &[f32], f: usize| t[f * dof..(f + 1) * dof].iter().map(|&x| f64::from(x)).collect::<Vec<_>>();
    for f in [0, 17, 50] {
        let (q, v) = (row(&walk.cycle.0, f), row(&walk.cycle.1, f));
        assert_eq!(walk.entry_frame(&q, &v), f);
        assert_eq!(turn.entry_frame(&q, &v), 0, "a turn always starts at its first frame");
    }

    // In the environment: a turn decision, then walk, which starts where the body's pose is.
    let mut env = MetaEnv::new(Arc::clone(&s));
    let mut rng = EnvRng::seed_from_u64(5);
    let mut obs = vec![0.0; env.obs_dim()];
    env.reset(&mut rng, &mut obs);
    assert!(!env.step(&[1.0, 0.0, 0.0], &mut obs).terminated, "no fall ends a decision under the steady rule");
    let (mut q, mut v) = (vec![0.0; dof], vec![0.0; dof]);
    env.world().joint_angles(&mut q);
    env.world().joint_velocities(&mut v);
    let entry = walk.entry_frame(&q, &v);
    let t0 = env.world().time();
    assert!(!env.step(&[0.0, 0.0, 0.0], &mut obs).terminated, "no fall ends a decision under the steady rule");
    let ticks = ((env.world().time() - t0) * s.control_hz()).round() as usize;
    let phi = s.layout.size + s.task.extra_dim() + s.skills.len();
    let cycle = walk.frames - 1;
    let expected = ((entry + ticks) % cycle) as f32 / cycle as f32;
    assert!((obs[phi] - expected).abs() < 1e-6, "walk phase {} after entering at frame {entry}", obs[phi]);
}

#[test]
fn training_writes_a_controller_and_evaluation_is_reproducible() {
    let s = setup(Some(SkillGraph::chain(&["walk_to", "turn_left", "sit"])));
    let dir = std::env::temp_dir().join(format!("repertoire-meta-train-{}", std::process::id()));
    let opts = MetaTrainOptions {
        out: dir.join("meta"),
        run_dir: dir.join("run"),
        ppo: PpoConfig {
            num_envs: 2,
            num_steps: 4,
            num_iterations: 2,
            num_minibatches: 2,
            update_epochs: 1,
            ..PpoConfig::default()
        },
        curriculum: true,
        command: "test".into(),
        resume: None,
        checkpoint_every: 0,
        warm_start: None,
        replace: Vec::new(),
    };
    let (manifest, history) = train(Arc::clone(&s), &opts).expect("train");
    assert_eq!(history.len(), 2);
    assert_eq!(manifest.skills, ["walk_to", "turn_left", "sit"]);
    let (_, head) = load(&dir.join("meta"), &s).expect("load");
    let zones = vec!["front".to_string(), "behind".to_string()];
    let a = evaluate(&s, &head, &zones, 3, 3, 7).expect("eval");
    let b = evaluate(&s, &head, &zones, 3, 3, 7).expect("eval");
    assert_eq!(a, b, "the same seed gives the same trials");
    assert_eq!(a.trials.len(), 6);
    assert_eq!(a.zones.len(), 3);
    for t in &a.trials {
        // The chain's order holds in every trial.
        let order: Vec<&str> = t.skills.iter().map(String::as_str).collect();
        assert!(["walk_to", "turn_left", "sit"].starts_with(&order), "illegal order {order:?}");
    }
    a.write(&dir.join("report")).expect("write");
    assert!(std::fs::read_to_string(dir.join("report/report.md")).unwrap().contains("| front | 3 |"));
    let svg = std::fs::read_to_string(dir.join("report/heatmap.svg")).unwrap();
    assert!(svg.contains("<svg") && svg.contains("success by start position (6 trials"), "{svg:.300}");
    for side in a.transitions.iter().map(|(side, _)| side) {
        assert!(dir.join(format!("report/transitions-{side}.png")).exists(), "{side}");
    }
    assert!(dir.join("report/heatmap.png").exists());
    // A controller trained for other skills is refused.
    let full = setup(None);
    let err = load(&dir.join("meta"), &full).expect_err("different skills").to_string();
    assert!(err.contains("meta.ron"), "{err}");

    // The controller pins its skills' weights: over a library whose turn_left was retrained
    // (here: its recorded checksum changed) it is refused, naming the skill; a manifest from
    // before skills were pinned still loads.
    let expected: Vec<u64> = s.skills.iter().map(|k| k.policy_fnv1a).collect();
    assert_eq!(manifest.skill_weights, expected);
    let meta_ron = dir.join("meta").join("meta.ron");
    let text = std::fs::read_to_string(&meta_ron).unwrap();
    let mut other = manifest.clone();
    other.skill_weights[1] ^= 1;
    let pretty = ron::ser::PrettyConfig::new();
    std::fs::write(&meta_ron, ron::ser::to_string_pretty(&other, pretty.clone()).unwrap()).unwrap();
    let err = load(&dir.join("meta"), &s).expect_err("retrained skill").to_string();
    assert!(err.contains("meta.ron") && err.contains("`turn_left`") && err.contains("retrained"), "{err}");
    other.skill_weights.clear();
    std::fs::write(&meta_ron, ron::ser::to_string_pretty(&other, pretty).unwrap()).unwrap();
    load(&dir.join("meta"), &s).expect("an unpinned manifest loads");
    std::fs::write(&meta_ron, text).unwrap();
    load(&dir.join("meta"), &s).expect("the pinned manifest loads");
}

#[test]
fn the_planners_copy_of_an_episode_plays_out_exactly_as_the_episode() {
    // The planner's premise: a plan simulated in its copy (snapshot, restore, step) ends where
    // the episode itself ends given the same decisions, bit for bit, also from mid-episode,
    // where MuJoCo's derived quantities belong to the state before the last substep.
    use repertoire_meta::search::planner::{Planner, PlannerConfig, write_action};
    let s = setup(None);
    let mut planner = Planner::new(Arc::clone(&s), PlannerConfig::default());
    // Walk (two targets; walk_to reads them), a left turn, then sit.
    let plan = [(0, 0), (0, 1), (1, 0), (1, 0), (3, 0), (3, 0), (3, 0), (3, 0)];
    let mut compared = 0;
    for seed in 0..4 {
        let mut env = MetaEnv::new(Arc::clone(&s));
        let mut obs = vec![0.0; env.obs_dim()];
        env.reset(&mut EnvRng::seed_from_u64(seed), &mut obs);
        let mut act = vec![0.0; env.act_dim()];
        if seed % 2 == 1 {
            write_action(&s, (0, 2), &mut act);
            env.step(&act, &mut obs);
        }
        let predicted = planner.simulate(&env, &plan);
        assert!(predicted.played >= 1);
        let mut ended = false;
        for &o in &plan[..predicted.played] {
            write_action(&s, o, &mut act);
            let out = env.step(&act, &mut obs);
            ended = out.terminated || out.truncated;
        }
        assert_eq!(ended, predicted.ended, "seed {seed}");
        assert_eq!(env.task().succeeded(), predicted.success, "seed {seed}");
        assert_eq!(env.snapshot(), predicted.snapshot, "seed {seed}: the copy and the episode differ");
        compared += predicted.played;
    }
    assert!(compared >= 4);
}

#[test]
fn the_planner_evaluates_reproducibly_and_only_plays_what_the_graph_allows() {
    use repertoire_meta::search::planner::PlannerConfig;
    let s = setup(None);
    let cfg = PlannerConfig { horizon: 4, repeats: 1 };
    let zones = ["front".to_string()];
    let a = evaluate(&s, &cfg, &zones, 3, 3, 7).expect("planner evaluation");
    let b = evaluate(&s, &cfg, &zones, 3, 3, 7).expect("again");
    assert_eq!(a, b, "the planner is deterministic for a seed");
    assert_eq!(a.trials.len(), 3);
    for t in &a.trials {
        let mut from = None;
        for name in &t.skills {
            let to = s.graph.index(name).expect("a skill of the graph");
            assert!(s.graph.is_allowed(from, to), "trial {}: {name} after {from:?} ({:?})", t.index, t.skills);
            from = Some(to);
        }
        assert!(!t.skills.is_empty());
    }
}

#[test]
fn the_planner_distilled_is_a_controller_that_loads_and_evaluates() {
    use repertoire_meta::handover::distill::{DistillOptions, Teacher, distill};
    use repertoire_meta::search::planner::PlannerConfig;
    let s = setup(None);
    let out = std::env::temp_dir().join(format!("repertoire-distill-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&out);
    let opts = DistillOptions {
        out: out.clone(),
        episodes: 2,
        zones: vec!["front".into()],
        teacher: Teacher::Planner(PlannerConfig { horizon: 3, repeats: 0 }),
        warm_start: None,
        successful_only: false,
        changed_weight: 1,
        epochs: 3,
        batch: 8,
        ppo: PpoConfig { num_envs: 2, ..repertoire_meta::train::default_ppo() },
        seed: 4,
        command: "test".into(),
        then_train: Some(MetaTrainOptions {
            out: out.clone(),
            run_dir: out.join("run"),
            ppo: PpoConfig { num_envs: 2, num_steps: 4, num_iterations: 1, ..repertoire_meta::train::default_ppo() },
            curriculum: false,
            command: "test".into(),
            resume: None,
            checkpoint_every: 0,
            warm_start: None,
            replace: Vec::new(),
        }),
    };
    let (manifest, f) = distill(Arc::clone(&s), &opts).expect("distil");
    assert!(manifest.warm_start.is_none(), "the planner's fit starts from a fresh policy");
    assert_eq!(f.changed, 0, "the planner changes no controller's decisions");
    assert_eq!(f.episodes, 2);
    assert!(f.demonstrations >= 2, "every episode makes at least one decision");
    assert_eq!(manifest.iterations, 1, "the fit, then one PPO iteration");
    assert_eq!(f.losses.len(), 3);
    assert!(f.losses.iter().all(|l| l.is_finite() && *l >= 0.0), "{:?}", f.losses);
    let (loaded, head) = load(&out, &s).expect("the distilled controller loads");
    assert_eq!(loaded, manifest);
    let (fitted, _) = load(&out.join("fitted"), &s).expect("the fit before PPO is kept and loads");
    assert_eq!((fitted.iterations, fitted.samples), (0, f.demonstrations as u64), "the fit alone");
    let weights = |dir: &Path| std::fs::read(dir.join("meta.safetensors")).unwrap();
    assert!(weights(&out) != weights(&out.join("fitted")), "PPO moved the fitted controller");
    assert!(!out.join("fitted").join(CRITIC_FILE).exists(), "the fit trains no critic, so none is saved");
    assert!(out.join(CRITIC_FILE).exists(), "PPO after the fit trained one");
    let report = evaluate(&s, &head, &["front".to_string()], 2, 2, 1).expect("evaluates");
    assert_eq!(report.trials.len(), 2);
    // Only successful episodes, when none succeeded, leave nothing to fit: a clear error.
    if f.successes == 0 {
        let only = DistillOptions { successful_only: true, then_train: None, ..opts };
        let err = distill(Arc::clone(&s), &only).expect_err("nothing to fit");
        assert!(err.to_string().contains("no demonstrations"), "{err}");
    }
}

#[test]
fn a_walk_that_takes_a_target_is_steered_every_decision() {
    // Walk stage 2 observes a target; the meta environment hands it the decision's target (in
    // the pelvis' heading frame) at every decision, not only when walk is switched to.
    let lib = std::env::temp_dir().join(format!("repertoire-meta-target-lib-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&lib);
    std::fs::create_dir_all(&lib).unwrap();
    for name in ["turn_left", "sit"] {
        let (from, to) = (library().join(name), lib.join(name));
        std::fs::create_dir_all(&to).unwrap();
        for f in std::fs::read_dir(&from).unwrap() {
            let f = f.unwrap().path();
            std::fs::copy(&f, to.join(f.file_name().unwrap())).unwrap();
        }
    }
    let specs = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../specs");
    let spec = SpecFile::load(&specs.join("walk_stage2.ron")).expect("spec");
    let walk = SkillSetup::new(spec, &lib).expect("walk stage 2 builds");
    repertoire_skill::train::train(&walk, &TrainOptions::quick(&lib, &lib.join("run-walk"), 1, 2, 1)).expect("train");

    let model = Arc::new(WorldModel::build(ScenarioFile::builtin_default()).expect("scene"));
    let s = Arc::new(MetaSetup::new(model, &lib, SkillGraph::chain(&["walk", "turn_left", "sit"])).expect("setup"));
    let env = MetaEnv::new(Arc::clone(&s));
    assert_eq!(env.options(), Some(vec![true, false, false]), "only walk takes a target");
    let mut env = env;
    let mut obs = vec![0.0; env.obs_dim()];
    env.reset(&mut EnvRng::seed_from_u64(2), &mut obs);
    let w = env.world().snapshot_len();
    // The continuous action is the target's azimuth and distance in units of the walk's
    // training range (±90°, 1.5–4 m), clamped: the middle is 2.75 m straight ahead.
    let walk = &s.skills[0];
    let near = |a: [f64; 2], b: [f64; 2]| (a[0] - b[0]).abs() < 1e-6 && (a[1] - b[1]).abs() < 1e-6;
    assert!(near(walk.target_offset([0.0, 0.0]), [2.75, 0.0]));
    assert!(near(walk.target_offset([1.0, -1.0]), [0.0, 1.5]), "full left, nearest");
    assert!(near(walk.target_offset([-3.0, 7.0]), [0.0, -4.0]), "clamped: full right, farthest");
    let [a, b] = walk.target_action(30.0, 2.0);
    let back = walk.target_offset([a, b]);
    assert!((back[0].hypot(back[1]) - 2.0).abs() < 1e-5 && (back[1].atan2(back[0]).to_degrees() - 30.0).abs() < 1e-4);
    for (a0, a1) in [(0.0f32, 0.0f32), (0.3, -0.6), (-0.9, 2.5)] {
        let p = env.world().pelvis_frame().pos;
        let yaw = env.world().heading();
        let [dx, dy] = walk.target_offset([a0, a1]);
        let want = [p[0] + yaw.cos() * dx - yaw.sin() * dy, p[1] + yaw.sin() * dx + yaw.cos() * dy];
        // (A barely trained walk may fall; the environment steps on, and the target logic is
        // what is checked here.)
        env.step(&[0.0, a0, a1], &mut obs);
        let snap = env.snapshot();
        let got = [snap[w + 2], snap[w + 3]];
        assert!((got[0] - want[0]).abs() < 1e-9 && (got[1] - want[1]).abs() < 1e-9, "target {got:?}, wanted {want:?}");
    }
    assert_eq!(env.chosen, [0], "walk all along");
}

#[test]
fn deliveries_record_the_seat_where_the_controller_hands_over_within_the_window() {
    use repertoire_meta::handover::deliver::{DeliveryWindow, deliver};
    use repertoire_meta::search::planner::PlannerConfig;
    let s = setup(None);
    let planner = PlannerConfig { horizon: 2, repeats: 0 };
    let zones = ["front".to_string(), "sides".to_string()];
    let window = |max_offset_m, max_turn_deg| DeliveryWindow { expected: [-0.4, 0.0, 0.0], max_offset_m, max_turn_deg };
    let all = deliver(&s, &planner, "sit", &zones, 2, 3, Some(window(100.0, 180.0)), 1000).expect("deliver");
    assert_eq!(all.episodes, 4);
    assert!(all.decisions >= 4, "at least the first decision of each episode: {}", all.decisions);
    assert_eq!(all.in_window, all.decisions, "an unbounded window keeps every decision");
    assert_eq!(all.pool.states.len(), all.decisions);
    assert_eq!(all.pool.body_hash, s.model.body.content_hash());
    // Sit ends each planner episode that reaches it: at most one handover per episode here,
    // and every handover in an unbounded window.
    assert!(all.handovers <= all.episodes && all.handovers_in_window == all.handovers, "{all:?}");
    assert_eq!(all.handover_pool.states.len(), all.handovers, "one state per handover");
    assert!(all.handover_pool.states.iter().all(|st| all.pool.states.contains(st)), "handovers are decisions too");
    // The start states: standing 1.5 m or more from the chair, so the seat is well away.
    let far = all.pool.states.iter().filter(|st| st.seat.is_some_and(|p| p[0].hypot(p[1]) > 1.0)).count();
    assert!(far >= 4, "{far} states with the seat over 1 m away");
    let again = deliver(&s, &planner, "sit", &zones, 2, 3, Some(window(100.0, 180.0)), 1000).expect("again");
    assert_eq!(again.pool, all.pool, "reproducible for a seed");
    // No window (a skill without a seat goal, the stand): every decision is kept, seat and all.
    let open = deliver(&s, &planner, "sit", &zones, 2, 3, None, 1000).expect("no window");
    assert_eq!((open.in_window, open.handovers_in_window), (open.decisions, open.handovers));
    assert_eq!(open.pool, all.pool, "no window keeps what an unbounded one does");

    // A window keeps exactly the states whose seat lies in it; the cap spreads what it keeps.
    let w = window(1.8, 90.0);
    let some = deliver(&s, &planner, "sit", &zones, 2, 3, Some(w), 1000).expect("deliver");
    let inside = all.pool.states.iter().filter(|st| w.contains(st.seat.unwrap())).count();
    assert_eq!(some.in_window, inside);
    assert_eq!(some.handovers, all.handovers, "the window only filters what is kept");
    assert!(some.handovers_in_window <= some.handovers);
    assert!(some.pool.states.iter().all(|st| w.contains(st.seat.unwrap())));
    let capped = deliver(&s, &planner, "sit", &zones, 2, 3, Some(window(100.0, 180.0)), 3).expect("capped");
    assert!(capped.pool.states.len() <= 3 && !capped.pool.states.is_empty());
    assert_eq!(capped.pool.states[0], all.pool.states[0]);
    let none = deliver(&s, &planner, "sit", &zones, 2, 3, Some(window(0.0, 0.0)), 1000).expect("deliver");
    assert_eq!(none.in_window, 0);
    assert_eq!(none.handover_pool, all.handover_pool, "handovers are kept whatever the window");

    let err = deliver(&s, &planner, "dance", &zones, 1, 3, Some(w), 10).expect_err("unknown skill").to_string();
    assert!(err.contains("`dance`") && err.contains("walk"), "{err}");
    let err = deliver(&s, &planner, "sit", &["nowhere".to_string()], 1, 3, Some(w), 10).expect_err("zone").to_string();
    assert!(err.contains("nowhere"), "{err}");
}

#[test]
fn seated_means_on_the_seat_facing_the_chairs_front_not_any_contact() {
    // The sit clip played open loop onto the chair where the skill puts it: the character sits,
    // facing the way the chair faces. The same contact with the chair turned round (the
    // character now faces its backrest, as after falling forward onto the seat) is contact,
    // but not sitting, unless the scenario counts any contact (`facing_deg: 180`).
    use repertoire_skill::imitation::ImitationTask;
    let (s, chair) = sit_skill();
    let r = &s.settings.reference;
    let mut env = s.env();
    ImitationTask::new(s.settings.clone()).place_at_frame(env.world_mut(), 0, 0.4, -0.3, 0.7);
    let world = env.world_mut();
    let mut sat = false;
    for f in 1..r.frames() + 30 {
        world.step(r.joints_at(f.min(r.frames() - 1))).expect("steps");
        sat |= world.contacts().pelvis_on_prop(chair) && f + 1 >= r.frames();
    }
    assert!(sat && world.contacts().pelvis_on_prop(chair), "the open-loop clip ends seated");
    let sixty = 60f64.to_radians();
    assert!(world.seated_on(chair, sixty), "seated facing the chair's front");
    let pl = world.placements()[chair];
    world.move_prop(chair, pl.pos[0], pl.pos[1], pl.yaw + std::f64::consts::PI).expect("turn the chair");
    assert!(world.contacts().pelvis_on_prop(chair), "still touching the (symmetric) seat");
    assert!(!world.seated_on(chair, sixty), "facing the backrest is not sitting");
    assert!(world.seated_on(chair, std::f64::consts::PI), "facing_deg 180 counts any contact");
}

/// The library's sit skill and the index of its chair prop.
fn sit_skill() -> (SkillSetup, usize) {
    let specs = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../specs");
    let s = SkillSetup::new(SpecFile::load(&specs.join("sit.ron")).expect("spec"), library()).expect("sit");
    let (chair, _) = s.settings.seat.expect("sit has a seat");
    (s, chair)
}

#[test]
fn the_spot_approach_pays_for_arriving_where_the_sit_starts() {
    // `SitApproach::Spot` measures the distance to the spot in front of the seat where the sit's
    // clip starts, plus the heading error: at the sit's first frame with the chair where the
    // skill expects it, the potential is about zero; turned to face the backrest it grows by
    // heading_m · π; `Seat` is the pelvis–seat distance whatever the heading.
    use repertoire_meta::task::sit_potential;
    use repertoire_scenes::SitApproach;
    use repertoire_skill::imitation::ImitationTask;
    let (s, chair) = sit_skill();
    let [ahead, left, yaw] = s.seat_at_start().expect("a seat goal");
    assert!(
        (ahead + 0.4).abs() < 0.05 && left.abs() < 0.05 && yaw.abs() < 0.05,
        "the seat 0.4 m behind: {ahead} {left} {yaw}"
    );
    let spot = SitApproach::Spot { ahead_m: 0.4, heading_m: 0.3, turn_within_m: None, around: None };
    let mut env = s.env();
    ImitationTask::new(s.settings.clone()).place_at_frame(env.world_mut(), 0, 0.4, -0.3, 0.7);
    let world = env.world_mut();
    let at_start = sit_potential(world, chair, &spot);
    assert!(at_start < 0.08, "where the sit starts: {at_start}");
    let seat = sit_potential(world, chair, &SitApproach::Seat);
    let pl = world.placements()[chair];
    let drop = world.pelvis_frame().pos[2] - pl.top;
    assert!((seat - 0.4f64.hypot(drop)).abs() < 0.05, "the seat's centre 0.4 m behind, {drop} m down: {seat}");
    world.move_prop(chair, pl.pos[0], pl.pos[1], pl.yaw + std::f64::consts::PI).expect("turn the chair");
    // The spot is now 0.4 m behind the seat's centre, the heading off by π.
    let turned = sit_potential(world, chair, &spot);
    let want = 0.3 * std::f64::consts::PI + 0.8;
    assert!((turned - want).abs() < 0.1, "facing the backrest: {turned}, about {want}");
    assert!((sit_potential(world, chair, &SitApproach::Seat) - seat).abs() < 1e-9, "Seat ignores the heading");
}

#[test]
fn with_turn_within_m_the_spot_approach_pays_for_facing_the_spot_far_off_and_the_chairs_way_at_it() {
    // Without `turn_within_m` the heading term always wants the chair's way (the seat behind),
    // so turning away from the chair 2.5 m off pays heading_m · π at once. With it, far off the
    // heading that counts is the bearing to the spot, at the spot the chair's way, blended in
    // between; the potential stays continuous across the chair's axis.
    use repertoire_meta::task::sit_potential;
    use repertoire_scenes::SitApproach;
    use std::f64::consts::PI;
    let (s, chair) = sit_skill();
    let fixed = SitApproach::Spot { ahead_m: 0.4, heading_m: 0.3, turn_within_m: None, around: None };
    let turning = SitApproach::Spot { ahead_m: 0.4, heading_m: 0.3, turn_within_m: Some(1.5), around: None };
    let mut env = s.env();
    let world = env.world_mut();
    let pl = world.placements()[chair];
    let (u, v) = ([pl.yaw.cos(), pl.yaw.sin()], [-pl.yaw.sin(), pl.yaw.cos()]);
    // The pelvis `ahead` metres in front of the spot and `side` metres to its left, facing the
    // chair (`toward`) or the chair's way.
    let mut at = |ahead: f64, side: f64, toward: bool, approach: &SitApproach| {
        let a = 0.4 + ahead;
        let yaw = if toward { pl.yaw + PI } else { pl.yaw };
        world.place_standing(pl.pos[0] + a * u[0] + side * v[0], pl.pos[1] + a * u[1] + side * v[1], yaw);
        sit_potential(world, chair, approach)
    };
    let h = 0.3 * PI;
    let close =
        |got: f64, want: f64, what: &str| assert!((got - want).abs() < 0.05, "{what}: {got}, want about {want}");
    close(at(2.5, 0.0, true, &fixed), 2.5 + h, "facing the chair 2.5 m off, fixed heading");
    close(at(2.5, 0.0, false, &fixed), 2.5, "turned away 2.5 m off, fixed heading");
    close(at(2.5, 0.0, true, &turning), 2.5, "facing the chair 2.5 m off, turning within 1.5 m");
    close(at(2.5, 0.0, false, &turning), 2.5 + h, "turned away 2.5 m off, turning within 1.5 m");
    close(at(0.0, 0.0, false, &turning), 0.0, "at the spot, the seat behind");
    close(at(0.0, 0.0, true, &turning), h, "at the spot, facing the chair");
    // Half way into the radius the two errors count half each.
    close(at(0.75, 0.0, true, &turning), 0.75 + 0.5 * h, "0.75 m off facing the chair");
    // Continuous across the axis, where the bearing's error wraps.
    let (left, right) = (at(0.75, 0.01, true, &turning), at(0.75, -0.01, true, &turning));
    assert!((left - right).abs() < 0.01, "either side of the axis: {left} against {right}");
}

#[test]
fn the_way_round_a_disc_is_straight_where_clear_tangent_and_arc_where_blocked_and_continuous() {
    use repertoire_meta::task::distance_round_disc;
    use std::f64::consts::PI;
    let o = [0.0, 0.0];
    let close = |got: f64, want: f64, what: &str| assert!((got - want).abs() < 1e-9, "{what}: {got}, want {want}");
    // Clear of the disc: the straight line.
    close(distance_round_disc([2.0, 1.5], [2.0, -1.5], o, 1.0), 3.0, "beside the disc");
    // Straight through the centre: two tangents of √3 and a third of the circle's half.
    close(distance_round_disc([-2.0, 0.0], [2.0, 0.0], o, 1.0), 2.0 * 3f64.sqrt() + PI / 3.0, "across the disc");
    // Symmetric, and unchanged by moving the whole picture.
    close(distance_round_disc([2.0, 0.0], [-2.0, 0.0], o, 1.0), 2.0 * 3f64.sqrt() + PI / 3.0, "the way back");
    close(
        distance_round_disc([3.0, 5.0], [7.0, 5.0], [5.0, 5.0], 1.0),
        2.0 * 3f64.sqrt() + PI / 3.0,
        "moved by (5, 5)",
    );
    // Never shorter than the straight line, longer exactly when the line crosses the disc.
    let straight = |a: [f64; 2], b: [f64; 2]| (a[0] - b[0]).hypot(a[1] - b[1]);
    for (a, b, crosses) in [
        ([-2.0, 0.5], [2.0, 0.5], true),
        ([-2.0, 1.01], [2.0, 1.01], false),
        ([-1.5, -1.5], [1.5, 1.5], true),
        ([0.0, 3.0], [3.0, 0.0], false),
    ] {
        let d = distance_round_disc(a, b, o, 1.0);
        assert!(d >= straight(a, b) - 1e-12, "{a:?} → {b:?}: {d}");
        assert_eq!(d > straight(a, b) + 1e-9, crosses, "{a:?} → {b:?}: {d} against {}", straight(a, b));
    }
    // Continuous as the start sweeps round behind the disc and across its edge into it.
    let mut last: Option<f64> = None;
    for i in 0..=400 {
        let angle = PI / 2.0 + PI * i as f64 / 400.0;
        let d = distance_round_disc([2.0 * angle.cos(), 2.0 * angle.sin()], [1.5, 0.0], o, 1.0);
        if let Some(l) = last {
            assert!((d - l).abs() < 0.02, "a jump at {angle}: {l} → {d}");
        }
        last = Some(d);
    }
    let (outside, inside) = (
        distance_round_disc([-1.0001, 0.0], [1.5, 0.0], o, 1.0),
        distance_round_disc([-0.9999, 0.0], [1.5, 0.0], o, 1.0),
    );
    assert!((outside - inside).abs() < 1e-3, "across the circle: {outside} against {inside}");
    // From inside: out along the radius, then on; from the centre, straight towards the target.
    close(distance_round_disc([0.0, 0.0], [1.5, 0.0], o, 1.0), 1.5, "from the centre");
    // Everywhere inside, however the exit point rounds (it once recursed without end): finite,
    // and at least the straight way.
    for i in 0..2000 {
        let (angle, r) = (i as f64 * 0.7311, 0.6 * (i as f64 / 2000.0));
        let from = [-0.3 + r * angle.cos(), 0.1 + r * angle.sin()];
        let d = distance_round_disc(from, [0.4, 0.0], [-0.3, 0.0], 0.6);
        assert!(d.is_finite() && d >= (from[0] - 0.4).hypot(from[1]) - 1e-9, "from {from:?}: {d}");
    }
    close(distance_round_disc([0.5, 0.0], [1.5, 0.0], o, 1.0), 1.0, "on the way out");
    // From 0.5 m behind the centre: 0.5 m out, then from the circle (no tangent of its own) round
    // to the target's tangent point and along it.
    close(
        distance_round_disc([-0.5, 0.0], [1.5, 0.0], o, 1.0),
        0.5 + 1.25f64.sqrt() + PI - (1.0f64 / 1.5).acos(),
        "out behind, then round",
    );
}

#[test]
fn the_spot_approach_round_the_chair_costs_more_from_behind_and_the_same_in_front() {
    // `around`: the distance to the spot is measured round a disc over the chair, so from
    // behind the chair the way round is longer than the straight line through it; in front of
    // the chair, along its axis, on the seat included, it is the same as without.
    use repertoire_meta::task::sit_potential;
    use repertoire_scenes::{SitApproach, SpotAround};
    let (s, chair) = sit_skill();
    let straight = SitApproach::Spot { ahead_m: 0.4, heading_m: 0.3, turn_within_m: None, around: None };
    let round = SitApproach::Spot {
        ahead_m: 0.4,
        heading_m: 0.3,
        turn_within_m: None,
        around: Some(SpotAround { radius_m: 0.6, behind_m: 0.3 }),
    };
    let mut env = s.env();
    let world = env.world_mut();
    let pl = world.placements()[chair];
    let u = [pl.yaw.cos(), pl.yaw.sin()];
    let mut at = |ahead: f64, approach: &SitApproach| {
        world.place_standing(pl.pos[0] + ahead * u[0], pl.pos[1] + ahead * u[1], pl.yaw);
        sit_potential(world, chair, approach)
    };
    for ahead in [2.5, 1.0, 0.4, 0.2, 0.0] {
        let (a, b) = (at(ahead, &straight), at(ahead, &round));
        assert!((a - b).abs() < 1e-9, "{ahead} m in front of the seat: {a} against {b}");
    }
    // 2 m behind the seat: straight 2.4 m; round the disc (0.6 m about 0.3 m behind the seat)
    // from 1.7 m behind its centre to 0.7 m in front of it: two tangents and half a turn less
    // what they cover.
    let (a, b) = (at(-2.0, &straight), at(-2.0, &round));
    let (rf, rt, r) = (1.7f64, 0.7f64, 0.6f64);
    let way = (rf * rf - r * r).sqrt()
        + (rt * rt - r * r).sqrt()
        + r * (std::f64::consts::PI - (r / rf).acos() - (r / rt).acos());
    assert!((a - 2.4).abs() < 0.02, "straight from behind: {a}");
    assert!((b - way).abs() < 0.03, "round from behind: {b}, want about {way}");
    assert!(b > a + 0.3, "the way round is longer: {b} against {a}");
}

#[test]
fn a_fall_forfeits_the_approach_reward_only_when_the_scenario_says_so() {
    // `on_fall: Forfeit`: the decision that ends in a fall pays back, negated, the approach
    // reward the episode earned, so walking towards the chair and falling earns nothing;
    // `Keep` (the paper's) pays 0 for the fall and keeps the rest. The running sum survives a
    // snapshot and restore (the planner's copies of an episode).
    use repertoire_meta::task::{EpisodeOverride, TaskSpec, sit_potential};
    use repertoire_scenes::{SitApproach, SitFall};
    let (s, chair) = sit_skill();
    let approach = SitApproach::Spot { ahead_m: 0.4, heading_m: 0.3, turn_within_m: None, around: None };
    let mut env = s.env();
    let world = env.world_mut();
    let pl = world.placements()[chair];
    // Walk in from 2.5 m in front, facing the chair, in steps of 0.5 m, then fall.
    let path: Vec<f64> = vec![2.5, 2.0, 1.5, 1.0];
    let mut totals = Vec::new();
    for on_fall in [SitFall::Keep, SitFall::Forfeit] {
        let spec = TaskSpec::Sit { seat: chair, hold_s: 3.0, facing: 1.0, approach, on_fall, touch_penalty: 0.0 };
        let mut state = spec.new_state(60.0);
        let mut rng = EnvRng::seed_from_u64(1);
        world.place_standing(pl.pos[0] + path[0], pl.pos[1], pl.yaw + std::f64::consts::PI);
        state.begin(&spec, world, &mut rng, &EpisodeOverride::default());
        let start = sit_potential(world, chair, &approach);
        let mut sum = 0.0;
        for &x in &path[1..] {
            world.place_standing(pl.pos[0] + x, pl.pos[1], pl.yaw + std::f64::consts::PI);
            let r = state.decision_reward(&spec, world, false, false, 0.5);
            assert!(r > 0.0, "walking towards the chair pays: {r}");
            sum += f64::from(r);
        }
        let walked = start - sit_potential(world, chair, &approach);
        assert!((sum - walked).abs() < 1e-4, "the approach reward telescopes: {sum} against {walked}");
        // A copy of the episode carries what was paid.
        let mut copy = spec.new_state(60.0);
        copy.restore(&state.snapshot());
        let fall = state.decision_reward(&spec, world, true, false, 0.5);
        let copied = copy.decision_reward(&spec, world, true, false, 0.5);
        assert_eq!(fall, copied, "the restored copy forfeits the same");
        totals.push((sum, f64::from(fall)));
    }
    let (kept, keep_fall) = totals[0];
    let (_, forfeit_fall) = totals[1];
    assert!(kept > 1.0 && keep_fall == 0.0, "Keep: the walk's {kept} stays, the fall pays {keep_fall}");
    assert!((forfeit_fall + kept).abs() < 1e-4, "Forfeit: the fall pays back {forfeit_fall} of {kept}");
}

/// The default scenario with sit guarded to within `within_m` of the chair.
fn guarded_setup(within_m: f64) -> Arc<MetaSetup> {
    let builtin = sit_scenario();
    let edges_end = "(\"turn_left_wide\", \"sit\"), (\"turn_right_wide\", \"sit\"),\n        ],";
    assert!(builtin.text.contains(edges_end), "the default graph's last edges moved");
    let text = builtin.text.replace(
        edges_end,
        &format!("{edges_end}\n        guards: [(skill: \"sit\", near: \"chair\", within_m: {within_m})],"),
    );
    let file = ScenarioFile::parse(&builtin.path, text).expect("the guarded scenario parses");
    let model = Arc::new(WorldModel::build(file).expect("scene"));
    let graph = SkillGraph::of(&model.scenario.scenario);
    Arc::new(MetaSetup::new(model, library(), graph).expect("meta setup"))
}

#[test]
fn the_planner_searches_only_what_the_guards_allow() {
    // Far from the chair a guarded sit is no option: the planner neither picks it nor spends
    // simulations on plans through it, as it does without the guard.
    use repertoire_meta::search::planner::{Planner, PlannerConfig};
    let cfg = PlannerConfig { horizon: 2, repeats: 0 };
    let mut searched = Vec::new();
    for s in [setup(None), guarded_setup(0.05)] {
        let (sit, turn) = (s.graph.index("sit").expect("sit"), s.graph.index("turn_left").expect("turn_left"));
        let chair = s.model.prop_id("chair").expect("chair");
        let mut env = MetaEnv::new(Arc::clone(&s));
        let mut obs = vec![0.0; env.obs_dim()];
        env.reset(&mut EnvRng::seed_from_u64(3), &mut obs);
        let mut act = [0.0; 3];
        act[0] = turn as f32;
        env.step(&act, &mut obs);
        let pl = env.world().placements()[chair];
        env.world_mut().place_standing(pl.pos[0] + 2.0 * pl.yaw.cos(), pl.pos[1] + 2.0 * pl.yaw.sin(), pl.yaw);
        let mut planner = Planner::new(Arc::clone(&s), cfg);
        planner.act(&env, &mut act);
        let guarded = s.skills[sit].guard.is_some();
        assert!(!guarded || act[0] as usize != sit, "the planner picked a guarded-off sit");
        searched.push(planner.simulated);
    }
    assert!(searched[1] < searched[0], "simulated decisions, unguarded and guarded: {searched:?}");
}

#[test]
fn a_guarded_sit_is_offered_only_near_the_chair_and_may_always_continue() {
    // `skill_graph.guards`: sit may follow a turn only while the pelvis is within 0.8 m of the
    // chair; once chosen it continues wherever the character is.
    let s = guarded_setup(0.8);
    let model = Arc::clone(&s.model);
    let (sit, turn) = (s.graph.index("sit").expect("sit"), s.graph.index("turn_left").expect("turn_left"));
    let chair = model.prop_id("chair").expect("chair");
    let mut env = MetaEnv::new(Arc::clone(&s));
    let mut rng = EnvRng::seed_from_u64(3);
    let mut obs = vec![0.0; env.obs_dim()];
    env.reset(&mut rng, &mut obs);
    let mut action = [0.0; 3];
    action[0] = turn as f32;
    env.step(&action, &mut obs);
    assert_eq!(env.current(), Some(turn));
    let pl = env.world().placements()[chair];
    let mut mask = vec![false; s.skills.len()];
    // In front of the chair (its front is its +x), back to it, 2 m and then 0.5 m away.
    for (d, allowed) in [(2.0, false), (0.5, true)] {
        let (c, sn) = (pl.yaw.cos(), pl.yaw.sin());
        env.world_mut().place_standing(pl.pos[0] + d * c, pl.pos[1] + d * sn, pl.yaw);
        env.option_mask(&mut mask);
        assert_eq!(mask[sit], allowed, "sit offered {d} m from the chair: {mask:?}");
        assert!(mask[turn], "the current skill may always continue");
    }
    // Asked for at 2 m, sit is refused (the turn continues); at 0.5 m it is taken, and it
    // continues once the character is moved away.
    let (c, sn) = (pl.yaw.cos(), pl.yaw.sin());
    env.world_mut().place_standing(pl.pos[0] + 2.0 * c, pl.pos[1] + 2.0 * sn, pl.yaw);
    action[0] = sit as f32;
    env.step(&action, &mut obs);
    assert_eq!(env.current(), Some(turn), "sit 2 m from the chair is refused");
    env.world_mut().place_standing(pl.pos[0] + 0.5 * c, pl.pos[1] + 0.5 * sn, pl.yaw);
    env.step(&action, &mut obs);
    assert_eq!(env.current(), Some(sit), "sit 0.5 m from the chair is taken");
    env.world_mut().place_standing(pl.pos[0] + 2.0 * c, pl.pos[1] + 2.0 * sn, pl.yaw);
    env.option_mask(&mut mask);
    assert!(mask[sit], "a chosen sit may continue anywhere");
}

/// Options of a tiny training run into `dir/<name>`, checkpointing every 2 iterations.
fn tiny_run(dir: &Path, name: &str, iterations: usize, resume: Option<PathBuf>) -> MetaTrainOptions {
    MetaTrainOptions {
        out: dir.join(name).join("meta"),
        run_dir: dir.join(name).join("run"),
        ppo: PpoConfig {
            num_envs: 2,
            num_steps: 8,
            num_iterations: iterations,
            num_minibatches: 2,
            update_epochs: 1,
            ..PpoConfig::default()
        },
        curriculum: true,
        command: name.into(),
        resume,
        checkpoint_every: 2,
        warm_start: None,
        replace: Vec::new(),
    }
}

/// `path`'s rows without the columns that time the run.
fn untimed_rows(path: &Path) -> Vec<String> {
    let text = std::fs::read_to_string(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    let header: Vec<&str> = text.lines().next().unwrap_or_default().split(',').collect();
    let timed = |c: &str| c == "samples_per_sec" || c == "env_time_fraction";
    text.lines()
        .map(|l| l.split(',').zip(&header).filter(|(_, c)| !timed(c)).map(|(v, _)| v).collect::<Vec<_>>().join(","))
        .collect()
}

#[test]
fn a_run_resumed_from_its_checkpoint_ends_where_the_uninterrupted_run_ends() {
    // The curriculum moves on after every episode, so the resumed run must pick up its zone, window
    // and episode count to switch where the uninterrupted one does.
    let text = include_str!("../../../scenarios/sit.ron").replace("max_episodes: Some(10000)", "max_episodes: Some(1)");
    assert!(text.contains("Some(1)"), "the scenario's curriculum budget moved");
    let file = ScenarioFile::parse(Path::new("sit-fast-curriculum.ron"), text).expect("scenario");
    let model = Arc::new(WorldModel::build(file).expect("scene"));
    let graph = SkillGraph::chain(&["walk_to", "turn_left", "sit"]);
    let s = Arc::new(MetaSetup::new(model, library(), graph).expect("meta setup"));
    let dir = std::env::temp_dir().join(format!("repertoire-meta-resume-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);

    let (straight, _) = train(Arc::clone(&s), &tiny_run(&dir, "straight", 6, None)).expect("train");
    assert!(!straight.advances.is_empty(), "the curriculum moves on inside the run");
    let ckpt = |name: &str, it: usize| dir.join(name).join(format!("run/checkpoints/iter-{it:06}"));
    for it in [2, 4, 6] {
        assert!(ckpt("straight", it).with_extension("run.ron").exists(), "checkpoint {it} and its run state");
    }

    // A run that logged past its last checkpoint before it stopped: the straight run's folder,
    // continued from iteration 2.
    std::fs::create_dir_all(dir.join("resumed")).unwrap();
    std::fs::create_dir_all(dir.join("resumed/run/checkpoints")).unwrap();
    for entry in std::fs::read_dir(dir.join("straight/run")).unwrap() {
        let p = entry.unwrap().path();
        if p.is_file() {
            std::fs::copy(&p, dir.join("resumed/run").join(p.file_name().unwrap())).unwrap();
        }
    }
    for ext in ["ron", "safetensors", "run.ron"] {
        let from = ckpt("straight", 2).with_extension(ext);
        std::fs::copy(&from, ckpt("resumed", 2).with_extension(ext)).unwrap();
    }
    let (resumed, history) =
        train(Arc::clone(&s), &tiny_run(&dir, "resumed", 6, Some(ckpt("resumed", 2)))).expect("resume");
    assert_eq!(history.len(), 4, "iterations 3 to 6");
    let bytes = |name: &str| std::fs::read(dir.join(name).join("meta/meta.safetensors")).unwrap();
    assert!(bytes("resumed") == bytes("straight"), "the same weights, bit for bit");
    assert_eq!(resumed.advances, straight.advances);
    assert_eq!((resumed.samples, resumed.iterations), (straight.samples, straight.iterations));
    assert_eq!(resumed.command, "straight", "the command that started the run");
    assert_eq!(resumed.resumed, [Resume { iteration: 2, command: "resumed".into() }]);
    assert!(straight.resumed.is_empty());
    for log in ["metrics.csv", "curriculum.csv"] {
        let rows = untimed_rows(&dir.join("resumed/run").join(log));
        assert_eq!(rows, untimed_rows(&dir.join("straight/run").join(log)), "{log}: no repeated or missing rows");
        assert_eq!(rows.len(), 7, "{log}: a header and 6 iterations");
    }

    // What cannot continue is refused, naming the checkpoint's run state.
    let refused =
        |opts: MetaTrainOptions, s: &Arc<MetaSetup>| train(Arc::clone(s), &opts).expect_err("refused").to_string();
    let from = || Some(ckpt("straight", 4));
    let err = refused(MetaTrainOptions { curriculum: false, ..tiny_run(&dir, "x", 6, from()) }, &s);
    assert!(err.contains("iter-000004.run.ron") && err.contains("without --no-curriculum"), "{err}");
    let mut reseeded = tiny_run(&dir, "x", 6, from());
    reseeded.ppo.seed = 2;
    let err = refused(reseeded, &s);
    assert!(err.contains("seed: 1") && err.contains("seed: 2"), "{err}");
    let err = refused(tiny_run(&dir, "x", 3, from()), &s);
    assert!(err.contains("already 4 iterations in"), "{err}");
    let other = setup(Some(SkillGraph::chain(&["walk_to", "turn_right", "sit"])));
    let err = refused(tiny_run(&dir, "x", 6, from()), &other);
    assert!(err.contains("trained over") && err.contains("turn_left"), "{err}");
    let err = refused(tiny_run(&dir, "x", 6, Some(dir.join("straight/run/checkpoints/iter-000003"))), &s);
    assert!(err.contains("iter-000003.run.ron"), "{err}");
    // More iterations than the run had: it goes on, annealing to the new total (named here by
    // the checkpoint's manifest rather than its stem).
    let manifest = Some(ckpt("straight", 4).with_extension("ron"));
    let (longer, _) = train(Arc::clone(&s), &tiny_run(&dir, "longer", 8, manifest)).expect("extend");
    assert_eq!((longer.iterations, longer.ppo.num_iterations), (8, 8));
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn a_warm_start_begins_where_the_controller_ended_and_records_it() {
    let s = setup(Some(SkillGraph::chain(&["walk_to", "turn_left", "sit"])));
    let dir = std::env::temp_dir().join(format!("repertoire-meta-warm-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    let (first, _) = train(Arc::clone(&s), &tiny_run(&dir, "first", 2, None)).expect("train");
    let from = dir.join("first/meta");
    assert!(from.join(CRITIC_FILE).exists(), "a controller is saved with its critic");
    let warm = |name: &str, iterations: usize| MetaTrainOptions {
        warm_start: Some(from.clone()),
        curriculum: false,
        ..tiny_run(&dir, name, iterations, None)
    };
    let bytes = |name: &str, file: &str| std::fs::read(dir.join(name).join("meta").join(file)).unwrap();
    let files = ["meta.safetensors", "meta.logits.safetensors", CRITIC_FILE];

    // No iterations from it: the option and continuous networks, the observation statistics
    // and the critic exactly as they were; the manifest names where they came from.
    let (copy, history) = train(Arc::clone(&s), &warm("copy", 0)).expect("warm start");
    assert!(history.is_empty());
    for file in files {
        assert!(bytes("copy", file) == bytes("first", file), "{file} is the controller's, bit for bit");
    }
    assert_eq!((copy.iterations, copy.samples), (0, 0), "the new run counts its own");
    let record = copy.warm_start.expect("the warm start is recorded");
    assert_eq!(
        (record.from.as_str(), record.iterations, record.samples, record.critic, record.command.as_str()),
        (from.display().to_string().as_str(), 2, first.samples, true, "first")
    );
    assert!(record.retrained.is_empty(), "no skill retrained since");
    assert!(first.warm_start.is_none());

    // Trained on from there, it moves; a warm-started run resumed from its checkpoint keeps
    // the record.
    let (trained, _) = train(Arc::clone(&s), &warm("trained", 4)).expect("warm start and train");
    assert!(bytes("trained", files[0]) != bytes("first", files[0]), "training moved the weights");
    assert_eq!(trained.iterations, 4);
    let before = bytes("trained", files[0]);
    let resume = Some(dir.join("trained/run/checkpoints/iter-000002"));
    let (resumed, _) =
        train(Arc::clone(&s), &MetaTrainOptions { resume, curriculum: false, ..tiny_run(&dir, "trained", 4, None) })
            .expect("resume");
    assert_eq!(resumed.warm_start, trained.warm_start);
    assert!(bytes("trained", files[0]) == before, "resumed, it ends where it ended");
    // From a warm-started controller: its own start is kept in the record.
    let second = MetaTrainOptions { warm_start: Some(dir.join("trained/meta")), ..warm("second", 0) };
    let (second, _) = train(Arc::clone(&s), &second).expect("a second warm start");
    assert_eq!(second.total_iterations(), 4 + 2, "the whole chain's iterations");
    assert_eq!(second.iterations_label(), "6 iterations, 0 in its last run");
    assert_eq!(first.iterations_label(), "2 iterations");
    let record = second.warm_start.expect("recorded");
    assert_eq!((record.iterations, record.command.as_str()), (4, "trained"));
    assert_eq!(record.before.expect("its own start").from, from.display().to_string());

    // A controller that saved no critic: the head comes along, the value network starts fresh.
    std::fs::remove_file(from.join(CRITIC_FILE)).unwrap();
    let (fresh, _) = train(Arc::clone(&s), &warm("fresh-critic", 0)).expect("warm start without a critic");
    assert!(!fresh.warm_start.expect("recorded").critic);
    assert!(bytes("fresh-critic", files[0]) == bytes("first", files[0]));
    assert!(!dir.join("fresh-critic/meta").join(CRITIC_FILE).exists(), "an untrained critic is not saved");

    // Over a library whose turn_left was retrained since (here: the pinned checksum changed)
    // the warm start goes on, naming the skill, where loading the controller to act refuses.
    let mut pinned = load(&from, &s).expect("loads").0;
    pinned.skill_weights[1] ^= 1;
    let text = ron::ser::to_string_pretty(&pinned, ron::ser::PrettyConfig::new()).unwrap();
    std::fs::write(from.join("meta.ron"), text).unwrap();
    assert!(load(&from, &s).is_err());
    let (over, _) = train(Arc::clone(&s), &warm("retrained", 0)).expect("warm start over a retrained skill");
    assert_eq!(over.warm_start.expect("recorded").retrained, ["turn_left"]);

    // Refused: over other skills (naming the controller's manifest), and with --resume.
    let other = setup(Some(SkillGraph::chain(&["walk_to", "turn_right", "sit"])));
    let err = train(Arc::clone(&other), &warm("x", 2)).expect_err("other skills").to_string();
    assert!(err.contains("first/meta/meta.ron") && err.contains("turn_right"), "{err}");
    // Unless the other skill takes the old one's place (`--replace turn_left=turn_right`): the
    // head comes along as it was, the record names the swap and does not call it retrained.
    let swap = |old: &str| MetaTrainOptions { replace: vec![(old.into(), "turn_right".into())], ..warm("swap", 0) };
    let (swapped, _) = train(Arc::clone(&other), &swap("turn_left")).expect("warm start over a replaced skill");
    assert!(bytes("swap", files[0]) == bytes("first", files[0]));
    let record = swapped.warm_start.expect("recorded");
    assert_eq!(record.replaced, [("turn_left".to_string(), "turn_right".to_string())]);
    assert!(record.retrained.is_empty(), "{:?}", record.retrained);
    assert_eq!(swapped.skills, ["walk_to", "turn_right", "sit"]);
    let err = train(Arc::clone(&other), &swap("turn_up")).expect_err("no such skill").to_string();
    assert!(err.contains("meta.ron") && err.contains("turn_up=turn_right") && err.contains("no skill"), "{err}");
    let both = MetaTrainOptions { resume: Some(dir.join("trained/run/checkpoints/iter-000002")), ..warm("x", 4) };
    let err = train(Arc::clone(&s), &both).expect_err("both").to_string();
    assert!(err.contains("--resume") && err.contains("--warm-start"), "{err}");
    std::fs::remove_dir_all(&dir).unwrap();
}

/// A controller trained for one tiny iteration over the tests' library, in `dir/meta`.
fn tiny_controller(s: &Arc<MetaSetup>, dir: &Path) -> repertoire_learn::acting::ActingHybrid {
    let _ = std::fs::remove_dir_all(dir);
    let opts = MetaTrainOptions {
        out: dir.join("meta"),
        run_dir: dir.join("run"),
        ppo: PpoConfig { num_envs: 2, num_steps: 4, num_iterations: 1, ..repertoire_meta::train::default_ppo() },
        curriculum: false,
        command: "test".into(),
        resume: None,
        checkpoint_every: 0,
        warm_start: None,
        replace: Vec::new(),
    };
    train(Arc::clone(s), &opts).expect("train");
    load(&dir.join("meta"), s).expect("load").1
}

#[test]
fn the_lookahead_plays_out_what_its_copy_showed_and_with_one_candidate_is_the_controller() {
    use repertoire_meta::handover::distill::{DistillOptions, Teacher, distill};
    use repertoire_meta::search::lookahead::{Lookahead, LookaheadConfig};
    let s = setup(None);
    let dir = std::env::temp_dir().join(format!("repertoire-lookahead-{}", std::process::id()));
    let mut head = tiny_controller(&s, &dir);
    let zones = vec!["front".to_string(), "behind".to_string()];
    // One candidate is the controller's own decision, never searched: the same trials.
    let alone = evaluate(&s, &head, &zones, 3, 3, 5).expect("controller");
    let one = LookaheadConfig { candidates: 1, searches: 4, seed: 0, skip_known: true };
    assert_eq!(evaluate(&s, &LookingAhead { head: &head, lookahead: one }, &zones, 3, 3, 5).expect("lookahead"), alone);
    // Reproducible for a seed, and every trial the controller seats it seats too.
    let cfg = LookaheadConfig { candidates: 3, searches: 2, seed: 9, skip_known: true };
    let a = evaluate(&s, &LookingAhead { head: &head, lookahead: cfg }, &zones, 3, 3, 5).expect("lookahead");
    assert_eq!(a, evaluate(&s, &LookingAhead { head: &head, lookahead: cfg }, &zones, 3, 3, 5).expect("again"));
    for (l, c) in a.trials.iter().zip(&alone.trials) {
        assert!(l.success || !c.success, "the controller seated trial {} and the lookahead did not", c.index);
        assert!(l.simulated >= 1 && c.simulated == 0, "the search's cost is counted: {l:?}");
    }
    assert!(a.markdown().contains("search cost:") && !alone.markdown().contains("search cost:"));
    // Skipping the candidates a search can already tell (repeats of an earlier one's effect,
    // the controller's own decision the last search played out) changes no decision, only the
    // cost.
    let wide = LookaheadConfig { candidates: 6, searches: 3, seed: 2, skip_known: true };
    let skip = evaluate(&s, &LookingAhead { head: &head, lookahead: wide }, &zones, 3, 3, 5).expect("skipping");
    let every = LookaheadConfig { skip_known: false, ..wide };
    let mut all =
        evaluate(&s, &LookingAhead { head: &head, lookahead: every }, &zones, 3, 3, 5).expect("every candidate");
    let (cost, full): (u64, u64) =
        (skip.trials.iter().map(|t| t.simulated).sum(), all.trials.iter().map(|t| t.simulated).sum());
    assert!(cost < full, "skipping saves simulation: {cost} of {full} decisions");
    for (t, u) in skip.trials.iter().zip(all.trials.iter_mut()) {
        assert!(t.simulated <= u.simulated, "trial {}: {} > {}", t.index, t.simulated, u.simulated);
        u.simulated = t.simulated;
    }
    assert_eq!(skip, all, "the same trials either way");
    // The copy is exact: a candidate played in the episode, the controller after it, ends
    // exactly as its rollout said, for the controller's own first decision and a drawn one.
    for (i, drawn) in [(0u64, false), (1, true), (2, true)] {
        let mut env = MetaEnv::new(Arc::clone(&s));
        let mut look = Lookahead::new(Arc::clone(&s), &head, cfg);
        let mut rng = EnvRng::seed_from_u64(40 + i);
        let mut obs = vec![0.0; env.obs_dim()];
        let mut act = vec![0.0; env.act_dim()];
        let mut mask = vec![true; s.skills.len()];
        env.reset(&mut rng, &mut obs);
        env.option_mask(&mut mask);
        if drawn {
            head.sample(&obs, &mask, &mut rng, &mut act);
        } else {
            head.act(&obs, &mask, &mut act);
        }
        let said = look.rollout(&env.snapshot(), &act);
        assert!(said.decisions >= 1 && look.simulated == u64::from(said.decisions), "{said:?}");
        let mut decisions = 0;
        let (success, fell, seconds) = loop {
            let out = env.step(&act, &mut obs);
            decisions += 1;
            if out.terminated || out.truncated {
                break (out.terms[0] > 0.5, out.terms[2] > 0.5, f64::from(out.terms[3]));
            }
            env.option_mask(&mut mask);
            head.act(&obs, &mask, &mut act);
        };
        assert_eq!((said.success, said.fell, said.decisions, said.seconds), (success, fell, decisions, seconds));
    }
    // Expert iteration: the lookahead teaches the controller it looks ahead with, so it needs
    // one; the fit starts from it and says so.
    let mut opts = DistillOptions {
        out: dir.join("expert"),
        episodes: 2,
        zones: vec!["front".into()],
        teacher: Teacher::Lookahead(cfg),
        warm_start: None,
        successful_only: false,
        changed_weight: 1,
        epochs: 2,
        batch: 8,
        ppo: PpoConfig { num_envs: 2, ..repertoire_meta::train::default_ppo() },
        seed: 4,
        command: "test".into(),
        then_train: None,
    };
    let err = distill(Arc::clone(&s), &opts).expect_err("no controller to look ahead with");
    assert!(err.to_string().contains("warm start"), "{err}");
    opts.warm_start = Some(dir.join("meta"));
    let (manifest, f) = distill(Arc::clone(&s), &opts).expect("expert iteration");
    assert_eq!(f.episodes, 2);
    assert!(f.demonstrations >= 2 && f.losses.iter().all(|l| l.is_finite()), "{f:?}");
    assert!(f.changed <= f.demonstrations, "{f:?}");
    let from = manifest.warm_start.as_ref().expect("the fit records the controller it started from");
    assert_eq!(from.from, dir.join("meta").display().to_string());
    let (loaded, _) = load(&dir.join("expert"), &s).expect("the fitted controller loads");
    assert_eq!(loaded, manifest);
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn the_oracle_sits_only_where_the_sit_succeeds_and_readiness_needs_a_ready_decision() {
    // `meta eval --oracle-sit`: the controller's sits timed by the planner's copy. A trial
    // that ends in the sit is one the copy saw succeed, so it succeeded; evaluation stays
    // reproducible for a seed.
    use repertoire_meta::handover::readiness::{ReadinessOptions, learn};
    use repertoire_meta::search::planner::PlannerConfig;
    let s = setup(None);
    let dir = std::env::temp_dir().join(format!("repertoire-readiness-{}", std::process::id()));
    let head = tiny_controller(&s, &dir);
    let cfg = PlannerConfig { horizon: 4, repeats: 0 };
    let zones = vec!["front".to_string()];
    let a = evaluate(&s, &OracleSit { head: &head, planner: cfg }, &zones, 3, 3, 5).expect("oracle evaluation");
    let b = evaluate(&s, &OracleSit { head: &head, planner: cfg }, &zones, 3, 3, 5).expect("again");
    assert_eq!(a, b);
    for t in &a.trials {
        if t.skills.last().map(String::as_str) == Some("sit") {
            assert!(t.success, "the oracle sat where the sit failed: {t:?}");
        }
    }
    // Readiness over these barely trained skills: if no labelled decision would have seen the
    // sit succeed there is nothing to fit, and the error says so; else a classifier is written
    // that loads for this setup only.
    let ropts = ReadinessOptions {
        out: dir.join("readiness"),
        zones: zones.clone(),
        trials: 2,
        seed: 3,
        planner: cfg,
        holdout: 2,
        classifier: repertoire_learn::classify::ClassifierConfig { epochs: 2, ..Default::default() },
        threshold: 0.5,
        controller: "test".into(),
        command: "test".into(),
    };
    match learn(Arc::clone(&s), &head, &ropts) {
        Err(e) => assert!(e.to_string().contains("nothing to learn readiness from"), "{e}"),
        Ok(m) => {
            assert!(m.train.ready > 0 && m.train.decisions >= m.train.ready, "{m:?}");
            let r = repertoire_meta::handover::readiness::Readiness::load(&dir.join("readiness"), &s).expect("loads");
            assert_eq!(r.manifest, m);
            let chain = setup(Some(SkillGraph::chain(&["walk_to", "turn_left", "sit"])));
            let err =
                repertoire_meta::handover::readiness::Readiness::load(&dir.join("readiness"), &chain).err().unwrap();
            assert!(err.to_string().contains("readiness.ron"), "{err}");
        }
    }
}

#[test]
fn the_first_touch_of_the_chair_is_kept_with_the_skill_playing() {
    let s = setup(None);
    let turn = s.graph.index("turn_left").expect("turn_left");
    let chair = s.model.prop_id("chair").expect("chair");
    let mut env = MetaEnv::new(Arc::clone(&s));
    let mut obs = vec![0.0; env.obs_dim()];
    env.reset(&mut EnvRng::seed_from_u64(5), &mut obs);
    assert_eq!(env.touched, None, "spawned 1.5 m or more from the chair");
    // Standing where the chair's seat is: the body meets it at the first tick.
    let pl = env.world().placements()[chair];
    env.world_mut().place_standing(pl.pos[0], pl.pos[1] + 0.15, pl.yaw);
    let mut act = [0.0; 3];
    act[0] = turn as f32;
    env.step(&act, &mut obs);
    assert_eq!(env.touched, Some(turn), "touched while the turn played");
    act[0] = 0.0;
    env.step(&act, &mut obs);
    assert_eq!(env.touched, Some(turn), "the first touch is kept");
    // A copy of the episode (the planner's) carries it; a corrupt one is refused.
    let snap = env.snapshot();
    let mut copy = MetaEnv::new(Arc::clone(&s));
    copy.reset(&mut EnvRng::seed_from_u64(6), &mut obs);
    copy.restore(&snap).expect("restore");
    assert_eq!(copy.touched, Some(turn), "the copy knows the turn touched the chair");
    let w = env.world().snapshot_len();
    let mut bad = snap.clone();
    bad[w + 6] = 42.0;
    let err = copy.restore(&bad).expect_err("skill 42");
    assert!(
        matches!(&err, StateError::OutOfRange { what, value: 42.0, of: "skills", .. } if what.contains("touched the chair")),
        "{err}"
    );
    env.reset(&mut EnvRng::seed_from_u64(6), &mut obs);
    assert_eq!(env.touched, None, "a new episode starts untouched");
    copy.restore(&env.snapshot()).expect("restore");
    assert_eq!(copy.touched, None, "and so does its copy");
}

#[test]
fn a_bump_into_the_chair_outside_the_sit_costs_the_touch_penalty() {
    // The same decision from the same state, with and without `touch_penalty`: standing where
    // the seat is, a turn touches the chair and pays 0.5 less; the sit (terminal in the graph)
    // touches it too and pays the same; away from the chair nothing changes.
    let builtin = sit_scenario();
    let approach = "approach: Spot(ahead_m: 0.4, heading_m: 0.3)),";
    assert!(builtin.text.contains(approach), "the default sit task's approach moved");
    let text = builtin.text.replace(approach, "approach: Spot(ahead_m: 0.4, heading_m: 0.3), touch_penalty: 0.5),");
    let model = Arc::new(WorldModel::build(ScenarioFile::parse(&builtin.path, text).expect("parses")).expect("scene"));
    let graph = SkillGraph::of(&model.scenario.scenario);
    let penalised = Arc::new(MetaSetup::new(model, library(), graph).expect("meta setup"));
    assert_eq!(penalised.task.touch_penalty(), 0.5);
    let plain = setup(None);
    assert_eq!(plain.task.touch_penalty(), 0.0, "the default scenario keeps the paper's reward");
    let chair = plain.model.prop_id("chair").expect("chair");
    // The last of the decisions `skills`, started on the seat's spot (or 3 m in front of it),
    // in each setup (the sit is no start skill, so a turn plays before it).
    let reward = |s: &Arc<MetaSetup>, skills: &[&str], on_chair: bool| {
        let mut env = MetaEnv::new(Arc::clone(s));
        let mut obs = vec![0.0; env.obs_dim()];
        env.reset(&mut EnvRng::seed_from_u64(5), &mut obs);
        let pl = env.world().placements()[chair];
        let ahead = if on_chair { 0.15 } else { 3.0 };
        env.world_mut().place_standing(pl.pos[0] + ahead, pl.pos[1] + if on_chair { 0.15 } else { 0.0 }, pl.yaw);
        let mut last = 0.0;
        for skill in skills {
            let act = [s.graph.index(skill).expect("skill") as f32, 0.0, 0.0];
            let out = env.step(&act, &mut obs);
            assert_eq!(env.current(), s.graph.index(skill), "{skill} plays");
            last = out.reward;
        }
        (last, env.touched.is_some(), env.world().contacts().character_on_prop(chair))
    };
    let (turn, touched, _) = reward(&plain, &["turn_left"], true);
    assert!(touched, "the turn started on the seat's spot touches the chair");
    let (turn_penalised, ..) = reward(&penalised, &["turn_left"], true);
    assert!((turn - turn_penalised - 0.5).abs() < 1e-5, "the bump costs 0.5: {turn} against {turn_penalised}");
    let (sit, _, touching) = reward(&plain, &["turn_left", "sit"], true);
    assert!(touching, "the sit started on the seat's spot ends its decision on the chair");
    assert_eq!(sit, reward(&penalised, &["turn_left", "sit"], true).0, "the sit's touch costs nothing");
    let (away, touched, _) = reward(&plain, &["turn_left"], false);
    assert!(!touched, "3 m from the chair the turn touches nothing");
    assert_eq!(away, reward(&penalised, &["turn_left"], false).0, "no touch, no cost");
}

#[test]
fn with_a_detour_the_walks_target_goes_round_the_chair() {
    use repertoire_meta::env::detour_target;
    let builtin = sit_scenario();
    let text = builtin
        .text
        .replace("    curriculum: (", "    detour: (around: [\"chair\"], radius_m: 0.7),\n    curriculum: (");
    let file = ScenarioFile::parse(&builtin.path, text).expect("the scenario with a detour parses");
    let model = Arc::new(WorldModel::build(file).expect("scene"));
    let graph = SkillGraph::of(&model.scenario.scenario);
    let s = Arc::new(MetaSetup::new(model, library(), graph).expect("meta setup"));
    let chair = s.model.prop_id("chair").expect("chair");
    assert_eq!(s.detour, Some((vec![chair], 0.7)));
    let walk = s.graph.index("walk_to").expect("walk_to");
    let mut env = MetaEnv::new(Arc::clone(&s));
    let mut obs = vec![0.0; env.obs_dim()];
    env.reset(&mut EnvRng::seed_from_u64(7), &mut obs);
    let w = env.world().snapshot_len();
    // 2 m behind the chair, facing it: the middle action's target, 2.75 m straight ahead, lies
    // beyond the chair.
    let pl = env.world().placements()[chair];
    let (c, sn) = (pl.yaw.cos(), pl.yaw.sin());
    env.world_mut().place_standing(pl.pos[0] - 2.0 * c, pl.pos[1] - 2.0 * sn, pl.yaw);
    let p = env.world().pelvis_frame().pos;
    let yaw = env.world().heading();
    let [dx, dy] = s.skills[walk].target_offset([0.0, 0.0]);
    let straight = [p[0] + yaw.cos() * dx - yaw.sin() * dy, p[1] + yaw.sin() * dx + yaw.cos() * dy];
    let want = detour_target([p[0], p[1]], straight, [[pl.pos[0], pl.pos[1]]].into_iter(), 0.7);
    assert!((want[0] - straight[0]).hypot(want[1] - straight[1]) > 0.5, "the straight way crosses the chair");
    let mut act = [0.0; 3];
    act[0] = walk as f32;
    env.step(&act, &mut obs);
    let snap = env.snapshot();
    let got = [snap[w + 2], snap[w + 3]];
    assert!((got[0] - want[0]).abs() < 1e-9 && (got[1] - want[1]).abs() < 1e-9, "target {got:?}, wanted {want:?}");
}
