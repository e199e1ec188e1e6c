//! Saving and loading clips: RON (`*.ron`, everything in one readable file) or NumPy
//! (`*.npy`: the qpos frames as a little-endian f64 `frames × nq` array, plus a sidecar
//! `*.meta.ron` with the rest). Writes are atomic (temporary file, then rename).

use crate::clip::Clip;
use crate::error::{ClipError, Result, read_text, write_atomic};
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};

/// Everything but the frames.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
struct Meta {
    name: String,
    fps: f64,
    nq: usize,
    root_qpos: usize,
    quat_qpos: Vec<usize>,
    body_hash: String,
    looping: bool,
    origin: String,
    frames: usize,
    /// Content hash when written (informational; recomputed on load).
    hash: String,
}

/// A RON clip file.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
struct ClipFile {
    meta: Meta,
    qpos: Vec<Vec<f64>>,
}

fn meta(clip: &Clip) -> Meta {
    Meta {
        name: clip.name.clone(),
        fps: clip.fps,
        nq: clip.nq,
        root_qpos: clip.root_qpos,
        quat_qpos: clip.quat_qpos.clone(),
        body_hash: clip.body_hash.clone(),
        looping: clip.looping,
        origin: clip.origin.clone(),
        frames: clip.frame_count(),
        hash: clip.content_hash(),
    }
}

fn from_meta(m: Meta, qpos: Vec<f64>) -> Clip {
    Clip {
        name: m.name,
        fps: m.fps,
        nq: m.nq,
        root_qpos: m.root_qpos,
        quat_qpos: m.quat_qpos,
        body_hash: m.body_hash,
        looping: m.looping,
        origin: m.origin,
        qpos,
    }
}

/// The sidecar metadata path of an `.npy` clip: `walk.npy` → `walk.meta.ron`.
pub fn sidecar(npy: &Path) -> PathBuf {
    npy.with_extension("meta.ron")
}

fn pretty() -> ron::ser::PrettyConfig {
    ron::ser::PrettyConfig::new().depth_limit(2).struct_names(true)
}

fn is_npy(path: &Path) -> bool {
    path.extension().is_some_and(|e| e.eq_ignore_ascii_case("npy"))
}

impl Clip {
    /// Saves to `path`: `.npy` writes the array and a `.meta.ron` sidecar, anything else RON.
    pub fn save(&self, path: &Path) -> Result<()> {
        self.validate()?;
        if is_npy(path) {
            write_atomic(path, &npy_bytes(&self.qpos, self.frame_count(), self.nq))?;
            let text = to_ron(path, &meta(self))?;
            write_atomic(&sidecar(path), text.as_bytes())
        } else {
            let file =
                ClipFile { meta: meta(self), qpos: self.qpos.chunks_exact(self.nq).map(<[f64]>::to_vec).collect() };
            write_atomic(path, to_ron(path, &file)?.as_bytes())
        }
    }

    /// Loads a clip saved by [`Clip::save`] and validates it; errors name the file (and, for
    /// a NaN or infinite value, the frame).
    pub fn load(path: &Path) -> Result<Clip> {
        let clip = if is_npy(path) {
            let meta_path = sidecar(path);
            let m: Meta = parse(&meta_path, &read_text(&meta_path)?)?;
            let bytes = std::fs::read(path).map_err(|e| ClipError::io(path, "cannot read", e))?;
            let (rows, cols, values) = parse_npy(&bytes).map_err(|m| ClipError::unusable(path.display(), m))?;
            if cols != m.nq || rows != m.frames {
                return Err(ClipError::unusable(
                    path.display(),
                    format!(
                        "array is {rows} × {cols}, the sidecar {} says {} × {}",
                        meta_path.display(),
                        m.frames,
                        m.nq
                    ),
                ));
            }
            let mut c = from_meta(m, values);
            c.origin = path.display().to_string();
            c
        } else {
            let f: ClipFile = parse(path, &read_text(path)?)?;
            let nq = f.meta.nq;
            if let Some(i) = f.qpos.iter().position(|r| r.len() != nq) {
                return Err(ClipError::unusable(
                    path.display(),
                    format!("frame {i} has {} values, the clip's qpos width is {nq}", f.qpos[i].len()),
                ));
            }
            let mut c = from_meta(f.meta, f.qpos.concat());
            c.origin = path.display().to_string();
            c
        };
        clip.validate()?;
        Ok(clip)
    }
}

fn parse<T: serde::de::DeserializeOwned>(path: &Path, text: &str) -> Result<T> {
    Ok(repertoire_files::parse_ron(path, text)?)
}

fn to_ron<T: Serialize>(path: &Path, value: &T) -> Result<String> {
    ron::ser::to_string_pretty(value, pretty()).map_err(|e| ClipError::Usage(format!("{}: {e}", path.display())))
}

