//! The warehouse task against real MuJoCo: each phase's success test on hand-placed states (the
//! walker near or far from a pedestal, the box in both hands, the box resting on a pedestal at
//! four or more points, the box on the floor), the phase judge's order and reward, and the meta
//! environment over the committed walk and turn skills.

mod support;

use std::path::Path;
use std::sync::Arc;

use rand::SeedableRng;
use rand::rngs::StdRng;
use repertoire_learn::env::{Env, EnvRng};
use repertoire_meta::task::WAREHOUSE_TERMS;
use repertoire_meta::tasks::warehouse::{WarehouseFacts, WarehouseJudge, WarehouseSpec, place_holding};
use repertoire_meta::{EpisodeOverride, MetaEnv, MetaSetup, SkillGraph, TaskSpec, TaskState};
use repertoire_scenes::scenario::{Task, WarehousePhase};
use repertoire_scenes::{ScenarioFile, World, WorldModel};

fn root() -> &'static Path {
    Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/../.."))
}

fn warehouse() -> Arc<WorldModel> {
    let file = ScenarioFile::load(root().join("scenarios/warehouse.ron")).expect("warehouse.ron");
    Arc::new(WorldModel::build(file).expect("compiles"))
}

fn spec(model: &WorldModel) -> WarehouseSpec {
    let Task::Warehouse(w) = &model.scenario.scenario.task else { panic!("not a warehouse") };
    WarehouseSpec::new(model, w).expect("spec")
}

fn hold(world: &World) -> Vec<f64> {
    let mut a = vec![0.0; world.model().index.dof()];
    world.joint_angles(&mut a);
    a
}

/// Where pedestal `k` (index into the spec's pedestals) stands this episode.
fn pedestal_at(world: &World, spec: &WarehouseSpec, k: usize) -> [f64; 3] {
    world.placements()[spec.pedestals[k]].pos
}

#[test]
fn goto_needs_the_pelvis_within_reach_of_the_focal_pedestal() {
    let model = warehouse();
    let spec = spec(&model);
    assert_eq!((spec.reach_m, spec.rest_contacts, spec.home), (0.65, 4, 0));
    let mut world = model.new_world();
    world.reset_in_zone("middle", &mut StdRng::seed_from_u64(1)).unwrap();
    let a = pedestal_at(&world, &spec, 0);
    for (d, near) in [(0.5, true), (0.62, true), (0.7, false), (1.5, false)] {
        world.place_standing(a[0] - d, a[1], 0.0);
        let facts = WarehouseFacts::measure(&world, &spec, 0, 1);
        assert!((facts.to_source_m - d).abs() < 1e-6, "{facts:?}");
        assert_eq!(facts.phase_done(WarehousePhase::Goto, &spec), near, "pelvis {d} m from the pedestal");
        // The same distance to the other pedestal does not count for GOTO.
        assert!(!WarehouseFacts::measure(&world, &spec, 1, 0).phase_done(WarehousePhase::Goto, &spec));
    }
}

#[test]
fn a_box_resting_on_a_pedestal_touches_it_at_four_points_and_is_not_lifted() {
    let model = warehouse();
    let spec = spec(&model);
    let mut world = model.new_world();
    let mut rng = StdRng::seed_from_u64(4);
    for _ in 0..3 {
        world.reset_in_zone("middle", &mut rng).unwrap();
        let action = hold(&world);
        for _ in 0..30 {
            world.step(&action).unwrap();
        }
        // The box rests on pedestal_a: PUTDOWN is done when a is the target, LIFT is not.
        let facts = WarehouseFacts::measure(&world, &spec, 1, 0);
        assert!(facts.target_contacts >= 4, "{facts:?}");
        assert!(facts.phase_done(WarehousePhase::PutDown, &spec));
        let facts = WarehouseFacts::measure(&world, &spec, 0, 1);
        assert!(!facts.phase_done(WarehousePhase::Lift, &spec), "the box still touches its pedestal");
        assert!(!facts.phase_done(WarehousePhase::PutDown, &spec), "not on the other pedestal");
        assert!(!facts.failed());
        // Tilted so that it rests on one edge only: fewer than four contacts, not put down.
        let p = world.body_position(model.props[spec.box_prop].body);
        let q = [0.92388, 0.38268, 0.0, 0.0]; // 45° about x
        let top = world.placements()[spec.pedestals[0]].top;
        let half = 0.15 * world.placements()[spec.box_prop].scale;
        world
            .set_free_prop(spec.box_prop, [p[0], p[1], top + half * 2f64.sqrt() - 0.002], q, [0.0; 3], [0.0; 3])
            .unwrap();
        let facts = WarehouseFacts::measure(&world, &spec, 1, 0);
        assert!((1..4).contains(&facts.target_contacts), "edge contact: {facts:?}");
        assert!(!facts.phase_done(WarehousePhase::PutDown, &spec));
    }
}

