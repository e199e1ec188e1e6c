//! BVH (Biovision hierarchy): parser and writer.
//!
//! Reading: any channel order, 3 or 6 channels on any joint, `End Site`s, LF or CRLF, one frame
//! per line. Position channels give the joint's local translation (they replace the `OFFSET`,
//! as Blender reads them); rotation channels compose intrinsically in listed order, so
//! `Zrotation Xrotation Yrotation` is `R = Rz · Rx · Ry`. BVH is y-up.
//!
//! Writing: tab-indented standard BVH that Blender and MotionBuilder import; channel values are
//! derived from the motion's quaternions, choosing the Euler solution closest to the file's raw
//! values (when present) or to the previous frame, so curves stay continuous.

use std::collections::HashSet;
use std::fmt::Write as _;
use std::path::Path;

use crate::error::{Error, ErrorKind, Location, read_file, shorten};
use crate::math::{Axis, EulerOrder, Quat, UpAxis, Vec3};
use crate::motion::{AngleUnit, Clip, Motion, RawChannels};
use crate::skeleton::{Channel, Joint, LengthUnit, Skeleton, SourceFormat, UnitBasis, UnitReport};
use crate::text::{Scanner, Token, line_tokens, utf8};

/// Options for reading BVH.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct BvhOptions {
    /// The file's length unit; `None` guesses it from the character's size
    /// ([`LengthUnit::guess_from_size`]) and reports the guess in [`Clip::units`].
    pub unit: Option<LengthUnit>,
    /// Drop frame 0 (a rest or T-pose some exporters put first).
    pub skip_first_frame: bool,
}

/// Reads a BVH file.
pub fn read_bvh(path: impl AsRef<Path>, options: &BvhOptions) -> Result<Clip, Error> {
    let path = path.as_ref();
    let bytes = read_file(path)?;
    parse_bvh(&bytes, options).map_err(|e| e.in_file(path))
}

/// Parses BVH text. Never panics; every error carries a line (and column where it helps).
pub fn parse_bvh(bytes: &[u8], options: &BvhOptions) -> Result<Clip, Error> {
    let text = utf8(bytes)?;
    let mut sc = Scanner::new(text);
    let mut skeleton = parse_hierarchy(&mut sc)?;
    let (raw, frame_time) = parse_motion(&mut sc, &skeleton)?;
    let width = skeleton.channel_count();

    let (unit, basis) = match options.unit {
        Some(u) => (u, UnitBasis::Explicit),
        None => (guess_unit(&skeleton, &raw, width), UnitBasis::Guessed),
    };
    let scale = unit.metres_per_unit();
    if !(scale.is_finite() && scale > 0.0) {
        return Err(Error::Mismatch(format!("length unit scale must be positive and finite, got {scale}")));
    }

    // Build local translations and rotations from the raw (unscaled) values.
    let n = skeleton.len();
    let mut motion = Motion::new(frame_time, n);
    let frames = raw.len().checked_div(width).unwrap_or(0);
    motion.translations.reserve(frames.saturating_mul(n));
    motion.rotations.reserve(frames.saturating_mul(n));
    for f in 0..frames {
        let values = raw.get(f * width..(f + 1) * width).unwrap_or_default();
        let mut k = 0;
        for joint in &skeleton.joints {
            let mut t = joint.offset;
            let mut r = Quat::IDENTITY;
            for ch in &joint.channels {
                let v = values.get(k).copied().unwrap_or(0.0);
                k += 1;
                match *ch {
                    Channel::Position(a) => t.set(a, v),
                    Channel::Rotation(a) => r = r * Quat::about(a, v.to_radians()),
                    _ => {}
                }
            }
            motion.translations.push(t * scale);
            motion.rotations.push(r);
        }
    }
    motion.raw = Some(RawChannels { width, values: raw, angle_unit: AngleUnit::Degrees, metres_per_unit: scale });
    skeleton.scale(scale);
    if options.skip_first_frame {
        motion.skip_first_frame();
    }
    Ok(Clip { skeleton, motion, units: UnitReport { unit, basis }, looping: None })
}

