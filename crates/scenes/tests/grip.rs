//! The hands' grip (MuJoCo adhesion actuators the scene adds when it has a free object): a box
//! touching a hand from below falls away from it with the grip off and hangs from it with the
//! grip on; scenes without a free object have no grip actuators.

use rand::SeedableRng;
use repertoire_scenes::compose::{GRIP_ACTUATORS, GRIP_FORCE_N};
use repertoire_scenes::{ScenarioFile, World, WorldModel};
use std::path::Path;
use std::sync::Arc;

const BOX_SCENE: &str = r#"Scenario(
    name: "grip_test",
    body: Humanoid,
    rates: (physics_hz: 240, control_hz: 60, meta_hz: 2),
    props: [Box(name: "box", at: (x: 3.0, y: 0.0, z: 0.0, yaw_deg: 0.0), size: (0.2, 0.2, 0.2), mass: 2.0)],
    spawn: [Zone(name: "origin", radius: (0.0, 0.1), angle_deg: (-180.0, 180.0), facing: Uniform)],
    task: Free(time_limit_s: 5.0),
    skills: ["walk"],
)"#;

/// Hangs the box under the right hand, touching it, for `ticks` control ticks with the body
/// holding its standing pose and the grip at `level`: whether the hand still touches the box,
/// and how far the box fell.
fn hang(model: &Arc<WorldModel>, level: f64, ticks: usize) -> (bool, f64) {
    let mut w = World::new(Arc::clone(model));
    w.place_standing(0.0, 0.0, 0.0);
    w.set_grip(level);
    let hand = w.body_position(model.index.hands[1]);
    let box_id = model.prop_id("box").expect("the box");
    // The hand sphere's radius is 0.045 m; the box (half height 0.1 m) touches it 1 mm deep.
    let z0 = hand[2] - 0.045 - 0.1 + 0.001;
    w.set_free_prop(box_id, [hand[0], hand[1], z0], [1.0, 0.0, 0.0, 0.0], [0.0; 3], [0.0; 3]).expect("box");
    let standing: Vec<f64> = model.index.joints.iter().map(|_| 0.0).collect();
    for _ in 0..ticks {
        w.step(&standing).expect("step");
    }
    let z = w.body_position(model.props[box_id].body)[2];
    (w.contacts().hands_on_prop(box_id)[1], z0 - z)
}

#[test]
fn a_gripping_hand_holds_what_it_touches_and_an_open_one_lets_it_fall() {
    let file = ScenarioFile::parse(Path::new("grip_test.ron"), BOX_SCENE.to_string()).expect("scene");
    let model = Arc::new(WorldModel::build(file).expect("builds"));
    assert_eq!(model.index.grip.len(), 2, "a scene with a free box has both hands' grip actuators");
    let m = model.mj_model();
    for (name, &a) in GRIP_ACTUATORS.iter().zip(&model.index.grip) {
        assert_eq!(m.id_to_name(mujoco_rs::prelude::MjtObjBase::mjOBJ_ACTUATOR, a), Some(*name));
        assert_eq!(m.actuator_gainprm()[a][0], GRIP_FORCE_N);
    }
    // 0.25 s: free fall would take the box 0.31 m down.
    let (open_touch, open_drop) = hang(&model, 0.0, 15);
    let (gripped_touch, gripped_drop) = hang(&model, 1.0, 15);
    assert!(open_drop > 0.2 && !open_touch, "with the grip off the box falls away from the hand ({open_drop:.3} m)");
    assert!(
        gripped_drop < 0.01 && gripped_touch,
        "with the grip on the box hangs from the hand ({gripped_drop:.3} m down)"
    );

    let mut w = World::new(Arc::clone(&model));
    assert_eq!(w.grip(), 0.0, "a new world's hands are open");
    w.set_grip(0.6);
    w.reset(&mut rand::rngs::StdRng::seed_from_u64(3), 0.0, 0.0, 0.0);
    assert_eq!(w.grip(), 0.6, "a reset keeps the level");
    let mut snap = Vec::new();
    w.snapshot(&mut snap);
    let mut other = World::new(Arc::clone(&model));
    other.restore(&snap).expect("restore");
    assert_eq!(other.grip(), 0.6, "a snapshot carries the grip");
    w.set_grip(3.0);
    assert_eq!(w.grip(), 1.0, "levels are clamped to [0, 1]");
    w.set_grip(f64::NAN);
    assert_eq!(w.grip(), 0.0, "a NaN level opens the hands");
}

#[test]
fn scenes_without_a_free_object_and_the_body_alone_have_no_grip() {
    let sit = Arc::new(WorldModel::build(ScenarioFile::builtin_default()).expect("sit"));
    assert!(sit.index.grip.is_empty());
    assert!(!sit.new_world().has_grip());
    let (_, body) = repertoire_scenes::body::BodyDef::humanoid().check().expect("body");
    assert!(body.grip.is_empty());
}
