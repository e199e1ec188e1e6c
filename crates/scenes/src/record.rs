//! Recordings of rollouts: per control tick, every body's pose, the scene's qpos and what the
//! rollout says about itself (active skill, reward terms, contacts, phase), plus, once per file,
//! the geoms needed to draw any MJCF scene; optionally a ghost (the reference clip's pose).
//!
//! A [`Recorder`] is fed by a rollout loop after each control step; it only pushes into buffers
//! sized up front. [`Recording::save`] writes one file, atomically:
//!
//! ```text
//! b"REPREC\x01\n"  u32 header length  header (JSON)
//! time f64[n]  qpos f64[n·nq]  poses f32[n·bodies·7]  ghost f32[n·character·7] (empty without one)
//! skill i32[n]  phase f32[n]  terms f32[n·terms]  contacts u64[n·6]  fall u8[n]
//! FNV-1a 64 of everything before it
//! ```
//!
//! all little-endian; a pose is `x y z qw qx qy qz` in the world frame; a frame's contacts are
//! pelvis_on, hand_on ×2, character_on, prop_on_floor (bit sets over props) and feet_on_floor
//! (bit 0 left, bit 1 right; format 1 files have the first five only); `fall` is the fall
//! test's verdict so far ([`crate::fall`]): 0 none, else [`FallCause::code`] (files written
//! before the shared fall test hold 1 wherever a part not allowed on the floor touched it). A 20 s rollout of the
//! built-in humanoid at 60 Hz with a ghost is about 1.5 MB.

use std::path::Path;
use std::sync::Arc;

use mujoco_rs::prelude::*;
use serde::{Deserialize, Serialize};

pub use crate::error::RecordingError;
use crate::error::{Result, SceneError};
use crate::fall::{Fall, FallCause};
use crate::world::{Contacts, PropMount, World, WorldModel};

/// The file's first bytes.
pub const MAGIC: &[u8; 8] = b"REPREC\x01\n";
/// Version of the layout: 2 added the feet's floor contact (format 1 is still read).
pub const FORMAT: u32 = 2;
/// Numbers per pose: position then quaternion (w x y z).
pub const POSE: usize = 7;
/// u64 words of [`Contacts`] per frame in a file of `format` (pelvis_on, hand_on ×2,
/// character_on, prop_on_floor, and from format 2 feet_on_floor).
fn contact_words(format: u32) -> usize {
    if format >= 2 { 6 } else { 5 }
}

/// How a geom is drawn.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub enum GeomShape {
    /// An infinite plane (size: half extents of the drawn part, 0 = unbounded).
    Plane,
    /// Sphere (size[0]: radius).
    Sphere,
    /// Capsule along local z (size: radius, half length).
    Capsule,
    /// Ellipsoid (size: three radii).
    Ellipsoid,
    /// Cylinder along local z (size: radius, half length).
    Cylinder,
    /// Box (size: half extents).
    Box,
    /// A mesh or height field, drawn as a box of its bounding size.
    Other,
}

/// One joint of a body (for exports: which hinges make up a body's rotation).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct JointInfo {
    /// Its name.
    pub name: String,
    /// `free`, `ball`, `slide` or `hinge`.
    pub kind: String,
    /// Axis in the body frame (hinge, slide).
    pub axis: [f64; 3],
    /// Index into qpos.
    pub qpos: usize,
}

/// One recorded body (every body of the model but the world).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct BodyInfo {
    /// Its name.
    pub name: String,
    /// Parent body (index into the recording's bodies), `None` under the world.
    pub parent: Option<usize>,
    /// Position in the parent's frame at qpos0.
    pub pos: [f64; 3],
    /// Orientation in the parent's frame at qpos0 (w x y z).
    pub quat: [f64; 4],
    /// Whether it belongs to the character (the ghost draws these).
    pub character: bool,
    /// Its joints, in model order.
    pub joints: Vec<JointInfo>,
}

