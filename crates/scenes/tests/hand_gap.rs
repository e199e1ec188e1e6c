//! Fitting the arms to an object's width: `World::fit_hand_gap` spreads or closes both arms at
//! the shoulders until the hands' surfaces are the asked gap apart, and leaves the rest of the
//! body (root, other joints, velocities) as it was.

use std::path::Path;
use std::sync::Arc;

use repertoire_scenes::{ScenarioFile, World, WorldModel};

const SCENE: &str = r#"Scenario(
    name: "hand_gap_test",
    body: Humanoid,
    rates: (physics_hz: 240, control_hz: 60, meta_hz: 2),
    props: [],
    spawn: [Zone(name: "origin", radius: (0.0, 0.1), angle_deg: (-180.0, 180.0), facing: Uniform)],
    task: Free(time_limit_s: 5.0),
    skills: ["walk"],
)"#;

/// Stands the body with both arms held forward and bent (carry's arm pose), moving.
fn holding_pose(model: &Arc<WorldModel>) -> World {
    let mut w = World::new(Arc::clone(model));
    let idx = &model.index;
    let mut q: Vec<f64> = idx.joints.iter().map(|_| 0.0).collect();
    let mut v: Vec<f64> = (0..q.len()).map(|k| 0.1 * (k as f64).sin()).collect();
    for (name, deg) in [
        ("left_shoulder_y", -45.0),
        ("right_shoulder_y", -45.0),
        ("left_shoulder_x", -7.0),
        ("right_shoulder_x", 7.0),
        ("left_elbow", 55.0),
        ("right_elbow", 55.0),
    ] {
        let k = idx.joints.iter().position(|j| j.name == name).unwrap_or_else(|| panic!("no joint {name}"));
        q[k] = f64::to_radians(deg);
        v[k] = 0.0;
    }
    w.set_motion([0.3, -0.2, 0.95], [1.0, 0.0, 0.0, 0.0], &q, [0.5, 0.0, 0.0, 0.0, 0.0, 0.1], Some(&v)).expect("pose");
    w
}

#[test]
fn the_arms_spread_or_close_to_the_asked_gap_and_nothing_else_moves() {
    let file = ScenarioFile::parse(Path::new("hand_gap_test.ron"), SCENE.to_string()).expect("scene");
    let model = Arc::new(WorldModel::build(file).expect("builds"));
    let idx = &model.index;
    let pair = |axis: &str| -> Vec<usize> {
        let names = [format!("left_shoulder_{axis}"), format!("right_shoulder_{axis}")];
        names.iter().map(|n| idx.joints.iter().position(|j| &j.name == n).expect("shoulder joint")).collect()
    };
    let shoulders: Vec<usize> = [pair("z"), pair("x")].concat();
    let natural = holding_pose(&model).hand_gap();
    assert!((0.2..0.35).contains(&natural), "carry's arm pose leaves the hands {natural:.3} m apart");
    for gap in [natural - 0.08, natural - 0.03, natural + 0.03, natural + 0.08] {
        let mut w = holding_pose(&model);
        let (mut q0, mut v0) = (vec![0.0; idx.dof()], vec![0.0; idx.dof()]);
        w.joint_angles(&mut q0);
        w.joint_velocities(&mut v0);
        let root0 = w.pelvis_frame().pos;
        let left = w.fit_hand_gap(gap).expect("the humanoid has both shoulder_x joints");
        assert!(left.abs() < 0.003, "asked {gap:.3} m, {left:+.4} m off");
        assert!((w.hand_gap() - gap).abs() < 0.003, "the hands are {:.3} m apart, asked {gap:.3}", w.hand_gap());
        let (mut q, mut v) = (vec![0.0; idx.dof()], vec![0.0; idx.dof()]);
        w.joint_angles(&mut q);
        w.joint_velocities(&mut v);
        for k in 0..q.len() {
            if !shoulders.contains(&k) {
                assert_eq!(q[k], q0[k], "joint {} moved", idx.joints[k].name);
            }
            assert_eq!(v[k], v0[k], "joint {}'s velocity changed", idx.joints[k].name);
        }
        // Mirrored: each pair of shoulder joints turned by the same amount, in opposite senses.
        for p in [&shoulders[0..2], &shoulders[2..4]] {
            let (dl, dr) = (q[p[0]] - q0[p[0]], q[p[1]] - q0[p[1]]);
            assert!((dl + dr).abs() < 1e-9, "shoulder turns {dl:+.4} / {dr:+.4}");
        }
        assert!(shoulders.iter().any(|&k| (q[k] - q0[k]).abs() > 1e-3), "the arms moved");
        assert_eq!(w.pelvis_frame().pos, root0, "the root stays");
        // The PD targets follow: a step without new targets keeps the fitted arms.
        let hold: Vec<f64> = q.clone();
        w.step(&hold).expect("step");
        let mut after = vec![0.0; idx.dof()];
        w.joint_angles(&mut after);
        assert!((after[shoulders[0]] - q[shoulders[0]]).abs() < 0.05);
    }
    // Wider than the arms reach: the best they can do, said by what is left.
    let mut w = holding_pose(&model);
    let left = w.fit_hand_gap(3.0).expect("fits");
    assert!(left < -1.0 && (w.hand_gap() - 3.0 - left).abs() < 1e-9, "left {left}");
}
