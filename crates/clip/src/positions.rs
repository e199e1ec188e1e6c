//! Joint-position clips: the form many research datasets ship motion in (a NumPy array of
//! `frames × joints × 3` positions, SMPL's 22 joints in HumanML3D, AMASS exports, pose
//! estimators' output), read as a source skeleton the retargeting maps then drive the body with.
//!
//! The array is a `.npy` file, or a member of an `.npz` archive; little-endian `f4` or `f8`,
//! C order, shaped `(frames, joints, 3)` or `(frames, joints·3)`. What its axes hold is declared
//! in a RON file beside it (`walk.npy` → `walk.joints.ron`), since the array itself carries no
//! joint names, hierarchy, rate or unit:
//!
//! ```ron
//! (
//!     fps: 20.0,
//!     // The second axis, in order.
//!     joints: ["pelvis", "left_hip", "right_hip", "spine1", ...],
//!     // Each joint's parent as an index into `joints` (-1 for the root), SMPL's kintree order.
//!     parents: [-1, 0, 0, 0, ...],
//!     unit: Metre,              // Metre (default), Centimetre, Millimetre, Inch, Custom(m)
//!     array: Some("positions"), // for an .npz: the member (default: its only member)
//! )
//! ```
//!
//! The up axis, like a BVH's, is the retarget map's (`up: Y` for SMPL data). A map for such
//! clips has `format: Positions` and names the declared joints.

use std::io::Read;
use std::path::{Path, PathBuf};

use repertoire_mocap::{
    Clip, Joint, LengthUnit, Motion, Quat, Skeleton, SourceFormat, UnitBasis, UnitReport, UpAxis, Vec3,
};
use repertoire_scenes::Location;
use serde::Deserialize;

use crate::error::{ClipError, Result, read_text};
use crate::io::parse_npy_array;
use crate::map::Unit;

/// What a positions array holds (its `.joints.ron` declaration).
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Declaration {
    /// Frames per second.
    pub fps: f64,
    /// The joints along the array's second axis, in order.
    pub joints: Vec<String>,
    /// Each joint's parent, an index into `joints`; -1 for the root (one root, first).
    pub parents: Vec<i64>,
    /// The positions' length unit.
    #[serde(default = "metre")]
    pub unit: Unit,
    /// For an `.npz`: the member holding the positions (default: the archive's only member).
    #[serde(default)]
    pub array: Option<String>,
}

fn metre() -> Unit {
    Unit::Metre
}

/// The declaration beside a positions array: `walk.npy` → `walk.joints.ron`.
pub fn declaration_path(array: &Path) -> PathBuf {
    array.with_extension("joints.ron")
}

