//! Keyframe clips (RON): joint-space poses at times, interpolated smoothly into a [`Clip`].
//!
//! ```ron
//! KeyframeClip(
//!     name: "wave",
//!     fps: 60.0,
//!     keys: [
//!         (t: 0.0),
//!         (t: 0.5, joints: {"right_shoulder_x": -150.0, "right_elbow": 40.0}),
//!         (t: 1.0, root: (x: 0.1, heading_deg: 10.0)),
//!     ],
//! )
//! ```
//!
//! Angles are degrees (slide joints metres). A joint or the root left out of a key keeps its
//! value from the key before (the first key starts from the standing pose). Each value follows a
//! cubic Hermite curve through its keys with Catmull–Rom tangents (zero at the ends and at local
//! extrema, so holds do not overshoot); angles are clamped to the joints' ranges. Without any
//! `z`, the root height is set each frame so the lowest foot point rests on the floor; with one,
//! it is interpolated and only lifted where a foot would go below the floor.

use crate::body::{ClipBody, JointKind};
use crate::clip::Clip;
use crate::error::{ClipError, Result, read_text};
use crate::math::{Q, yaw_quat};
use crate::retarget::lowest_foot;
use mujoco_rs::prelude::*;
use repertoire_scenes::Location;
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

/// The root's pose in a key.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct RootKey {
    /// Position along x, metres.
    pub x: f64,
    /// Position along y, metres.
    pub y: f64,
    /// Height of the root, metres; `None`: feet on the floor.
    pub z: Option<f64>,
    /// Heading, degrees counter-clockwise from +x.
    pub heading_deg: f64,
    /// Pitch about the root's y axis, degrees (positive tips forward).
    pub pitch_deg: f64,
    /// Roll about the root's x axis, degrees.
    pub roll_deg: f64,
}

/// One key: a time and the values set at it.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Key {
    /// Seconds.
    pub t: f64,
    /// Root pose; omitted: as at the previous key.
    #[serde(default)]
    pub root: Option<RootKey>,
    /// Joint name → angle in degrees (metres for slide joints); omitted joints keep their value.
    #[serde(default)]
    pub joints: BTreeMap<String, f64>,
}

/// A keyframe clip file.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct KeyframeClip {
    /// Clip name.
    pub name: String,
    /// What the motion is, in words.
    #[serde(default)]
    pub description: String,
    /// Output frame rate.
    #[serde(default = "default_fps")]
    pub fps: f64,
    /// Whether the clip is a cycle.
    #[serde(default)]
    pub looping: bool,
    /// The keys, in increasing time.
    pub keys: Vec<Key>,
}

fn default_fps() -> f64 {
    60.0
}

/// A keyframe clip with its file and text (for error locations).
#[derive(Debug, Clone)]
pub struct LoadedKeyframes {
    /// The clip description.
    pub clip: KeyframeClip,
    /// The file.
    pub path: PathBuf,
    /// Its text.
    pub text: String,
}

impl LoadedKeyframes {
    /// Reads a keyframe file.
    pub fn load(path: &Path) -> Result<Self> {
        Self::parse(path, read_text(path)?)
    }

    /// Parses keyframe text (`path` for messages).
    pub fn parse(path: &Path, text: String) -> Result<Self> {
        let clip: KeyframeClip = repertoire_files::parse_ron(path, &text)?;
        Ok(LoadedKeyframes { clip, path: path.to_path_buf(), text })
    }

    fn error(&self, needle: &str, message: String) -> ClipError {
        ClipError::Keyframes { file: self.path.clone(), loc: Location::find_quoted(&self.text, needle), message }
    }

