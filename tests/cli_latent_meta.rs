//! The latent low level inside scenarios and the meta tools: the scenario's `low_level` field
//! (default, relative path, a missing model refused with the file named), a two-iteration
//! latent high level trained and evaluated on the sitting scenario through the committed latent
//! model (real MuJoCo, real networks), and the ablation row that plans it.

mod common;

use std::path::Path;

use common::{ok, repertoire};
use repertoire::scenes::{LowLevel, ScenarioFile};

fn root() -> &'static Path {
    Path::new(env!("CARGO_MANIFEST_DIR"))
}

/// The built-in sitting scenario with `low_level` set to `value` (none: left out).
fn sit_with(low_level: Option<&str>) -> String {
    let text = std::fs::read_to_string(root().join("scenarios/sit.ron")).unwrap();
    let end = text.rfind(')').unwrap();
    match low_level {
        Some(v) => format!("{}    low_level: {v},\n)\n", &text[..end]),
        None => text,
    }
}

#[test]
fn the_low_level_field_defaults_resolves_and_refuses_a_missing_model() {
    let dir = common::temp_dir("latent-meta-ron");
    // Left out: the skills.
    let file = ScenarioFile::parse(&dir.join("a.ron"), sit_with(None)).unwrap();
    assert_eq!(file.scenario.low_level, LowLevel::Skills);
    assert_eq!(file.latent_dir(), None);
    // A folder holding latent.ron, relative to the scenario file.
    std::fs::create_dir_all(dir.join("model")).unwrap();
    std::fs::write(dir.join("model/latent.ron"), "()").unwrap();
    let path = common::write(&dir, "b.ron", &sit_with(Some("Latent(\"model\")")));
    let file = ScenarioFile::load(&path).unwrap();
    assert_eq!(file.scenario.low_level, LowLevel::Latent("model".into()));
    assert_eq!(file.latent_dir(), Some(dir.join("model")));
    // A folder without latent.ron: refused at load, naming the file, the line and the folder.
    let path = common::write(&dir, "c.ron", &sit_with(Some("Latent(\"nowhere\")")));
    let err = ScenarioFile::load(&path).unwrap_err().to_string();
    let line = sit_with(Some("Latent(\"nowhere\")")).lines().position(|l| l.contains("nowhere")).unwrap() + 1;
    assert!(err.contains("c.ron") && err.contains(&format!(":{line}:")) && err.contains("latent.ron"), "{err}");
    assert!(err.contains("nowhere"), "{err}");
    // `scene check` refuses it too, and names the low level of a good one.
    let out = repertoire(&["scene", "check", path.to_str().unwrap()]);
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("c.ron"));
    let text = ok(&repertoire(&["scene", "check", root().join("scenarios/sit_latent.ron").to_str().unwrap()]));
    assert!(text.contains("low level latent model") && text.contains("library/latent"), "{text}");
    let text = ok(&repertoire(&["scene", "check"]));
    assert!(text.contains("low level skills"), "{text}");
    assert!(text.contains("standing pose: the feet's lowest point 1.0 mm above the floor"), "{text}");
    // An unknown low level is a located RON error.
    let path = common::write(&dir, "d.ron", &sit_with(Some("Latnt(\"model\")")));
    let err = ScenarioFile::load(&path).unwrap_err().to_string();
    assert!(err.contains("d.ron") && err.contains("Latnt"), "{err}");
}

