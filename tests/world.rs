//! The world against real MuJoCo: falling, standing, sitting, props, observations, parallel steps.

mod common;

use common::{default_model, model_from};
use rand::SeedableRng;
use rand::rngs::StdRng;
use repertoire::scenes::{
    Feature, ObservationLayout, Param, ScenarioFile, ThrowSpec, World, WorldModel, step_parallel,
};
use std::sync::Arc;

fn hold(world: &World) -> Vec<f64> {
    let mut a = vec![0.0; world.model().index.dof()];
    world.joint_angles(&mut a);
    a
}

#[test]
fn an_unactuated_body_falls_and_the_fall_is_detected() {
    let mut model = WorldModel::build(ScenarioFile::builtin_default()).unwrap();
    model.disable_actuation().unwrap();
    let model = Arc::new(model);
    let mut world = model.new_world();
    world.place_standing(0.0, 0.0, 0.0);
    let action = hold(&world);
    assert!(!world.has_fallen(), "standing still at the start");
    let mut fell_at = None;
    for tick in 0..(3.0 / model.control_dt()) as usize {
        world.step(&action).unwrap();
        if world.has_fallen() {
            fell_at = Some(tick);
            break;
        }
    }
    let tick = fell_at.expect("a limp body falls within 3 s");
    assert!(world.root_height() < 0.8, "pelvis at {} m when the fall was detected", world.root_height());
    assert!(tick > 5, "the fall is not instantaneous (tick {tick})");
}

#[test]
fn pd_targets_at_the_standing_pose_keep_it_standing_for_five_seconds() {
    let model = default_model();
    let mut world = model.new_world();
    world.place_standing(0.5, -0.3, 0.7);
    let action = hold(&world);
    let start = world.body_position(model.index.pelvis);
    for _ in 0..(5.0 / model.control_dt()) as usize {
        world.step(&action).unwrap();
        assert!(!world.has_fallen(), "fell at t = {:.2} s", world.time());
    }
    assert!(world.time() >= 5.0);
    let end = world.body_position(model.index.pelvis);
    assert!(end[2] > 0.85, "pelvis height {} after 5 s", end[2]);
    let drift = ((end[0] - start[0]).powi(2) + (end[1] - start[1]).powi(2)).sqrt();
    assert!(drift < 0.05, "the standing body drifted {drift} m");
    let mut feet = [false; 2];
    world.foot_touch(1.0, &mut feet);
    assert_eq!(feet, [true, true], "both feet carry weight");
    assert!((world.heading() - 0.7).abs() < 0.05, "heading {}", world.heading());
}

/// Joint angles of a seated pose: hips flexed 90°, knees bent 60°, hands forward on the thighs.
fn seated_pose(world: &World) -> Vec<f64> {
    let idx = &world.model().index;
    idx.joints
        .iter()
        .map(|j| match j.name.as_str() {
            n if n.ends_with("hip_y") => -90f64.to_radians(),
            n if n.ends_with("knee") => 60f64.to_radians(),
            n if n.ends_with("shoulder_y") => -40f64.to_radians(),
            n if n.ends_with("elbow") => 60f64.to_radians(),
            _ => 0.0,
        })
        .collect()
}

#[test]
fn a_body_placed_seated_on_the_chair_reports_pelvis_seat_contact() {
    let model = default_model();
    let chair = model.prop_id("chair").unwrap();
    let mut world = model.new_world();
    world.reset(&mut StdRng::seed_from_u64(3), 2.0, 0.0, 0.0);
    let seat = world.placements()[chair].top;
    assert!((0.42..=0.48).contains(&seat), "seat height {seat} is drawn from the scenario's range");
    let pose = seated_pose(&world);
    // Pelvis over the seat centre, just above it, facing the chair's front (+x).
    world.set_pose([-0.04, 0.0, seat + 0.135], [1.0, 0.0, 0.0, 0.0], &pose).unwrap();
    assert!(!world.contacts().pelvis_on_prop(chair), "not touching before physics runs");
    let mut touching = 0;
    for _ in 0..(1.0 / model.control_dt()) as usize {
        world.step(&pose).unwrap();
        if world.contacts().pelvis_on_prop(chair) {
            touching += 1;
        }
    }
    let c = world.contacts();
    assert!(c.pelvis_on_prop(chair), "pelvis rests on the seat after 1 s");
    assert!(!c.fallen, "sitting is not falling");
    assert!(!world.has_fallen(), "sitting is not falling by the fall test: {:?}", world.fall());
    assert!(touching > 30, "contact held for {touching} of 60 ticks");

    // The same pose a metre away from the chair: no seat contact, and the body drops.
    world.set_pose([1.2, 0.0, seat + 0.135], [1.0, 0.0, 0.0, 0.0], &pose).unwrap();
    for _ in 0..30 {
        world.step(&pose).unwrap();
    }
    assert!(!world.contacts().pelvis_on_prop(chair));
}

