//! Bodies: an MJCF document plus a RON body map that names the parts every skill needs.
//!
//! The built-in humanoid and a user's own MJCF go through the same code: the map names the
//! pelvis, feet, hands, head and the actuated joints in policy order, and [`BodyIndex`] resolves
//! those names against the compiled model once, so the world never looks names up again.

use crate::error::{Location, Result, SceneError};
use mujoco_rs::prelude::*;
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};

/// Names, in the body's MJCF, of the parts Repertoire needs.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct BodyMap {
    /// The free joint at the root of the body, on the pelvis. Left out: the pelvis's own free
    /// joint, or, when the pelvis has no joint at all (a body written to be attached, as
    /// dm_control's), one Repertoire adds ([`ADDED_ROOT_JOINT`]).
    #[serde(default)]
    pub root_joint: Option<String>,
    /// The pelvis body (the free joint's body).
    pub pelvis: String,
    /// The upper-body body (chest or torso).
    pub torso: String,
    /// The head body.
    pub head: String,
    /// Left foot body.
    pub left_foot: String,
    /// Right foot body.
    pub right_foot: String,
    /// Left hand body.
    pub left_hand: String,
    /// Right hand body.
    pub right_hand: String,
    /// A site at the eyes, for a head camera.
    #[serde(default)]
    pub head_camera: Option<String>,
    /// Bodies (with their descendants) whose touching the floor is not a fall.
    pub floor_contact_allowed: Vec<String>,
    /// Touch sensors under the feet, in observation order.
    #[serde(default)]
    pub foot_touch_sensors: Vec<String>,
    /// Touch sensors on the hands, in observation order.
    #[serde(default)]
    pub hand_touch_sensors: Vec<String>,
    /// Actuated joints in policy order; each is driven by exactly one actuator: a position
    /// servo, or a torque motor, which is driven as a PD servo ([`MotorPd`]).
    pub actuated_joints: Vec<String>,
    /// Gains of the torque motors among the actuated joints' actuators.
    #[serde(default)]
    pub motor_pd: MotorPd,
    /// Move the default pose (every joint at 0) up or down until the feet's lowest point is on
    /// the floor, instead of refusing a body that floats or sinks (a third-party file whose
    /// root stands at another height, used without an edit). `scene check` says by how much.
    #[serde(default)]
    pub stand_on_floor: bool,
    /// The rotation (quaternion w, x, y, z) that stands the body up facing +x, for a file whose
    /// root frame is not Repertoire's (x forward, y left, z up). dm_control's CMU humanoid is
    /// written y up, facing +z: `upright: Some((0.5, 0.5, 0.5, 0.5))`. Needs a pelvis without
    /// joints: Repertoire puts it, turned by this rotation, inside a body of its own
    /// ([`UPRIGHT_FRAME`]) that carries the added free joint, so headings, the fall test and
    /// the clips' root follow Repertoire's axes while the file stays as it is.
    #[serde(default)]
    pub upright: Option<(f64, f64, f64, f64)>,
}

/// How torque motors (`<motor>`, as gymnasium's and dm_control's humanoids have) are driven.
/// Policies write joint-angle targets; a motor would take them as torques. Each motor of an
/// actuated joint is therefore driven as a PD servo, computed by MuJoCo every physics step:
/// torque = kp·(target − q) − kv·q̇, limited to the motor's own peak torque (its control range
/// times its gain and gear). The body's file is not changed; `scene check` lists the gains.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MotorPd {
    /// Stiffness (N·m/rad) of every motor. Default: twice the motor's peak torque, so it
    /// saturates half a radian from its target (the built-in humanoid's servos are so tuned).
    #[serde(default)]
    pub kp: Option<f64>,
    /// Damping (N·m·s/rad). Default: a tenth of kp.
    #[serde(default)]
    pub kv: Option<f64>,
    /// Per joint: (kp, kv), over the two above.
    #[serde(default)]
    pub joints: std::collections::BTreeMap<String, (f64, f64)>,
    /// Per joint: the peak torque (N·m) in place of the motor's own, as dm_control's
    /// position-controlled CMU humanoid gives its joints more force than the file's motors.
    #[serde(default)]
    pub peaks: std::collections::BTreeMap<String, f64>,
}

