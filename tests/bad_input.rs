//! Every class of bad input gets an error naming the file and the place, never a panic.

mod common;

use common::{temp_dir, write};
use rand::SeedableRng;
use repertoire::scenes::error::FileError;
use repertoire::scenes::{BodyDef, Location, ScenarioFile, SceneError, WorldModel};

fn load(dir: &std::path::Path, text: &str) -> Result<WorldModel, SceneError> {
    let path = write(dir, "scene.ron", text);
    WorldModel::build(ScenarioFile::load(&path)?)
}

#[test]
fn ron_syntax_error_names_file_line_and_column() {
    let dir = temp_dir("syntax");
    let err = load(&dir, "Scenario(\n    name: \"x\",\n    props: [Chair(name: \"c\"\n)").err().unwrap();
    let SceneError::File(FileError::Ron { path: file, loc, .. }) = &err else {
        panic!("expected a RON error, got {err}")
    };
    assert!(file.ends_with("scene.ron"));
    assert!(loc.line >= 3, "{err}");
    assert!(err.to_string().starts_with(&format!("{}:", file.display())), "{err}");
}

#[test]
fn unknown_field_is_rejected_with_its_name_and_place() {
    let dir = temp_dir("unknown-field");
    let text = "Scenario(\n    name: \"x\",\n    rates: (physics_hz: 240, control_hz: 60, meta_hz: 2, turbo: true),\n)";
    let err = load(&dir, text).err().unwrap();
    let msg = err.to_string();
    assert!(msg.contains("unknown field `turbo`"), "{msg}");
    assert!(msg.contains("physics_hz"), "lists the expected fields: {msg}");
    let SceneError::File(FileError::Ron { loc, .. }) = err else { panic!() };
    assert_eq!(loc.line, 3, "{msg}");
}

#[test]
fn unknown_prop_reference_is_located() {
    let dir = temp_dir("unknown-prop");
    let text = "Scenario(\n  name: \"x\",\n  props: [Chair(name: \"chair\")],\n  task: Sit(seat: \"sofa\"),\n)";
    let err = load(&dir, text).err().unwrap();
    let msg = err.to_string();
    assert!(msg.contains("`sofa`") && msg.contains("props: chair"), "{msg}");
    let SceneError::Invalid { loc, .. } = err else { panic!("{msg}") };
    assert_eq!(loc, Some(Location { line: 4, col: 19 }), "{msg}");

    let zone = "Scenario(name: \"x\", props: [Chair(name: \"chair\")],\n spawn: [Zone(name: \"z\", around: \"table\", radius: 1.0, angle_deg: 0.0)])";
    let msg = load(&dir, zone).err().unwrap().to_string();
    assert!(msg.contains("zone `z`") && msg.contains("`table`") && msg.contains(":2:"), "{msg}");
}

#[test]
fn inconsistent_values_are_explained() {
    let dir = temp_dir("inconsistent");
    for (text, expect) in [
        ("Scenario(name: \"x\", rates: (physics_hz: 240, control_hz: 50, meta_hz: 2))", "must divide physics_hz"),
        ("Scenario(name: \"x\", props: [Chair(name: \"c\", seat_height: (0.5, 0.4))])", "low end above its high end"),
        ("Scenario(name: \"x\", skills: [\"walk\", \"Moon-walk\"])", "skill name `Moon-walk`"),
        ("Scenario(name: \"x\", props: [Chair(name: \"c\"), Box(name: \"c\")])", "two props are named `c`"),
        ("Scenario(name: \"x\", props: [Ball(name: \"b\"), Box(name: \"k\", on: \"b\")])", "not on ball `b`"),
        ("Scenario(name: \"x\", curriculum: (zones: [\"front\"]))", "curriculum names zone `front`"),
        (
            "Scenario(name: \"x\", props: [Chair(name: \"c\")], spawn: [Zone(name: \"z\", around: \"c\", radius: 1.0, angle_deg: 0.0)], curriculum: (zones: [\"z\"], max_episodes: Some(0)))",
            "`max_episodes` must be at least 1",
        ),
        (
            "Scenario(name: \"x\", props: [Chair(name: \"c\")], skills: [\"walk\", \"sit\"], skill_graph: (start: [\"walk\"], edges: [(\"walk\", \"sit\")], guards: [(skill: \"sit\", near: \"d\", within_m: 0.8)]))",
            "the guard on `sit` names prop `d`",
        ),
        (
            "Scenario(name: \"x\", props: [Chair(name: \"c\")], skills: [\"walk\", \"sit\"], skill_graph: (start: [\"walk\"], edges: [(\"walk\", \"sit\")], guards: [(skill: \"sit\", near: \"c\", within_m: 0.0)]))",
            "needs `within_m` > 0",
        ),
        (
            "Scenario(name: \"x\", props: [Chair(name: \"c\")], skills: [\"walk\", \"sit\"], skill_graph: (start: [\"walk\"], edges: [(\"walk\", \"sit\")], guards: [(skill: \"turn_left\", near: \"c\", within_m: 0.8)]))",
            "names `turn_left`, which `skills` does not list",
        ),
        (
            "Scenario(name: \"x\", props: [Chair(name: \"c\")], skills: [\"walk\", \"sit\"], skill_graph: (start: [\"walk\"], edges: [(\"walk\", \"sit\")], guards: [(skill: \"sit\", near: \"c\", within_m: 0.8), (skill: \"sit\", near: \"c\", within_m: 0.5)]))",
            "has two guards",
        ),
        (
            "Scenario(name: \"x\", props: [Chair(name: \"c\")], detour: (around: [\"sofa\"], radius_m: 0.7))",
            "the detour names prop `sofa`, which the scenario does not have (c)",
        ),
        (
            "Scenario(name: \"x\", props: [Chair(name: \"c\")], detour: (around: [\"c\"], radius_m: -1.0))",
            "needs `radius_m` > 0",
        ),
        ("Scenario(name: \"x\", props: [Chair(name: \"c\")], detour: (around: [], radius_m: 0.7))", "names no prop"),
    ] {
        let err = load(&dir, text).err().unwrap_or_else(|| panic!("accepted: {text}"));
        assert!(err.to_string().contains(expect), "{text}\n→ {err}");
        assert!(err.to_string().contains("scene.ron"), "{err}");
    }
}

