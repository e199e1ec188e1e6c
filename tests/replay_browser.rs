//! The replay page in a real browser: a short real rollout (the committed sit skill started from
//! a turn's end pose, with the chair and the reference ghost) is recorded, written as HTML by
//! the CLI, and opened in headless Chromium
//! (Debian's `chromium`, driven by `playwright-core`; both installed by `scripts/setup.sh`).
//! The page must draw its canvas, advance its timeline and log no error. The screenshot is
//! kept as `target/test-artifacts/replay.png`.

mod common;

use std::path::{Path, PathBuf};
use std::process::Command;

const SETUP: &str =
    "run `bash scripts/setup.sh` (it installs Debian's chromium and runs `npm ci` in crates/scenes/web)";

fn artifacts() -> PathBuf {
    // CARGO_TARGET_TMPDIR is <target>/tmp.
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR")).parent().expect("target dir").join("test-artifacts");
    std::fs::create_dir_all(&dir).expect("artifact folder");
    dir
}

#[test]
fn replay_page_draws_plays_and_logs_no_error() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let chromium = std::env::var("CHROMIUM").unwrap_or_else(|_| "/usr/bin/chromium".into());
    assert!(Path::new(&chromium).exists(), "{chromium} is missing: {SETUP}");
    let web = root.join("crates/scenes/web/node_modules");
    assert!(
        web.join("three/build/three.module.js").exists() && web.join("playwright-core").exists(),
        "{} lacks three or playwright-core: {SETUP}",
        web.display()
    );
    let node = Command::new("node").arg("--version").output();
    assert!(node.is_ok_and(|o| o.status.success()), "node is not installed (Node 18 or newer): {SETUP}");

    let dir = common::temp_dir("replay-browser");
    let (rec, html) = (dir.join("sit.rec"), dir.join("sit.html"));
    let spec = root.join("specs/sit.ron");
    let out = Command::new(env!("CARGO_BIN_EXE_repertoire"))
        .args(["skill", "play", spec.to_str().unwrap(), "--record", rec.to_str().unwrap()])
        .args(["--from", "turn_left,turn_right", "--seed", "1"])
        .args(["--html", html.to_str().unwrap(), "--library", root.join("library").to_str().unwrap()])
        .output()
        .expect("run repertoire");
    assert!(out.status.success(), "skill play failed: {}", String::from_utf8_lossy(&out.stderr));
    let page = std::fs::read_to_string(&html).expect("the page");
    assert!(page.contains("id=\"recording\"") && page.contains("REVISION"), "three.js or the data is not inlined");
    assert!(!page.contains("src=\"http") && !page.contains("src=\"//"), "the page must not load anything");

    let shot = artifacts().join("replay.png");
    let _ = std::fs::remove_file(&shot);
    let check = Command::new("node")
        .arg(root.join("tests/browser/replay_check.mjs"))
        .args([&html, &shot])
        .env("CHROMIUM", &chromium)
        .output()
        .expect("run node");
    let stdout = String::from_utf8_lossy(&check.stdout);
    let stderr = String::from_utf8_lossy(&check.stderr);
    assert!(check.status.success(), "the replay page failed in Chromium:\n{stderr}\n{stdout}");
    assert!(std::fs::metadata(&shot).is_ok_and(|m| m.len() > 10_000), "no screenshot at {}", shot.display());
    // The sit starts standing where a turn left the body: both feet are on the floor in some
    // frames, and the page counted them (format 2 records the feet's contact).
    let feet = stdout
        .split_once("\"foot_frames\":[")
        .and_then(|(_, rest)| rest.split_once(']'))
        .map(|(list, _)| list.split(',').map(|n| n.trim().parse::<usize>().unwrap_or(0)).collect::<Vec<_>>());
    assert!(feet.as_ref().is_some_and(|f| f.len() == 2 && f.iter().all(|&n| n > 0)), "foot frames {feet:?}: {stdout}");
    println!("{stdout}screenshot: {}", shot.display());
}

