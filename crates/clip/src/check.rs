//! What `repertoire clip check` measures: import, retarget (or interpolate keyframes) and
//! report per-key-point retarget error, foot penetration and skate, root drift, heading change
//! and duration. A library function, so other tools (the clip pack set-up) can check files too.

use crate::body::ClipBody;
use crate::clip::Clip;
use crate::error::{ClipError, Result};
use crate::keyframe::LoadedKeyframes;
use crate::map::{LoadedMap, Role};
use crate::retarget::{RetargetOptions, Retargeted, lowest_foot, retarget};
use crate::source::{ClipSource, import};
use mujoco_rs::prelude::*;
use std::path::PathBuf;

/// Height below which a foot counts as in contact for the skate measure, metres.
pub const CONTACT_HEIGHT: f64 = 0.025;

/// Retarget error of one key point over the clip.
#[derive(Debug, Clone, PartialEq)]
pub struct PointError {
    /// The key point's role.
    pub role: Role,
    /// Its body (or site) name.
    pub target: String,
    /// Mean distance to the re-proportioned source point, cm.
    pub mean_cm: f64,
    /// Largest distance, cm.
    pub max_cm: f64,
}

/// Points of a foot geom that can touch the floor (world): a box's 8 corners, a capsule's or
/// cylinder's two end bottoms, a sphere's bottom.
fn contact_points(model: &MjModel, data: &MjData<&MjModel>, g: usize, out: &mut Vec<[f64; 3]>) {
    let c = data.geom_xpos()[g];
    let r = data.geom_xmat()[g];
    let s = model.geom_size()[g];
    let at = |l: [f64; 3]| {
        [
            c[0] + r[0] * l[0] + r[1] * l[1] + r[2] * l[2],
            c[1] + r[3] * l[0] + r[4] * l[1] + r[5] * l[2],
            c[2] + r[6] * l[0] + r[7] * l[1] + r[8] * l[2],
        ]
    };
    match model.geom_type()[g] {
        MjtGeomBase::mjGEOM_BOX => {
            for k in 0..8 {
                let sign = |bit: usize| if k & bit == 0 { -1.0 } else { 1.0 };
                out.push(at([sign(1) * s[0], sign(2) * s[1], sign(4) * s[2]]));
            }
        }
        MjtGeomBase::mjGEOM_CAPSULE | MjtGeomBase::mjGEOM_CYLINDER => {
            for end in [-1.0, 1.0] {
                let p = at([0.0, 0.0, end * s[1]]);
                out.push([p[0], p[1], p[2] - s[0]]);
            }
        }
        _ => out.push(crate::retarget::geom_lowest(model, data, g)),
    }
}

/// Motion measures of a clip on its body (any clip, retargeted or authored).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MotionMeasures {
    /// Deepest any foot point goes below the floor, cm (0 when none does).
    pub foot_penetration_cm: f64,
    /// Mean horizontal speed of the feet's floor-contact points (box corners, capsule ends)
    /// while within [`CONTACT_HEIGHT`] of the floor in two consecutive frames, cm/s (0 when
    /// the feet never touch).
    pub foot_skate_cm_s: f64,
    /// Horizontal distance from the root's first to its last position, m.
    pub root_drift_m: f64,
    /// Pelvis heading change from the first to the last frame, degrees (left turn positive).
    pub heading_change_deg: f64,
    /// Mean pelvis pitch over the frames, degrees (positive: tipped forward, the front of the
    /// pelvis down; Z-Y-X Euler angles of the pelvis frame), and its lowest and highest value.
    pub pelvis_pitch_deg: (f64, f64, f64),
    /// Seconds from the first to the last frame.
    pub duration_s: f64,
    /// Frames.
    pub frames: usize,
    /// Frames per second.
    pub fps: f64,
}

