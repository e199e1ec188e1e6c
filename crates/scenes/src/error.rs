//! Errors of the scenes crate: every one names the file and, where there is one, the place in it.

use std::path::{Path, PathBuf};

use repertoire_files::at;
pub use repertoire_files::{FileError, Location, ron_message};

/// Everything that can go wrong between a scenario file and a running world.
#[derive(Debug, thiserror::Error)]
pub enum SceneError {
    /// A file could not be read, or its RON is not well-formed or does not match the schema
    /// (syntax, unknown field, wrong type, a range whose low end exceeds its high end, ...).
    #[error(transparent)]
    File(#[from] FileError),
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
    #[error("{}: {problem}", file.display())]
    Recording {
        /// The recording file.
        file: PathBuf,
        /// What is wrong.
        #[source]
        problem: RecordingError,
    },
    /// A runtime request that does not fit the world (wrong action length, unknown prop, ...).
    #[error("{0}")]
    Usage(String),
}

impl SceneError {
    /// Wraps a RON parse error of `file` (whose text is `text`) with a sentence a person can act on.
    pub fn from_ron(file: &Path, err: ron::error::SpannedError) -> Self {
        Self::File(FileError::ron(file, err))
    }

    /// `file` could not be read.
    pub fn unreadable(file: &Path, source: std::io::Error) -> Self {
        Self::File(FileError::io(file, "cannot read", source))
    }
}

/// Result alias for this crate.
pub type Result<T, E = SceneError> = std::result::Result<T, E>;

/// What is wrong with the bytes of a recording ([`crate::Recording::from_bytes`]).
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum RecordingError {
    /// It does not start as a recording does.
    #[error("not a Repertoire recording (it does not start with REPREC 1; make one with `--record`)")]
    NotARecording,
    /// It ends before the header's length.
    #[error("cut short inside the header")]
    HeaderCut,
    /// It ends inside the header.
    #[error("cut short: the header says it is {said} bytes, {found} bytes follow")]
    HeaderLength {
        /// The header's length as stored.
        said: usize,
        /// The bytes after it.
        found: usize,
    },
    /// The header is not the JSON a recording's header is.
    #[error("header line {line} column {column}: {message}")]
    Header {
        /// Line in the header.
        line: usize,
        /// Column.
        column: usize,
        /// The parser's message.
        message: String,
    },
    /// A format this build does not read (a newer one).
    #[error("recording format {found} (this build reads formats 1 to {newest})")]
    Format {
        /// The file's format.
        found: u32,
        /// The newest this build reads.
        newest: u32,
    },
    /// The header's sizes do not fit in memory.
    #[error("the header's sizes overflow")]
    Overflow,
    /// The frames after the header are not as many bytes as the header says.
    #[error("cut short or padded: the header's {frames} frames need {want} bytes after the header, found {found}")]
    Length {
        /// Frames in the header.
        frames: usize,
        /// Bytes they need (with the checksum).
        want: usize,
        /// Bytes there.
        found: usize,
    },
    /// The checksum does not match: changed after it was written.
    #[error("checksum mismatch: the file is corrupt (changed after it was written)")]
    Checksum,
    /// The header's references or the numbers are inconsistent (a body's parent after it, a
    /// value not finite, ...).
    #[error("{0}")]
    Inconsistent(String),
}
