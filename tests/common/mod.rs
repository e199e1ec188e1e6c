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