#[test]
fn a_box_held_in_both_hands_is_lifted_and_carried() {
    let model = warehouse();
    let spec = spec(&model);
    let mut world = model.new_world();
    let mut rng = StdRng::seed_from_u64(9);
    let mut scales = Vec::new();
    for _ in 0..4 {
        world.reset_in_zone("middle", &mut rng).unwrap();
        scales.push(world.placements()[spec.box_prop].scale);
        let (x, y, yaw) = (0.2, -0.1, 0.4);
        place_holding(&mut world, spec.box_prop, x, y, yaw).expect("the box fits between the hands");
        let facts = WarehouseFacts::measure(&world, &spec, 0, 1);
        assert_eq!(facts.hands_on_box, [true, true], "{facts:?}");
        assert_eq!(facts.source_contacts, 0);
        assert!(facts.phase_done(WarehousePhase::Lift, &spec), "{facts:?}");
        assert!(!facts.failed());
        // Far from the target: not carried there yet.
        assert!(!facts.phase_done(WarehousePhase::Carry, &spec));
        // The same hold next to the target pedestal completes CARRY.
        let b = pedestal_at(&world, &spec, 1);
        place_holding(&mut world, spec.box_prop, b[0] + 0.5, b[1], std::f64::consts::PI).unwrap();
        let facts = WarehouseFacts::measure(&world, &spec, 0, 1);
        assert!(facts.to_target_m < 0.65 && facts.phase_done(WarehousePhase::Carry, &spec), "{facts:?}");
        // One hand off the box (the right arm hanging): neither LIFT nor CARRY.
        let idx = &world.model().index;
        let mut pose = hold(&world);
        for (k, j) in idx.joints.iter().enumerate() {
            if j.name.starts_with("right_") && (j.name.contains("shoulder") || j.name.contains("elbow")) {
                pose[k] = 0.0;
            }
        }
        let f = world.pelvis_frame();
        let quat = world.data().qpos()[idx.root_qpos + 3..idx.root_qpos + 7].try_into().unwrap();
        world.set_pose(f.pos, quat, &pose).unwrap();
        let facts = WarehouseFacts::measure(&world, &spec, 0, 1);
        assert_eq!(facts.hands_on_box, [true, false], "{facts:?}");
        assert!(!facts.phase_done(WarehousePhase::Lift, &spec) && !facts.phase_done(WarehousePhase::Carry, &spec));
    }
    scales.dedup();
    assert!(scales.len() > 1, "boxes of several sizes were held: {scales:?}");
}

#[test]
fn a_box_on_the_floor_fails_the_episode() {
    let model = warehouse();
    let spec = spec(&model);
    let mut world = model.new_world();
    world.reset_in_zone("middle", &mut StdRng::seed_from_u64(2)).unwrap();
    let half = 0.15 * world.placements()[spec.box_prop].scale;
    world.set_free_prop(spec.box_prop, [1.0, 1.0, half + 0.05], [1.0, 0.0, 0.0, 0.0], [0.0; 3], [0.0; 3]).unwrap();
    let mut judge = WarehouseJudge::new(WarehousePhase::Goto, 0, 1);
    let action = hold(&world);
    for _ in 0..30 {
        world.step(&action).unwrap();
        judge.tick(&WarehouseFacts::measure(&world, &spec, 0, 1), &spec);
    }
    let facts = WarehouseFacts::measure(&world, &spec, 0, 1);
    assert!(facts.box_on_floor && facts.failed() && !facts.fallen, "{facts:?}");
    assert!(judge.failed && judge.dropped);
    assert_eq!((judge.completed, judge.take_reward()), (0, 0.0));
    // A failed judge completes nothing more, whatever the facts say.
    let done = WarehouseFacts { to_source_m: 0.1, box_on_floor: false, ..facts };
    assert!(!judge.tick(&done, &spec));
}

