//! Retarget maps (RON): which source joint drives which point of the target body, plus the
//! source's up axis, unit, scale and heading corrections. Maps for every skeleton in
//! `mocap/` ship in `crates/clip/maps/` and are compiled in; [`detect`] picks the one
//! that fits a parsed skeleton.

use crate::error::{ClipError, Result, read_text};
use repertoire_mocap::{LengthUnit, Skeleton, UpAxis};
use repertoire_scenes::Location;
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};

/// The source file format a map is written for.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub enum SourceFormat {
    /// Biovision BVH.
    Bvh,
    /// CMU ASF skeleton + AMC motion.
    AsfAmc,
    /// DeepMimic JSON motion (humanoid3d layout).
    DeepMimic,
    /// Joint positions (`.npy`/`.npz` with a `.joints.ron` declaration; [`crate::positions`]).
    Positions,
}

impl SourceFormat {
    /// Lower-case name for messages.
    pub fn name(self) -> &'static str {
        match self {
            SourceFormat::Bvh => "BVH",
            SourceFormat::AsfAmc => "ASF/AMC",
            SourceFormat::DeepMimic => "DeepMimic",
            SourceFormat::Positions => "joint-positions",
        }
    }
}

/// The up axis of the source data.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
pub enum Up {
    /// +y up (BVH, CMU, DeepMimic).
    #[default]
    Y,
    /// +z up (already MuJoCo's).
    Z,
}

impl From<Up> for UpAxis {
    fn from(u: Up) -> Self {
        match u {
            Up::Y => UpAxis::Y,
            Up::Z => UpAxis::Z,
        }
    }
}

/// A source length unit, overriding the parser's guess.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub enum Unit {
    /// Metres.
    Metre,
    /// Centimetres.
    Centimetre,
    /// Millimetres.
    Millimetre,
    /// Inches.
    Inch,
    /// CMU units (≈ 0.056444 m).
    Cmu,
    /// Metres per file unit.
    Custom(f64),
}

impl From<Unit> for LengthUnit {
    fn from(u: Unit) -> Self {
        match u {
            Unit::Metre => LengthUnit::Metre,
            Unit::Centimetre => LengthUnit::Centimetre,
            Unit::Millimetre => LengthUnit::Millimetre,
            Unit::Inch => LengthUnit::Inch,
            Unit::Cmu => LengthUnit::Cmu,
            Unit::Custom(s) => LengthUnit::Custom(s),
        }
    }
}

/// What a key point is on a human body; retargeting uses the roles to scale (hip, knee, ankle),
/// find the heading (hips, shoulders) and the floor (ankles), and reports errors by role.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[allow(missing_docs)]
pub enum Role {
    Pelvis,
    Spine,
    Chest,
    Neck,
    Head,
    LeftShoulder,
    RightShoulder,
    LeftElbow,
    RightElbow,
    LeftHand,
    RightHand,
    LeftHip,
    RightHip,
    LeftKnee,
    RightKnee,
    LeftAnkle,
    RightAnkle,
    LeftToe,
    RightToe,
}

impl Role {
    /// snake_case name for tables.
    pub fn name(self) -> &'static str {
        match self {
            Role::Pelvis => "pelvis",
            Role::Spine => "spine",
            Role::Chest => "chest",
            Role::Neck => "neck",
            Role::Head => "head",
            Role::LeftShoulder => "left_shoulder",
            Role::RightShoulder => "right_shoulder",
            Role::LeftElbow => "left_elbow",
            Role::RightElbow => "right_elbow",
            Role::LeftHand => "left_hand",
            Role::RightHand => "right_hand",
            Role::LeftHip => "left_hip",
            Role::RightHip => "right_hip",
            Role::LeftKnee => "left_knee",
            Role::RightKnee => "right_knee",
            Role::LeftAnkle => "left_ankle",
            Role::RightAnkle => "right_ankle",
            Role::LeftToe => "left_toe",
            Role::RightToe => "right_toe",
        }
    }

    /// The roles every map must have (scale, heading and floor need them).
    pub const REQUIRED: [Role; 7] = [
        Role::Pelvis,
        Role::LeftHip,
        Role::RightHip,
        Role::LeftKnee,
        Role::RightKnee,
        Role::LeftAnkle,
        Role::RightAnkle,
    ];
}

fn one() -> f64 {
    1.0
}

