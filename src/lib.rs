//! Repertoire: physics-based humanoid characters that compose learned motor skills.
//!
//! The crates of the workspace, by role (arrows point one way: scenes ← skills ← meta/curriculum ← CLI):
//! - [`scenes`]: scenario RON, bodies, props and the MuJoCo world;
//! - `repertoire-mocap` (skills/mocap): motion-capture clip formats;
//! - `repertoire-learn` (skills/learn): environments, policies and PPO.

pub use repertoire_scenes as scenes;
