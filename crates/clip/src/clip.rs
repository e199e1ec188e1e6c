//! [`Clip`]: qpos frames of one body at a frame rate, with the operations skills need (resample,
//! cut, reverse, mirror, loop), a content hash, and the reference features derived from it by
//! MuJoCo kinematics ([`Features`]).

use crate::body::ClipBody;
use crate::error::{ClipError, Result};
use crate::math::{Q, heading_of_quat, slerp, unwrap_angles, yaw_quat};
use mujoco_rs::mujoco_c;
use mujoco_rs::prelude::*;

/// A reference motion for one body: `frames × nq` qpos values sampled at `fps`.
#[derive(Debug, Clone, PartialEq)]
pub struct Clip {
    /// Short name (the source file's stem, or the keyframe clip's name).
    pub name: String,
    /// Frames per second.
    pub fps: f64,
    /// qpos width of the body.
    pub nq: usize,
    /// qpos address of the root free joint.
    pub root_qpos: usize,
    /// qpos addresses of every quaternion block (root and ball joints).
    pub quat_qpos: Vec<usize>,
    /// Content hash of the body the clip was made for ([`ClipBody::hash`]).
    pub body_hash: String,
    /// Whether the clip is a cycle meant to repeat (its last frame is in phase with its first).
    pub looping: bool,
    /// Where it came from, in words (source file, map), for people.
    pub origin: String,
    /// The frames, row-major.
    pub qpos: Vec<f64>,
}

impl Clip {
    /// A clip for `body` from row-major qpos frames; validated (see [`Clip::validate`]).
    pub fn new(
        name: impl Into<String>,
        body: &ClipBody,
        fps: f64,
        qpos: Vec<f64>,
        origin: impl Into<String>,
    ) -> Result<Self> {
        let clip = Clip {
            name: name.into(),
            fps,
            nq: body.nq(),
            root_qpos: body.index.root_qpos,
            quat_qpos: body.quat_qpos.clone(),
            body_hash: body.hash(),
            looping: false,
            origin: origin.into(),
            qpos,
        };
        clip.validate()?;
        Ok(clip)
    }

    /// Number of frames.
    pub fn frame_count(&self) -> usize {
        self.qpos.len().checked_div(self.nq).unwrap_or(0)
    }

    /// Seconds from the first to the last frame.
    pub fn duration(&self) -> f64 {
        self.frame_count().saturating_sub(1) as f64 / self.fps
    }

    /// Frame `i`'s qpos.
    pub fn frame(&self, i: usize) -> Option<&[f64]> {
        self.qpos.get(i * self.nq..(i + 1) * self.nq)
    }

    /// Checks the clip is usable: a positive frame rate, whole frames, at least 2 of them, every
    /// value finite, indices inside a frame. The message names the clip's origin and, for a
    /// NaN or infinite value, the frame.
    pub fn validate(&self) -> Result<()> {
        let bad = |m: String| Err(ClipError::unusable(&self.origin, m));
        if !(self.fps.is_finite() && self.fps > 0.0) {
            return bad(format!("frame rate must be positive, found {}", self.fps));
        }
        if self.nq == 0 || !self.qpos.len().is_multiple_of(self.nq) {
            return bad(format!("{} values do not make whole frames of {} qpos", self.qpos.len(), self.nq));
        }
        if self.root_qpos + 7 > self.nq || self.quat_qpos.iter().any(|&q| q + 4 > self.nq) {
            return bad(format!("root or quaternion address outside a {}-wide frame", self.nq));
        }
        if let Some(k) = self.qpos.iter().position(|v| !v.is_finite()) {
            return bad(format!(
                "frame {} has a non-finite value ({} at qpos index {})",
                k / self.nq,
                self.qpos[k],
                k % self.nq
            ));
        }
        let n = self.frame_count();
        if n < 2 {
            return bad(format!("too short: {n} frame(s); a clip needs at least 2"));
        }
        Ok(())
    }

    /// Checks the clip fits `body`: the same qpos width (naming both) and root address.
    pub fn check_body(&self, body: &ClipBody) -> Result<()> {
        if self.nq != body.nq() {
            return Err(ClipError::unusable(
                &self.origin,
                format!("qpos width {} does not match the body's {} ({})", self.nq, body.nq(), body.origin().display()),
            ));
        }
        if self.root_qpos != body.index.root_qpos || self.quat_qpos != body.quat_qpos {
            return Err(ClipError::unusable(&self.origin, "the root or quaternion layout differs from the body's"));
        }
        Ok(())
    }

