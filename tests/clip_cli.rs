//! `repertoire clip check` on a real clip (table and output file) and on unusable ones.

mod common;

use common::{temp_dir, write};
use std::path::Path;
use std::process::Command;

const MOCAP: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/mocap");

fn repertoire(dir: &Path, args: &[&str]) -> std::process::Output {
    Command::new(env!("CARGO_BIN_EXE_repertoire")).current_dir(dir).args(args).output().expect("runs")
}

#[test]
fn clip_check_prints_the_table_and_writes_the_clip() {
    let dir = temp_dir("clip-check");
    let file = format!("{MOCAP}/cmu-subject16-30fps/16_19_walk_90deg_right_turn.bvh");
    let out = repertoire(&dir, &["clip", "check", &file, "--body", "humanoid", "--fps", "60"]);
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(out.status.success(), "{stdout}\n{}", String::from_utf8_lossy(&out.stderr));
    for needle in
        ["map       cmu-subject16-bvh", "left_knee", "right_hand", "foot penetration", "foot skate", "root drift"]
    {
        assert!(stdout.contains(needle), "missing `{needle}`:\n{stdout}");
    }
    let heading = stdout.lines().find(|l| l.starts_with("heading change")).expect("heading line");
    let deg: f64 = heading.split_whitespace().nth(2).unwrap().trim_end_matches('°').parse().unwrap();
    assert!(deg < -60.0, "a right turn: {heading}");
    let all = stdout.lines().find(|l| l.trim_start().starts_with("all")).expect("overall error line");
    let mean: f64 = all.split_whitespace().nth(1).unwrap().parse().unwrap();
    assert!(mean < 4.0, "{all}");
    let written = dir.join("16_19_walk_90deg_right_turn.clip.ron");
    let clip = repertoire_clip::Clip::load(&written).expect("the written clip loads");
    assert_eq!(clip.fps, 60.0);
    assert_eq!(clip.nq, 32);
    assert!(stdout.contains(&clip.content_hash()), "prints the clip's hash");

    let npy = dir.join("turn.npy");
    let out = repertoire(&dir, &["clip", "check", &file, "--out", npy.to_str().unwrap()]);
    assert!(out.status.success());
    assert!(npy.exists() && dir.join("turn.meta.ron").exists());
}

#[test]
fn clip_check_refuses_unusable_clips_with_a_reason() {
    let dir = temp_dir("clip-check-bad");
    let walk = std::fs::read_to_string(format!("{MOCAP}/cmu-subject16-30fps/16_15_walk.bvh")).unwrap();
    let motion = walk.find("MOTION").unwrap();
    let header = &walk[..motion];
    let frames: Vec<&str> = walk[motion..].lines().skip(3).collect();

    // One frame only.
    let short = write(&dir, "short.bvh", &format!("{header}MOTION\nFrames: 1\nFrame Time: 0.0333333\n{}\n", frames[0]));
    let out = repertoire(&dir, &["clip", "check", short.to_str().unwrap()]);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success());
    assert!(stderr.contains("short.bvh") && stderr.contains("too short"), "{stderr}");

    // A NaN value in frame 1.
    let mut bad = frames[..3].to_vec();
    let nan_line = bad[1].replacen(bad[1].split_whitespace().next().unwrap(), "nan", 1);
    bad[1] = &nan_line;
    let nan =
        write(&dir, "nan.bvh", &format!("{header}MOTION\nFrames: 3\nFrame Time: 0.0333333\n{}\n", bad.join("\n")));
    let out = repertoire(&dir, &["clip", "check", nan.to_str().unwrap()]);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success());
    assert!(stderr.contains("nan.bvh") && stderr.contains("frame 1"), "{stderr}");

    // A map naming a joint the file lacks.
    let map = std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/crates/clip/maps/cmu-subject16.bvh.ron"))
        .unwrap()
        .replace("\"lfoot\"", "\"lankle\"")
        .replace("\"rhand\"", "\"rwrist\"");
    let map = write(&dir, "my.map.ron", &map);
    let file = format!("{MOCAP}/cmu-subject16-30fps/16_15_walk.bvh");
    let out = repertoire(&dir, &["clip", "check", &file, "--map", map.to_str().unwrap()]);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success());
    assert!(stderr.contains("my.map.ron:") && stderr.contains("`lankle`"), "{stderr}");
    // Every missing joint at once, not one per attempt.
    assert!(stderr.contains("source joints `lankle` (LeftAnkle), `rwrist` (RightHand) are not in"), "{stderr}");
    assert!(!dir.join("16_15_walk.clip.ron").exists(), "nothing written for an unusable clip");
}

