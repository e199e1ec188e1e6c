//! The common skeleton: joints in parent-before-child order, offsets in metres, in the
//! source's own frame (its up axis recorded, never silently rotated).

use crate::math::{Axis, Quat, UpAxis, Vec3};

/// Which file format a skeleton came from; it tells how to read [`Joint::channels`].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SourceFormat {
    /// BVH: rotation channels compose intrinsically in listed order (`R = R1 · R2 · R3`).
    Bvh,
    /// ASF/AMC: DoFs apply in listed order about the joint's [`Joint::axis`] frame
    /// (`M = R3 · R2 · R1`, local rotation `C · M · C⁻¹`).
    AsfAmc,
    /// DeepMimic JSON: quaternion channels (w, x, y, z) and single-angle revolute joints.
    DeepMimic,
    /// Built in code.
    Other,
}

/// One degree of freedom of a joint as stored in a file.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Channel {
    /// Translation along an axis (file length unit).
    Position(Axis),
    /// Rotation about an axis (file angle unit).
    Rotation(Axis),
    /// Quaternion scalar part.
    QuatW,
    /// Quaternion i part.
    QuatX,
    /// Quaternion j part.
    QuatY,
    /// Quaternion k part.
    QuatZ,
    /// ASF bone-length DoF (`l`); read and kept raw, not applied to the pose.
    Length,
}

impl Channel {
    /// The BVH channel name (`Xposition`, `Zrotation`, ...), if this channel has one.
    pub fn bvh_name(self) -> Option<&'static str> {
        Some(match self {
            Channel::Position(Axis::X) => "Xposition",
            Channel::Position(Axis::Y) => "Yposition",
            Channel::Position(Axis::Z) => "Zposition",
            Channel::Rotation(Axis::X) => "Xrotation",
            Channel::Rotation(Axis::Y) => "Yrotation",
            Channel::Rotation(Axis::Z) => "Zrotation",
            _ => return None,
        })
    }

    /// Parses a BVH channel name (ASCII case-insensitive).
    pub fn from_bvh_name(s: &str) -> Option<Channel> {
        if s.len() != 9 {
            return None;
        }
        let (a, rest) = s.split_at_checked(1)?;
        let axis = Axis::from_letter(a.chars().next()?)?;
        if rest.eq_ignore_ascii_case("position") {
            Some(Channel::Position(axis))
        } else if rest.eq_ignore_ascii_case("rotation") {
            Some(Channel::Rotation(axis))
        } else {
            None
        }
    }

    /// Short display name, e.g. `Zrotation`, `qw`, `l`.
    pub fn name(self) -> &'static str {
        match self {
            Channel::QuatW => "qw",
            Channel::QuatX => "qx",
            Channel::QuatY => "qy",
            Channel::QuatZ => "qz",
            Channel::Length => "l",
            other => other.bvh_name().unwrap_or("?"),
        }
    }
}

/// A range a DoF may take: radians for rotations, metres for translations. May be infinite.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Limit {
    /// Lower bound.
    pub min: f64,
    /// Upper bound.
    pub max: f64,
}

/// One joint: the origin of a bone, placed at `offset` in its parent's frame.
#[derive(Clone, Debug, PartialEq)]
pub struct Joint {
    /// Name as in the file.
    pub name: String,
    /// Index of the parent joint (always smaller than this joint's index); `None` for the root.
    pub parent: Option<usize>,
    /// Rest position relative to the parent joint, in the parent's frame, metres.
    pub offset: Vec3,
    /// DoFs in file order; each frame's raw values follow this order.
    pub channels: Vec<Channel>,
    /// Per-channel limits (ASF `limits`), empty when the file gives none.
    pub limits: Vec<Limit>,
    /// Frame of the DoF axes relative to the rest frame (ASF `axis`, `C`); identity otherwise.
    pub axis: Quat,
    /// Position of a bone end with no child joint (BVH `End Site`, ASF leaf bone), metres.
    pub end_site: Option<Vec3>,
}