const ALL_PROPS: &str = r#"Scenario(
    name: "props",
    props: [
        Pedestal(name: "stand", at: (x: 2.0, y: 0.0), height: (0.45, 0.75)),
        Box(name: "crate", on: "stand", size: (0.3, 0.3, 0.3), scale: (0.75, 1.25), mass: (2.0, 7.0)),
        Ball(name: "ball", at: (x: 0.0, y: 2.0, z: 1.0), radius: 0.12, mass: 3.0),
        Bucket(name: "bucket", at: (x: -2.0, y: 0.0)),
        Chair(name: "chair", at: (x: 0.0, y: -2.0, yaw_deg: 90.0)),
    ],
    spawn: [Zone(name: "near", around: "chair", radius: (1.0, 1.5), angle_deg: 0.0, facing: Toward())],
    task: Sit(seat: "chair"),
)"#;

#[test]
fn props_are_drawn_per_episode_and_rest_where_the_scenario_puts_them() {
    let model = model_from(ALL_PROPS);
    let [stand, crate_, ball] = ["stand", "crate", "ball"].map(|n| model.prop_id(n).unwrap());
    let mut world = model.new_world();
    let mut rng = StdRng::seed_from_u64(11);
    let mut masses = Vec::new();
    for _ in 0..4 {
        world.reset_in_zone("near", &mut rng).unwrap();
        let (p, b) = (world.placements()[stand], world.placements()[crate_]);
        assert!((0.45..=0.75).contains(&p.top));
        assert!((2.0..=7.0).contains(&b.mass) && (0.75..=1.25).contains(&b.scale));
        let body = model.props[crate_].body;
        assert!(
            (world.data().model().body_mass()[body] - b.mass).abs() < 1e-9,
            "the world's model carries the drawn mass"
        );
        masses.push(b.mass);
        // Let physics run: the crate stays on the pedestal, the ball drops onto the floor.
        let action = hold(&world);
        for _ in 0..90 {
            world.step(&action).unwrap();
        }
        let crate_z = world.body_position(model.props[crate_].body)[2];
        let expected = p.top + 0.5 * 0.3 * b.scale;
        assert!((crate_z - expected).abs() < 0.01, "crate centre at {crate_z}, expected {expected}");
        let c = world.contacts();
        assert!(c.prop_on_floor(ball), "the ball lies on the floor");
        assert!(!c.prop_on_floor(crate_), "the crate is on its pedestal");
        let resting = world.prop_contact_count(crate_, stand);
        assert!(resting >= 4, "a box resting flat on a pedestal touches it at 4+ points, got {resting}");
        assert_eq!(world.prop_contact_count(ball, stand), 0);
    }
    masses.dedup();
    assert!(masses.len() > 1, "mass is drawn per episode");
    // The shared model is untouched by a world's draws.
    let nominal = model.mj_model().body_mass()[model.props[crate_].body];
    assert!((nominal - 4.5).abs() < 1e-9, "nominal mass {nominal}");
}

#[test]
fn a_free_prop_set_in_flight_follows_its_ballistic_path() {
    let model = model_from(ALL_PROPS);
    let [stand, ball] = ["stand", "ball"].map(|n| model.prop_id(n).unwrap());
    let mut world = model.new_world();
    let mut rng = StdRng::seed_from_u64(3);
    world.reset_in_zone("near", &mut rng).unwrap();
    let spin = [0.0, 0.0, 5.0];
    world.set_free_prop(ball, [0.0, 2.0, 2.0], [0.0, 0.0, 0.0, 1.0], [2.0, 0.0, 1.0], spin).unwrap();
    let action = hold(&world);
    let dt = model.control_dt();
    let ticks = 12;
    for _ in 0..ticks {
        world.step(&action).unwrap();
    }
    let t = dt * ticks as f64;
    let p = world.body_position(model.props[ball].body);
    let expected = [2.0 * t, 2.0, 2.0 + t - 0.5 * 9.81 * t * t];
    for k in 0..3 {
        assert!((p[k] - expected[k]).abs() < 0.01, "axis {k}: {} vs {}", p[k], expected[k]);
    }
    // The spin is about world z whatever the ball's orientation (MuJoCo keeps it body-local).
    let b = model.props[ball].body;
    let cvel = world.data().cvel()[b];
    assert!((cvel[2] - 5.0).abs() < 1e-3 && cvel[0].abs() < 1e-3, "angular velocity {cvel:?}");
    let err = world.set_free_prop(stand, [0.0; 3], [1.0, 0.0, 0.0, 0.0], [0.0; 3], [0.0; 3]).unwrap_err();
    assert!(err.to_string().contains("fixed"), "{err}");
    let err = world.set_free_prop(ball, [f64::NAN, 0.0, 0.0], [1.0, 0.0, 0.0, 0.0], [0.0; 3], [0.0; 3]);
    assert!(err.is_err());
}

