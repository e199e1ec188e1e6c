//! Helpers shared by the integration tests.
#![allow(dead_code)]

use repertoire::scenes::{ScenarioFile, WorldModel};
use std::path::{Path, PathBuf};
use std::sync::Arc;

/// A fresh, empty folder under the system temp dir for one test.
pub fn temp_dir(test: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("repertoire-test-{}-{test}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).expect("temp dir");
    dir
}

/// Writes `text` to `dir/name` and returns the path.
pub fn write(dir: &Path, name: &str, text: &str) -> PathBuf {
    let path = dir.join(name);
    std::fs::write(&path, text).expect("write test file");
    path
}

/// The built-in default scene.
pub fn default_model() -> Arc<WorldModel> {
    Arc::new(WorldModel::build(ScenarioFile::builtin_default()).expect("default scene builds"))
}

/// A scene built from scenario text.
pub fn model_from(text: &str) -> Arc<WorldModel> {
    let file = ScenarioFile::parse(Path::new("test.ron"), text.to_string()).expect("scenario parses");
    Arc::new(WorldModel::build(file).expect("scene builds"))
}

/// Runs the `repertoire` binary built for these tests with `args`.
pub fn repertoire(args: &[&str]) -> std::process::Output {
    std::process::Command::new(env!("CARGO_BIN_EXE_repertoire")).args(args).output().expect("run repertoire")
}

/// The standard output of a run that must have succeeded (else the test fails with both streams).
pub fn ok(out: &std::process::Output) -> String {
    let text = String::from_utf8_lossy(&out.stdout).into_owned();
    assert!(out.status.success(), "exit {:?}\n{text}\n{}", out.status, String::from_utf8_lossy(&out.stderr));
    text
}

/// The tiny recipe, working in `dir/work`, its fine-tunes taking `fraction` of their episodes
/// from the pool.
pub fn tiny_recipe(dir: &Path, fraction: &str) -> PathBuf {
    let text = format!(
        r#"(
    about: "a tiny walk: trained, its pool evaluated, fine-tuned from its own end poses in two rounds",
    work: "{work}",
    vars: {{"fraction": "{fraction}"}},
    stages: [
        Run(name: "walk", args: ["skill", "train", "specs/walk.ron", "--library", "{{work}}/lib", "--run-dir", "{{work}}/runs/walk",
            "--iterations", "2", "--envs", "2", "--serial", "--checkpoint-every", "1"], writes: ["{{work}}/lib/walk"], resume: "{{work}}/runs/walk"),
        Run(name: "pool", args: ["skill", "eval", "specs/walk.ron", "--library", "{{work}}/lib", "--trials", "4", "--batch", "2"],
            writes: ["{{work}}/lib/walk/end_poses.ron"]),
        Rounds(name: "tune", max: 2, stages: [
            Run(name: "finetune", args: ["skill", "finetune", "specs/walk.ron", "--from", "walk", "--fraction", "{{fraction}}",
                "--library", "{{work}}/lib", "--run-dir", "{{work}}/runs/tune-{{round}}", "--iterations", "2", "--envs", "2", "--serial",
                "--checkpoint-every", "1"],
                writes: ["{{work}}/lib/walk"], resume: "{{work}}/runs/tune-{{round}}"),
        ]),
    ],
)"#,
        work = dir.join("work").display()
    );
    let path = dir.join("tiny.ron");
    std::fs::write(&path, text).unwrap();
    path
}
