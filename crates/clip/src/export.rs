//! Exporting a recorded rollout ([`Recording`]) for other tools: BVH (Blender, Maya, game
//! engines) and NumPy (`.npy` of qpos, `frames × nq` float64).
//!
//! BVH is y-up by convention, so the z-up body is turned about +x by −90° (x stays forward,
//! z up becomes y up, y left becomes −z). Each body of the character becomes a joint: its
//! offset is the body's position in its parent (from the MJCF), its rotation the composition of
//! the body's own orientation and its joints' rotations in model order (`R = Q·R₁·R₂·R₃`), the
//! same product MuJoCo's kinematics forms. The channel order follows the body's hinge axes
//! (`abdomen_z, _y, _x` → `Yrotation Zrotation Xrotation` after the axis change), so the
//! written Euler angles are the hinge angles themselves (up to sign) where the axes allow.
//! Slide joints and hinges anchored off the body's origin move a body in ways BVH offsets
//! cannot hold; they are left out (a note says which).

use std::path::Path;

use repertoire_mocap::{Axis, BvhWriteOptions, Channel, Joint, Motion, Quat, Skeleton, SourceFormat, UpAxis, Vec3};
use repertoire_scenes::Recording;
use repertoire_scenes::record::{BodyInfo, write_atomic};

use crate::error::{ClipError, Result};
use crate::io::npy_bytes;

/// The turn from the body's z-up frame to BVH's y-up frame: −90° about +x.
fn to_y_up() -> Quat {
    let h = std::f64::consts::FRAC_1_SQRT_2;
    Quat::new(h, -h, 0.0, 0.0)
}

/// A point or direction of the z-up body in the y-up BVH frame.
pub fn point_to_y_up(v: [f64; 3]) -> Vec3 {
    Vec3::new(v[0], v[2], -v[1])
}

/// A rotation of the z-up body expressed in the y-up BVH frame (`C·q·C⁻¹`).
pub fn rotation_to_y_up(q: Quat) -> Quat {
    let c = to_y_up();
    c * q * c.conjugate()
}

/// A rotation of the y-up BVH frame back in the z-up body's frame.
pub fn rotation_from_y_up(q: Quat) -> Quat {
    let c = to_y_up();
    c.conjugate() * q * c
}

fn quat(q: [f64; 4]) -> Quat {
    Quat::new(q[0], q[1], q[2], q[3])
}

/// The BVH axis a body-frame hinge axis turns into, when it is a coordinate axis.
fn bvh_axis(axis: [f64; 3]) -> Option<Axis> {
    let v = point_to_y_up(axis);
    let n = v.norm();
    [Axis::X, Axis::Y, Axis::Z].into_iter().find(|&a| (v.get(a).abs() - n).abs() < 1e-9 * n.max(1.0))
}

/// Rotation channels for a body: its hinge axes in order, then the missing axes.
fn rotation_order(body: &BodyInfo) -> Vec<Axis> {
    let mut order: Vec<Axis> = Vec::new();
    for j in body.joints.iter().filter(|j| j.kind == "hinge") {
        match bvh_axis(j.axis) {
            Some(a) if !order.contains(&a) => order.push(a),
            Some(_) => {}
            None => return vec![Axis::Z, Axis::X, Axis::Y],
        }
    }
    for a in [Axis::Z, Axis::X, Axis::Y] {
        if !order.contains(&a) {
            order.push(a);
        }
    }
    order
}

/// Local rotation of `body` (in its parent's frame, z-up) for one frame's qpos.
pub fn local_rotation(body: &BodyInfo, qpos: &[f64]) -> Quat {
    let mut q = quat(body.quat);
    for j in &body.joints {
        let a = j.qpos;
        match j.kind.as_str() {
            "hinge" => q = q * Quat::from_axis_angle(Vec3::new(j.axis[0], j.axis[1], j.axis[2]), qpos[a]),
            "ball" => q = q * quat([qpos[a], qpos[a + 1], qpos[a + 2], qpos[a + 3]]),
            "free" => q = quat([qpos[a + 3], qpos[a + 4], qpos[a + 5], qpos[a + 6]]),
            _ => {}
        }
    }
    q.normalized().unwrap_or(Quat::IDENTITY)
}

