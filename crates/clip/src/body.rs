//! The target body of retargeting and of clip features: a body compiled alone (no floor, no
//! props), its map resolved, every joint's qpos layout and limits, the feet's geoms, and the
//! left/right mirror table.

use crate::error::{ClipError, Result};
use mujoco_rs::prelude::*;
use repertoire_scenes::{BodyDef, BodyIndex};
use std::path::{Path, PathBuf};

/// How a joint is stored in qpos.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum JointKind {
    /// Free joint: position (3) and quaternion w x y z (4).
    Free,
    /// Ball joint: quaternion (4).
    Ball,
    /// Hinge: one angle, radians.
    Hinge,
    /// Slide: one displacement, metres.
    Slide,
}

/// One joint of the body.
#[derive(Debug, Clone, PartialEq)]
pub struct JointInfo {
    /// MJCF name.
    pub name: String,
    /// Kind.
    pub kind: JointKind,
    /// qpos address.
    pub qpos: usize,
    /// qvel address.
    pub dof: usize,
    /// Range when limited (radians or metres).
    pub range: Option<[f64; 2]>,
    /// Axis in the body frame.
    pub axis: [f64; 3],
}

/// The body clips are made for.
pub struct ClipBody {
    /// The body's MJCF and map.
    pub def: BodyDef,
    /// The body compiled alone.
    pub model: MjModel,
    /// The map resolved in `model`.
    pub index: BodyIndex,
    /// Every joint, in model order.
    pub joints: Vec<JointInfo>,
    /// Geoms of each foot's subtree (left, right).
    pub foot_geoms: [Vec<usize>; 2],
    /// qpos addresses of quaternion blocks (free and ball joints), in qpos order.
    pub quat_qpos: Vec<usize>,
    mirror: std::result::Result<Vec<(usize, usize, f64)>, String>,
}

impl std::fmt::Debug for ClipBody {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("ClipBody").field("mjcf", &self.def.mjcf_path).field("nq", &self.nq()).finish_non_exhaustive()
    }
}

impl ClipBody {
    /// The built-in humanoid.
    pub fn humanoid() -> Result<Self> {
        Self::new(BodyDef::humanoid())
    }

    /// A body named on the command line: `humanoid`, a scenario file (its body), an MJCF file
    /// (its map is the same path with `.map.ron` in place of `.xml`) or a body-map file
    /// `NAME.map.ron` (its MJCF is `NAME.xml` beside it).
    pub fn from_arg(arg: &str) -> Result<Self> {
        if arg == "humanoid" {
            return Self::humanoid();
        }
        let path = PathBuf::from(arg);
        let name = path.file_name().map(|n| n.to_string_lossy().into_owned()).unwrap_or_default();
        let (mjcf, map) = if let Some(stem) = name.strip_suffix(".map.ron") {
            (path.with_file_name(format!("{stem}.xml")), path.clone())
        } else if name.ends_with(".ron") {
            // A scenario: its body.
            return Self::new(repertoire_scenes::ScenarioFile::load(&path)?.body_def()?);
        } else if let Some(stem) = name.strip_suffix(".xml") {
            (path.clone(), path.with_file_name(format!("{stem}.map.ron")))
        } else {
            return Err(ClipError::Usage(format!(
                "--body {arg}: expected `humanoid`, a scenario FILE.ron (its body), an MJCF file NAME.xml (with NAME.map.ron beside it) or a body map NAME.map.ron (with NAME.xml beside it)"
            )));
        };
        Self::new(BodyDef::load(&mjcf, &map)?)
    }

    /// Compiles `def` alone and resolves its map.
    pub fn new(def: BodyDef) -> Result<Self> {
        let (mut model, index) = def.check()?;
        // The standing pose on the floor, as the scenes place it (the map's `stand_on_floor`).
        repertoire_scenes::stand_on_floor(&mut model, &index, &def);
        let njnt = model.ffi().njnt as usize;
        let mut joints = Vec::with_capacity(njnt);
        let mut quat_qpos = Vec::new();
        for j in 0..njnt {
            let kind = match model.jnt_type()[j] {
                MjtJoint::mjJNT_FREE => JointKind::Free,
                MjtJoint::mjJNT_BALL => JointKind::Ball,
                MjtJoint::mjJNT_SLIDE => JointKind::Slide,
                _ => JointKind::Hinge,
            };
            let qpos = model.jnt_qposadr()[j] as usize;
            match kind {
                JointKind::Free => quat_qpos.push(qpos + 3),
                JointKind::Ball => quat_qpos.push(qpos),
                _ => {}
            }
            joints.push(JointInfo {
                name: model.id_to_name(MjtObjBase::mjOBJ_JOINT, j).unwrap_or("").to_string(),
                kind,
                qpos,
                dof: model.jnt_dofadr()[j] as usize,
                range: model.jnt_limited()[j].then(|| model.jnt_range()[j]),
                axis: model.jnt_axis()[j],
            });
        }
        let parent: Vec<usize> = model.body_parentid().iter().map(|&p| p as usize).collect();
        let in_subtree = |mut b: usize, root: usize| loop {
            if b == root {
                return true;
            }
            if b == 0 {
                return false;
            }
            b = parent[b];
        };
        let geom_body = model.geom_bodyid();
        let foot_geoms = index
            .feet
            .map(|foot| (0..geom_body.len()).filter(|&g| in_subtree(geom_body[g] as usize, foot)).collect::<Vec<_>>());
        let mirror = mirror_table(&joints, index.root_qpos);
        Ok(ClipBody { def, model, index, joints, foot_geoms, quat_qpos, mirror })
    }

