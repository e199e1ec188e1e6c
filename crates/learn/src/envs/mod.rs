//! Environments built by the project for testing the learning core.
pub mod cartpole;
