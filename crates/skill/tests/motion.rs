//! Motion quality against real MuJoCo and the real clips: a body standing still neither slips
//! nor swings, a turn clip measured kinematically turns by its own heading change, the walk
//! cycle lifts its feet and slides them less than a body pushed along, and `skill eval` reports
//! the committed turn's motion beside its reference.

use std::path::{Path, PathBuf};

use repertoire_skill::eval::{StartFrom, evaluate};
use repertoire_skill::library;
use repertoire_skill::motion::{MotionMeter, reference_quality};
use repertoire_skill::{SkillSetup, SpecFile};

fn specs() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../../specs")
}

fn shipped_library() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../../library")
}

fn setup(spec: &str) -> SkillSetup {
    let spec = SpecFile::load(&specs().join(spec)).expect("the shipped spec parses");
    SkillSetup::new(spec, &shipped_library()).expect("the shipped spec builds (needs scripts/setup.sh's clip pack)")
}

#[test]
fn a_body_standing_still_has_no_slip_no_swing_and_no_turn() {
    let s = setup("walk.ron");
    let mut world = s.model.new_world();
    world.place_standing(0.3, -0.2, 0.5);
    let mut hold = vec![0.0; s.model.index.dof()];
    world.joint_angles(&mut hold);
    let mut meter = MotionMeter::new(&s.model);
    for _ in 0..60 {
        world.step(&hold).unwrap();
        meter.observe(&world);
    }
    let m = meter.quality();
    assert!(m.foot_slip_m_s < 0.01, "{m:?}");
    assert_eq!(m.clearance_m, 0.0, "no swing completed");
    assert!(m.torso_tilt_deg < 3.0 && m.arm_swing_m < 0.01 && m.turn_deg.abs() < 0.5, "{m:?}");
    assert_eq!((m.pose_term, m.end_effector_term), (None, None));
}

#[test]
fn a_turn_clip_measured_on_the_body_turns_by_its_own_heading_change() {
    for spec in ["turn_left.ron", "turn_right.ron"] {
        let s = setup(spec);
        let r = &s.settings.reference;
        let clip = (r.heading[r.heading.len() - 1] - r.heading[0]).to_degrees();
        let m = reference_quality(&s.model, r);
        assert!((m.turn_deg - clip).abs() < 1.0, "{spec}: measured {:.1}°, the clip turns {clip:.1}°", m.turn_deg);
        assert!(m.clearance_m > 0.03, "{spec}: a gait lifts its feet ({:.3} m)", m.clearance_m);
    }
}

#[test]
fn the_walk_cycle_slides_its_feet_less_than_a_body_pushed_along() {
    let s = setup("walk.ron");
    let walk = reference_quality(&s.model, &s.settings.reference);
    assert!(walk.arm_swing_m > 0.1, "the walk swings its arms ({:.3} m)", walk.arm_swing_m);
    // The standing pose slid forward at 1 m/s: both feet in stance and sliding all the way.
    let mut world = s.model.new_world();
    let mut meter = MotionMeter::new(&s.model);
    for k in 0..60 {
        world.place_standing(k as f64 / 60.0, 0.0, 0.0);
        meter.observe(&world);
    }
    let pushed = meter.quality();
    assert!((pushed.foot_slip_m_s - 1.0).abs() < 0.01, "{pushed:?}");
    assert!(walk.foot_slip_m_s < 0.5 * pushed.foot_slip_m_s, "walk {walk:?}");
}

#[test]
fn skill_eval_reports_the_committed_turn_beside_its_reference() {
    let s = setup("turn_right.ron");
    let mut skill = library::load(&shipped_library(), "turn_right").expect("the committed turn_right");
    let (report, _) = evaluate(&s, &mut skill, StartFrom::ClipStart, 4, 4, 1).expect("eval");
    let m = report.motion.expect("motion figures");
    let pose = m.pose_term.expect("a skill's rollouts carry the pose term");
    assert!(pose > 0.0 && pose <= 1.0, "{m:?}");
    assert!(m.turn_deg < -30.0, "turn_right turns right ({:.1}°)", m.turn_deg);
    let reference = reference_quality(&s.model, &s.settings.reference);
    assert!(reference.turn_deg < -30.0, "{reference:?}");
}
