//! The encoder's input: the next `k` reference frames expressed relative to the current body
//! (joint angles, root offset and heading change in the current heading frame, pitch and roll),
//! so the same motion asked of a body anywhere on the floor reads the same.

use repertoire_scenes::World;
use repertoire_scenes::math::wrap_angle;
use repertoire_scenes::obs::LayoutEntry;
use repertoire_skill::imitation::ImitationTask;
use repertoire_skill::reference::to_heading;

/// Values per reference frame besides the joint angles: root offset (3), heading change as
/// sin/cos (2), pitch and roll (2).
pub const ROOT_VALUES: usize = 7;

/// The layout of the reference features: per future frame `j = 1..=k`, the frame's joint
/// angles, its root offset from the pelvis in the current heading frame, sin/cos of its heading
/// relative to the current heading, and its pitch and roll.
pub fn reference_layout(k: usize, dof: usize) -> Vec<LayoutEntry> {
    let mut entries = Vec::with_capacity(4 * k);
    let mut offset = 0;
    for j in 1..=k {
        for (name, len) in [("joints", dof), ("root_offset", 3), ("heading", 2), ("pitch_roll", 2)] {
            entries.push(LayoutEntry { name: format!("ref{j}.{name}"), offset, len });
            offset += len;
        }
    }
    entries
}

/// Number of values in [`reference_layout`].
pub fn reference_size(k: usize, dof: usize) -> usize {
    k * (dof + ROOT_VALUES)
}

/// Writes the features of the `k` reference frames after `task`'s current phase, relative to
/// the character of `world`, into `out` (length [`reference_size`]).
pub fn reference_features(task: &ImitationTask, world: &World, k: usize, out: &mut [f32]) {
    let r = &task.settings().reference;
    let pelvis = world.pelvis_frame();
    let heading = pelvis.yaw();
    let per = r.dof + ROOT_VALUES;
    debug_assert_eq!(out.len(), k * per);
    for (j, dst) in out.chunks_exact_mut(per).enumerate() {
        let (f, root, h) = task.reference_ahead(j + 1);
        let (joints, rest) = dst.split_at_mut(r.dof);
        for (o, &a) in joints.iter_mut().zip(r.joints_at(f)) {
            *o = a as f32;
        }
        let d = to_heading(heading, [root[0] - pelvis.pos[0], root[1] - pelvis.pos[1], root[2] - pelvis.pos[2]]);
        let dh = wrap_angle(h - heading);
        let [pitch, roll] = r.pitch_roll[f];
        let values = [d[0], d[1], d[2], dh.sin(), dh.cos(), pitch, roll];
        for (o, v) in rest.iter_mut().zip(values) {
            *o = v as f32;
        }
    }
}