impl MotionMeasures {
    /// Measures `clip` on `body`.
    pub fn of(clip: &Clip, body: &ClipBody) -> Result<Self> {
        let features = clip.features(body)?;
        let (n, nq) = (clip.frame_count(), clip.nq);
        let mut data = MjData::new(&body.model);
        let mut penetration: f64 = 0.0;
        let mut skate_sum = 0.0;
        let mut skate_count = 0usize;
        let mut prev: Vec<[f64; 3]> = Vec::new();
        let mut now: Vec<[f64; 3]> = Vec::new();
        let (mut pitch_sum, mut pitch_low, mut pitch_high) = (0.0, f64::INFINITY, f64::NEG_INFINITY);
        for f in 0..n {
            data.qpos_mut().copy_from_slice(&clip.qpos[f * nq..(f + 1) * nq]);
            data.kinematics();
            let pitch = (-data.xmat()[body.index.pelvis][6]).clamp(-1.0, 1.0).asin().to_degrees();
            pitch_sum += pitch;
            pitch_low = pitch_low.min(pitch);
            pitch_high = pitch_high.max(pitch);
            penetration = penetration.max(-lowest_foot(body, &data));
            now.clear();
            for &g in body.foot_geoms.iter().flatten() {
                contact_points(&body.model, &data, g, &mut now);
            }
            if prev.len() == now.len() {
                for (a, b) in prev.iter().zip(&now) {
                    if a[2] < CONTACT_HEIGHT && b[2] < CONTACT_HEIGHT {
                        skate_sum += (b[0] - a[0]).hypot(b[1] - a[1]) * clip.fps;
                        skate_count += 1;
                    }
                }
            }
            std::mem::swap(&mut prev, &mut now);
        }
        let r = clip.root_qpos;
        let (first, last) = (&clip.qpos[..nq], &clip.qpos[(n - 1) * nq..]);
        Ok(MotionMeasures {
            foot_penetration_cm: 100.0 * penetration.max(0.0),
            foot_skate_cm_s: if skate_count > 0 { 100.0 * skate_sum / skate_count as f64 } else { 0.0 },
            root_drift_m: (last[r] - first[r]).hypot(last[r + 1] - first[r + 1]),
            heading_change_deg: features.heading_change().to_degrees(),
            pelvis_pitch_deg: (pitch_sum / n.max(1) as f64, pitch_low, pitch_high),
            duration_s: clip.duration(),
            frames: n,
            fps: clip.fps,
        })
    }
}

/// The result of checking one clip file.
#[derive(Debug, Clone)]
pub struct CheckReport {
    /// The file checked.
    pub source: PathBuf,
    /// The retarget map used (`None` for keyframes).
    pub map: Option<String>,
    /// The shipped maps whose joints the source skeleton has (empty for keyframes).
    pub fitting: Vec<String>,
    /// Where several shipped maps take the skeleton and none was given: each one's mean
    /// key-point error (cm) over the clip's first [`FIT_SECONDS`]; the lowest was used.
    pub fits: Vec<(String, f64)>,
    /// Per key point retarget error (empty for keyframes).
    pub points: Vec<PointError>,
    /// Mean and largest retarget error over all key points and frames, cm.
    pub error_cm: Option<(f64, f64)>,
    /// Measures of the output clip.
    pub motion: MotionMeasures,
    /// Seconds spent in IK (0 for keyframes), and frames solved per second.
    pub retarget_seconds: f64,
    /// Frames retargeted per second of IK.
    pub frames_per_second: f64,
    /// The clip (resampled when asked).
    pub clip: Clip,
}

/// Seconds of a clip retargeted with each candidate map to choose among them by fit.
pub const FIT_SECONDS: f64 = 2.0;

/// Mean key-point error (cm) of `map` on the first [`FIT_SECONDS`] of `source` on `body`.
fn fit_cm(source: &ClipSource, map: LoadedMap, body: &ClipBody, options: &RetargetOptions) -> Result<f64> {
    let (mut mocap, map) = import(source, Some(map))?;
    let keep = ((FIT_SECONDS / mocap.motion.frame_time).round() as usize).max(2);
    mocap.motion.truncate_frames(keep);
    let rt = retarget(&mocap, source.path(), &map, body, options)?;
    Ok(point_errors(&rt).1.0)
}