impl Joint {
    /// A joint with no channels, limits, DoF frame or end site.
    pub fn new(name: impl Into<String>, parent: Option<usize>, offset: Vec3) -> Self {
        Joint {
            name: name.into(),
            parent,
            offset,
            channels: Vec::new(),
            limits: Vec::new(),
            axis: Quat::IDENTITY,
            end_site: None,
        }
    }
}

/// A joint hierarchy. Joint 0 is the root; parents come before their children.
///
/// Coordinates are the source's own: BVH, DeepMimic and CMU ASF are y-up (`up` says which);
/// retargeting to a z-up MuJoCo body is a later step. Lengths are metres.
#[derive(Clone, Debug, PartialEq)]
pub struct Skeleton {
    /// The joints, root first, each parent before its children.
    pub joints: Vec<Joint>,
    /// The up axis of the source data.
    pub up: UpAxis,
    /// The format the skeleton came from.
    pub source: SourceFormat,
}

impl Skeleton {
    /// Number of joints.
    pub fn len(&self) -> usize {
        self.joints.len()
    }

    /// True when there are no joints.
    pub fn is_empty(&self) -> bool {
        self.joints.is_empty()
    }

    /// Index of the joint called `name`.
    pub fn joint_index(&self, name: &str) -> Option<usize> {
        self.joints.iter().position(|j| j.name == name)
    }

    /// Total raw channels per frame (sum over joints).
    pub fn channel_count(&self) -> usize {
        self.joints.iter().map(|j| j.channels.len()).sum()
    }

    /// Indices of the children of joint `i`, in index order.
    pub fn children(&self, i: usize) -> impl Iterator<Item = usize> + '_ {
        self.joints.iter().enumerate().filter(move |(_, j)| j.parent == Some(i)).map(|(k, _)| k)
    }

    /// World positions of every joint in the rest pose (all rotations identity, root at its
    /// offset).
    pub fn rest_positions(&self) -> Vec<Vec3> {
        let mut out: Vec<Vec3> = Vec::with_capacity(self.joints.len());
        for j in &self.joints {
            let base = j.parent.and_then(|p| out.get(p).copied()).unwrap_or(Vec3::ZERO);
            out.push(base + j.offset);
        }
        out
    }

    /// Extent of the rest pose (joints and end sites) along the up axis, metres.
    pub fn rest_height(&self) -> f64 {
        let pos = self.rest_positions();
        let up = self.up.axis();
        let mut lo = f64::INFINITY;
        let mut hi = f64::NEG_INFINITY;
        for (j, p) in self.joints.iter().zip(&pos) {
            for v in std::iter::once(*p).chain(j.end_site.map(|e| *p + e)) {
                lo = lo.min(v.get(up));
                hi = hi.max(v.get(up));
            }
        }
        if hi >= lo { hi - lo } else { 0.0 }
    }

    /// Multiplies every length (offsets, end sites, translation limits) by `factor`.
    pub fn scale(&mut self, factor: f64) {
        for j in &mut self.joints {
            j.offset = j.offset * factor;
            j.end_site = j.end_site.map(|e| e * factor);
            for (c, l) in j.channels.iter().zip(j.limits.iter_mut()) {
                if matches!(c, Channel::Position(_)) {
                    l.min *= factor;
                    l.max *= factor;
                }
            }
        }
    }
}

/// A length unit of a source file.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum LengthUnit {
    /// Metres.
    Metre,
    /// Centimetres (most BVH).
    Centimetre,
    /// Millimetres.
    Millimetre,
    /// Inches.
    Inch,
    /// CMU units (ASF `length 0.45`, cgspeed BVH): 1 unit = 0.0254 / 0.45 m ≈ 0.056444 m.
    Cmu,
    /// Any other scale, in metres per unit.
    Custom(f64),
}

