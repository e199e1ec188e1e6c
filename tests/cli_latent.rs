//! `repertoire latent collect / train / eval` end to end with tiny budgets on the committed
//! walk skill, and bad input named by file (and line and column for a RON config).

mod common;

use std::path::Path;

use common::{ok, repertoire};

#[test]
fn collect_train_and_eval_a_latent_model() {
    let dir = common::temp_dir("cli-latent");
    let data = dir.join("data");
    let text = ok(&repertoire(&[
        "latent",
        "collect",
        "--skills",
        "walk",
        "--steps",
        "200",
        "--batch",
        "4",
        "--out",
        data.to_str().unwrap(),
    ]));
    assert!(text.contains("| walk | 200 |") && text.contains("per 10^5 steps"), "{text}");
    assert!(data.join("dataset.ron").exists() && data.join("dataset.safetensors").exists());

    let config = common::write(
        &dir,
        "tiny.ron",
        "LatentConfig(latent_dim: 4, encoder_hidden: [16], decoder_hidden: [16], seq_len: 4, batch_sequences: 4)",
    );
    let model = dir.join("model");
    let text = ok(&repertoire(&[
        "latent",
        "train",
        data.to_str().unwrap(),
        "--config",
        config.to_str().unwrap(),
        "--updates",
        "60",
        "--out",
        model.to_str().unwrap(),
    ]));
    assert!(text.contains("| 60 |"), "{text}");
    assert!(model.join("latent.ron").exists() && model.join("latent.safetensors").exists());
    let csv = std::fs::read_to_string(model.join("metrics.csv")).unwrap();
    assert_eq!(csv.lines().count(), 1 + 60 / 50 + 1, "{csv}");

    let text = ok(&repertoire(&["latent", "eval", model.to_str().unwrap(), "--skills", "walk", "--episodes", "2"]));
    assert!(text.contains("| walk | 2 |") && text.contains("| mean |"), "{text}");
    assert!(model.join("eval/one_shot.md").exists() && model.join("eval/one_shot.csv").exists());

    // An AWR model beside it, both compared on the same starts; turn_left is in neither
    // dataset, so it is marked held out.
    let awr = dir.join("awr");
    let args = ["--config", config.to_str().unwrap(), "--updates", "60", "--weighting", "awr", "--out"];
    ok(&repertoire(&[&["latent", "train", data.to_str().unwrap()][..], &args, &[awr.to_str().unwrap()]].concat()));
    let manifest = std::fs::read_to_string(awr.join("latent.ron")).unwrap();
    assert!(manifest.contains("weighting: Awr("), "{manifest}");
    let compare = dir.join("compare");
    let pair = [model.to_str().unwrap(), awr.to_str().unwrap(), "--skills", "walk,turn_left", "--episodes", "2"];
    let out = repertoire(&[&["latent", "eval"][..], &pair].concat());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success() && err.contains("--out"), "{err}");
    // A real CMU walk no expert was trained on, tracked by each latent model alone.
    let clip = ["--clip", "mocap/cmu-subject16-30fps/16_15_walk.bvh"];
    let text =
        ok(&repertoire(&[&["latent", "eval"][..], &pair, &clip, &["--out", compare.to_str().unwrap()]].concat()));
    assert!(text.contains("| model | BC | 60 |") && text.contains("| awr | AWR, temperature 1 | 60 |"), "{text}");
    assert!(text.contains("| model | 16_15_walk.bvh | 2 |") && text.contains("| awr | 16_15_walk.bvh | 2 |"), "{text}");
    let out = repertoire(&["latent", "eval", model.to_str().unwrap(), "--skills", "walk", "--clip", "no-such.bvh"]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success() && err.contains("no-such.bvh"), "{err}");
    assert!(text.contains("turn_left (held out)") && text.contains("mean, held-out clips"), "{text}");
    for name in ["model", "awr"] {
        let table = std::fs::read_to_string(compare.join(name).join("one_shot.md")).unwrap();
        assert!(table.contains("| turn_left (held out) | 2 |") && table.contains("| mean, trained clips |"), "{table}");
        assert!(table.contains(&format!("| {name} | 16_15_walk.bvh | 2 |")), "{table}");
    }
    assert!(std::fs::read_to_string(compare.join("comparison.md")).unwrap().contains("the same starts"));

    // A high level over z for one PPO iteration, beside z = 0.
    let text = ok(&repertoire(&[
        "latent",
        "goto",
        model.to_str().unwrap(),
        "--iterations",
        "1",
        "--envs",
        "2",
        "--steps",
        "8",
        "--trials",
        "2",
        "--run-dir",
        dir.join("goto-run").to_str().unwrap(),
    ]));
    assert!(text.contains("| constant z = 0 | 2 |") && text.contains("| PPO over z | 2 |"), "{text}");
    assert!(model.join("goto/goto.md").exists() && model.join("goto/high_level.safetensors").exists());
    assert!(dir.join("goto-run/metrics.csv").exists());

    // A config with an unknown field, a missing dataset, a missing spec.
    let bad = common::write(&dir, "bad.ron", "LatentConfig(\n  latent_dim: 4,\n  wings: 2,\n)");
    let out = repertoire(&["latent", "train", data.to_str().unwrap(), "--config", bad.to_str().unwrap()]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success() && err.contains("bad.ron:3:") && err.contains("wings"), "{err}");
    let out = repertoire(&["latent", "train", dir.join("nothing").to_str().unwrap()]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success() && err.contains("nothing") && err.contains("dataset.ron"), "{err}");
    let out = repertoire(&["latent", "collect", "--skills", "fly", "--out", dir.join("x").to_str().unwrap()]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success() && err.contains("fly.ron"), "{err}");
    assert!(!Path::new(&dir.join("x")).exists(), "nothing written for a bad collect");
}
