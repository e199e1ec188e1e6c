//! Retargeting a motion-capture clip onto a MuJoCo body.
//!
//! 1. Source key points (the map's joints) are taken per frame by forward kinematics and turned
//!    z-up (y-up data: `(x, y, z) → (z, x, y)`, a proper rotation, so a left turn stays a left
//!    turn).
//! 2. They are re-proportioned to the body: the pelvis follows the source pelvis scaled by the
//!    leg-length ratio (or the map's `scale`); every other point hangs off its parent point
//!    (nearest key-point ancestor in the source skeleton) along the source direction, at the
//!    body's own segment length. The clip is turned so its initial heading (from the hip and
//!    shoulder lines) is +x, plus the map's `heading_offset_deg`, starts above the origin, and
//!    is lifted so a low percentile of ankle heights matches the body's standing ankle height.
//! 3. Joint angles (the root free joint and every hinge) are solved frame by frame by damped
//!    least squares on the weighted key-point errors with MuJoCo Jacobians (`mj_jac` after
//!    `mj_kinematics` + `mj_comPos` on the body alone), warm-started from the previous frame,
//!    limited joints clamped to their range, with a floor term that pushes up any foot geom
//!    below z = 0; a post-pass then lifts the root so the lowest foot point never penetrates.

use crate::body::{ClipBody, JointKind};
use crate::clip::Clip;
use crate::error::{ClipError, Result};
use crate::map::{LoadedMap, Role};
use crate::math::{Q, cholesky_solve, norm, sub, yaw_quat};
use mujoco_rs::mujoco_c;
use mujoco_rs::prelude::*;
use std::path::Path;
use std::time::Instant;

/// MuJoCo data of a body-only model.
pub(crate) type Data<'a> = MjData<&'a MjModel>;

/// Solver settings.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RetargetOptions {
    /// IK iterations for the first frame (cold start).
    pub first_iterations: usize,
    /// IK iterations per later frame (warm start).
    pub iterations: usize,
    /// Levenberg–Marquardt damping λ added to the normal equations.
    pub damping: f64,
    /// Weight of the floor term (foot geoms below z = 0).
    pub floor_weight: f64,
    /// Stop iterating when the largest step is below this (radians / metres).
    pub tolerance: f64,
    /// Percentile (0–1) of per-frame lowest-ankle heights that is put at the body's standing
    /// ankle height.
    pub floor_percentile: f64,
}

impl Default for RetargetOptions {
    fn default() -> Self {
        RetargetOptions {
            first_iterations: 200,
            iterations: 30,
            damping: 1e-4,
            floor_weight: 4.0,
            tolerance: 1e-6,
            floor_percentile: 0.1,
        }
    }
}

/// A retargeted clip with what it was matched against.
#[derive(Debug, Clone)]
pub struct Retargeted {
    /// The clip (qpos frames of the body at the source frame rate).
    pub clip: Clip,
    /// The key points' roles, in map order.
    pub roles: Vec<Role>,
    /// The key points' target names (body or site), in map order.
    pub targets: Vec<String>,
    /// Re-proportioned source key points per frame (`frames × points`, world, metres).
    pub goals: Vec<[f64; 3]>,
    /// Distance from each goal to the body's point after retargeting (`frames × points`, m).
    pub errors: Vec<f64>,
    /// Source-to-body length factor used for the root path.
    pub scale: f64,
    /// Total IK iterations.
    pub iterations: usize,
    /// Wall-clock seconds for the IK and floor passes.
    pub seconds: f64,
}

/// A point of the body: body id and offset in the body frame.
#[derive(Debug, Clone, Copy)]
struct BodyPoint {
    body: usize,
    offset: [f64; 3],
}

