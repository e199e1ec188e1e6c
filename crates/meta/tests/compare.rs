//! `meta compare`: two sitting evaluations paired trial by trial.

use std::path::{Path, PathBuf};

use repertoire_meta::compare::{compare, read_trials};

const HEADER: &str = "index,zone,x,y,yaw,side,success,fell,min_distance,seconds,skills,touched\n";

fn dir() -> PathBuf {
    let d = std::env::temp_dir().join(format!("repertoire-compare-{}", std::process::id()));
    std::fs::create_dir_all(&d).unwrap();
    d
}

/// A trials.csv with one row per (zone, success, fell), starts from the index.
fn write(path: &Path, rows: &[(&str, bool, bool)]) {
    let mut s = String::from(HEADER);
    for (i, (zone, success, fell)) in rows.iter().enumerate() {
        s.push_str(&format!(
            "{i},{zone},{:.4},0.5000,1.0000,left,{success},{fell},0.3000,6.00,walk_to>sit,\n",
            i as f64 * 0.1
        ));
    }
    std::fs::write(path, s).unwrap();
}

#[test]
fn paired_trials_give_the_discordant_counts_and_mcnemar_and_other_trials_are_refused() {
    let d = dir();
    let (a, b) = (d.join("a.csv"), d.join("b.csv"));
    // front: A seats 0, 1; B seats 1, 2, 3. behind: A seats 4; B seats nothing, falls on 5.
    let zones = ["front", "front", "front", "front", "behind", "behind"];
    let seat_a = [true, true, false, false, true, false];
    let seat_b = [false, true, true, true, false, false];
    let rows_a: Vec<_> = zones.iter().zip(seat_a).map(|(z, s)| (*z, s, !s)).collect();
    let rows_b: Vec<_> = zones.iter().zip(seat_b).enumerate().map(|(i, (z, s))| (*z, s, i == 5)).collect();
    write(&a, &rows_a);
    write(&b, &rows_b);
    let c = compare(["A".into(), "B".into()], &read_trials(&a).unwrap(), &read_trials(&b).unwrap()).unwrap();
    let zones: Vec<&str> = c.rows.iter().map(|r| r.zone.as_str()).collect();
    assert_eq!(zones, ["front", "behind", "all"]);
    let (front, behind, all) = (&c.rows[0], &c.rows[1], &c.rows[2]);
    assert_eq!((front.trials, front.seated, front.only), (4, [2, 3], [1, 2]));
    assert_eq!((behind.trials, behind.seated, behind.only, behind.falls), (2, [1, 0], [1, 0], [1, 1]));
    assert_eq!((all.trials, all.seated, all.only), (6, [3, 3], [2, 2]));
    assert!((front.difference() - 25.0).abs() < 1e-12 && (front.z() - 1.0 / 3f64.sqrt()).abs() < 1e-12);
    // 1 against 2 discordant: p = 2 · (1 + 3) / 8 = 1; 0 against 1: p = 2 / 2 = 1.
    assert_eq!((front.p_value(), behind.p_value(), all.z()), (1.0, 1.0, 0.0));
    let md = c.markdown();
    assert!(md.contains("| front | 4 | 50.0% | 75.0% | 1 | 2 | +25.0 | +0.58 | 1.0000 |"), "{md}");
    // A lopsided split is evidence: 0 against 10 discordant trials, p = 2 / 1024.
    let many: Vec<_> = (0..10).map(|_| ("sides", false, false)).collect();
    let seated: Vec<_> = (0..10).map(|_| ("sides", true, false)).collect();
    write(&a, &many);
    write(&b, &seated);
    let c = compare(["A".into(), "B".into()], &read_trials(&a).unwrap(), &read_trials(&b).unwrap()).unwrap();
    assert!((c.rows[0].p_value() - 2.0 / 1024.0).abs() < 1e-15 && (c.rows[0].z() - 10f64.sqrt()).abs() < 1e-12);
    // Other trials: another count, another start.
    write(&b, &seated[..9]);
    let err = compare(["A".into(), "B".into()], &read_trials(&a).unwrap(), &read_trials(&b).unwrap()).unwrap_err();
    assert!(err.to_string().contains("not the same trials: 10 trials against 9"), "{err}");
    let moved = std::fs::read_to_string(&a).unwrap().replacen("0.5000", "0.6000", 1);
    std::fs::write(&b, moved).unwrap();
    let err = compare(["A".into(), "B".into()], &read_trials(&a).unwrap(), &read_trials(&b).unwrap()).unwrap_err();
    assert!(err.to_string().contains("trial 0 of zone sides starts at (0.0000, 0.5000, 1.0000) in A"), "{err}");
    // Bad files are named with the line.
    std::fs::write(&b, format!("{HEADER}0,front,0,0,0,left,maybe,false,0,0,sit,\n")).unwrap();
    let err = read_trials(&b).unwrap_err().to_string();
    assert!(err.contains("b.csv:2") && err.contains("success is `maybe`"), "{err}");
    std::fs::write(&b, "index,start_phase,phases\n0,1,2\n").unwrap();
    let err = read_trials(&b).unwrap_err().to_string();
    assert!(err.contains("b.csv:1") && err.contains("no `zone` column"), "{err}");
    std::fs::write(&b, format!("{HEADER}0,front,0,0\n")).unwrap();
    assert!(read_trials(&b).unwrap_err().to_string().contains("b.csv:2: 4 fields, the header has 12"));
    assert!(read_trials(&d.join("none")).unwrap_err().to_string().contains("none"));
    std::fs::remove_dir_all(&d).unwrap();
}