    /// qpos width.
    pub fn nq(&self) -> usize {
        self.model.ffi().nq as usize
    }

    /// qvel width.
    pub fn nv(&self) -> usize {
        self.model.ffi().nv as usize
    }

    /// The body's content hash (MJCF + map), as recorded in clips.
    pub fn hash(&self) -> String {
        self.def.content_hash()
    }

    /// The standing pose (the model's qpos0, moved onto the floor where the map asks).
    pub fn standing_qpos(&self) -> &[f64] {
        self.model.qpos0()
    }

    /// The joint called `name`.
    pub fn joint(&self, name: &str) -> Option<&JointInfo> {
        self.joints.iter().find(|j| j.name == name)
    }

    /// Where the body came from, for messages.
    pub fn origin(&self) -> &Path {
        &self.def.mjcf_path
    }

    /// The left/right mirror table: `(qpos a, qpos b, sign)` meaning mirrored `qpos[a]` is
    /// `sign · qpos[b]`. Errors when the body has no consistent left/right joint pairs.
    pub fn mirror_table(&self) -> Result<&[(usize, usize, f64)]> {
        self.mirror.as_deref().map_err(|e| ClipError::Usage(format!("{}: cannot mirror: {e}", self.origin().display())))
    }
}

/// The counterpart of a joint name: every `left` becomes `right` and vice versa.
pub fn counterpart(name: &str) -> String {
    let mut out = String::with_capacity(name.len() + 1);
    let mut rest = name;
    while !rest.is_empty() {
        if let Some(r) = rest.strip_prefix("left") {
            out.push_str("right");
            rest = r;
        } else if let Some(r) = rest.strip_prefix("right") {
            out.push_str("left");
            rest = r;
        } else if let Some(r) = rest.strip_prefix("Left") {
            out.push_str("Right");
            rest = r;
        } else if let Some(r) = rest.strip_prefix("Right") {
            out.push_str("Left");
            rest = r;
        } else {
            let c = rest.chars().next().unwrap_or(' ');
            out.push(c);
            rest = &rest[c.len_utf8()..];
        }
    }
    out
}

/// Mirror across the x–z plane (y → −y). A hinge about `a` on one side rotated by θ becomes a
/// rotation by −θ about `M a` (M = diag(1, −1, 1)); on the counterpart with axis `b` that is the
/// angle `−(b · M a) θ`. So x and z axes flip sign, y axes keep it.
fn mirror_table(joints: &[JointInfo], root: usize) -> std::result::Result<Vec<(usize, usize, f64)>, String> {
    let mut table = Vec::new();
    for j in joints {
        match j.kind {
            JointKind::Free if j.qpos == root => continue,
            JointKind::Free | JointKind::Ball => {
                return Err(format!(
                    "joint `{}` is a ball or second free joint; only hinges and slides mirror",
                    j.name
                ));
            }
            JointKind::Hinge | JointKind::Slide => {}
        }
        let other_name = counterpart(&j.name);
        let other = joints
            .iter()
            .find(|o| o.name == other_name)
            .ok_or_else(|| format!("joint `{}` has no counterpart `{other_name}`", j.name))?;
        let ma = [j.axis[0], -j.axis[1], j.axis[2]];
        let dot = other.axis[0] * ma[0] + other.axis[1] * ma[1] + other.axis[2] * ma[2];
        if (dot.abs() - 1.0).abs() > 1e-6 {
            return Err(format!("joints `{}` and `{}` have axes that are not mirror images", j.name, other.name));
        }
        // A slide's displacement mirrors like a vector, not like an angle.
        let sign = if j.kind == JointKind::Slide { dot.signum() } else { -dot.signum() };
        table.push((j.qpos, other.qpos, sign));
    }
    Ok(table)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn counterparts_swap_sides() {
        assert_eq!(counterpart("left_shoulder_x"), "right_shoulder_x");
        assert_eq!(counterpart("right_knee"), "left_knee");
        assert_eq!(counterpart("abdomen_z"), "abdomen_z");
        assert_eq!(counterpart("LeftArm"), "RightArm");
    }

    #[test]
    fn humanoid_mirror_flips_x_and_z_axes() {
        let body = ClipBody::humanoid().unwrap();
        let table = body.mirror_table().unwrap();
        let find = |name: &str| {
            let q = body.joint(name).unwrap().qpos;
            table.iter().find(|t| t.0 == q).copied().unwrap()
        };
        let (_, b, s) = find("left_shoulder_x");
        assert_eq!(b, body.joint("right_shoulder_x").unwrap().qpos);
        assert_eq!(s, -1.0);
        assert_eq!(find("left_elbow").2, 1.0);
        assert_eq!(find("abdomen_z").2, -1.0);
        assert_eq!(find("abdomen_y").2, 1.0);
        assert_eq!(body.nq(), 32);
        assert_eq!(body.quat_qpos, [3]);
        assert!(!body.foot_geoms[0].is_empty());
    }
}