/// The free joint Repertoire adds to a pelvis without one.
pub const ADDED_ROOT_JOINT: &str = "repertoire/root";
/// The body Repertoire wraps a pelvis in when the map gives an [`BodyMap::upright`] rotation:
/// Repertoire's axes, the added free joint on it, the pelvis inside it turned upright.
pub const UPRIGHT_FRAME: &str = "repertoire/pelvis";

/// A torque motor of an actuated joint, driven as a PD servo ([`MotorPd`]).
#[derive(Debug, Clone, PartialEq)]
pub struct PdMotor {
    /// The actuator's name.
    pub actuator: String,
    /// Its joint.
    pub joint: String,
    /// Stiffness (N·m/rad).
    pub kp: f64,
    /// Damping (N·m·s/rad).
    pub kv: f64,
    /// Peak torque (N·m), `None` when the motor has no limit.
    pub max_torque: Option<f64>,
}

/// A body ready to be placed in a scene: its MJCF text and its map, with where each came from.
#[derive(Debug, Clone)]
pub struct BodyDef {
    /// The MJCF document of the body alone.
    pub mjcf: String,
    /// Where the MJCF came from (for messages).
    pub mjcf_path: PathBuf,
    /// The body map.
    pub map: BodyMap,
    /// Where the map came from (for messages).
    pub map_path: PathBuf,
    /// The map's text (to locate names in messages).
    pub map_text: String,
}

/// Prefix of the actuators Repertoire adds to a scene (they drive no body joint; the scene's
/// composition adds them, [`crate::compose`]).
pub const ADDED_ACTUATOR_PREFIX: &str = "repertoire/";
/// Names of the left and right hands' grip actuators.
pub const GRIP_ACTUATORS: [&str; 2] = ["repertoire/grip/left", "repertoire/grip/right"];

const HUMANOID_XML: &str = include_str!("../assets/humanoid.xml");
const HUMANOID_MAP: &str = include_str!("../assets/humanoid.map.ron");

impl BodyDef {
    /// Repertoire's built-in humanoid (25 actuated DoF, 1.70 m, about 70 kg).
    pub fn humanoid() -> Self {
        let map_path = PathBuf::from("<built-in>/scenes/assets/humanoid.map.ron");
        let map = parse_map(&map_path, HUMANOID_MAP).expect("the built-in body map is tested");
        Self {
            mjcf: HUMANOID_XML.to_string(),
            mjcf_path: PathBuf::from("<built-in>/scenes/assets/humanoid.xml"),
            map,
            map_path,
            map_text: HUMANOID_MAP.to_string(),
        }
    }

    /// Reads a user's MJCF body and its RON map.
    pub fn load(mjcf_path: &Path, map_path: &Path) -> Result<Self> {
        let read = |p: &Path| std::fs::read_to_string(p).map_err(|source| SceneError::unreadable(p, source));
        let mjcf = read(mjcf_path)?;
        let map_text = read(map_path)?;
        let map = parse_map(map_path, &map_text)?;
        let mut def =
            Self { mjcf, mjcf_path: mjcf_path.to_path_buf(), map, map_path: map_path.to_path_buf(), map_text };
        def.add_root_joint()?;
        Ok(def)
    }

