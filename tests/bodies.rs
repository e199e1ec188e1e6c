//! Third-party bodies loaded as users bring them, their files untouched: Gymnasium's MuJoCo
//! humanoid (fetched from its wheel by scripts/setup.sh into third_party/bodies/, its map in
//! bodies/) holding its pose under the PD and standing under its committed balance policy, and a
//! body written without a free joint.

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

/// The held pose tips over (above); a balance policy trained on the body holds it: the committed
/// stand (`bodies/library-gymnasium/stand`, made by `recipes/bodies.ron`'s `gymnasium-stand`
/// stage) over 20 trials of 6 s (the 3 s standing clip, then its last frame held 3 s) from the
/// standing pose under the software PD: none falls, every one lasts to its end.
#[test]
fn gymnasiums_humanoid_stands_6_s_under_its_committed_balance_policy() {
    let library = std::path::Path::new("bodies/library-gymnasium");
    assert!(library.join("stand/policy.safetensors").exists(), "the committed stand is missing");
    let args = ["skill", "eval", "specs/gymnasium/stand.ron", "--library", "bodies/library-gymnasium"];
    let text = common::ok(&common::repertoire(&[&args[..], &["--trials", "20", "--no-pool"]].concat()));
    assert!(text.contains("| stand | clip start | 20 | 100.0% | 0.0% | 1.000 |"), "{text}");
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
    // The free root may be on a part the pelvis hangs from: with the head named as the pelvis,
    // the root is still the body's own (on `pelvis`), and everything below it is the character.
    let map = builtin.map_text.replace("pelvis: \"pelvis\"", "pelvis: \"head\"");
    assert_ne!(map, builtin.map_text);
    write(&dir, "body.map.ron", &map);
    let model =
        WorldModel::build(ScenarioFile::load(dir.join("scene.ron")).unwrap()).expect("the head hangs from the root");
    let id = |name: &str| model.mj_model().name_to_id(mujoco_rs::prelude::MjtObjBase::mjOBJ_BODY, name).unwrap();
    assert_eq!((model.index.root_body, model.index.pelvis), (id("pelvis"), id("head")));
    assert!(model.index.is_character[id("left_foot")]);
    // A root_joint the pelvis does not hang from (another free body in the file) is refused.
    let xml = builtin.mjcf.replacen(
        "  </worldbody>",
        "    <body name=\"ball\" pos=\"2 0 0.2\"><freejoint name=\"ball_free\"/><geom type=\"sphere\" size=\"0.1\"/></body>\n  </worldbody>",
        1,
    );
    write(&dir, "body.xml", &xml);
    write(&dir, "body.map.ron", &builtin.map_text.replace("root_joint: \"root\"", "root_joint: \"ball_free\""));
    let msg = WorldModel::build(ScenarioFile::load(dir.join("scene.ron")).unwrap()).err().expect("refused").to_string();
    assert!(
        msg.contains("body.map.ron")
            && msg.contains("is on body `ball`, and the pelvis `pelvis` does not hang from it"),
        "{msg}"
    );
}

/// The built-in humanoid re-rooted at its torso: the free joint on the torso, the pelvis its
/// child through the abdomen joints (reversed), the legs below the pelvis. The same bodies,
/// geoms and actuators; only the tree is turned over.
fn chest_rooted_humanoid() -> String {
    let xml = BodyDef::humanoid().mjcf;
    let swap = |text: String, from: &str, to: &str| {
        assert!(text.contains(from), "the built-in humanoid has `{from}`");
        text.replacen(from, to, 1)
    };
    let pelvis_open = "<body name=\"pelvis\" pos=\"0 0 0.958\">\n      <freejoint name=\"root\"/>\n      <geom name=\"pelvis\" fromto=\"0 -0.07 -0.03 0 0.07 -0.03\" size=\"0.10\" mass=\"10\"/>\n      <site name=\"pelvis\" pos=\"0 0 0\" size=\"0.02\"/>\n\n      <body name=\"torso\" pos=\"0 0 0.08\">\n        <joint name=\"abdomen_z\" type=\"hinge\" axis=\"0 0 1\" range=\"-45 45\"/>\n        <joint name=\"abdomen_y\" type=\"hinge\" axis=\"0 1 0\" range=\"-30 75\"/>\n        <joint name=\"abdomen_x\" type=\"hinge\" axis=\"1 0 0\" range=\"-35 35\"/>";
    let xml = swap(xml, pelvis_open, "<body name=\"torso\" pos=\"0 0 1.038\">\n      <freejoint name=\"root\"/>");
    let pelvis_child = "<body name=\"pelvis\" pos=\"0 0 -0.08\">\n        <joint name=\"abdomen_z\" type=\"hinge\" pos=\"0 0 0.08\" axis=\"0 0 -1\" range=\"-45 45\"/>\n        <joint name=\"abdomen_y\" type=\"hinge\" pos=\"0 0 0.08\" axis=\"0 -1 0\" range=\"-30 75\"/>\n        <joint name=\"abdomen_x\" type=\"hinge\" pos=\"0 0 0.08\" axis=\"-1 0 0\" range=\"-35 35\"/>\n        <geom name=\"pelvis\" fromto=\"0 -0.07 -0.03 0 0.07 -0.03\" size=\"0.10\" mass=\"10\"/>\n        <site name=\"pelvis\" pos=\"0 0 0\" size=\"0.02\"/>\n\n      <body name=\"right_thigh\"";
    let xml = swap(xml, "</body>\n\n      <body name=\"right_thigh\"", pelvis_child);
    swap(xml, "    </body>\n  </worldbody>", "    </body>\n    </body>\n  </worldbody>")
}