/// Reads a positions array and its declaration into a source clip whose joints sit where the
/// array puts them in every frame (local translations from the parent, no rotations), ready for
/// a map of `format: Positions`.
pub fn read(array: &Path, declaration: &Path) -> Result<Clip> {
    let text = read_text(declaration)?;
    let decl: Declaration = repertoire_files::parse_ron(declaration, &text)?;
    let bad = |needle: &str, message: String| ClipError::Positions {
        file: declaration.to_path_buf(),
        loc: Location::find_quoted(&text, needle),
        message,
    };
    if !(decl.fps.is_finite() && decl.fps > 0.0) {
        return Err(bad("fps", format!("fps must be a positive number, found {}", decl.fps)));
    }
    if decl.joints.is_empty() {
        return Err(bad("joints", "no joints are declared".into()));
    }
    if decl.parents.len() != decl.joints.len() {
        return Err(bad(
            "parents",
            format!(
                "{} parents for {} joints: give one per joint (-1 for the root)",
                decl.parents.len(),
                decl.joints.len()
            ),
        ));
    }
    for (j, (&p, name)) in decl.parents.iter().zip(&decl.joints).enumerate() {
        let ok = if j == 0 { p == -1 } else { p >= 0 && (p as usize) < j };
        if !ok {
            return Err(bad(
                name,
                format!(
                    "joint {j} (`{name}`) has parent {p}: the first joint is the root (-1) and every other names an \
                     earlier joint"
                ),
            ));
        }
        if decl.joints[..j].contains(name) {
            return Err(bad(name, format!("joint `{name}` is declared twice")));
        }
    }
    let metres = LengthUnit::from(decl.unit).metres_per_unit();
    if !(metres.is_finite() && metres > 0.0) {
        return Err(bad("unit", format!("the unit must be a positive length, found {metres} m")));
    }

    let unusable = |m: String| ClipError::unusable(array.display(), m);
    let bytes = std::fs::read(array).map_err(|e| ClipError::io(array, "cannot read", e))?;
    let npy = if array.extension().is_some_and(|e| e.eq_ignore_ascii_case("npz")) {
        npz_member(array, &bytes, decl.array.as_deref()).map_err(|m| match m {
            Member::Archive(m) => unusable(m),
            Member::Named(m) => bad("array", m),
        })?
    } else {
        bytes
    };
    let (dims, values) = parse_npy_array(&npy).map_err(unusable)?;
    let nj = decl.joints.len();
    let frames = match dims[..] {
        [f, j, 3] if j == nj => f,
        [f, c] if c == 3 * nj => f,
        _ => {
            return Err(unusable(format!(
                "shape {dims:?} does not hold the {nj} declared joints: expected ({}, {nj}, 3) or ({}, {})",
                dims.first().copied().unwrap_or(0),
                dims.first().copied().unwrap_or(0),
                3 * nj
            )));
        }
    };
    if frames < 2 {
        return Err(unusable(format!("too short: {frames} frame(s); a clip needs at least 2")));
    }
    if let Some(k) = values.iter().position(|v| !v.is_finite()) {
        return Err(unusable(format!(
            "frame {}, joint `{}`: a position is not finite",
            k / (3 * nj),
            decl.joints[k / 3 % nj]
        )));
    }

    let at = |f: usize, j: usize| {
        let k = (f * nj + j) * 3;
        Vec3::new(values[k] * metres, values[k + 1] * metres, values[k + 2] * metres)
    };
    let parent = |j: usize| (decl.parents[j] >= 0).then(|| decl.parents[j] as usize);
    let local = |f: usize, j: usize| match parent(j) {
        Some(p) => at(f, j) - at(f, p),
        None => at(f, j),
    };
    let joints = (0..nj).map(|j| Joint::new(decl.joints[j].clone(), parent(j), local(0, j))).collect();
    let skeleton = Skeleton { joints, up: UpAxis::Y, source: SourceFormat::Other };
    let mut motion = Motion::new(1.0 / decl.fps, nj);
    let rotations = vec![Quat::IDENTITY; nj];
    for f in 0..frames {
        let translations: Vec<Vec3> = (0..nj).map(|j| local(f, j)).collect();
        motion.push_frame(&translations, &rotations);
    }
    Ok(Clip {
        skeleton,
        motion,
        units: UnitReport { unit: decl.unit.into(), basis: UnitBasis::Explicit },
        looping: None,
    })
}

/// Why an `.npz` member could not be had: the archive is broken, or the declaration names a
/// member it does not hold (or none, where it holds several).
enum Member {
    Archive(String),
    Named(String),
}

fn npz_member(path: &Path, bytes: &[u8], name: Option<&str>) -> std::result::Result<Vec<u8>, Member> {
    let mut zip = zip::ZipArchive::new(std::io::Cursor::new(bytes))
        .map_err(|e| Member::Archive(format!("not a readable .npz (zip) archive: {e}")))?;
    let members: Vec<String> =
        zip.file_names().filter_map(|n| n.ok()).map(|n| n.trim_end_matches(".npy").to_string()).collect();
    let want = match name {
        Some(n) => n.trim_end_matches(".npy").to_string(),
        None if members.len() == 1 => members[0].clone(),
        None => {
            return Err(Member::Named(format!(
                "{} holds {} arrays ({}); say which with `array: Some(\"NAME\")`",
                path.display(),
                members.len(),
                members.join(", ")
            )));
        }
    };
    let file = format!("{want}.npy");
    let mut entry = match zip.by_name(&file) {
        Ok(e) => e,
        Err(_) => {
            return Err(Member::Named(format!(
                "{} has no array `{want}` (it holds: {})",
                path.display(),
                members.join(", ")
            )));
        }
    };
    let mut out = Vec::new();
    entry.read_to_end(&mut out).map_err(|e| Member::Archive(format!("cannot read array `{want}`: {e}")))?;
    Ok(out)
}
