//! Charts are real pictures: PNGs that decode with ink on them and SVGs with the series named.

use std::path::{Path, PathBuf};

use repertoire_report::{
    BarRow, CurriculumPoint, ReportError, StartPoint, grid_map, grouped_bars, learning_curves, read_table, success_map,
    transition_matrix,
};

fn temp_dir(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("repertoire-report-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

/// Share of pixels that are not white.
fn ink(png: &Path) -> f64 {
    let img = image::open(png).unwrap_or_else(|e| panic!("{}: {e}", png.display())).to_rgb8();
    let inked = img.pixels().filter(|p| p.0 != [255, 255, 255]).count();
    inked as f64 / (img.width() * img.height()) as f64
}

#[test]
fn learning_curves_draw_return_terminations_and_every_term() {
    let dir = temp_dir("curves");
    let mut csv = String::from("iteration,global_step,mean_return,mean_length,termination_rate,term_pose,term_goal\n");
    for i in 0..50 {
        let x = f64::from(i);
        csv += &format!(
            "{i},{},{},{},{},{},{}\n",
            4096 * i,
            10.0 + x,
            100.0 + x,
            1.0 - x / 50.0,
            0.5 * (100.0 + x),
            0.2 * (100.0 + x)
        );
    }
    csv += "50,204800,NaN,,,,\n"; // an iteration where no episode ended
    std::fs::write(dir.join("metrics.csv"), csv).unwrap();
    let files = learning_curves(&dir.join("metrics.csv"), &dir.join("curves")).unwrap();
    assert_eq!(files.len(), 4, "{files:?}");
    for f in &files {
        assert!(f.exists(), "{}", f.display());
    }
    for png in files.iter().filter(|f| f.extension().is_some_and(|e| e == "png")) {
        let share = ink(png);
        assert!(share > 0.01 && share < 0.6, "{}: {share}", png.display());
    }
    let svg = std::fs::read_to_string(dir.join("curves-terms.svg")).unwrap();
    assert!(svg.contains("<svg") && svg.contains("pose") && svg.contains("goal"), "{svg:.300}");
    assert!(!dir.read_dir().unwrap().any(|e| e.unwrap().file_name().to_string_lossy().contains("partial")));
}

#[test]
fn a_malformed_metrics_file_is_refused_naming_the_line() {
    let dir = temp_dir("bad");
    let path = dir.join("metrics.csv");
    std::fs::write(&path, "iteration,global_step,mean_return,mean_length,termination_rate\n0,1,2,3,4\n1,2,3\n")
        .unwrap();
    let err = learning_curves(&path, &dir.join("x")).unwrap_err();
    assert!(matches!(err, ReportError::Invalid { .. }));
    let msg = err.to_string();
    assert!(msg.contains("metrics.csv") && msg.contains("line 3"), "{msg}");

    std::fs::write(&path, "iteration,global_step,mean_return,mean_length,termination_rate\n0,1,two,3,4\n").unwrap();
    let msg = learning_curves(&path, &dir.join("x")).unwrap_err().to_string();
    assert!(msg.contains("line 2") && msg.contains("mean_return") && msg.contains("two"), "{msg}");

    std::fs::write(&path, "iteration,steps\n0,1\n").unwrap();
    let msg = learning_curves(&path, &dir.join("x")).unwrap_err().to_string();
    assert!(msg.contains("no column `global_step`"), "{msg}");
    assert!(!dir.join("x-return.png").exists());
}

#[test]
fn success_map_and_matrix_are_drawn_and_a_misshapen_matrix_is_refused() {
    let dir = temp_dir("map");
    let points: Vec<StartPoint> = (0..200)
        .map(|i| {
            let a = f64::from(i) * 0.1;
            StartPoint { x: 2.0 * a.cos(), y: 2.0 * a.sin(), success: a.cos() > 0.0 }
        })
        .collect();
    let [png, svg] = success_map(&dir.join("heatmap"), "success by start", &points).unwrap();
    assert!(ink(&png) > 0.02);
    assert!(std::fs::read_to_string(svg).unwrap().contains("success by start"));

    let names: Vec<String> = ["walk", "turn_left", "sit"].map(String::from).to_vec();
    let rows: Vec<String> = std::iter::once("start".to_string()).chain(names.iter().cloned()).collect();
    let counts = vec![vec![10, 0, 0], vec![3, 5, 2], vec![4, 0, 6], vec![0, 0, 0]];
    let [png, _] = transition_matrix(&dir.join("transitions"), "left side", &rows, &names, &counts).unwrap();
    assert!(ink(&png) > 0.02);
    let err = transition_matrix(&dir.join("bad"), "x", &rows, &names, &counts[..2]).unwrap_err();
    assert!(err.to_string().contains("4 × 3"), "{err}");
}

#[test]
fn curriculum_schedule_shows_the_switches() {
    let dir = temp_dir("curriculum");
    let zones: Vec<String> = ["front", "sides", "behind"].map(String::from).to_vec();
    let points: Vec<CurriculumPoint> = (0..100)
        .map(|i| CurriculumPoint {
            iteration: f64::from(i),
            zone: (i / 40) as usize,
            success: f64::from(i % 40) / 40.0,
        })
        .collect();
    let [png, svg] = repertoire_report::curriculum_schedule(&dir.join("curriculum"), &zones, 0.8, &points).unwrap();
    assert!(ink(&png) > 0.01);
    let svg = std::fs::read_to_string(svg).unwrap();
    assert!(svg.contains("sides") && svg.contains("advance at 80%"), "{svg:.200}");
    let t = read_table(&{
        let p = dir.join("c.csv");
        std::fs::write(&p, "a,b\n1,x\n").unwrap();
        p
    })
    .unwrap();
    assert_eq!(t.text_column("b").unwrap(), ["x"]);
}

#[test]
fn a_grid_map_labels_every_cell_and_a_misshapen_grid_is_refused() {
    let dir = temp_dir("grid");
    let xs = [1.5, 3.0, 4.5];
    let ys = [-0.5, 0.5];
    let cells =
        vec![vec![(Some(0.0), 10), (Some(0.5), 10), (None, 0)], vec![(Some(1.0), 4), (Some(0.25), 4), (Some(0.1), 10)]];
    let [png, svg] = grid_map(&dir.join("zone"), "catch rate", "v_x (m/s)", "lateral (m/s)", &xs, &ys, &cells).unwrap();
    assert!(ink(&png) > 0.05, "the cells are shaded");
    let text = std::fs::read_to_string(svg).unwrap();
    for label in ["catch rate", "v_x (m/s)", "50%", "100%", "25%", "n=4", "–"] {
        assert!(text.contains(label), "{label} missing");
    }
    let err = grid_map(&dir.join("bad"), "t", "x", "y", &xs, &ys, &cells[..1]).unwrap_err();
    assert!(matches!(err, ReportError::Invalid { .. }), "{err}");
}

#[test]
fn grouped_bars_draw_every_row_and_a_row_of_the_wrong_width_is_refused() {
    let dir = temp_dir("bars");
    let groups: Vec<String> = ["front", "sides", "behind"].map(String::from).to_vec();
    let rows = vec![
        BarRow { label: "full model".into(), values: vec![(52.6, 3.0), (4.5, 1.0), (0.0, 0.0)] },
        BarRow { label: "flat: the sit policy alone".into(), values: vec![(0.0, 0.0), (0.0, 0.0), (0.0, 0.0)] },
    ];
    let [png, svg] = grouped_bars(&dir.join("ablation"), "seated, by zone", &groups, &rows).unwrap();
    let full = ink(&png);
    assert!(full > 0.01, "{full}");
    let svg = std::fs::read_to_string(svg).unwrap();
    for text in ["seated, by zone", "full model", "flat: the sit policy alone", "behind", "52.6"] {
        assert!(svg.contains(text), "{text} missing from the SVG");
    }
    // Longer bars put more ink on the page.
    let longer = vec![
        BarRow { label: "full model".into(), values: vec![(95.0, 0.0), (90.0, 0.0), (85.0, 0.0)] },
        rows[1].clone(),
    ];
    let [png, _] = grouped_bars(&dir.join("longer"), "seated, by zone", &groups, &longer).unwrap();
    assert!(ink(&png) > full, "{} vs {full}", ink(&png));
    let bad = vec![BarRow { label: "short".into(), values: vec![(1.0, 0.0)] }];
    let err = grouped_bars(&dir.join("bad"), "x", &groups, &bad).unwrap_err();
    assert!(err.to_string().contains("row `short` has 1 values for 3 groups"), "{err}");
    assert!(!dir.join("bad.png").exists(), "nothing drawn for a refused chart");
}
