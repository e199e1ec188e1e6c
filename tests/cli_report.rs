//! `repertoire report` over real folders: a two-iteration meta-controller run (learning curves
//! and the curriculum schedule) and its evaluation (zone table, success map, transition
//! matrices), each gathered into report/index.md and a self-contained index.html.

mod common;

use std::path::Path;

use common::{ok, repertoire};

#[test]
fn report_gathers_a_meta_run_and_its_evaluation() {
    let dir = common::temp_dir("cli-report");
    let lib = Path::new(env!("CARGO_MANIFEST_DIR")).join("library");
    let (meta, run, eval) = (dir.join("meta"), dir.join("run"), dir.join("eval"));
    let s = |p: &Path| p.to_str().unwrap().to_string();
    ok(&repertoire(&[
        "meta",
        "train",
        "--library",
        &s(&lib),
        "--out",
        &s(&meta),
        "--run-dir",
        &s(&run),
        "--iterations",
        "2",
        "--envs",
        "4",
    ]));
    ok(&repertoire(&[
        "meta",
        "eval",
        "--library",
        &s(&lib),
        "--meta",
        &s(&meta),
        "--trials",
        "3",
        "--batch",
        "3",
        "--out",
        &s(&eval),
    ]));
    for f in ["heatmap.png", "heatmap.svg", "report.json", "trials.csv"] {
        assert!(eval.join(f).exists(), "meta eval wrote no {f}");
    }

    let text = ok(&repertoire(&["report", &s(&run)]));
    assert!(text.contains("index.html"), "{text}");
    let md = std::fs::read_to_string(run.join("report/index.md")).unwrap();
    assert!(md.contains("## Training") && md.contains("| 2 |"), "{md}");
    assert!(md.contains("## Zone curriculum") && md.contains("stayed in `front`"), "{md}");
    for f in ["curves-return.png", "curves-terms.png", "curriculum.png"] {
        let bytes = std::fs::read(run.join("report").join(f)).unwrap();
        assert!(bytes.starts_with(b"\x89PNG") && bytes.len() > 5_000, "{f}: {} bytes", bytes.len());
    }
    let html = std::fs::read_to_string(run.join("report/index.html")).unwrap();
    assert!(html.matches("<svg").count() >= 3 && !html.contains("src=\""), "charts inline, nothing fetched");

    ok(&repertoire(&["report", &s(&eval)]));
    let md = std::fs::read_to_string(eval.join("report/index.md")).unwrap();
    assert!(md.contains("## Evaluation") && md.contains("| front |") && md.contains("heatmap.png"), "{md}");
    assert!(eval.join("report/heatmap.png").exists());
    assert!(md.contains("## Replays") && md.contains(".rec"), "the worst trials are listed: {md}");

    // A folder with nothing to report says what it looked for.
    let empty = dir.join("empty");
    std::fs::create_dir_all(&empty).unwrap();
    let out = repertoire(&["report", &s(&empty)]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success() && err.contains("nothing to report") && err.contains("metrics.csv"), "{err}");
    // A corrupt metrics file is named, with its line.
    std::fs::write(empty.join("metrics.csv"), "iteration,global_step\n1\n").unwrap();
    let out = repertoire(&["report", &s(&empty)]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success() && err.contains("metrics.csv") && err.contains("line 2"), "{err}");
}
