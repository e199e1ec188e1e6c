//! `repertoire skill train / eval / finetune` end to end with tiny budgets: a walk is trained
//! and evaluated (writing its end-pose pool), then turn_left is trained and fine-tuned from
//! walk's end poses and evaluated from both starts.

mod common;

use std::path::Path;

use common::{ok, repertoire};

#[test]
fn train_eval_and_finetune_a_chain() {
    let dir = common::temp_dir("cli-skill");
    let lib = dir.join("library");
    let lib = lib.to_str().unwrap();
    let spec = |name: &str| Path::new(env!("CARGO_MANIFEST_DIR")).join("specs").join(name);
    let tiny = ["--iterations", "2", "--envs", "4", "--checkpoint-every", "0"];

    let walk = spec("walk.ron");
    let run = dir.join("run-walk");
    let text = ok(&repertoire(
        &[&["skill", "train", walk.to_str().unwrap(), "--library", lib, "--run-dir", run.to_str().unwrap()], &tiny[..]]
            .concat(),
    ));
    assert!(text.contains("| walk | 2 |"), "{text}");
    assert!(
        Path::new(lib).join("walk/manifest.ron").exists() && Path::new(lib).join("walk/policy.safetensors").exists()
    );
    assert!(run.join("metrics.csv").exists() && run.join("run.ron").exists());

    let text =
        ok(&repertoire(&["skill", "eval", walk.to_str().unwrap(), "--library", lib, "--trials", "6", "--batch", "3"]));
    assert!(text.contains("| walk | clip start | 6 |"), "{text}");
    assert!(Path::new(lib).join("walk/end_poses.ron").exists(), "{text}");

    let turn = spec("turn_left.ron");
    let run = dir.join("run-turn");
    ok(&repertoire(
        &[&["skill", "train", turn.to_str().unwrap(), "--library", lib, "--run-dir", run.to_str().unwrap()], &tiny[..]]
            .concat(),
    ));
    // A 2-iteration walk rarely survives to its time limit, so its pool may be empty; the
    // fine-tune then starts from reference states only, which the command must still accept.
    let stage_one = repertoire_skill::library::load(Path::new(lib), "turn_left").expect("stage one loads").manifest;
    assert!(stage_one.lineage.is_empty(), "a skill trained from scratch has no earlier stages");
    let run = dir.join("run-turn-ft");
    let text = ok(&repertoire(
        &[
            &["skill", "finetune", turn.to_str().unwrap(), "--from", "walk", "--library", lib],
            &["--run-dir", run.to_str().unwrap()][..],
            &tiny[..],
        ]
        .concat(),
    ));
    assert!(text.contains("| turn_left | 2 |"), "{text}");
    let manifest = std::fs::read_to_string(Path::new(lib).join("turn_left/manifest.ron")).unwrap();
    assert!(manifest.contains("Pools") && manifest.contains("finetune"), "the manifest records the fine-tune");
    // Its lineage is the stage it started from: stage one's command and policy.
    let tuned = repertoire_skill::library::load(Path::new(lib), "turn_left").expect("fine-tune loads").manifest;
    assert_eq!(tuned.lineage, vec![stage_one.stage()]);
    assert!(tuned.lineage[0].command.contains("skill train"), "{:?}", tuned.lineage);
    assert_ne!(tuned.policy_fnv1a, stage_one.policy_fnv1a);
    // A second fine-tune appends the first, oldest first.
    let run = dir.join("run-turn-ft2");
    ok(&repertoire(
        &[
            &["skill", "finetune", turn.to_str().unwrap(), "--from", "walk", "--library", lib],
            &["--run-dir", run.to_str().unwrap()][..],
            &tiny[..],
        ]
        .concat(),
    ));
    let twice = repertoire_skill::library::load(Path::new(lib), "turn_left").expect("second fine-tune loads").manifest;
    assert_eq!(twice.lineage, vec![stage_one.stage(), tuned.stage()]);

    // Fine-tuning from a skill that was never evaluated names what is missing.
    let out = repertoire(&["skill", "finetune", turn.to_str().unwrap(), "--from", "sit", "--library", lib]);
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("end_poses.ron") && err.contains("skill eval sit"), "{err}");

    // Raising the spread of a policy there is none to start from is refused, not ignored.
    let out = repertoire(&["skill", "train", walk.to_str().unwrap(), "--explore-log-std", "-2", "--library", lib]);
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("--explore-log-std") && err.contains("--warm-start"), "{err}");
    // So is a fresh critic for a policy that starts fresh anyway.
    let out = repertoire(&["skill", "train", walk.to_str().unwrap(), "--fresh-critic", "--library", lib]);
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("--fresh-critic") && err.contains("--warm-start"), "{err}");
    // A critic warm-up as long as the run would leave the policy untrained.
    let out = repertoire(&[
        "skill",
        "finetune",
        turn.to_str().unwrap(),
        "--from",
        "walk",
        "--iterations",
        "5",
        "--critic-warmup",
        "5",
        "--library",
        lib,
    ]);
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("warm-up of 5") && err.contains("--critic-warmup"), "{err}");
    let out = repertoire(&["skill", "train", walk.to_str().unwrap(), "--learning-rate", "0", "--library", lib]);
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("--learning-rate"), "{err}");
}