/// One geom, as drawn.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct GeomInfo {
    /// Its name (may be empty).
    pub name: String,
    /// The body it moves with (index into the recording's bodies), `None` for world geoms.
    pub body: Option<usize>,
    /// Its shape.
    pub shape: GeomShape,
    /// MuJoCo's size triple for the shape.
    pub size: [f64; 3],
    /// Position in its body's frame.
    pub pos: [f64; 3],
    /// Orientation in its body's frame (w x y z).
    pub quat: [f64; 4],
    /// Colour.
    pub rgba: [f32; 4],
}

/// What a recording holds, written once per file.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Header {
    /// [`FORMAT`].
    pub format: u32,
    /// One line for people: what was recorded (`walk: skill play, seed 1`).
    pub title: String,
    /// The scenario's name.
    pub scenario: String,
    /// Frames per second (the control rate).
    pub control_hz: f64,
    /// qpos width of the scene.
    pub nq: usize,
    /// Bodies, model order (world left out).
    pub bodies: Vec<BodyInfo>,
    /// Geoms, model order.
    pub geoms: Vec<GeomInfo>,
    /// Props by name, with their body index.
    pub props: Vec<(String, usize)>,
    /// The character's root body (the free joint's: the pelvis, or the part it hangs from), index
    /// into `bodies`.
    pub root: usize,
    /// The character's feet (left, right), indices into `bodies` (format 2 on).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub feet: Option<[usize; 2]>,
    /// Names a frame's skill index refers to.
    pub skills: Vec<String>,
    /// Names of the per-frame terms (reward terms, distances, ...).
    pub terms: Vec<String>,
    /// What the phase counts (`reference frame`, ...).
    pub phase: String,
    /// The ghost's clip, when ghost poses of the character's bodies are recorded.
    pub ghost: Option<String>,
    /// Number of frames.
    pub frames: usize,
}

impl Header {
    /// Indices (into `bodies`) of the character's bodies, in order: the ghost's pose layout.
    pub fn character(&self) -> Vec<usize> {
        (0..self.bodies.len()).filter(|&b| self.bodies[b].character).collect()
    }

    fn ghost_bodies(&self) -> usize {
        if self.ghost.is_some() { self.bodies.iter().filter(|b| b.character).count() } else { 0 }
    }

    /// Bytes of the frame columns (everything between the header and the checksum).
    fn data_len(&self) -> Option<usize> {
        let n = self.frames;
        let per_frame = 8usize
            .checked_add(8usize.checked_mul(self.nq)?)?
            .checked_add(4 * POSE * self.bodies.len().checked_add(self.ghost_bodies())?)?
            .checked_add(4 + 4 + 4usize.checked_mul(self.terms.len())?)?
            .checked_add(8 * contact_words(self.format) + 1)?;
        n.checked_mul(per_frame)
    }
}

/// A whole recording: the header and per-frame columns.
#[derive(Debug, Clone, PartialEq)]
pub struct Recording {
    /// What is recorded.
    pub header: Header,
    /// Simulated seconds per frame.
    pub time: Vec<f64>,
    /// Scene qpos, `frames × nq`.
    pub qpos: Vec<f64>,
    /// Body poses, `frames × bodies × 7`.
    pub poses: Vec<f32>,
    /// Ghost poses of the character's bodies, `frames × character × 7` (empty without a ghost).
    pub ghost: Vec<f32>,
    /// Active skill (index into `header.skills`), −1 for none.
    pub skill: Vec<i32>,
    /// Phase (reference frame index, or what `header.phase` says).
    pub phase: Vec<f32>,
    /// Terms, `frames × terms`.
    pub terms: Vec<f32>,
    /// Contacts per frame (`fallen`: the fall test's verdict so far, as in `fall`).
    pub contacts: Vec<Contacts>,
    /// The fall test's verdict per frame: 0 none, else the cause's [`FallCause::code`].
    pub fall: Vec<u8>,
}

