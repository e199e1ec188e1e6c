//! Errors of datasets and latent models: each names the file and what is wrong with it.

use std::path::{Path, PathBuf};

/// What went wrong with a dataset, a latent model or their inputs.
#[derive(Debug, thiserror::Error)]
pub enum LatentError {
    /// A file could not be read or written, or a RON file did not parse.
    #[error(transparent)]
    File(#[from] repertoire_files::FileError),
    /// A file is damaged or does not agree with its manifest.
    #[error("{}: {reason}", path.display())]
    Corrupt {
        /// The file.
        path: PathBuf,
        /// What is wrong.
        reason: String,
    },
    /// A dataset or model does not fit what it is used with (body, layout, shapes).
    #[error("{}: {message}", path.display())]
    Mismatch {
        /// The manifest.
        path: PathBuf,
        /// The first difference.
        message: String,
    },
    /// A setting or argument is out of range.
    #[error("{0}")]
    Invalid(String),
    /// From the skill crate (specs, library).
    #[error(transparent)]
    Skill(#[from] repertoire_skill::SkillError),
    /// From the scene crate (layouts, worlds).
    #[error(transparent)]
    Scene(#[from] repertoire_scenes::SceneError),
}

impl LatentError {
    /// An I/O error on `path`.
    pub fn io(path: &Path, what: &'static str, source: std::io::Error) -> Self {
        LatentError::File(repertoire_files::FileError::io(path, what, source))
    }

    /// A RON error in `file`.
    pub fn ron(file: &Path, err: ron::error::SpannedError) -> Self {
        LatentError::File(repertoire_files::FileError::ron(file, err))
    }

    /// A damaged file.
    pub fn corrupt(path: &Path, reason: impl Into<String>) -> Self {
        LatentError::Corrupt { path: path.to_path_buf(), reason: reason.into() }
    }
}

/// Result alias for this crate.
pub type Result<T, E = LatentError> = std::result::Result<T, E>;

/// Writes `bytes` to `path` through a temporary sibling and a rename ([`repertoire_files`]).
pub fn write_atomic(path: &Path, bytes: &[u8]) -> Result<()> {
    repertoire_files::write_atomic(path, bytes).map_err(|e| LatentError::io(&e.path, e.action, e.source))
}