    /// Gives a pelvis without any joint a free joint ([`ADDED_ROOT_JOINT`]) when the map names
    /// no root joint: a body written to be attached to something (dm_control's) becomes one
    /// that stands on the floor. The joint goes on the pelvis tag's own line, so MuJoCo's line
    /// numbers still point into the user's file. With an `upright` rotation the pelvis is
    /// wrapped instead: `<body name="repertoire/pelvis"><freejoint/><body quat="…">` before its
    /// tag and the two closing tags after its own, on the same lines.
    fn add_root_joint(&mut self) -> Result<()> {
        let upright = self.map.upright;
        if self.map.root_joint.is_some() {
            return match upright {
                Some(_) => Err(self.map_error(
                    "upright",
                    "`upright` turns a pelvis that Repertoire gives a free joint; this map names a root_joint: \
                     leave root_joint out (the pelvis must have no joint in the file) or turn the body in its file"
                        .to_string(),
                )),
                None => Ok(()),
            };
        }
        let model = compile(&self.mjcf, &self.mjcf_path)?;
        let Some(pelvis) = model.name_to_id(MjtObjBase::mjOBJ_BODY, &self.map.pelvis) else {
            return Ok(()); // BodyIndex::resolve names the missing pelvis
        };
        if model.body_jntnum()[pelvis] > 0 {
            return match upright {
                Some(_) => Err(self.map_error(
                    "upright",
                    format!(
                        "`upright` needs a pelvis without joints (Repertoire then adds the free joint); `{}` has {} in {}",
                        self.map.pelvis,
                        model.body_jntnum()[pelvis],
                        self.mjcf_path.display()
                    ),
                )),
                None => Ok(()),
            };
        }
        let open = format!("<body name=\"{}\"", self.map.pelvis);
        let start = self.mjcf.find(&open);
        let at = start.and_then(|i| self.mjcf[i..].find('>').map(|j| i + j));
        let no_tag = || {
            self.map_error(
                &self.map.pelvis,
                format!(
                    "the pelvis `{}` has no joint and no `<body name=\"{}\">` tag to add a free joint to in {}; \
                     give it `<freejoint/>` or name its root_joint",
                    self.map.pelvis,
                    self.map.pelvis,
                    self.mjcf_path.display()
                ),
            )
        };
        let (Some(start), Some(end)) = (start, at) else { return Err(no_tag()) };
        if self.mjcf[..end].ends_with('/') {
            return Err(no_tag());
        }
        let Some((w, x, y, z)) = upright else {
            self.mjcf.insert_str(end + 1, &format!("<freejoint name=\"{ADDED_ROOT_JOINT}\"/>"));
            return Ok(());
        };
        let norm = (w * w + x * x + y * y + z * z).sqrt();
        if !(norm.is_finite() && norm > 1e-9) {
            return Err(self.map_error("upright", format!("`upright` ({w}, {x}, {y}, {z}) is not a rotation")));
        }
        let Some(close) = closing_body_tag(&self.mjcf, end + 1) else {
            return Err(self.map_error(
                &self.map.pelvis,
                format!("the pelvis `{}` has no closing `</body>` in {}", self.map.pelvis, self.mjcf_path.display()),
            ));
        };
        self.mjcf.insert_str(close, "</body></body>");
        let q = [w / norm, x / norm, y / norm, z / norm];
        self.mjcf.insert_str(
            start,
            &format!(
                "<body name=\"{UPRIGHT_FRAME}\"><freejoint name=\"{ADDED_ROOT_JOINT}\"/><body name=\"{UPRIGHT_FRAME}/turn\" \
                 quat=\"{} {} {} {}\">",
                q[0], q[1], q[2], q[3]
            ),
        );
        Ok(())
    }

    /// Compiles the body alone, so MuJoCo's messages (with line numbers) refer to the user's
    /// own file, and checks the map against it.
    pub fn check(&self) -> Result<(MjModel, BodyIndex)> {
        let mut model = compile(&self.mjcf, &self.mjcf_path)?;
        drive_motors_as_pd(&mut model, self)?;
        let index = BodyIndex::resolve(&model, self)?;
        Ok((model, index))
    }

    /// The name of the body's root joint: the map's, or the first free joint on the pelvis or
    /// a body it hangs from (a body whose free root is its chest), or the one added to it.
    fn root_joint<'a>(&'a self, model: &'a MjModel, pelvis: usize) -> Result<&'a str> {
        if let Some(name) = &self.map.root_joint {
            return Ok(name);
        }
        let parent = model.body_parentid();
        let mut b = pelvis;
        while b != 0 {
            let first = model.body_jntadr()[b];
            let count = model.body_jntnum()[b];
            let free = (first..first + count)
                .map(|j| j as usize)
                .find(|&j| model.jnt_type()[j] == MjtJoint::mjJNT_FREE)
                .and_then(|j| model.id_to_name(MjtObjBase::mjOBJ_JOINT, j));
            if let Some(name) = free {
                return Ok(name);
            }
            b = parent[b] as usize;
        }
        Err(self.map_error(
            &self.map.pelvis,
            format!(
                "neither the pelvis `{}` nor a body it hangs from has a free joint, and the map names no root_joint \
                 (a body with joints but no free joint cannot stand on the floor: give its root body `<freejoint/>`)",
                self.map.pelvis
            ),
        ))
    }

