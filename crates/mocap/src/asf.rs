//! Acclaim ASF (skeleton, version 1.10) and AMC (motion) as used by the CMU database.
//!
//! Each bone becomes a joint at the bone's start, offset from its parent joint by the parent
//! bone's `direction × length` (root children start at the root). A leaf bone's far end is its
//! [`Joint::end_site`]. DoF values of a frame rotate the bone about the axes of its `axis`
//! frame `C`: `M = R(dof_n) ··· R(dof_1)` (first DoF applied first), local rotation
//! `L = C · M · C⁻¹` in the rest-aligned frame (CMU's `L = C⁻¹ M C` in row-vector notation).
//! The root uses its `order` channels the same way, with `C` from `orientation` in `axis`
//! order. Lengths: `:units length s` means file lengths are inches × `s`, so a file unit is
//! `0.0254 / s` metres (CMU: `s = 0.45`, ≈ 0.056444 m). CMU data is y-up.

use std::collections::{HashMap, HashSet};
use std::path::Path;

use crate::error::{Error, ErrorKind, Location, read_file, shorten};
use crate::math::{Axis, EulerOrder, Quat, UpAxis, Vec3};
use crate::motion::{AngleUnit, Clip, Motion, RawChannels};
use crate::skeleton::{Channel, Joint, LengthUnit, Limit, Skeleton, SourceFormat, UnitBasis, UnitReport};
use crate::text::{Token, line_tokens, utf8};

/// A parsed ASF file: the skeleton plus what AMC parsing needs.
#[derive(Clone, Debug, PartialEq)]
pub struct Asf {
    /// `:name`, if given.
    pub name: Option<String>,
    /// The skeleton (metres); joint 0 is `root`.
    pub skeleton: Skeleton,
    /// Source length unit.
    pub units: UnitReport,
    /// `:units angle`, the default for AMC files without `:DEGREES`/`:RADIANS`.
    pub angle_unit: AngleUnit,
}

/// Options for reading AMC motion.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct AmcOptions {
    /// Seconds per frame; AMC does not store it (CMU captures at 120 fps).
    pub frame_time: f64,
    /// Drop frame 0.
    pub skip_first_frame: bool,
}

impl Default for AmcOptions {
    fn default() -> Self {
        AmcOptions { frame_time: 1.0 / 120.0, skip_first_frame: false }
    }
}

/// Reads an ASF file; `unit` overrides the file's `:units length`.
pub fn read_asf(path: impl AsRef<Path>, unit: Option<LengthUnit>) -> Result<Asf, Error> {
    let path = path.as_ref();
    let bytes = read_file(path)?;
    parse_asf(&bytes, unit).map_err(|e| e.in_file(path))
}

/// Reads an AMC file for a skeleton read with [`read_asf`].
pub fn read_amc(path: impl AsRef<Path>, asf: &Asf, options: &AmcOptions) -> Result<Clip, Error> {
    let path = path.as_ref();
    let bytes = read_file(path)?;
    parse_amc(&bytes, asf, options).map_err(|e| e.in_file(path))
}

/// The rotation of an ASF Euler triple: `values[i]` about `order[i]`, first applied first.
pub fn extrinsic(order: EulerOrder, values: [f64; 3]) -> Quat {
    order.reversed().to_quat([values[2], values[1], values[0]])
}

#[derive(Debug, Default)]
struct Bone {
    line: usize,
    name: String,
    direction: Vec3,
    length: f64,
    axis: [f64; 3],
    order: Option<EulerOrder>,
    dof: Vec<Channel>,
    limits: Vec<Limit>,
}

#[derive(Clone, Copy, PartialEq, Eq)]
enum Section {
    None,
    Units,
    Root,
    Bonedata,
    Hierarchy,
    Other,
}

fn dof_channel(t: &Token<'_>) -> Result<Channel, Error> {
    let c = match t.text.to_ascii_lowercase().as_str() {
        "rx" => Channel::Rotation(Axis::X),
        "ry" => Channel::Rotation(Axis::Y),
        "rz" => Channel::Rotation(Axis::Z),
        "tx" => Channel::Position(Axis::X),
        "ty" => Channel::Position(Axis::Y),
        "tz" => Channel::Position(Axis::Z),
        "l" => Channel::Length,
        _ => return Err(t.error(ErrorKind::UnknownChannel(shorten(t.text)))),
    };
    Ok(c)
}