/// Resolves a map target name (body or site) plus offset against the body.
fn resolve_target(body: &ClipBody, map: &LoadedMap, name: &str, offset: (f64, f64, f64)) -> Result<BodyPoint> {
    let m = &body.model;
    let off = [offset.0, offset.1, offset.2];
    if let Some(b) = m.name_to_id(MjtObjBase::mjOBJ_BODY, name) {
        return Ok(BodyPoint { body: b, offset: off });
    }
    if let Some(s) = m.name_to_id(MjtObjBase::mjOBJ_SITE, name) {
        let q = Q::from_slice(&m.site_quat()[s]);
        let r = q.rotate(off);
        let p = m.site_pos()[s];
        return Ok(BodyPoint { body: m.site_bodyid()[s] as usize, offset: [p[0] + r[0], p[1] + r[1], p[2] + r[2]] });
    }
    Err(map.error(name, format!("target point `{name}` is not a body or site of {}", body.origin().display())))
}

fn point_pos(data: &Data<'_>, p: BodyPoint) -> [f64; 3] {
    let x = data.xpos()[p.body];
    let r = data.xmat()[p.body];
    let o = p.offset;
    [
        x[0] + r[0] * o[0] + r[1] * o[1] + r[2] * o[2],
        x[1] + r[3] * o[0] + r[4] * o[1] + r[5] * o[2],
        x[2] + r[6] * o[0] + r[7] * o[1] + r[8] * o[2],
    ]
}

/// The lowest point of a geom (world) after kinematics.
pub(crate) fn geom_lowest(model: &MjModel, data: &Data<'_>, g: usize) -> [f64; 3] {
    let c = data.geom_xpos()[g];
    let r = data.geom_xmat()[g];
    let size = model.geom_size()[g];
    let col = |k: usize| [r[k], r[3 + k], r[6 + k]];
    let add = |p: [f64; 3], v: [f64; 3], s: f64| [p[0] + v[0] * s, p[1] + v[1] * s, p[2] + v[2] * s];
    match model.geom_type()[g] {
        MjtGeomBase::mjGEOM_BOX => {
            let mut p = c;
            for k in 0..3 {
                let s = if r[6 + k] > 0.0 { -size[k] } else { size[k] };
                p = add(p, col(k), s);
            }
            p
        }
        MjtGeomBase::mjGEOM_SPHERE => [c[0], c[1], c[2] - size[0]],
        MjtGeomBase::mjGEOM_CAPSULE | MjtGeomBase::mjGEOM_CYLINDER => {
            let a = col(2);
            let end = add(c, a, if a[2] > 0.0 { -size[1] } else { size[1] });
            [end[0], end[1], end[2] - size[0]]
        }
        MjtGeomBase::mjGEOM_ELLIPSOID => [c[0], c[1], c[2] - size[0].max(size[1]).max(size[2])],
        _ => [c[0], c[1], c[2] - model.geom_rbound()[g]],
    }
}

/// The lowest foot point's height (world z) after kinematics.
pub(crate) fn lowest_foot(body: &ClipBody, data: &Data<'_>) -> f64 {
    body.foot_geoms.iter().flatten().map(|&g| geom_lowest(&body.model, data, g)[2]).fold(f64::INFINITY, f64::min)
}

fn kinematics(data: &mut Data<'_>) {
    data.kinematics();
    data.com_pos();
}

