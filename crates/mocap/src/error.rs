//! Errors: every parse error names the file (when known), the line and, where it helps, the
//! column, e.g. `16_15_walk.bvh:31:3: expected 3 or 6 channels, found 4`.

use std::fmt;
use std::path::{Path, PathBuf};

/// Where in an input a problem was found.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct Location {
    /// The file, when parsing from a path.
    pub file: Option<PathBuf>,
    /// 1-based line number; 0 when the input was empty.
    pub line: usize,
    /// 1-based column (in bytes), when it helps.
    pub column: Option<usize>,
}

impl Location {
    /// A location on `line` at `column`, with no file yet.
    pub fn at(line: usize, column: usize) -> Self {
        Location { file: None, line, column: Some(column) }
    }

    /// A location on `line`, with no file or column.
    pub fn line(line: usize) -> Self {
        Location { file: None, line, column: None }
    }
}

impl fmt::Display for Location {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match &self.file {
            Some(p) => write!(f, "{}", p.display())?,
            None => f.write_str("<input>")?,
        }
        write!(f, ":{}", self.line)?;
        if let Some(c) = self.column {
            write!(f, ":{c}")?;
        }
        Ok(())
    }
}

/// What went wrong while reading a clip.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum ErrorKind {
    /// The bytes are not UTF-8 text.
    #[error("invalid UTF-8 text")]
    InvalidUtf8,
    /// The input ended early.
    #[error("unexpected end of input, expected {0}")]
    UnexpectedEof(&'static str),
    /// A keyword or symbol other than the one the grammar needs.
    #[error("expected {expected}, found `{found}`")]
    Expected {
        /// What the grammar needs here.
        expected: &'static str,
        /// What the input has (shortened).
        found: String,
    },
    /// A token that should be a number is not one.
    #[error("invalid number `{0}`")]
    BadNumber(String),
    /// A number in the header (offset, length, frame time...) is NaN or infinite.
    #[error("{0} is not finite")]
    NonFiniteHeader(&'static str),
    /// A BVH joint with a channel count other than 3 or 6.
    #[error("expected 3 or 6 channels, found {0}")]
    ChannelCount(usize),
    /// An unknown channel or DoF name.
    #[error("unknown channel `{0}`")]
    UnknownChannel(String),
    /// The same channel listed twice on one joint.
    #[error("channel `{0}` listed twice")]
    DuplicateChannel(String),
    /// Two joints or bones with the same name.
    #[error("duplicate joint name `{0}`")]
    DuplicateJoint(String),
    /// A joint or bone name that the skeleton does not have.
    #[error("unknown joint `{0}`")]
    UnknownJoint(String),
    /// More than one `End Site` in a joint.
    #[error("joint `{0}` has more than one End Site")]
    DuplicateEndSite(String),
    /// A BVH file with a second `ROOT`.
    #[error("only one ROOT hierarchy is supported")]
    MultipleRoots,
    /// A skeleton with no channels at all, so frames carry no data.
    #[error("the skeleton has no channels")]
    NoChannels,
    /// The frame time is zero, negative or not finite.
    #[error("frame time must be positive, found {0}")]
    BadFrameTime(f64),
    /// A frame with the wrong number of values.
    #[error("frame {frame}: expected {expected} values, found {found}")]
    FrameLength {
        /// 0-based frame index.
        frame: usize,
        /// Values the skeleton needs.
        expected: usize,
        /// Values present.
        found: usize,
    },
    /// A frame value that is NaN or infinite.
    #[error("frame {frame}: non-finite value in {field}")]
    NonFinite {
        /// 0-based frame index.
        frame: usize,
        /// The channel, e.g. `lfemur Zrotation`.
        field: String,
    },
    /// A quaternion of (nearly) zero length.
    #[error("frame {frame}: zero-length quaternion for `{joint}`")]
    ZeroQuaternion {
        /// 0-based frame index.
        frame: usize,
        /// Joint name.
        joint: String,
    },
    /// The number of frames differs from the header.
    #[error("header declares {declared} frames, found {found}")]
    FrameCount {
        /// Count in the header.
        declared: usize,
        /// Frames present.
        found: usize,
    },
    /// A fully specified AMC frame that omits a bone with DoFs.
    #[error("frame {frame}: bone `{bone}` is missing")]
    MissingBone {
        /// 0-based frame index.
        frame: usize,
        /// Bone name.
        bone: String,
    },
    /// The same bone twice in one AMC frame.
    #[error("frame {frame}: bone `{bone}` given twice")]
    RepeatedBone {
        /// 0-based frame index.
        frame: usize,
        /// Bone name.
        bone: String,
    },
    /// Malformed JSON.
    #[error("JSON: {0}")]
    Json(String),
    /// Anything else the format forbids, in words.
    #[error("{0}")]
    Invalid(String),
}

/// Error type of the crate.
#[derive(Debug, thiserror::Error)]
pub enum Error {
    /// The file could not be read.
    #[error("{}: {source}", path.display())]
    Io {
        /// The file.
        path: PathBuf,
        /// The I/O error.
        #[source]
        source: std::io::Error,
    },
    /// The input is not a valid clip.
    #[error("{location}: {kind}")]
    Parse {
        /// Where.
        location: Location,
        /// What.
        kind: ErrorKind,
    },
    /// A skeleton and motion (or options) that do not fit together, e.g. when writing.
    #[error("{0}")]
    Mismatch(String),
}

impl Error {
    /// A parse error at `location`.
    pub fn parse(location: Location, kind: ErrorKind) -> Self {
        Error::Parse { location, kind }
    }

    /// Attaches a file name to a parse error that has none.
    pub fn in_file(mut self, path: &Path) -> Self {
        if let Error::Parse { location, .. } = &mut self
            && location.file.is_none()
        {
            location.file = Some(path.to_path_buf());
        }
        self
    }

    /// The parse error kind, if this is a parse error.
    pub fn kind(&self) -> Option<&ErrorKind> {
        match self {
            Error::Parse { kind, .. } => Some(kind),
            _ => None,
        }
    }

    /// The location, if this is a parse error.
    pub fn location(&self) -> Option<&Location> {
        match self {
            Error::Parse { location, .. } => Some(location),
            _ => None,
        }
    }
}

/// Shortens a token for an error message (at most 40 characters).
pub(crate) fn shorten(s: &str) -> String {
    let mut out: String = s.chars().take(40).collect();
    if out.len() < s.len() {
        out.push('…');
    }
    out
}

/// Reads a whole file, naming it in the error.
pub(crate) fn read_file(path: &Path) -> Result<Vec<u8>, Error> {
    std::fs::read(path).map_err(|source| Error::Io { path: path.to_path_buf(), source })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn display_names_file_line_and_column() {
        let e = Error::parse(Location::at(31, 3), ErrorKind::ChannelCount(4)).in_file(Path::new("16_15_walk.bvh"));
        assert_eq!(e.to_string(), "16_15_walk.bvh:31:3: expected 3 or 6 channels, found 4");
        let e = Error::parse(Location::line(7), ErrorKind::NoChannels);
        assert_eq!(e.to_string(), "<input>:7: the skeleton has no channels");
    }

    #[test]
    fn shorten_keeps_char_boundaries() {
        let s = "é".repeat(100);
        assert_eq!(shorten(&s).chars().count(), 41);
    }
}