    /// A stable 64-bit content hash of the MJCF and the map (FNV-1a), recorded by skills so a
    /// skill refuses a different body.
    pub fn content_hash(&self) -> String {
        format!("{:016x}", fnv1a(&[self.mjcf.as_bytes(), b"\0", self.map_text.as_bytes()]))
    }

    pub(crate) fn map_error(&self, name: &str, message: String) -> SceneError {
        SceneError::BodyMap { file: self.map_path.clone(), loc: Location::find_quoted(&self.map_text, name), message }
    }
}

/// The byte just past the `</body>` that closes the body whose opening tag ends before `from`,
/// skipping comments and self-closing `<body …/>` tags.
fn closing_body_tag(xml: &str, from: usize) -> Option<usize> {
    let mut depth = 1usize;
    let mut i = from;
    while i < xml.len() {
        let rest = &xml[i..];
        let next = rest.find('<')?;
        i += next;
        let rest = &xml[i..];
        if rest.starts_with("<!--") {
            i += rest.find("-->")? + 3;
        } else if rest.starts_with("</body") {
            let end = i + rest.find('>')? + 1;
            depth -= 1;
            if depth == 0 {
                return Some(end);
            }
            i = end;
        } else if rest.starts_with("<body")
            && rest[5..].starts_with(|c: char| c.is_whitespace() || c == '>' || c == '/')
        {
            let end = i + rest.find('>')?;
            if !xml[..end].ends_with('/') {
                depth += 1;
            }
            i = end + 1;
        } else {
            i += 1;
        }
    }
    None
}

fn parse_map(path: &Path, text: &str) -> Result<BodyMap> {
    Ok(repertoire_files::parse_ron(path, text)?)
}

/// Compiles an MJCF document, passing MuJoCo's own message on when it refuses.
pub fn compile(mjcf: &str, file: &Path) -> Result<MjModel> {
    MjModel::from_xml_string(mjcf).map_err(|e| SceneError::Mjcf {
        file: file.to_path_buf(),
        message: e.to_string().trim().trim_start_matches("model load failed: ").to_string(),
    })
}

