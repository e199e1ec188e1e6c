//! [`Reference`]: a clip resampled to the control rate and laid out as the rewards read it.
//!
//! Everything the imitation reward compares is heading-invariant (joint angles and velocities,
//! end effectors relative to the pelvis in its heading frame, pelvis height, pitch and roll,
//! root velocity in the heading frame), so a reference frame can be matched wherever and
//! whichever way the character stands. Root poses are kept to place the character at a frame.

use mujoco_rs::prelude::*;
use repertoire_clip::{Clip, ClipBody};
use repertoire_scenes::math::Frame;

use crate::error::{Result, SkillError};

/// End effectors, in this order: left hand, right hand, left foot, right foot, head.
pub const END_EFFECTORS: usize = 5;

/// One clip at the control rate, per frame.
#[derive(Debug, Clone, PartialEq)]
pub struct Reference {
    /// The clip's name.
    pub name: String,
    /// The clip's content hash (recorded in skill manifests).
    pub clip_hash: String,
    /// Seconds per frame (the control period).
    pub dt: f64,
    /// Whether the clip is a cycle (the phase wraps instead of ending).
    pub looping: bool,
    /// Control steps the last frame is held once the clip has played (`ClipRef::hold_s`).
    pub hold_steps: usize,
    /// Actuated joints per frame.
    pub dof: usize,
    /// Actuated joint angles, `frames × dof`, body-map order.
    pub joints: Vec<f64>,
    /// Actuated joint velocities, `frames × dof`.
    pub joint_vel: Vec<f64>,
    /// Root position per frame (world of the clip).
    pub root_pos: Vec<[f64; 3]>,
    /// Root orientation per frame (w x y z).
    pub root_quat: Vec<[f64; 4]>,
    /// The root's qvel per frame (linear velocity in the world, angular in the root frame).
    pub root_qvel: Vec<[f64; 6]>,
    /// Pelvis height per frame.
    pub height: Vec<f64>,
    /// Pelvis heading per frame (radians, unwrapped).
    pub heading: Vec<f64>,
    /// Pelvis pitch and roll per frame.
    pub pitch_roll: Vec<[f64; 2]>,
    /// Root linear velocity in the heading frame per frame.
    pub velocity: Vec<[f64; 3]>,
    /// End effectors relative to the pelvis in its heading frame, per frame.
    pub end_effectors: Vec<[[f64; 3]; END_EFFECTORS]>,
    /// The hands' midpoint per frame (world of the clip): where a held box or ball goes.
    pub hands: Vec<[f64; 3]>,
}

/// `v` (world) in the heading frame of `yaw`: x forward, y left, z up.
pub fn to_heading(yaw: f64, v: [f64; 3]) -> [f64; 3] {
    let (s, c) = yaw.sin_cos();
    [c * v[0] + s * v[1], -s * v[0] + c * v[1], v[2]]
}

/// End effector positions relative to `pelvis` in its heading frame.
pub fn local_end_effectors(pelvis: &Frame, points: [[f64; 3]; END_EFFECTORS]) -> [[f64; 3]; END_EFFECTORS] {
    let yaw = pelvis.yaw();
    points.map(|p| to_heading(yaw, [p[0] - pelvis.pos[0], p[1] - pelvis.pos[1], p[2] - pelvis.pos[2]]))
}

impl Reference {
    /// Resamples `clip` to `control_hz` and derives the per-frame quantities on `body`.
    pub fn new(clip: &Clip, body: &ClipBody, control_hz: f64) -> Result<Self> {
        let clip = clip.resampled(control_hz).map_err(SkillError::Clip)?;
        let features = clip.features(body).map_err(SkillError::Clip)?;
        let n = clip.frame_count();
        if n < 2 {
            return Err(SkillError::Invalid(format!("clip `{}` has {n} frame(s) at {control_hz} Hz", clip.name)));
        }
        let idx = &body.index;
        let (nq, nv, dof) = (clip.nq, features.nv, idx.joints.len());
        let mut data = MjData::new(&body.model);
        let mut r = Reference {
            name: clip.name.clone(),
            clip_hash: clip.content_hash(),
            dt: 1.0 / control_hz,
            looping: clip.looping,
            hold_steps: 0,
            dof,
            joints: Vec::with_capacity(n * dof),
            joint_vel: Vec::with_capacity(n * dof),
            root_pos: Vec::with_capacity(n),
            root_quat: Vec::with_capacity(n),
            root_qvel: Vec::with_capacity(n),
            height: Vec::with_capacity(n),
            heading: Vec::with_capacity(n),
            pitch_roll: Vec::with_capacity(n),
            velocity: Vec::with_capacity(n),
            end_effectors: Vec::with_capacity(n),
            hands: Vec::with_capacity(n),
        };
        for f in 0..n {
            let q = &clip.qpos[f * nq..(f + 1) * nq];
            let v = &features.qvel[f * nv..(f + 1) * nv];
            r.joints.extend(idx.joints.iter().map(|j| q[j.qpos]));
            r.joint_vel.extend(idx.joints.iter().map(|j| v[j.dof]));
            let (rq, rd) = (idx.root_qpos, idx.root_dof);
            r.root_pos.push([q[rq], q[rq + 1], q[rq + 2]]);
            r.root_quat.push([q[rq + 3], q[rq + 4], q[rq + 5], q[rq + 6]]);
            r.root_qvel.push([v[rd], v[rd + 1], v[rd + 2], v[rd + 3], v[rd + 4], v[rd + 5]]);
            data.qpos_mut().copy_from_slice(q);
            data.kinematics();
            let pelvis = Frame { pos: data.xpos()[idx.pelvis], rot: data.xmat()[idx.pelvis] };
            let x = data.xpos();
            let ee = [x[idx.hands[0]], x[idx.hands[1]], x[idx.feet[0]], x[idx.feet[1]], x[idx.head]];
            r.end_effectors.push(local_end_effectors(&pelvis, ee));
            r.hands.push(std::array::from_fn(|k| 0.5 * (ee[0][k] + ee[1][k])));
            r.height.push(pelvis.pos[2]);
            r.heading.push(features.heading[f]);
            r.pitch_roll.push([pelvis.pitch(), pelvis.roll()]);
            r.velocity.push(to_heading(features.heading[f], [v[rd], v[rd + 1], v[rd + 2]]));
        }
        if r.joints.iter().chain(&r.joint_vel).any(|x| !x.is_finite()) {
            return Err(SkillError::Invalid(format!("clip `{}` yields a NaN joint angle or velocity", clip.name)));
        }
        Ok(r)
    }