#[test]
fn the_replay_page_names_the_prop_under_the_pelvis() {
    // The warehouse fixture of tests/falls.rs: at frame 60 the carrier's pelvis rests on the box
    // (once labelled "pelvis on seat" whatever the prop).
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let chromium = std::env::var("CHROMIUM").unwrap_or_else(|_| "/usr/bin/chromium".into());
    assert!(Path::new(&chromium).exists(), "{chromium} is missing: {SETUP}");
    let dir = common::temp_dir("replay-labels");
    let html = dir.join("warehouse.html");
    let rec = root.join("tests/data/falls/warehouse_headstand_on_pedestal.rec");
    let out = Command::new(env!("CARGO_BIN_EXE_repertoire"))
        .args(["replay", rec.to_str().unwrap(), "-o", html.to_str().unwrap()])
        .output()
        .expect("run repertoire");
    assert!(out.status.success(), "replay failed: {}", String::from_utf8_lossy(&out.stderr));
    let check = Command::new("node")
        .arg(root.join("tests/browser/replay_check.mjs"))
        .args([html.as_os_str(), dir.join("warehouse.png").as_os_str()])
        .args(["60", "pelvis on box", "10", "contacts hand on prop"])
        .env("CHROMIUM", &chromium)
        .output()
        .expect("run node");
    let stdout = String::from_utf8_lossy(&check.stdout);
    assert!(check.status.success(), "{}\n{stdout}", String::from_utf8_lossy(&check.stderr));
    assert!(stdout.contains("pelvis on box"), "{stdout}");
}

/// Width and height of a PNG, from its IHDR chunk.
fn png_size(path: &Path) -> (u32, u32) {
    let bytes = std::fs::read(path).expect("the PNG");
    assert_eq!(&bytes[..8], b"\x89PNG\r\n\x1a\n", "{} is not a PNG", path.display());
    let be = |at: usize| u32::from_be_bytes(bytes[at..at + 4].try_into().unwrap());
    (be(16), be(20))
}

#[test]
fn a_filmstrip_tiles_evenly_spaced_frames_with_their_captions() {
    // The warehouse fixture again: six frames from above, three to a row, into one PNG of
    // 480 × (360 + a 22 px caption) tiles.
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let chromium = std::env::var("CHROMIUM").unwrap_or_else(|_| "/usr/bin/chromium".into());
    assert!(Path::new(&chromium).exists(), "{chromium} is missing: {SETUP}");
    let dir = common::temp_dir("filmstrip");
    let (html, png) = (dir.join("warehouse.html"), dir.join("strip/warehouse.png"));
    let rec = root.join("tests/data/falls/warehouse_headstand_on_pedestal.rec");
    let run = |extra: &[&str]| {
        Command::new(env!("CARGO_BIN_EXE_repertoire"))
            .args(["replay", rec.to_str().unwrap(), "-o", html.to_str().unwrap()])
            .args(extra)
            .env("CHROMIUM", &chromium)
            .output()
            .expect("run repertoire")
    };
    let out = run(&["--filmstrip", png.to_str().unwrap(), "--frames", "6", "--columns", "3", "--view", "top"]);
    assert!(out.status.success(), "filmstrip failed: {}", String::from_utf8_lossy(&out.stderr));
    assert_eq!(png_size(&png), (3 * 480, 2 * (360 + 22)));
    // Drawn frames, not an empty sheet: a blank 1440 × 764 PNG compresses to a few kB.
    let bytes = std::fs::metadata(&png).unwrap().len();
    assert!(bytes > 100_000, "{} is only {bytes} bytes", png.display());
    assert!(!png.with_extension("png.tmp").exists(), "the temporary file was left");
    // More columns than frames: one row.
    let out = run(&["--filmstrip", png.to_str().unwrap(), "--frames", "2", "--columns", "4"]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    assert_eq!(png_size(&png), (2 * 480, 360 + 22));
    for bad in [
        &["--filmstrip", "x.png", "--frames", "0"][..],
        &["--filmstrip", "x.png", "--view", "back"],
        &["--frames", "3"],
    ] {
        assert!(!run(bad).status.success(), "{bad:?} was accepted");
    }
}
