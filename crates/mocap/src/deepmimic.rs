//! DeepMimic JSON motion (`{"Loop": "wrap", "Frames": [[dt, root pos 3, root quat wxyz, joint
//! DoFs...], ...]}`), y-up, metres, radians.
//!
//! The per-joint layout of a frame depends on the character, so it is data: a
//! [`DeepMimicLayout`] lists joints with their kind (spherical = quaternion `w x y z`, revolute =
//! one angle about an axis, fixed = no data). [`DeepMimicLayout::humanoid3d`] is DeepMimic's
//! humanoid, used by pybullet's walker clips: 44 numbers per frame (1 + 3 + 4 + 36).

use std::path::Path;

use crate::error::{Error, ErrorKind, Location, read_file, shorten};
use crate::math::{Axis, Quat, UpAxis, Vec3};
use crate::motion::{AngleUnit, Clip, Motion, RawChannels};
use crate::skeleton::{Channel, Joint, LengthUnit, Skeleton, SourceFormat, UnitBasis, UnitReport};
use crate::text::{parse_f64, utf8};

/// How a layout joint moves and how many frame values it takes.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum JointKind {
    /// The root: position (3) and quaternion `w x y z` (4), world frame.
    Root,
    /// Ball joint: quaternion `w x y z` (4), local.
    Spherical,
    /// Hinge: one angle in radians about the axis (DeepMimic uses z).
    Revolute(Axis),
    /// Rigidly attached (e.g. a wrist): no values; becomes its parent's end site.
    Fixed,
}

impl JointKind {
    /// Frame values this joint takes.
    pub fn dof_values(self) -> usize {
        match self {
            JointKind::Root => 7,
            JointKind::Spherical => 4,
            JointKind::Revolute(_) => 1,
            JointKind::Fixed => 0,
        }
    }
}

/// One joint of a DeepMimic character, in the file's joint order.
#[derive(Clone, Debug, PartialEq)]
pub struct DeepMimicJoint {
    /// Joint name (DeepMimic's).
    pub name: String,
    /// Parent index in the layout; `None` only for the root.
    pub parent: Option<usize>,
    /// Attachment point in the parent's frame, metres (DeepMimic `AttachX/Y/Z`).
    pub offset: Vec3,
    /// Kind, which fixes the number of frame values.
    pub kind: JointKind,
}

/// The joints of a DeepMimic character in frame order.
#[derive(Clone, Debug, PartialEq)]
pub struct DeepMimicLayout {
    joints: Vec<DeepMimicJoint>,
}

impl DeepMimicLayout {
    /// Checks and wraps a layout: joint 0 and only it is the root, parents precede children,
    /// fixed joints have no children.
    pub fn new(joints: Vec<DeepMimicJoint>) -> Result<Self, Error> {
        let bad = |msg: String| Err(Error::Mismatch(format!("DeepMimic layout: {msg}")));
        for (i, j) in joints.iter().enumerate() {
            match (i, j.parent, j.kind) {
                (0, None, JointKind::Root) => {}
                (0, _, _) => return bad("joint 0 must be the root with no parent".into()),
                (_, Some(p), k) if p < i && k != JointKind::Root => {
                    if joints.get(p).is_some_and(|pj| pj.kind == JointKind::Fixed) {
                        return bad(format!("fixed joint `{}` has a child", joints[p].name));
                    }
                }
                _ => return bad(format!("joint `{}` needs an earlier parent", j.name)),
            }
        }
        if joints.is_empty() {
            return bad("no joints".into());
        }
        Ok(DeepMimicLayout { joints })
    }

    /// DeepMimic's `humanoid3d` (data/characters/humanoid3d.txt): root, chest, neck, right
    /// hip/knee/ankle, right shoulder/elbow/wrist, then the left side; y-up, x forward, right
    /// side at +z. Knees and elbows are revolute about z; wrists are fixed.
    pub fn humanoid3d() -> Self {
        use JointKind::*;
        let j = |name: &str, parent: Option<usize>, x, y, z, kind| DeepMimicJoint {
            name: name.to_string(),
            parent,
            offset: Vec3::new(x, y, z),
            kind,
        };
        DeepMimicLayout {
            joints: vec![
                j("root", None, 0.0, 0.0, 0.0, Root),
                j("chest", Some(0), 0.0, 0.236151, 0.0, Spherical),
                j("neck", Some(1), 0.0, 0.223894, 0.0, Spherical),
                j("right_hip", Some(0), 0.0, 0.0, 0.084887, Spherical),
                j("right_knee", Some(3), 0.0, -0.421546, 0.0, Revolute(Axis::Z)),
                j("right_ankle", Some(4), 0.0, -0.40987, 0.0, Spherical),
                j("right_shoulder", Some(1), -0.02405, 0.2435, 0.18311, Spherical),
                j("right_elbow", Some(6), 0.0, -0.274788, 0.0, Revolute(Axis::Z)),
                j("right_wrist", Some(7), 0.0, -0.258947, 0.0, Fixed),
                j("left_hip", Some(0), 0.0, 0.0, -0.084887, Spherical),
                j("left_knee", Some(9), 0.0, -0.421546, 0.0, Revolute(Axis::Z)),
                j("left_ankle", Some(10), 0.0, -0.40987, 0.0, Spherical),
                j("left_shoulder", Some(1), -0.02405, 0.2435, -0.18311, Spherical),
                j("left_elbow", Some(12), 0.0, -0.274788, 0.0, Revolute(Axis::Z)),
                j("left_wrist", Some(13), 0.0, -0.258947, 0.0, Fixed),
            ],
        }
    }