/// What a rollout says about one frame besides the world's state.
#[derive(Debug, Clone, Copy, Default)]
pub struct Annotation<'a> {
    /// Active skill (index into the header's skills).
    pub skill: Option<usize>,
    /// Phase.
    pub phase: f64,
    /// Term values, in the header's order (missing ones are recorded as NaN-free zeros).
    pub terms: &'a [f32],
    /// The ghost's full scene qpos (only the character's part is used).
    pub ghost_qpos: Option<&'a [f64]>,
}

/// What a [`Recorder`] is told up front.
#[derive(Debug, Clone, Default)]
pub struct RecordOptions {
    /// One line for people.
    pub title: String,
    /// Skill names.
    pub skills: Vec<String>,
    /// Term names.
    pub terms: Vec<String>,
    /// What the phase counts.
    pub phase: String,
    /// The ghost's clip name, when a ghost is recorded.
    pub ghost: Option<String>,
    /// Frames to reserve room for.
    pub capacity: usize,
}

/// Collects a rollout's frames; see the module documentation.
pub struct Recorder {
    rec: Recording,
    /// Kinematics of the recorded qpos (after `mj_step`, MuJoCo's body poses are those of the
    /// state before the last physics step; recomputing them keeps poses and qpos in step).
    kin: MjData<Arc<MjModel>>,
    ghost_data: Option<MjData<Arc<MjModel>>>,
    character: Vec<usize>,
}

fn shape_of(t: mujoco_rs::wrappers::mj_model::MjtGeomBase) -> GeomShape {
    use mujoco_rs::wrappers::mj_model::MjtGeomBase as MjtGeom;
    match t {
        MjtGeom::mjGEOM_PLANE => GeomShape::Plane,
        MjtGeom::mjGEOM_SPHERE => GeomShape::Sphere,
        MjtGeom::mjGEOM_CAPSULE => GeomShape::Capsule,
        MjtGeom::mjGEOM_ELLIPSOID => GeomShape::Ellipsoid,
        MjtGeom::mjGEOM_CYLINDER => GeomShape::Cylinder,
        MjtGeom::mjGEOM_BOX => GeomShape::Box,
        _ => GeomShape::Other,
    }
}

/// The header of a recording of `model`'s scene (frames: 0).
pub fn header_of(model: &WorldModel, options: &RecordOptions) -> Header {
    let m = model.mj_model();
    let nbody = m.ffi().nbody as usize;
    let name = |kind, i| m.id_to_name(kind, i).unwrap_or("").to_string();
    let jnt_body = m.jnt_bodyid();
    let bodies = (1..nbody)
        .map(|b| BodyInfo {
            name: name(MjtObjBase::mjOBJ_BODY, b),
            parent: match m.body_parentid()[b] as usize {
                0 => None,
                p => Some(p - 1),
            },
            pos: m.body_pos()[b],
            quat: m.body_quat()[b],
            character: model.index.is_character[b],
            joints: (0..jnt_body.len())
                .filter(|&j| jnt_body[j] as usize == b)
                .map(|j| JointInfo {
                    name: name(MjtObjBase::mjOBJ_JOINT, j),
                    kind: match m.jnt_type()[j] {
                        MjtJoint::mjJNT_FREE => "free",
                        MjtJoint::mjJNT_BALL => "ball",
                        MjtJoint::mjJNT_SLIDE => "slide",
                        _ => "hinge",
                    }
                    .to_string(),
                    axis: m.jnt_axis()[j],
                    qpos: m.jnt_qposadr()[j] as usize,
                })
                .collect(),
        })
        .collect();
    let matid = m.geom_matid();
    let geoms = (0..m.ffi().ngeom as usize)
        .map(|g| GeomInfo {
            name: name(MjtObjBase::mjOBJ_GEOM, g),
            body: match m.geom_bodyid()[g] as usize {
                0 => None,
                b => Some(b - 1),
            },
            shape: shape_of(m.geom_type()[g]),
            size: m.geom_size()[g],
            pos: m.geom_pos()[g],
            quat: m.geom_quat()[g],
            rgba: if matid[g] >= 0 { m.mat_rgba()[matid[g] as usize] } else { m.geom_rgba()[g] },
        })
        .collect();
    Header {
        format: FORMAT,
        title: options.title.clone(),
        scenario: model.scenario.scenario.name.clone(),
        control_hz: 1.0 / model.control_dt(),
        nq: m.ffi().nq as usize,
        bodies,
        geoms,
        props: model.props.iter().map(|p| (p.name.clone(), p.body - 1)).collect(),
        root: model.index.root_body - 1,
        feet: Some(model.index.feet.map(|b| b - 1)),
        skills: options.skills.clone(),
        terms: options.terms.clone(),
        phase: options.phase.clone(),
        ghost: options.ghost.clone(),
        frames: 0,
    }
}