#[test]
fn meta_train_eval_and_the_main_job() {
    let dir = common::temp_dir("cli-meta");
    let lib = dir.join("library");
    let lib_s = lib.to_str().unwrap();
    let spec = |name: &str| Path::new(env!("CARGO_MANIFEST_DIR")).join("specs").join(name);
    // The stand starts from walk_to's and the turns' end poses, so their pools are written first
    // (a 1-iteration policy's may be empty; training then starts from reference states).
    for name in ["walk_to", "turn_left", "turn_right", "turn_left_wide", "turn_right_wide", "stand", "sit"] {
        if name == "stand" {
            for pred in ["walk_to", "turn_left", "turn_right", "turn_left_wide", "turn_right_wide"] {
                let spec = spec(&format!("{pred}.ron"));
                ok(&repertoire(&["skill", "eval", spec.to_str().unwrap(), "--library", lib_s, "--trials", "2"]));
            }
        }
        let run = dir.join(format!("run-{name}"));
        ok(&repertoire(&[
            "skill",
            "train",
            spec(&format!("{name}.ron")).to_str().unwrap(),
            "--library",
            lib_s,
            "--run-dir",
            run.to_str().unwrap(),
            "--iterations",
            "1",
            "--envs",
            "2",
            "--checkpoint-every",
            "0",
        ]));
    }
    // Without --out the controller goes into the library it was trained over, and eval and run
    // look for it there.
    let meta = lib.join("meta");
    let run = dir.join("run-meta");
    let text = ok(&repertoire(&[
        "meta",
        "train",
        "--library",
        lib_s,
        "--run-dir",
        run.to_str().unwrap(),
        "--iterations",
        "1",
        "--envs",
        "2",
    ]));
    assert!(text.contains("meta-controller written to"), "{text}");
    assert!(meta.join("meta.ron").exists() && meta.join("meta.safetensors").exists(), "{text}");
    // The run goes on from its checkpoint, in its own run directory, to a larger total.
    let stem = run.join("checkpoints/iter-000001");
    let resumed = dir.join("meta-resumed");
    let args = ["meta", "train", "--library", lib_s, "--out", resumed.to_str().unwrap(), "--iterations", "2"];
    let text = ok(&repertoire(&[&args[..], &["--resume", stem.to_str().unwrap()]].concat()));
    assert!(text.contains(&format!("run in {}", run.display())), "{text}");
    let manifest = std::fs::read_to_string(resumed.join("meta.ron")).unwrap();
    assert!(manifest.contains("iterations: 2,") && manifest.contains("resumed: [") && manifest.contains("--resume"));
    assert_eq!(std::fs::read_to_string(run.join("metrics.csv")).unwrap().lines().count(), 3, "a header, 2 iterations");
    let out = repertoire(&[&args[..], &["--resume", dir.join("no-such/iter-000001").to_str().unwrap()]].concat());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success() && err.contains("no-such/iter-000001.ron"), "{err}");
    // A new run from the trained controller: its critic comes along, so no warm-up; the
    // manifest names where it started. Not together with --resume.
    let warm = dir.join("meta-warm");
    let meta_s = meta.to_str().unwrap();
    let args = ["meta", "train", "--library", lib_s, "--out", warm.to_str().unwrap(), "--iterations", "1"];
    let rest = ["--warm-start", meta_s, "--no-curriculum", "--learning-rate", "1e-4", "--envs", "2"];
    let warm_run = dir.join("run-warm");
    let run_dir = ["--run-dir", warm_run.to_str().unwrap()];
    ok(&repertoire(&[&args[..], &rest[..], &run_dir[..]].concat()));
    let manifest = std::fs::read_to_string(warm.join("meta.ron")).unwrap();
    assert!(manifest.contains(&format!("from: \"{meta_s}\"")) && manifest.contains("critic: true"), "{manifest}");
    assert!(manifest.contains("critic_warmup: 0,") && manifest.contains("learning_rate: 0.0001,"), "{manifest}");
    let out = repertoire(&[&args[..], &rest[..], &["--resume", stem.to_str().unwrap()]].concat());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success() && err.contains("--warm-start") && err.contains("--resume"), "{err}");
    let out = repertoire(&[&args[..], &["--warm-start", dir.join("no-such").to_str().unwrap()]].concat());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success() && err.contains("no-such/meta.ron"), "{err}");
    let args = ["meta", "eval", "--library", lib_s, "--trials", "2", "--zones", "front"];
    let text = ok(&repertoire(&[&args[..], &["--record", "random:2", "--record", "successes:1"]].concat()));
    assert!(text.contains("| front | 2 |") && text.contains("| all | 2 |"), "{text}");
    assert!(meta.join("eval/report.md").exists() && meta.join("eval/trials.csv").exists());
    // Other episodes than the worst are recorded on request: both random ones, and a success
    // when there was one.
    let recs = |dir: &str| -> Vec<String> {
        std::fs::read_dir(meta.join("eval").join(dir)).map_or_else(
            |_| Vec::new(),
            |d| d.filter_map(|e| e.ok()?.file_name().into_string().ok()).filter(|n| n.ends_with(".rec")).collect(),
        )
    };
    let mut random = recs("random");
    random.sort();
    assert_eq!(random, ["trial_front_0.rec", "trial_front_1.rec"], "{text}");
    let success = text.lines().find(|l| l.starts_with("| front |")).and_then(|l| l.split('|').nth(3)).unwrap();
    assert_eq!(recs("successes").len(), usize::from(success.trim() != "0.0%"), "{text}");
    assert!(text.contains("2 random episodes recorded in"), "{text}");
    let out = repertoire(&[&args[..], &["--record", "best:1"]].concat());
    assert!(!out.status.success() && String::from_utf8_lossy(&out.stderr).contains("successes:N or random:N"));
    // The controller with its sit timed by the planner's copy writes its own report.
    let args = ["meta", "eval", "--library", lib_s, "--trials", "1", "--zones", "front", "--horizon", "2"];
    let text = ok(&repertoire(&[&args[..], &["--controller", "oracle-sit"]].concat()));
    assert!(text.contains("| front | 1 |") && text.contains("timed by the planner's copy"), "{text}");
    assert!(meta.join("eval-oracle-sit/report.md").exists());
    // A gate threshold without a gate, and a gate missing its files, are refused by name.
    let out = repertoire(&[&args[..], &["--ready-at", "0.3"]].concat());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success() && err.contains("--controller gated"), "{err}");
    let none = dir.join("no-readiness");
    let out = repertoire(&[&args[..], &["--controller", &format!("gated:{}", none.display())]].concat());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success() && err.contains("no-readiness/readiness.ron"), "{err}");
    let out = repertoire(&[&args[..], &["--controller", "oracle-sit", "--ready-at", "1.5"]].concat());
    assert!(!out.status.success() && String::from_utf8_lossy(&out.stderr).contains("not a probability"));
    // The controller checked in a copy before it commits writes its own report; it cannot be
    // combined with another way of choosing, and zero candidates are refused.
    let text = ok(&repertoire(&[&args[..], &["--controller", "lookahead:2", "--lookahead-searches", "1"]].concat()));
    assert!(text.contains("| front | 1 |") && text.contains("looking ahead 2 candidates a search"), "{text}");
    assert!(meta.join("eval-lookahead/report.md").exists());
    for bad in [
        &["--controller", "lookahead:0"][..],
        &["--controller", "lookahead"],
        &["--controller", "dance"],
        &["--controller", "lookahead:2", "--oracle-sit"],
        &["--lookahead", "2", "--oracle-sit"],
        &["--controller", "planner", "--meta", meta_s],
        &["--lookahead-searches", "2"],
        &["--lookahead-every-candidate"],
    ] {
        let out = repertoire(&[&args[..], bad].concat());
        assert!(!out.status.success(), "{bad:?} was accepted");
    }
    // The older flags still choose as they did: --lookahead K is lookahead:K.
    let text = ok(&repertoire(&[&args[..], &["--lookahead", "2", "--lookahead-searches", "1"]].concat()));
    assert!(text.contains("looking ahead 2 candidates a search"), "{text}");
    // Two evaluations of the same trials compare trial by trial; other trials are refused.
    let (oracle, look, first) = (meta.join("eval-oracle-sit"), meta.join("eval-lookahead"), meta.join("eval"));
    let text = ok(&repertoire(&["meta", "compare", oracle.to_str().unwrap(), look.to_str().unwrap()]));
    assert!(text.contains("McNemar") && text.contains("| front | 1 |") && text.contains("| all | 1 |"), "{text}");
    let out = repertoire(&["meta", "compare", first.to_str().unwrap(), look.to_str().unwrap()]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success() && err.contains("not the same trials: 2 trials against 1"), "{err}");
    // Expert iteration needs the controller whose lookahead teaches.
    let out = repertoire(&["meta", "distill", "--library", lib_s, "--episodes", "1", "--lookahead", "2"]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success() && err.contains("--warm-start"), "{err}");
    // The main job runs the trained controller on the default scenario, with lookahead when asked.
    let text = ok(&repertoire(&["run", "--library", lib_s, "--trials", "1"]));
    assert!(text.contains("| front | 1 |") && text.contains("| behind | 1 |"), "{text}");
    let text = ok(&repertoire(&["run", "--library", lib_s, "--trials", "1", "--controller", "lookahead:2"]));
    assert!(text.contains("looking ahead 2 candidates") && text.contains("| behind | 1 |"), "{text}");
    // Without a controller it says how to get one.
    let text = ok(&repertoire(&["run", "--meta", dir.join("none").to_str().unwrap(), "--seconds", "0.5"]));
    assert!(text.contains("no trained meta-controller"), "{text}");
}