/// The character of `rec` as a BVH skeleton and motion (y-up, metres), with notes on what
/// BVH cannot hold.
pub fn to_bvh(rec: &Recording) -> Result<(Skeleton, Motion, Vec<String>)> {
    let h = &rec.header;
    let bodies: Vec<usize> = (0..h.bodies.len()).filter(|&b| h.bodies[b].character).collect();
    if bodies.first() != Some(&h.root) {
        return Err(ClipError::Usage(format!(
            "the recording's character does not start at its root body `{}`",
            h.bodies.get(h.root).map_or("?", |b| b.name.as_str())
        )));
    }
    let mut notes = Vec::new();
    let mut joints = Vec::with_capacity(bodies.len());
    for (i, &b) in bodies.iter().enumerate() {
        let body = &h.bodies[b];
        let parent = if i == 0 { None } else { body.parent.and_then(|p| bodies.iter().position(|&x| x == p)) };
        if i > 0 && parent.is_none() {
            return Err(ClipError::Usage(format!("body `{}` is not under the character's root", body.name)));
        }
        let offset = if i == 0 { Vec3::ZERO } else { point_to_y_up(body.pos) };
        let mut joint = Joint::new(body.name.clone(), parent, offset);
        if i == 0 {
            joint.channels.extend([Axis::X, Axis::Y, Axis::Z].map(Channel::Position));
        }
        joint.channels.extend(rotation_order(body).into_iter().map(Channel::Rotation));
        for j in body.joints.iter().filter(|j| j.kind == "slide") {
            notes.push(format!("slide joint `{}` of `{}` is left out (BVH offsets are fixed)", j.name, body.name));
        }
        joints.push(joint);
    }
    // End sites for leaves: past the body's farthest geom centre, or a short way along the bone.
    for i in 0..joints.len() {
        if joints.iter().any(|j| j.parent == Some(i)) {
            continue;
        }
        let b = bodies[i];
        let norm = |p: &[f64; 3]| p.iter().map(|v| v * v).sum::<f64>();
        let geom = h
            .geoms
            .iter()
            .filter(|g| g.body == Some(b) && norm(&g.pos) > 1e-12)
            .max_by(|a, b| norm(&a.pos).total_cmp(&norm(&b.pos)));
        joints[i].end_site = Some(match geom {
            Some(g) => point_to_y_up(g.pos.map(|v| 2.0 * v)),
            None => {
                let o = joints[i].offset;
                if o.norm() > 1e-9 { o * (0.1 / o.norm()) } else { Vec3::new(0.0, 0.1, 0.0) }
            }
        });
    }
    let skeleton = Skeleton { joints, up: UpAxis::Y, source: SourceFormat::Other };

    let n = bodies.len();
    let mut motion = Motion::new(rec.dt(), n);
    let mut translations = vec![Vec3::ZERO; n];
    let mut rotations = vec![Quat::IDENTITY; n];
    let root = &h.bodies[h.root];
    let root_pos = root.joints.iter().find(|j| j.kind == "free").map(|j| j.qpos);
    for f in 0..rec.frames() {
        let q = rec.qpos_at(f);
        for (k, &b) in bodies.iter().enumerate() {
            translations[k] = skeleton.joints[k].offset;
            rotations[k] = rotation_to_y_up(local_rotation(&h.bodies[b], q));
        }
        translations[0] = match root_pos {
            Some(a) => point_to_y_up([q[a], q[a + 1], q[a + 2]]),
            None => {
                let (p, _) = rec.pose(f, h.root);
                point_to_y_up(p)
            }
        };
        motion.push_frame(&translations, &rotations);
    }
    Ok((skeleton, motion, notes))
}

/// Writes the character of `rec` as BVH to `path` (atomically); returns the notes of
/// [`to_bvh`].
pub fn write_bvh(rec: &Recording, path: &Path) -> Result<Vec<String>> {
    let (skeleton, motion, notes) = to_bvh(rec)?;
    let text = repertoire_mocap::write_bvh(&skeleton, &motion, &BvhWriteOptions::default())?;
    write_atomic(path, text.as_bytes())?;
    Ok(notes)
}

/// Writes the recording's qpos as a NumPy `.npy` file (float64, `frames × nq`), atomically.
pub fn write_npy(rec: &Recording, path: &Path) -> Result<()> {
    write_atomic(path, &npy_bytes(&rec.qpos, rec.frames(), rec.header.nq))?;
    Ok(())
}