#[test]
fn the_judge_runs_the_phases_in_order_with_one_reward_each_and_swaps_pedestals() {
    let model = warehouse();
    let spec = spec(&model);
    let base = WarehouseFacts {
        to_source_m: 3.0,
        to_target_m: 3.0,
        hands_on_box: [false; 2],
        source_contacts: 4,
        target_contacts: 0,
        box_on_floor: false,
        fallen: false,
    };
    let mut j = WarehouseJudge::new(WarehousePhase::Goto, 0, 1);
    // Holding the box next to the target does nothing during GOTO: phases go in order.
    let carried = WarehouseFacts { to_target_m: 0.3, hands_on_box: [true; 2], source_contacts: 0, ..base };
    assert!(!j.tick(&carried, &spec));
    assert!(j.tick(&WarehouseFacts { to_source_m: 0.5, ..base }, &spec));
    assert_eq!((j.phase, j.focal()), (WarehousePhase::Lift, 0));
    assert!(!j.tick(&WarehouseFacts { hands_on_box: [true, false], source_contacts: 0, ..base }, &spec));
    assert!(j.tick(&WarehouseFacts { hands_on_box: [true; 2], source_contacts: 0, ..base }, &spec));
    assert_eq!((j.phase, j.focal()), (WarehousePhase::Carry, 1));
    assert!(j.tick(&carried, &spec));
    assert_eq!(j.take_reward(), 3.0, "one per completed phase");
    assert_eq!(j.take_reward(), 0.0);
    assert!(!j.tick(&WarehouseFacts { target_contacts: 3, ..base }, &spec));
    assert!(j.tick(&WarehouseFacts { target_contacts: 4, ..base }, &spec));
    assert_eq!((j.phase, j.source, j.target, j.completed), (WarehousePhase::Goto, 1, 0, 4));
    assert_eq!(j.take_reward(), 1.0);
    let mut k = j.clone();
    k.restore(&j.snapshot());
    assert_eq!(k, j);
}