#[test]
fn a_latent_high_level_trains_and_evaluates_on_the_sitting_scenario() {
    let dir = common::temp_dir("latent-meta-run");
    let scenario = root().join("scenarios/sit_latent.ron");
    let meta = dir.join("meta");
    let text = ok(&repertoire(&[
        "meta",
        "train",
        scenario.to_str().unwrap(),
        "--iterations",
        "2",
        "--envs",
        "2",
        "--out",
        meta.to_str().unwrap(),
        "--run-dir",
        dir.join("run").to_str().unwrap(),
    ]));
    assert!(text.contains("| 2 |") && text.contains("latent high level (z of"), "{text}");
    assert!(meta.join("latent_meta.ron").exists() && meta.join("latent_meta.safetensors").exists());
    let manifest = std::fs::read_to_string(meta.join("latent_meta.ron")).unwrap();
    assert!(manifest.contains("latent_fnv1a") && manifest.contains("library/latent"), "{manifest}");
    let metrics = std::fs::read_to_string(dir.join("run/metrics.csv")).unwrap();
    assert_eq!(metrics.lines().count(), 3, "{metrics}");
    // The zone curriculum is logged as for the skills' controller (for `repertoire report`).
    let schedule = std::fs::read_to_string(dir.join("run/curriculum.csv")).unwrap();
    assert!(schedule.starts_with("iteration,episodes,zone,") && schedule.lines().count() == 3, "{schedule}");
    assert!(schedule.lines().skip(1).all(|l| l.split(',').nth(2) == Some("front")), "{schedule}");
    // The per-episode figures are the episodes' (the learning core sums terms over an episode):
    // at most the 20 s limit, a minimum distance no larger than a start 2.5 m from the chair.
    let header: Vec<&str> = metrics.lines().next().unwrap().split(',').collect();
    let col = |name: &str| header.iter().position(|h| *h == name).unwrap();
    let (seconds, min_d) = (col("term_seconds"), col("term_min_distance"));
    let mut ended = 0;
    for line in metrics.lines().skip(1) {
        let v: Vec<f64> = line.split(',').map(|x| x.parse().unwrap_or(f64::NAN)).collect();
        if v[seconds].is_finite() {
            ended += 1;
            assert!(v[seconds] > 0.0 && v[seconds] <= 20.0 + 1e-6, "{line}");
            assert!(v[min_d] > 0.0 && v[min_d] < 3.5, "{line}");
        }
    }
    assert!(ended > 0, "no episode ended in two iterations: {metrics}");

    let out = dir.join("eval");
    let text = ok(&repertoire(&[
        "meta",
        "eval",
        scenario.to_str().unwrap(),
        "--meta",
        meta.to_str().unwrap(),
        "--trials",
        "3",
        "--batch",
        "2",
        "--out",
        out.to_str().unwrap(),
    ]));
    for zone in ["front", "sides", "behind"] {
        assert!(text.contains(&format!("| {zone} | 3 |")), "{text}");
    }
    assert!(text.contains("| all | 9 |"), "{text}");
    // The same report.json shape as the skills' controller writes (what `ablate` gathers).
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("report.json")).unwrap()).unwrap();
    let zones = json["zones"].as_array().unwrap();
    assert_eq!(zones.len(), 4);
    for z in zones {
        let rate = z["success_rate"].as_f64().unwrap();
        let d = z["min_distance_mean"].as_f64().unwrap();
        assert!((0.0..=1.0).contains(&rate) && d.is_finite() && d > 0.0, "{z}");
    }
    assert_eq!(json["trials"].as_array().unwrap().len(), 9);
    assert!(out.join("report.md").exists() && out.join("trials.csv").exists());
    // Evaluated as every controller is: its worst episodes played again, recorded (and
    // checked to end as they did), a frame per control tick under the skill `latent`.
    let worst: Vec<_> = std::fs::read_dir(out.join("worst"))
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|x| x == "rec"))
        .collect();
    assert!(!worst.is_empty(), "no worst episode recorded in {}", out.display());
    for path in &worst {
        let rec = repertoire::scenes::Recording::load(path).unwrap();
        assert_eq!(rec.header.skills, ["latent"], "{}", path.display());
        assert!(rec.frames() > 1 && rec.skill.iter().all(|&k| k == 0), "{}", path.display());
        assert!(rec.header.title.starts_with("latent high level, zone"), "{}", rec.header.title);
    }

    // `run` on the latent scenario runs the latent high level, not the skills' controller.
    let run_out = dir.join("run-out");
    let ran = ok(&repertoire(&[
        "run",
        scenario.to_str().unwrap(),
        "--meta",
        meta.to_str().unwrap(),
        "--trials",
        "1",
        "--out",
        run_out.to_str().unwrap(),
    ]));
    assert!(ran.contains("latent high level") && ran.contains("| all | 3 |"), "{ran}");
    assert!(run_out.join("report.json").exists());
    let missing = ok(&repertoire(&["run", scenario.to_str().unwrap(), "--meta", dir.join("none").to_str().unwrap()]));
    assert!(missing.contains("no latent high level is trained") && missing.contains("meta train"), "{missing}");

    // The same run again is the same evaluation (seeded starts, the policy's mean).
    let again = ok(&repertoire(&[
        "meta",
        "eval",
        scenario.to_str().unwrap(),
        "--meta",
        meta.to_str().unwrap(),
        "--trials",
        "3",
        "--batch",
        "3",
        "--out",
        dir.join("eval2").to_str().unwrap(),
    ]));
    let table = |t: &str| t.lines().filter(|l| l.starts_with("| ")).map(String::from).collect::<Vec<_>>();
    assert_eq!(table(&text), table(&again));

    // A manifest vouching for other latent weights is refused, naming it.
    let edited = manifest.replace("latent_fnv1a: ", "latent_fnv1a: 1");
    std::fs::write(meta.join("latent_meta.ron"), edited).unwrap();
    let res = repertoire(&["meta", "eval", scenario.to_str().unwrap(), "--meta", meta.to_str().unwrap()]);
    assert!(!res.status.success());
    let err = String::from_utf8_lossy(&res.stderr);
    assert!(err.contains("latent_meta.ron") && err.contains("other weights"), "{err}");
    // z held for several ticks: recorded, and read back by the evaluation.
    let held = dir.join("held");
    let args = ["--iterations", "1", "--envs", "2", "--hold", "3", "--out", held.to_str().unwrap()];
    let run = dir.join("run-held");
    ok(&repertoire(
        &[&["meta", "train", scenario.to_str().unwrap(), "--run-dir", run.to_str().unwrap()], &args[..]].concat(),
    ));
    assert!(std::fs::read_to_string(held.join("latent_meta.ron")).unwrap().contains("hold: 3"));
    let text = ok(&repertoire(&[
        "meta",
        "eval",
        scenario.to_str().unwrap(),
        "--meta",
        held.to_str().unwrap(),
        "--trials",
        "1",
        "--zones",
        "front",
    ]));
    assert!(text.contains("| front | 1 |") && held.join("eval/report.json").exists(), "{text}");
    // Skill-graph options make no sense through a latent space.
    let res = repertoire(&["meta", "train", scenario.to_str().unwrap(), "--chain", "walk,sit", "--iterations", "1"]);
    assert!(!res.status.success());
    assert!(String::from_utf8_lossy(&res.stderr).contains("latent low level"));
}