/// Retargets `source` (parsed from `source_path`) onto `body` with `map`.
pub fn retarget(
    source: &repertoire_mocap::Clip,
    source_path: &Path,
    map: &LoadedMap,
    body: &ClipBody,
    options: &RetargetOptions,
) -> Result<Retargeted> {
    let skel = &source.skeleton;
    map.check_source(skel, source_path)?;
    let points = &map.map.points;
    let np = points.len();
    let targets: Vec<BodyPoint> =
        points.iter().map(|p| resolve_target(body, map, &p.target, p.offset)).collect::<Result<_>>()?;
    let role_index = |r: Role| points.iter().position(|p| p.role == r);
    let req = |r: Role| role_index(r).ok_or_else(|| map.error("points", format!("the map has no `{r:?}` point")));
    let (pelvis, lhip, rhip) = (req(Role::Pelvis)?, req(Role::LeftHip)?, req(Role::RightHip)?);
    let (lknee, rknee, lankle, rankle) =
        (req(Role::LeftKnee)?, req(Role::RightKnee)?, req(Role::LeftAnkle)?, req(Role::RightAnkle)?);

    // Source key points per frame, z-up.
    let n = source.motion.frame_count();
    if n < 2 {
        return Err(ClipError::unusable(
            source_path.display(),
            format!("too short: {n} frame(s); a clip needs at least 2"),
        ));
    }
    let joint_of: Vec<usize> = points.iter().map(|p| skel.joint_index(&p.source).unwrap_or(0)).collect();
    let up = map.map.up;
    let mut src = Vec::with_capacity(n * np);
    for f in 0..n {
        let pose = source.motion.world_pose(skel, f).ok_or_else(|| {
            ClipError::unusable(source_path.display(), format!("frame {f}: the motion does not fit the skeleton"))
        })?;
        for (p, &j) in points.iter().zip(&joint_of) {
            let v = if p.end_site { pose.end_sites[j].unwrap_or(pose.positions[j]) } else { pose.positions[j] };
            if !v.is_finite() {
                return Err(ClipError::unusable(
                    source_path.display(),
                    format!("frame {f} has a non-finite position for joint `{}`", p.source),
                ));
            }
            src.push(match up {
                crate::map::Up::Y => [v.z, v.x, v.y],
                crate::map::Up::Z => [v.x, v.y, v.z],
            });
        }
    }
    let s = |f: usize, k: usize| src[f * np + k];

    // Key-point tree: the nearest key-point ancestor in the source skeleton.
    let parent: Vec<Option<usize>> = (0..np)
        .map(|k| {
            if k == pelvis {
                return None;
            }
            let own = |j: usize| (0..np).find(|&p| !points[p].end_site && joint_of[p] == j);
            let mut j = if points[k].end_site { Some(joint_of[k]) } else { skel.joints[joint_of[k]].parent };
            while let Some(jj) = j {
                if let Some(p) = own(jj).filter(|&p| p != k) {
                    return Some(p);
                }
                j = skel.joints[jj].parent;
            }
            Some(pelvis)
        })
        .collect();
    let mut order: Vec<usize> = (0..np).collect();
    order.sort_by_key(|&k| (k != pelvis, joint_of[k], points[k].end_site));

    // The body's rest geometry.
    let model = &body.model;
    let nq = body.nq();
    let mut data = MjData::new(model);
    let qpos0 = body.standing_qpos().to_vec();
    data.qpos_mut().copy_from_slice(&qpos0);
    kinematics(&mut data);
    let rest: Vec<[f64; 3]> = targets.iter().map(|&t| point_pos(&data, t)).collect();
    let seg: Vec<f64> = (0..np).map(|k| parent[k].map_or(0.0, |p| norm(sub(rest[k], rest[p])))).collect();

    let leg = |get: &dyn Fn(usize) -> [f64; 3]| {
        0.5 * (norm(sub(get(lhip), get(lknee)))
            + norm(sub(get(lknee), get(lankle)))
            + norm(sub(get(rhip), get(rknee)))
            + norm(sub(get(rknee), get(rankle))))
    };
    let body_leg = leg(&|k| rest[k]);
    let source_leg = (0..n).map(|f| leg(&|k| s(f, k))).sum::<f64>() / n as f64;
    let scale = match map.map.scale {
        Some(x) => x,
        None if source_leg > 1e-6 => body_leg / source_leg,
        None => return Err(map.error("points", "the source legs have zero length; set `scale`".into())),
    };

    // Heading: turn the initial left direction (hips, plus shoulders) to +y, i.e. facing +x.
    let mut left = sub(s(0, lhip), s(0, rhip));
    if let (Some(a), Some(b)) = (role_index(Role::LeftShoulder), role_index(Role::RightShoulder)) {
        let d = sub(s(0, a), s(0, b));
        left = [left[0] + d[0], left[1] + d[1], left[2]];
    }
    let heading = (-left[0]).atan2(left[1]);
    let turn = -heading + map.map.heading_offset_deg.to_radians();
    let (st, ct) = turn.sin_cos();
    let rot = |v: [f64; 3]| [ct * v[0] - st * v[1], st * v[0] + ct * v[1], v[2]];

    // Re-proportioned goals.
    let origin = rot(s(0, pelvis));
    let mut goals = vec![[0.0; 3]; n * np];
    for f in 0..n {
        for &k in &order {
            let g = match parent[k] {
                None => {
                    let p = rot(s(f, k).map(|c| c * scale));
                    [p[0] - origin[0] * scale, p[1] - origin[1] * scale, p[2]]
                }
                Some(p) => {
                    let d = rot(sub(s(f, k), s(f, p)));
                    let len = norm(d);
                    let gp = goals[f * np + p];
                    let k_len = if len > 1e-9 { seg[k] / len } else { scale };
                    [gp[0] + d[0] * k_len, gp[1] + d[1] * k_len, gp[2] + d[2] * k_len]
                }
            };
            goals[f * np + k] = g;
        }
    }
    let mut lows: Vec<f64> = (0..n).map(|f| goals[f * np + lankle][2].min(goals[f * np + rankle][2])).collect();
    lows.sort_by(f64::total_cmp);
    let pick = ((n - 1) as f64 * options.floor_percentile.clamp(0.0, 1.0)).round() as usize;
    let lift = 0.5 * (rest[lankle][2] + rest[rankle][2]) - lows[pick];
    for g in &mut goals {
        g[2] += lift;
    }

    // IK.
    let start = Instant::now();
    let mut solver = Solver::new(body, options);
    let weights: Vec<f64> = points.iter().map(|p| p.weight).collect();
    let r = body.index.root_qpos;
    let mut q = qpos0.clone();
    let mut qpos = Vec::with_capacity(n * nq);
    let mut errors = Vec::with_capacity(n * np);
    let mut iterations = 0;
    let mut prev_pelvis = goals[pelvis];
    for f in 0..n {
        let goal = &goals[f * np..(f + 1) * np];
        if f == 0 {
            let l = sub(goal[lhip], goal[rhip]);
            let yaw = (-l[0]).atan2(l[1]);
            q[r + 3..r + 7].copy_from_slice(&yaw_quat(yaw).to_array());
            let off = yaw_quat(yaw).rotate(sub(rest[pelvis], [qpos0[r], qpos0[r + 1], qpos0[r + 2]]));
            for i in 0..3 {
                q[r + i] = goal[pelvis][i] - off[i];
            }
        } else {
            let d = sub(goal[pelvis], prev_pelvis);
            for i in 0..3 {
                q[r + i] += d[i];
            }
        }
        prev_pelvis = goal[pelvis];
        let its = if f == 0 { options.first_iterations } else { options.iterations };
        iterations += solver.solve(&mut data, &mut q, &targets, goal, &weights, its);
        // Post-pass: the lowest foot point never below the floor.
        data.qpos_mut().copy_from_slice(&q);
        kinematics(&mut data);
        let low = lowest_foot(body, &data);
        if low < 0.0 {
            q[r + 2] -= low;
            data.qpos_mut().copy_from_slice(&q);
            kinematics(&mut data);
        }
        for (k, &t) in targets.iter().enumerate() {
            errors.push(norm(sub(point_pos(&data, t), goal[k])));
        }
        qpos.extend_from_slice(&q);
    }
    let seconds = start.elapsed().as_secs_f64();

    let name = source_path.file_stem().map(|s| s.to_string_lossy().into_owned()).unwrap_or_else(|| "clip".into());
    let origin = format!("{} (map {})", source_path.display(), map.map.name);
    let mut clip = Clip::new(name, body, 1.0 / source.motion.frame_time, qpos, origin)?;
    clip.looping = source.looping.unwrap_or(false);
    Ok(Retargeted {
        clip,
        roles: points.iter().map(|p| p.role).collect(),
        targets: points.iter().map(|p| p.target.clone()).collect(),
        goals,
        errors,
        scale,
        iterations,
        seconds,
    })
}