/// Size of the character in file units: the larger of the rest-pose height and the median
/// root height over the clip.
fn guess_unit(skeleton: &Skeleton, raw: &[f64], width: usize) -> LengthUnit {
    let rest = skeleton.rest_height();
    let mut root_heights: Vec<f64> = Vec::new();
    if let Some(k) =
        skeleton.joints.first().and_then(|j| j.channels.iter().position(|c| *c == Channel::Position(Axis::Y)))
        && width > 0
    {
        root_heights = raw.iter().skip(k).step_by(width).map(|v| v.abs()).collect();
    }
    root_heights.sort_by(f64::total_cmp);
    let median = root_heights.get(root_heights.len() / 2).copied().unwrap_or(0.0);
    LengthUnit::guess_from_size(rest.max(median))
}

fn parse_vec3(sc: &mut Scanner<'_>, what: &'static str) -> Result<Vec3, Error> {
    let mut v = [0.0; 3];
    for x in &mut v {
        *x = sc.expect_token("a number")?.finite(what)?;
    }
    Ok(Vec3::new(v[0], v[1], v[2]))
}

/// Reads a joint name to the end of the line; returns whether a `{` ended the line.
fn joint_name(sc: &mut Scanner<'_>, kw: Token<'_>) -> Result<(String, bool), Error> {
    let (rest, col) = sc.rest_of_line();
    let (name, brace) = match rest.strip_suffix('{') {
        Some(n) => (n.trim_end(), true),
        None => (rest, false),
    };
    if name.is_empty() {
        return Err(Error::parse(Location::at(kw.line, col), ErrorKind::UnexpectedEof("a joint name")));
    }
    Ok((name.to_string(), brace))
}

fn parse_channels(sc: &mut Scanner<'_>, joint: &mut Joint) -> Result<(), Error> {
    let count_tok = sc.expect_token("a channel count")?;
    let count = count_tok.usize()?;
    if count != 3 && count != 6 {
        return Err(count_tok.error(ErrorKind::ChannelCount(count)));
    }
    for _ in 0..count {
        let t = sc.expect_token("a channel name")?;
        let c = Channel::from_bvh_name(t.text).ok_or_else(|| t.error(ErrorKind::UnknownChannel(shorten(t.text))))?;
        if joint.channels.contains(&c) {
            return Err(t.error(ErrorKind::DuplicateChannel(shorten(t.text))));
        }
        joint.channels.push(c);
    }
    Ok(())
}