fn vec3_from<'a>(
    kw: &Token<'a>,
    toks: &mut impl Iterator<Item = Token<'a>>,
    what: &'static str,
) -> Result<[f64; 3], Error> {
    let mut v = [0.0; 3];
    for x in &mut v {
        let t =
            toks.next().ok_or_else(|| Error::parse(Location::line(kw.line), ErrorKind::UnexpectedEof("3 numbers")))?;
        *x = t.finite(what)?;
    }
    Ok(v)
}

fn order_from(t: Option<Token<'_>>, line: usize) -> Result<EulerOrder, Error> {
    let t = t.ok_or_else(|| Error::parse(Location::line(line), ErrorKind::UnexpectedEof("an axis order")))?;
    EulerOrder::parse(t.text).ok_or_else(|| t.expected("an axis order such as XYZ"))
}

/// Parses limit numbers (`(-160.0 20.0)`, possibly `inf`) from tokens into `out`.
fn push_limit_numbers<'a>(toks: impl Iterator<Item = Token<'a>>, out: &mut Vec<f64>) -> Result<(), Error> {
    for t in toks {
        for piece in t.text.split(['(', ')']) {
            if piece.is_empty() {
                continue;
            }
            let v = crate::text::parse_f64(piece).ok_or_else(|| t.error(ErrorKind::BadNumber(shorten(piece))))?;
            if v.is_nan() {
                return Err(t.error(ErrorKind::NonFiniteHeader("limit")));
            }
            out.push(v);
        }
    }
    Ok(())
}