    /// A stable 64-bit FNV-1a hash of the motion content (frame rate, layout, body hash,
    /// looping flag and every qpos value's bits; not the name or origin), as 16 hex digits.
    pub fn content_hash(&self) -> String {
        let mut h: u64 = 0xcbf2_9ce4_8422_2325;
        let mut eat = |bytes: &[u8]| {
            for &b in bytes {
                h ^= u64::from(b);
                h = h.wrapping_mul(0x0100_0000_01b3);
            }
        };
        eat(b"repertoire-clip/1\0");
        eat(&self.fps.to_le_bytes());
        eat(&(self.nq as u64).to_le_bytes());
        eat(&(self.root_qpos as u64).to_le_bytes());
        for &q in &self.quat_qpos {
            eat(&(q as u64).to_le_bytes());
        }
        eat(self.body_hash.as_bytes());
        eat(&[u8::from(self.looping)]);
        for v in &self.qpos {
            eat(&v.to_le_bytes());
        }
        format!("{h:016x}")
    }

    fn with_frames(&self, qpos: Vec<f64>) -> Clip {
        Clip { qpos, ..self.clone() }
    }

    /// Frames `start..end` (end exclusive); an error when the range is empty or out of bounds.
    pub fn cut(&self, start: usize, end: usize) -> Result<Clip> {
        let n = self.frame_count();
        if start >= end || end > n {
            return Err(ClipError::Usage(format!("{}: cannot cut frames {start}..{end} of {n}", self.origin)));
        }
        let mut c = self.with_frames(self.qpos[start * self.nq..end * self.nq].to_vec());
        c.looping = false;
        c.validate()?;
        Ok(c)
    }

    /// The clip with its first frame held for `frames` more frames before it plays (a lead-in:
    /// time for a character arriving in motion to settle before the clip moves on). The held
    /// frames repeat the first frame's qpos, so their velocities are zero.
    pub fn with_lead(&self, frames: usize) -> Clip {
        let mut q = Vec::with_capacity(self.qpos.len() + frames * self.nq);
        for _ in 0..frames {
            q.extend_from_slice(&self.qpos[..self.nq]);
        }
        q.extend_from_slice(&self.qpos);
        self.with_frames(q)
    }

    /// The clip played backwards (reversing twice gives the clip back exactly).
    pub fn reversed(&self) -> Clip {
        let mut q = Vec::with_capacity(self.qpos.len());
        for f in self.qpos.chunks_exact(self.nq).rev() {
            q.extend_from_slice(f);
        }
        self.with_frames(q)
    }

    /// The clip resampled to `fps` over the same time span: linear interpolation for every value,
    /// spherical (slerp) for quaternions.
    pub fn resampled(&self, fps: f64) -> Result<Clip> {
        if !(fps.is_finite() && fps > 0.0) {
            return Err(ClipError::Usage(format!("resample: frame rate must be positive, found {fps}")));
        }
        let n = self.frame_count();
        let span = self.duration();
        let m = (span * fps + 1e-9).floor() as usize + 1;
        let nq = self.nq;
        let mut out = vec![0.0; m * nq];
        for (k, dst) in out.chunks_exact_mut(nq).enumerate() {
            let t = (k as f64 / fps * self.fps).min((n - 1) as f64);
            let i = (t.floor() as usize).min(n - 2);
            let u = t - i as f64;
            let (a, b) = (&self.qpos[i * nq..(i + 1) * nq], &self.qpos[(i + 1) * nq..(i + 2) * nq]);
            for ((d, x), y) in dst.iter_mut().zip(a).zip(b) {
                *d = x + (y - x) * u;
            }
            for &q in self.quat_qpos.iter().filter(|_| u > 0.0) {
                let s = slerp(Q::from_slice(&a[q..q + 4]), Q::from_slice(&b[q..q + 4]), u);
                dst[q..q + 4].copy_from_slice(&s.to_array());
            }
        }
        let mut c = self.with_frames(out);
        c.fps = fps;
        c.validate()?;
        Ok(c)
    }

