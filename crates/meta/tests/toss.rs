//! The toss task against real MuJoCo: a throw arrives at the catch point's height after its
//! flight time, a ball between both hands is caught, a ball on the floor fails the episode, a
//! ball in the bucket earns reward while it stays there, and the meta environment throws a ball
//! at every reset.

use std::path::Path;
use std::sync::Arc;

use rand::SeedableRng;
use rand::rngs::StdRng;
use repertoire_learn::env::{Env, EnvRng};
use repertoire_meta::task::TOSS_TERMS;
use repertoire_meta::tasks::toss::{TossFacts, TossJudge, TossSpec};
use repertoire_meta::tasks::warehouse::place_holding;
use repertoire_meta::{EpisodeOverride, MetaEnv, MetaSetup, SkillGraph, TaskState};
use repertoire_scenes::scenario::Task;
use repertoire_scenes::{ScenarioFile, World, WorldModel};

mod support;

fn root() -> &'static Path {
    Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/../.."))
}

fn toss() -> (Arc<WorldModel>, TossSpec) {
    let file = ScenarioFile::load(root().join("scenarios/toss.ron")).expect("toss.ron");
    let model = Arc::new(WorldModel::build(file).expect("compiles"));
    let Task::Toss(t) = &model.scenario.scenario.task else { panic!("not a toss") };
    let spec = TossSpec::new(&model, t).unwrap();
    (model, spec)
}

fn hold(world: &World) -> Vec<f64> {
    let mut a = vec![0.0; world.model().index.dof()];
    world.joint_angles(&mut a);
    a
}

#[test]
fn a_throw_arrives_at_the_catch_point_height_after_its_flight_time() {
    let (model, spec) = toss();
    let mut world = model.new_world();
    let mut rng = StdRng::seed_from_u64(6);
    let dt = model.control_dt();
    for v_x in [1.5, 2.5, 3.5, 4.5] {
        world.reset_in_zone("middle", &mut rng).unwrap();
        let target = spec.target(&world);
        assert!((target[2] - 1.2).abs() < 1e-12, "aimed at 1.2 m");
        let throw = spec.launch(&mut world, &mut rng, Some((v_x, 0.0))).unwrap();
        assert_eq!((throw.v_x, throw.lateral), (v_x, 0.0));
        let d_x = (throw.pos[0] - target[0]).hypot(throw.pos[1] - target[1]);
        assert!((2.8..=3.2).contains(&d_x) && (throw.t_hit - d_x / v_x).abs() < 1e-12);
        let action = hold(&world);
        let ticks = (throw.t_hit / dt).round() as usize;
        for _ in 0..ticks {
            world.step(&action).unwrap();
        }
        let ball = world.body_position(model.props[spec.ball].body);
        // Within a tick of t_hit the ball is at the catch point: its height up to the vertical
        // distance it moves in half a tick, and over the catch point horizontally.
        let vz_hit = throw.linvel[2] - 9.81 * throw.t_hit;
        assert!((ball[2] - 1.2).abs() < 0.01 + vz_hit.abs() * dt, "v_x {v_x}: arrives at z {}", ball[2]);
        let off = (ball[0] - target[0]).hypot(ball[1] - target[1]);
        assert!(off < v_x * dt, "v_x {v_x}: {off} m from the catch point");
        assert!(!world.contacts().prop_on_floor(spec.ball));
    }
}

#[test]
fn a_ball_between_both_hands_is_caught_and_one_on_the_floor_fails() {
    let (model, spec) = toss();
    let mut world = model.new_world();
    let mut rng = StdRng::seed_from_u64(3);
    for _ in 0..3 {
        world.reset_in_zone("middle", &mut rng).unwrap();
        place_holding(&mut world, spec.ball, 0.0, 0.0, 0.2).expect("the ball fits between the hands");
        let facts = TossFacts::measure(&world, &spec);
        assert_eq!(facts.hands_on_ball, [true, true]);
        assert!(facts.caught() && !facts.failed(), "{facts:?}");
        let mut judge = TossJudge::new(3.0, 0.0, facts.to_bucket_m);
        judge.tick(&facts, model.control_dt());
        assert!(judge.caught && !judge.failed);
    }
    // Only one hand on it: not caught.
    let mut judge = TossJudge::new(3.0, 0.0, 2.0);
    let facts = TossFacts::measure(&world, &spec);
    judge.tick(&TossFacts { hands_on_ball: [true, false], ..facts }, 1.0 / 60.0);
    assert!(!judge.caught);
    // The ball dropped onto the floor.
    let r = spec.ball_radius * world.placements()[spec.ball].scale;
    world.set_free_prop(spec.ball, [1.5, 0.0, r + 0.1], [1.0, 0.0, 0.0, 0.0], [0.0; 3], [0.0; 3]).unwrap();
    let action = hold(&world);
    for _ in 0..30 {
        world.step(&action).unwrap();
        judge.tick(&TossFacts::measure(&world, &spec), 1.0 / 60.0);
    }
    let facts = TossFacts::measure(&world, &spec);
    assert!(facts.ball_on_floor && facts.failed() && !facts.caught(), "{facts:?}");
    assert!(judge.failed && judge.dropped);
}