/// Parses ASF text; `unit` overrides `:units length`. Never panics.
pub fn parse_asf(bytes: &[u8], unit: Option<LengthUnit>) -> Result<Asf, Error> {
    let text = utf8(bytes)?;
    let mut section = Section::None;
    let mut name = None;
    let mut length_mult: Option<(f64, usize)> = None;
    let mut angle_unit = AngleUnit::Degrees;
    let mut root_order: Vec<Channel> = Vec::new();
    let mut root_axis = EulerOrder::new([Axis::X, Axis::Y, Axis::Z]).unwrap_or(EulerOrder::ZXY);
    let mut root_position = [0.0; 3];
    let mut root_orientation = [0.0; 3];
    let mut bones: Vec<Bone> = Vec::new();
    let mut bone_names: HashSet<String> = HashSet::new();
    let mut bone: Option<Bone> = None;
    let mut limit_values: Vec<f64> = Vec::new();
    let mut in_limits = false;
    let mut edges: Vec<(Token<'_>, Token<'_>)> = Vec::new();
    let mut last_line = 0;

    for (line_no, line) in text.split('\n').enumerate() {
        let line_no = line_no + 1;
        last_line = line_no;
        let mut toks = line_tokens(line_no, line);
        let Some(first) = toks.next() else { continue };
        if first.text.starts_with('#') {
            continue;
        }
        if first.text.starts_with(':') {
            in_limits = false;
            section = match first.text.to_ascii_lowercase().as_str() {
                ":units" => Section::Units,
                ":root" => Section::Root,
                ":bonedata" => Section::Bonedata,
                ":hierarchy" => Section::Hierarchy,
                ":name" => {
                    let rest: Vec<&str> = toks.map(|t| t.text).collect();
                    name = Some(rest.join(" "));
                    Section::Other
                }
                _ => Section::Other,
            };
            continue;
        }
        let key = first.text.to_ascii_lowercase();
        match section {
            Section::None | Section::Other => {}
            Section::Units => match key.as_str() {
                "length" => {
                    let t = toks
                        .next()
                        .ok_or_else(|| Error::parse(Location::line(line_no), ErrorKind::UnexpectedEof("a number")))?;
                    let v = t.finite("length unit")?;
                    if v <= 0.0 {
                        return Err(t.error(ErrorKind::Invalid("length unit must be positive".into())));
                    }
                    length_mult = Some((v, line_no));
                }
                "angle" => {
                    let t = toks
                        .next()
                        .ok_or_else(|| Error::parse(Location::line(line_no), ErrorKind::UnexpectedEof("deg or rad")))?;
                    angle_unit = match t.text.to_ascii_lowercase().as_str() {
                        "deg" | "degree" | "degrees" => AngleUnit::Degrees,
                        "rad" | "radian" | "radians" => AngleUnit::Radians,
                        _ => return Err(t.expected("deg or rad")),
                    };
                }
                _ => {}
            },
            Section::Root => match key.as_str() {
                "order" => {
                    root_order.clear();
                    for t in toks {
                        let c = match t.text.to_ascii_lowercase().as_str() {
                            "tx" => Channel::Position(Axis::X),
                            "ty" => Channel::Position(Axis::Y),
                            "tz" => Channel::Position(Axis::Z),
                            "rx" => Channel::Rotation(Axis::X),
                            "ry" => Channel::Rotation(Axis::Y),
                            "rz" => Channel::Rotation(Axis::Z),
                            _ => return Err(t.error(ErrorKind::UnknownChannel(shorten(t.text)))),
                        };
                        if root_order.contains(&c) {
                            return Err(t.error(ErrorKind::DuplicateChannel(shorten(t.text))));
                        }
                        root_order.push(c);
                    }
                }
                "axis" => root_axis = order_from(toks.next(), line_no)?,
                "position" => root_position = vec3_from(&first, &mut toks, "root position")?,
                "orientation" => root_orientation = vec3_from(&first, &mut toks, "root orientation")?,
                _ => {}
            },
            Section::Bonedata => {
                if in_limits && first.text.starts_with('(') {
                    push_limit_numbers(std::iter::once(first).chain(toks), &mut limit_values)?;
                    continue;
                }
                in_limits = false;
                match key.as_str() {
                    "begin" => {
                        if bone.is_some() {
                            return Err(first.expected("end"));
                        }
                        bone = Some(Bone { line: line_no, ..Bone::default() });
                        limit_values.clear();
                    }
                    "end" => {
                        let Some(mut b) = bone.take() else {
                            return Err(first.expected("begin"));
                        };
                        if b.name.is_empty() {
                            return Err(Error::parse(
                                Location::line(b.line),
                                ErrorKind::Invalid("bone without a name".into()),
                            ));
                        }
                        if !limit_values.is_empty() {
                            if limit_values.len() != 2 * b.dof.len() {
                                return Err(Error::parse(
                                    Location::line(line_no),
                                    ErrorKind::Invalid(format!(
                                        "bone `{}` has {} DoFs but {} limit values",
                                        shorten(&b.name),
                                        b.dof.len(),
                                        limit_values.len()
                                    )),
                                ));
                            }
                            b.limits = limit_values
                                .chunks_exact(2)
                                .map(|p| Limit {
                                    min: p.first().copied().unwrap_or(0.0),
                                    max: p.get(1).copied().unwrap_or(0.0),
                                })
                                .collect();
                        }
                        if b.name == "root" || !bone_names.insert(b.name.clone()) {
                            return Err(first.error(ErrorKind::DuplicateJoint(shorten(&b.name))));
                        }
                        bones.push(b);
                    }
                    _ => {
                        let Some(b) = bone.as_mut() else {
                            return Err(first.expected("begin"));
                        };
                        match key.as_str() {
                            "name" => {
                                let t = toks.next().ok_or_else(|| {
                                    Error::parse(Location::line(line_no), ErrorKind::UnexpectedEof("a bone name"))
                                })?;
                                b.name = t.text.to_string();
                            }
                            "direction" => {
                                let [x, y, z] = vec3_from(&first, &mut toks, "direction")?;
                                b.direction = Vec3::new(x, y, z);
                            }
                            "length" => {
                                let t = toks.next().ok_or_else(|| {
                                    Error::parse(Location::line(line_no), ErrorKind::UnexpectedEof("a number"))
                                })?;
                                b.length = t.finite("bone length")?;
                            }
                            "axis" => {
                                b.axis = vec3_from(&first, &mut toks, "axis")?;
                                b.order = Some(order_from(toks.next(), line_no)?);
                            }
                            "dof" => {
                                for t in toks {
                                    let c = dof_channel(&t)?;
                                    if b.dof.contains(&c) {
                                        return Err(t.error(ErrorKind::DuplicateChannel(shorten(t.text))));
                                    }
                                    b.dof.push(c);
                                }
                            }
                            "limits" => {
                                in_limits = true;
                                push_limit_numbers(toks, &mut limit_values)?;
                            }
                            // id, bodymass, cofmass and unknown keys carry nothing we use.
                            _ => {}
                        }
                    }
                }
            }
            Section::Hierarchy => match key.as_str() {
                "begin" | "end" => {}
                _ => {
                    for child in toks {
                        edges.push((first, child));
                    }
                }
            },
        }
    }
    if bone.is_some() {
        return Err(Error::parse(Location::line(last_line), ErrorKind::UnexpectedEof("end")));
    }

    let (unit, basis) = match (unit, length_mult) {
        (Some(u), _) => (u, UnitBasis::Explicit),
        (None, Some((m, _))) if (m - 0.45).abs() < 1e-12 => (LengthUnit::Cmu, UnitBasis::Declared),
        (None, Some((m, _))) => (LengthUnit::Custom(0.0254 / m), UnitBasis::Declared),
        (None, None) => (LengthUnit::Inch, UnitBasis::Declared),
    };
    let scale = unit.metres_per_unit();
    if !(scale.is_finite() && scale > 0.0) {
        return Err(Error::Mismatch(format!("length unit scale must be positive and finite, got {scale}")));
    }
    let to_rad = |v: f64| angle_unit.to_radians(v);

    // Hierarchy: node 0 is the root, bone i is node i + 1.
    let mut by_name: HashMap<&str, usize> = HashMap::with_capacity(bones.len() + 1);
    by_name.insert("root", 0);
    for (i, b) in bones.iter().enumerate() {
        by_name.insert(b.name.as_str(), i + 1);
    }
    let node_count = bones.len() + 1;
    let mut parent_of: Vec<Option<usize>> = vec![None; node_count];
    let mut children: Vec<Vec<usize>> = vec![Vec::new(); node_count];
    for (p, c) in &edges {
        let pi = *by_name.get(p.text).ok_or_else(|| p.error(ErrorKind::UnknownJoint(shorten(p.text))))?;
        let ci = *by_name.get(c.text).ok_or_else(|| c.error(ErrorKind::UnknownJoint(shorten(c.text))))?;
        let slot = parent_of.get_mut(ci).ok_or_else(|| c.error(ErrorKind::UnknownJoint(shorten(c.text))))?;
        if ci == 0 || slot.is_some() {
            return Err(c.error(ErrorKind::Invalid(format!("`{}` has more than one parent", shorten(c.text)))));
        }
        *slot = Some(pi);
        if let Some(ch) = children.get_mut(pi) {
            ch.push(ci);
        }
    }

    // Depth-first from the root, without recursion; cycles never reach the root.
    let mut joints: Vec<Joint> = Vec::with_capacity(node_count);
    let mut root = Joint::new("root", None, Vec3::new(root_position[0], root_position[1], root_position[2]) * scale);
    root.channels = root_order;
    root.axis = extrinsic(root_axis, root_orientation.map(to_rad));
    joints.push(root);
    let mut joint_of_node: Vec<Option<usize>> = vec![None; node_count];
    if let Some(slot) = joint_of_node.first_mut() {
        *slot = Some(0);
    }
    let mut stack: Vec<usize> = children.first().map(|c| c.iter().rev().copied().collect()).unwrap_or_default();
    while let Some(node) = stack.pop() {
        let Some(b) = node.checked_sub(1).and_then(|i| bones.get(i)) else {
            continue;
        };
        let parent_node = parent_of.get(node).copied().flatten().unwrap_or(0);
        let parent_joint = joint_of_node.get(parent_node).copied().flatten().unwrap_or(0);
        let offset = match parent_node.checked_sub(1).and_then(|i| bones.get(i)) {
            Some(pb) => bone_vector(pb) * scale,
            None => Vec3::ZERO,
        };
        let mut j = Joint::new(b.name.clone(), Some(parent_joint), offset);
        j.channels = b.dof.clone();
        j.limits = b
            .dof
            .iter()
            .zip(&b.limits)
            .map(|(c, l)| match c {
                Channel::Rotation(_) => Limit { min: to_rad(l.min), max: to_rad(l.max) },
                _ => Limit { min: l.min * scale, max: l.max * scale },
            })
            .collect();
        let order = b.order.unwrap_or(root_axis);
        j.axis = extrinsic(order, b.axis.map(to_rad));
        let kids = children.get(node).map(Vec::as_slice).unwrap_or_default();
        if kids.is_empty() {
            j.end_site = Some(bone_vector(b) * scale);
        }
        if let Some(slot) = joint_of_node.get_mut(node) {
            *slot = Some(joints.len());
        }
        joints.push(j);
        stack.extend(kids.iter().rev());
    }
    if let Some(b) =
        bones.iter().enumerate().find(|(i, _)| joint_of_node.get(i + 1).copied().flatten().is_none()).map(|(_, b)| b)
    {
        return Err(Error::parse(
            Location::line(b.line),
            ErrorKind::Invalid(format!("bone `{}` is not below root in :hierarchy", shorten(&b.name))),
        ));
    }
    Ok(Asf {
        name,
        skeleton: Skeleton { joints, up: UpAxis::Y, source: SourceFormat::AsfAmc },
        units: UnitReport { unit, basis },
        angle_unit,
    })
}