    /// The joints in frame order.
    pub fn joints(&self) -> &[DeepMimicJoint] {
        &self.joints
    }

    /// Numbers per frame, including the leading duration.
    pub fn frame_len(&self) -> usize {
        1 + self.joints.iter().map(|j| j.kind.dof_values()).sum::<usize>()
    }

    /// The skeleton of this character: fixed joints become end sites of their parents.
    pub fn skeleton(&self) -> Skeleton {
        let mut joints: Vec<Joint> = Vec::new();
        let mut index: Vec<Option<usize>> = Vec::with_capacity(self.joints.len());
        for dj in &self.joints {
            let parent = dj.parent.and_then(|p| index.get(p).copied().flatten());
            if dj.kind == JointKind::Fixed {
                if let Some(pj) = parent.and_then(|p| joints.get_mut(p)) {
                    pj.end_site = Some(dj.offset);
                }
                index.push(None);
                continue;
            }
            let mut j = Joint::new(dj.name.clone(), parent, dj.offset);
            j.channels = match dj.kind {
                JointKind::Root => vec![
                    Channel::Position(Axis::X),
                    Channel::Position(Axis::Y),
                    Channel::Position(Axis::Z),
                    Channel::QuatW,
                    Channel::QuatX,
                    Channel::QuatY,
                    Channel::QuatZ,
                ],
                JointKind::Spherical => {
                    vec![Channel::QuatW, Channel::QuatX, Channel::QuatY, Channel::QuatZ]
                }
                JointKind::Revolute(a) => vec![Channel::Rotation(a)],
                JointKind::Fixed => Vec::new(),
            };
            index.push(Some(joints.len()));
            joints.push(j);
        }
        Skeleton { joints, up: UpAxis::Y, source: SourceFormat::DeepMimic }
    }
}

/// Reads a DeepMimic motion file for the given character layout.
pub fn read_deepmimic(path: impl AsRef<Path>, layout: &DeepMimicLayout) -> Result<Clip, Error> {
    let path = path.as_ref();
    let bytes = read_file(path)?;
    parse_deepmimic(&bytes, layout).map_err(|e| e.in_file(path))
}