/// Drives every torque motor of `def`'s actuated joints as a PD servo in `model` ([`MotorPd`]):
/// gain kp/g, bias −kp/g²·length − kv/g²·velocity (g the motor's gear), so the joint sees
/// kp·(ctrl − q) − kv·q̇ with ctrl a joint angle; the control range becomes the joint's range and
/// the force range the motor's own. Position servos and anything else are left to
/// [`BodyIndex::resolve`]. Returns the motors it converted.
pub fn drive_motors_as_pd(model: &mut MjModel, def: &BodyDef) -> Result<Vec<PdMotor>> {
    let pd = &def.map.motor_pd;
    if let Some(name) = pd.joints.keys().chain(pd.peaks.keys()).find(|n| !def.map.actuated_joints.contains(n)) {
        return Err(def.map_error(name, format!("motor_pd names `{name}`, which is not among the actuated_joints")));
    }
    let mut driven = Vec::new();
    for name in &def.map.actuated_joints {
        let Some(j) = model.name_to_id(MjtObjBase::mjOBJ_JOINT, name) else { continue };
        let drivers: Vec<usize> = (0..model.actuator_trntype().len())
            .filter(|&a| {
                model.actuator_trntype()[a] == MjtTrn::mjTRN_JOINT && model.actuator_trnid()[a][0] as usize == j
            })
            .collect();
        let [a] = drivers[..] else { continue };
        let motor = model.actuator_gaintype()[a] == MjtGain::mjGAIN_FIXED
            && model.actuator_biastype()[a] == MjtBias::mjBIAS_NONE
            && model.actuator_dyntype()[a] == MjtDyn::mjDYN_NONE
            && model.actuator_gainprm()[a][0] != 0.0;
        if !motor {
            continue;
        }
        let actuator = model.id_to_name(MjtObjBase::mjOBJ_ACTUATOR, a).unwrap_or("(unnamed)").to_string();
        let g = model.actuator_gear()[a][0];
        let gain = model.actuator_gainprm()[a][0];
        // The force range in actuator units: the control range times the gain, else the
        // motor's force range, else none.
        let force = if model.actuator_ctrllimited()[a] {
            let [lo, hi] = model.actuator_ctrlrange()[a];
            Some([(lo * gain).min(hi * gain), (lo * gain).max(hi * gain)])
        } else if model.actuator_forcelimited()[a] {
            Some(model.actuator_forcerange()[a])
        } else {
            None
        };
        let force = match pd.peaks.get(name) {
            Some(&peak) if peak.is_finite() && peak > 0.0 && g != 0.0 => Some([-peak / g.abs(), peak / g.abs()]),
            Some(&peak) => {
                return Err(def.map_error(
                    name,
                    format!("the peak torque of `{name}` is {peak}; it must be a positive number of N·m"),
                ));
            }
            None => force,
        };
        let max_torque = force.map(|[lo, hi]| lo.abs().max(hi.abs()) * g.abs());
        let (kp, kv) = match (pd.joints.get(name), pd.kp, max_torque) {
            (Some(&(kp, kv)), _, _) => (kp, kv),
            (None, Some(kp), _) => (kp, pd.kv.unwrap_or(kp / 10.0)),
            (None, None, Some(t)) => (2.0 * t, pd.kv.unwrap_or(0.2 * t)),
            (None, None, None) => {
                return Err(def.map_error(
                    name,
                    format!(
                        "the motor `{actuator}` of `{name}` has neither a control nor a force range, so its PD gains \
                         cannot be taken from its peak torque: give them in the map, \
                         `motor_pd: (kp: Some(…), kv: Some(…))` or per joint `joints: {{\"{name}\": (kp, kv)}}`"
                    ),
                ));
            }
        };
        if !(kp > 0.0 && kv >= 0.0 && g != 0.0 && kp.is_finite() && kv.is_finite()) {
            return Err(def.map_error(
                name,
                format!(
                    "the motor `{actuator}` of `{name}`: kp {kp} must be positive, kv {kv} at least 0, gear {g} not 0"
                ),
            ));
        }
        // SAFETY: the gain and bias types written are valid MuJoCo enum values.
        unsafe {
            model.actuator_gainprm_mut()[a] = [0.0; 10];
            model.actuator_gainprm_mut()[a][0] = kp / g;
            model.actuator_biastype_mut()[a] = MjtBias::mjBIAS_AFFINE;
        }
        model.actuator_biasprm_mut()[a] = [0.0; 10];
        model.actuator_biasprm_mut()[a][1] = -kp / (g * g);
        model.actuator_biasprm_mut()[a][2] = -kv / (g * g);
        if model.jnt_limited()[j] {
            model.actuator_ctrlrange_mut()[a] = model.jnt_range()[j];
            model.actuator_ctrllimited_mut()[a] = true;
        } else {
            model.actuator_ctrllimited_mut()[a] = false;
        }
        if let Some(range) = force {
            model.actuator_forcerange_mut()[a] = range;
            model.actuator_forcelimited_mut()[a] = true;
        }
        driven.push(PdMotor { actuator, joint: name.clone(), kp, kv, max_torque });
    }
    Ok(driven)
}

/// FNV-1a over several byte slices.
pub(crate) fn fnv1a(parts: &[&[u8]]) -> u64 {
    let mut h: u64 = 0xcbf2_9ce4_8422_2325;
    for part in parts {
        for &b in *part {
            h ^= u64::from(b);
            h = h.wrapping_mul(0x0100_0000_01b3);
        }
    }
    h
}

/// One actuated joint, resolved: where it lives in qpos/qvel, its limits and its actuator.
#[derive(Debug, Clone, PartialEq)]
pub struct ActuatedJoint {
    /// The joint's name.
    pub name: String,
    /// Index into qpos.
    pub qpos: usize,
    /// Index into qvel.
    pub dof: usize,
    /// Joint range in radians (or metres for a slide joint).
    pub range: [f64; 2],
    /// The actuator (index into ctrl) that drives it.
    pub actuator: usize,
    /// The actuator's control range.
    pub ctrl_range: [f64; 2],
}