/// One key point: a source joint (its origin, or its end site) drives a point of the target
/// body (an MJCF body or site, plus an offset in that frame).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct KeyPoint {
    /// What the point is.
    pub role: Role,
    /// Source joint name, exactly as in the file.
    pub source: String,
    /// Use the joint's end site (BVH `End Site`, DeepMimic wrist) instead of its origin.
    #[serde(default)]
    pub end_site: bool,
    /// Target MJCF body or site name.
    pub target: String,
    /// Offset of the point in the target body's (or site's) frame, metres.
    #[serde(default)]
    pub offset: (f64, f64, f64),
    /// Weight in the IK least-squares problem.
    #[serde(default = "one")]
    pub weight: f64,
}

/// A retarget map: how one source skeleton maps onto one target body.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RetargetMap {
    /// Short name (e.g. `cmu-subject16-bvh`).
    pub name: String,
    /// What skeleton it is for, in words.
    #[serde(default)]
    pub description: String,
    /// The source format.
    pub format: SourceFormat,
    /// Up axis of the source data.
    #[serde(default)]
    pub up: Up,
    /// Source length unit; `None` keeps the parser's (declared or guessed) unit.
    #[serde(default)]
    pub unit: Option<Unit>,
    /// Source-to-target length factor; `None` uses the ratio of leg lengths (hip → knee →
    /// ankle) of the target and the source.
    #[serde(default)]
    pub scale: Option<f64>,
    /// Extra rotation about the up axis after the clip's initial heading is turned to +x,
    /// degrees (counter-clockwise seen from above).
    #[serde(default)]
    pub heading_offset_deg: f64,
    /// Drop frame 0 (a rest or reference pose).
    #[serde(default)]
    pub skip_first_frame: bool,
    /// The key points.
    pub points: Vec<KeyPoint>,
}

/// A map with the file it came from and its text (for error locations).
#[derive(Debug, Clone)]
pub struct LoadedMap {
    /// The map.
    pub map: RetargetMap,
    /// Where it came from (`<built-in>/crates/clip/maps/...` for shipped maps).
    pub path: PathBuf,
    /// The RON text.
    pub text: String,
}

impl LoadedMap {
    /// Reads a map file.
    pub fn load(path: &Path) -> Result<Self> {
        let text = read_text(path)?;
        Self::parse(path, text)
    }

    /// Parses map text; `path` is used in messages.
    pub fn parse(path: &Path, text: String) -> Result<Self> {
        let map: RetargetMap = repertoire_files::parse_ron(path, &text)?;
        let loaded = LoadedMap { map, path: path.to_path_buf(), text };
        loaded.check_shape()?;
        Ok(loaded)
    }

    /// An error located at the first occurrence of `name` in the map.
    pub fn error(&self, name: &str, message: String) -> ClipError {
        ClipError::Map { file: self.path.clone(), loc: Location::find_quoted(&self.text, name), message }
    }

    fn check_shape(&self) -> Result<()> {
        let m = &self.map;
        for role in Role::REQUIRED {
            if !m.points.iter().any(|p| p.role == role) {
                return Err(ClipError::Map {
                    file: self.path.clone(),
                    loc: Location::find_quoted(&self.text, "points"),
                    message: format!("the map has no `{role:?}` point; every map needs {:?}", Role::REQUIRED),
                });
            }
        }
        for (i, p) in m.points.iter().enumerate() {
            if m.points[..i].iter().any(|q| q.role == p.role) {
                return Err(self.error(&format!("{:?}", p.role), format!("role `{:?}` is listed twice", p.role)));
            }
            if !(p.weight.is_finite() && p.weight >= 0.0) {
                return Err(self.error(&p.source, format!("point `{:?}` has weight {}, not ≥ 0", p.role, p.weight)));
            }
        }
        if let Some(s) = m.scale
            && !(s.is_finite() && s > 0.0)
        {
            return Err(self.error("scale", format!("scale must be positive, found {s}")));
        }
        Ok(())
    }

    /// The point with `role`.
    pub fn point(&self, role: Role) -> Option<&KeyPoint> {
        self.map.points.iter().find(|p| p.role == role)
    }