impl Recorder {
    /// A recorder for worlds of `model`, with room for `options.capacity` frames.
    pub fn new(model: &WorldModel, options: RecordOptions) -> Self {
        let header = header_of(model, &options);
        let character = header.character();
        let rec = Recording::empty(header, options.capacity);
        let ghost_data = options.ghost.as_ref().map(|_| MjData::new(Arc::clone(model.mj_model())));
        Recorder { rec, kin: MjData::new(Arc::clone(model.mj_model())), ghost_data, character }
    }

    /// Frames recorded so far.
    pub fn len(&self) -> usize {
        self.rec.time.len()
    }

    /// Whether no frame was recorded yet.
    pub fn is_empty(&self) -> bool {
        self.rec.time.is_empty()
    }

    /// Records `world` as it is now, with the rollout's annotation. A diverged state (a NaN or
    /// infinite qpos) is not recorded: the recording ends at the last finite frame.
    pub fn record(&mut self, world: &World, a: &Annotation<'_>) {
        let d = world.data();
        if !d.time().is_finite() || d.qpos().iter().any(|v| !v.is_finite()) {
            return;
        }
        let r = &mut self.rec;
        r.time.push(d.time());
        r.qpos.extend_from_slice(d.qpos());
        let k = &mut self.kin;
        k.qpos_mut().copy_from_slice(d.qpos());
        for (dst, src) in k.mocap_pos_mut().iter_mut().zip(d.mocap_pos()) {
            *dst = *src;
        }
        for (dst, src) in k.mocap_quat_mut().iter_mut().zip(d.mocap_quat()) {
            *dst = *src;
        }
        k.kinematics();
        let (xpos, xquat) = (k.xpos(), k.xquat());
        for b in 1..xpos.len() {
            push_pose(&mut r.poses, xpos[b], xquat[b]);
        }
        if let Some(g) = self.ghost_data.as_mut() {
            match a.ghost_qpos.filter(|q| q.len() == g.qpos().len()) {
                Some(q) => {
                    g.qpos_mut().copy_from_slice(q);
                    for (dst, src) in g.mocap_pos_mut().iter_mut().zip(d.mocap_pos()) {
                        *dst = *src;
                    }
                    g.kinematics();
                    for &b in &self.character {
                        push_pose(&mut r.ghost, g.xpos()[b + 1], g.xquat()[b + 1]);
                    }
                }
                // No reference this frame: the ghost stands where the body is.
                None => {
                    for &b in &self.character {
                        push_pose(&mut r.ghost, xpos[b + 1], xquat[b + 1]);
                    }
                }
            }
        }
        r.skill.push(a.skill.map_or(-1, |s| s as i32));
        r.phase.push(a.phase as f32);
        let nt = r.header.terms.len();
        r.terms.extend((0..nt).map(|k| a.terms.get(k).copied().filter(|v| v.is_finite()).unwrap_or(0.0)));
        let fall = world.fall();
        r.contacts.push(Contacts { fallen: fall.is_some(), ..world.contacts() });
        r.fall.push(fall.map_or(0, |f| f.cause.code()));
        r.header.frames += 1;
    }

    /// The recording.
    pub fn finish(self) -> Recording {
        self.rec
    }