/// Damped least-squares IK with preallocated buffers (no allocation per iteration).
struct Solver<'a> {
    body: &'a ClipBody,
    opts: RetargetOptions,
    nv: usize,
    jac: Vec<f64>,
    h: Vec<f64>,
    g: Vec<f64>,
    limited: Vec<(usize, [f64; 2])>,
}

impl<'a> Solver<'a> {
    fn new(body: &'a ClipBody, opts: &RetargetOptions) -> Self {
        let nv = body.nv();
        let limited = body
            .joints
            .iter()
            .filter(|j| matches!(j.kind, JointKind::Hinge | JointKind::Slide))
            .filter_map(|j| j.range.map(|r| (j.qpos, r)))
            .collect();
        Solver { body, opts: *opts, nv, jac: vec![0.0; 3 * nv], h: vec![0.0; nv * nv], g: vec![0.0; nv], limited }
    }

    /// Adds `w · Jᵀ J` and `w · Jᵀ e` for the 3 rows in `self.jac` (rows with `mask`).
    fn accumulate(&mut self, w: f64, e: [f64; 3], rows: [bool; 3]) {
        let nv = self.nv;
        for r in 0..3 {
            if !rows[r] {
                continue;
            }
            let row = &self.jac[r * nv..(r + 1) * nv];
            for i in 0..nv {
                let ji = row[i];
                if ji == 0.0 {
                    continue;
                }
                self.g[i] += w * ji * e[r];
                let hrow = &mut self.h[i * nv..(i + 1) * nv];
                for (hj, &jj) in hrow.iter_mut().zip(row) {
                    *hj += w * ji * jj;
                }
            }
        }
    }

