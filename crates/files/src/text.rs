//! Reading the text files Repertoire's crates read (scenarios, body maps, specs, maps, manifests)
//! and the one error for a file that cannot be read or does not parse: [`FileError`] names the
//! file and, for RON, the line and column with a sentence a person can act on.

use std::fmt;
use std::path::{Path, PathBuf};

/// A place in a text file: 1-based line and column.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Location {
    /// 1-based line number.
    pub line: usize,
    /// 1-based column number.
    pub col: usize,
}

impl Location {
    /// The location of byte offset `offset` in `text`.
    pub fn of_offset(text: &str, offset: usize) -> Self {
        let before = &text[..offset.min(text.len())];
        let line = before.matches('\n').count() + 1;
        let col = before.rsplit('\n').next().map_or(0, |l| l.chars().count()) + 1;
        Self { line, col }
    }

    /// The location of the first occurrence of `needle` as a quoted RON string (`"needle"`),
    /// falling back to the bare word; `None` when it does not occur.
    pub fn find_quoted(text: &str, needle: &str) -> Option<Self> {
        let quoted = format!("\"{needle}\"");
        text.find(&quoted).or_else(|| find_word(text, needle)).map(|offset| Self::of_offset(text, offset))
    }
}

/// Finds `word` delimited by non-identifier characters.
fn find_word(text: &str, word: &str) -> Option<usize> {
    if word.is_empty() {
        return None;
    }
    let is_ident = |c: char| c.is_alphanumeric() || c == '_';
    text.match_indices(word).map(|(i, _)| i).find(|&i| {
        let before = text[..i].chars().next_back();
        let after = text[i + word.len()..].chars().next();
        !before.is_some_and(is_ident) && !after.is_some_and(is_ident)
    })
}

impl fmt::Display for Location {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}:{}", self.line, self.col)
    }
}

/// `file:line:col` when the location is known, else `file`.
pub fn at(file: &Path, loc: &Option<Location>) -> String {
    match loc {
        Some(l) => format!("{}:{l}", file.display()),
        None => file.display().to_string(),
    }
}

/// A file that could not be read, or whose RON does not parse.
#[derive(Debug, thiserror::Error)]
pub enum FileError {
    /// The file could not be read (or written).
    #[error("{}: {action}: {source}", path.display())]
    Io {
        /// The file.
        path: PathBuf,
        /// What was being done (`cannot read`, ...).
        action: &'static str,
        /// The OS error.
        #[source]
        source: std::io::Error,
    },
    /// The RON is not well-formed or does not match the schema (syntax, unknown field, wrong
    /// type, ...).
    #[error("{}: {message}", at(path, &Some(*loc)))]
    Ron {
        /// The file.
        path: PathBuf,
        /// Where the parser stopped.
        loc: Location,
        /// What is wrong, in a sentence.
        message: String,
    },
}

impl FileError {
    /// An I/O error on `path` while doing `action`.
    pub fn io(path: &Path, action: &'static str, source: std::io::Error) -> Self {
        FileError::Io { path: path.to_path_buf(), action, source }
    }

    /// A RON parse error of `path`.
    pub fn ron(path: &Path, err: ron::error::SpannedError) -> Self {
        let loc = Location { line: err.span.start.line, col: err.span.start.col };
        FileError::Ron { path: path.to_path_buf(), loc, message: ron_message(&err.code) }
    }
}

/// A RON parser error as a sentence a person can act on (an unknown field lists the known ones).
pub fn ron_message(code: &ron::Error) -> String {
    match code {
        ron::Error::NoSuchStructField { expected, found, outer } => format!(
            "unknown field `{found}`{}; expected one of: {}",
            outer.as_ref().map(|o| format!(" in `{o}`")).unwrap_or_default(),
            expected.join(", ")
        ),
        other => other.to_string(),
    }
}

/// The text of `path`.
pub fn read_text(path: &Path) -> Result<String, FileError> {
    std::fs::read_to_string(path).map_err(|e| FileError::io(path, "cannot read", e))
}

/// `text` (the content of `path`) parsed as RON, `Option` fields written bare
/// (`IMPLICIT_SOME`).
pub fn parse_ron<T: serde::de::DeserializeOwned>(path: &Path, text: &str) -> Result<T, FileError> {
    ron::Options::default()
        .with_default_extension(ron::extensions::Extensions::IMPLICIT_SOME)
        .from_str(text)
        .map_err(|e| FileError::ron(path, e))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn offsets_map_to_lines_and_columns() {
        let text = "ab\ncd\n  \"chair\"";
        assert_eq!(Location::of_offset(text, 0), Location { line: 1, col: 1 });
        assert_eq!(Location::of_offset(text, 4), Location { line: 2, col: 2 });
        assert_eq!(Location::find_quoted(text, "chair"), Some(Location { line: 3, col: 3 }));
        assert_eq!(Location::find_quoted(text, "ch"), None);
    }

    #[derive(Debug, serde::Deserialize)]
    #[serde(deny_unknown_fields)]
    #[allow(dead_code)]
    struct Probe {
        name: String,
        size: Option<f64>,
    }

    #[test]
    fn ron_errors_name_the_file_the_place_and_the_known_fields() {
        let path = Path::new("dir/probe.ron");
        let ok: Probe = parse_ron(path, "(name: \"a\", size: 2.0)").expect("parses");
        assert_eq!(ok.size, Some(2.0));
        let err = parse_ron::<Probe>(path, "(\n  name: \"a\",\n  sise: 2.0)").unwrap_err().to_string();
        assert!(err.starts_with("dir/probe.ron:3:"), "{err}");
        assert!(err.contains("unknown field `sise`") && err.contains("name, size"), "{err}");
        let err = read_text(Path::new("no/such.ron")).unwrap_err().to_string();
        assert!(err.starts_with("no/such.ron: cannot read: "), "{err}");
    }
}