/// Parses `HIERARCHY ... ` up to the closing brace of the root, without recursion.
fn parse_hierarchy(sc: &mut Scanner<'_>) -> Result<Skeleton, Error> {
    sc.expect_word("HIERARCHY")?;
    let root_kw = sc.expect_word("ROOT")?;
    let mut joints: Vec<Joint> = Vec::new();
    let mut names: HashSet<String> = HashSet::new();
    // Stack of open joints (indices); a joint is "open" from its `{` to its `}`.
    let mut stack: Vec<usize> = Vec::new();
    let mut pending: Option<(Token<'_>, Option<usize>)> = Some((root_kw, None));

    loop {
        if let Some((kw, parent)) = pending.take() {
            let (name, has_brace) = joint_name(sc, kw)?;
            if !names.insert(name.clone()) {
                return Err(kw.error(ErrorKind::DuplicateJoint(shorten(&name))));
            }
            if !has_brace {
                sc.expect_word("{")?;
            }
            sc.expect_word("OFFSET")?;
            let offset = parse_vec3(sc, "OFFSET")?;
            let mut joint = Joint::new(name, parent, offset);
            sc.expect_word("CHANNELS")?;
            parse_channels(sc, &mut joint)?;
            stack.push(joints.len());
            joints.push(joint);
            continue;
        }
        let t = sc.expect_token("JOINT, End Site or }")?;
        let current = stack.last().copied();
        let kw = t.text.to_ascii_uppercase();
        match kw.as_str() {
            "JOINT" => pending = Some((t, current)),
            "END" => {
                sc.expect_word("Site")?;
                sc.expect_word("{")?;
                sc.expect_word("OFFSET")?;
                let site = parse_vec3(sc, "End Site OFFSET")?;
                sc.expect_word("}")?;
                let Some(j) = current.and_then(|c| joints.get_mut(c)) else {
                    return Err(t.expected("JOINT"));
                };
                if j.end_site.is_some() {
                    return Err(t.error(ErrorKind::DuplicateEndSite(shorten(&j.name))));
                }
                j.end_site = Some(site);
            }
            "}" => {
                stack.pop();
                if stack.is_empty() {
                    break;
                }
            }
            "ROOT" => return Err(t.error(ErrorKind::MultipleRoots)),
            _ => return Err(t.expected("JOINT, End Site or }")),
        }
    }
    if joints.iter().all(|j| j.channels.is_empty()) {
        return Err(Error::parse(Location::line(sc.line()), ErrorKind::NoChannels));
    }
    Ok(Skeleton { joints, up: UpAxis::Y, source: SourceFormat::Bvh })
}

/// Parses `MOTION`, the frame count and time, and the frame lines. Returns the raw values
/// (`frames × width`) and the frame time.
fn parse_motion(sc: &mut Scanner<'_>, skeleton: &Skeleton) -> Result<(Vec<f64>, f64), Error> {
    let t = sc.expect_token("MOTION")?;
    if t.text == "ROOT" {
        return Err(t.error(ErrorKind::MultipleRoots));
    }
    if !t.text.eq_ignore_ascii_case("MOTION") {
        return Err(t.expected("MOTION"));
    }
    // "Frames: N" or "Frames:N".
    let t = sc.expect_token("Frames:")?;
    let declared_tok = match t.text.strip_prefix("Frames:") {
        Some("") => sc.expect_token("a frame count")?,
        Some(rest) => Token { text: rest, col: t.col + 7, ..t },
        None => return Err(t.expected("Frames:")),
    };
    let declared = declared_tok.usize()?;
    // "Frame Time: t" or "Frame Time:t".
    sc.expect_word("Frame")?;
    let t = sc.expect_token("Time:")?;
    let time_tok = match t.text.strip_prefix("Time:") {
        Some("") => sc.expect_token("a frame time")?,
        Some(rest) => Token { text: rest, col: t.col + 5, ..t },
        None => return Err(t.expected("Time:")),
    };
    let frame_time = time_tok.f64()?;
    if !(frame_time.is_finite() && frame_time > 0.0) {
        return Err(time_tok.error(ErrorKind::BadFrameTime(frame_time)));
    }
    let (rest, col) = sc.rest_of_line();
    if !rest.is_empty() {
        return Err(Error::parse(
            Location::at(time_tok.line, col),
            ErrorKind::Expected { expected: "end of line", found: shorten(rest) },
        ));
    }

    let width = skeleton.channel_count();
    let labels: Vec<(usize, Channel)> =
        skeleton.joints.iter().enumerate().flat_map(|(i, j)| j.channels.iter().map(move |c| (i, *c))).collect();
    // Never trust the declared count for allocation: each value takes at least two bytes.
    let cap = declared.saturating_mul(width).min(sc.remaining() / 2 + 1);
    let mut raw: Vec<f64> = Vec::with_capacity(cap);
    let mut frame = 0usize;
    while let Some((line_no, line)) = sc.next_line() {
        if line.trim().is_empty() {
            continue;
        }
        if frame >= declared {
            return Err(Error::parse(Location::line(line_no), ErrorKind::FrameCount { declared, found: frame + 1 }));
        }
        let mut found = 0usize;
        for tok in line_tokens(line_no, line) {
            if found >= width {
                found += 1;
                continue;
            }
            let v = tok.f64()?;
            if !v.is_finite() {
                let field = match labels.get(found) {
                    Some(&(j, c)) => {
                        format!("{} {}", skeleton.joints.get(j).map_or("?", |j| j.name.as_str()), c.name())
                    }
                    None => format!("value {found}"),
                };
                return Err(tok.error(ErrorKind::NonFinite { frame, field }));
            }
            raw.push(v);
            found += 1;
        }
        if found != width {
            return Err(Error::parse(
                Location::line(line_no),
                ErrorKind::FrameLength { frame, expected: width, found },
            ));
        }
        frame += 1;
    }
    if frame != declared {
        return Err(Error::parse(sc.eof_location(), ErrorKind::FrameCount { declared, found: frame }));
    }
    Ok((raw, frame_time))
}

/// Options for writing BVH.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BvhWriteOptions {
    /// Length unit of the written file (Blender reads BVH numbers as its own units, metres).
    pub unit: LengthUnit,
    /// Digits after the decimal point for channel values and offsets.
    pub precision: usize,
    /// Write CRLF line endings instead of LF.
    pub crlf: bool,
}

