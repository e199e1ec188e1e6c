//! The common motion: per frame, each joint's local translation (metres) and local rotation
//! (unit quaternion), plus the file's raw channel values; forward kinematics.

use crate::math::{Quat, Vec3};
use crate::skeleton::{Skeleton, UnitReport};

/// Angle unit of raw channel values.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum AngleUnit {
    /// Degrees (BVH, most AMC).
    Degrees,
    /// Radians (DeepMimic, some AMC).
    Radians,
}

impl AngleUnit {
    /// Converts a value in this unit to radians.
    pub fn to_radians(self, v: f64) -> f64 {
        match self {
            AngleUnit::Degrees => v.to_radians(),
            AngleUnit::Radians => v,
        }
    }

    /// Converts radians to this unit.
    pub fn from_radians(self, v: f64) -> f64 {
        match self {
            AngleUnit::Degrees => v.to_degrees(),
            AngleUnit::Radians => v,
        }
    }
}

/// Channel values exactly as read from the file, frame after frame.
///
/// Per frame there are `width` values in the order of the skeleton's joints and each joint's
/// [`crate::Joint::channels`]. Positions are in file length units (multiply by
/// `metres_per_unit`), rotations in `angle_unit`.
#[derive(Clone, Debug, PartialEq)]
pub struct RawChannels {
    /// Values per frame.
    pub width: usize,
    /// `frames × width` values.
    pub values: Vec<f64>,
    /// Unit of rotation channels.
    pub angle_unit: AngleUnit,
    /// Metres per file length unit.
    pub metres_per_unit: f64,
}

impl RawChannels {
    /// The raw values of frame `i`.
    pub fn frame(&self, i: usize) -> Option<&[f64]> {
        let start = i.checked_mul(self.width)?;
        self.values.get(start..start.checked_add(self.width)?)
    }
}

/// A sampled motion for one skeleton.
///
/// Frame `f`, joint `j` lives at index `f * joint_count + j` of `translations` and `rotations`.
/// A joint's translation is its offset unless the file animates it (root position channels,
/// BVH joints with 6 channels); the root's translation is its position in the source frame.
#[derive(Clone, Debug, PartialEq)]
pub struct Motion {
    /// Seconds between frames.
    pub frame_time: f64,
    /// Joints per frame (the skeleton's length).
    pub joint_count: usize,
    /// Local translations relative to the parent joint, metres.
    pub translations: Vec<Vec3>,
    /// Local rotations relative to the parent's frame.
    pub rotations: Vec<Quat>,
    /// The file's channel values, when the format has them.
    pub raw: Option<RawChannels>,
}

/// One frame's local pose, borrowed from a [`Motion`].
#[derive(Clone, Copy, Debug)]
pub struct Frame<'a> {
    /// Local translation of each joint, metres.
    pub translations: &'a [Vec3],
    /// Local rotation of each joint.
    pub rotations: &'a [Quat],
}

/// World-space pose of every joint in one frame, in the source frame.
#[derive(Clone, Debug, PartialEq)]
pub struct WorldPose {
    /// Joint origins, metres.
    pub positions: Vec<Vec3>,
    /// Joint orientations.
    pub rotations: Vec<Quat>,
    /// End-site positions for joints that have one, metres.
    pub end_sites: Vec<Option<Vec3>>,
}

impl Motion {
    /// An empty motion for `joint_count` joints.
    pub fn new(frame_time: f64, joint_count: usize) -> Self {
        Motion { frame_time, joint_count, translations: Vec::new(), rotations: Vec::new(), raw: None }
    }

    /// Number of frames.
    pub fn frame_count(&self) -> usize {
        self.rotations.len().checked_div(self.joint_count).unwrap_or(0)
    }

    /// Frames per second.
    pub fn fps(&self) -> f64 {
        1.0 / self.frame_time
    }

    /// Duration from the first to one frame past the last frame, seconds.
    pub fn duration(&self) -> f64 {
        self.frame_count() as f64 * self.frame_time
    }

