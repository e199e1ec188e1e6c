//! Errors of skill specs, training and the library: each names the file and, where it can, the
//! place in it.

use std::path::{Path, PathBuf};

use repertoire_scenes::SceneError;

/// What went wrong with a skill.
#[derive(Debug, thiserror::Error)]
pub enum SkillError {
    /// A file could not be read or written, or a RON file did not parse.
    #[error(transparent)]
    File(#[from] repertoire_files::FileError),
    /// A spec, library entry or argument is inconsistent.
    #[error("{0}")]
    Invalid(String),
    /// A skill does not fit the world it is loaded into.
    #[error("{}: {message}", path.display())]
    Mismatch {
        /// The skill's manifest.
        path: PathBuf,
        /// The first difference.
        message: String,
    },
    /// From the clip crate (import, retargeting, clip files).
    #[error(transparent)]
    Clip(#[from] repertoire_clip::ClipError),
    /// From the scene crate (scenario, world).
    #[error(transparent)]
    Scene(#[from] SceneError),
    /// From checkpoints (weights files).
    #[error(transparent)]
    Checkpoint(#[from] repertoire_learn::checkpoint::CheckpointError),
}

impl SkillError {
    /// An I/O error on `path`.
    pub fn io(path: &Path, what: &'static str, source: std::io::Error) -> Self {
        SkillError::File(repertoire_files::FileError::io(path, what, source))
    }

    /// A RON error in `file`.
    pub fn ron(file: &Path, err: ron::error::SpannedError) -> Self {
        SkillError::File(repertoire_files::FileError::ron(file, err))
    }
}

/// Result alias for this crate.
pub type Result<T, E = SkillError> = std::result::Result<T, E>;