#[test]
fn the_ablation_study_plans_one_described_run_per_variant_and_seed() {
    let dir = common::temp_dir("cli-ablate");
    let spec = Path::new(env!("CARGO_MANIFEST_DIR")).join("ablations/sit.ron");
    let text = ok(&repertoire(&["ablate", spec.to_str().unwrap(), "--plan-only", "--out", dir.to_str().unwrap()]));
    assert!(text.contains("33 runs planned"), "{text}");
    let plan = std::fs::read_to_string(dir.join("runs/flat--the-sit-policy-alone-s1/plan.ron")).expect("plan file");
    assert!(plan.contains("\"--chain\"") && plan.contains("\"sit\""), "{plan}");
    // The budget can be overridden for a quick pass.
    let quick = dir.join("quick");
    let text = ok(&repertoire(&[
        "ablate",
        spec.to_str().unwrap(),
        "--plan-only",
        "--out",
        quick.to_str().unwrap(),
        "--seeds",
        "7",
        "--iterations",
        "5",
    ]));
    assert!(text.contains("11 runs planned"), "{text}");
    let plan = std::fs::read_to_string(quick.join("runs/full-model-s7/plan.ron")).expect("plan file");
    let compact: String = plan.split_whitespace().collect();
    assert!(compact.contains("\"--iterations\",\"5\"") && compact.contains("\"--seed\",\"7\""), "{plan}");
    let plan = std::fs::read_to_string(dir.join("runs/fixed-order-walk-l-turn-sit-s2/plan.ron")).expect("plan file");
    assert!(
        plan.contains("\"--chain\"") && plan.contains("\"walk_to,turn_left,sit\"") && plan.contains("\"--seed\""),
        "{plan}"
    );
    let plan = std::fs::read_to_string(dir.join("runs/no-curriculum-s1/plan.ron")).expect("plan file");
    assert!(plan.contains("--no-curriculum"), "{plan}");
    // A variant on another scenario trains and evaluates on it; the others on the default.
    let plan = std::fs::read_to_string(dir.join("runs/the-paper-s-approach-reward-s1/plan.ron")).expect("plan file");
    assert_eq!(plan.matches("scenarios/sit_paper_reward.ron").count(), 2, "{plan}");
    assert!(!std::fs::read_to_string(dir.join("runs/full-model-s1/plan.ron")).unwrap().contains("sit_paper_reward"));
    // A malformed study is refused with its place.
    let bad = dir.join("bad.ron");
    std::fs::write(&bad, "Ablation(seeds: [1], iterations: 1, trials: 1, variants: [Variant(nme: \"x\")])").unwrap();
    let out = repertoire(&["ablate", bad.to_str().unwrap(), "--plan-only"]);
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("bad.ron:1:") && err.contains("nme"), "{err}");
}