fn bone_vector(b: &Bone) -> Vec3 {
    let n = b.direction.norm();
    let dir = if n > 1e-12 && n.is_finite() { b.direction * (1.0 / n) } else { b.direction };
    dir * b.length
}

/// Parses AMC text (fully specified frames) for `asf`'s skeleton. Never panics.
pub fn parse_amc(bytes: &[u8], asf: &Asf, options: &AmcOptions) -> Result<Clip, Error> {
    let text = utf8(bytes)?;
    if !(options.frame_time.is_finite() && options.frame_time > 0.0) {
        return Err(Error::parse(Location::line(0), ErrorKind::BadFrameTime(options.frame_time)));
    }
    let skel = &asf.skeleton;
    let n = skel.len();
    let scale = asf.units.unit.metres_per_unit();
    let index: HashMap<&str, usize> = skel.joints.iter().enumerate().map(|(i, j)| (j.name.as_str(), i)).collect();
    let mut starts = Vec::with_capacity(n);
    let mut width = 0;
    for j in &skel.joints {
        starts.push(width);
        width += j.channels.len();
    }
    if width == 0 {
        return Err(Error::parse(Location::line(1), ErrorKind::NoChannels));
    }

    let mut angle_unit = asf.angle_unit;
    let mut motion = Motion::new(options.frame_time, n);
    let mut raw: Vec<f64> = Vec::new();
    let mut current: Option<(usize, Vec<f64>, Vec<bool>)> = None; // (line, values, filled)
    let mut frame = 0usize;

    let finish = |line: usize,
                  frame: usize,
                  values: &[f64],
                  filled: &[bool],
                  angle_unit: AngleUnit,
                  motion: &mut Motion|
     -> Result<(), Error> {
        for (j, joint) in skel.joints.iter().enumerate() {
            if !joint.channels.is_empty() && !filled.get(j).copied().unwrap_or(false) {
                return Err(Error::parse(
                    Location::line(line),
                    ErrorKind::MissingBone { frame, bone: shorten(&joint.name) },
                ));
            }
        }
        let mut ts = Vec::with_capacity(n);
        let mut rs = Vec::with_capacity(n);
        for (j, joint) in skel.joints.iter().enumerate() {
            let base = starts.get(j).copied().unwrap_or(0);
            let mut m = Quat::IDENTITY;
            let mut t = Vec3::ZERO;
            let mut has_t = false;
            for (k, c) in joint.channels.iter().enumerate() {
                let v = values.get(base + k).copied().unwrap_or(0.0);
                match *c {
                    Channel::Rotation(a) => m = Quat::about(a, angle_unit.to_radians(v)) * m,
                    Channel::Position(a) => {
                        t.set(a, v * scale);
                        has_t = true;
                    }
                    _ => {}
                }
            }
            let c = joint.axis;
            rs.push(c * m * c.conjugate());
            ts.push(match (joint.parent, has_t) {
                (None, true) => t,
                (_, true) => joint.offset + c.rotate(t),
                (_, false) => joint.offset,
            });
        }
        motion.push_frame(&ts, &rs);
        Ok(())
    };

    for (line_no, line) in text.split('\n').enumerate() {
        let line_no = line_no + 1;
        let mut toks = line_tokens(line_no, line);
        let Some(first) = toks.next() else { continue };
        if first.text.starts_with('#') {
            continue;
        }
        if first.text.starts_with(':') {
            match first.text.to_ascii_uppercase().as_str() {
                ":DEGREES" => angle_unit = AngleUnit::Degrees,
                ":RADIANS" => angle_unit = AngleUnit::Radians,
                _ => {}
            }
            continue;
        }
        if first.text.bytes().all(|b| b.is_ascii_digit()) {
            if let Some(extra) = toks.next() {
                return Err(extra.expected("end of line after the frame number"));
            }
            if let Some((l, values, filled)) = current.take() {
                finish(l, frame, &values, &filled, angle_unit, &mut motion)?;
                raw.extend_from_slice(&values);
                frame += 1;
            }
            current = Some((line_no, vec![0.0; width], vec![false; n]));
            continue;
        }
        let Some((_, values, filled)) = current.as_mut() else {
            return Err(first.expected("a frame number"));
        };
        let j = *index.get(first.text).ok_or_else(|| first.error(ErrorKind::UnknownJoint(shorten(first.text))))?;
        let joint = skel.joints.get(j).ok_or_else(|| first.error(ErrorKind::UnknownJoint(shorten(first.text))))?;
        let seen = filled.get_mut(j).ok_or_else(|| first.error(ErrorKind::UnknownJoint(shorten(first.text))))?;
        if *seen {
            return Err(first.error(ErrorKind::RepeatedBone { frame, bone: shorten(first.text) }));
        }
        *seen = true;
        let base = starts.get(j).copied().unwrap_or(0);
        let mut k = 0;
        for t in toks {
            if k >= joint.channels.len() {
                return Err(t.error(ErrorKind::Invalid(format!(
                    "frame {frame}: bone `{}` has {} DoFs, found more values",
                    shorten(&joint.name),
                    joint.channels.len()
                ))));
            }
            let v = t.f64()?;
            if !v.is_finite() {
                let ch = joint.channels.get(k).map_or("?", |c| c.name());
                return Err(t.error(ErrorKind::NonFinite { frame, field: format!("{} {}", shorten(&joint.name), ch) }));
            }
            if let Some(slot) = values.get_mut(base + k) {
                *slot = v;
            }
            k += 1;
        }
        if k != joint.channels.len() {
            return Err(first.error(ErrorKind::Invalid(format!(
                "frame {frame}: bone `{}` has {} DoFs, found {k} values",
                shorten(&joint.name),
                joint.channels.len()
            ))));
        }
    }
    if let Some((l, values, filled)) = current.take() {
        finish(l, frame, &values, &filled, angle_unit, &mut motion)?;
        raw.extend_from_slice(&values);
    }
    motion.raw = Some(RawChannels { width, values: raw, angle_unit, metres_per_unit: scale });
    if options.skip_first_frame {
        motion.skip_first_frame();
    }
    Ok(Clip { skeleton: skel.clone(), motion, units: asf.units, looping: None })
}

