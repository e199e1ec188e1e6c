//! A world's snapshot: restored into another world of the same scene, it reports the same
//! bodies and contacts and steps on exactly as the original does, whether it was taken after a
//! physics step or after a state set by hand.

use rand::SeedableRng;
use rand::rngs::StdRng;
use repertoire_scenes::{ScenarioFile, World, WorldModel};
use std::path::Path;
use std::sync::Arc;

/// Every actuated joint's PD target swinging with time, different per joint.
fn wave(tick: usize, joints: usize) -> Vec<f64> {
    (0..joints).map(|k| 0.4 * ((tick * 7 + k * 3) as f64 * 0.1).sin()).collect()
}

fn snapshot(w: &World) -> Vec<f64> {
    let mut out = Vec::new();
    w.snapshot(&mut out);
    out
}

/// What a reader sees of a world without stepping it: body poses and contacts.
fn reading(w: &World) -> (Vec<[f64; 3]>, usize, [f64; 3]) {
    let bodies = w.data().model().ffi().nbody as usize;
    let poses = (0..bodies).map(|b| w.body_position(b)).collect();
    (poses, w.data().ffi().ncon as usize, w.center_of_mass())
}

fn check(scenario: ScenarioFile) {
    let name = scenario.path.display().to_string();
    let model = Arc::new(WorldModel::build(scenario).expect("scene"));
    let joints = model.index.joints.len();
    let mut a = World::new(Arc::clone(&model));
    a.reset(&mut StdRng::seed_from_u64(4), 0.0, 0.0, 0.3);
    // Right after a reset (a state set by hand, no step yet) and after some steps.
    for (taken_at, ticks) in [("after the reset", 0), ("after 12 steps", 12)] {
        for t in 0..ticks {
            a.step(&wave(t, joints)).expect("step");
        }
        let mut b = World::new(Arc::clone(&model));
        b.reset(&mut StdRng::seed_from_u64(99), 1.0, -1.0, 2.0);
        b.restore(&snapshot(&a)).expect("a snapshot of the same scene");
        assert_eq!(snapshot(&b), snapshot(&a), "{name}: the restored state, {taken_at}");
        assert_eq!(reading(&b), reading(&a), "{name}: bodies and contacts as the original reports them, {taken_at}");
        for t in 100..130 {
            a.step(&wave(t, joints)).expect("step");
            b.step(&wave(t, joints)).expect("step");
            assert_eq!(snapshot(&b), snapshot(&a), "{name}: tick {t} after a restore {taken_at}");
        }
    }
    let mut short = snapshot(&a);
    short.pop();
    let err = World::new(Arc::clone(&model)).restore(&short).expect_err("a truncated snapshot is refused");
    assert!(err.to_string().contains("values"), "{err}");
}

#[test]
fn a_restored_world_steps_on_exactly_as_the_original() {
    check(ScenarioFile::builtin_default());
    // Free props (a box drawn at another size and mass per episode) on pedestals.
    let warehouse = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../scenarios/warehouse.ron");
    check(ScenarioFile::load(&warehouse).expect("warehouse scenario"));
}