const BODY_SCENE: &str =
    "Scenario(name: \"own\", body: Mjcf(file: \"body.xml\", map: \"body.map.ron\"), props: [Chair(name: \"chair\")])";

fn user_body(dir: &std::path::Path, xml: &str, map: &str) -> Result<WorldModel, SceneError> {
    write(dir, "body.xml", xml);
    write(dir, "body.map.ron", map);
    load(dir, BODY_SCENE)
}

#[test]
fn a_user_mjcf_body_goes_through_the_same_path() {
    let dir = temp_dir("user-body");
    let builtin = BodyDef::humanoid();
    let model =
        user_body(&dir, &builtin.mjcf, &builtin.map_text).expect("a copy of the built-in body loads as a user body");
    assert_eq!(model.index.dof(), 25);
    assert!(model.body.mjcf_path.ends_with("body.xml"));
}

#[test]
fn an_mjcf_that_mujoco_rejects_passes_on_mujocos_message() {
    let dir = temp_dir("bad-mjcf");
    let builtin = BodyDef::humanoid();
    let xml = builtin.mjcf.replace(r#"<geom name="head" type="sphere""#, r#"<geom name="head" type="spherical""#);
    let err = user_body(&dir, &xml, &builtin.map_text).err().unwrap();
    let msg = err.to_string();
    let SceneError::Mjcf { file, .. } = &err else { panic!("{msg}") };
    assert!(file.ends_with("body.xml"), "names the user's file: {msg}");
    assert!(msg.contains("line") && msg.contains("geom"), "MuJoCo's message with its line: {msg}");
}

#[test]
fn a_body_that_brings_its_own_ground_stands_on_it_and_other_clashes_name_its_line() {
    // A body file that ships its own ground plane (as many do) stands on it: the scene adds no
    // second floor under it.
    let dir = temp_dir("own-floor");
    let builtin = BodyDef::humanoid();
    let xml = builtin.mjcf.replacen(
        "<worldbody>",
        "<worldbody>\n    <geom name=\"floor\" type=\"plane\" size=\"5 5 0.1\"/>",
        1,
    );
    let model = user_body(&dir, &xml, &builtin.map_text).expect("a body with its own ground plane loads");
    assert!(model.own_floor, "the body's plane is the floor");
    let planes = model.mjcf.matches("type=\"plane\"").count();
    assert_eq!(planes, 1, "one ground plane in the scene: {planes}");
    // A geom called floor that is not a ground plane clashes with the scene's floor: the line
    // of the user's file is named.
    let xml = builtin.mjcf.replacen(
        "<worldbody>",
        "<worldbody>\n    <geom name=\"floor\" type=\"box\" size=\"0.1 0.1 0.1\" pos=\"5 5 0.1\"/>",
        1,
    );
    let line = xml.lines().position(|l| l.contains("name=\"floor\"")).unwrap() + 1;
    let msg = user_body(&dir, &xml, &builtin.map_text).err().expect("refused").to_string();
    assert!(msg.contains(&format!("body.xml:{line}:")), "{msg}");
    assert!(msg.contains("<geom name=\"floor\">") && msg.contains("rename it"), "{msg}");
    // A body (not a geom) called floor clashes with nothing: MuJoCo keeps names per kind.
    let xml = builtin.mjcf.replacen("<body name=\"head\"", "<body name=\"floor\"", 1);
    assert_ne!(xml, builtin.mjcf);
    if let Err(e) = user_body(&dir, &xml, &builtin.map_text) {
        assert!(!e.to_string().contains("has the name of a"), "{e}");
    }
}

#[test]
fn torque_motors_are_driven_as_pd_servos_and_other_actuators_refused() {
    // Joint-angle targets written into motors would collapse the body: each motor of an
    // actuated joint is driven as a PD servo from its peak torque (gain × control range × gear).
    let dir = temp_dir("motors");
    let builtin = BodyDef::humanoid();
    let mut xml = builtin.mjcf.clone();
    for knee in ["left_knee", "right_knee"] {
        let servo = format!(r#"<position name="{knee}" joint="{knee}" class="knee"/>"#);
        assert!(xml.contains(&servo), "the built-in body drives {knee} by a position servo");
        xml = xml.replace(&servo, &format!(r#"<motor name="{knee}" joint="{knee}" gear="100" ctrlrange="-3 3"/>"#));
    }
    let model = user_body(&dir, &xml, &builtin.map_text).expect("motors are driven as PD servos");
    let knees: Vec<_> = model.pd_motors.iter().map(|m| (m.joint.as_str(), m.kp, m.kv, m.max_torque)).collect();
    assert_eq!(knees, [("right_knee", 600.0, 60.0, Some(300.0)), ("left_knee", 600.0, 60.0, Some(300.0))]);
    // The knees hold the standing pose as the built-in servos do (kp 600 there too): the same
    // pelvis height after a second of holding it.
    let held = |m: WorldModel| -> f64 {
        let m = std::sync::Arc::new(m);
        let mut world = m.new_world();
        world.reset(&mut rand::rngs::StdRng::seed_from_u64(1), 0.0, 0.0, 0.0);
        let mut hold = vec![0.0; m.index.dof()];
        world.joint_angles(&mut hold);
        for _ in 0..60 {
            world.step(&hold).expect("steps");
        }
        world.root_height()
    };
    let servos = user_body(&dir, &builtin.mjcf, &builtin.map_text).expect("the built-in body");
    let (a, b) = (held(user_body(&dir, &xml, &builtin.map_text).unwrap()), held(servos));
    assert!((a - b).abs() < 0.01, "pelvis {a:.3} m with the knees as motors, {b:.3} m as servos");
    // Gains in the map win over the default.
    let map = builtin.map_text.replacen("BodyMap(", "BodyMap(\n    motor_pd: (kp: Some(400.0)),", 1);
    let model = user_body(&dir, &xml, &map).expect("map gains");
    assert!(model.pd_motors.iter().all(|m| m.kp == 400.0 && m.kv == 40.0), "{:?}", model.pd_motors);
    // A peak torque of the map's replaces the motor's own (and sets the default gains from it).
    let map = builtin.map_text.replacen("BodyMap(", "BodyMap(\n    motor_pd: (peaks: {\"left_knee\": 500.0}),", 1);
    let model = user_body(&dir, &xml, &map).expect("map peaks");
    let knee = model.pd_motors.iter().find(|m| m.joint == "left_knee").expect("the knee motor");
    assert_eq!((knee.kp, knee.max_torque), (1000.0, Some(500.0)), "{knee:?}");
    // Gains or peaks for a joint that is not actuated are refused at their line.
    let map = builtin.map_text.replacen("BodyMap(", "BodyMap(\n    motor_pd: (peaks: {\"left_kne\": 500.0}),", 1);
    let msg = user_body(&dir, &xml, &map).err().expect("refused").to_string();
    assert!(
        msg.contains("body.map.ron:4") && msg.contains("`left_kne`, which is not among the actuated_joints"),
        "{msg}"
    );
    // A motor with no range gives no peak torque to take gains from: the map must give them.
    let unlimited = xml.replace(r#"gear="100" ctrlrange="-3 3""#, r#"gear="100" ctrllimited="false""#);
    let msg = user_body(&dir, &unlimited, &builtin.map_text).err().expect("refused").to_string();
    assert!(msg.contains("body.map.ron") && msg.contains("neither a control nor a force range"), "{msg}");
    assert!(msg.contains("motor_pd"), "says what to write: {msg}");
    // A velocity servo is neither: refused, naming it and saying what to write.
    let servo = r#"<position name="left_elbow" joint="left_elbow" class="elbow"/>"#;
    assert!(builtin.mjcf.contains(servo));
    let velocity = builtin.mjcf.replace(servo, r#"<velocity name="left_elbow" joint="left_elbow" kv="10"/>"#);
    let msg = user_body(&dir, &velocity, &builtin.map_text).err().expect("refused").to_string();
    assert!(msg.contains("body.xml") && msg.contains("`left_elbow` (left_elbow)"), "{msg}");
    assert!(msg.contains("neither position servos nor torque motors") && msg.contains("<position joint="), "{msg}");
}

#[test]
fn a_floating_or_sunken_body_is_refused_saying_how_far_and_which_way() {
    // A body whose default pose holds the feet above the floor (a third-party file with its root
    // at another height) would drop at every start; one below it would start in the floor.
    let dir = temp_dir("floating");
    let builtin = BodyDef::humanoid();
    let standing = r#"<body name="pelvis" pos="0 0 0.958">"#;
    assert!(builtin.mjcf.contains(standing));
    let floating = builtin.mjcf.replace(standing, r#"<body name="pelvis" pos="0 0 1.073">"#);
    let msg = user_body(&dir, &floating, &builtin.map_text).err().expect("refused").to_string();
    assert!(msg.contains("body.xml") && msg.contains("11.6 cm above the floor") && msg.contains("lower"), "{msg}");
    assert!(msg.contains("stand_on_floor: true"), "names the other way: {msg}");
    // The map may ask for the default pose to be moved onto the floor instead.
    let map = builtin.map_text.replacen("BodyMap(", "BodyMap(\n    stand_on_floor: true,", 1);
    let model = user_body(&dir, &floating, &map).expect("moved onto the floor");
    assert!((model.lowered_by - 0.115).abs() < 0.002 && model.sole_clearance().abs() < 1e-4, "{}", model.lowered_by);
    let sunken = builtin.mjcf.replace(standing, r#"<body name="pelvis" pos="0 0 0.908">"#);
    let msg = user_body(&dir, &sunken, &builtin.map_text).err().expect("refused").to_string();
    assert!(msg.contains("4.9 cm below the floor") && msg.contains("raise"), "{msg}");
    // A centimetre is taken as standing.
    let close = builtin.mjcf.replace(standing, r#"<body name="pelvis" pos="0 0 0.968">"#);
    let model = user_body(&dir, &close, &builtin.map_text).expect("a centimetre off stands");
    assert!((model.sole_clearance() - 0.011).abs() < 0.001, "{}", model.sole_clearance());
}

#[test]
fn a_body_map_naming_a_missing_joint_is_rejected() {
    let dir = temp_dir("bad-map");
    let builtin = BodyDef::humanoid();
    let map = builtin.map_text.replace("\"left_knee\"", "\"left_kne\"");
    let err = user_body(&dir, &builtin.mjcf, &map).err().unwrap();
    let msg = err.to_string();
    let SceneError::BodyMap { file, loc, .. } = &err else { panic!("{msg}") };
    assert!(file.ends_with("body.map.ron"));
    assert!(msg.contains("`left_kne` is not a joint"), "{msg}");
    assert!(loc.is_some(), "located in the map: {msg}");

    let unmapped = builtin.map_text.replace("\"left_ankle_x\",", "");
    let msg = user_body(&dir, &builtin.mjcf, &unmapped).err().unwrap().to_string();
    assert!(msg.contains("actuator `left_ankle_x` drives no joint listed"), "{msg}");
}

#[test]
fn missing_files_are_named() {
    let dir = temp_dir("missing");
    let err = ScenarioFile::load(dir.join("nope.ron")).err().unwrap();
    assert!(matches!(err, SceneError::File(FileError::Io { .. })) && err.to_string().contains("nope.ron"), "{err}");
    let msg = load(&dir, BODY_SCENE).err().unwrap().to_string();
    assert!(msg.contains("body.xml") && msg.contains("cannot read"), "{msg}");
}

#[test]
fn the_builtin_scenario_and_the_shipped_file_agree() {
    let shipped = ScenarioFile::load(concat!(env!("CARGO_MANIFEST_DIR"), "/scenarios/sit.ron")).unwrap();
    assert_eq!(shipped.scenario, ScenarioFile::builtin_default().scenario);
}
