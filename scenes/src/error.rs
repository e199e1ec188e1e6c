//! Errors of the scenes crate: every one names the file and, where there is one, the place in it.

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
fn at(file: &Path, loc: &Option<Location>) -> String {
    match loc {
        Some(l) => format!("{}:{l}", file.display()),
        None => file.display().to_string(),
    }
}

/// Everything that can go wrong between a scenario file and a running world.
#[derive(Debug, thiserror::Error)]
pub enum SceneError {
    /// A file could not be read.
    #[error("{}: cannot read: {source}", file.display())]
    Io {
        /// The file.
        file: PathBuf,
        /// The I/O error.
        source: std::io::Error,
    },
    /// A RON file is not well-formed or does not match the schema (syntax, unknown field,
    /// wrong type, a range whose low end exceeds its high end, ...).
    #[error("{}: {message}", at(file, &Some(*loc)))]
    Ron {
        /// The RON file.
        file: PathBuf,
        /// Where the parser stopped.
        loc: Location,
        /// What is wrong, in a sentence.
        message: String,
    },
    /// The file parses but is inconsistent (a reference to a prop that does not exist, rates
    /// that do not divide, ...).
    #[error("{}: {message}", at(file, loc))]
    Invalid {
        /// The file.
        file: PathBuf,
        /// Where the offending value is, when it can be found.
        loc: Option<Location>,
        /// What is wrong, in a sentence.
        message: String,
    },
    /// MuJoCo rejected an MJCF document; `message` is MuJoCo's own (it names the element and line).
    #[error("{}: MuJoCo rejected the model: {message}", file.display())]
    Mjcf {
        /// The MJCF file (or, for a composed scene, the scenario that produced it).
        file: PathBuf,
        /// MuJoCo's message.
        message: String,
    },
    /// A body map names something the body's MJCF does not have, or a role is ill-formed.
    #[error("{}: {message}", at(file, loc))]
    BodyMap {
        /// The body-map file.
        file: PathBuf,
        /// Where the offending name is in the map, when it can be found.
        loc: Option<Location>,
        /// What is wrong.
        message: String,
    },
    /// A file could not be written.
    #[error("{}: cannot write: {source}", file.display())]
    Write {
        /// The file.
        file: PathBuf,
        /// The I/O error.
        source: std::io::Error,
    },
    /// A recording file that is not one, is cut short, corrupt or inconsistent.
    #[error("{}: {message}", file.display())]
    Recording {
        /// The recording file.
        file: PathBuf,
        /// What is wrong.
        message: String,
    },
    /// A runtime request that does not fit the world (wrong action length, unknown prop, ...).
    #[error("{0}")]
    Usage(String),
}

impl SceneError {
    /// Wraps a RON parse error of `file` (whose text is `text`) with a sentence a person can act on.
    pub fn from_ron(file: &Path, err: ron::error::SpannedError) -> Self {
        let loc = Location { line: err.span.start.line, col: err.span.start.col };
        Self::Ron { file: file.to_path_buf(), loc, message: ron_message(&err.code) }
    }
}

/// A RON parser error as a sentence a person can act on (an unknown field lists the known ones);
/// shared by every crate that reads RON files.
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

/// Result alias for this crate.
pub type Result<T, E = SceneError> = std::result::Result<T, E>;

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
}
