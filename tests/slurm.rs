//! The recipe and the ablation through a real one-node Slurm cluster (Debian's slurm-wlm and
//! munge, started by `scripts/slurm-local.sh`): each stage a batch job with `afterok` edges,
//! the ablation's runs a job array; what comes back is identical to the local run.

mod common;

use std::path::{Path, PathBuf};
use std::process::Command;

use common::{ok, tiny_recipe};

/// The test's cluster, stopped when the test ends.
struct Cluster {
    dir: PathBuf,
    conf: String,
}

impl Cluster {
    fn start() -> Cluster {
        let dir = Path::new(env!("CARGO_TARGET_TMPDIR")).join("slurm-local");
        let out = Command::new("bash")
            .arg(Path::new(env!("CARGO_MANIFEST_DIR")).join("scripts/slurm-local.sh"))
            .arg(&dir)
            .output()
            .expect("bash runs");
        let text = ok(&out);
        let conf =
            text.lines().find_map(|l| l.strip_prefix("export SLURM_CONF=")).expect("the script names its slurm.conf");
        Cluster { dir, conf: conf.to_string() }
    }

    fn repertoire(&self, args: &[&str]) -> std::process::Output {
        Command::new(env!("CARGO_BIN_EXE_repertoire"))
            .args(args)
            .env("SLURM_CONF", &self.conf)
            .env("PATH", format!("{}:/usr/sbin", std::env::var("PATH").unwrap_or_default()))
            .output()
            .expect("run repertoire")
    }
}

impl Drop for Cluster {
    fn drop(&mut self) {
        let _ = Command::new("bash")
            .arg(Path::new(env!("CARGO_MANIFEST_DIR")).join("scripts/slurm-local.sh"))
            .arg("stop")
            .arg(&self.dir)
            .output();
    }
}

fn records(work: &Path) -> Vec<(String, String)> {
    let mut out = Vec::new();
    for e in std::fs::read_dir(work.join(".recipe/stages")).unwrap() {
        let text = std::fs::read_to_string(e.unwrap().path()).unwrap();
        let field = |name: &str| {
            let at = text.find(&format!("{name}: \"")).unwrap() + name.len() + 3;
            text[at..at + text[at..].find('"').unwrap()].to_string()
        };
        assert!(text.contains("status: Done"), "{text}");
        out.push((field("id"), field("identity")));
    }
    out.sort();
    out
}

#[test]
fn a_recipe_and_an_ablation_through_slurm_come_back_as_the_local_runs() {
    let cluster = Cluster::start();
    let dir = common::temp_dir("slurm");

    // The recipe: here, then through Slurm into another work folder.
    let here = dir.join("here");
    std::fs::create_dir_all(&here).unwrap();
    let file = tiny_recipe(&here, "0.5");
    ok(&common::repertoire(&["recipe", "run", file.to_str().unwrap()]));
    let there = dir.join("there");
    std::fs::create_dir_all(&there).unwrap();
    let file = tiny_recipe(&there, "0.5");
    let text = ok(&cluster.repertoire(&[
        "recipe",
        "run",
        file.to_str().unwrap(),
        "--slurm",
        "--cpus-per-task",
        "1",
        "--wait",
    ]));
    assert!(text.contains("4 jobs submitted") && text.contains("every stage"), "{text}");
    assert!(text.contains("tune/r2/finetune: job") && text.contains(" after "), "afterok edges: {text}");
    // Same identities (the work folder is not part of them), every stage done, same weights.
    assert_eq!(records(&here.join("work")), records(&there.join("work")));
    for f in ["policy.safetensors", "value.safetensors", "end_poses.ron"] {
        let a = std::fs::read(here.join("work/lib/walk").join(f)).unwrap();
        let b = std::fs::read(there.join("work/lib/walk").join(f)).unwrap();
        assert!(a == b, "{f} differs between the local and the Slurm run");
    }
    let record = std::fs::read_to_string(there.join("work/.recipe/stages/tune~r2~finetune.ron")).unwrap();
    assert!(record.contains("ran: \"slurm job "), "{record}");
    // Submitted again, nothing is left to do.
    let text = ok(&cluster.repertoire(&["recipe", "run", file.to_str().unwrap(), "--slurm", "--wait"]));
    assert!(text.contains("0 jobs submitted") && text.contains("4 stages done"), "{text}");

    // The ablation: two variants, here and as a job array.
    let library = Path::new(env!("CARGO_MANIFEST_DIR")).join("library");
    let spec = dir.join("study.ron");
    std::fs::write(
        &spec,
        format!(
            "Ablation(library: \"{}\", iterations: 1, seeds: [1], trials: 2, variants: [Variant(name: \"full model\"), \
             Variant(name: \"fixed order\", chain: [\"walk_to\", \"turn_left\", \"sit\"])])",
            library.display()
        ),
    )
    .unwrap();
    let a = dir.join("ablation-here");
    ok(&common::repertoire(&["ablate", spec.to_str().unwrap(), "--out", a.to_str().unwrap()]));
    let b = dir.join("ablation-there");
    let text =
        ok(&cluster.repertoire(&["ablate", spec.to_str().unwrap(), "--out", b.to_str().unwrap(), "--slurm", "--wait"]));
    assert!(text.contains("2 runs submitted as job array"), "{text}");
    let csv = |d: &Path| std::fs::read_to_string(d.join("table.csv")).unwrap();
    assert_eq!(csv(&a), csv(&b));
    assert!(b.join("slurm").read_dir().unwrap().count() >= 3, "a log per array task and the table job");
}
