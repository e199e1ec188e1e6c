//! Reference motion clips: mocap retargeted onto a MuJoCo body, keyframe clips, and the
//! operations skills need.
//!
//! - [`map`]: retarget maps (RON), shipped for every skeleton in the repository's `mocap/`, and
//!   detection of the one that fits a file.
//! - [`retarget()`]: re-proportion the source key points to the body, then damped-least-squares
//!   IK with MuJoCo Jacobians, warm-started, limits respected, feet on (not under) the floor.
//! - [`Clip`]: qpos frames at a frame rate; resample, cut, reverse, mirror, loop, content hash,
//!   RON / npy files; [`Features`] (joint velocities, end effectors, centre of mass, root
//!   velocities, heading) by MuJoCo kinematics.
//! - [`keyframe`]: keyframe clips in RON for motions no capture covers (catch, lift, carry).
//! - [`check()`]: what `repertoire clip check` reports.
//!
//! Conventions: the body is z-up and faces +x at heading 0; headings are counter-clockwise
//! seen from above, so a left turn is positive.

pub mod body;
pub mod check;
pub mod clip;
pub mod error;
pub mod export;
pub mod io;
pub mod keyframe;
pub mod map;
pub mod math;
pub mod positions;
pub mod retarget;
pub mod source;

pub use body::ClipBody;
pub use check::{CheckReport, MotionMeasures, PointError, check};
pub use clip::{Clip, Features};
pub use error::{ClipError, Result};
pub use keyframe::{KeyframeClip, LoadedKeyframes};
pub use map::{LoadedMap, RetargetMap, Role};
pub use retarget::{RetargetOptions, Retargeted, retarget};
pub use source::{ClipSource, import};
