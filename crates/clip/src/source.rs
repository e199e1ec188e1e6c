//! Reading a source clip of any supported format and choosing its retarget map.

use crate::error::{ClipError, Result};
use crate::map::{LoadedMap, SourceFormat, detect};
use repertoire_mocap::{
    AmcOptions, BvhOptions, DeepMimicLayout, LengthUnit, read_amc, read_asf, read_bvh, read_deepmimic,
};
use std::path::{Path, PathBuf};

/// What kind of file a path is, by its extension.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum ClipSource {
    /// A BVH file.
    Bvh(PathBuf),
    /// A CMU ASF skeleton with an AMC motion.
    AsfAmc {
        /// The skeleton.
        asf: PathBuf,
        /// The motion.
        amc: PathBuf,
    },
    /// A DeepMimic motion (`.txt` or `.json`).
    DeepMimic(PathBuf),
    /// A keyframe clip (`.ron`).
    Keyframes(PathBuf),
    /// Joint positions (`.npy`, or an `.npz` member) with their declaration
    /// ([`crate::positions`]).
    Positions {
        /// The array.
        array: PathBuf,
        /// What it holds (`NAME.joints.ron`).
        declaration: PathBuf,
    },
}

impl ClipSource {
    /// Classifies `file` by extension. For ASF/AMC, `other` is the partner file (`--asf` for
    /// an AMC, `--amc` for an ASF); an AMC without one looks for `SUBJECT.asf` beside it
    /// (CMU naming: `01_01.amc` → `01.asf`).
    pub fn from_path(file: &Path, other: Option<&Path>) -> Result<Self> {
        let ext = file.extension().map(|e| e.to_string_lossy().to_ascii_lowercase()).unwrap_or_default();
        Ok(match ext.as_str() {
            "bvh" => ClipSource::Bvh(file.to_path_buf()),
            "amc" => {
                let asf = match other {
                    Some(a) => a.to_path_buf(),
                    None => {
                        let stem = file.file_stem().map(|s| s.to_string_lossy().into_owned()).unwrap_or_default();
                        let subject = stem.split('_').next().unwrap_or(&stem).to_string();
                        let guess = file.with_file_name(format!("{subject}.asf"));
                        if !guess.exists() {
                            return Err(ClipError::Usage(format!(
                                "{}: an AMC file needs its ASF skeleton; pass --asf FILE ({} does not exist)",
                                file.display(),
                                guess.display()
                            )));
                        }
                        guess
                    }
                };
                ClipSource::AsfAmc { asf, amc: file.to_path_buf() }
            }
            "asf" => {
                let amc = other.ok_or_else(|| {
                    ClipError::Usage(format!(
                        "{}: an ASF file is a skeleton; pass --amc FILE with the motion",
                        file.display()
                    ))
                })?;
                ClipSource::AsfAmc { asf: file.to_path_buf(), amc: amc.to_path_buf() }
            }
            "txt" | "json" => ClipSource::DeepMimic(file.to_path_buf()),
            "ron" => ClipSource::Keyframes(file.to_path_buf()),
            "npy" | "npz" => {
                let declaration = crate::positions::declaration_path(file);
                if !declaration.exists() {
                    return Err(ClipError::Usage(format!(
                        "{}: a joint-positions array needs a declaration of its joints, parents, rate and unit \
                         beside it: {} (see docs/cli.md, joint-position clips)",
                        file.display(),
                        declaration.display()
                    )));
                }
                ClipSource::Positions { array: file.to_path_buf(), declaration }
            }
            _ => {
                return Err(ClipError::Usage(format!(
                    "{}: unknown clip type `.{ext}`; expected .bvh, .amc (+ .asf), DeepMimic .txt/.json, joint positions \
                     .npy/.npz (+ .joints.ron) or keyframe .ron",
                    file.display()
                )));
            }
        })
    }

    /// The motion file (the AMC for ASF/AMC).
    pub fn path(&self) -> &Path {
        match self {
            ClipSource::Bvh(p) | ClipSource::DeepMimic(p) | ClipSource::Keyframes(p) => p,
            ClipSource::AsfAmc { amc, .. } => amc,
            ClipSource::Positions { array, .. } => array,
        }
    }

    /// The mocap format, or `None` for keyframes.
    pub fn format(&self) -> Option<SourceFormat> {
        match self {
            ClipSource::Bvh(_) => Some(SourceFormat::Bvh),
            ClipSource::AsfAmc { .. } => Some(SourceFormat::AsfAmc),
            ClipSource::DeepMimic(_) => Some(SourceFormat::DeepMimic),
            ClipSource::Positions { .. } => Some(SourceFormat::Positions),
            ClipSource::Keyframes(_) => None,
        }
    }
}

/// Reads a mocap source and picks its map (`map`, or the shipped one that fits), then applies
/// the map's unit and `skip_first_frame`. Keyframe files are not mocap: an error.
pub fn import(source: &ClipSource, map: Option<LoadedMap>) -> Result<(repertoire_mocap::Clip, LoadedMap)> {
    let mut clip = match source {
        ClipSource::Bvh(p) => read_bvh(p, &BvhOptions::default())?,
        ClipSource::AsfAmc { asf, amc } => {
            let asf = read_asf(asf, None)?;
            read_amc(amc, &asf, &AmcOptions::default())?
        }
        ClipSource::DeepMimic(p) => read_deepmimic(p, &DeepMimicLayout::humanoid3d())?,
        ClipSource::Positions { array, declaration } => crate::positions::read(array, declaration)?,
        ClipSource::Keyframes(p) => {
            return Err(ClipError::Usage(format!("{}: a keyframe clip is not motion capture", p.display())));
        }
    };
    let format = source.format().unwrap_or(SourceFormat::Bvh);
    let map = match map {
        Some(m) => {
            if m.map.format != format {
                return Err(m.error(
                    "format",
                    format!(
                        "the map is for {} files, {} is {}",
                        m.map.format.name(),
                        source.path().display(),
                        format.name()
                    ),
                ));
            }
            m.check_source(&clip.skeleton, source.path())?;
            m
        }
        None => detect(format, &clip.skeleton, source.path())?,
    };
    if let Some(unit) = map.map.unit {
        let want = LengthUnit::from(unit).metres_per_unit();
        let have = clip.units.unit.metres_per_unit();
        if !(want.is_finite() && want > 0.0) {
            return Err(map.error("unit", format!("unit must be positive, found {want} m")));
        }
        let factor = want / have;
        clip.skeleton.scale(factor);
        clip.motion.scale(factor);
        clip.units.unit = unit.into();
    }
    if map.map.skip_first_frame {
        clip.motion.skip_first_frame();
    }
    Ok((clip, map))
}