/// The shipped warehouse with only the committed walk and turn skills.
fn walking_setup(start_phases: &str) -> Arc<MetaSetup> {
    let text = std::fs::read_to_string(root().join("scenarios/warehouse.ron")).unwrap();
    let skills = r#"skills: ["walk_to", "turn_left", "turn_right", "lift", "carry", "put_down"]"#;
    assert!(text.contains(skills), "scenarios/warehouse.ron no longer lists {skills}");
    let text = text
        .replace(skills, r#"skills: ["walk", "turn_left", "turn_right"]"#)
        .replace(&support::graph_block(&text), "")
        .replace("        hold_from: \"lift\",\n", "")
        .replace("start_phases: [Goto, Lift, Carry, PutDown]", &format!("start_phases: [{start_phases}]"));
    let file = ScenarioFile::parse(&root().join("scenarios/warehouse-walk.ron"), text).expect("variant");
    let model = Arc::new(WorldModel::build(file).unwrap());
    let graph = SkillGraph::of(&model.scenario.scenario);
    Arc::new(MetaSetup::new(model, &root().join("library"), graph).expect("committed walk and turns"))
}

#[test]
fn the_meta_environment_observes_the_phase_and_rewards_a_completed_goto() {
    let s = walking_setup("Goto");
    let TaskSpec::Warehouse(w) = &s.task else { panic!() };
    assert_eq!(s.obs_dim(), s.layout.size + 4 + 5 + 5 + 3 + 1);
    let mut env = MetaEnv::new(Arc::clone(&s));
    assert_eq!(env.term_names(), WAREHOUSE_TERMS);
    let mut rng = EnvRng::seed_from_u64(3);
    let mut obs = vec![0.0; env.obs_dim()];
    let n = s.layout.size;
    // An ordinary episode: GOTO, with the focal pedestal 2–4 m away in the observation.
    env.reset(&mut rng, &mut obs);
    assert_eq!(&obs[n..n + 4], [1.0, 0.0, 0.0, 0.0], "phase one-hot: GOTO");
    let d = obs[n + 4].hypot(obs[n + 5]);
    assert!((1.9..4.1).contains(&d), "focal pedestal {d} m away in the pelvis frame");
    // Started next to the box's pedestal: the first tick completes GOTO, reward 1, LIFT next.
    let home = w.pedestals[w.home];
    env.set_override(EpisodeOverride { start: Some((-0.4, 0.0, 0.3)), ..Default::default() });
    env.reset(&mut EnvRng::seed_from_u64(5), &mut obs);
    let at = env.world().placements()[home];
    let (x, y, yaw) = env.start;
    assert!(((x - at.pos[0]).hypot(y - at.pos[1]) - 0.4).abs() < 1e-9, "0.4 m from the pedestal's centre");
    let facing = (at.pos[1] - y).atan2(at.pos[0] - x);
    assert!((repertoire_scenes::math::wrap_angle(yaw - facing) - 0.3).abs() < 1e-9, "turned 0.3 rad from facing it");
    let out = env.step(&[0.0, 0.0, 0.0], &mut obs);
    assert_eq!(out.reward, 1.0, "GOTO completed");
    assert_eq!(&obs[n..n + 4], [0.0, 1.0, 0.0, 0.0], "phase one-hot: LIFT");
    let TaskState::Warehouse(j) = env.task() else { panic!() };
    assert_eq!((j.phase, j.completed), (WarehousePhase::Lift, 1));
    // Walking on with no lift skill: the episode ends by a fall, a drop or the 15 s limit,
    // reporting the phases completed.
    let mut last = out;
    while !(last.terminated || last.truncated) {
        last = env.step(&[0.0, 0.5, 0.0], &mut obs);
    }
    assert_eq!(last.terms[1], 1.0, "phases completed: {:?}", last.terms);
    assert!(last.terms[3] <= 15.0 + 0.5);
}

#[test]
fn episodes_start_in_every_phase_with_the_box_in_the_hands_for_carry_and_putdown() {
    let s = walking_setup("Goto, Lift, Carry, PutDown");
    let TaskSpec::Warehouse(w) = &s.task else { panic!() };
    let mut env = MetaEnv::new(Arc::clone(&s));
    let mut rng = EnvRng::seed_from_u64(11);
    let mut obs = vec![0.0; env.obs_dim()];
    let mut seen = std::collections::HashSet::new();
    for _ in 0..24 {
        env.reset(&mut rng, &mut obs);
        let TaskState::Warehouse(j) = env.task().clone() else { panic!() };
        seen.insert(j.phase);
        let facts = WarehouseFacts::measure(env.world(), w, j.source, j.target);
        match j.phase {
            WarehousePhase::Goto => assert!(facts.hands_on_box == [false; 2] && facts.to_source_m > 0.65),
            WarehousePhase::Lift => {
                assert!(facts.phase_done(WarehousePhase::Goto, w) && facts.hands_on_box == [false; 2]);
            }
            WarehousePhase::Carry => assert!(facts.phase_done(WarehousePhase::Lift, w), "{facts:?}"),
            WarehousePhase::PutDown => {
                assert!(facts.phase_done(WarehousePhase::Carry, w), "{facts:?}");
                assert!(!facts.phase_done(WarehousePhase::PutDown, w));
            }
        }
        assert_eq!(obs[s.layout.size + j.phase.index()], 1.0);
    }
    assert_eq!(seen.len(), 4, "every phase is drawn: {seen:?}");
}

#[test]
fn a_library_without_the_warehouse_skills_is_refused_naming_them() {
    // A library holding only walk (copied from the committed one).
    let lib = std::env::temp_dir().join(format!("repertoire-walk-only-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&lib);
    std::fs::create_dir_all(lib.join("walk")).unwrap();
    for f in std::fs::read_dir(root().join("library/walk")).unwrap() {
        let f = f.unwrap().path();
        if f.is_file() {
            std::fs::copy(&f, lib.join("walk").join(f.file_name().unwrap())).unwrap();
        }
    }
    let file = ScenarioFile::load(root().join("scenarios/warehouse.ron")).unwrap();
    let model = Arc::new(WorldModel::build(file).unwrap());
    let graph = SkillGraph::of(&model.scenario.scenario);
    let err = MetaSetup::new(model, &lib, graph).err().expect("skills are missing").to_string();
    assert!(err.contains("warehouse.ron") && err.contains("turn_left, turn_right, lift, carry, put_down"), "{err}");
    assert!(err.contains("(it has: walk)") && err.contains("--skills"), "{err}");
    let _ = std::fs::remove_dir_all(&lib);
}

#[test]
fn a_warehouse_without_spawn_zones_is_refused() {
    let text = std::fs::read_to_string(root().join("scenarios/warehouse.ron")).unwrap();
    let start = text.find("    spawn: [").unwrap();
    let end = start + text[start..].find("    ],\n").unwrap() + "    ],\n".len();
    let text = format!("{}{}", &text[..start], &text[end..]);
    let file = ScenarioFile::parse(&root().join("scenarios/no-spawn.ron"), text).unwrap();
    let model = Arc::new(WorldModel::build(file).unwrap());
    let graph = SkillGraph::of(&model.scenario.scenario).restricted(&["walk_to".to_string()]).unwrap();
    let err = MetaSetup::new(model, &root().join("library"), graph).err().expect("no zone").to_string();
    assert!(err.contains("no-spawn.ron") && err.contains("spawn zone"), "{err}");
}

#[test]
fn a_body_without_the_humanoid_arm_joints_cannot_start_holding_the_box() {
    // The built-in humanoid with its elbows renamed: the holding pose has no elbow to bend.
    let dir = std::env::temp_dir().join(format!("repertoire-forearm-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let body = repertoire_scenes::BodyDef::humanoid();
    std::fs::write(dir.join("forearm.xml"), body.mjcf.replace("_elbow\"", "_forearm\"")).unwrap();
    std::fs::write(dir.join("forearm.map.ron"), body.map_text.replace("_elbow\"", "_forearm\"")).unwrap();
    let text = std::fs::read_to_string(root().join("scenarios/warehouse.ron")).unwrap().replace(
        "body: Humanoid",
        &format!(
            "body: Mjcf(file: \"{}\", map: \"{}\")",
            dir.join("forearm.xml").display(),
            dir.join("forearm.map.ron").display()
        ),
    );
    let file = ScenarioFile::parse(&dir.join("warehouse.ron"), text.clone()).expect("the scenario parses");
    let model = WorldModel::build(file).expect("the body builds");
    let err = TaskSpec::of(&model).expect_err("CARRY starts need the arm joints").to_string();
    let line = text.lines().position(|l| l.contains("start_phases:")).unwrap() + 1;
    assert!(err.contains(&format!("warehouse.ron:{line}:")), "located at start_phases: {err}");
    assert!(err.contains("forearm.xml") && err.contains("no joint `left_elbow`"), "{err}");
    assert!(err.contains("start_phases: [Goto, Lift]"), "says what to do: {err}");
    // Starting in GOTO and LIFT only, the same body is accepted.
    let text = text.replace("start_phases: [Goto, Lift, Carry, PutDown]", "start_phases: [Goto, Lift]");
    let model = WorldModel::build(ScenarioFile::parse(&dir.join("warehouse.ron"), text).unwrap()).unwrap();
    assert!(matches!(TaskSpec::of(&model), Ok(TaskSpec::Warehouse(_))));
    let _ = std::fs::remove_dir_all(&dir);
}

/// The warehouse with `hold_from: "lift"` (CARRY and PUTDOWN start in lift's end states),
/// episodes starting in `start_phases`, over the committed library.
fn holding_setup(start_phases: &str, library: &Path) -> Result<Arc<MetaSetup>, repertoire_meta::MetaError> {
    let text = std::fs::read_to_string(root().join("scenarios/warehouse.ron")).unwrap();
    let phases = "start_phases: [Goto, Lift, Carry, PutDown],";
    assert!(text.contains(phases), "scenarios/warehouse.ron no longer holds {phases}");
    let text = text
        .replace("        hold_from: \"lift\",\n", "")
        .replace(phases, &format!("start_phases: [{start_phases}],\n        hold_from: \"lift\","));
    let file = ScenarioFile::parse(&root().join("scenarios/warehouse-hold.ron"), text).expect("variant");
    let model = Arc::new(WorldModel::build(file).unwrap());
    let graph = SkillGraph::of(&model.scenario.scenario);
    MetaSetup::new(model, library, graph).map(Arc::new)
}

#[test]
fn carry_and_putdown_can_start_in_lifts_end_states_with_the_box_fitted_between_the_hands() {
    let lib = root().join("library");
    let s = holding_setup("Carry, PutDown", &lib).expect("the committed library has lift's end states");
    let TaskSpec::Warehouse(w) = &s.task else { panic!() };
    let pool = w.hold_pool.clone().expect("hold_from's pool is loaded");
    let mut env = MetaEnv::new(Arc::clone(&s));
    let mut rng = EnvRng::seed_from_u64(21);
    let mut obs = vec![0.0; env.obs_dim()];
    let idx = &s.model.index;
    // The arm joints the fit may turn; every other joint is the pool state's.
    let arms: Vec<usize> = idx
        .joints
        .iter()
        .enumerate()
        .filter(|(_, j)| j.name.ends_with("_shoulder_x") || j.name.ends_with("_shoulder_z"))
        .map(|(k, _)| k)
        .collect();
    let mut seen = std::collections::HashSet::new();
    for _ in 0..16 {
        env.reset(&mut rng, &mut obs);
        let TaskState::Warehouse(j) = env.task().clone() else { panic!() };
        seen.insert(j.phase);
        let world = env.world();
        let facts = WarehouseFacts::measure(world, w, j.source, j.target);
        assert!(facts.phase_done(WarehousePhase::Lift, w), "{:?}: the box is held off its pedestal {facts:?}", j.phase);
        let q = hold(world);
        let from_pool = pool.states.iter().any(|st| {
            q.iter().zip(&st.joints).enumerate().all(|(k, (a, b))| arms.contains(&k) || (a - b).abs() < 1e-9)
        });
        assert!(from_pool, "{:?}: the body stands in one of lift's end states", j.phase);
        let width = 0.3 * world.placements()[w.box_prop].scale;
        let want = width - 2.0 * repertoire_skill::imitation::HOLD_SQUEEZE_M;
        assert!(
            (world.hand_gap() - want).abs() <= repertoire_skill::imitation::HOLD_FIT_TOLERANCE_M + 1e-9,
            "hands {:.3} m apart round a {width:.3} m box",
            world.hand_gap()
        );
        if j.phase == WarehousePhase::PutDown {
            assert!(facts.to_target_m < 1.0, "PUTDOWN starts by the target pedestal ({:.2} m)", facts.to_target_m);
        }
        // As if lift had just played: the scenario's graph lets only lift's successors follow,
        // and put_down's guard only within 1 m of the focal pedestal (the target's, here).
        let mut mask = vec![false; s.skills.len()];
        env.allowed_now(&mut mask);
        let allowed: Vec<&str> =
            s.skills.iter().zip(&mask).filter(|(_, m)| **m).map(|(k, _)| k.name.as_str()).collect();
        if facts.to_target_m > 1.0 {
            assert_eq!(allowed, ["lift", "carry"], "{:?}", j.phase);
        } else {
            assert_eq!(allowed, ["lift", "carry", "put_down"], "{:?}", j.phase);
        }
    }
    assert_eq!(seen.len(), 2, "both phases drawn: {seen:?}");

    // A library whose lift has no end states: refused, naming the file that is missing.
    let bare = std::env::temp_dir().join(format!("repertoire-no-lift-pool-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&bare);
    for skill in ["walk_to", "turn_left", "turn_right", "lift", "carry", "put_down"] {
        std::fs::create_dir_all(bare.join(skill)).unwrap();
        for f in std::fs::read_dir(lib.join(skill)).unwrap() {
            let f = f.unwrap().path();
            if f.is_file() && !(skill == "lift" && f.ends_with("end_poses.ron")) {
                std::fs::copy(&f, bare.join(skill).join(f.file_name().unwrap())).unwrap();
            }
        }
    }
    let err = holding_setup("Carry", &bare).err().expect("lift's pool is missing").to_string();
    assert!(err.contains("warehouse-hold.ron") && err.contains("hold_from"), "{err}");
    assert!(err.contains(&bare.join("lift").join("end_poses.ron").display().to_string()), "{err}");
    let _ = std::fs::remove_dir_all(&bare);
}
