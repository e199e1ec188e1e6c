//! The shared fall test against real MuJoCo: the recorded cases it was built for (a walk_to
//! that trips and a warehouse episode that ends upside down by the pedestal, both recorded
//! `fell: false` by the old floor-only test), a body lying across a pedestal, the rule in a
//! scenario, snapshots, and the committed walk_to's trip as a skill plays it now.

mod common;

use common::{model_from, ok, repertoire, temp_dir};
use repertoire::scenes::{FallCause, Recording, ScenarioFile, World, WorldModel};
use std::path::{Path, PathBuf};
use std::sync::Arc;

fn repo(rel: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join(rel)
}

fn model_of(scenario: &str) -> Arc<WorldModel> {
    Arc::new(WorldModel::build(ScenarioFile::load(repo(scenario)).expect("scenario loads")).expect("scene builds"))
}

/// Judges a committed fixture again; returns the first frame that counts as a fall and its cause.
fn judged(fixture: &str, scenario: &str) -> (Recording, Option<(usize, FallCause)>) {
    let rec = Recording::load(&repo(&format!("tests/data/falls/{fixture}"))).expect("fixture loads");
    let mut world = World::new(model_of(scenario));
    let verdicts = world.judge(&rec).expect("the fixture is of this scene");
    assert_eq!(verdicts.len(), rec.frames());
    let first = verdicts.iter().enumerate().find_map(|(f, v)| v.map(|v| (f, v.cause)));
    // Once counted, a fall stays counted to the end of the recording.
    if let Some((f, _)) = first {
        assert!(verdicts[f..].iter().all(Option::is_some), "{fixture}: the fall latches");
    }
    (rec, first)
}

#[test]
fn the_walk_to_that_trips_is_a_fall_though_it_was_recorded_as_none() {
    let (rec, first) = judged("walk_to_trips_seed1.rec", "specs/arena.ron");
    assert_eq!(rec.first_fall(), None, "the old test recorded no fall in this clip");
    let (f, cause) = first.expect("the fall test counts the trip");
    assert_eq!(cause, FallCause::Low, "the pelvis goes below a third of its standing height");
    let pelvis = rec.pose(f, rec.header.root).0[2];
    assert!(pelvis < 0.33, "pelvis at {pelvis} m when it counted");
    // Not earlier than the pelvis went low: the walk before it is no fall.
    assert!(rec.pose(f - 5, rec.header.root).0[2] > 0.33);
}

#[test]
fn the_warehouse_episode_that_ends_upside_down_by_the_pedestal_is_a_fall() {
    let (rec, first) = judged("warehouse_headstand_on_pedestal.rec", "scenarios/warehouse.ron");
    assert_eq!(rec.first_fall(), None, "the old test recorded no fall in this clip");
    let (f, cause) = first.expect("the fall test counts the flip");
    assert_eq!(cause, FallCause::Inverted);
    let head = rec.header.bodies.iter().position(|b| b.name == "head").unwrap();
    let (h, p) = (rec.pose(f, head).0[2], rec.pose(f, rec.header.root).0[2]);
    assert!(h < p, "head {h} m under the pelvis {p} m when it counted");
    assert!(f > 60, "the first second of the clip, carrying upright, is no fall (counted at frame {f})");
}

#[test]
fn fall_check_reports_both_recorded_cases_and_cuts_a_fixture() {
    let out = ok(&repertoire(&[
        "fall-check",
        repo("tests/data/falls/warehouse_headstand_on_pedestal.rec").to_str().unwrap(),
        "--scenario",
        repo("scenarios/warehouse.ron").to_str().unwrap(),
    ]));
    assert!(out.contains("| no fall | frame 135 (7.50 s) | upside down | head |"), "{out}");
    assert!(out.contains("1 of 1 recordings fall by the fall test now (0 as recorded)"), "{out}");
    let dir = temp_dir("fall-cut");
    let cut = dir.join("cut.rec");
    let out = ok(&repertoire(&[
        "fall-check",
        repo("tests/data/falls/walk_to_trips_seed1.rec").to_str().unwrap(),
        "--scenario",
        repo("specs/arena.ron").to_str().unwrap(),
        "--last-s",
        "0.5",
        "--cut-out",
        cut.to_str().unwrap(),
    ]));
    assert!(out.contains("pelvis low"), "{out}");
    assert_eq!(Recording::load(&cut).unwrap().frames(), 30);
    // A recording of another scene is refused, naming both.
    let out = repertoire(&[
        "fall-check",
        repo("tests/data/falls/walk_to_trips_seed1.rec").to_str().unwrap(),
        "--scenario",
        repo("scenarios/warehouse.ron").to_str().unwrap(),
    ]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success() && err.contains("cannot judge it") && err.contains("warehouse"), "{err}");
}

const PEDESTAL: &str = r#"Scenario(
    name: "pedestal",
    props: [Pedestal(name: "stand", at: (x: 2.0, y: 0.0), height: 0.7)],
    spawn: [Zone(name: "near", around: "stand", radius: (1.0, 1.5), angle_deg: 0.0, facing: Toward())],
)"#;