#[test]
fn a_body_whose_free_root_is_its_chest_stands_walks_and_turns_by_its_pelvis() {
    let dir = temp_dir("chest-root");
    let builtin = BodyDef::humanoid();
    write(&dir, "body.xml", &chest_rooted_humanoid());
    write(&dir, "body.map.ron", &builtin.map_text);
    write(&dir, "scene.ron", "Scenario(name: \"chest\", body: Mjcf(file: \"body.xml\", map: \"body.map.ron\"))");
    let model = std::sync::Arc::new(
        WorldModel::build(ScenarioFile::load(dir.join("scene.ron")).unwrap()).expect("a chest root loads"),
    );
    let m = model.mj_model();
    let id = |name: &str| m.name_to_id(mujoco_rs::prelude::MjtObjBase::mjOBJ_BODY, name).expect(name);
    let index = &model.index;
    assert_eq!((index.root_body, index.pelvis), (id("torso"), id("pelvis")));
    assert_eq!(index.dof(), 25);
    let said = common::ok(&common::repertoire(&["scene", "check", dir.join("scene.ron").to_str().unwrap()]));
    assert!(said.contains("root: the free joint is on `torso`; the pelvis `pelvis` hangs from it"), "{said}");
    for part in ["torso", "head", "left_hand", "pelvis", "right_foot"] {
        assert!(index.is_character[id(part)], "{part} is the character's");
    }
    let clearance = common::default_model().sole_clearance();
    assert!(
        (model.sole_clearance() - clearance).abs() < 1e-9,
        "stands as the built-in humanoid does: {}",
        model.sole_clearance()
    );
    // Held in its standing pose for half a second it stays up, its pelvis where the built-in
    // humanoid's is (the fall rule's pelvis height is the pelvis's, not the root's).
    let mut world = model.new_world();
    world.reset(&mut rand::rngs::StdRng::seed_from_u64(1), 0.0, 0.0, 0.0);
    assert!((world.root_height() - 0.958).abs() < 0.01, "pelvis at {:.3} m", world.root_height());
    let mut hold = vec![0.0f64; index.dof()];
    world.joint_angles(&mut hold);
    for _ in 0..30 {
        world.step(&hold).expect("steps");
    }
    assert!(!world.has_fallen() && world.root_height() > 0.9, "pelvis at {:.3} m", world.root_height());
    // Headings are the pelvis's: placed facing 90°, it faces 90°.
    world.place_standing(1.0, 2.0, std::f64::consts::FRAC_PI_2);
    assert!((world.heading() - std::f64::consts::FRAC_PI_2).abs() < 1e-6, "heading {}", world.heading());
    let p = world.body_position(id("pelvis"));
    assert!((p[0] - 1.0).abs() < 0.01 && (p[1] - 2.0).abs() < 0.01, "pelvis at {p:?}");
    // A CMU walk retargets onto it through the shipped map (the same body names) as onto the
    // built-in humanoid.
    let body = repertoire_clip::ClipBody::from_arg(dir.join("scene.ron").to_str().unwrap()).expect("the clip body");
    let source = repertoire_clip::ClipSource::from_path(
        std::path::Path::new("mocap/cmu-subject16-30fps/16_17_walk_90deg_left_turn.bvh"),
        None,
    )
    .unwrap();
    let options = repertoire_clip::RetargetOptions::default();
    let chest = repertoire_clip::check(&source, &body, None, None, &options).expect("retargets");
    let built_in =
        repertoire_clip::check(&source, &repertoire_clip::ClipBody::humanoid().unwrap(), None, None, &options).unwrap();
    let (mean, _) = chest.error_cm.unwrap();
    assert!(mean < 2.0 * built_in.error_cm.unwrap().0.max(1.0), "key-point error {mean:.2} cm");
    let turn = chest.motion.heading_change_deg;
    assert!((turn - built_in.motion.heading_change_deg).abs() < 5.0, "turns {turn:.1}°");
    // Played and recorded, its motion exports as BVH from its root, the torso.
    let clip = dir.join("turn.clip.ron");
    chest.clip.save(&clip).unwrap();
    let scene = dir.join("scene.ron");
    let rec = dir.join("turn.rec");
    let bvh = dir.join("turn.bvh");
    for args in [
        ["clip", "play", clip.to_str().unwrap(), "--scene", scene.to_str().unwrap(), "--record", rec.to_str().unwrap()],
        ["export", rec.to_str().unwrap(), "--bvh", bvh.to_str().unwrap(), "", "", ""],
    ] {
        let args: Vec<&str> = args.into_iter().filter(|a| !a.is_empty()).collect();
        common::ok(&common::repertoire(&args));
    }
    let text = std::fs::read_to_string(&bvh).unwrap();
    assert!(text.contains("ROOT torso") && text.contains("JOINT pelvis"), "{}", &text[..200.min(text.len())]);
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
    // The gains and peak torques of dm_control's position-controlled variant, over the file's
    // weaker motors (the ankle's gear is 20).
    let ankle = model.pd_motors.iter().find(|m| m.joint == "lfootrx").expect("an ankle");
    assert_eq!((ankle.kp, ankle.kv, ankle.max_torque), (120.0, 6.0, Some(120.0)));
    // The wrapper and the free joint go on the root's own lines: MuJoCo's line numbers still
    // point into the file as it ships.
    assert_eq!(model.body.mjcf.lines().count(), shipped.lines().count());
    assert!(model.body.mjcf.contains(r#"<freejoint name="repertoire/root"/>"#));
    let said = common::ok(&common::repertoire(&["scene", "check", path.to_str().unwrap()]));
    assert!(
        said.contains("root: free joint `repertoire/root` added (the file has none) on `repertoire/pelvis`"),
        "{said}"
    );
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
