//! The warehouse and toss scenarios through the `repertoire` binary: `scene check` accepts both,
//! and the meta-controller commands name the skills a library lacks instead of failing later.

mod common;

use common::{ok, repertoire, temp_dir};

#[test]
fn scene_check_accepts_the_warehouse_and_the_toss() {
    let out = ok(&repertoire(&["scene", "check", "scenarios/warehouse.ron"]));
    assert!(out.contains("pedestal_a") && out.contains("2.5..3.5 m at -45..45°") && out.ends_with("ok\n"), "{out}");
    assert!(out.contains("Warehouse: move `box`") && out.contains("reach 0.65 m, 4 resting contacts"), "{out}");
    assert!(out.contains("bind      skills' props: pedestal → the focal pedestal"), "{out}");
    let out = ok(&repertoire(&["scene", "check", "scenarios/toss.ron"]));
    assert!(out.contains("Toss: catch `ball`") && out.contains("v_x 1.5..4.5 m/s") && out.ends_with("ok\n"), "{out}");
}

#[test]
fn meta_commands_name_the_missing_warehouse_and_toss_skills() {
    // A library holding only walk, copied from the committed one (which may gain the others).
    let lib = temp_dir("walk-only-library");
    std::fs::create_dir_all(lib.join("walk")).unwrap();
    for f in std::fs::read_dir("library/walk").unwrap() {
        let f = f.unwrap().path();
        if f.is_file() {
            std::fs::copy(&f, lib.join("walk").join(f.file_name().unwrap())).unwrap();
        }
    }
    let lib = lib.display().to_string();
    for (file, missing) in [
        ("scenarios/warehouse.ron", "turn_left, turn_right, lift, carry, put_down"),
        ("scenarios/toss.ron", "turn_left, turn_right, catch, put_down"),
    ] {
        for cmd in ["train", "eval"] {
            let out = repertoire(&["meta", cmd, file, "--library", &lib]);
            assert!(!out.status.success(), "{cmd} {file} succeeded");
            let err = String::from_utf8_lossy(&out.stderr);
            assert!(err.contains(file) && err.contains(missing) && err.contains("--skills"), "{cmd} {file}: {err}");
        }
    }
    // The toss's graph starts in catch: leaving catch out is refused before any training.
    let out = repertoire(&[
        "meta",
        "train",
        "scenarios/toss.ron",
        "--library",
        &lib,
        "--skills",
        "walk,turn_left,turn_right",
    ]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        !out.status.success()
            && err.contains("scenarios/toss.ron")
            && err.contains("start skill")
            && err.contains("catch"),
        "{err}"
    );
}

#[test]
fn report_gathers_warehouse_and_toss_evaluations() {
    use repertoire_meta::tasks::task_eval::{PhaseRow, PickupMap, StartGrid, TossReport, TossTrial, WarehouseReport};
    let dir = temp_dir("task-reports");
    let row = |p: &str| PhaseRow {
        start_phase: p.into(),
        episodes: 2,
        phases_mean: 0.5,
        phases_sd: 0.7,
        fall_rate: 0.5,
        drop_rate: 0.0,
    };
    let warehouse = WarehouseReport {
        rows: vec![row("GOTO"), row("all")],
        trials: Vec::new(),
        pickup: Some(PickupMap {
            grid: StartGrid { n: 2, half_m: 1.0, trials: 2 },
            xs: vec![-0.5, 0.5],
            ys: vec![-0.5, 0.5],
            successes: vec![vec![Some(0), Some(1)], vec![None, Some(2)]],
            reached: vec![vec![Some(1), Some(2)], vec![None, Some(2)]],
        }),
        recorded: Vec::new(),
    };
    warehouse.write(&dir.join("warehouse")).unwrap();
    let throw = |v_x: f64, caught: bool| TossTrial {
        index: 0,
        v_x,
        lateral: 0.0,
        caught,
        delivered: false,
        dropped: !caught,
        fell: false,
        fall_cause: None,
        episode_return: 0.0,
    };
    let toss = TossReport {
        v_x: vec![2.0, 4.0],
        lateral: vec![0.0],
        trials: 1,
        throws: vec![throw(2.0, true), throw(4.0, false)],
        recorded: Vec::new(),
    };
    toss.write(&dir.join("toss")).unwrap();
    let w = dir.join("warehouse");
    ok(&repertoire(&["report", w.to_str().unwrap()]));
    let page = std::fs::read_to_string(w.join("report/index.md")).unwrap();
    assert!(
        page.contains("Warehouse evaluation") && page.contains("(pickup.png)") && page.contains("(goto.png)"),
        "{page}"
    );
    assert!(page.contains("| GOTO | 2 | 0.50 ± 0.70 |"), "{page}");
    let t = dir.join("toss");
    ok(&repertoire(&["report", t.to_str().unwrap()]));
    let page = std::fs::read_to_string(t.join("report/index.md")).unwrap();
    assert!(
        page.contains("Toss evaluation") && page.contains("(strike_zone.png)") && page.contains("| 2 | 50.0% |"),
        "{page}"
    );
}

#[test]
fn warehouse_evaluations_record_their_worst_episodes() {
    // A one-iteration controller over the committed library's warehouse skills.
    let dir = temp_dir("warehouse-worst");
    let meta = dir.join("meta");
    let (meta_s, run_s) = (meta.to_str().unwrap(), dir.join("run").display().to_string());
    let args = ["meta", "train", "scenarios/warehouse.ron", "--iterations", "1", "--envs", "2", "--out", meta_s];
    ok(&repertoire(&[&args[..], &["--run-dir", &run_s]].concat()));
    let eval = dir.join("eval");
    let eval_s = eval.to_str().unwrap();
    let args =
        ["--meta", meta_s, "--trials", "4", "--grid", "0", "--worst", "2", "--out", eval_s, "--record", "random:3"];
    let out = ok(&repertoire(&[&["meta", "eval", "scenarios/warehouse.ron"][..], &args[..]].concat()));
    assert!(out.contains("2 worst episodes recorded"), "{out}");
    let random = std::fs::read_dir(eval.join("random"))
        .unwrap()
        .filter(|e| e.as_ref().unwrap().path().extension().is_some_and(|x| x == "rec"))
        .count();
    assert_eq!(random, 3, "{out}");
    // A search looks for a sit that succeeds: refused on the warehouse, naming the scenario.
    let out = repertoire(&["meta", "eval", "scenarios/warehouse.ron", "--meta", meta_s, "--controller", "lookahead:2"]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success() && err.contains("warehouse.ron") && err.contains("sitting scenarios only"), "{err}");
    let recs: Vec<_> = std::fs::read_dir(eval.join("worst"))
        .unwrap()
        .filter_map(|e| e.ok().map(|e| e.file_name().to_string_lossy().into_owned()))
        .filter(|n| n.ends_with(".rec"))
        .collect();
    assert_eq!(recs.len(), 2, "{recs:?}");
    let md = std::fs::read_to_string(eval.join("report.md")).unwrap();
    for r in &recs {
        assert!(md.contains(&format!("| worst/{r} |")), "{r} listed in {md}");
    }
    // `run` on the warehouse records its worst episodes too.
    let run = dir.join("run-out");
    let args = ["run", "scenarios/warehouse.ron", "--meta", meta_s, "--trials", "3", "--out", run.to_str().unwrap()];
    ok(&repertoire(&args));
    let md = std::fs::read_to_string(run.join("report.md")).unwrap();
    assert!(md.contains("worst episodes") && run.join("worst").read_dir().unwrap().count() >= 3, "{md}");
}