    /// Drops the frames recorded so far (a new episode of the same scene).
    pub fn restart(&mut self) {
        let r = &mut self.rec;
        r.time.clear();
        r.qpos.clear();
        r.poses.clear();
        r.ghost.clear();
        r.skill.clear();
        r.phase.clear();
        r.terms.clear();
        r.contacts.clear();
        r.fall.clear();
        r.header.frames = 0;
    }

    /// The recording so far, leaving this recorder empty (same header) for the next episode.
    pub fn take(&mut self) -> Recording {
        let empty = Recording::empty(self.rec.header.clone(), 0);
        std::mem::replace(&mut self.rec, empty)
    }
}

impl Recording {
    /// A recording of no frames under `header`, with room for `capacity` frames.
    fn empty(mut header: Header, n: usize) -> Recording {
        header.frames = 0;
        Recording {
            time: Vec::with_capacity(n),
            qpos: Vec::with_capacity(n * header.nq),
            poses: Vec::with_capacity(n * header.bodies.len() * POSE),
            ghost: Vec::with_capacity(n * header.ghost_bodies() * POSE),
            skill: Vec::with_capacity(n),
            phase: Vec::with_capacity(n),
            terms: Vec::with_capacity(n * header.terms.len()),
            contacts: Vec::with_capacity(n),
            fall: Vec::with_capacity(n),
            header,
        }
    }
}

fn push_pose(out: &mut Vec<f32>, p: [f64; 3], q: [f64; 4]) {
    out.extend([p[0], p[1], p[2], q[0], q[1], q[2], q[3]].map(|v| v as f32));
}

fn fnv1a(bytes: &[u8]) -> u64 {
    crate::body::fnv1a(&[bytes])
}

impl Recording {
    /// Number of frames.
    pub fn frames(&self) -> usize {
        self.header.frames
    }

    /// Seconds per frame.
    pub fn dt(&self) -> f64 {
        1.0 / self.header.control_hz
    }

    /// The first frame the fall test counted a fall at, with its cause.
    pub fn first_fall(&self) -> Option<(usize, FallCause)> {
        self.fall.iter().enumerate().find_map(|(f, &c)| FallCause::from_code(c).map(|cause| (f, cause)))
    }

    /// The frames `from..` as a recording of their own (a fixture cut from a long episode).
    pub fn frames_from(&self, from: usize) -> Recording {
        let from = from.min(self.frames());
        let h = &self.header;
        let n = self.frames() - from;
        let cut = |v: usize| from * v..;
        let nb = h.bodies.len();
        Recording {
            header: Header { frames: n, ..h.clone() },
            time: self.time[cut(1)].to_vec(),
            qpos: self.qpos[cut(h.nq)].to_vec(),
            poses: self.poses[cut(nb * POSE)].to_vec(),
            ghost: self.ghost[cut(h.ghost_bodies() * POSE)].to_vec(),
            skill: self.skill[cut(1)].to_vec(),
            phase: self.phase[cut(1)].to_vec(),
            terms: self.terms[cut(h.terms.len())].to_vec(),
            contacts: self.contacts[cut(1)].to_vec(),
            fall: self.fall[cut(1)].to_vec(),
        }
    }

    /// Frame `f`'s qpos.
    pub fn qpos_at(&self, f: usize) -> &[f64] {
        &self.qpos[f * self.header.nq..(f + 1) * self.header.nq]
    }

    /// Frame `f`'s pose of body `b` (index into the header's bodies): position, quaternion.
    pub fn pose(&self, f: usize, b: usize) -> ([f64; 3], [f64; 4]) {
        let k = (f * self.header.bodies.len() + b) * POSE;
        let p = &self.poses[k..k + POSE];
        let v = |i: usize| f64::from(p[i]);
        ([v(0), v(1), v(2)], [v(3), v(4), v(5), v(6)])
    }