/// The body map resolved to MuJoCo ids in one compiled model.
#[derive(Debug, Clone)]
pub struct BodyIndex {
    /// qpos address of the root free joint (3 position + 4 quaternion values).
    pub root_qpos: usize,
    /// qvel address of the root free joint (3 linear + 3 angular values).
    pub root_dof: usize,
    /// The free joint's body: the pelvis, the upright frame around it, or a part the pelvis
    /// hangs from (a chest). Everything below it is the character.
    pub root_body: usize,
    /// The pelvis's frame (heading, pitch, roll, height): the map's pelvis, or the
    /// [`UPRIGHT_FRAME`] around it when the map turns the body upright.
    pub pelvis: usize,
    /// The map's pelvis body itself, whose geoms sit on seats and must not touch the floor
    /// (the same as `pelvis` unless the map has `upright`).
    pub pelvis_part: usize,
    /// Torso body id.
    pub torso: usize,
    /// Head body id.
    pub head: usize,
    /// Left and right foot body ids.
    pub feet: [usize; 2],
    /// Left and right hand body ids.
    pub hands: [usize; 2],
    /// Head camera site id.
    pub head_camera: Option<usize>,
    /// Actuated joints in policy order.
    pub joints: Vec<ActuatedJoint>,
    /// Per model body: true when it belongs to the character.
    pub is_character: Vec<bool>,
    /// Per model body: true when it may touch the floor without it being a fall.
    pub floor_ok: Vec<bool>,
    /// Per model body: 0 for the left hand subtree, 1 for the right, none otherwise.
    pub hand_of: Vec<Option<usize>>,
    /// Per model body: 0 for the left foot subtree (toes included), 1 for the right, none
    /// otherwise.
    pub foot_of: Vec<Option<usize>>,
    /// sensordata addresses of the foot touch sensors.
    pub foot_touch: Vec<usize>,
    /// sensordata addresses of the hand touch sensors.
    pub hand_touch: Vec<usize>,
    /// The hands' grip actuators (left, right) where the scene added them
    /// ([`crate::compose::GRIP_ACTUATORS`]); empty for the body alone and scenes without a
    /// free object.
    pub grip: Vec<usize>,
}