#[test]
fn a_clip_retargeted_onto_another_body_is_refused_by_play_and_train() {
    // Another body: the built-in humanoid with a larger head (same joints, another content hash),
    // in a scenario of its own.
    let dir = temp_dir("clip-other-body");
    let builtin = repertoire::scenes::BodyDef::humanoid();
    let xml = builtin.mjcf.replace(r#"size="0.095" mass="4.5""#, r#"size="0.105" mass="4.5""#);
    assert_ne!(xml, builtin.mjcf, "the head's size changed");
    write(&dir, "big_head.xml", &xml);
    write(&dir, "big_head.map.ron", &builtin.map_text);
    write(
        &dir,
        "scene.ron",
        "Scenario(name: \"big head\", body: Mjcf(file: \"big_head.xml\", map: \"big_head.map.ron\"))",
    );
    let file = format!("{MOCAP}/cmu-subject16-30fps/16_19_walk_90deg_right_turn.bvh");
    let out = repertoire(&dir, &["clip", "check", &file, "--body", "humanoid", "--out", "walk.clip.ron"]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));

    // Played on its own body it records; on the other body it is refused, saying what to do.
    let out = repertoire(&dir, &["clip", "play", "walk.clip.ron", "--record", "own.rec"]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let out = repertoire(&dir, &["clip", "play", "walk.clip.ron", "--scene", "scene.ron", "--record", "other.rec"]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success() && !dir.join("other.rec").exists(), "{err}");
    assert!(err.contains("retargeted onto another body") && err.contains("--body big_head.xml"), "{err}");
    assert!(!err.contains("panicked"), "{err}");

    // A skill whose spec's clip was made for another body is refused before training.
    let spec = std::fs::read_to_string(Path::new(env!("CARGO_MANIFEST_DIR")).join("specs/walk.ron")).unwrap();
    let clip_line = spec.lines().find(|l| l.trim_start().starts_with("clip:")).expect("walk.ron names its clip");
    let spec = spec
        .replace(clip_line, "    clip: (file: \"walk.clip.ron\"),")
        .replace("scene: \"arena.ron\"", "scene: \"scene.ron\"");
    write(&dir, "walk.ron", &spec);
    let out = repertoire(&dir, &["skill", "train", "walk.ron", "--iterations", "1", "--library", "lib"]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success() && err.contains("retargeted onto another body"), "{err}");
}

/// The shipped map of CMU subject 16's BVH export, for tests to alter.
const SUBJECT16_MAP: &str = include_str!("../crates/clip/maps/cmu-subject16.bvh.ron");

/// `clip check` of the 16_15 walk with `map` written as a user's map file in `dir`: its output,
/// the command having succeeded (a poor fit is a warning, not a refusal).
fn check_walk_with_map(dir: &Path, map: &str) -> String {
    let map = write(dir, "user.map.ron", map);
    let file = format!("{MOCAP}/cmu-subject16-30fps/16_15_walk.bvh");
    let out = repertoire(dir, &["clip", "check", &file, "--map", map.to_str().unwrap()]);
    let stdout = String::from_utf8_lossy(&out.stdout).into_owned();
    assert!(out.status.success(), "a warning, not a refusal: {stdout}");
    stdout
}

#[test]
fn a_map_that_fits_the_skeleton_poorly_is_warned_about_with_the_maps_that_would_take_it() {
    // A user's map with the arms' source joints swapped left for right: every joint exists, so
    // it is accepted, but the hands cannot reach where the source puts them.
    let dir = temp_dir("clip-poor-fit");
    let shipped = SUBJECT16_MAP;
    let mut map = shipped.replace("name: \"cmu-subject16-bvh\"", "name: \"mine\"");
    for (a, b) in [("lhand", "rhand"), ("lradius", "rradius")] {
        map = map
            .replace(&format!("source: \"{a}\""), "source: \"SWAP\"")
            .replace(&format!("source: \"{b}\""), &format!("source: \"{a}\""))
            .replace("source: \"SWAP\"", &format!("source: \"{b}\""));
    }
    assert_ne!(map, shipped);
    let stdout = check_walk_with_map(&dir, &map);
    let warning = stdout.lines().find(|l| l.starts_with("warning")).unwrap_or_else(|| panic!("no warning:\n{stdout}"));
    assert!(
        warning.contains("fits this skeleton poorly") && warning.contains("cmu-subject16-bvh (--map)"),
        "{warning}"
    );
    // The shipped map on the same file fits: no warning.
    let file = format!("{MOCAP}/cmu-subject16-30fps/16_15_walk.bvh");
    let out = repertoire(&dir, &["clip", "check", &file]);
    assert!(!String::from_utf8_lossy(&out.stdout).contains("warning"));
}

#[test]
fn a_key_point_far_off_is_named_even_when_the_mean_error_is_low() {
    // The left toe point driven by the knee joint: the mean over all points stays under the
    // poor-fit bound, but the toe cannot reach back up to the knee, and `clip check` names it.
    let dir = temp_dir("clip-point-off");
    let map = SUBJECT16_MAP.replace("source: \"ltoes\"", "source: \"ltibia\"");
    assert_ne!(map, SUBJECT16_MAP);
    let stdout = check_walk_with_map(&dir, &map);
    let all = stdout.lines().find(|l| l.trim_start().starts_with("all")).expect("overall error line");
    let mean: f64 = all.split_whitespace().nth(1).unwrap().parse().unwrap();
    assert!(mean <= 5.0, "the mean stays low: {all}");
    let warning = stdout.lines().find(|l| l.starts_with("warning")).unwrap_or_else(|| panic!("no warning:\n{stdout}"));
    assert!(
        warning.contains("one key point") && warning.contains("left_toe") && !warning.contains("right_toe"),
        "{warning}"
    );
}
