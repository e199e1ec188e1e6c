//! Atomic file writes: every output Repertoire writes (checkpoints, manifests, clips, pools,
//! reports, recordings, plots) goes to a temporary sibling first and is renamed into place, so
//! a reader (or a crash) never sees half a file and a failed write leaves the old file intact.
//!
//! Temporary names carry the process id and a per-process counter, so concurrent writers of the
//! same file (parallel evaluations, two runs sharing a library) never write into each other's
//! temporary file; the one that renames last wins, whole.

use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};

mod text;
pub use text::{FileError, Location, at, parse_ron, read_text, ron_message};

/// A write that failed: the file it was for, what was being done, and why.
#[derive(Debug, thiserror::Error)]
#[error("{}: {action}: {source}", path.display())]
pub struct WriteError {
    /// The file being written (the destination, or the temporary sibling when creating it failed).
    pub path: PathBuf,
    /// What failed: "cannot write" or "cannot rename into place".
    pub action: &'static str,
    /// The underlying error.
    #[source]
    pub source: std::io::Error,
}

/// A value of a file that breaks a rule (a scenario's fall rule, a skill spec's reward weight):
/// the field as written in the file (`fall.prop_s`), its value, and the rule. The caller adds
/// the file and the line.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("`{field}` is {value}; {rule}")]
pub struct FieldError {
    /// The field, dotted from the part of the file that was checked (`fall.prop_s`).
    pub field: String,
    /// Its value, as the message shows it.
    pub value: String,
    /// What it must be.
    pub rule: String,
}

impl FieldError {
    /// `field` is `value`, and must be as `rule` says.
    pub fn new(field: impl Into<String>, value: impl std::fmt::Display, rule: impl Into<String>) -> FieldError {
        FieldError { field: field.into(), value: value.to_string(), rule: rule.into() }
    }
}

static COUNTER: AtomicU64 = AtomicU64::new(0);

/// A hidden temporary sibling of `path` that keeps its extension (`dir/.stem.partial-PID-N.ext`),
/// for writers that pick the format from the name (image encoders). Unique within the process
/// and across processes.
pub fn temp_sibling(path: &Path) -> PathBuf {
    let stem = path.file_stem().map(|s| s.to_string_lossy().into_owned()).unwrap_or_else(|| "out".into());
    let n = COUNTER.fetch_add(1, Ordering::Relaxed);
    let pid = std::process::id();
    match path.extension() {
        Some(ext) => path.with_file_name(format!(".{stem}.partial-{pid}-{n}.{}", ext.to_string_lossy())),
        None => path.with_file_name(format!(".{stem}.partial-{pid}-{n}")),
    }
}

/// Renames the finished temporary file `tmp` onto `path`; on failure the temporary is removed.
pub fn commit(tmp: &Path, path: &Path) -> Result<(), WriteError> {
    std::fs::rename(tmp, path).map_err(|source| {
        let _ = std::fs::remove_file(tmp);
        WriteError { path: path.to_path_buf(), action: "cannot rename into place", source }
    })
}

/// Writes `bytes` to `path` through a temporary sibling renamed into place.
pub fn write_atomic(path: &Path, bytes: &[u8]) -> Result<(), WriteError> {
    let tmp = temp_sibling(path);
    if let Err(source) = std::fs::write(&tmp, bytes) {
        let _ = std::fs::remove_file(&tmp);
        return Err(WriteError { path: path.to_path_buf(), action: "cannot write", source });
    }
    commit(&tmp, path)
}

/// `text` with every absolute path in it (a word beginning with `/`) that lies in the working
/// folder or in this repository written relative to it, `..` folded: what manifests, lineages
/// and reports record, so that they name no folder of the machine they were made on.
/// (`/home/me/repertoire/crates/skill/../../third_party/clips/walk.txt (map m)` →
/// `third_party/clips/walk.txt (map m)`.) Paths elsewhere are left as they are.
pub fn portable(text: &str) -> String {
    let cwd = std::env::current_dir().ok().map(normal);
    let repo = normal(Path::new(env!("CARGO_MANIFEST_DIR")).join("../.."));
    let mut out = String::with_capacity(text.len());
    let mut word = String::new();
    let flush = |word: &mut String, out: &mut String| {
        out.push_str(&portable_word(word, cwd.as_deref(), &repo));
        word.clear();
    };
    for c in text.chars() {
        if c.is_whitespace() || c == ',' || c == '=' || c == '"' || c == '\'' {
            flush(&mut word, &mut out);
            out.push(c);
        } else {
            word.push(c);
        }
    }
    flush(&mut word, &mut out);
    out
}

/// [`portable`] of a path.
pub fn portable_path(path: &Path) -> String {
    portable(&path.display().to_string())
}

fn portable_word(word: &str, cwd: Option<&Path>, repo: &Path) -> String {
    if !word.starts_with('/') {
        return word.to_string();
    }
    let p = normal(PathBuf::from(word));
    for base in cwd.into_iter().chain([repo]) {
        if let Ok(rel) = p.strip_prefix(base) {
            let rel = rel.display().to_string();
            return if rel.is_empty() { ".".into() } else { rel };
        }
    }
    word.to_string()
}

/// `p` with `.` dropped and `..` folded where it can be.
pub fn normal(p: PathBuf) -> PathBuf {
    let mut out = PathBuf::new();
    for c in p.components() {
        match c {
            std::path::Component::CurDir => {}
            std::path::Component::ParentDir if out.file_name().is_some() => {
                out.pop();
            }
            c => out.push(c),
        }
    }
    out
}

#[cfg(test)]
mod portable_tests {
    use super::*;

    #[test]
    fn paths_in_the_repository_or_working_folder_become_relative_and_others_stay() {
        let repo = normal(Path::new(env!("CARGO_MANIFEST_DIR")).join("../.."));
        let text = format!(
            "{}/crates/skill/../../third_party/clips/walk.txt (map m) --from {}/runs/h.ron,stand --out=/elsewhere/x",
            repo.display(),
            repo.display()
        );
        assert_eq!(portable(&text), "third_party/clips/walk.txt (map m) --from runs/h.ron,stand --out=/elsewhere/x");
        assert_eq!(portable("repertoire skill train a.ron"), "repertoire skill train a.ron");
    }
}
