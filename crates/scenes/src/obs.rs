//! Named observation features and their layout in a policy's input vector.
//!
//! A skill declares the features it observes; the [`ObservationLayout`] fixes their order, sizes
//! and offsets for one scene. The layout is recorded in skill manifests, so a skill refuses a
//! world whose layout differs.

use crate::error::{Result, SceneError};
use crate::world::{PropMount, World, WorldModel};
use serde::{Deserialize, Serialize};

/// One named group of observation values.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub enum Feature {
    /// Actuated joint angles (radians), map order.
    JointAngles,
    /// Actuated joint velocities (rad/s), map order.
    JointVelocities,
    /// Pelvis height above the floor (m).
    RootHeight,
    /// Root linear velocity in the heading frame (m/s; forward, left, up).
    RootVelocity,
    /// Pelvis pitch and roll (radians).
    PitchRoll,
    /// The root's angular velocity in the pelvis frame (rad/s; MuJoCo's free-joint qvel).
    RootAngularVelocity,
    /// Foot touch sensors as 0/1, map order.
    FootContacts,
    /// A prop's pose relative to the pelvis in the heading frame: dx, dy, dz, sin Δyaw, cos Δyaw.
    PropPose(String),
    /// A prop's linear velocity relative to the pelvis's, in the heading frame (m/s; forward,
    /// left, up): a ball in flight. Fixed props move with nothing, so theirs is minus the pelvis's.
    PropVelocity(String),
    /// A box's or ball's size this episode (m): its three edge lengths, or its diameter three
    /// times, after the scenario's per-episode scale. What a hand must close round.
    PropSize(String),
}

impl Feature {
    /// The feature's name in layouts and manifests.
    pub fn name(&self) -> String {
        match self {
            Feature::JointAngles => "joint_angles".into(),
            Feature::JointVelocities => "joint_velocities".into(),
            Feature::RootHeight => "root_height".into(),
            Feature::RootVelocity => "root_velocity".into(),
            Feature::PitchRoll => "pitch_roll".into(),
            Feature::RootAngularVelocity => "root_angular_velocity".into(),
            Feature::FootContacts => "foot_contacts".into(),
            Feature::PropPose(p) => format!("prop_pose:{p}"),
            Feature::PropVelocity(p) => format!("prop_velocity:{p}"),
            Feature::PropSize(p) => format!("prop_size:{p}"),
        }
    }

    /// The proprioceptive features every skill starts from.
    pub fn proprioception() -> Vec<Feature> {
        vec![
            Feature::JointAngles,
            Feature::JointVelocities,
            Feature::RootHeight,
            Feature::RootVelocity,
            Feature::PitchRoll,
            Feature::RootAngularVelocity,
            Feature::FootContacts,
        ]
    }
}

/// One entry of a layout: a feature's name and where its values sit.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct LayoutEntry {
    /// The feature's name.
    pub name: String,
    /// First index in the observation vector.
    pub offset: usize,
    /// Number of values.
    pub len: usize,
}

/// The features of an observation, in order, with their offsets for one scene.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ObservationLayout {
    /// Features in order.
    pub features: Vec<Feature>,
    /// Names, offsets and sizes.
    pub entries: Vec<LayoutEntry>,
    /// Total number of values.
    pub size: usize,
    #[serde(skip)]
    prop_ids: Vec<usize>,
}

impl ObservationLayout {
    /// Lays `features` out for `model`'s scene; a prop feature naming no prop is an error.
    pub fn new(model: &WorldModel, features: &[Feature]) -> Result<Self> {
        Self::with_props(model, features, |f, name| {
            model.prop_id(name).ok_or_else(|| {
                SceneError::Usage(format!(
                    "observation feature {}: no prop `{name}` in {}",
                    f.name(),
                    model.scenario.path.display()
                ))
            })
        })
    }

    /// Lays `features` out with each prop feature's prop chosen by `resolve(feature, name)`
    /// (a skill's prop bound to another prop of this scene); its error is passed on.
    pub fn with_props(
        model: &WorldModel,
        features: &[Feature],
        mut resolve: impl FnMut(&Feature, &str) -> Result<usize>,
    ) -> Result<Self> {
        let dof = model.index.dof();
        let mut entries = Vec::with_capacity(features.len());
        let mut prop_ids = Vec::new();
        let mut offset = 0;
        for f in features {
            let len = match f {
                Feature::JointAngles | Feature::JointVelocities => dof,
                Feature::RootHeight => 1,
                Feature::RootVelocity | Feature::RootAngularVelocity => 3,
                Feature::PitchRoll => 2,
                Feature::FootContacts => model.index.foot_touch.len(),
                Feature::PropPose(name) | Feature::PropVelocity(name) | Feature::PropSize(name) => {
                    let id = resolve(f, name)?;
                    if id >= model.props.len() {
                        return Err(SceneError::Usage(format!(
                            "observation feature {}: prop index {id} is out of range ({} props)",
                            f.name(),
                            model.props.len()
                        )));
                    }
                    if matches!(f, Feature::PropSize(_)) && !model.scenario.scenario.props[id].is_free() {
                        return Err(SceneError::Usage(format!(
                            "observation feature {}: prop `{}` is a {}; only a box's or a ball's size is observed",
                            f.name(),
                            model.props[id].name,
                            model.scenario.scenario.props[id].kind()
                        )));
                    }
                    prop_ids.push(id);
                    if matches!(f, Feature::PropPose(_)) { 5 } else { 3 }
                }
            };
            entries.push(LayoutEntry { name: f.name(), offset, len });
            offset += len;
        }
        Ok(Self { features: features.to_vec(), entries, size: offset, prop_ids })
    }