    /// The file's bytes (see the module documentation).
    pub fn to_bytes(&self) -> Vec<u8> {
        // Written in this build's format, whatever the file it was read from.
        let header = Header { format: FORMAT, ..self.header.clone() };
        let data = header.data_len().unwrap_or(0);
        let header = serde_json::to_vec(&header).expect("a header is plain data");
        let mut out = Vec::with_capacity(MAGIC.len() + 4 + header.len() + data + 8);
        out.extend_from_slice(MAGIC);
        out.extend_from_slice(&(header.len() as u32).to_le_bytes());
        out.extend_from_slice(&header);
        self.time.iter().for_each(|v| out.extend_from_slice(&v.to_le_bytes()));
        self.qpos.iter().for_each(|v| out.extend_from_slice(&v.to_le_bytes()));
        self.poses.iter().for_each(|v| out.extend_from_slice(&v.to_le_bytes()));
        self.ghost.iter().for_each(|v| out.extend_from_slice(&v.to_le_bytes()));
        self.skill.iter().for_each(|v| out.extend_from_slice(&v.to_le_bytes()));
        self.phase.iter().for_each(|v| out.extend_from_slice(&v.to_le_bytes()));
        self.terms.iter().for_each(|v| out.extend_from_slice(&v.to_le_bytes()));
        for c in &self.contacts {
            let feet = u64::from(c.feet_on_floor[0]) | u64::from(c.feet_on_floor[1]) << 1;
            for w in [c.pelvis_on, c.hand_on[0], c.hand_on[1], c.character_on, c.prop_on_floor, feet] {
                out.extend_from_slice(&w.to_le_bytes());
            }
        }
        out.extend_from_slice(&self.fall);
        let sum = fnv1a(&out);
        out.extend_from_slice(&sum.to_le_bytes());
        out
    }

    /// Writes the recording to `path` (a temporary file beside it, then a rename).
    pub fn save(&self, path: &Path) -> Result<()> {
        self.check().map_err(|m| corrupt(path, RecordingError::Inconsistent(m)))?;
        write_atomic(path, &self.to_bytes())
    }

    /// Reads a recording; a file that is not one, is cut short, corrupt or inconsistent is
    /// refused with the file and what is wrong named.
    pub fn load(path: &Path) -> Result<Recording> {
        let bytes = std::fs::read(path).map_err(|source| SceneError::unreadable(path, source))?;
        Self::from_bytes(&bytes).map_err(|e| corrupt(path, e))
    }

    /// Parses a recording's bytes; the error says what is wrong (without the file name).
    pub fn from_bytes(bytes: &[u8]) -> std::result::Result<Recording, RecordingError> {
        let rest = bytes.strip_prefix(MAGIC.as_slice()).ok_or(RecordingError::NotARecording)?;
        let (len, rest) = rest.split_at_checked(4).ok_or(RecordingError::HeaderCut)?;
        let len = u32::from_le_bytes([len[0], len[1], len[2], len[3]]) as usize;
        let (header, data) =
            rest.split_at_checked(len).ok_or(RecordingError::HeaderLength { said: len, found: rest.len() })?;
        let header: Header = serde_json::from_slice(header).map_err(|e| RecordingError::Header {
            line: e.line(),
            column: e.column(),
            message: e.to_string(),
        })?;
        if !(1..=FORMAT).contains(&header.format) {
            return Err(RecordingError::Format { found: header.format, newest: FORMAT });
        }
        let want = header.data_len().ok_or(RecordingError::Overflow)?;
        if data.len() != want + 8 {
            return Err(RecordingError::Length { frames: header.frames, want: want + 8, found: data.len() });
        }
        let body_end = bytes.len() - 8;
        let stored = u64::from_le_bytes(bytes[body_end..].try_into().expect("8 bytes"));
        if fnv1a(&bytes[..body_end]) != stored {
            return Err(RecordingError::Checksum);
        }
        let n = header.frames;
        let mut at = 0usize;
        let mut take = |count: usize, width: usize| {
            let s = &data[at..at + count * width];
            at += count * width;
            s
        };
        let f64s = |s: &[u8]| s.chunks_exact(8).map(|c| f64::from_le_bytes(c.try_into().expect("8"))).collect();
        let f32s = |s: &[u8]| s.chunks_exact(4).map(|c| f32::from_le_bytes(c.try_into().expect("4"))).collect();
        let u64s = |s: &[u8]| -> Vec<u64> {
            s.chunks_exact(8).map(|c| u64::from_le_bytes(c.try_into().expect("8"))).collect()
        };
        let nb = header.bodies.len();
        let time: Vec<f64> = f64s(take(n, 8));
        let qpos: Vec<f64> = f64s(take(n * header.nq, 8));
        let poses: Vec<f32> = f32s(take(n * nb * POSE, 4));
        let ghost: Vec<f32> = f32s(take(n * header.ghost_bodies() * POSE, 4));
        let skill = take(n, 4).chunks_exact(4).map(|c| i32::from_le_bytes(c.try_into().expect("4"))).collect();
        let phase: Vec<f32> = f32s(take(n, 4));
        let terms: Vec<f32> = f32s(take(n * header.terms.len(), 4));
        let words_per_frame = contact_words(header.format);
        let words = u64s(take(n * words_per_frame, 8));
        let fall = take(n, 1).to_vec();
        let contacts = words
            .chunks_exact(words_per_frame)
            .zip(&fall)
            .map(|(w, &f)| {
                let feet = w.get(5).copied().unwrap_or(0);
                Contacts {
                    fallen: f != 0,
                    pelvis_on: w[0],
                    hand_on: [w[1], w[2]],
                    character_on: w[3],
                    prop_on_floor: w[4],
                    feet_on_floor: [feet & 1 != 0, feet & 2 != 0],
                }
            })
            .collect();
        let rec = Recording { header, time, qpos, poses, ghost, skill, phase, terms, contacts, fall };
        rec.check().map_err(RecordingError::Inconsistent)?;
        Ok(rec)
    }

