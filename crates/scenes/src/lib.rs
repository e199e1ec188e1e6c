//! Scenes: the scenario file (RON), bodies and props, and the MuJoCo world every skill runs in.
//!
//! Data flows one way: a [`ScenarioFile`] is parsed and validated, its body ([`BodyDef`]) and
//! props are composed into one MJCF document, MuJoCo compiles it into a [`WorldModel`], and any
//! number of [`World`]s share that model and step in parallel. Nothing here knows about
//! learning.

pub mod bench;
pub mod body;
pub mod compose;
pub mod error;
pub mod fall;
pub mod math;
pub mod obs;
pub mod param;
pub mod record;
pub mod replay;
pub mod scenario;
pub mod throw;
pub mod world;

pub use body::{BodyDef, BodyIndex, BodyMap};
pub use error::{Location, Result, SceneError};
pub use fall::{Fall, FallCause, FallRule};
pub use obs::{Feature, ObservationLayout};
pub use param::Param;
pub use record::{Annotation, RecordOptions, Recorder, Recording, RecordingError};
pub use scenario::{LowLevel, Prop, SEATED_FACING_DEG, Scenario, ScenarioFile, SitApproach, SitFall, SpotAround};
pub use throw::{Throw, ThrowSpec};
pub use world::{Contacts, World, WorldModel, sole_clearance, stand_on_floor, step_parallel};

/// The MuJoCo version this build links against (e.g. "3.17.0").
pub fn mujoco_version() -> String {
    // SAFETY: mj_versionString returns a pointer to a static, NUL-terminated string.
    let version = unsafe { std::ffi::CStr::from_ptr(mujoco_rs::mujoco_c::mj_versionString()) };
    version.to_string_lossy().into_owned()
}