    fn jacobian(&mut self, data: &Data<'_>, point: [f64; 3], body: usize) {
        // SAFETY: jac holds 3·nv values; the point and body id are valid for the model.
        unsafe {
            mujoco_c::mj_jac(
                self.body.model.ffi(),
                data.ffi(),
                self.jac.as_mut_ptr(),
                std::ptr::null_mut(),
                &point,
                body as i32,
            );
        }
    }

    /// Runs up to `iterations` DLS steps from `q`; returns the number taken.
    fn solve(
        &mut self,
        data: &mut Data<'_>,
        q: &mut [f64],
        targets: &[BodyPoint],
        goal: &[[f64; 3]],
        weights: &[f64],
        iterations: usize,
    ) -> usize {
        let nv = self.nv;
        let model = &self.body.model;
        for it in 0..iterations {
            data.qpos_mut().copy_from_slice(q);
            kinematics(data);
            self.h.fill(0.0);
            self.g.fill(0.0);
            for ((&t, &gp), &w) in targets.iter().zip(goal).zip(weights) {
                if w == 0.0 {
                    continue;
                }
                let p = point_pos(data, t);
                self.jacobian(data, p, t.body);
                self.accumulate(w, sub(gp, p), [true; 3]);
            }
            for side in 0..2 {
                for gi in 0..self.body.foot_geoms[side].len() {
                    let g = self.body.foot_geoms[side][gi];
                    let low = geom_lowest(model, data, g);
                    if low[2] < 0.0 {
                        self.jacobian(data, low, model.geom_bodyid()[g] as usize);
                        self.accumulate(self.opts.floor_weight, [0.0, 0.0, -low[2]], [false, false, true]);
                    }
                }
            }
            for i in 0..nv {
                self.h[i * nv + i] += self.opts.damping;
            }
            if !cholesky_solve(&mut self.h, &mut self.g, nv) {
                return it;
            }
            // SAFETY: q has nq values and g nv values for this model.
            unsafe { mujoco_c::mj_integratePos(model.ffi(), q.as_mut_ptr(), self.g.as_ptr(), 1.0) };
            for &(a, [lo, hi]) in &self.limited {
                q[a] = q[a].clamp(lo, hi);
            }
            let step = self.g.iter().fold(0.0f64, |m, v| m.max(v.abs()));
            if step < self.opts.tolerance {
                return it + 1;
            }
        }
        iterations
    }
}