/// A NumPy v1.0 `.npy` file of a C-order little-endian f64 `rows × cols` array.
pub fn npy_bytes(values: &[f64], rows: usize, cols: usize) -> Vec<u8> {
    let mut header = format!("{{'descr': '<f8', 'fortran_order': False, 'shape': ({rows}, {cols}), }}");
    // magic (6) + version (2) + length (2) + header + '\n' is a multiple of 64.
    let total = 10 + header.len() + 1;
    header.push_str(&" ".repeat((64 - total % 64) % 64));
    header.push('\n');
    let mut out = Vec::with_capacity(10 + header.len() + values.len() * 8);
    out.extend_from_slice(b"\x93NUMPY\x01\x00");
    out.extend_from_slice(&(header.len() as u16).to_le_bytes());
    out.extend_from_slice(header.as_bytes());
    for v in values {
        out.extend_from_slice(&v.to_le_bytes());
    }
    out
}

/// Parses a `.npy` file holding a 2-D little-endian f64 C-order array: `(rows, cols, values)`.
pub fn parse_npy(bytes: &[u8]) -> std::result::Result<(usize, usize, Vec<f64>), String> {
    let (dims, values) = parse_npy_array(bytes)?;
    let [rows, cols] = dims[..] else { return Err(format!("expected a 2-D array, shape is {dims:?}")) };
    Ok((rows, cols, values))
}

/// Parses a `.npy` file of a little-endian C-order `f8` or `f4` array of any shape: `(shape,
/// values)`, the values as f64.
pub fn parse_npy_array(bytes: &[u8]) -> std::result::Result<(Vec<usize>, Vec<f64>), String> {
    let rest = bytes.strip_prefix(b"\x93NUMPY").ok_or("not a .npy file (bad magic)")?;
    let (major, rest) = rest.split_first().ok_or("truncated header")?;
    let (_minor, rest) = rest.split_first().ok_or("truncated header")?;
    let (len, rest) = match major {
        1 => {
            let (l, r) = rest.split_at_checked(2).ok_or("truncated header")?;
            (usize::from(u16::from_le_bytes([l[0], l[1]])), r)
        }
        2 | 3 => {
            let (l, r) = rest.split_at_checked(4).ok_or("truncated header")?;
            (u32::from_le_bytes([l[0], l[1], l[2], l[3]]) as usize, r)
        }
        v => return Err(format!("unsupported .npy version {v}")),
    };
    let (header, data) = rest.split_at_checked(len).ok_or("truncated header")?;
    let header = std::str::from_utf8(header).map_err(|_| "header is not text")?;
    let compact: String = header.chars().filter(|c| !c.is_whitespace()).collect();
    let width = if compact.contains("'descr':'<f8'") {
        8
    } else if compact.contains("'descr':'<f4'") {
        4
    } else {
        return Err(format!("expected little-endian f64 or f32 ('<f8', '<f4'), header is {}", header.trim()));
    };
    if !compact.contains("'fortran_order':False") {
        return Err("Fortran-order arrays are not supported".into());
    }
    let shape = compact
        .split_once("'shape':(")
        .and_then(|(_, s)| s.split_once(')'))
        .map(|(s, _)| s)
        .ok_or("header has no shape")?;
    let dims: Vec<usize> = shape
        .split(',')
        .filter(|s| !s.is_empty())
        .map(|s| s.parse().map_err(|_| format!("bad shape `{shape}`")))
        .collect::<std::result::Result<_, _>>()?;
    let count = dims.iter().try_fold(1usize, |n, &d| n.checked_mul(d)).ok_or("shape overflows")?;
    if data.len() != count * width {
        return Err(format!("shape {dims:?} needs {} bytes of data, found {}", count * width, data.len()));
    }
    let values = if width == 8 {
        data.chunks_exact(8).map(|c| f64::from_le_bytes(c.try_into().expect("8 bytes"))).collect()
    } else {
        data.chunks_exact(4).map(|c| f64::from(f32::from_le_bytes(c.try_into().expect("4 bytes")))).collect()
    };
    Ok((dims, values))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn npy_round_trips_and_is_aligned() {
        let v = [1.0, -2.5, f64::MIN_POSITIVE, 1e300, 0.1, 7.0];
        let b = npy_bytes(&v, 2, 3);
        let header_len = u16::from_le_bytes([b[8], b[9]]) as usize;
        assert_eq!((10 + header_len) % 64, 0);
        assert_eq!(parse_npy(&b).unwrap(), (2, 3, v.to_vec()));
        assert!(parse_npy(&b[..b.len() - 1]).unwrap_err().contains("needs 48 bytes"));
        assert!(parse_npy(b"hello").is_err());
    }
}
