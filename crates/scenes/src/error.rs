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
        problem: crate::record::RecordingError,
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
