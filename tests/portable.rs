//! Committed artifacts are portable: no manifest, lineage, report, recipe or page in the
//! repository names a folder of the machine it was made on (`/tmp/…`, `/home/…`, `/work/…`, or
//! this checkout's own absolute path). Where an input lay outside the repository and was not
//! kept, lineages write `<scratch>/…`; the recipes re-make it.

use std::path::{Path, PathBuf};

/// Folders whose every text file is checked: the data (library, results, scenarios, specs,
/// recipes, ablations, bodies, clips, docs) and the code crates.
const CHECKED: [&str; 15] = [
    "library",
    "library-stage1",
    "results",
    "scenarios",
    "specs",
    "recipes",
    "ablations",
    "bodies",
    "mocap",
    "docs",
    "skills",
    "meta",
    "scenes",
    "report",
    "curriculum",
];

fn files(dir: &Path, out: &mut Vec<PathBuf>) {
    let Ok(entries) = std::fs::read_dir(dir) else { return };
    for e in entries.flatten() {
        let p = e.path();
        let name = e.file_name();
        if name == "node_modules" || name == "target" || name.to_string_lossy().starts_with('.') {
            continue;
        }
        if p.is_dir() {
            files(&p, out);
        } else {
            out.push(p);
        }
    }
}

/// The absolute paths in `text`: a `/` after a space, quote, bracket, `=`, `,`, `:` or
/// backquote (or at a line start) followed by a top folder where machines keep their files.
fn absolute_paths(text: &str, own: &str) -> Vec<String> {
    let mut found = Vec::new();
    for (n, line) in text.lines().enumerate() {
        if line.contains(own) {
            found.push(format!("line {}: {}", n + 1, line.trim()));
            continue;
        }
        let bytes = line.as_bytes();
        for (i, _) in line.match_indices('/') {
            let before_ok = i == 0 || b" \"'(=,:`".contains(&bytes[i - 1]);
            let rest = &line[i + 1..];
            let top =
                ["tmp/", "work/", "home/", "root/", "Users/", "mnt/", "scratch/"].iter().any(|t| rest.starts_with(t));
            if before_ok && top {
                found.push(format!("line {}: {}", n + 1, line.trim().chars().take(200).collect::<String>()));
                break;
            }
        }
    }
    found
}

#[test]
fn no_committed_file_names_an_absolute_path() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let own = root.display().to_string();
    let mut all = Vec::new();
    for d in CHECKED {
        files(&root.join(d), &mut all);
    }
    for f in ["README.md", "CHANGELOG.md"] {
        all.push(root.join(f));
    }
    // What git ignores (a user's own evaluations inside the library folder) is not committed.
    if let Ok(out) = std::process::Command::new("git")
        .args(["ls-files", "--others", "--ignored", "--exclude-standard"])
        .current_dir(root)
        .output()
        && out.status.success()
    {
        let ignored: std::collections::HashSet<PathBuf> =
            String::from_utf8_lossy(&out.stdout).lines().map(|l| root.join(l)).collect();
        all.retain(|f| !ignored.contains(f));
    }
    assert!(all.len() > 100, "the checked folders hold the library, results and docs: {} files", all.len());
    let mut bad = Vec::new();
    for f in &all {
        let Ok(text) = std::fs::read_to_string(f) else { continue }; // binary files
        for hit in absolute_paths(&text, &own) {
            bad.push(format!("{}: {hit}", f.strip_prefix(root).unwrap_or(f).display()));
        }
    }
    assert!(bad.is_empty(), "absolute paths in committed files:\n{}", bad.join("\n"));
}

#[test]
fn the_check_finds_what_it_looks_for() {
    let own = "/src/checkout";
    assert_eq!(absolute_paths("command: \"repertoire x --library /tmp/lib\"", own).len(), 1);
    assert_eq!(absolute_paths("/home/me/x", own).len(), 1);
    assert_eq!(absolute_paths("see /src/checkout/skills", own).len(), 1);
    assert!(absolute_paths("library/tmp/x and <scratch>/exp/B and /usr/bin/chromium", own).is_empty());
}

/// `# recipe FILE#STAGE` in `text` (what a command run by a recipe stage records).
fn recipe_stages(text: &str) -> Vec<(String, String)> {
    text.match_indices("# recipe ")
        .filter_map(|(i, _)| {
            let rest = &text[i + "# recipe ".len()..];
            let end = rest.find(|c: char| c == '"' || c.is_whitespace()).unwrap_or(rest.len());
            rest[..end].split_once('#').map(|(f, s)| (f.to_string(), s.to_string()))
        })
        .collect()
}

#[test]
fn lineages_name_recipe_stages_that_exist() {
    assert_eq!(
        recipe_stages("command: \"repertoire x  # recipe recipes/sit.ron#handover/r2/sit\","),
        [("recipes/sit.ron".to_string(), "handover/r2/sit".to_string())]
    );
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let mut all = Vec::new();
    files(&root.join("library"), &mut all);
    files(&root.join("library-stage1"), &mut all);
    assert!(all.iter().filter(|f| f.ends_with("manifest.ron")).count() > 10, "the libraries' manifests are read");
    let mut named = std::collections::BTreeSet::new();
    for f in all
        .iter()
        .filter(|f| f.file_name().is_some_and(|n| n == "manifest.ron" || n == "meta.ron" || n == "latent.ron"))
    {
        named.extend(recipe_stages(&std::fs::read_to_string(f).unwrap()));
    }
    for (file, stage) in named {
        let path = root.join(&file);
        assert!(path.exists(), "a lineage names {file}, which is not in the repository");
        let out = std::process::Command::new(env!("CARGO_BIN_EXE_repertoire"))
            .args(["recipe", "plan", path.to_str().unwrap()])
            .current_dir(root)
            .output()
            .unwrap();
        let plan = String::from_utf8_lossy(&out.stdout);
        assert!(
            plan.contains(&format!("| {stage} |")),
            "a lineage names stage {stage} of {file}, which has none:\n{plan}"
        );
    }
}

/// The relative link targets in markdown `text` (`[x](../docs/a.md#b)` → `../docs/a.md`).
fn relative_links(text: &str) -> Vec<&str> {
    text.match_indices("](")
        .filter_map(|(i, _)| {
            let rest = &text[i + 2..];
            let end = rest.find([')', ' ', '#'])?;
            let link = &rest[..end];
            (!link.is_empty() && !link.contains("://") && !link.starts_with("mailto:")).then_some(link)
        })
        .collect()
}

#[test]
fn every_relative_link_in_the_committed_markdown_resolves() {
    assert_eq!(relative_links("see [a](../docs/a.md#b), [w](https://x.org/y) and [c](c/)"), ["../docs/a.md", "c/"]);
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let mut all = vec![root.join("README.md"), root.join("CHANGELOG.md")];
    for d in CHECKED {
        files(&root.join(d), &mut all);
    }
    all.retain(|f| f.extension().is_some_and(|e| e == "md"));
    assert!(all.len() > 50, "{} markdown files", all.len());
    let mut bad = Vec::new();
    for f in &all {
        let text = std::fs::read_to_string(f).unwrap();
        for link in relative_links(&text) {
            if !f.parent().unwrap().join(link).exists() {
                bad.push(format!("{}: {link}", f.strip_prefix(root).unwrap().display()));
            }
        }
    }
    assert!(bad.is_empty(), "links to nothing:\n{}", bad.join("\n"));
}
