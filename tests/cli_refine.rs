//! `repertoire meta refine`: a skill fine-tuned in the controller's episodes, through the binary,
//! on a copy of the committed library (it never writes into `library`).

mod common;

use std::path::{Path, PathBuf};

use common::{ok, repertoire, temp_dir};

/// A copy of the committed library's sitting skills and controller.
fn sitting_library(name: &str) -> PathBuf {
    let lib = temp_dir(name);
    for skill in ["walk_to", "turn_left", "turn_right", "turn_left_wide", "turn_right_wide", "stand", "sit", "meta"] {
        let to = lib.join(skill);
        std::fs::create_dir_all(&to).unwrap();
        for f in std::fs::read_dir(Path::new("library").join(skill)).unwrap() {
            let f = f.unwrap().path();
            if f.is_file() {
                std::fs::copy(&f, to.join(f.file_name().unwrap())).unwrap();
            }
        }
    }
    lib
}

/// `repertoire meta refine --spec specs/SPEC --library LIB` with `more` after it.
fn refine(spec: &str, lib: &Path, more: &[&str]) -> std::process::Output {
    let (spec, lib) = (format!("specs/{spec}"), lib.display().to_string());
    let mut args = vec!["meta", "refine", "--spec", &spec, "--library", &lib];
    args.extend_from_slice(more);
    repertoire(&args)
}

#[test]
fn refine_writes_the_skill_and_says_how_to_re_pin_the_controller() {
    let lib = sitting_library("refine-library");
    let run = lib.join("run");
    let before = std::fs::read(lib.join("walk_to/policy.safetensors")).unwrap();
    let r = run.display().to_string();
    let out = ok(&refine(
        "walk_to.ron",
        &lib,
        &["--iterations", "1", "--envs", "2", "--run-dir", &r, "--skill-weight", "0.5", "--task-weight", "4"],
    ));
    assert!(out.contains("| walk_to | 1 |") && out.contains("re-pin the controller"), "{out}");
    assert!(out.contains("success") && out.contains("`walk_to` fell in"), "{out}");
    assert_ne!(std::fs::read(lib.join("walk_to/policy.safetensors")).unwrap(), before, "the weights were written back");
    assert!(run.join("metrics.csv").exists());
    // The controller is pinned to the old walk_to: evaluating it over the new one is refused
    // until it is re-pinned.
    let out = repertoire(&["meta", "eval", "--library", &lib.display().to_string(), "--trials", "1"]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success() && err.contains("walk_to"), "{err}");
}

#[test]
fn refine_refuses_a_skill_outside_the_graph_and_bad_weights() {
    let lib = sitting_library("refine-refusals");
    let out = refine("catch.ron", &lib, &[]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success() && err.contains("no skill `catch`") && err.contains("sit"), "{err}");
    let out = refine("walk_to.ron", &lib, &["--skill-weight", "-1"]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success() && err.contains("--skill-weight") && err.contains("0 or more"), "{err}");
}