impl Default for BvhWriteOptions {
    fn default() -> Self {
        BvhWriteOptions { unit: LengthUnit::Metre, precision: 6, crlf: false }
    }
}

/// The channels a joint gets in written BVH, and whether they are its own (so raw values can
/// guide the Euler solution).
fn write_channels(joint: &Joint) -> (Vec<Channel>, bool) {
    let own = &joint.channels;
    let valid = (own.len() == 3 || own.len() == 6)
        && own.iter().all(|c| matches!(c, Channel::Position(_) | Channel::Rotation(_)))
        && [Axis::X, Axis::Y, Axis::Z].iter().all(|a| own.contains(&Channel::Rotation(*a)));
    if valid {
        return (own.clone(), true);
    }
    let animated = joint.parent.is_none() || own.iter().any(|c| matches!(c, Channel::Position(_)));
    let mut chans = Vec::with_capacity(6);
    if animated {
        chans.extend([Axis::X, Axis::Y, Axis::Z].map(Channel::Position));
    }
    chans.extend([Axis::Z, Axis::X, Axis::Y].map(Channel::Rotation));
    (chans, false)
}

/// Joint indices in depth-first pre-order (children in index order), without recursion.
fn preorder(skeleton: &Skeleton) -> Vec<usize> {
    let n = skeleton.len();
    let mut children: Vec<Vec<usize>> = vec![Vec::new(); n];
    let mut roots = Vec::new();
    for (i, j) in skeleton.joints.iter().enumerate() {
        match j.parent.and_then(|p| children.get_mut(p)) {
            Some(c) => c.push(i),
            None => roots.push(i),
        }
    }
    let mut out = Vec::with_capacity(n);
    let mut stack: Vec<usize> = roots.into_iter().rev().collect();
    while let Some(i) = stack.pop() {
        out.push(i);
        if let Some(c) = children.get(i) {
            stack.extend(c.iter().rev());
        }
    }
    out
}

