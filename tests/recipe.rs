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
    assert!(plan.contains("| tune/r2/finetune | tune/r1/finetune |"), "{plan}");

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
    // (--var sets one of the recipe's values, as editing it would.)
    let plan = ok(&repertoire(&["recipe", "plan", file_s, "--var", "fraction=0.6"]));
    assert_eq!(plan.matches("| done (").count(), 2, "{plan}");
    assert!(plan.contains("rounds `tune`: at most 2; runs every round"), "{plan}");
    let text = ok(&repertoire(&["recipe", "run", file_s, "--var", "fraction=0.6"]));
    assert!(text.contains("2 stages run, 2 done before"), "{text}");
    assert_eq!(lineage_len(&lib), 2);
    let manifest = std::fs::read_to_string(lib.join("walk/manifest.ron")).unwrap();
    assert!(manifest.contains("--fraction 0.6"), "the rerun's command");

    // `--resume` refuses a checkpoint of another skill, another start, or flags that differ
    // from the run's.
    let stem = dir.join("work/runs/tune-2/checkpoints/iter-000002");
    let stem_s = stem.to_str().unwrap();
    let lib_s = lib.to_str().unwrap();
    let turn = ["skill", "train", "specs/turn_left.ron", "--library", lib_s, "--resume", stem_s];
    let err = String::from_utf8_lossy(&repertoire(&turn).stderr).into_owned();
    assert!(err.contains("the checkpoint trains `walk`, not `turn_left`"), "{err}");
    let walk = ["skill", "train", "specs/walk.ron", "--library", lib_s, "--resume", stem_s];
    let err = String::from_utf8_lossy(&repertoire(&walk).stderr).into_owned();
    assert!(err.contains("started as `finetune` from walk, not `train`"), "{err}");
    let finetune = [
        "skill",
        "finetune",
        "specs/walk.ron",
        "--from",
        "walk",
        "--fraction",
        "0.6",
        "--library",
        lib_s,
        "--iterations",
        "2",
        "--envs",
        "3",
        "--seed",
        "9",
        "--resume",
        stem_s,
    ];
    let err = String::from_utf8_lossy(&repertoire(&finetune).stderr).into_owned();
    assert!(err.contains("--envs 3 (the run's: 2)") && err.contains("--seed 9"), "{err}");
    let text = ok(&repertoire(&[&finetune[..11], &["--resume", stem_s, "--serial"][..]].concat()));
    assert!(text.contains("| walk | 2 |"), "the same flags resume: {text}");

    // A bad recipe is refused with its place.
    let bad = dir.join("bad.ron");
    std::fs::write(&bad, "(work: \"w\", stages: [Run(name: \"a\", argz: [])])").unwrap();
    let out = repertoire(&["recipe", "plan", bad.to_str().unwrap()]);
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("bad.ron:1:") && err.contains("argz"), "{err}");
}

#[test]
fn every_committed_recipe_plans() {
    // The recipes that re-make the shipped library, controllers and latent model parse, name
    // inputs that exist, and order their stages; none of them has run here, so all would run.
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("recipes");
    let mut n = 0;
    for e in std::fs::read_dir(&dir).unwrap() {
        let path = e.unwrap().path();
        if path.extension().is_none_or(|x| x != "ron") {
            continue;
        }
        let work = common::temp_dir(&format!("recipe-plan-{n}"));
        let text = ok(&repertoire(&["recipe", "plan", path.to_str().unwrap(), "--work", work.to_str().unwrap()]));
        assert!(text.contains("| 1 |") && text.contains("run"), "{}: {text}", path.display());
        assert!(!text.contains("| done"), "{text}");
        n += 1;
    }
    assert!(n >= 4, "the sit, library, objects and latent recipes");
}