/// Of `candidates` (maps that each take the source's skeleton), the one whose retarget of the
/// first [`FIT_SECONDS`] of `source` onto `body` has the lowest mean key-point error, with
/// every candidate's error (cm) in the order given.
pub fn best_fit(
    source: &ClipSource,
    candidates: Vec<LoadedMap>,
    body: &ClipBody,
    options: &RetargetOptions,
) -> Result<(LoadedMap, Vec<(String, f64)>)> {
    let mut best: Option<(f64, LoadedMap)> = None;
    let mut fits = Vec::with_capacity(candidates.len());
    for candidate in candidates {
        let cm = fit_cm(source, candidate.clone(), body, options)?;
        fits.push((candidate.map.name.clone(), cm));
        if best.as_ref().is_none_or(|(b, _)| cm < *b) {
            best = Some((cm, candidate));
        }
    }
    let (_, map) = best.ok_or_else(|| ClipError::Usage(format!("{}: no candidate map", source.path().display())))?;
    Ok((map, fits))
}

/// Imports, retargets (or interpolates) and measures `source` on `body`. `map` overrides the
/// shipped map; without one, the shipped map that takes the skeleton, or, where several do,
/// the one that fits it best (lowest key-point error over the first [`FIT_SECONDS`]). `fps`
/// resamples the output clip.
pub fn check(
    source: &ClipSource,
    body: &ClipBody,
    map: Option<LoadedMap>,
    fps: Option<f64>,
    options: &RetargetOptions,
) -> Result<CheckReport> {
    let mut fitting = Vec::new();
    let mut fits = Vec::new();
    let (clip, map_name, points, error_cm, seconds, fps_solved) = match source {
        ClipSource::Keyframes(p) => {
            let clip = LoadedKeyframes::load(p)?.to_clip(body)?;
            (clip, None, Vec::new(), None, 0.0, 0.0)
        }
        _ => {
            let given = map.is_some();
            let (mut mocap, mut map) = import(source, map)?;
            fitting = crate::map::fitting(map.map.format, &mocap.skeleton, source.path())?;
            if !given && fitting.len() > 1 {
                let candidates = crate::map::shipped()?.into_iter().filter(|m| fitting.contains(&m.map.name)).collect();
                (map, fits) = best_fit(source, candidates, body, options)?;
                // Imported again: the map sets the unit and whether frame 0 is a rest pose.
                (mocap, map) = import(source, Some(map))?;
            }
            let rt = retarget(&mocap, source.path(), &map, body, options)?;
            let (points, overall) = point_errors(&rt);
            let fps_solved = rt.clip.frame_count() as f64 / rt.seconds.max(1e-9);
            (rt.clip, Some(map.map.name.clone()), points, Some(overall), rt.seconds, fps_solved)
        }
    };
    let clip = match fps {
        Some(f) => clip.resampled(f)?,
        None => clip,
    };
    let motion = MotionMeasures::of(&clip, body)?;
    Ok(CheckReport {
        source: source.path().to_path_buf(),
        map: map_name,
        fitting,
        fits,
        points,
        error_cm,
        motion,
        retarget_seconds: seconds,
        frames_per_second: fps_solved,
        clip,
    })
}

/// Mean and max error per key point, and over all of them (cm).
pub fn point_errors(rt: &Retargeted) -> (Vec<PointError>, (f64, f64)) {
    let np = rt.roles.len();
    let n = rt.errors.len() / np.max(1);
    let mut all_sum = 0.0;
    let mut all_max: f64 = 0.0;
    let points = (0..np)
        .map(|k| {
            let e = (0..n).map(|f| rt.errors[f * np + k]);
            let (sum, max) = e.fold((0.0, 0.0f64), |(s, m), v| (s + v, m.max(v)));
            all_sum += sum;
            all_max = all_max.max(max);
            PointError {
                role: rt.roles[k],
                target: rt.targets[k].clone(),
                mean_cm: 100.0 * sum / n.max(1) as f64,
                max_cm: 100.0 * max,
            }
        })
        .collect();
    (points, (100.0 * all_sum / (n * np).max(1) as f64, 100.0 * all_max))
}