/// Writes a clip as BVH text.
///
/// Fails if the motion does not match the skeleton, the skeleton has several roots, or a value
/// is not finite.
pub fn write_bvh(skeleton: &Skeleton, motion: &Motion, options: &BvhWriteOptions) -> Result<String, Error> {
    let n = skeleton.len();
    if n == 0 || motion.joint_count != n {
        return Err(Error::Mismatch(format!("motion has {} joints, skeleton {}", motion.joint_count, n)));
    }
    if skeleton.joints.iter().filter(|j| j.parent.is_none()).count() != 1 {
        return Err(Error::Mismatch("BVH needs exactly one root joint".into()));
    }
    if !(motion.frame_time.is_finite() && motion.frame_time > 0.0) {
        return Err(Error::Mismatch(format!("frame time must be positive, got {}", motion.frame_time)));
    }
    let to_unit = 1.0 / options.unit.metres_per_unit();
    if !(to_unit.is_finite() && to_unit > 0.0) {
        return Err(Error::Mismatch("output unit scale must be positive".into()));
    }
    let prec = options.precision;
    let nl = if options.crlf { "\r\n" } else { "\n" };
    let order = preorder(skeleton);
    let chans: Vec<(Vec<Channel>, bool)> = skeleton.joints.iter().map(write_channels).collect();

    let num = |v: f64| -> Result<String, Error> {
        if v.is_finite() {
            // Avoid "-0.000000".
            let s = format!("{v:.prec$}");
            Ok(match s.strip_prefix('-') {
                Some(rest) if rest.bytes().all(|b| b == b'0' || b == b'.') => rest.to_string(),
                _ => s,
            })
        } else {
            Err(Error::Mismatch(format!("non-finite value {v} cannot be written")))
        }
    };
    let vec = |v: Vec3| -> Result<String, Error> {
        Ok(format!("{} {} {}", num(v.x * to_unit)?, num(v.y * to_unit)?, num(v.z * to_unit)?))
    };

    let mut out = String::new();
    out.push_str("HIERARCHY");
    out.push_str(nl);
    // Depth of each joint for indentation, and closing braces when leaving subtrees.
    let mut depth = vec![0usize; n];
    let mut open: Vec<usize> = Vec::new();
    for &i in &order {
        let joint = skeleton.joints.get(i).ok_or_else(|| Error::Mismatch("bad joint index".into()))?;
        // Close joints that are not ancestors of i.
        while let Some(&top) = open.last() {
            if Some(top) == joint.parent {
                break;
            }
            open.pop();
            close_joint(&mut out, skeleton, top, depth.get(top).copied().unwrap_or(0), &vec, nl)?;
        }
        let d = open.len();
        if let Some(slot) = depth.get_mut(i) {
            *slot = d;
        }
        let ind = "\t".repeat(d);
        let kw = if joint.parent.is_none() { "ROOT" } else { "JOINT" };
        let _ = write!(out, "{ind}{kw} {}{nl}{ind}{{{nl}", joint.name);
        let _ = write!(out, "{ind}\tOFFSET {}{nl}", vec(joint.offset)?);
        let (cs, _) = chans.get(i).ok_or_else(|| Error::Mismatch("bad joint index".into()))?;
        let names: Vec<&str> = cs.iter().filter_map(|c| c.bvh_name()).collect();
        let _ = write!(out, "{ind}\tCHANNELS {} {}{nl}", names.len(), names.join(" "));
        open.push(i);
    }
    while let Some(top) = open.pop() {
        close_joint(&mut out, skeleton, top, depth.get(top).copied().unwrap_or(0), &vec, nl)?;
    }

    let frames = motion.frame_count();
    let _ = write!(out, "MOTION{nl}Frames: {frames}{nl}");
    let _ = write!(out, "Frame Time: {:.8}{nl}", motion.frame_time);

    // Raw offsets per joint, usable as Euler hints when the raw layout matches the skeleton.
    let raw = motion.raw.as_ref().filter(|r| r.width == skeleton.channel_count());
    let mut raw_start = Vec::with_capacity(n);
    let mut acc = 0;
    for j in &skeleton.joints {
        raw_start.push(acc);
        acc += j.channels.len();
    }
    let mut prev: Vec<[f64; 3]> = vec![[0.0; 3]; n];
    let mut line = String::new();
    for f in 0..frames {
        let frame = motion.frame(f).ok_or_else(|| Error::Mismatch(format!("frame {f} missing")))?;
        let raw_frame = raw.and_then(|r| r.frame(f).map(|v| (v, r.angle_unit)));
        line.clear();
        for &i in &order {
            let (cs, own) = chans.get(i).ok_or_else(|| Error::Mismatch("bad joint".into()))?;
            let t = frame.translations.get(i).copied().unwrap_or_default();
            let q = frame.rotations.get(i).copied().unwrap_or_default();
            let axes: Vec<Axis> = cs
                .iter()
                .filter_map(|c| match c {
                    Channel::Rotation(a) => Some(*a),
                    _ => None,
                })
                .collect();
            let order_e = EulerOrder::new([
                axes.first().copied().unwrap_or(Axis::Z),
                axes.get(1).copied().unwrap_or(Axis::X),
                axes.get(2).copied().unwrap_or(Axis::Y),
            ])
            .unwrap_or(EulerOrder::ZXY);
            let mut hint = prev.get(i).copied().unwrap_or_default();
            if let (true, Some((vals, unit))) = (*own, raw_frame) {
                let base = raw_start.get(i).copied().unwrap_or(0);
                let mut k = 0;
                for (c_i, c) in cs.iter().enumerate() {
                    if let Channel::Rotation(_) = c
                        && let (Some(v), Some(h)) = (vals.get(base + c_i), hint.get_mut(k))
                    {
                        *h = unit.to_radians(*v);
                        k += 1;
                    }
                }
            }
            let q = q.normalized().unwrap_or(Quat::IDENTITY);
            let angles = order_e.from_quat_near(q, hint);
            if let Some(p) = prev.get_mut(i) {
                *p = angles;
            }
            let mut k = 0;
            for c in cs {
                let v = match *c {
                    Channel::Position(a) => t.get(a) * to_unit,
                    Channel::Rotation(_) => {
                        let a = angles.get(k).copied().unwrap_or(0.0).to_degrees();
                        k += 1;
                        a
                    }
                    _ => 0.0,
                };
                if !line.is_empty() {
                    line.push(' ');
                }
                line.push_str(&num(v).map_err(|_| {
                    Error::Mismatch(format!(
                        "frame {f}: non-finite value for joint `{}`",
                        skeleton.joints.get(i).map_or("?", |j| j.name.as_str())
                    ))
                })?);
            }
        }
        out.push_str(&line);
        out.push_str(nl);
    }
    Ok(out)
}

