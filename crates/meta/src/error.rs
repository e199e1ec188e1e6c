//! Errors of the meta level.

/// What went wrong.
#[derive(Debug, thiserror::Error)]
pub enum MetaError {
    /// An inconsistent scenario, library or argument.
    #[error("{0}")]
    Invalid(String),
    /// From the skill library.
    #[error(transparent)]
    Skill(#[from] repertoire_skill::SkillError),
    /// From the latent model.
    #[error(transparent)]
    Latent(#[from] repertoire_latent::LatentError),
    /// From the scene.
    #[error(transparent)]
    Scene(#[from] repertoire_scenes::SceneError),
}

/// Result alias.
pub type Result<T, E = MetaError> = std::result::Result<T, E>;
