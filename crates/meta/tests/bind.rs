//! Prop binding in the meta environment against real MuJoCo and the committed library: lift and
//! put_down, trained beside a prop called "pedestal", see the warehouse's focal pedestal exactly
//! as they saw their own; the binding is read when a skill starts and held while it plays; a
//! skill observing a prop the scenario neither has nor binds is refused, located.

use std::path::Path;
use std::sync::Arc;

use repertoire_learn::env::{Env, EnvRng, StateError};
use repertoire_meta::tasks::warehouse::place_holding;
use repertoire_meta::{EpisodeOverride, MetaEnv, MetaSetup, SkillGraph, TaskState};
use repertoire_scenes::scenario::WarehousePhase;
use repertoire_scenes::world::PropMount;
use repertoire_scenes::{ObservationLayout, ScenarioFile, WorldModel};
use repertoire_skill::library;

use rand::SeedableRng;

fn root() -> &'static Path {
    Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/../.."))
}

/// The shipped warehouse with `edit` applied to its text, as if read from `name`.
fn warehouse_with(name: &str, edit: impl Fn(String) -> String) -> Arc<WorldModel> {
    let text = std::fs::read_to_string(root().join("scenarios/warehouse.ron")).unwrap();
    let file = ScenarioFile::parse(&root().join("scenarios").join(name), edit(text)).expect("variant parses");
    Arc::new(WorldModel::build(file).expect("compiles"))
}

/// `text` without its skill graph's guards (lift and put_down near the focal pedestal), for tests
/// that play those skills wherever the character stands.
fn unguarded(text: String) -> String {
    let start = text.find("        guards: [").expect("scenarios/warehouse.ron guards lift and put_down");
    let end = start + text[start..].find('\n').unwrap() + 1;
    format!("{}{}", &text[..start], &text[end..])
}

fn setup(model: Arc<WorldModel>) -> Arc<MetaSetup> {
    let graph = SkillGraph::of(&model.scenario.scenario);
    Arc::new(MetaSetup::new(model, &root().join("library"), graph).expect("the committed library fits"))
}

fn skill(s: &MetaSetup, name: &str) -> usize {
    s.skills.iter().position(|k| k.name == name).unwrap_or_else(|| panic!("no skill {name}"))
}

#[test]
fn lift_sees_the_focal_pedestal_as_it_saw_its_own() {
    // Pedestals as high as lift's training pedestal and a box of its size, so that the same
    // placement gives the same observation.
    let model = warehouse_with("warehouse-057.ron", |t| {
        t.replace("height: (0.45, 0.75)", "height: 0.57").replace("scale: (0.75, 1.25)", "scale: 1.0")
    });
    let s = setup(Arc::clone(&model));
    let (lift, put_down) = (skill(&s, "lift"), skill(&s, "put_down"));
    let pedestal_a = model.prop_id("pedestal_a").unwrap();
    let pedestal_b = model.prop_id("pedestal_b").unwrap();
    let crate_ = model.prop_id("box").unwrap();
    // lift observes PropPose("box"), PropPose("pedestal"): the box by name, the pedestal bound.
    let names: Vec<&str> = s.skills[lift].layout.prop_names().collect();
    assert_eq!(names, ["box", "pedestal"]);

    // Lift's own scene, where it was trained.
    let own = library::load(&root().join("library"), "lift").expect("lift");
    let own_file = ScenarioFile::load(root().join("specs/pedestal_box.ron")).unwrap();
    let own_model = Arc::new(WorldModel::build(own_file).unwrap());
    let own_layout = ObservationLayout::new(&own_model, &own.manifest.observation.features).unwrap();
    let mut own_world = own_model.new_world();
    let own_pedestal = own_model.prop_id("pedestal").unwrap();
    let own_box = own_model.prop_id("box").unwrap();

    let mut env = MetaEnv::new(Arc::clone(&s));
    let mut obs = vec![0.0; env.obs_dim()];
    let width = s.skills[lift].policy.obs_dim();
    let n = s.skills[lift].layout.size;
    let (mut here, mut there) = (vec![0.0; width], vec![0.0; n]);
    for seed in 0..4 {
        env.set_override(EpisodeOverride { phase: Some(WarehousePhase::Lift), ..Default::default() });
        env.reset(&mut EnvRng::seed_from_u64(seed), &mut obs);
        assert_eq!(env.bound_props(lift), [crate_, pedestal_a], "LIFT: the box's pedestal");
        env.skill_observation(lift, &mut here);

        // The same placement in lift's scene: walker, pedestal and box where they are here.
        let w = env.world();
        let f = w.pelvis_frame();
        let (x, y, yaw) = (f.pos[0], f.pos[1], f.yaw());
        let p = w.placements()[pedestal_a];
        let PropMount::Free { qpos: q, .. } = model.props[crate_].mount else { panic!("a free box") };
        let bq = &w.data().qpos()[q..q + 7];
        own_world.reset(&mut EnvRng::seed_from_u64(seed), x, y, yaw);
        own_world.move_prop(own_pedestal, p.pos[0], p.pos[1], p.yaw).unwrap();
        own_world
            .set_free_prop(own_box, [bq[0], bq[1], bq[2]], [bq[3], bq[4], bq[5], bq[6]], [0.0; 3], [0.0; 3])
            .unwrap();
        own_world.observe(&own_layout, &mut there);
        for (k, (a, o)) in here[..n].iter().zip(&there).enumerate() {
            assert!((a - o).abs() < 1e-4, "seed {seed}: value {k} is {a} in the warehouse, {o} in lift's scene");
        }
        let pose = own_layout.entries.iter().find(|e| e.name == "prop_pose:pedestal").unwrap();
        let d = here[pose.offset].hypot(here[pose.offset + 1]);
        assert!((0.3..0.6).contains(&d), "LIFT starts 0.45 m from the pedestal's centre, read {d}");

        // PUTDOWN: the same slot reads the target pedestal.
        env.set_override(EpisodeOverride { phase: Some(WarehousePhase::PutDown), ..Default::default() });
        env.reset(&mut EnvRng::seed_from_u64(seed), &mut obs);
        assert_eq!(env.bound_props(put_down), [crate_, pedestal_b], "PUTDOWN: the target pedestal");
        assert_eq!(env.bound_props(lift), [crate_, pedestal_b]);
        env.skill_observation(put_down, &mut here[..s.skills[put_down].policy.obs_dim()]);
        let rel = env.world().prop_relative(pedestal_b);
        for (k, v) in rel.iter().enumerate() {
            assert!((here[pose.offset + k] - *v as f32).abs() < 1e-5, "slot value {k}: {here:?} vs {rel:?}");
        }
    }
}

