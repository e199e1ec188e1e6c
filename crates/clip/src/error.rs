//! Errors of the clip crate: each names the file and, where there is one, the line (and the
//! name or frame) that is wrong, e.g. `maps/cmu.ron:12:15: source joint `lfemurx` is not in
//! 16_15_walk.bvh (joints: pelvis, lfemur, …)`.

use repertoire_files::{FileError, Location, at};
use std::fmt;
use std::path::{Path, PathBuf};

/// Everything that can go wrong between a clip file and a retargeted, validated clip.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum ClipError {
    /// A file could not be read or written, or a RON file (retarget map, keyframes, clip
    /// metadata) is malformed.
    #[error(transparent)]
    File(#[from] FileError),
    /// A motion-capture file could not be parsed (the message names file, line and column).
    #[error(transparent)]
    Mocap(#[from] repertoire_mocap::Error),
    /// The target body could not be loaded or compiled.
    #[error(transparent)]
    Scene(#[from] repertoire_scenes::SceneError),
    /// A retarget map that does not fit the source skeleton or the target body.
    #[error("{}: {message}", at(file, loc))]
    Map {
        /// The map file.
        file: PathBuf,
        /// Where the offending name is, when it can be found.
        loc: Option<Location>,
        /// What is wrong (names the joint or body point).
        message: String,
    },
    /// A keyframe clip that parses but names unknown joints or has bad times.
    #[error("{}: {message}", at(file, loc))]
    Keyframes {
        /// The keyframe file.
        file: PathBuf,
        /// Where the offending value is.
        loc: Option<Location>,
        /// What is wrong.
        message: String,
    },
    /// A joint-positions declaration (`NAME.joints.ron`) that parses but does not fit: parents
    /// out of order, a joint named twice, a member the `.npz` does not hold.
    #[error("{}: {message}", at(file, loc))]
    Positions {
        /// The declaration.
        file: PathBuf,
        /// Where the offending value is.
        loc: Option<Location>,
        /// What is wrong.
        message: String,
    },
    /// A clip that cannot be used: a NaN or infinite frame, fewer than 2 frames, a qpos width
    /// that differs from the body's, a malformed .npy file.
    #[error("{origin}: {message}")]
    Unusable {
        /// The clip's file or source.
        origin: String,
        /// Why it cannot be used (names the frame where one is at fault).
        message: String,
    },
    /// A request the inputs cannot satisfy (no map fits a skeleton, mirroring a body without
    /// left/right pairs, an unknown file type, ...).
    #[error("{0}")]
    Usage(String),
}

impl ClipError {
    /// An unusable-clip error.
    pub(crate) fn unusable(origin: impl fmt::Display, message: impl Into<String>) -> Self {
        ClipError::Unusable { origin: origin.to_string(), message: message.into() }
    }

    pub(crate) fn io(file: &Path, action: &'static str, source: std::io::Error) -> Self {
        ClipError::File(FileError::io(file, action, source))
    }
}

/// Result alias for this crate.
pub type Result<T, E = ClipError> = std::result::Result<T, E>;

/// Reads a text file, naming it in the error.
pub(crate) fn read_text(path: &Path) -> Result<String> {
    std::fs::read_to_string(path).map_err(|e| ClipError::io(path, "cannot read", e))
}

/// Writes `bytes` to `path` atomically ([`repertoire_files`]).
pub(crate) fn write_atomic(path: &Path, bytes: &[u8]) -> Result<()> {
    repertoire_files::write_atomic(path, bytes).map_err(|e| ClipError::io(&e.path, e.action, e.source))
}
