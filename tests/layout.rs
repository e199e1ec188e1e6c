//! The layout docs/architecture.md promises: every library crate under `crates/`, and no
//! import circle between the modules of a crate (a module never imports one that imports it,
//! directly or round about).

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

fn root() -> &'static Path {
    Path::new(env!("CARGO_MANIFEST_DIR"))
}

fn rust_files(dir: &Path, out: &mut Vec<PathBuf>) {
    for e in std::fs::read_dir(dir).unwrap() {
        let p = e.unwrap().path();
        if p.is_dir() {
            rust_files(&p, out);
        } else if p.extension().is_some_and(|x| x == "rs") {
            out.push(p);
        }
    }
}

/// Each module of the crate whose sources are in `src` (`handover::readiness`), with the modules
/// of the same crate its code (not its comments) names through `crate::`.
fn imports(src: &Path) -> BTreeMap<String, BTreeSet<String>> {
    let mut files = Vec::new();
    rust_files(src, &mut files);
    let module = |p: &Path| {
        let rel = p.strip_prefix(src).unwrap().with_extension("");
        let name = rel.to_string_lossy().replace('/', "::");
        name.strip_suffix("::mod").map(String::from).unwrap_or(name)
    };
    let names: BTreeSet<String> = files.iter().map(|p| module(p)).filter(|m| m != "lib").collect();
    let mut out = BTreeMap::new();
    for f in &files {
        let m = module(f);
        if m == "lib" {
            continue;
        }
        let code: String = std::fs::read_to_string(f)
            .unwrap()
            .lines()
            .filter(|l| !l.trim_start().starts_with("//"))
            .collect::<Vec<_>>()
            .join("\n");
        let mut deps = BTreeSet::new();
        for (i, _) in code.match_indices("crate::") {
            let path: String =
                code[i + 7..].chars().take_while(|c| c.is_ascii_alphanumeric() || *c == '_' || *c == ':').collect();
            let parts: Vec<&str> = path.split("::").filter(|s| !s.is_empty()).collect();
            // The longest prefix that is a module of the crate.
            if let Some(d) = (1..=parts.len()).rev().map(|k| parts[..k].join("::")).find(|p| names.contains(p))
                && d != m
            {
                deps.insert(d);
            }
        }
        out.insert(m, deps);
    }
    out
}

/// A circle of imports in `graph`, if there is one.
fn circle(graph: &BTreeMap<String, BTreeSet<String>>) -> Option<Vec<String>> {
    fn visit(
        n: &str,
        graph: &BTreeMap<String, BTreeSet<String>>,
        state: &mut BTreeMap<String, u8>,
        path: &mut Vec<String>,
    ) -> Option<Vec<String>> {
        state.insert(n.to_string(), 1);
        path.push(n.to_string());
        for d in graph.get(n).into_iter().flatten() {
            match state.get(d.as_str()).copied().unwrap_or(0) {
                1 => {
                    let at = path.iter().position(|p| p == d).unwrap();
                    let mut c = path[at..].to_vec();
                    c.push(d.clone());
                    return Some(c);
                }
                0 => {
                    if let Some(c) = visit(d, graph, state, path) {
                        return Some(c);
                    }
                }
                _ => {}
            }
        }
        path.pop();
        state.insert(n.to_string(), 2);
        None
    }
    let mut state = BTreeMap::new();
    for n in graph.keys() {
        if state.get(n.as_str()).copied().unwrap_or(0) == 0
            && let Some(c) = visit(n, graph, &mut state, &mut Vec::new())
        {
            return Some(c);
        }
    }
    None
}

#[test]
fn the_check_finds_a_circle() {
    let g: BTreeMap<String, BTreeSet<String>> = [("a", vec!["b"]), ("b", vec!["c"]), ("c", vec!["a"]), ("d", vec![])]
        .into_iter()
        .map(|(k, v)| (k.to_string(), v.into_iter().map(String::from).collect()))
        .collect();
    assert_eq!(circle(&g), Some(vec!["a".into(), "b".into(), "c".into(), "a".into()]));
    let mut g = g;
    g.get_mut("c").unwrap().clear();
    assert_eq!(circle(&g), None);
}

#[test]
fn every_library_crate_lies_under_crates_and_none_imports_in_a_circle() {
    let crates: Vec<PathBuf> = std::fs::read_dir(root().join("crates"))
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.join("Cargo.toml").is_file())
        .collect();
    assert!(crates.len() >= 12, "{crates:?}");
    let manifest = std::fs::read_to_string(root().join("Cargo.toml")).unwrap();
    assert!(manifest.contains("members = [\"crates/*\"]"), "the workspace takes its members from crates/");
    let meta = imports(&root().join("crates/meta/src"));
    assert!(meta["controller"].contains("search::planner") && meta["eval"].contains("controller"), "{meta:?}");
    for dir in &crates {
        let graph = imports(&dir.join("src"));
        assert_eq!(circle(&graph), None, "{}: modules import each other", dir.display());
    }
}