/// Writes `DIR/study.ron`: one iteration per run over the committed library, with `budget`
/// (seeds and trials) and `variants`.
fn study(dir: &Path, budget: &str, variants: &str) -> std::path::PathBuf {
    let library = Path::new(env!("CARGO_MANIFEST_DIR")).join("library");
    let spec = dir.join("study.ron");
    let text = format!("Ablation(library: \"{}\", iterations: 1, {budget}, variants: [{variants}])", library.display());
    std::fs::write(&spec, text).unwrap();
    spec
}

#[test]
fn a_tiny_ablation_runs_every_plan_then_gathers_the_table_and_its_chart() {
    // Two variants × two seeds, one iteration each, over the committed library: real training
    // and evaluation two runs at a time, then the table with a spread over seeds, the CSV and the
    // chart.
    let dir = common::temp_dir("cli-ablate-tiny");
    let spec = study(
        &dir,
        "seeds: [1, 2], trials: 2",
        "Variant(name: \"full model\"), \
         Variant(name: \"fixed order walk→l-turn→sit\", chain: [\"walk_to\", \"turn_left\", \"sit\"])",
    );
    let out = dir.join("study");
    // Two runs at a time: each logs into its own folder, a line as each ends.
    let text = ok(&repertoire(&["ablate", spec.to_str().unwrap(), "--out", out.to_str().unwrap(), "--jobs", "2"]));
    assert_eq!(text.matches("): done").count(), 4, "{text}");
    let log = std::fs::read_to_string(out.join("runs/fixed-order-walk-l-turn-sit-s2/log.txt")).unwrap();
    assert!(log.contains("meta-controller written to") && log.contains("| front |"), "training and evaluation: {log}");
    let md = std::fs::read_to_string(out.join("table.md")).unwrap();
    assert!(md.starts_with("| variant | seeds | front: success / min dist (m) |"), "{md}");
    assert!(md.contains("| falls, all zones |"), "{md}");
    assert!(text.contains(&md), "the table is printed too: {text}");
    for variant in ["full model", "fixed order walk→l-turn→sit"] {
        let row = md.lines().find(|l| l.starts_with(&format!("| {variant} | 2 |"))).unwrap_or_else(|| panic!("{md}"));
        assert_eq!(row.matches('±').count(), 2 * 4 + 1, "a spread per zone (success, distance) and for falls: {row}");
    }
    // The CSV's front success of the full model is the mean of its two seeds' reports.
    let front = |seed: u64| {
        let path = out.join(format!("runs/full-model-s{seed}/eval/report.json"));
        let r: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(&path).unwrap()).unwrap();
        100.0 * r["zones"][0]["success_rate"].as_f64().unwrap()
    };
    let csv = std::fs::read_to_string(out.join("table.csv")).unwrap();
    let mut lines = csv.lines();
    assert_eq!(
        lines.next(),
        Some(
            "variant,zone,seeds,success_mean,success_sd,min_distance_mean,min_distance_sd,fall_rate_mean,fall_rate_sd"
        )
    );
    let row: Vec<&str> =
        lines.find(|l| l.starts_with("full model,front,2,")).unwrap_or_else(|| panic!("{csv}")).split(',').collect();
    let mean: f64 = row[3].parse().unwrap();
    assert!((mean - (front(1) + front(2)) / 2.0).abs() < 1e-3, "{row:?}");
    assert_eq!(csv.lines().count(), 1 + 2 * 4, "{csv}");
    let svg = std::fs::read_to_string(out.join("ablation.svg")).unwrap();
    assert!(svg.contains("full model") && svg.contains("seeds 1, 2") && out.join("ablation.png").exists());
    // Run again, nothing is retrained (the reports exist); the page takes the chart along.
    let weights = out.join("runs/full-model-s1/meta/meta.safetensors");
    let before = std::fs::metadata(&weights).unwrap().modified().unwrap();
    ok(&repertoire(&["ablate", spec.to_str().unwrap(), "--out", out.to_str().unwrap()]));
    assert_eq!(std::fs::metadata(&weights).unwrap().modified().unwrap(), before, "a run with a report is skipped");
    ok(&repertoire(&["report", out.to_str().unwrap()]));
    let page = std::fs::read_to_string(out.join("report/index.md")).unwrap();
    assert!(
        page.contains("## Ablation") && page.contains("(ablation.png)") && out.join("report/ablation.png").exists(),
        "{page}"
    );
}