    /// How low frame `f` sits in the clip: 0 at its highest pelvis, 1 at its lowest (0 for a
    /// clip whose pelvis never moves). Sit uses it to tell seated frames from standing ones.
    pub fn lowness(&self, f: usize) -> f64 {
        let (lo, hi) = self.height.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &h| (a.min(h), b.max(h)));
        if hi > lo { ((hi - self.height[f]) / (hi - lo)).clamp(0.0, 1.0) } else { 0.0 }
    }

    /// Raises the root by `dz · lowness` (velocities follow), so a seated clip rests on a higher
    /// seat while the standing part is unchanged. Joint angles and pelvis-relative end effectors
    /// stay as they are.
    pub fn lift_low(&mut self, dz: f64) {
        if dz == 0.0 {
            return;
        }
        let lift: Vec<f64> = (0..self.frames()).map(|f| dz * self.lowness(f)).collect();
        let n = lift.len();
        for f in 0..n {
            self.root_pos[f][2] += lift[f];
            self.height[f] += lift[f];
            self.hands[f][2] += lift[f];
            // Central differences (one-sided at the ends) of the added height.
            let (a, b) = (f.saturating_sub(1), (f + 1).min(n - 1));
            let vz = if b > a { (lift[b] - lift[a]) / ((b - a) as f64 * self.dt) } else { 0.0 };
            self.root_qvel[f][2] += vz;
            self.velocity[f][2] += vz;
        }
    }

    /// Number of frames.
    pub fn frames(&self) -> usize {
        self.root_pos.len()
    }

    /// The frame whose joint angles and velocities are nearest `joints` / `joint_vel` (a cycle's
    /// last frame repeats its first and is never chosen): where a looping clip picks up a
    /// character that arrives mid-stride from another skill.
    pub fn nearest_frame(&self, joints: &[f64], joint_vel: &[f64]) -> usize {
        nearest_pose(&self.joints, &self.joint_vel, self.dof, self.frames().saturating_sub(1).max(1), joints, joint_vel)
    }

    /// Seconds from the first to the last frame.
    pub fn duration(&self) -> f64 {
        (self.frames() - 1) as f64 * self.dt
    }

    /// Joint angles of frame `f`.
    pub fn joints_at(&self, f: usize) -> &[f64] {
        &self.joints[f * self.dof..(f + 1) * self.dof]
    }

    /// Joint velocities of frame `f`.
    pub fn joint_vel_at(&self, f: usize) -> &[f64] {
        &self.joint_vel[f * self.dof..(f + 1) * self.dof]
    }

    /// The frame at `t` seconds into the clip (clamped to the last).
    pub fn frame_at(&self, t: f64) -> usize {
        ((t / self.dt).round().max(0.0) as usize).min(self.frames() - 1)
    }

    /// Heading change over the clip (radians, left positive).
    pub fn heading_change(&self) -> f64 {
        self.heading[self.frames() - 1] - self.heading[0]
    }
}

/// Weight of joint velocities (rad/s) against joint angles (rad) in [`nearest_pose`]: enough to
/// tell a leg swinging forward from one swinging back through the same angle.
pub const PHASE_VELOCITY_WEIGHT: f64 = 0.01;

/// The index among the first `frames` rows of `table_q`/`table_v` (`dof` values per row) nearest
/// `q`/`v` in `Σ wrap(Δq)² + w·Σ Δv²` with `w` = [`PHASE_VELOCITY_WEIGHT`].
pub fn nearest_pose<T: Copy + Into<f64>>(
    table_q: &[T],
    table_v: &[T],
    dof: usize,
    frames: usize,
    q: &[f64],
    v: &[f64],
) -> usize {
    let mut best = (0, f64::INFINITY);
    for f in 0..frames.min(table_q.len() / dof.max(1)) {
        let rows = (&table_q[f * dof..(f + 1) * dof], &table_v[f * dof..(f + 1) * dof]);
        let dq: f64 =
            rows.0.iter().zip(q).map(|(&a, b)| repertoire_scenes::math::wrap_angle(a.into() - b).powi(2)).sum();
        let dv: f64 = rows.1.iter().zip(v).map(|(&a, b)| (a.into() - b).powi(2)).sum();
        let d = dq + PHASE_VELOCITY_WEIGHT * dv;
        if d < best.1 {
            best = (f, d);
        }
    }
    best.0
}