fn close_joint(
    out: &mut String,
    skeleton: &Skeleton,
    i: usize,
    depth: usize,
    vec: &dyn Fn(Vec3) -> Result<String, Error>,
    nl: &str,
) -> Result<(), Error> {
    let ind = "\t".repeat(depth);
    if let Some(site) = skeleton.joints.get(i).and_then(|j| j.end_site) {
        let _ = write!(out, "{ind}\tEnd Site{nl}{ind}\t{{{nl}{ind}\t\tOFFSET {}{nl}{ind}\t}}{nl}", vec(site)?);
    }
    let _ = write!(out, "{ind}}}{nl}");
    Ok(())
}

/// Writes a clip to a BVH file.
pub fn write_bvh_file(
    path: impl AsRef<Path>,
    skeleton: &Skeleton,
    motion: &Motion,
    options: &BvhWriteOptions,
) -> Result<(), Error> {
    let path = path.as_ref();
    let text = write_bvh(skeleton, motion, options)?;
    std::fs::write(path, text).map_err(|source| Error::Io { path: path.to_path_buf(), source })
}

#[cfg(test)]
mod tests {
    use super::*;

    const SMALL: &str = "HIERARCHY
ROOT hips
{
  OFFSET 0 0 0
  CHANNELS 6 Xposition Yposition Zposition Zrotation Xrotation Yrotation
  JOINT leg
  {
    OFFSET 10 -40 0
    CHANNELS 3 Xrotation Yrotation Zrotation
    End Site
    {
      OFFSET 0 -40 0
    }
  }
  JOINT spine
  {
    OFFSET 0 20 0
    CHANNELS 3 Yrotation Xrotation Zrotation
    End Site
    {
      OFFSET 0 50 0
    }
  }
}
MOTION
Frames: 2
Frame Time: 0.5
0 90 0 0 0 0 0 0 0 0 0 0
1 90 2 90 0 0 0 0 90 90 0 0
";