#[test]
fn the_ablation_plans_the_latent_row() {
    let dir = common::temp_dir("latent-meta-ablate");
    let spec = root().join("ablations/sit.ron");
    ok(&repertoire(&["ablate", spec.to_str().unwrap(), "--plan-only", "--out", dir.to_str().unwrap()]));
    let plan = std::fs::read_to_string(dir.join("runs/latent-low-level--npmp--s1/plan.ron")).expect("plan file");
    let compact: String = plan.split_whitespace().collect();
    assert!(compact.contains("\"meta\",\"train\"") && compact.contains("\"meta\",\"eval\""), "{plan}");
    assert_eq!(compact.matches("\"--latent\",\"library/latent\"").count(), 2, "{plan}");
    assert!(!compact.contains("--chain") && !compact.contains("--skills"), "{plan}");
    // The skills' rows do not name a latent model.
    let plan = std::fs::read_to_string(dir.join("runs/full-model-s1/plan.ron")).unwrap();
    assert!(!plan.contains("--latent"), "{plan}");
    // A latent row that also restricts the skills is refused.
    let bad = common::write(
        &dir,
        "bad.ron",
        "Ablation(seeds: [1], iterations: 1, trials: 1, variants: [Variant(name: \"x\", low_level: \"m\", chain: [\"sit\"])])",
    );
    let out = repertoire(&["ablate", bad.to_str().unwrap(), "--plan-only"]);
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("variant `x`"));
}
