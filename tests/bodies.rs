//! Third-party bodies loaded as users bring them, their files untouched: Gymnasium's MuJoCo
//! humanoid (fetched from its wheel by scripts/setup.sh into third_party/bodies/, its map in
//! bodies/), and a body written without a free joint.

mod common;

use common::{temp_dir, write};
use rand::SeedableRng;
use repertoire::scenes::{BodyDef, ScenarioFile, WorldModel};

#[test]
fn gymnasiums_humanoid_loads_as_it_ships_and_holds_its_pose_under_the_pd() {
    let path = std::path::Path::new("bodies/gymnasium_humanoid.ron");
    let file = std::path::Path::new("third_party/bodies/gymnasium/humanoid.xml");
    assert!(file.exists(), "{} is missing: run scripts/setup.sh", file.display());
    let model = WorldModel::build(ScenarioFile::load(path).expect("the scenario")).expect("the body loads");
    // 17 torque motors with gears 25 to 300 and control range ±0.4: driven as PD servos.
    assert_eq!(model.index.dof(), 17);
    assert_eq!(model.pd_motors.len(), 17);
    let hip = model.pd_motors.iter().find(|m| m.joint == "left_hip_y").expect("a hip");
    assert_eq!((hip.kp, hip.kv, hip.max_torque), (240.0, 24.0, Some(120.0)), "gear 300 × 0.4 N·m peak");
    // Its own ground plane is the floor, and its root stands 10.7 cm too high in the file.
    assert!(model.own_floor);
    assert!((model.lowered_by - 0.107).abs() < 0.001 && model.sole_clearance().abs() < 1e-4, "{}", model.lowered_by);
    // Holding the standing pose, the legs stay at their targets and the body at its height while
    // it is upright. The trunk and arms sag under gravity (up to 0.17 rad): the motors are weak
    // (the abdomen's peak is 40 N·m) and the default gains soft, twice the peak torque per
    // radian, which is what its RK4 integration stays stable with (six times diverges). It
    // then tips over, after about a second: its feet are two spheres and it has no ankles, so
    // standing needs a balance controller, not a held pose.
    let model = std::sync::Arc::new(model);
    let mut world = model.new_world();
    world.reset(&mut rand::rngs::StdRng::seed_from_u64(1), 0.0, 0.0, 0.0);
    let start = world.root_height();
    let mut hold = vec![0.0f64; model.index.dof()];
    world.joint_angles(&mut hold);
    let mut now = vec![0.0f64; model.index.dof()];
    for _ in 0..30 {
        world.step(&hold).expect("steps");
    }
    world.joint_angles(&mut now);
    let error = |joint: &str| {
        let i = model.index.joints.iter().position(|j| j.name == joint).expect(joint);
        (now[i] - hold[i]).abs()
    };
    for leg in ["hip_x", "hip_z", "hip_y", "knee"] {
        for side in ["left", "right"] {
            let e = error(&format!("{side}_{leg}"));
            assert!(e < 0.05, "{side}_{leg} drifted {e:.3} rad from its target in 0.5 s");
        }
    }
    for upper in ["abdomen_y", "abdomen_z", "abdomen_x", "left_shoulder1", "right_shoulder2", "left_elbow"] {
        assert!(error(upper) < 0.2, "{upper} sagged {:.3} rad", error(upper));
    }
    assert!((world.root_height() - start).abs() < 0.02, "{start:.3} → {:.3} m", world.root_height());
    assert!(!world.has_fallen());
}

