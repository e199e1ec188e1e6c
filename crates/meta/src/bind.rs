//! Prop binding: the props a frozen skill observes are named after its training scene (lift's
//! `"box"` and `"pedestal"`); in a scenario each such name resolves to one of the scenario's
//! props. A name the scenario's `bind` map lists resolves as it says (a prop of another name,
//! or a task role such as the warehouse's focal pedestal); any other name means the scenario's
//! prop of that name, and a name that is neither is a located error naming the skill.
//!
//! Role bindings change during an episode; [`SkillProps::refresh`] re-reads them from the task
//! state when a skill starts playing, writing into a buffer sized once (no allocation per tick).

use repertoire_scenes::scenario::PropBinding;
use repertoire_scenes::{Feature, ObservationLayout, WorldModel};

use crate::error::{MetaError, Result};
use crate::task::{TaskSpec, TaskState};

/// Where one prop slot of a skill's observation reads from in a scenario.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum BoundProp {
    /// Always this prop (index into the scene's props).
    Prop(usize),
    /// The warehouse's focal pedestal when the skill started playing.
    Focal,
}

/// A skill's prop slots in one scenario, and the props they read now.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct SkillProps {
    /// One per prop feature of the skill's observation, in feature order.
    pub slots: Vec<BoundProp>,
    /// The prop each slot reads now (what [`repertoire_scenes::World::observe_props`] takes).
    pub ids: Vec<usize>,
}

impl SkillProps {
    /// Lays out skill `skill`'s observation `features` in `model`'s scenario, resolving each prop
    /// feature through the scenario's `bind` map (task roles against `task`). An unbound name
    /// the scenario has no prop of is an error located at the skill in the scenario file.
    pub fn resolve(
        model: &WorldModel,
        task: &TaskSpec,
        skill: &str,
        features: &[Feature],
    ) -> Result<(ObservationLayout, Self)> {
        let file = &model.scenario;
        let bind = &file.scenario.bind;
        let mut slots = Vec::new();
        for f in features {
            let (Feature::PropPose(name) | Feature::PropVelocity(name) | Feature::PropSize(name)) = f else { continue };
            let slot = match bind.get(name) {
                Some(PropBinding::Prop(other)) => model.prop_id(other).map(BoundProp::Prop),
                Some(PropBinding::Focal) => task.focal_home().map(|_| BoundProp::Focal),
                None => model.prop_id(name).map(BoundProp::Prop),
            };
            let Some(slot) = slot else {
                let known: Vec<&str> = model.props.iter().map(|p| p.name.as_str()).collect();
                let why = match bind.get(name) {
                    Some(PropBinding::Focal) => format!(
                        "binds to Focal, which its {} task does not supply (only the warehouse does)",
                        task.name()
                    ),
                    Some(PropBinding::Prop(other)) => format!("binds to `{other}`, which is not one of its props"),
                    None => "neither has as a prop nor binds".to_string(),
                };
                let roles = if matches!(task, TaskSpec::Warehouse(_)) {
                    format!(" or `bind: {{\"{name}\": Focal}}`")
                } else {
                    String::new()
                };
                let message = format!(
                    "skill `{skill}` observes prop `{name}` ({}), which scenario `{}` {why} (props: {}); add \
                     `bind: {{\"{name}\": Prop(\"<one of them>\")}}`{roles} to the scenario",
                    f.name(),
                    file.scenario.name,
                    if known.is_empty() { "none".to_string() } else { known.join(", ") },
                );
                return Err(MetaError::Scene(file.invalid(Some(skill), message)));
            };
            slots.push(slot);
        }
        let ids: Vec<usize> = slots
            .iter()
            .map(|slot| match slot {
                BoundProp::Prop(id) => *id,
                BoundProp::Focal => task.focal_home().unwrap_or(0),
            })
            .collect();
        let mut next = ids.iter();
        let layout = ObservationLayout::with_props(model, features, |f, _| {
            next.next().copied().ok_or_else(|| {
                repertoire_scenes::SceneError::Usage(format!("observation feature {}: no prop slot", f.name()))
            })
        })?;
        Ok((layout, SkillProps { slots, ids }))
    }

    /// Whether any slot follows a task role (and so needs [`SkillProps::refresh`]).
    pub fn has_roles(&self) -> bool {
        self.slots.iter().any(|s| !matches!(s, BoundProp::Prop(_)))
    }

    /// Re-reads the role slots from the episode's task state into `ids` (same length as the
    /// slots; no allocation).
    pub fn refresh(&self, task: &TaskSpec, state: &TaskState, ids: &mut [usize]) {
        for (id, slot) in ids.iter_mut().zip(&self.slots) {
            *id = match slot {
                BoundProp::Prop(p) => *p,
                BoundProp::Focal => state.focal_prop(task).unwrap_or(*id),
            };
        }
    }
}

/// The prop names a skill's observation reads (its `PropPose`, `PropVelocity` and `PropSize` features), in
/// feature order.
pub fn observed_props(features: &[Feature]) -> impl Iterator<Item = &str> {
    features.iter().filter_map(|f| match f {
        Feature::PropPose(p) | Feature::PropVelocity(p) | Feature::PropSize(p) => Some(p.as_str()),
        _ => None,
    })
}

/// The keys of `bind` that none of `observed` (the prop names the graph's skills observe)
/// reads, in key order: a typo, or a binding for a skill the graph leaves out. Such an entry
/// does nothing, so the meta environment warns about it.
pub fn unused_bindings<'a>(
    bind: &'a std::collections::BTreeMap<String, PropBinding>,
    observed: &[&str],
) -> Vec<&'a str> {
    bind.keys().map(String::as_str).filter(|k| !observed.contains(k)).collect()
}
