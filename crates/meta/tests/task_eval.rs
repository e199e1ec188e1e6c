//! Warehouse and toss evaluation over a barely trained meta-controller (the committed walk and
//! turns as its skills): the phase table, the pick-up map and the strike zone are reproducible
//! for a seed and written as tables and pictures.

mod support;

use std::path::{Path, PathBuf};
use std::sync::Arc;

use repertoire_learn::ppo::PpoConfig;
use repertoire_meta::tasks::task_eval::{
    StartGrid, evaluate_toss, evaluate_warehouse, save_worst_toss, save_worst_warehouse, worst_toss, worst_warehouse,
};
use repertoire_meta::train::{MetaTrainOptions, load, train};
use repertoire_meta::{MetaSetup, SkillGraph};
use repertoire_scenes::{Recording, ScenarioFile, WorldModel};

fn root() -> &'static Path {
    Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/../.."))
}

/// The shipped scenario `name` with only walk and the turns and a `seconds` episode limit.
fn walking(name: &str, skills: &str, limit: &str, seconds: f64) -> Arc<MetaSetup> {
    let text = std::fs::read_to_string(root().join(format!("scenarios/{name}.ron"))).unwrap();
    assert!(text.contains(skills) && text.contains(limit), "scenarios/{name}.ron no longer says {skills} and {limit}");
    let text = text
        .replace(skills, r#"skills: ["walk", "turn_left", "turn_right"]"#)
        .replace(&support::graph_block(&text), "")
        .replace("        hold_from: \"lift\",\n", "")
        .replace(limit, &format!("time_limit_s: {seconds:.1}"));
    let file = ScenarioFile::parse(&root().join(format!("scenarios/{name}-walk.ron")), text).unwrap();
    let model = Arc::new(WorldModel::build(file).unwrap());
    let graph = SkillGraph::of(&model.scenario.scenario);
    Arc::new(MetaSetup::new(model, &root().join("library"), graph).unwrap())
}

fn tiny_controller(setup: &Arc<MetaSetup>, tag: &str) -> (PathBuf, repertoire_learn::acting::ActingHybrid) {
    let dir = std::env::temp_dir().join(format!("repertoire-task-eval-{tag}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    let opts = MetaTrainOptions {
        out: dir.join("meta"),
        run_dir: dir.join("run"),
        ppo: PpoConfig {
            num_envs: 2,
            num_steps: 4,
            num_iterations: 1,
            num_minibatches: 2,
            update_epochs: 1,
            ..PpoConfig::default()
        },
        curriculum: false,
        command: "test".into(),
        resume: None,
        checkpoint_every: 0,
        warm_start: None,
        replace: Vec::new(),
    };
    let (manifest, _) = train(Arc::clone(setup), &opts).expect("train");
    assert_eq!(manifest.skills, ["walk", "turn_left", "turn_right"]);
    let (_, head) = load(&dir.join("meta"), setup).expect("load");
    (dir, head)
}

#[test]
fn the_warehouse_evaluation_counts_phases_and_maps_pick_ups() {
    let s = walking(
        "warehouse",
        r#"skills: ["walk_to", "turn_left", "turn_right", "lift", "carry", "put_down"]"#,
        "time_limit_s: 15.0",
        2.0,
    );
    let (dir, head) = tiny_controller(&s, "warehouse");
    let grid = StartGrid { n: 3, half_m: 1.5, trials: 1 };
    let a = evaluate_warehouse(&s, &head, 8, Some(grid), 3).expect("evaluate");
    let b = evaluate_warehouse(&s, &head, 8, Some(grid), 3).expect("evaluate");
    assert_eq!(a, b, "the same seed gives the same report");
    assert_eq!(a.trials.len(), 8);
    let all = a.rows.last().unwrap();
    assert_eq!((all.start_phase.as_str(), all.episodes), ("all", 8));
    assert_eq!(a.rows[..a.rows.len() - 1].iter().map(|r| r.episodes).sum::<usize>(), 8);
    for t in &a.trials {
        assert!(t.seconds <= 2.0 + 0.5 && f64::from(t.phases) <= t.episode_return + 1e-6, "{t:?}");
    }
    let p = a.pickup.as_ref().unwrap();
    assert_eq!(p.xs, [-1.0, 0.0, 1.0]);
    assert_eq!(p.successes[1][1], None, "the centre cell is the pedestal");
    assert_eq!(p.successes.iter().flatten().flatten().count(), 8);
    for (row, reached) in p.successes.iter().zip(&p.reached) {
        for (k, r) in row.iter().zip(reached) {
            assert_eq!(k.is_some(), r.is_some());
            assert!(k.unwrap_or(0) <= r.unwrap_or(0), "a pick-up passes through GOTO");
        }
    }
    a.write(&dir.join("report")).unwrap();
    let md = std::fs::read_to_string(dir.join("report/report.md")).unwrap();
    assert!(md.contains("| all | 8 |") && md.contains("pedestal") && md.contains("/1"), "{md}");
    assert!(dir.join("report/pickup.png").exists() && dir.join("report/trials.csv").exists());
    assert!(dir.join("report/goto.svg").exists() && md.contains("GOTO reached"));

    // The two worst episodes, run again recorded: the same episodes, listed in the report.
    let mut a = a;
    let worst: Vec<_> = worst_warehouse(&a, 2).into_iter().cloned().collect();
    assert!(worst[0].phases <= worst[1].phases);
    assert!(a.trials.iter().all(|t| t.phases >= worst[1].phases), "the fewest phases: {worst:?}");
    let out = dir.join("report");
    let files = save_worst_warehouse(&s, &head, &mut a, 3, 2, &out.join("worst"), &out).expect("record");
    assert_eq!(a.recorded.len(), 2);
    for ((file, listed), t) in files.iter().zip(&a.recorded).zip(&worst) {
        assert_eq!(*listed, format!("worst/{}_{}.rec", t.start_phase.to_lowercase(), t.index));
        let rec = Recording::load(file).expect("a recording");
        assert_eq!(rec.header.skills, ["walk", "turn_left", "turn_right"]);
        assert_eq!(rec.header.terms, ["phase", "phases_done", "focal_distance", "hands_on_box"]);
        let ticks = (t.seconds * rec.header.control_hz).round() as usize;
        assert_eq!(rec.frames(), ticks + 1, "the start, then one frame per control tick");
        let last = (rec.frames() - 1) * rec.header.terms.len();
        assert_eq!(rec.terms[last + 1], t.phases as f32, "phases completed at the end");
    }
    a.write(&out).unwrap();
    let md = std::fs::read_to_string(out.join("report.md")).unwrap();
    assert!(md.contains("worst episodes") && md.contains(&format!("| {} |", a.recorded[0])), "{md}");
    let json = std::fs::read_to_string(out.join("report.json")).unwrap();
    assert!(json.contains(&a.recorded[1]), "{json}");
}

#[test]
fn the_strike_zone_throws_every_cell() {
    let s = walking(
        "toss",
        r#"skills: ["walk", "turn_left", "turn_right", "catch", "put_down"]"#,
        "time_limit_s: 10.0",
        3.0,
    );
    let (dir, head) = tiny_controller(&s, "toss");
    let a = evaluate_toss(&s, &head, 3, 2, 2, 5).expect("evaluate");
    assert_eq!(a, evaluate_toss(&s, &head, 3, 2, 2, 5).unwrap(), "reproducible");
    assert_eq!(a.v_x, [2.0, 3.0, 4.0]);
    assert_eq!(a.lateral, [-0.375, 0.375]);
    assert_eq!(a.throws.len(), 12);
    for v in &a.v_x {
        assert_eq!(a.throws.iter().filter(|t| t.v_x == *v).count(), 4);
    }
    for t in &a.throws {
        // Without a catch there is no shaping: an uncaught throw earns only the time its ball
        // spent in the bucket (a deflection off the body can put it there).
        if !t.caught {
            assert_eq!(t.delivered, t.episode_return > 0.0, "{t:?}");
        }
    }
    a.write(&dir.join("report")).unwrap();
    let md = std::fs::read_to_string(dir.join("report/report.md")).unwrap();
    assert!(md.contains("| 12 |") && md.contains("catch rate by throw"), "{md}");
    let svg = std::fs::read_to_string(dir.join("report/strike_zone.svg")).unwrap();
    assert!(svg.contains("strike zone") && svg.contains("n=2"));

    // The worst throw, thrown again recorded: uncaught first, then the lowest return.
    let mut a = a;
    let worst = worst_toss(&a, 1)[0].clone();
    assert!(a.throws.iter().all(|t| (t.caught, t.episode_return) >= (worst.caught, worst.episode_return)));
    let out = dir.join("report");
    let files = save_worst_toss(&s, &head, &mut a, 5, 1, &out.join("worst"), &out).expect("record");
    assert_eq!(a.recorded, [format!("worst/throw_{}.rec", worst.index)]);
    let rec = Recording::load(&files[0]).expect("a recording");
    assert_eq!(rec.header.terms, ["caught", "bucket_s", "ball_to_bucket", "hands_on_ball"]);
    assert!(rec.frames() > 1 && rec.frames() <= 3 * 60 + 1, "{} frames", rec.frames());
    let md = a.markdown();
    assert!(md.contains("worst throws") && md.contains("worst/throw_"), "{md}");
}