    /// The clip mirrored left↔right across the x–z plane: root y negated, root orientation
    /// reflected, left and right joints swapped with x/z-axis angles negated (see
    /// [`ClipBody::mirror_table`]). Mirroring twice gives the clip back exactly; a left turn
    /// becomes a right turn.
    pub fn mirrored(&self, body: &ClipBody) -> Result<Clip> {
        self.check_body(body)?;
        let table = body.mirror_table()?;
        let r = self.root_qpos;
        let mut out = self.qpos.clone();
        for (src, dst) in self.qpos.chunks_exact(self.nq).zip(out.chunks_exact_mut(self.nq)) {
            dst[r + 1] = -src[r + 1];
            // Reflection M R M of a rotation: (w, x, y, z) → (w, −x, y, −z).
            dst[r + 4] = -src[r + 4];
            dst[r + 6] = -src[r + 6];
            for &(a, b, sign) in table {
                dst[a] = sign * src[b];
            }
        }
        let mut c = self.with_frames(out);
        c.name = format!("{}_mirrored", self.name);
        Ok(c)
    }

    /// `cycles` repetitions of a cyclic clip, seamless: the last frame is taken to be in phase
    /// with the first, joint angles and root height are blended linearly over the cycle so the
    /// last frame equals the first, and each repetition starts where the previous one ended
    /// (root position and heading accumulate).
    pub fn looped(&self, cycles: usize) -> Result<Clip> {
        if cycles == 0 {
            return Err(ClipError::Usage("loop: need at least one cycle".into()));
        }
        let (n, nq, r) = (self.frame_count(), self.nq, self.root_qpos);
        let mut base = self.qpos.clone();
        // Close the seam: spread first − last over the cycle for every scalar value but the
        // root's x, y and quaternion blocks.
        let is_quat = |i: usize| self.quat_qpos.iter().any(|&q| (q..q + 4).contains(&i));
        let (first, last) = (self.qpos[..nq].to_vec(), self.qpos[(n - 1) * nq..].to_vec());
        for (f, frame) in base.chunks_exact_mut(nq).enumerate() {
            let t = f as f64 / (n - 1) as f64;
            for i in 0..nq {
                if i == r || i == r + 1 || is_quat(i) {
                    continue;
                }
                frame[i] += (first[i] - last[i]) * t;
            }
        }
        let root = |frame: &[f64]| (frame[r], frame[r + 1], heading_of_quat(Q::from_slice(&frame[r + 3..r + 7])));
        let (x0, y0, h0) = root(&base[..nq]);
        let (x1, y1, h1) = root(&base[(n - 1) * nq..]);
        let dh = h1 - h0;
        let mut out = Vec::with_capacity((cycles * (n - 1) + 1) * nq);
        // Transform of cycle k: rotate by k·dh about the cycle start, then translate.
        let (mut ox, mut oy, mut oh) = (x0, y0, 0.0f64);
        for k in 0..cycles {
            let frames = if k + 1 == cycles { n } else { n - 1 };
            let (s, c) = oh.sin_cos();
            let yaw = yaw_quat(oh);
            for frame in base.chunks_exact(nq).take(frames) {
                let mut f = frame.to_vec();
                let (dx, dy) = (frame[r] - x0, frame[r + 1] - y0);
                f[r] = ox + c * dx - s * dy;
                f[r + 1] = oy + s * dx + c * dy;
                let q = yaw * Q::from_slice(&frame[r + 3..r + 7]);
                f[r + 3..r + 7].copy_from_slice(&q.to_array());
                out.extend_from_slice(&f);
            }
            let (dx, dy) = (x1 - x0, y1 - y0);
            ox += c * dx - s * dy;
            oy += s * dx + c * dy;
            oh += dh;
        }
        let mut clip = self.with_frames(out);
        clip.looping = true;
        clip.validate()?;
        Ok(clip)
    }

    /// Joint-space distance between the last and the first frame, ignoring the root's horizontal
    /// position and heading: how far the clip is from a seamless cycle (radians, RMS).
    pub fn seam_error(&self) -> f64 {
        let (n, nq, r) = (self.frame_count(), self.nq, self.root_qpos);
        if n < 2 {
            return 0.0;
        }
        let (a, b) = (&self.qpos[..nq], &self.qpos[(n - 1) * nq..]);
        let skip = |i: usize| i == r || i == r + 1 || self.quat_qpos.iter().any(|&q| (q..q + 4).contains(&i));
        let (sum, count) = (0..nq).filter(|&i| !skip(i)).fold((0.0, 0), |(s, c), i| (s + (a[i] - b[i]).powi(2), c + 1));
        (sum / f64::from(count.max(1))).sqrt()
    }