    /// Interpolates the keys into a clip for `body`.
    pub fn to_clip(&self, body: &ClipBody) -> Result<Clip> {
        let kc = &self.clip;
        if kc.keys.len() < 2 {
            return Err(self.error("keys", format!("{} key(s); a keyframe clip needs at least 2", kc.keys.len())));
        }
        if !(kc.fps.is_finite() && kc.fps > 0.0) {
            return Err(self.error("fps", format!("fps must be positive, found {}", kc.fps)));
        }
        for w in kc.keys.windows(2) {
            if w[1].t <= w[0].t || !w[0].t.is_finite() || !w[1].t.is_finite() {
                return Err(self.error(
                    &format!("t: {}", fmt_num(w[1].t)),
                    format!("key times must increase: {} then {}", w[0].t, w[1].t),
                ));
            }
        }
        // Channels: the root's six values, then each named joint.
        let mut channels: Vec<(usize, f64, Option<[f64; 2]>)> = Vec::new(); // (qpos, scale, range)
        let mut names: Vec<&str> = Vec::new();
        for key in &kc.keys {
            for (name, v) in &key.joints {
                let Some(j) = body.joint(name) else {
                    return Err(self.error(
                        name,
                        format!("unknown joint `{name}`; {} has: {}", body.origin().display(), hinge_names(body)),
                    ));
                };
                if !matches!(j.kind, JointKind::Hinge | JointKind::Slide) {
                    return Err(
                        self.error(name, format!("joint `{name}` is not a hinge or slide; use `root` for the root"))
                    );
                }
                if !v.is_finite() {
                    return Err(self.error(name, format!("joint `{name}` has a non-finite value at t = {}", key.t)));
                }
                if !names.contains(&name.as_str()) {
                    names.push(name);
                    let scale = if j.kind == JointKind::Hinge { 1f64.to_radians() } else { 1.0 };
                    channels.push((j.qpos, scale, j.range));
                }
            }
        }
        let times: Vec<f64> = kc.keys.iter().map(|k| k.t).collect();
        // Root values per key (held from the previous key when omitted).
        let mut roots = Vec::with_capacity(kc.keys.len());
        let mut last = RootKey::default();
        for k in &kc.keys {
            if let Some(r) = k.root {
                last = r;
            }
            roots.push(last);
        }
        let has_z = kc.keys.iter().any(|k| k.root.is_some_and(|r| r.z.is_some()));
        let root_series = |f: &dyn Fn(&RootKey) -> f64| roots.iter().map(f).collect::<Vec<_>>();
        let rx = root_series(&|r| r.x);
        let ry = root_series(&|r| r.y);
        let rh = root_series(&|r| r.heading_deg.to_radians());
        let rp = root_series(&|r| r.pitch_deg.to_radians());
        let rr = root_series(&|r| r.roll_deg.to_radians());
        let mut zlast = body.standing_qpos()[body.index.root_qpos + 2];
        let rz: Vec<f64> = roots
            .iter()
            .map(|r| {
                if let Some(z) = r.z {
                    zlast = z;
                }
                zlast
            })
            .collect();
        let joint_series: Vec<Vec<f64>> = names
            .iter()
            .map(|name| {
                let mut v = body.standing_qpos()[body.joint(name).map_or(0, |j| j.qpos)];
                let scale = channels[names.iter().position(|n| n == name).unwrap_or(0)].1;
                kc.keys
                    .iter()
                    .map(|k| {
                        if let Some(a) = k.joints.get(*name) {
                            v = a * scale;
                        }
                        v
                    })
                    .collect()
            })
            .collect();

        let (t0, t1) = (times[0], times[times.len() - 1]);
        let n = ((t1 - t0) * kc.fps + 1e-9).floor() as usize + 1;
        let nq = body.nq();
        let r = body.index.root_qpos;
        let mut data = MjData::new(&body.model);
        let mut qpos = Vec::with_capacity(n * nq);
        for f in 0..n {
            let t = t0 + f as f64 / kc.fps;
            let mut q = body.standing_qpos().to_vec();
            for ((qa, _, range), series) in channels.iter().zip(&joint_series) {
                let v = hermite(&times, series, t);
                q[*qa] = range.map_or(v, |[lo, hi]| v.clamp(lo, hi));
            }
            q[r] = hermite(&times, &rx, t);
            q[r + 1] = hermite(&times, &ry, t);
            q[r + 2] = hermite(&times, &rz, t);
            let rot = yaw_quat(hermite(&times, &rh, t))
                * Q::axis_angle([0.0, 1.0, 0.0], hermite(&times, &rp, t))
                * Q::axis_angle([1.0, 0.0, 0.0], hermite(&times, &rr, t));
            q[r + 3..r + 7].copy_from_slice(&rot.to_array());
            data.qpos_mut().copy_from_slice(&q);
            data.kinematics();
            let low = lowest_foot(body, &data);
            if !has_z || low < 0.0 {
                q[r + 2] -= low;
            }
            qpos.extend_from_slice(&q);
        }
        let mut clip = Clip::new(kc.name.clone(), body, kc.fps, qpos, self.path.display().to_string())?;
        clip.looping = kc.looping;
        Ok(clip)
    }
}

fn fmt_num(v: f64) -> String {
    format!("{v:?}")
}

fn hinge_names(body: &ClipBody) -> String {
    body.joints
        .iter()
        .filter(|j| matches!(j.kind, JointKind::Hinge | JointKind::Slide))
        .map(|j| j.name.as_str())
        .collect::<Vec<_>>()
        .join(", ")
}

/// Cubic Hermite interpolation of `(times, values)` at `t` with Catmull–Rom tangents, zero at
/// the ends and at local extrema.
pub fn hermite(times: &[f64], values: &[f64], t: f64) -> f64 {
    let n = times.len().min(values.len());
    if n == 0 {
        return 0.0;
    }
    if n == 1 || t <= times[0] {
        return values[0];
    }
    if t >= times[n - 1] {
        return values[n - 1];
    }
    let i = times[..n].partition_point(|&x| x <= t).saturating_sub(1).min(n - 2);
    let tangent = |k: usize| {
        if k == 0 || k + 1 >= n {
            return 0.0;
        }
        let (a, b, c) = (values[k - 1], values[k], values[k + 1]);
        if (b - a) * (c - b) <= 0.0 {
            return 0.0;
        }
        (c - a) / (times[k + 1] - times[k - 1])
    };
    let h = times[i + 1] - times[i];
    let u = (t - times[i]) / h;
    let (u2, u3) = (u * u, u * u * u);
    let h00 = 2.0 * u3 - 3.0 * u2 + 1.0;
    let h10 = u3 - 2.0 * u2 + u;
    let h01 = -2.0 * u3 + 3.0 * u2;
    let h11 = u3 - u2;
    h00 * values[i] + h10 * h * tangent(i) + h01 * values[i + 1] + h11 * h * tangent(i + 1)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn hermite_passes_through_keys_without_overshoot() {
        let t = [0.0, 1.0, 2.0, 3.0];
        let v = [0.0, 1.0, 1.0, 0.0];
        for (ti, vi) in t.iter().zip(v) {
            assert!((hermite(&t, &v, *ti) - vi).abs() < 1e-12);
        }
        for k in 0..=300 {
            let x = hermite(&t, &v, k as f64 * 0.01);
            assert!((-1e-12..=1.0 + 1e-12).contains(&x), "{x}");
        }
        let rising = [0.0, 1.0, 2.0, 3.0];
        assert!((hermite(&t, &rising, 1.5) - 1.5).abs() < 1e-12);
    }
}
