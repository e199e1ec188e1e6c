//! Motion-capture clip formats (BVH, ASF/AMC, DeepMimic JSON): parse into one common
//! [`Skeleton`] + [`Motion`] representation, write BVH, and never panic on any input bytes.
//!
//! # Conventions
//! - Lengths are metres after parsing; the source unit and how it was chosen is in
//!   [`Clip::units`] (BVH: caller's unit or a guess from the character's size; ASF: its
//!   `:units length`, so CMU's `0.45` gives ≈ 0.056444 m per unit; DeepMimic: metres).
//! - Coordinates stay in the source frame, whose up axis is recorded in [`Skeleton::up`]:
//!   BVH, DeepMimic and CMU ASF/AMC are y-up. In BVH a positive yaw about +y is a left turn.
//!   Retargeting onto the z-up MuJoCo body is a later crate's job.
//! - Rotations are unit quaternions ([`Quat`], `w, x, y, z`), local to the parent joint;
//!   `a * b` applies `b` first. Forward kinematics: `world_j = world_parent * local_j`,
//!   `pos_j = pos_parent + world_parent · translation_j` ([`Motion::world_pose`]).
//! - Frames are 0-based everywhere, including in error messages.
//!
//! # Example
//! ```no_run
//! use repertoire_mocap::{BvhOptions, read_bvh};
//! let clip = read_bvh("16_15_walk.bvh", &BvhOptions::default())?;
//! let pose = clip.motion.world_pose(&clip.skeleton, 0).expect("frame 0");
//! println!("{} joints at {} fps; head at {:?}", clip.skeleton.len(), clip.motion.fps(),
//!          pose.positions.last());
//! # Ok::<(), repertoire_mocap::Error>(())
//! ```

pub mod asf;
pub mod bvh;
pub mod deepmimic;
pub mod error;
pub mod math;
pub mod motion;
pub mod skeleton;
mod text;

pub use asf::{AmcOptions, Asf, parse_amc, parse_asf, read_amc, read_asf};
pub use bvh::{BvhOptions, BvhWriteOptions, parse_bvh, read_bvh, write_bvh, write_bvh_file};
pub use deepmimic::{DeepMimicJoint, DeepMimicLayout, JointKind, parse_deepmimic, read_deepmimic};
pub use error::{Error, ErrorKind, Location};
pub use math::{Axis, EulerOrder, Quat, UpAxis, Vec3};
pub use motion::{AngleUnit, Clip, Frame, Motion, RawChannels, WorldPose};
pub use skeleton::{Channel, Joint, LengthUnit, Limit, Skeleton, SourceFormat, UnitBasis, UnitReport};