/// Parses DeepMimic motion JSON for the given character layout. Never panics.
///
/// The frame time is the first frame's duration; per-frame durations are not kept.
pub fn parse_deepmimic(bytes: &[u8], layout: &DeepMimicLayout) -> Result<Clip, Error> {
    let text = utf8(bytes)?;
    let mut p = JsonParser::new(text);
    let doc = p.document()?;
    let Json::Object(fields) = &doc.value else {
        return Err(doc.error(ErrorKind::Json("expected an object at the top level".into())));
    };
    let mut looping = None;
    let mut frames_node = None;
    for (k, v) in fields {
        match k.as_str() {
            "Loop" => {
                let Json::String(s) = &v.value else {
                    return Err(v.error(ErrorKind::Json("`Loop` must be a string".into())));
                };
                looping = Some(s == "wrap");
            }
            "Frames" => frames_node = Some(v),
            _ => {}
        }
    }
    let Some(frames_node) = frames_node else {
        return Err(doc.error(ErrorKind::Json("missing `Frames`".into())));
    };
    let Json::Array(frames) = &frames_node.value else {
        return Err(frames_node.error(ErrorKind::Json("`Frames` must be an array".into())));
    };

    let skeleton = layout.skeleton();
    let width = skeleton.channel_count();
    let expected = layout.frame_len();
    let labels: Vec<String> = std::iter::once("dt".to_string())
        .chain(skeleton.joints.iter().flat_map(|j| j.channels.iter().map(move |c| format!("{} {}", j.name, c.name()))))
        .collect();
    let n = skeleton.len();
    let mut motion = Motion::new(1.0, n);
    let mut raw = Vec::with_capacity(frames.len().saturating_mul(width));
    let mut row = Vec::with_capacity(expected);
    for (f, node) in frames.iter().enumerate() {
        let Json::Array(items) = &node.value else {
            return Err(node.error(ErrorKind::Json(format!("frame {f} must be an array"))));
        };
        if items.len() != expected {
            return Err(node.error(ErrorKind::FrameLength { frame: f, expected, found: items.len() }));
        }
        row.clear();
        for (k, item) in items.iter().enumerate() {
            let Json::Number(v) = item.value else {
                return Err(item.error(ErrorKind::Json(format!("frame {f}: expected a number"))));
            };
            if !v.is_finite() {
                let field = labels.get(k).cloned().unwrap_or_else(|| format!("value {k}"));
                return Err(item.error(ErrorKind::NonFinite { frame: f, field }));
            }
            row.push(v);
        }
        let dt = row.first().copied().unwrap_or(0.0);
        if f == 0 {
            if dt <= 0.0 {
                return Err(node.error(ErrorKind::BadFrameTime(dt)));
            }
            motion.frame_time = dt;
        }
        let values = row.get(1..).unwrap_or_default();
        let mut ts = Vec::with_capacity(n);
        let mut rs = Vec::with_capacity(n);
        let mut k = 0;
        let mut take = |count: usize| -> &[f64] {
            let s = values.get(k..k + count).unwrap_or_default();
            k += count;
            s
        };
        for j in &skeleton.joints {
            let quat = |s: &[f64]| -> Result<Quat, Error> {
                match s {
                    [w, x, y, z] => Quat::new(*w, *x, *y, *z)
                        .normalized()
                        .ok_or_else(|| node.error(ErrorKind::ZeroQuaternion { frame: f, joint: shorten(&j.name) })),
                    _ => Ok(Quat::IDENTITY),
                }
            };
            let (t, r) = match j.channels.as_slice() {
                [Channel::Position(_), _, _, _, _, _, _] => {
                    let s = take(7);
                    let t = match s.get(..3) {
                        Some([x, y, z]) => Vec3::new(*x, *y, *z),
                        _ => j.offset,
                    };
                    (t, quat(s.get(3..).unwrap_or_default())?)
                }
                [Channel::QuatW, ..] => (j.offset, quat(take(4))?),
                [Channel::Rotation(a)] => {
                    let angle = take(1).first().copied().unwrap_or(0.0);
                    (j.offset, Quat::about(*a, angle))
                }
                _ => (j.offset, Quat::IDENTITY),
            };
            ts.push(t);
            rs.push(r);
        }
        motion.push_frame(&ts, &rs);
        raw.extend_from_slice(values);
    }
    motion.raw = Some(RawChannels { width, values: raw, angle_unit: AngleUnit::Radians, metres_per_unit: 1.0 });
    Ok(Clip { skeleton, motion, units: UnitReport { unit: LengthUnit::Metre, basis: UnitBasis::Declared }, looping })
}

// --- A small JSON reader that keeps line and column of every value. ---

const MAX_DEPTH: usize = 64;

#[derive(Debug)]
enum Json {
    Null,
    Bool,
    Number(f64),
    String(String),
    Array(Vec<Node>),
    Object(Vec<(String, Node)>),
}

#[derive(Debug)]
struct Node {
    value: Json,
    line: usize,
    col: usize,
}

impl Node {
    fn error(&self, kind: ErrorKind) -> Error {
        Error::parse(Location::at(self.line, self.col), kind)
    }
}

struct JsonParser<'a> {
    src: &'a str,
    pos: usize,
    line: usize,
    line_start: usize,
}

impl<'a> JsonParser<'a> {
    fn new(src: &'a str) -> Self {
        JsonParser { src, pos: 0, line: 1, line_start: 0 }
    }

    fn err(&self, msg: impl Into<String>) -> Error {
        Error::parse(Location::at(self.line, self.pos - self.line_start + 1), ErrorKind::Json(msg.into()))
    }

    fn peek(&self) -> Option<u8> {
        self.src.as_bytes().get(self.pos).copied()
    }

    fn skip_ws(&mut self) {
        while let Some(b) = self.peek() {
            match b {
                b'\n' => {
                    self.pos += 1;
                    self.line += 1;
                    self.line_start = self.pos;
                }
                b' ' | b'\t' | b'\r' => self.pos += 1,
                _ => break,
            }
        }
    }