impl BodyIndex {
    /// Resolves `def`'s map in `model` (the body alone or a whole scene built around it).
    pub fn resolve(model: &MjModel, def: &BodyDef) -> Result<Self> {
        let map = &def.map;
        let body = |role: &str, name: &str| {
            model.name_to_id(MjtObjBase::mjOBJ_BODY, name).ok_or_else(|| {
                def.map_error(name, format!("{role} `{name}` is not a body in {}", def.mjcf_path.display()))
            })
        };
        let pelvis_part = body("pelvis", &map.pelvis)?;
        // With `upright`, the frame of the pelvis is Repertoire's wrapper around it.
        let pelvis = match map.upright {
            Some(_) => model.name_to_id(MjtObjBase::mjOBJ_BODY, UPRIGHT_FRAME).unwrap_or(pelvis_part),
            None => pelvis_part,
        };
        let torso = body("torso", &map.torso)?;
        let head = body("head", &map.head)?;
        let feet = [body("left_foot", &map.left_foot)?, body("right_foot", &map.right_foot)?];
        let hands = [body("left_hand", &map.left_hand)?, body("right_hand", &map.right_hand)?];

        let root_joint = def.root_joint(model, pelvis)?;
        let root = model.name_to_id(MjtObjBase::mjOBJ_JOINT, root_joint).ok_or_else(|| {
            def.map_error(
                root_joint,
                format!("root_joint `{root_joint}` is not a joint in {}", def.mjcf_path.display()),
            )
        })?;
        if model.jnt_type()[root] != MjtJoint::mjJNT_FREE {
            return Err(def.map_error(root_joint, format!("root_joint `{root_joint}` is not a free joint")));
        }
        let nbody = model.ffi().nbody as usize;
        let parent: Vec<usize> = model.body_parentid().iter().map(|&p| p as usize).collect();
        let in_subtree = |b: usize, root: usize| in_subtree(&parent, b, root);
        // The free root may be another part than the pelvis (a chest), as long as the pelvis
        // hangs from it: the character is everything below the root.
        let root_body = model.jnt_bodyid()[root] as usize;
        if !in_subtree(pelvis, root_body) {
            let on = model.id_to_name(MjtObjBase::mjOBJ_BODY, root_body).unwrap_or("?");
            return Err(def.map_error(
                root_joint,
                format!(
                    "root_joint `{root_joint}` is on body `{on}`, and the pelvis `{}` does not hang from it: the free \
                     joint must be on the pelvis or on a body the pelvis hangs from",
                    map.pelvis
                ),
            ));
        }
        let is_character: Vec<bool> = (0..nbody).map(|b| in_subtree(b, root_body)).collect();
        let mut allowed = Vec::new();
        for name in &map.floor_contact_allowed {
            allowed.push(body("floor_contact_allowed", name)?);
        }
        let floor_ok = (0..nbody).map(|b| allowed.iter().any(|&a| in_subtree(b, a))).collect();
        let hand_of = (0..nbody).map(|b| (0..2).find(|&side| in_subtree(b, hands[side]))).collect();
        let foot_of = (0..nbody).map(|b| (0..2).find(|&side| in_subtree(b, feet[side]))).collect();

        let trn_type = model.actuator_trntype();
        let trn_id = model.actuator_trnid();
        let ctrl_range = model.actuator_ctrlrange();
        let ctrl_limited = model.actuator_ctrllimited();
        let gain_type = model.actuator_gaintype();
        let bias_type = model.actuator_biastype();
        let gain = model.actuator_gainprm();
        let bias = model.actuator_biasprm();
        let mut not_servos = Vec::new();
        let mut joints = Vec::with_capacity(map.actuated_joints.len());
        for name in &map.actuated_joints {
            let j = model.name_to_id(MjtObjBase::mjOBJ_JOINT, name).ok_or_else(|| {
                def.map_error(name, format!("actuated joint `{name}` is not a joint in {}", def.mjcf_path.display()))
            })?;
            if !matches!(model.jnt_type()[j], MjtJoint::mjJNT_HINGE | MjtJoint::mjJNT_SLIDE) {
                return Err(def.map_error(name, format!("actuated joint `{name}` must be a hinge or slide joint")));
            }
            if joints.iter().any(|a: &ActuatedJoint| a.name == *name) {
                return Err(def.map_error(name, format!("actuated joint `{name}` is listed twice")));
            }
            let drivers: Vec<usize> = (0..trn_type.len())
                .filter(|&a| trn_type[a] == MjtTrn::mjTRN_JOINT && trn_id[a][0] as usize == j)
                .collect();
            let [actuator] = drivers[..] else {
                return Err(def.map_error(
                    name,
                    format!("actuated joint `{name}` is driven by {} actuators; it needs exactly one", drivers.len()),
                ));
            };
            // Policies write joint-angle targets into the controls: a position servo
            // (force = kp·(ctrl − q) − kv·q̇: fixed gain kp, affine bias 0, −kp, −kv) turns them into
            // torques; a motor would take an angle as a torque and the body would collapse.
            // With a gear g the actuator's length is g·q, and the joint sees g times its force:
            // the target is a joint angle when the bias's position term is −kp/g.
            let kp = gain[actuator][0];
            let g = model.actuator_gear()[actuator][0];
            let servo = gain_type[actuator] == MjtGain::mjGAIN_FIXED
                && bias_type[actuator] == MjtBias::mjBIAS_AFFINE
                && kp > 0.0
                && g != 0.0
                && bias[actuator][0] == 0.0
                && (bias[actuator][1] + kp / g).abs() <= 1e-9 * kp.max(1.0);
            if !servo {
                let a = model.id_to_name(MjtObjBase::mjOBJ_ACTUATOR, actuator).unwrap_or("(unnamed)").to_string();
                not_servos.push(format!("`{a}` ({name})"));
            }
            let range = if model.jnt_limited()[j] { model.jnt_range()[j] } else { [-f64::INFINITY, f64::INFINITY] };
            let ctrl = if ctrl_limited[actuator] { ctrl_range[actuator] } else { range };
            joints.push(ActuatedJoint {
                name: name.clone(),
                qpos: model.jnt_qposadr()[j] as usize,
                dof: model.jnt_dofadr()[j] as usize,
                range,
                actuator,
                ctrl_range: ctrl,
            });
        }
        if !not_servos.is_empty() {
            let n = not_servos.len();
            return Err(SceneError::Mjcf {
                file: def.mjcf_path.clone(),
                message: format!(
                    "{n} actuator{} of the actuated joints {} neither position servos nor torque motors: {}{}. \
                     Policies drive the joints by angle targets. Write each as \
                     `<position joint=\"J\" kp=\"…\" kv=\"…\" ctrlrange=\"lo hi\" forcerange=\"…\"/>` \
                     (crates/scenes/assets/humanoid.xml shows gains for a 70 kg body)",
                    if n == 1 { "" } else { "s" },
                    if n == 1 { "is" } else { "are" },
                    not_servos.iter().take(6).cloned().collect::<Vec<_>>().join(", "),
                    if n > 6 { format!(" and {} more", n - 6) } else { String::new() }
                ),
            });
        }
        for (a, &trn) in trn_type.iter().enumerate() {
            let name = model.id_to_name(MjtObjBase::mjOBJ_ACTUATOR, a).unwrap_or("(unnamed)");
            if name.starts_with(ADDED_ACTUATOR_PREFIX) && trn != MjtTrn::mjTRN_JOINT {
                continue; // added by the scene (the grip), not the body's
            }
            if !joints.iter().any(|j| j.actuator == a) {
                return Err(def.map_error(
                    &map.actuated_joints.first().cloned().unwrap_or_default(),
                    format!("actuator `{name}` drives no joint listed in actuated_joints; list its joint or remove it"),
                ));
            }
        }

        let sensor = |name: &str| {
            let s = model.name_to_id(MjtObjBase::mjOBJ_SENSOR, name).ok_or_else(|| {
                def.map_error(name, format!("touch sensor `{name}` is not a sensor in {}", def.mjcf_path.display()))
            })?;
            Ok::<_, SceneError>(model.sensor_adr()[s] as usize)
        };
        let foot_touch = map.foot_touch_sensors.iter().map(|s| sensor(s)).collect::<Result<_>>()?;
        let hand_touch = map.hand_touch_sensors.iter().map(|s| sensor(s)).collect::<Result<_>>()?;
        let head_camera = match &map.head_camera {
            Some(name) => Some(model.name_to_id(MjtObjBase::mjOBJ_SITE, name).ok_or_else(|| {
                def.map_error(name, format!("head_camera `{name}` is not a site in {}", def.mjcf_path.display()))
            })?),
            None => None,
        };

        Ok(Self {
            root_qpos: model.jnt_qposadr()[root] as usize,
            root_dof: model.jnt_dofadr()[root] as usize,
            root_body,
            pelvis,
            pelvis_part,
            torso,
            head,
            feet,
            hands,
            head_camera,
            joints,
            is_character,
            floor_ok,
            hand_of,
            foot_of,
            foot_touch,
            hand_touch,
            grip: GRIP_ACTUATORS.iter().filter_map(|n| model.name_to_id(MjtObjBase::mjOBJ_ACTUATOR, n)).collect(),
        })
    }