    /// Checks that every source joint (and end site) exists in `skeleton` (read from `source`).
    pub fn check_source(&self, skeleton: &Skeleton, source: &Path) -> Result<()> {
        // Every missing joint at once, located at the first.
        let missing: Vec<_> = self.map.points.iter().filter(|p| skeleton.joint_index(&p.source).is_none()).collect();
        if let Some(first) = missing.first() {
            let names: Vec<&str> = skeleton.joints.iter().map(|j| j.name.as_str()).collect();
            let list: Vec<String> = missing.iter().map(|p| format!("`{}` ({:?})", p.source, p.role)).collect();
            return Err(self.error(
                &first.source,
                format!(
                    "source joint{} {} {} not in {} (joints: {})",
                    if missing.len() == 1 { "" } else { "s" },
                    list.join(", "),
                    if missing.len() == 1 { "is" } else { "are" },
                    source.display(),
                    names.join(", ")
                ),
            ));
        }
        for p in &self.map.points {
            let j = skeleton.joint_index(&p.source).expect("checked above");
            if p.end_site && skeleton.joints[j].end_site.is_none() {
                return Err(self
                    .error(&p.source, format!("source joint `{}` has no end site in {}", p.source, source.display())));
            }
        }
        Ok(())
    }
}

/// The maps shipped in `crates/clip/maps/`, compiled in.
pub const SHIPPED: [(&str, &str); 7] = [
    ("cmu-subject16.bvh.ron", include_str!("../maps/cmu-subject16.bvh.ron")),
    ("cmu-cgspeed.bvh.ron", include_str!("../maps/cmu-cgspeed.bvh.ron")),
    ("cmu-retargeted16.bvh.ron", include_str!("../maps/cmu-retargeted16.bvh.ron")),
    ("mocapbank.bvh.ron", include_str!("../maps/mocapbank.bvh.ron")),
    ("cmu.asf.ron", include_str!("../maps/cmu.asf.ron")),
    ("deepmimic-humanoid3d.ron", include_str!("../maps/deepmimic-humanoid3d.ron")),
    ("smpl22.positions.ron", include_str!("../maps/smpl22.positions.ron")),
];

/// The shipped maps, parsed.
pub fn shipped() -> Result<Vec<LoadedMap>> {
    SHIPPED
        .iter()
        .map(|(name, text)| LoadedMap::parse(&Path::new("<built-in>/crates/clip/maps").join(name), text.to_string()))
        .collect()
}

/// The names of the shipped maps for `format` whose every source joint is in `skeleton`: the
/// maps `clip check` could use for it (`--map`).
pub fn fitting(format: SourceFormat, skeleton: &Skeleton, source: &Path) -> Result<Vec<String>> {
    Ok(shipped()?
        .into_iter()
        .filter(|m| m.map.format == format && m.check_source(skeleton, source).is_ok())
        .map(|m| m.map.name)
        .collect())
}

/// The shipped map for `format` whose every source joint is in `skeleton`; when several fit,
/// the one whose joints cover the most of the skeleton. An error lists why each map failed.
pub fn detect(format: SourceFormat, skeleton: &Skeleton, source: &Path) -> Result<LoadedMap> {
    let mut best: Option<(usize, LoadedMap)> = None;
    let mut reasons = Vec::new();
    for map in shipped()? {
        if map.map.format != format {
            continue;
        }
        match map.check_source(skeleton, source) {
            Ok(()) => {
                let covered =
                    skeleton.joints.iter().filter(|j| map.map.points.iter().any(|p| p.source == j.name)).count();
                if best.as_ref().is_none_or(|(c, _)| covered > *c) {
                    best = Some((covered, map));
                }
            }
            Err(e) => {
                let missing: Vec<String> = map
                    .map
                    .points
                    .iter()
                    .filter(|p| skeleton.joint_index(&p.source).is_none())
                    .map(|p| format!("`{}`", p.source))
                    .collect();
                let why = if missing.is_empty() { e.to_string() } else { format!("no joint {}", missing.join(", ")) };
                reasons.push(format!("{} ({why})", map.map.name));
            }
        }
    }
    best.map(|(_, m)| m).ok_or_else(|| {
        let names: Vec<&str> = skeleton.joints.iter().take(12).map(|j| j.name.as_str()).collect();
        ClipError::Usage(format!(
            "{}: no shipped retarget map fits this {} skeleton (joints: {}{}); tried: {}; pass --map with a map of your own",
            source.display(),
            format.name(),
            names.join(", "),
            if skeleton.len() > 12 { ", …" } else { "" },
            if reasons.is_empty() { "none for this format".to_string() } else { reasons.join("; ") }
        ))
    })
}