    /// The local pose of frame `i`.
    pub fn frame(&self, i: usize) -> Option<Frame<'_>> {
        let start = i.checked_mul(self.joint_count)?;
        let end = start.checked_add(self.joint_count)?;
        Some(Frame { translations: self.translations.get(start..end)?, rotations: self.rotations.get(start..end)? })
    }

    /// Appends one frame; both slices must have `joint_count` entries.
    pub fn push_frame(&mut self, translations: &[Vec3], rotations: &[Quat]) -> bool {
        if translations.len() != self.joint_count || rotations.len() != self.joint_count {
            return false;
        }
        self.translations.extend_from_slice(translations);
        self.rotations.extend_from_slice(rotations);
        true
    }

    /// Root translation of frame `i` (joint 0), metres.
    pub fn root_translation(&self, i: usize) -> Option<Vec3> {
        self.frame(i)?.translations.first().copied()
    }

    /// Root rotation of frame `i` (joint 0).
    pub fn root_rotation(&self, i: usize) -> Option<Quat> {
        self.frame(i)?.rotations.first().copied()
    }

    /// Keeps the first `frames` frames, raw values included.
    pub fn truncate_frames(&mut self, frames: usize) {
        let n = frames * self.joint_count;
        self.translations.truncate(n);
        self.rotations.truncate(n);
        if let Some(raw) = &mut self.raw {
            raw.values.truncate(frames * raw.width);
        }
    }

    /// Drops the first frame (e.g. a rest or T-pose), raw values included.
    pub fn skip_first_frame(&mut self) {
        if self.frame_count() == 0 {
            return;
        }
        let n = self.joint_count;
        self.translations.drain(..n);
        self.rotations.drain(..n);
        if let Some(raw) = &mut self.raw {
            let w = raw.width.min(raw.values.len());
            raw.values.drain(..w);
        }
    }

    /// Multiplies every translation by `factor` (raw values keep their unit; their
    /// `metres_per_unit` is updated to match).
    pub fn scale(&mut self, factor: f64) {
        for t in &mut self.translations {
            *t = *t * factor;
        }
        if let Some(raw) = &mut self.raw {
            raw.metres_per_unit *= factor;
        }
    }

    /// Forward kinematics for frame `i`: world positions and rotations of every joint and end
    /// site. `None` if the frame does not exist or the skeleton has another joint count.
    pub fn world_pose(&self, skeleton: &Skeleton, i: usize) -> Option<WorldPose> {
        if skeleton.len() != self.joint_count {
            return None;
        }
        let f = self.frame(i)?;
        let n = self.joint_count;
        let mut positions = Vec::with_capacity(n);
        let mut rotations = Vec::with_capacity(n);
        let mut end_sites = Vec::with_capacity(n);
        for ((joint, &t), &r) in skeleton.joints.iter().zip(f.translations).zip(f.rotations) {
            let (pp, pr) = match joint.parent.and_then(|p| Some((positions.get(p)?, rotations.get(p)?))) {
                Some((&pp, &pr)) => (pp, pr),
                None => (Vec3::ZERO, Quat::IDENTITY),
            };
            let pos = pp + pr.rotate(t);
            let rot = pr * r;
            end_sites.push(joint.end_site.map(|e| pos + rot.rotate(e)));
            positions.push(pos);
            rotations.push(rot);
        }
        Some(WorldPose { positions, rotations, end_sites })
    }

    /// World positions of every joint for every frame (`frames × joints`), metres.
    pub fn world_positions(&self, skeleton: &Skeleton) -> Vec<Vec<Vec3>> {
        (0..self.frame_count()).filter_map(|i| self.world_pose(skeleton, i).map(|p| p.positions)).collect()
    }
}

/// A parsed clip: skeleton, motion and the length unit the source used.
#[derive(Clone, Debug, PartialEq)]
pub struct Clip {
    /// The joint hierarchy, metres.
    pub skeleton: Skeleton,
    /// The frames.
    pub motion: Motion,
    /// Source length unit and how it was chosen.
    pub units: UnitReport,
    /// Whether the clip is meant to loop (DeepMimic `"Loop": "wrap"`), when the file says.
    pub looping: Option<bool>,
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::math::{Axis, UpAxis};
    use crate::skeleton::{Joint, SourceFormat};

    #[test]
    fn fk_rotates_children_about_their_parent() {
        let skel = Skeleton {
            joints: vec![
                Joint::new("root", None, Vec3::ZERO),
                Joint::new("arm", Some(0), Vec3::new(1.0, 0.0, 0.0)),
                Joint::new("hand", Some(1), Vec3::new(1.0, 0.0, 0.0)),
            ],
            up: UpAxis::Y,
            source: SourceFormat::Other,
        };
        let mut m = Motion::new(0.1, 3);
        let quarter = std::f64::consts::FRAC_PI_2;
        let t = [Vec3::new(0.0, 1.0, 0.0), skel.joints[1].offset, skel.joints[2].offset];
        let r = [Quat::IDENTITY, Quat::about(Axis::Z, quarter), Quat::IDENTITY];
        assert!(m.push_frame(&t, &r));
        let p = m.world_pose(&skel, 0).unwrap().positions;
        assert!((p[1] - Vec3::new(1.0, 1.0, 0.0)).norm() < 1e-12);
        assert!((p[2] - Vec3::new(1.0, 2.0, 0.0)).norm() < 1e-12);
        assert_eq!(m.frame_count(), 1);
        assert!(m.world_pose(&skel, 1).is_none());
    }

    #[test]
    fn skip_first_frame_drops_raw_too() {
        let mut m = Motion::new(0.1, 1);
        m.push_frame(&[Vec3::ZERO], &[Quat::IDENTITY]);
        m.push_frame(&[Vec3::new(1.0, 0.0, 0.0)], &[Quat::IDENTITY]);
        m.raw = Some(RawChannels {
            width: 1,
            values: vec![0.0, 1.0],
            angle_unit: AngleUnit::Degrees,
            metres_per_unit: 1.0,
        });
        m.skip_first_frame();
        assert_eq!(m.frame_count(), 1);
        assert_eq!(m.root_translation(0), Some(Vec3::new(1.0, 0.0, 0.0)));
        assert_eq!(m.raw.unwrap().values, [1.0]);
    }
}