    fn document(&mut self) -> Result<Node, Error> {
        // A UTF-8 byte order mark is harmless.
        if self.src.starts_with('\u{feff}') {
            self.pos = 3;
        }
        let v = self.value(0)?;
        self.skip_ws();
        if self.peek().is_some() {
            return Err(self.err("trailing characters after the document"));
        }
        Ok(v)
    }

    fn value(&mut self, depth: usize) -> Result<Node, Error> {
        if depth > MAX_DEPTH {
            return Err(self.err("nested too deeply"));
        }
        self.skip_ws();
        let (line, col) = (self.line, self.pos - self.line_start + 1);
        let node = |value| Node { value, line, col };
        match self.peek() {
            None => Err(self.err("unexpected end of input")),
            Some(b'{') => {
                self.pos += 1;
                let mut fields = Vec::new();
                self.skip_ws();
                if self.peek() == Some(b'}') {
                    self.pos += 1;
                    return Ok(node(Json::Object(fields)));
                }
                loop {
                    self.skip_ws();
                    if self.peek() != Some(b'"') {
                        return Err(self.err("expected a string key"));
                    }
                    let key = self.string()?;
                    self.skip_ws();
                    if self.peek() != Some(b':') {
                        return Err(self.err("expected `:`"));
                    }
                    self.pos += 1;
                    let v = self.value(depth + 1)?;
                    fields.push((key, v));
                    self.skip_ws();
                    match self.peek() {
                        Some(b',') => self.pos += 1,
                        Some(b'}') => {
                            self.pos += 1;
                            return Ok(node(Json::Object(fields)));
                        }
                        _ => return Err(self.err("expected `,` or `}`")),
                    }
                }
            }
            Some(b'[') => {
                self.pos += 1;
                let mut items = Vec::new();
                self.skip_ws();
                if self.peek() == Some(b']') {
                    self.pos += 1;
                    return Ok(node(Json::Array(items)));
                }
                loop {
                    items.push(self.value(depth + 1)?);
                    self.skip_ws();
                    match self.peek() {
                        Some(b',') => self.pos += 1,
                        Some(b']') => {
                            self.pos += 1;
                            return Ok(node(Json::Array(items)));
                        }
                        _ => return Err(self.err("expected `,` or `]`")),
                    }
                }
            }
            Some(b'"') => Ok(node(Json::String(self.string()?))),
            Some(_) => {
                let start = self.pos;
                while let Some(b) = self.peek() {
                    if b.is_ascii_alphanumeric() || matches!(b, b'-' | b'+' | b'.') {
                        self.pos += 1;
                    } else {
                        break;
                    }
                }
                let word = self.src.get(start..self.pos).unwrap_or_default();
                match word {
                    "" => Err(self.err("unexpected character")),
                    "null" => Ok(node(Json::Null)),
                    "true" | "false" => Ok(node(Json::Bool)),
                    // Python's json module writes these for non-finite floats.
                    "NaN" => Ok(node(Json::Number(f64::NAN))),
                    "Infinity" => Ok(node(Json::Number(f64::INFINITY))),
                    "-Infinity" => Ok(node(Json::Number(f64::NEG_INFINITY))),
                    w if w.starts_with(|c: char| c == '-' || c.is_ascii_digit()) => {
                        let v = parse_f64(w)
                            .filter(|v| v.is_finite())
                            .ok_or_else(|| Error::parse(Location::at(line, col), ErrorKind::BadNumber(shorten(w))))?;
                        Ok(node(Json::Number(v)))
                    }
                    w => Err(Error::parse(
                        Location::at(line, col),
                        ErrorKind::Json(format!("unexpected `{}`", shorten(w))),
                    )),
                }
            }
        }
    }