    /// Checks the header's references and that every number is finite.
    fn check(&self) -> std::result::Result<(), String> {
        let h = &self.header;
        let nb = h.bodies.len();
        if h.control_hz.is_nan() || h.control_hz <= 0.0 {
            return Err(format!("control rate {} is not positive", h.control_hz));
        }
        if h.root >= nb {
            return Err(format!("root body {} is not one of the {nb} bodies", h.root));
        }
        for (i, b) in h.bodies.iter().enumerate() {
            if b.parent.is_some_and(|p| p >= i) {
                return Err(format!(
                    "body {i} (`{}`) names parent {:?}, which does not come before it",
                    b.name, b.parent
                ));
            }
            if let Some(j) = b.joints.iter().find(|j| j.qpos >= h.nq) {
                return Err(format!("joint `{}` has qpos address {} past nq {}", j.name, j.qpos, h.nq));
            }
        }
        if let Some(g) = h.geoms.iter().find(|g| g.body.is_some_and(|b| b >= nb)) {
            return Err(format!("geom `{}` belongs to body {:?}, past the {nb} bodies", g.name, g.body));
        }
        if let Some((p, _)) = h.props.iter().find(|(_, b)| *b >= nb) {
            return Err(format!("prop `{p}` has no body"));
        }
        let n = h.frames;
        let sizes = [
            ("time", self.time.len(), n),
            ("qpos", self.qpos.len(), n * h.nq),
            ("poses", self.poses.len(), n * nb * POSE),
            ("ghost", self.ghost.len(), n * h.ghost_bodies() * POSE),
            ("skill", self.skill.len(), n),
            ("phase", self.phase.len(), n),
            ("terms", self.terms.len(), n * h.terms.len()),
            ("contacts", self.contacts.len(), n),
            ("fall", self.fall.len(), n),
        ];
        if let Some((what, got, want)) = sizes.iter().find(|(_, got, want)| got != want) {
            return Err(format!("{what} holds {got} values, {n} frames need {want}"));
        }
        let frame_of = |k: usize, width: usize| k / width.max(1);
        if let Some(k) = self.time.iter().position(|v| !v.is_finite()) {
            return Err(format!("frame {k}: time is not a finite number"));
        }
        if let Some(k) = self.qpos.iter().position(|v| !v.is_finite()) {
            return Err(format!("frame {}: qpos value {} is not a finite number", frame_of(k, h.nq), k % h.nq));
        }
        if let Some(k) = self.poses.iter().position(|v| !v.is_finite()) {
            let b = (k / POSE) % nb.max(1);
            return Err(format!(
                "frame {}: the pose of body `{}` is not finite",
                frame_of(k, nb * POSE),
                h.bodies[b].name
            ));
        }
        if let Some(k) = self.ghost.iter().position(|v| !v.is_finite()) {
            return Err(format!("frame {}: a ghost pose is not finite", frame_of(k, h.ghost_bodies() * POSE)));
        }
        if let Some(k) = self.skill.iter().position(|&s| s < -1 || s >= h.skills.len() as i32) {
            return Err(format!(
                "frame {k}: skill index {} is not one of the {} skills",
                self.skill[k],
                h.skills.len()
            ));
        }
        Ok(())
    }
}

