//! The committed meta-controller's worst evaluation trials are recorded by running them again:
//! the rerun is the same trial (same outcome), recorded at the control rate with the skills.

use std::path::Path;
use std::sync::Arc;

use repertoire_meta::eval::{evaluate, save_worst, worst_trials};
use repertoire_meta::train::load;
use repertoire_meta::{MetaSetup, SkillGraph};
use repertoire_scenes::{Recording, ScenarioFile, WorldModel};

#[test]
fn worst_trials_are_recorded_as_they_ran() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("../..");
    let model = Arc::new(WorldModel::build(ScenarioFile::builtin_default()).expect("default scene"));
    let graph = SkillGraph::of(&model.scenario.scenario);
    let setup = Arc::new(MetaSetup::new(model, &root.join("library"), graph).expect("committed library"));
    let (_, head) = load(&root.join("library/meta"), &setup).expect("committed meta-controller");
    let zones = vec!["front".to_string(), "behind".to_string()];
    let report = evaluate(&setup, &head, &zones, 3, 3, 7).expect("evaluate");

    let per_zone = worst_trials(&report, 1, true);
    assert_eq!(per_zone.iter().map(|t| t.zone.as_str()).collect::<Vec<_>>(), ["front", "behind"]);
    let dir = std::env::temp_dir().join(format!("repertoire-worst-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    let files = save_worst(&setup, &head, &report, &zones, 3, 7, 2, false, &dir).expect("record the worst");
    assert_eq!(files.len(), 2);
    for (file, trial) in files.iter().zip(worst_trials(&report, 2, false)) {
        let rec = Recording::load(file).expect("recording");
        assert_eq!(file.file_name().unwrap().to_string_lossy(), format!("trial_{}_{}.rec", trial.zone, trial.index));
        assert_eq!(
            rec.header.skills,
            ["walk_to", "turn_left", "turn_right", "turn_left_wide", "turn_right_wide", "stand", "sit"]
        );
        // Frame 0 is the start; then one frame per control tick until the trial ended.
        let ticks = (trial.seconds * rec.header.control_hz).round() as usize;
        assert_eq!(rec.frames(), ticks + 1, "{}", file.display());
        let last_min = rec.terms[(rec.frames() - 1) * rec.header.terms.len() + 3];
        assert!((f64::from(last_min) - trial.min_distance).abs() < 1e-5, "{last_min} vs {}", trial.min_distance);
        assert!(rec.skill.iter().all(|&s| (0..7).contains(&s)));
    }
}