#[test]
fn an_ablation_run_that_fails_is_named_and_the_others_still_run() {
    let dir = common::temp_dir("cli-ablate-fail");
    let missing = dir.join("missing");
    let spec = study(
        &dir,
        "seeds: [1], trials: 1",
        &format!("Variant(name: \"full model\"), Variant(name: \"no library\", library: \"{}\")", missing.display()),
    );
    let out = dir.join("study");
    let run = repertoire(&["ablate", spec.to_str().unwrap(), "--out", out.to_str().unwrap(), "--jobs", "2"]);
    let err = String::from_utf8_lossy(&run.stderr);
    assert!(!run.status.success(), "{err}");
    assert!(err.contains("1 of 2 runs failed") && err.contains("no-library-s1/plan.ron"), "{err}");
    assert!(err.contains("no-library-s1/log.txt"), "names where its output went: {err}");
    assert!(out.join("runs/full-model-s1/eval/report.json").exists(), "the other run went on");
    assert!(!out.join("table.md").exists(), "no table from a study with a run missing");
}

#[test]
fn zero_iterations_are_refused_rather_than_run_as_one() {
    // `--iterations 0` used to train one iteration and write it into the library.
    let dir = common::temp_dir("cli-zero-iterations");
    let lib = dir.join("library");
    let walk = Path::new(env!("CARGO_MANIFEST_DIR")).join("specs/walk.ron");
    for args in [
        vec!["skill", "train", walk.to_str().unwrap(), "--iterations", "0", "--library", lib.to_str().unwrap()],
        vec!["meta", "train", "--iterations", "0", "--library", lib.to_str().unwrap()],
    ] {
        let out = repertoire(&args);
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(!out.status.success(), "{args:?} succeeded");
        assert!(err.contains("--iterations") && err.contains("at least 1"), "{args:?}: {err}");
    }
    assert!(!lib.exists(), "nothing was written");
}