impl LengthUnit {
    /// Metres per unit of this length.
    pub fn metres_per_unit(self) -> f64 {
        match self {
            LengthUnit::Metre => 1.0,
            LengthUnit::Centimetre => 0.01,
            LengthUnit::Millimetre => 0.001,
            LengthUnit::Inch => 0.0254,
            LengthUnit::Cmu => 0.0254 / 0.45,
            LengthUnit::Custom(s) => s,
        }
    }

    /// Guesses the unit from a character's size in file units (rest height, or root height):
    /// below 4 metres, below 60 CMU units, below 400 centimetres, else millimetres.
    ///
    /// A person is 1.5–2 m = 27–35 CMU units = 150–200 cm; inches (≈ 67) cannot be told from
    /// centimetres, so pass the unit explicitly for such files.
    pub fn guess_from_size(size: f64) -> LengthUnit {
        if !(size.is_finite()) || size < 4.0 {
            LengthUnit::Metre
        } else if size < 60.0 {
            LengthUnit::Cmu
        } else if size < 400.0 {
            LengthUnit::Centimetre
        } else {
            LengthUnit::Millimetre
        }
    }
}

/// The unit a parser used for a file and how it chose it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct UnitReport {
    /// The source unit; lengths were multiplied by its [`LengthUnit::metres_per_unit`].
    pub unit: LengthUnit,
    /// How the unit was chosen.
    pub basis: UnitBasis,
}

/// How a parser chose the source length unit.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum UnitBasis {
    /// Given by the caller.
    Explicit,
    /// Stated by the file (ASF `:units length`) or fixed by the format (DeepMimic metres).
    Declared,
    /// Guessed from the skeleton size ([`LengthUnit::guess_from_size`]).
    Guessed,
}

#[cfg(test)]
mod tests {
    use super::*;

    fn chain() -> Skeleton {
        let mut a = Joint::new("a", None, Vec3::new(0.0, 1.0, 0.0));
        a.end_site = None;
        let b = Joint::new("b", Some(0), Vec3::new(0.0, 0.5, 0.0));
        let mut c = Joint::new("c", Some(1), Vec3::new(0.0, -2.0, 0.0));
        c.end_site = Some(Vec3::new(0.0, -0.25, 0.0));
        Skeleton { joints: vec![a, b, c], up: UpAxis::Y, source: SourceFormat::Other }
    }

    #[test]
    fn rest_positions_accumulate_offsets() {
        let s = chain();
        let p = s.rest_positions();
        assert_eq!(p[2], Vec3::new(0.0, -0.5, 0.0));
        // From the end site at -0.75 to b at 1.5.
        assert!((s.rest_height() - 2.25).abs() < 1e-12);
        assert_eq!(s.children(0).collect::<Vec<_>>(), [1]);
    }

    #[test]
    fn scale_touches_offsets_and_end_sites() {
        let mut s = chain();
        s.scale(2.0);
        assert_eq!(s.joints[2].end_site, Some(Vec3::new(0.0, -0.5, 0.0)));
        assert_eq!(s.joints[1].offset, Vec3::new(0.0, 1.0, 0.0));
    }

    #[test]
    fn channel_names_round_trip() {
        for c in [Channel::Position(Axis::Y), Channel::Rotation(Axis::Z)] {
            assert_eq!(Channel::from_bvh_name(c.bvh_name().unwrap()), Some(c));
        }
        assert_eq!(Channel::from_bvh_name("Wrotation"), None);
        assert_eq!(Channel::from_bvh_name("Xrotatio"), None);
        assert_eq!(Channel::from_bvh_name("éXrotatio"), None);
    }

    #[test]
    fn unit_guess() {
        assert_eq!(LengthUnit::guess_from_size(1.7), LengthUnit::Metre);
        assert_eq!(LengthUnit::guess_from_size(31.0), LengthUnit::Cmu);
        assert_eq!(LengthUnit::guess_from_size(170.0), LengthUnit::Centimetre);
        assert_eq!(LengthUnit::guess_from_size(1700.0), LengthUnit::Millimetre);
        assert!((LengthUnit::Cmu.metres_per_unit() - 0.056444).abs() < 1e-6);
    }
}