#[test]
fn a_skill_keeps_its_pedestal_while_it_plays_and_the_next_one_reads_the_new_focus() {
    let model = warehouse_with("warehouse.ron", unguarded);
    let s = setup(Arc::clone(&model));
    let (lift, put_down) = (skill(&s, "lift"), skill(&s, "put_down"));
    let pedestal_a = model.prop_id("pedestal_a").unwrap();
    let pedestal_b = model.prop_id("pedestal_b").unwrap();
    let crate_ = model.prop_id("box").unwrap();
    let mut env = MetaEnv::new(Arc::clone(&s));
    let mut obs = vec![0.0; env.obs_dim()];
    env.set_override(EpisodeOverride { phase: Some(WarehousePhase::Lift), ..Default::default() });
    env.reset(&mut EnvRng::seed_from_u64(2), &mut obs);
    // The box put into the hands 1.5 m from its pedestal: LIFT holds on the first tick.
    let at = env.world().placements()[pedestal_a].pos;
    place_holding(env.world_mut(), crate_, at[0] + 1.5, at[1], 0.0).expect("holding pose");
    env.step(&[lift as f32, 0.0, 0.0], &mut obs);
    let TaskState::Warehouse(j) = env.task() else { panic!("a warehouse") };
    assert!(j.completed >= 1 && j.phase != WarehousePhase::Lift, "LIFT completed: {j:?}");
    assert_eq!(env.task().focal_prop(&s.task), Some(pedestal_b), "CARRY's focus is the target");
    assert_eq!(env.bound_props(lift), [crate_, pedestal_a], "lift keeps the pedestal it started with");
    // Choosing put_down now binds the focus of the current phase.
    env.step(&[put_down as f32, 0.0, 0.0], &mut obs);
    assert_eq!(env.bound_props(put_down), [crate_, pedestal_b]);
    // A snapshot carries the bindings; a corrupt one is refused.
    let snap = env.snapshot();
    let mut other = MetaEnv::new(Arc::clone(&s));
    other.reset(&mut EnvRng::seed_from_u64(9), &mut obs);
    other.restore(&snap).expect("restore");
    assert_eq!(other.bound_props(lift), env.bound_props(lift));
    assert_eq!(other.bound_props(put_down), env.bound_props(put_down));
    let mut bad = snap.clone();
    *bad.last_mut().unwrap() = 99.0;
    let err = other.restore(&bad).expect_err("prop 99");
    assert!(matches!(err, StateError::OutOfRange { value: 99.0, of: "props", .. }), "{err}");
}