    fn parse(s: &str) -> Result<Clip, Error> {
        parse_bvh(s.as_bytes(), &BvhOptions::default())
    }

    #[test]
    fn parses_small_file_and_guesses_centimetres() {
        let c = parse(SMALL).unwrap();
        assert_eq!(c.skeleton.len(), 3);
        assert_eq!(c.motion.frame_count(), 2);
        assert_eq!(c.units.unit, LengthUnit::Centimetre);
        assert_eq!(c.units.basis, UnitBasis::Guessed);
        assert_eq!(c.skeleton.joints[1].offset, Vec3::new(0.1, -0.4, 0.0));
        assert_eq!(c.motion.root_translation(1), Some(Vec3::new(0.01, 0.9, 0.02)));
    }

    #[test]
    fn explicit_unit_wins() {
        let opts = BvhOptions { unit: Some(LengthUnit::Metre), skip_first_frame: true };
        let c = parse_bvh(SMALL.as_bytes(), &opts).unwrap();
        assert_eq!(c.units.basis, UnitBasis::Explicit);
        assert_eq!(c.motion.frame_count(), 1);
        assert_eq!(c.skeleton.joints[1].offset, Vec3::new(10.0, -40.0, 0.0));
    }

    #[test]
    fn errors_name_line_and_reason() {
        let bad = SMALL.replace("CHANNELS 3 Xrotation Yrotation Zrotation", "CHANNELS 4 Xrotation");
        let e = parse(&bad).unwrap_err();
        assert_eq!(e.to_string(), "<input>:9:14: expected 3 or 6 channels, found 4");

        let bad = SMALL.replace("1 90 2 90 0 0 0 0 90 90 0 0", "1 90 2 90 0 nan 0 0 90 90 0 0");
        let e = parse(&bad).unwrap_err();
        assert_eq!(e.kind(), Some(&ErrorKind::NonFinite { frame: 1, field: "hips Yrotation".into() }));
        assert_eq!(e.location().map(|l| l.line), Some(29));

        let bad = SMALL.replace("Frames: 2", "Frames: 3");
        assert!(matches!(parse(&bad).unwrap_err().kind(), Some(ErrorKind::FrameCount { declared: 3, found: 2 })));
        let bad = SMALL.replace("0 90 0 0 0 0 0 0 0 0 0 0", "0 90 0 0 0 0 0 0 0 0 0");
        assert!(matches!(
            parse(&bad).unwrap_err().kind(),
            Some(ErrorKind::FrameLength { frame: 0, expected: 12, found: 11 })
        ));
    }

    #[test]
    fn crlf_equals_lf() {
        let crlf = SMALL.replace('\n', "\r\n");
        assert_eq!(parse(SMALL).unwrap(), parse(&crlf).unwrap());
    }

    #[test]
    fn write_then_parse_keeps_angles() {
        let c = parse(SMALL).unwrap();
        let text = write_bvh(&c.skeleton, &c.motion, &BvhWriteOptions::default()).unwrap();
        let back = parse(&text).unwrap();
        assert_eq!(back.units.unit, LengthUnit::Metre);
        assert_eq!(back.skeleton.len(), 3);
        let (a, b) = (c.motion.raw.unwrap(), back.motion.raw.unwrap());
        assert_eq!(a.values.len(), b.values.len());
        // Root positions are now metres; compare the angles (channels 3..12).
        for f in 0..2 {
            let (fa, fb) = (a.frame(f).unwrap(), b.frame(f).unwrap());
            for k in 3..12 {
                assert!((fa[k] - fb[k]).abs() < 1e-6, "frame {f} channel {k}");
            }
        }
    }
}