#[test]
fn a_drawn_throw_reaches_the_catch_point_after_its_flight_time() {
    let model = model_from(ALL_PROPS);
    let ball = model.prop_id("ball").unwrap();
    let mut world = model.new_world();
    let mut rng = StdRng::seed_from_u64(8);
    let spec = ThrowSpec::default();
    spec.validate().unwrap();
    let target = [0.0, 3.0, 1.2];
    let dt = model.control_dt();
    for k in 0..6 {
        world.reset_in_zone("near", &mut rng).unwrap();
        let throw = spec.sample(target, 0.3 * k as f64, &mut rng);
        assert!((1.5..=4.5).contains(&throw.v_x) && throw.lateral.abs() <= 0.75);
        let rise = target[2] - throw.pos[2];
        assert!((0.1..=0.4).contains(&rise), "the ball rises {rise} m over the flight");
        throw.launch(&mut world, ball).unwrap();
        let action = hold(&world);
        let ticks = (throw.t_hit / dt).round() as usize;
        for _ in 0..ticks {
            world.step(&action).unwrap();
        }
        let t = ticks as f64 * dt;
        let p = world.body_position(model.props[ball].body);
        // Arrival height: the launch height plus d_z, up to the tick rounding of t_hit.
        let vz = throw.linvel[2];
        let expected_z = throw.pos[2] + vz * t - 0.5 * 9.81 * t * t;
        assert!((p[2] - expected_z).abs() < 0.02, "throw {k}: z {} vs {expected_z}", p[2]);
        assert!((p[2] - target[2]).abs() < 0.06 + 2.0 * vz.abs() * dt, "throw {k}: arrives at z {}", p[2]);
        // Horizontally: over the catch point's line, off it sideways by lateral·t_hit.
        let along = (p[0] - target[0]) * (0.3 * k as f64).cos() + (p[1] - target[1]) * (0.3 * k as f64).sin();
        assert!(along.abs() < throw.v_x * dt + 0.01, "throw {k}: {along} m short of the catch line");
        let side = ((p[0] - target[0]).powi(2) + (p[1] - target[1]).powi(2) - along * along).max(0.0).sqrt();
        assert!((side - throw.lateral.abs() * t).abs() < 0.02, "throw {k}: sideways {side}");
    }
    let bad = ThrowSpec { v_x: Param::Fixed(0.0), ..ThrowSpec::default() };
    assert_eq!(bad.validate().unwrap_err().field, "throw.v_x");
}

#[test]
fn observations_follow_their_layout() {
    let model = default_model();
    let mut features = Feature::proprioception();
    features.push(Feature::PropPose("chair".into()));
    let layout = ObservationLayout::new(&model, &features).unwrap();
    assert_eq!(layout.size, 25 + 25 + 1 + 3 + 2 + 3 + 2 + 5);
    let mut world = model.new_world();
    world.place_standing(2.0, 0.0, std::f64::consts::PI); // 2 m in front of the chair, facing it
    let mut obs = vec![0.0f32; layout.size];
    world.observe(&layout, &mut obs);
    let at = |name: &str| layout.entries.iter().find(|e| e.name == name).unwrap().offset;
    assert!((obs[at("root_height")] - 0.958).abs() < 0.01);
    let chair = &obs[at("prop_pose:chair")..at("prop_pose:chair") + 5];
    assert!((chair[0] - 2.0).abs() < 0.01 && chair[1].abs() < 0.01, "chair 2 m straight ahead: {chair:?}");
    assert!((chair[4] + 1.0).abs() < 0.01, "the chair faces the character: {chair:?}");
    assert!(ObservationLayout::new(&model, &[Feature::PropPose("sofa".into())]).is_err());
    let other = ObservationLayout::new(&model, &Feature::proprioception()).unwrap();
    let err = layout.ensure_same(&other).unwrap_err().to_string();
    assert!(err.contains("prop_pose:chair") || err.contains("features"), "{err}");
}

#[test]
fn parallel_steps_match_serial_steps() {
    let model = default_model();
    let start = |i: usize| {
        let mut w = model.new_world();
        w.reset(&mut StdRng::seed_from_u64(i as u64), i as f64, 0.0, 0.3 * i as f64);
        w
    };
    let mut par: Vec<World> = (0..4).map(start).collect();
    let mut ser: Vec<World> = (0..4).map(start).collect();
    let dof = model.index.dof();
    let actions: Vec<f64> = (0..4 * dof).map(|k| 0.2 * ((k as f64) * 0.37).sin()).collect();
    for _ in 0..20 {
        step_parallel(&mut par, &actions).unwrap();
        for (w, a) in ser.iter_mut().zip(actions.chunks(dof)) {
            w.step(a).unwrap();
        }
    }
    for (p, s) in par.iter().zip(&ser) {
        assert_eq!(p.data().qpos(), s.data().qpos());
    }
    assert!(step_parallel(&mut par, &actions[1..]).is_err(), "a short action batch is an error");
    let mut bad = actions.clone();
    bad[3] = f64::NAN;
    let before = par[0].data().qpos().to_vec();
    let err = par[0].step(&bad[..dof]).unwrap_err().to_string();
    assert!(err.contains("action 3") && err.contains("not a finite number"), "{err}");
    assert_eq!(par[0].data().qpos(), &before[..], "a refused step leaves the world untouched");
}