#[test]
fn a_ball_in_the_bucket_earns_reward_while_it_stays_there() {
    let (model, spec) = toss();
    let mut world = model.new_world();
    world.reset_in_zone("middle", &mut StdRng::seed_from_u64(4)).unwrap();
    let b = world.placements()[spec.bucket].pos;
    let r = spec.ball_radius * world.placements()[spec.ball].scale;
    let start = TossFacts::measure(&world, &spec).to_bucket_m;
    let mut judge = TossJudge::new(3.0, 0.0, start);
    // Caught, then carried half-way to the bucket: shaping of 0.5 × the approach speed.
    judge.tick(&TossFacts { hands_on_ball: [true; 2], ball_on_floor: false, ..TossFacts::measure(&world, &spec) }, 0.0);
    assert!(judge.caught);
    let reward = judge.take_reward(start / 2.0, 0.5);
    assert!((f64::from(reward) - 0.5 * (start / 2.0) / 0.5).abs() < 1e-5, "{reward}");
    // Dropped into the bucket: it lands on the bucket's bottom (not the floor) and stays.
    world.set_free_prop(spec.ball, [b[0], b[1], r + 0.15], [1.0, 0.0, 0.0, 0.0], [0.0; 3], [0.0; 3]).unwrap();
    let action = hold(&world);
    let dt = model.control_dt();
    for _ in 0..60 {
        world.step(&action).unwrap();
        judge.tick(&TossFacts::measure(&world, &spec), dt);
    }
    let facts = TossFacts::measure(&world, &spec);
    assert!(facts.in_bucket && !facts.ball_on_floor && !facts.failed(), "{facts:?}");
    assert!(!judge.failed && judge.delivered());
    assert!((judge.bucket_s - 1.0).abs() < 1e-9, "in the bucket for {} s", judge.bucket_s);
    let reward = judge.take_reward(facts.to_bucket_m, 1.0);
    assert!(reward >= 1.0, "1 per second in the bucket plus the last approach: {reward}");
    // Beside the bucket on the floor: not in it.
    world.set_free_prop(spec.ball, [b[0] + 0.6, b[1], r], [1.0, 0.0, 0.0, 0.0], [0.0; 3], [0.0; 3]).unwrap();
    assert!(!TossFacts::measure(&world, &spec).in_bucket);

    // A ball knocked into the bucket without a catch (a deflection off the body) counts as
    // delivered: the task rewards the ball in the bucket however it got there, but there is no
    // approach shaping without a catch.
    world.set_free_prop(spec.ball, [b[0], b[1], r + 0.15], [1.0, 0.0, 0.0, 0.0], [0.0; 3], [0.0; 3]).unwrap();
    let mut uncaught = TossJudge::new(3.0, 0.0, start);
    for _ in 0..60 {
        world.step(&action).unwrap();
        let facts = TossFacts::measure(&world, &spec);
        assert!(!facts.caught());
        uncaught.tick(&facts, dt);
    }
    assert!(uncaught.delivered() && !uncaught.caught);
    let reward = uncaught.take_reward(0.0, 1.0);
    assert!((f64::from(reward) - uncaught.bucket_s).abs() < 1e-6, "{reward} for {} s", uncaught.bucket_s);
}

#[test]
fn the_meta_environment_throws_a_ball_at_every_reset() {
    let text = std::fs::read_to_string(root().join("scenarios/toss.ron")).unwrap();
    // Without catch and put_down, and so without the graph that starts in catch.
    let text = text
        .replace(
            r#"skills: ["walk", "turn_left", "turn_right", "catch", "put_down"]"#,
            r#"skills: ["walk", "turn_left", "turn_right"]"#,
        )
        .replace(&support::graph_block(&text), "");
    let file = ScenarioFile::parse(&root().join("scenarios/toss-walk.ron"), text).unwrap();
    let model = Arc::new(WorldModel::build(file).unwrap());
    let graph = SkillGraph::of(&model.scenario.scenario);
    let s = Arc::new(MetaSetup::new(model, &root().join("library"), graph).expect("committed skills"));
    assert_eq!(s.obs_dim(), s.layout.size + 4 + 3 + 1);
    let mut env = MetaEnv::new(Arc::clone(&s));
    assert_eq!(env.term_names(), TOSS_TERMS);
    let mut obs = vec![0.0; env.obs_dim()];
    let mut rng = EnvRng::seed_from_u64(2);
    for cell in [(1.5, -0.75), (4.5, 0.5)] {
        env.set_override(EpisodeOverride { throw: Some(cell), ..Default::default() });
        env.reset(&mut rng, &mut obs);
        let TaskState::Toss(j) = env.task() else { panic!() };
        assert_eq!(j.throw, cell);
        // The ball flies towards the walker: its velocity (heading frame) points backwards.
        let n = s.layout.size;
        assert!((f64::from(obs[n]) + cell.0).abs() < 0.2, "ball velocity {:?}", &obs[n..n + 4]);
        assert_eq!(obs[n + 3], 0.0, "not caught yet");
        let mut out = env.step(&[0.0, 0.0, 0.0], &mut obs);
        while !(out.terminated || out.truncated) {
            out = env.step(&[0.0, 0.0, 0.0], &mut obs);
        }
        // Without a catch skill the ball ends on the floor (or the walker falls).
        assert!(out.terminated && (out.terms[5] == 1.0 || out.terms[2] > 0.5), "{:?}", out.terms);
        assert_eq!(out.terms[0], 0.0, "no ball in the bucket");
    }
}
