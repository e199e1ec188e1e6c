//! `repertoire recipe plan / run` end to end with tiny budgets: a walk trained, evaluated for its
//! pool and fine-tuned in two rounds; run again it skips what is done, an interrupted stage goes
//! on from its checkpoint, and a changed input reruns that stage and those after it from what the
//! stages before left.

mod common;

use std::path::Path;

use common::{ok, repertoire, tiny_recipe};

fn lineage_len(lib: &Path) -> usize {
    repertoire_skill::library::load(lib, "walk").expect("the walk loads").manifest.lineage.len()
}

#[test]
fn a_recipe_runs_skips_what_is_done_resumes_and_reruns_what_changed() {
    let dir = common::temp_dir("recipe");
    let file = tiny_recipe(&dir, "0.5");
    let file_s = file.to_str().unwrap();
    let lib = dir.join("work/lib");

    let plan = ok(&repertoire(&["recipe", "plan", file_s]));
    assert_eq!(plan.matches("| run |").count(), 4, "{plan}");
    assert!(plan.contains("| tune/r2/finetune | walk, pool, tune/r1/finetune |"), "{plan}");

    let text = ok(&repertoire(&["recipe", "run", file_s]));
    assert!(text.contains("4 stages run, 0 done before"), "{text}");
    // Stage one, then a fine-tune per round: the lineage holds the two stages before the last.
    assert_eq!(lineage_len(&lib), 2);
    let manifest = std::fs::read_to_string(lib.join("walk/manifest.ron")).unwrap();
    assert!(manifest.contains(&format!("# recipe {file_s}#tune/r2/finetune")), "the manifest names its stage");

    let text = ok(&repertoire(&["recipe", "run", file_s]));
    assert!(text.contains("0 stages run, 4 done before"), "{text}");

    // An interrupted last round (its record says started; its checkpoints are there) goes on
    // from its last checkpoint.
    let record = dir.join("work/.recipe/stages/tune~r2~finetune.ron");
    let r = std::fs::read_to_string(&record).unwrap();
    std::fs::write(&record, r.replace("status: Done", "status: Started")).unwrap();
    let plan = ok(&repertoire(&["recipe", "plan", file_s]));
    assert!(plan.contains("| resume |"), "{plan}");
    let text = ok(&repertoire(&["recipe", "run", file_s]));
    assert!(text.contains("1 stages run, 3 done before") && text.contains("resuming from"), "{text}");
    assert!(text.contains("runs/tune-2/checkpoints/iter-000002"), "{text}");
    assert_eq!(lineage_len(&lib), 2, "resumed from round 1's library, not its own output");

    // A changed input of the rounds reruns both of them, round 1 from the evaluated walk (not
    // from what round 2 left), so the lineage is as long as before.
    let file = tiny_recipe(&dir, "0.6");
    let plan = ok(&repertoire(&["recipe", "plan", file.to_str().unwrap()]));
    assert_eq!(plan.matches("| done |").count(), 2, "{plan}");
    let text = ok(&repertoire(&["recipe", "run", file.to_str().unwrap()]));
    assert!(text.contains("2 stages run, 2 done before"), "{text}");
    assert_eq!(lineage_len(&lib), 2);
    let manifest = std::fs::read_to_string(lib.join("walk/manifest.ron")).unwrap();
    assert!(manifest.contains("--fraction 0.6"), "the rerun's command");

    // A bad recipe is refused with its place.
    let bad = dir.join("bad.ron");
    std::fs::write(&bad, "(work: \"w\", stages: [Run(name: \"a\", argz: [])])").unwrap();
    let out = repertoire(&["recipe", "plan", bad.to_str().unwrap()]);
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("bad.ron:1:") && err.contains("argz"), "{err}");
}