#[test]
fn zero_iterations_from_a_warm_start_copy_the_controller_pinned_to_the_library() {
    // The re-pin after a skill was retrained: the networks bit for bit, the manifest pinned to
    // the library's skills and naming the controller it came from.
    let dir = common::temp_dir("cli-repin");
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let from = root.join("library/meta");
    let (library, out, run) = (root.join("library"), dir.join("meta"), dir.join("run"));
    let path = |p: &Path| p.to_str().unwrap().to_string();
    let args = ["meta", "train", "--iterations", "0", "--warm-start", &path(&from), "--library", &path(&library)];
    let stdout = common::ok(&repertoire(&[&args[..], &["--out", &path(&out), "--run-dir", &path(&run)]].concat()));
    assert!(stdout.contains("copied as it is") && stdout.contains("retrained since: none"), "{stdout}");
    for file in ["meta.safetensors", "meta.logits.safetensors", "meta.critic.safetensors"] {
        let (a, b) = (std::fs::read(from.join(file)).unwrap(), std::fs::read(out.join(file)).unwrap());
        assert!(a == b, "{file} is the controller's, bit for bit");
    }
    let weights = |text: &str| text.split("skill_weights: [").nth(1).unwrap().split(']').next().unwrap().to_string();
    let (shipped, copy) = (
        std::fs::read_to_string(from.join("meta.ron")).unwrap(),
        std::fs::read_to_string(out.join("meta.ron")).unwrap(),
    );
    assert_eq!(weights(&copy), weights(&shipped), "pinned to the library's skills");
    assert!(copy.contains("iterations: 0,") && copy.contains(&format!("from: \"{}\"", from.display())), "{copy}");
    assert!(copy.contains("curriculum: false,"), "no decision taken, so no curriculum ran: {copy}");
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn a_negative_or_non_finite_entropy_bonus_or_learning_rate_is_refused() {
    let dir = common::temp_dir("cli-ent-coef");
    let lib = dir.join("library");
    for bad in ["-0.01", "NaN", "inf"] {
        let flag = format!("--ent-coef={bad}");
        let out = repertoire(&["meta", "train", &flag, "--iterations", "1", "--library", lib.to_str().unwrap()]);
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(!out.status.success(), "--ent-coef {bad} succeeded");
        assert!(err.contains("--ent-coef") && err.contains("0 or more"), "--ent-coef {bad}: {err}");
    }
    for bad in ["0", "-1e-4", "NaN"] {
        let flag = format!("--learning-rate={bad}");
        let out = repertoire(&["meta", "train", &flag, "--iterations", "1", "--library", lib.to_str().unwrap()]);
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(!out.status.success() && err.contains("--learning-rate") && err.contains("above 0"), "{bad}: {err}");
    }
    assert!(!lib.exists(), "nothing was written");
}

#[test]
fn meta_deliver_refuses_one_file_for_both_pools() {
    let dir = common::temp_dir("cli-deliver");
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let spec = root.join("specs/sit_reach.ron");
    let lib = root.join("library");
    let same = dir.join("pool.ron");
    let out = repertoire(&[
        "meta",
        "deliver",
        "--planner",
        "--spec",
        spec.to_str().unwrap(),
        "--library",
        lib.to_str().unwrap(),
        "--trials",
        "50",
        "--out",
        same.to_str().unwrap(),
        "--handovers-out",
        same.to_str().unwrap(),
    ]);
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("--handovers-out") && err.contains("pool.ron"), "{err}");
    assert!(!same.exists(), "nothing written");
}