#[cfg(test)]
mod tests {
    use super::*;

    const ASF: &str = ":version 1.10
:name test
:units
  mass 1.0
  length 1.0
  angle deg
:root
   order TX TY TZ RX RY RZ
   axis XYZ
   position 0 0 0
   orientation 0 0 0
:bonedata
  begin
     id 1
     name thigh
     direction 0 -1 0
     length 10
     axis 0 0 90 XYZ
    dof rx rz
    limits (-160.0 20.0)
           (-inf inf)
  end
  begin
     id 2
     name shin
     direction 0 -1 0
     length 5
     axis 0 0 0 XYZ
    dof rx
  end
:hierarchy
  begin
    root thigh
    thigh shin
  end
";

    #[test]
    fn builds_joints_at_bone_starts() {
        let asf = parse_asf(ASF.as_bytes(), Some(LengthUnit::Metre)).unwrap();
        let s = &asf.skeleton;
        assert_eq!(s.len(), 3);
        assert_eq!(s.joints[1].offset, Vec3::ZERO);
        assert_eq!(s.joints[2].offset, Vec3::new(0.0, -10.0, 0.0));
        assert_eq!(s.joints[2].end_site, Some(Vec3::new(0.0, -5.0, 0.0)));
        let lim = &s.joints[1].limits;
        assert!((lim[0].min + 160f64.to_radians()).abs() < 1e-12);
        assert!(lim[1].max.is_infinite());
        assert_eq!(asf.name.as_deref(), Some("test"));
    }

