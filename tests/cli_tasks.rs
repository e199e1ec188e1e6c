//! The warehouse and toss scenarios through the `repertoire` binary: `scene check` accepts both,
//! and the meta-controller commands name the skills a library lacks instead of failing later.

mod common;

use common::{ok, repertoire, temp_dir};

#[test]
fn scene_check_accepts_the_warehouse_and_the_toss() {
    let out = ok(&repertoire(&["scene", "check", "scenes/warehouse.ron"]));
    assert!(out.contains("pedestal_a") && out.contains("2.5..3.5 m at -45..45°") && out.ends_with("ok\n"), "{out}");
    let out = ok(&repertoire(&["scene", "check", "scenes/toss.ron"]));
    assert!(out.contains("Toss(") && out.contains("v_x: Uniform(1.5, 4.5)") && out.ends_with("ok\n"), "{out}");
}

#[test]
fn meta_commands_name_the_missing_warehouse_and_toss_skills() {
    // A library holding only walk, copied from the committed one (which may gain the others).
    let lib = temp_dir("walk-only-library");
    std::fs::create_dir_all(lib.join("walk")).unwrap();
    for f in std::fs::read_dir("skills/library/walk").unwrap() {
        let f = f.unwrap().path();
        if f.is_file() {
            std::fs::copy(&f, lib.join("walk").join(f.file_name().unwrap())).unwrap();
        }
    }
    let lib = lib.display().to_string();
    for (file, missing) in [
        ("scenes/warehouse.ron", "turn_left, turn_right, lift, carry, put_down"),
        ("scenes/toss.ron", "turn_left, turn_right, catch, put_down"),
    ] {
        for cmd in ["train", "eval"] {
            let out = repertoire(&["meta", cmd, file, "--library", &lib]);
            assert!(!out.status.success(), "{cmd} {file} succeeded");
            let err = String::from_utf8_lossy(&out.stderr);
            assert!(err.contains(file) && err.contains(missing) && err.contains("--skills"), "{cmd} {file}: {err}");
        }
    }
}