/// Quaternion (w, x, y, z) of a rotation by `deg` about +y.
fn about_y(deg: f64) -> [f64; 4] {
    let h = deg.to_radians() / 2.0;
    [h.cos(), 0.0, h.sin(), 0.0]
}

#[test]
fn a_body_lying_across_a_pedestal_falls_by_the_prop_rule_and_one_standing_beside_it_does_not() {
    let model = model_from(PEDESTAL);
    let stand = model.prop_id("stand").unwrap();
    let mut world = model.new_world();
    world.place_standing(0.0, 0.0, 0.0);
    let top = world.placements()[stand].top;
    assert!((top - 0.7).abs() < 1e-9);
    let rest = vec![0.0; model.index.dof()];
    // Face down across the top, the trunk resting on it (the pelvis capsule, radius 0.1 m, sinks
    // 5 mm into it).
    world.set_pose([1.9, 0.0, top + 0.095], about_y(90.0), &rest).unwrap();
    let signs = world.fall_signs();
    let (part, prop) = signs.prop.expect("the trunk touches the pedestal");
    assert_eq!(prop, stand);
    assert!([model.index.pelvis, model.index.torso].contains(&part), "part {part}");
    assert!(signs.floor.is_none(), "nothing on the floor yet");
    assert!(!world.has_fallen(), "a touch is not yet a fall");
    let mut ticks = 0;
    while !world.has_fallen() && ticks < 60 {
        world.step(&rest).unwrap();
        ticks += 1;
    }
    let fall = world.fall().expect("lying on it is a fall within a second");
    assert_eq!(fall.cause, FallCause::Prop, "{fall:?}");
    assert!(ticks >= 12, "the rule waits 0.2 s (12 ticks); it counted after {ticks}");

    // Standing beside it, the thighs a few centimetres from its side, is no fall.
    world.place_standing(1.55, 0.0, 0.0);
    let signs = world.fall_signs();
    assert!(signs.prop.is_none() && signs.floor.is_none(), "{signs:?}");
    assert!(!world.has_fallen(), "placing the body again forgets the fall");
}

#[test]
fn the_rule_is_read_from_the_scenario_and_bad_values_are_refused_where_they_are() {
    let text = PEDESTAL.replace("\n)", "\n    fall: (hands_on_floor: true, prop_s: 0.5),\n)");
    let model = model_from(&text);
    assert!(model.fall_rule().hands_on_floor && model.fall_rule().prop_s == 0.5);
    assert_eq!(model.fall_rule().inverted_s, 0.3, "the rest keep their defaults");
    let bad = PEDESTAL.replace("\n)", "\n    fall: (pelvis_below: 1.2),\n)");
    let err = ScenarioFile::parse(Path::new("bad.ron"), bad).unwrap_err().to_string();
    assert!(err.contains("bad.ron") && err.contains("fall.pelvis_below") && err.contains(":5:5"), "{err}");
}

#[test]
fn a_snapshot_taken_after_a_fall_restores_the_fall() {
    let model = model_from(PEDESTAL);
    let mut world = model.new_world();
    world.place_standing(0.0, 0.0, 0.0);
    let mut standing = Vec::new();
    world.snapshot(&mut standing);
    let rest = vec![0.0; model.index.dof()];
    world.set_pose([0.0, 0.0, 0.2], about_y(90.0), &rest).unwrap();
    assert_eq!(world.fall().map(|f| f.cause), Some(FallCause::Low), "a body lying on the floor has fallen");
    let mut fallen = Vec::new();
    world.snapshot(&mut fallen);
    let mut other = model.new_world();
    other.restore(&fallen).unwrap();
    assert_eq!(other.fall(), world.fall());
    other.restore(&standing).unwrap();
    assert!(!other.has_fallen());
    // A snapshot whose fall state is bad (cause code 9) is refused and changes nothing.
    let mut bad = fallen.clone();
    let code = bad.len() - 4;
    bad[code] = 9.0;
    let err = other.restore(&bad).unwrap_err().to_string();
    assert!(err.contains("cause code 9"), "{err}");
    let mut after = Vec::new();
    other.snapshot(&mut after);
    assert_eq!(after, standing, "the refused restore left the world as it was");
}

#[test]
fn the_committed_walk_to_records_its_trip_as_a_fall() {
    let dir = temp_dir("walk-to-trip");
    let rec = dir.join("walk_to.rec");
    let out = ok(&repertoire(&[
        "skill",
        "play",
        repo("specs/walk_to.ron").to_str().unwrap(),
        "--library",
        repo("library").to_str().unwrap(),
        "--seed",
        "1",
        "--record",
        rec.to_str().unwrap(),
    ]));
    let rec = Recording::load(&rec).unwrap();
    // What the episode decided and what its recording shows agree (on this machine seed 1 trips
    // at 9.57 s, the fixture above; the policy's arithmetic may differ elsewhere).
    if out.contains("fell or dropped") {
        let (f, cause) = rec.first_fall().expect("the recording marks the fall");
        assert_eq!(f, rec.frames() - 1, "the fall ends the episode ({cause:?})");
    } else {
        assert!(out.contains("did not fall"), "{out}");
        assert_eq!(rec.first_fall(), None);
        assert_eq!(rec.frames(), 601, "a 10 s episode at 60 Hz, with its start frame");
    }
}