#[test]
fn a_pelvis_without_a_joint_gets_a_free_one() {
    // A body written to be attached to something (dm_control's walkers) has no free joint; a
    // map that names no root_joint gets one added on the pelvis, on the pelvis tag's own line.
    let dir = temp_dir("no-free-joint");
    let builtin = BodyDef::humanoid();
    let joint = r#"<freejoint name="root"/>"#;
    assert!(builtin.mjcf.contains(joint));
    let xml = builtin.mjcf.replace(joint, "");
    let map = builtin.map_text.replace("    root_joint: \"root\",\n", "");
    assert_ne!(map, builtin.map_text);
    write(&dir, "body.xml", &xml);
    write(&dir, "body.map.ron", &map);
    let scene = "Scenario(name: \"own\", body: Mjcf(file: \"body.xml\", map: \"body.map.ron\"))";
    write(&dir, "scene.ron", scene);
    let model = WorldModel::build(ScenarioFile::load(dir.join("scene.ron")).unwrap()).expect("loads with a free joint");
    assert!(model.body.mjcf.contains(r#"<freejoint name="repertoire/root"/>"#));
    assert_eq!(model.body.mjcf.lines().count(), xml.lines().count(), "no line added");
    assert_eq!(model.index.dof(), 25);
    // The map may also leave root_joint out when the pelvis has its own free joint.
    write(&dir, "body.xml", &builtin.mjcf);
    let model = WorldModel::build(ScenarioFile::load(dir.join("scene.ron")).unwrap()).expect("its own free joint");
    assert!(!model.body.mjcf.contains("repertoire/root"));
    // A root_joint on another part than the pelvis is refused, saying what to name instead.
    let map = builtin.map_text.replace("pelvis: \"pelvis\"", "pelvis: \"torso\"");
    assert_ne!(map, builtin.map_text);
    write(&dir, "body.map.ron", &map);
    let msg = WorldModel::build(ScenarioFile::load(dir.join("scene.ron")).unwrap()).err().expect("refused").to_string();
    assert!(msg.contains("body.map.ron") && msg.contains("is on body `pelvis`, not on the pelvis `torso`"), "{msg}");
}

#[test]
fn dm_controls_cmu_humanoid_stands_up_facing_x_as_it_ships() {
    // dm_control's CMU humanoid (fetched from the dm-control wheel by scripts/setup.sh, its map
    // in bodies/): no free joint in the file (dm_control attaches it), written y up and facing
    // +z, 56 torque motors. The map's `upright` stands it on Repertoire's axes without an edit.
    let path = std::path::Path::new("bodies/dm_control_cmu_humanoid.ron");
    let file = std::path::Path::new("third_party/bodies/dm_control/humanoid_CMU_V2020.xml");
    assert!(file.exists(), "{} is missing: run scripts/setup.sh", file.display());
    let shipped = std::fs::read_to_string(file).unwrap();
    let model = std::sync::Arc::new(
        WorldModel::build(ScenarioFile::load(path).expect("the scenario")).expect("the body loads"),
    );
    assert_eq!(model.index.dof(), 56);
    assert_eq!(model.pd_motors.len(), 56);
    // The wrapper and the free joint go on the root's own lines: MuJoCo's line numbers still
    // point into the file as it ships.
    assert_eq!(model.body.mjcf.lines().count(), shipped.lines().count());
    assert!(model.body.mjcf.contains(r#"<freejoint name="repertoire/root"/>"#));
    let m = model.mj_model();
    let id = |name: &str| m.name_to_id(mujoco_rs::prelude::MjtObjBase::mjOBJ_BODY, name).expect(name);
    assert_eq!(model.index.pelvis, id("repertoire/pelvis"));
    assert_eq!(model.index.pelvis_part, id("root"));
    let mut world = model.new_world();
    world.reset(&mut rand::rngs::StdRng::seed_from_u64(1), 0.0, 0.0, 0.0);
    let at = |name: &str| world.body_position(id(name));
    let (pelvis, head) = (at("root"), at("head"));
    assert!(head[2] - pelvis[2] > 0.4, "the head {head:?} stands over the pelvis {pelvis:?}");
    assert!(world.heading().abs() < 1e-9, "heading {}", world.heading());
    // Toes ahead of the ankles (+x), the left leg on the left (+y), the soles on the floor.
    for side in ["l", "r"] {
        let (foot, toes) = (at(&format!("{side}foot")), at(&format!("{side}toes")));
        assert!(toes[0] - foot[0] > 0.1, "{side}: toes {toes:?}, foot {foot:?}");
    }
    assert!(at("lfemur")[1] - at("rfemur")[1] > 0.15, "left hip at +y");
    assert!(model.sole_clearance().abs() < 1e-4);
    let (pitch, roll) = world.pitch_roll();
    assert!(pitch.abs() < 0.05 && roll.abs() < 0.05, "pitch {pitch}, roll {roll}");
}

#[test]
fn upright_is_refused_where_it_cannot_apply() {
    let dir = temp_dir("upright-refused");
    let builtin = BodyDef::humanoid();
    write(&dir, "body.xml", &builtin.mjcf);
    // The built-in pelvis has its own free joint: `upright` cannot wrap it.
    let map = builtin.map_text.replace("    root_joint: \"root\",\n", "    upright: Some((0.5, 0.5, 0.5, 0.5)),\n");
    assert_ne!(map, builtin.map_text);
    write(&dir, "body.map.ron", &map);
    write(&dir, "scene.ron", "Scenario(name: \"own\", body: Mjcf(file: \"body.xml\", map: \"body.map.ron\"))");
    let msg = WorldModel::build(ScenarioFile::load(dir.join("scene.ron")).unwrap()).err().expect("refused").to_string();
    assert!(msg.contains("body.map.ron") && msg.contains("`upright` needs a pelvis without joints"), "{msg}");
    // Nor with a root_joint named.
    let map = builtin.map_text.replace("BodyMap(", "BodyMap(\n    upright: Some((1.0, 0.0, 0.0, 0.0)),");
    write(&dir, "body.map.ron", &map);
    let msg = WorldModel::build(ScenarioFile::load(dir.join("scene.ron")).unwrap()).err().expect("refused").to_string();
    assert!(msg.contains("body.map.ron:4:5") && msg.contains("names a root_joint"), "{msg}");
}