#[test]
fn a_skill_observing_a_prop_the_scenario_neither_has_nor_binds_is_refused() {
    let model = warehouse_with("warehouse-unbound.ron", |t| unguarded(t).replace(r#"bind: {"pedestal": Focal},"#, ""));
    assert!(model.scenario.scenario.bind.is_empty());
    let graph = SkillGraph::of(&model.scenario.scenario);
    let err = MetaSetup::new(model, &root().join("library"), graph).err().expect("refused").to_string();
    // Located at the skill in the file, naming the skill, the prop and the scenario's props.
    let line = std::fs::read_to_string(root().join("scenarios/warehouse.ron"))
        .unwrap()
        .lines()
        .position(|l| l.contains(r#""lift""#))
        .unwrap()
        + 1;
    assert!(err.contains(&format!("warehouse-unbound.ron:{line}:")), "{err}");
    assert!(err.contains("skill `lift` observes prop `pedestal`"), "{err}");
    assert!(err.contains("pedestal_a, pedestal_b, box") && err.contains(r#"bind: {"pedestal": Focal}"#), "{err}");

    // Bound to a prop the task does not move (a fixed binding) it loads, and reads that prop.
    let model = warehouse_with("warehouse-fixed.ron", |t| {
        t.replace(r#"bind: {"pedestal": Focal},"#, r#"bind: {"pedestal": Prop("pedestal_b")},"#)
    });
    let b = model.prop_id("pedestal_b").unwrap();
    let s = setup(model);
    let mut env = MetaEnv::new(Arc::clone(&s));
    let mut obs = vec![0.0; env.obs_dim()];
    env.set_override(EpisodeOverride { phase: Some(WarehousePhase::Lift), ..Default::default() });
    env.reset(&mut EnvRng::seed_from_u64(1), &mut obs);
    assert_eq!(env.bound_props(skill(&s, "lift"))[1], b);
}

#[test]
fn bind_entries_no_skill_reads_are_found() {
    // The shipped warehouse's one binding is read by lift and put_down; a misspelt key (the
    // skills observe "pedestal") is read by none, so it does nothing and is reported.
    let s = setup(warehouse_with("warehouse.ron", |t| t));
    let lift = library::load(&root().join("library"), "lift").expect("lift loads");
    let observed: Vec<&str> = repertoire_meta::bind::observed_props(&lift.manifest.observation.features).collect();
    assert!(observed.contains(&"pedestal"), "{observed:?}");
    let bind = &s.model.scenario.scenario.bind;
    assert!(repertoire_meta::bind::unused_bindings(bind, &observed).is_empty());
    let typo = warehouse_with("typo.ron", |t| {
        t.replace("bind: {\"pedestal\": Focal}", "bind: {\"pedestal\": Focal, \"pedestral\": Focal}")
    });
    let bind = &typo.scenario.scenario.bind;
    assert_eq!(repertoire_meta::bind::unused_bindings(bind, &observed), vec!["pedestral"]);
}

#[test]
fn each_skill_plays_with_its_own_grip_and_episodes_start_with_open_hands() {
    // The warehouse lists the library's carry (it grips; the other skills let go).
    let skills = r#"skills: ["walk_to", "turn_left", "turn_right", "lift", "carry", "put_down"]"#;
    let model = warehouse_with("warehouse-carry.ron", |t| {
        assert!(t.contains(skills), "scenarios/warehouse.ron no longer lists {skills}");
        unguarded(t)
    });
    let s = setup(model);
    let (carry, walk, lift) = (skill(&s, "carry"), skill(&s, "walk_to"), skill(&s, "lift"));
    assert_eq!((s.skills[carry].grip, s.skills[walk].grip, s.skills[lift].grip), (1.0, 0.0, 0.0));
    assert!(s.skills[carry].uses_target, "the library's carry steers to the controller's target");
    let mut env = MetaEnv::new(Arc::clone(&s));
    let mut obs = vec![0.0; env.obs_dim()];
    env.set_override(EpisodeOverride { phase: Some(WarehousePhase::Carry), ..Default::default() });
    env.reset(&mut EnvRng::seed_from_u64(5), &mut obs);
    assert!(env.world().has_grip());
    assert_eq!(env.world().grip(), 0.0);
    env.step(&[carry as f32, 0.0, 0.0], &mut obs);
    assert_eq!(env.world().grip(), 1.0, "carry grips while it plays");
    let snap = env.snapshot();
    env.reset(&mut EnvRng::seed_from_u64(6), &mut obs);
    assert_eq!(env.world().grip(), 0.0, "a new episode starts with open hands");
    env.restore(&snap).expect("restore");
    assert_eq!(env.world().grip(), 1.0, "a snapshot carries the grip");
    let put_down = skill(&s, "put_down");
    assert_eq!(s.skills[put_down].grip, 0.0);
    env.step(&[put_down as f32, 0.0, 0.0], &mut obs);
    assert_eq!(env.world().grip(), 0.0, "put_down (the graph's way on from carry) lets go");
}