    #[test]
    fn dof_rotates_about_the_axis_frame() {
        // thigh's C turns its local x axis onto world y; rx = 90° therefore rotates about
        // world +y, swinging the shin's start (world -y of the thigh) ... which is on the
        // axis, so use the rz DoF: local z stays world z, rotating -y towards +x.
        let asf = parse_asf(ASF.as_bytes(), Some(LengthUnit::Metre)).unwrap();
        let amc = ":FULLY-SPECIFIED\n:DEGREES\n1\nroot 0 0 0 0 0 0\nthigh 0 90\nshin 0\n";
        let clip = parse_amc(amc.as_bytes(), &asf, &AmcOptions::default()).unwrap();
        let pose = clip.motion.world_pose(&clip.skeleton, 0).unwrap();
        let shin = pose.positions[2];
        assert!((shin - Vec3::new(10.0, 0.0, 0.0)).norm() < 1e-9, "{shin:?}");
        let q = pose.rotations[1];
        // rx about C's x axis (world y) by 90°: check with a second frame.
        let amc = "1\nroot 0 0 0 0 0 0\nthigh 90 0\nshin 0\n";
        let clip = parse_amc(amc.as_bytes(), &asf, &AmcOptions::default()).unwrap();
        let r = clip.motion.world_pose(&clip.skeleton, 0).unwrap().rotations[1];
        let expect = Quat::about(Axis::Y, std::f64::consts::FRAC_PI_2);
        assert!(r.angle_to(expect) < 1e-9);
        assert!(q.angle_to(Quat::about(Axis::Z, std::f64::consts::FRAC_PI_2)) < 1e-9);
    }