fn corrupt(path: &Path, problem: RecordingError) -> SceneError {
    SceneError::Recording { file: path.to_path_buf(), problem }
}

/// Writes `bytes` to `path` via a temporary file beside it and a rename, so readers never see
/// half a file.
pub fn write_atomic(path: &Path, bytes: &[u8]) -> Result<()> {
    repertoire_files::write_atomic(path, bytes).map_err(|e| SceneError::Write { file: e.path, source: e.source })
}

/// Judging a recording again needs the world of its scene; it lives here, beside recordings,
/// so that the world does not depend on them.
impl World {
    /// The fall test run again over a recording of this scene, frame by frame from its recorded
    /// qpos and fixed props' poses (velocities zero, so only what poses and contacts show):
    /// per frame, the fall once one counted. Recordings made before the shared fall test, or
    /// under another rule, are judged by this scene's. `Err` when the recording is of another
    /// scene (its qpos width or bodies differ).
    pub fn judge(&mut self, rec: &Recording) -> Result<Vec<Option<Fall>>> {
        let h = &rec.header;
        let model = self.shared.mj_model();
        let nbody = model.ffi().nbody as usize;
        let names: Vec<&str> =
            (1..nbody).map(|b| model.id_to_name(MjtObjBase::mjOBJ_BODY, b).unwrap_or_default()).collect();
        if h.nq != self.data.qpos().len() || h.bodies.len() != names.len() {
            return Err(SceneError::Usage(format!(
                "the recording `{}` is of a scene with qpos width {} and {} bodies; scenario `{}` has {} and {}",
                h.title,
                h.nq,
                h.bodies.len(),
                self.shared.scenario.scenario.name,
                self.data.qpos().len(),
                names.len()
            )));
        }
        if let Some((b, (want, got))) =
            names.iter().zip(&h.bodies).map(|(n, r)| (*n, r.name.as_str())).enumerate().find(|(_, (n, r))| n != r)
        {
            return Err(SceneError::Usage(format!(
                "the recording's body {b} is `{got}`; scenario `{}` has `{want}` there",
                self.shared.scenario.scenario.name
            )));
        }
        let fixed: Vec<(usize, usize)> = self
            .shared
            .props
            .iter()
            .filter_map(|p| match p.mount {
                PropMount::Fixed { mocap } => Some((mocap, p.body)),
                PropMount::Free { .. } => None,
            })
            .collect();
        let dt = rec.dt();
        self.fall.reset();
        let mut out = Vec::with_capacity(rec.frames());
        for f in 0..rec.frames() {
            self.data.qpos_mut().copy_from_slice(rec.qpos_at(f));
            self.data.qvel_mut().fill(0.0);
            self.data.set_time(rec.time[f]);
            for &(mocap, body) in &fixed {
                let (pos, quat) = rec.pose(f, body - 1);
                self.data.mocap_pos_mut()[mocap] = pos;
                self.data.mocap_quat_mut()[mocap] = quat;
            }
            self.forward();
            self.check_fall(if f == 0 { 0.0 } else { dt });
            out.push(self.fall.fall());
        }
        Ok(out)
    }
}