    /// Number of actuated joints (the action size of a skill policy).
    pub fn dof(&self) -> usize {
        self.joints.len()
    }
}

/// Whether body `b` is `root` or hangs below it, by the model's `parent` ids (the world is 0).
pub(crate) fn in_subtree(parent: &[usize], b: usize, root: usize) -> bool {
    let mut b = b;
    loop {
        if b == root {
            return true;
        }
        if b == 0 {
            return false;
        }
        b = parent[b];
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn builtin_humanoid_resolves() {
        let def = BodyDef::humanoid();
        let (model, index) = def.check().expect("built-in humanoid compiles");
        assert_eq!(index.dof(), 25);
        let mass: f64 = model.body_mass().iter().sum();
        assert!((60.0..=75.0).contains(&mass), "mass {mass}");
        assert!(index.is_character[index.pelvis] && !index.is_character[0]);
        assert!(index.floor_ok[index.feet[0]] && !index.floor_ok[index.pelvis]);
        assert_eq!(index.hand_of[index.hands[1]], Some(1));
        assert_eq!(index.foot_of[index.feet[0]], Some(0));
        assert_eq!(index.foot_of[index.pelvis], None);
        assert_eq!(index.foot_touch.len(), 2);
    }

    #[test]
    fn hash_is_stable_and_content_sensitive() {
        let a = BodyDef::humanoid();
        let mut b = a.clone();
        assert_eq!(a.content_hash(), b.content_hash());
        b.mjcf.push(' ');
        assert_ne!(a.content_hash(), b.content_hash());
    }
}