    /// The props the prop features read, in feature order (one per prop feature).
    pub fn prop_ids(&self) -> &[usize] {
        &self.prop_ids
    }

    /// The prop names the prop features were declared with, in feature order (the slots
    /// [`World::observe_props`] fills).
    pub fn prop_names(&self) -> impl Iterator<Item = &str> {
        self.features.iter().filter_map(|f| match f {
            Feature::PropPose(n) | Feature::PropVelocity(n) | Feature::PropSize(n) => Some(n.as_str()),
            _ => None,
        })
    }

    /// Checks that `other` (e.g. from a skill manifest) lays out the same values in the same
    /// places; the error names the first difference.
    pub fn ensure_same(&self, other: &ObservationLayout) -> Result<()> {
        for (i, (a, b)) in self.entries.iter().zip(&other.entries).enumerate() {
            if a != b {
                return Err(SceneError::Usage(format!(
                    "observation entry {i} differs: this world has {} ({} values at {}), expected {} ({} values at {})",
                    a.name, a.len, a.offset, b.name, b.len, b.offset
                )));
            }
        }
        if self.entries.len() != other.entries.len() {
            return Err(SceneError::Usage(format!(
                "observation has {} features here, {} expected",
                self.entries.len(),
                other.entries.len()
            )));
        }
        Ok(())
    }
}

impl World {
    /// A prop's linear velocity relative to the pelvis's, in the heading frame (forward, left,
    /// up; m/s). Fixed props do not move.
    pub fn prop_velocity_relative(&self, prop: usize) -> [f64; 3] {
        let qvel = self.data().qvel();
        let prop_v = match self.model().props[prop].mount {
            PropMount::Fixed { .. } => [0.0; 3],
            PropMount::Free { dof, .. } => [qvel[dof], qvel[dof + 1], qvel[dof + 2]],
        };
        let d = self.model().index.root_dof;
        let v = [prop_v[0] - qvel[d], prop_v[1] - qvel[d + 1], prop_v[2] - qvel[d + 2]];
        let (s, c) = self.heading().sin_cos();
        [c * v[0] + s * v[1], -s * v[0] + c * v[1], v[2]]
    }

    /// Writes the observation described by `layout` into `out` (length `layout.size`).
    pub fn observe(&self, layout: &ObservationLayout, out: &mut [f32]) {
        self.observe_props(layout, &layout.prop_ids, out);
    }

    /// Like [`World::observe`], with the prop features reading `props` (one prop index per prop
    /// feature, in order) instead of the layout's: a skill's prop bound per tick to another.
    pub fn observe_props(&self, layout: &ObservationLayout, props: &[usize], out: &mut [f32]) {
        debug_assert_eq!(out.len(), layout.size);
        debug_assert_eq!(props.len(), layout.prop_ids.len());
        let mut props = props.iter();
        let data = self.data();
        let idx = &self.model().index;
        for (f, e) in layout.features.iter().zip(&layout.entries) {
            let dst = &mut out[e.offset..e.offset + e.len];
            match f {
                Feature::JointAngles => {
                    for (o, j) in dst.iter_mut().zip(&idx.joints) {
                        *o = data.qpos()[j.qpos] as f32;
                    }
                }
                Feature::JointVelocities => {
                    for (o, j) in dst.iter_mut().zip(&idx.joints) {
                        *o = data.qvel()[j.dof] as f32;
                    }
                }
                Feature::RootHeight => dst[0] = self.root_height() as f32,
                Feature::RootVelocity => {
                    for (o, v) in dst.iter_mut().zip(self.root_velocity_heading()) {
                        *o = v as f32;
                    }
                }
                Feature::PitchRoll => {
                    let (p, r) = self.pitch_roll();
                    dst[0] = p as f32;
                    dst[1] = r as f32;
                }
                Feature::RootAngularVelocity => {
                    let d = idx.root_dof + 3;
                    for (o, &v) in dst.iter_mut().zip(&data.qvel()[d..d + 3]) {
                        *o = v as f32;
                    }
                }
                Feature::FootContacts => {
                    for (o, &adr) in dst.iter_mut().zip(&idx.foot_touch) {
                        *o = if data.sensordata()[adr] > 1.0 { 1.0 } else { 0.0 };
                    }
                }
                Feature::PropPose(_) => {
                    let id = *props.next().expect("one id per prop feature");
                    for (o, v) in dst.iter_mut().zip(self.prop_relative(id)) {
                        *o = v as f32;
                    }
                }
                Feature::PropVelocity(_) => {
                    let id = *props.next().expect("one id per prop feature");
                    for (o, v) in dst.iter_mut().zip(self.prop_velocity_relative(id)) {
                        *o = v as f32;
                    }
                }
                Feature::PropSize(_) => {
                    let id = *props.next().expect("one id per prop feature");
                    for (o, v) in dst.iter_mut().zip(self.prop_extent(id)) {
                        *o = v as f32;
                    }
                }
            }
        }
    }
}