    /// Derived reference features by MuJoCo kinematics on `body`.
    pub fn features(&self, body: &ClipBody) -> Result<Features> {
        Features::compute(self, body)
    }
}

/// Reference features of a clip, per frame, from MuJoCo kinematics of the body alone.
#[derive(Debug, Clone, PartialEq)]
pub struct Features {
    /// Seconds per frame.
    pub dt: f64,
    /// qvel width.
    pub nv: usize,
    /// Joint velocities (`frames × nv`) by finite differences (`mj_differentiatePos`, so the
    /// root's angular velocity is quaternion-correct, in the root's local frame as MuJoCo's
    /// qvel); the last frame repeats the previous difference.
    pub qvel: Vec<f64>,
    /// End effectors per frame: left hand, right hand, left foot, right foot, head (world).
    pub end_effectors: Vec<[[f64; 3]; 5]>,
    /// Centre of mass of the body per frame (world).
    pub com: Vec<[f64; 3]>,
    /// Root linear velocity per frame (world).
    pub root_linear_velocity: Vec<[f64; 3]>,
    /// Root angular velocity per frame (world).
    pub root_angular_velocity: Vec<[f64; 3]>,
    /// Pelvis heading per frame (radians, counter-clockwise from +x, unwrapped).
    pub heading: Vec<f64>,
}

impl Features {
    /// Computes the features of `clip` on `body`.
    pub fn compute(clip: &Clip, body: &ClipBody) -> Result<Self> {
        clip.check_body(body)?;
        let (n, nq, nv) = (clip.frame_count(), clip.nq, body.nv());
        let model = &body.model;
        let mut data = MjData::new(model);
        let idx = &body.index;
        let mut qvel = vec![0.0; n * nv];
        let mut end_effectors = Vec::with_capacity(n);
        let mut com = Vec::with_capacity(n);
        let mut heading = Vec::with_capacity(n);
        let mut root_linear_velocity = Vec::with_capacity(n);
        let mut root_angular_velocity = Vec::with_capacity(n);
        let dt = 1.0 / clip.fps;
        for f in 0..n {
            let (a, b) = if f + 1 < n { (f, f + 1) } else { (f - 1, f) };
            // SAFETY: both frames and the output row have the model's nq / nv values.
            unsafe {
                mujoco_c::mj_differentiatePos(
                    model.ffi(),
                    qvel[f * nv..].as_mut_ptr(),
                    dt,
                    clip.qpos[a * nq..].as_ptr(),
                    clip.qpos[b * nq..].as_ptr(),
                );
            }
            data.qpos_mut().copy_from_slice(&clip.qpos[f * nq..(f + 1) * nq]);
            data.kinematics();
            data.com_pos();
            let xpos = data.xpos();
            end_effectors.push([
                xpos[idx.hands[0]],
                xpos[idx.hands[1]],
                xpos[idx.feet[0]],
                xpos[idx.feet[1]],
                xpos[idx.head],
            ]);
            com.push(data.subtree_com()[idx.root_body]);
            let m = data.xmat()[idx.pelvis];
            heading.push(m[3].atan2(m[0]));
            let d = idx.root_dof;
            let v = &qvel[f * nv + d..f * nv + d + 6];
            root_linear_velocity.push([v[0], v[1], v[2]]);
            let w = Q::from_slice(&clip.qpos[f * nq + clip.root_qpos + 3..]).rotate([v[3], v[4], v[5]]);
            root_angular_velocity.push(w);
        }
        unwrap_angles(&mut heading);
        Ok(Features { dt, nv, qvel, end_effectors, com, root_linear_velocity, root_angular_velocity, heading })
    }

    /// Heading change from the first to the last frame, radians (left turn positive).
    pub fn heading_change(&self) -> f64 {
        match (self.heading.first(), self.heading.last()) {
            (Some(a), Some(b)) => b - a,
            _ => 0.0,
        }
    }
}