/// The number in `… N successful end poses written to …`.
fn poses_written(text: &str) -> usize {
    let line = text.lines().find(|l| l.contains("successful end poses written to")).expect("a pool line");
    line.split_whitespace().next().and_then(|n| n.parse().ok()).expect("a count")
}

/// The successes in a `| skill | start | trials | success | …` row (rounded from the rate).
fn successes(text: &str, start: &str) -> usize {
    let row = text.lines().find(|l| l.contains(start)).unwrap_or_else(|| panic!("no `{start}` row in {text}"));
    let cells: Vec<&str> = row.split('|').map(str::trim).collect();
    let trials: f64 = cells[3].parse().unwrap();
    let rate: f64 = cells[4].trim_end_matches('%').parse().unwrap();
    (trials * rate / 100.0).round() as usize
}

#[test]
fn skill_eval_takes_its_pool_from_the_trials_pool_from_names() {
    // The committed sit and turns: from the clip start the sit succeeds far more often than from
    // the turns' end poses (96 / 50 % over 1000 trials), so the two pools differ in size.
    let dir = common::temp_dir("cli-pool-from");
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let lib = dir.join("library");
    for name in ["sit", "turn_left", "turn_right"] {
        std::fs::create_dir_all(lib.join(name)).unwrap();
        for file in ["manifest.ron", "policy.safetensors", "end_poses.ron"] {
            std::fs::copy(root.join("library").join(name).join(file), lib.join(name).join(file)).unwrap();
        }
    }
    let spec = root.join("specs/sit.ron");
    let eval = |pool_from: &str| {
        ok(&repertoire(&[
            "skill",
            "eval",
            spec.to_str().unwrap(),
            "--library",
            lib.to_str().unwrap(),
            "--from",
            "turn_left,turn_right",
            "--trials",
            "40",
            "--batch",
            "8",
            "--pool-from",
            pool_from,
        ]))
    };
    let clip = eval("clip-start");
    let (from_clip, from_turns) = (successes(&clip, "clip start"), successes(&clip, "end poses of"));
    assert_ne!(from_clip, from_turns, "the test needs the two starts to differ: {clip}");
    assert_eq!(poses_written(&clip), from_clip, "{clip}");
    let pred = eval("predecessors");
    assert_eq!(poses_written(&pred), from_turns, "{pred}");
    let pool = std::fs::read_to_string(lib.join("sit/end_poses.ron")).unwrap();
    assert_eq!(pool.matches("height:").count(), from_turns, "the file holds the predecessors' successes");

    // Without predecessors there is nothing to take the pool from.
    let out = repertoire(&[
        "skill",
        "eval",
        root.join("specs/walk.ron").to_str().unwrap(),
        "--library",
        lib.to_str().unwrap(),
        "--trials",
        "2",
        "--pool-from",
        "predecessors",
    ]);
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("--pool-from predecessors") && err.contains("walk.ron"), "{err}");
}