    /// Reads a string starting at the opening quote.
    fn string(&mut self) -> Result<String, Error> {
        self.pos += 1;
        let mut out = String::new();
        loop {
            let rest = self.src.get(self.pos..).unwrap_or_default();
            let Some(c) = rest.chars().next() else {
                return Err(self.err("unterminated string"));
            };
            self.pos += c.len_utf8();
            match c {
                '"' => return Ok(out),
                '\n' => return Err(self.err("newline in string")),
                '\\' => {
                    let Some(e) = self.peek() else {
                        return Err(self.err("unterminated string"));
                    };
                    self.pos += 1;
                    match e {
                        b'"' => out.push('"'),
                        b'\\' => out.push('\\'),
                        b'/' => out.push('/'),
                        b'b' => out.push('\u{8}'),
                        b'f' => out.push('\u{c}'),
                        b'n' => out.push('\n'),
                        b'r' => out.push('\r'),
                        b't' => out.push('\t'),
                        b'u' => {
                            let hex = self.src.get(self.pos..self.pos + 4).unwrap_or_default();
                            let code = u32::from_str_radix(hex, 16)
                                .ok()
                                .filter(|_| hex.len() == 4 && hex.bytes().all(|b| b.is_ascii_hexdigit()))
                                .ok_or_else(|| self.err("bad \\u escape"))?;
                            self.pos += 4;
                            out.push(char::from_u32(code).unwrap_or('\u{fffd}'));
                        }
                        _ => return Err(self.err("bad escape")),
                    }
                }
                c => out.push(c),
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn frame(values: &[f64]) -> String {
        let v: Vec<String> = values.iter().map(|v| v.to_string()).collect();
        format!("[{}]", v.join(", "))
    }

    fn rest_frame() -> Vec<f64> {
        let mut f = vec![0.0333, 0.0, 0.85, 0.0, 1.0, 0.0, 0.0, 0.0];
        for j in DeepMimicLayout::humanoid3d().joints().iter().skip(1) {
            match j.kind {
                JointKind::Spherical => f.extend([1.0, 0.0, 0.0, 0.0]),
                JointKind::Revolute(_) => f.push(0.0),
                _ => {}
            }
        }
        f
    }

    #[test]
    fn humanoid_layout_has_44_values_and_12_joints() {
        let l = DeepMimicLayout::humanoid3d();
        assert_eq!(l.frame_len(), 44);
        let s = l.skeleton();
        assert_eq!(s.len(), 13);
        assert_eq!(s.channel_count(), 43);
        let elbow = s.joint_index("right_elbow").unwrap();
        assert_eq!(s.joints[elbow].end_site, Some(Vec3::new(0.0, -0.258947, 0.0)));
        assert!(DeepMimicLayout::new(l.joints().to_vec()).is_ok());
    }

    #[test]
    fn parses_rest_frames_and_bent_knee() {
        let mut f2 = rest_frame();
        // right knee is value 1 + 3 + 4 + 4 + 4 + 4 = index 20.
        f2[20] = -std::f64::consts::FRAC_PI_2;
        let text = format!("{{\"Loop\": \"wrap\",\n\"Frames\": [\n{},\n{}\n]}}", frame(&rest_frame()), frame(&f2));
        let clip = parse_deepmimic(text.as_bytes(), &DeepMimicLayout::humanoid3d()).unwrap();
        assert_eq!(clip.motion.frame_count(), 2);
        assert_eq!(clip.looping, Some(true));
        assert!((clip.motion.frame_time - 0.0333).abs() < 1e-12);
        let s = &clip.skeleton;
        let ankle = s.joint_index("right_ankle").unwrap();
        let p0 = clip.motion.world_pose(s, 0).unwrap().positions[ankle];
        let p1 = clip.motion.world_pose(s, 1).unwrap().positions[ankle];
        assert!((p0.y - (0.85 - 0.421546 - 0.40987)).abs() < 1e-9);
        // Knee at -90° about z swings the shin towards -x (backwards, DeepMimic faces +x).
        assert!((p1.x + 0.40987).abs() < 1e-9, "{p1:?}");
    }

    #[test]
    fn errors_name_frame_and_line() {
        let mut bad = frame(&rest_frame());
        bad = bad.replacen("0.85", "NaN", 1);
        let text = format!("{{\"Frames\": [\n{},\n{}]}}", frame(&rest_frame()), bad);
        let e = parse_deepmimic(text.as_bytes(), &DeepMimicLayout::humanoid3d()).unwrap_err();
        assert!(matches!(e.kind(), Some(ErrorKind::NonFinite { frame: 1, field }) if field == "root Yposition"));
        assert_eq!(e.location().map(|l| l.line), Some(3));

        let text = "{\"Frames\": [[0.1, 2]]}";
        let e = parse_deepmimic(text.as_bytes(), &DeepMimicLayout::humanoid3d()).unwrap_err();
        assert!(matches!(e.kind(), Some(ErrorKind::FrameLength { frame: 0, expected: 44, found: 2 })));

        let deep = "[".repeat(10_000);
        assert!(parse_deepmimic(deep.as_bytes(), &DeepMimicLayout::humanoid3d()).is_err());
    }

    #[test]
    fn json_strings_and_escapes() {
        let mut p = JsonParser::new(r#"{"a\n\u00e9": [true, null, -1.5e2]}"#);
        let doc = p.document().unwrap();
        let Json::Object(f) = doc.value else { panic!() };
        assert_eq!(f[0].0, "a\né");
    }
}