    #[test]
    fn amc_errors() {
        let asf = parse_asf(ASF.as_bytes(), None).unwrap();
        assert_eq!(asf.units.unit, LengthUnit::Custom(0.0254));
        let opts = AmcOptions::default();
        let e = parse_amc(b"1\nroot 0 0 0 0 0 0\nthigh 0 nan\nshin 0\n", &asf, &opts).unwrap_err();
        assert_eq!(e.to_string(), "<input>:3:9: frame 0: non-finite value in thigh Zrotation");
        let e = parse_amc(b"1\nroot 0 0 0 0 0 0\nshin 0\n", &asf, &opts).unwrap_err();
        assert!(matches!(e.kind(), Some(ErrorKind::MissingBone { frame: 0, .. })));
        let e = parse_amc(b"thigh 0 0\n", &asf, &opts).unwrap_err();
        assert!(e.to_string().contains("expected a frame number"));
    }

    #[test]
    fn asf_errors() {
        let bad = ASF.replace("thigh shin", "thigh ghost");
        let e = parse_asf(bad.as_bytes(), None).unwrap_err();
        assert!(matches!(e.kind(), Some(ErrorKind::UnknownJoint(n)) if n == "ghost"));
        assert_eq!(e.location().map(|l| l.line), Some(34));
        let bad = ASF.replace("(-inf inf)", "");
        assert!(parse_asf(bad.as_bytes(), None).is_err());
    }
}
