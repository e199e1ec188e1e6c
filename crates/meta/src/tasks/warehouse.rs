//! The warehouse task of Catch & Carry (Merel et al. 2020): GOTO → LIFT → CARRY → PUTDOWN →
//! GOTO …, each phase's success read from contacts, reward 1 per completed phase, failure when
//! the walker falls or the box touches the floor.
//!
//! | phase   | done when                                                                    |
//! |---------|------------------------------------------------------------------------------|
//! | GOTO    | the pelvis is within `reach_m` (horizontally) of the pedestal the box is on   |
//! | LIFT    | each hand touches the box and the box no longer touches that pedestal         |
//! | CARRY   | the pelvis is within `reach_m` of the target pedestal, both hands on the box  |
//! | PUTDOWN | the box touches the target pedestal at `rest_contacts` points or more         |
//!
//! After PUTDOWN the target becomes the box's pedestal and the next pedestal the target.

use repertoire_scenes::compose::yaw_quat;
use repertoire_scenes::scenario::{Prop, Warehouse, WarehousePhase};
use std::path::Path;
use std::sync::Arc;

use rand::Rng;
use repertoire_scenes::world::{HOLD_FIT_TOLERANCE_M, HOLD_SQUEEZE_M};
use repertoire_scenes::{World, WorldModel};
use repertoire_skill::library;
use repertoire_skill::pool::Pool;

use crate::error::{MetaError, Result};

/// The warehouse task resolved to prop indices of one scene.
#[derive(Debug, Clone, PartialEq)]
pub struct WarehouseSpec {
    /// The box (prop index).
    pub box_prop: usize,
    /// The pedestals (prop indices), in the scenario's order.
    pub pedestals: Vec<usize>,
    /// Position in `pedestals` of the one the box starts on.
    pub home: usize,
    /// Pelvis-to-pedestal reach of GOTO and CARRY (m).
    pub reach_m: f64,
    /// Box–pedestal contacts that make PUTDOWN.
    pub rest_contacts: usize,
    /// Phases an episode may start in.
    pub start_phases: Vec<WarehousePhase>,
    /// The box's full edge lengths before its per-episode scale (m).
    pub box_size: (f64, f64, f64),
    /// The scenario's `hold_from` skill, whose end states start CARRY and PUTDOWN episodes.
    pub hold_from: Option<String>,
    /// Those end states, once [`WarehouseSpec::load_hold_pool`] read them from a library
    /// (`None` before, and without `hold_from`: the fitted standing pose instead).
    pub hold_pool: Option<Arc<Pool>>,
}

impl WarehouseSpec {
    /// Resolves `task` in `world`'s scene (the scenario was validated, so names exist).
    pub fn new(model: &WorldModel, task: &Warehouse) -> Result<Self> {
        let id = |name: &str| {
            model.prop_id(name).ok_or_else(|| MetaError::Invalid(format!("the warehouse names no prop `{name}`")))
        };
        let box_prop = id(&task.box_)?;
        let pedestals = task.pedestals.iter().map(|p| id(p)).collect::<Result<Vec<_>>>()?;
        let Prop::Box(b) = &model.scenario.scenario.props[box_prop] else {
            return Err(MetaError::Invalid(format!("warehouse prop `{}` is not a box", task.box_)));
        };
        if task.start_phases.iter().any(|p| matches!(p, WarehousePhase::Carry | WarehousePhase::PutDown)) {
            holding_joints(model).map_err(|e| {
                MetaError::Scene(model.scenario.invalid(
                    Some("start_phases"),
                    format!("{e}; start this body's episodes in GOTO and LIFT only (`start_phases: [Goto, Lift]`)"),
                ))
            })?;
        }
        let home =
            b.on.as_deref().and_then(|on| task.pedestals.iter().position(|p| p == on)).ok_or_else(|| {
                MetaError::Invalid(format!("box `{}` does not start on a warehouse pedestal", task.box_))
            })?;
        Ok(WarehouseSpec {
            box_prop,
            pedestals,
            home,
            reach_m: task.reach_m,
            rest_contacts: task.rest_contacts,
            start_phases: task.start_phases.clone(),
            box_size: b.size,
            hold_from: task.hold_from.clone(),
            hold_pool: None,
        })
    }

    /// Reads the end states of the scenario's `hold_from` skill from `library` (nothing to do
    /// without one). A pool that is missing, empty or recorded on another body is an error
    /// naming the file.
    pub fn load_hold_pool(&mut self, model: &WorldModel, library: &Path) -> Result<()> {
        let Some(skill) = &self.hold_from else { return Ok(()) };
        let path = library::skill_dir(library, skill).join("end_poses.ron");
        let scenario = model.scenario.path.display();
        if !path.exists() {
            return Err(MetaError::Invalid(format!(
                "{scenario}: hold_from names skill `{skill}`, but {} does not exist; `repertoire skill eval` of \
                 `{skill}` records its successful end states there",
                path.display()
            )));
        }
        let pool = Pool::load(&path)?;
        if pool.states.is_empty() {
            return Err(MetaError::Invalid(format!(
                "{scenario}: hold_from's pool {} holds no states (`{skill}` succeeded in none of the trials that \
                 recorded it)",
                path.display()
            )));
        }
        if pool.body_hash != model.body.content_hash() {
            return Err(MetaError::Invalid(format!(
                "{scenario}: hold_from's pool {} was recorded on body {}, this scenario's body is {}",
                path.display(),
                pool.body_hash,
                model.body.content_hash()
            )));
        }
        self.hold_pool = Some(Arc::new(pool));
        Ok(())
    }
}

/// What the phase tests read from the world in one control tick.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct WarehouseFacts {
    /// Horizontal pelvis distance to the centre of the pedestal the box is on / came from (m).
    pub to_source_m: f64,
    /// Horizontal pelvis distance to the centre of the target pedestal (m).
    pub to_target_m: f64,
    /// Which hands (left, right) touch the box.
    pub hands_on_box: [bool; 2],
    /// Contacts between the box and its source pedestal.
    pub source_contacts: usize,
    /// Contacts between the box and the target pedestal.
    pub target_contacts: usize,
    /// The box touches the floor.
    pub box_on_floor: bool,
    /// The fall test counted a fall ([`World::has_fallen`]).
    pub fallen: bool,
}

impl WarehouseFacts {
    /// Reads the facts from `world` for source pedestal `source` and target `target` (indices
    /// into `spec.pedestals`).
    pub fn measure(world: &World, spec: &WarehouseSpec, source: usize, target: usize) -> Self {
        let contacts = world.contacts();
        let pelvis = world.pelvis_frame().pos;
        let placements = world.placements();
        let horizontal = |p: usize| {
            let at = placements[spec.pedestals[p]].pos;
            (pelvis[0] - at[0]).hypot(pelvis[1] - at[1])
        };
        WarehouseFacts {
            to_source_m: horizontal(source),
            to_target_m: horizontal(target),
            hands_on_box: contacts.hands_on_prop(spec.box_prop),
            source_contacts: world.prop_contact_count(spec.box_prop, spec.pedestals[source]),
            target_contacts: world.prop_contact_count(spec.box_prop, spec.pedestals[target]),
            box_on_floor: contacts.prop_on_floor(spec.box_prop),
            fallen: world.has_fallen(),
        }
    }

    /// Whether `phase`'s success test holds (the table in the module documentation).
    pub fn phase_done(&self, phase: WarehousePhase, spec: &WarehouseSpec) -> bool {
        let both_hands = self.hands_on_box == [true, true];
        match phase {
            WarehousePhase::Goto => self.to_source_m <= spec.reach_m,
            WarehousePhase::Lift => both_hands && self.source_contacts == 0 && !self.box_on_floor,
            WarehousePhase::Carry => both_hands && self.to_target_m <= spec.reach_m && !self.box_on_floor,
            WarehousePhase::PutDown => self.target_contacts >= spec.rest_contacts,
        }
    }

    /// Whether the episode has failed: the walker fell or the box touches the floor.
    pub fn failed(&self) -> bool {
        self.fallen || self.box_on_floor
    }
}

/// Judges one warehouse episode, tick by tick.
#[derive(Debug, Clone, PartialEq)]
pub struct WarehouseJudge {
    /// The phase being attempted.
    pub phase: WarehousePhase,
    /// The phase the episode started in.
    pub start_phase: WarehousePhase,
    /// Index into the pedestals of the box's pedestal (or the one it was lifted from).
    pub source: usize,
    /// Index into the pedestals of where the box goes.
    pub target: usize,
    /// Phases completed this episode.
    pub completed: u32,
    /// Phases completed since the last [`WarehouseJudge::take_reward`].
    pending: u32,
    /// The episode has failed (a fall or the box on the floor).
    pub failed: bool,
    /// The box was dropped onto the floor.
    pub dropped: bool,
}

impl WarehouseJudge {
    /// A judge starting in `phase` with the box on pedestal `source`, going to `target`.
    pub fn new(phase: WarehousePhase, source: usize, target: usize) -> Self {
        WarehouseJudge {
            phase,
            start_phase: phase,
            source,
            target,
            completed: 0,
            pending: 0,
            failed: false,
            dropped: false,
        }
    }

    /// The pedestal (index into the pedestals) the current phase is about: the box's during
    /// GOTO and LIFT, the target's during CARRY and PUTDOWN.
    pub fn focal(&self) -> usize {
        match self.phase {
            WarehousePhase::Goto | WarehousePhase::Lift => self.source,
            WarehousePhase::Carry | WarehousePhase::PutDown => self.target,
        }
    }

    /// Records one control tick's facts; returns whether a phase was completed on it.
    pub fn tick(&mut self, facts: &WarehouseFacts, spec: &WarehouseSpec) -> bool {
        if self.failed {
            return false;
        }
        if facts.failed() {
            self.failed = true;
            self.dropped = facts.box_on_floor;
            return false;
        }
        if !facts.phase_done(self.phase, spec) {
            return false;
        }
        if self.phase == WarehousePhase::PutDown {
            // The box now rests on the target: it becomes the source, the next pedestal the target.
            let n = spec.pedestals.len();
            self.source = self.target;
            self.target = (1..n).map(|k| (self.source + k) % n).next().unwrap_or(self.source);
        }
        self.phase = self.phase.next();
        self.completed += 1;
        self.pending += 1;
        true
    }

    /// Phases completed since the last call: the reward of one decision (1 per phase).
    pub fn take_reward(&mut self) -> f32 {
        std::mem::take(&mut self.pending) as f32
    }

    /// The judge's state as numbers (checkpoints).
    pub fn snapshot(&self) -> [f64; 8] {
        [
            self.phase.index() as f64,
            self.start_phase.index() as f64,
            self.source as f64,
            self.target as f64,
            f64::from(self.completed),
            f64::from(self.pending),
            f64::from(u8::from(self.failed)),
            f64::from(u8::from(self.dropped)),
        ]
    }

    /// Restores [`WarehouseJudge::snapshot`]'s output.
    pub fn restore(&mut self, s: &[f64]) {
        let phase = |v: f64| WarehousePhase::ALL[(v.max(0.0) as usize).min(3)];
        self.phase = phase(s[0]);
        self.start_phase = phase(s[1]);
        self.source = s[2] as usize;
        self.target = s[3] as usize;
        self.completed = s[4] as u32;
        self.pending = s[5] as u32;
        self.failed = s[6] != 0.0;
        self.dropped = s[7] != 0.0;
    }
}

/// The arm joints the holding pose moves, per side (left, right): the built-in humanoid's
/// `<side>_shoulder_y`, `<side>_shoulder_z` and `<side>_elbow` (indices into the body's joints).
/// A body without them is an error naming the first missing joint and the body.
pub fn holding_joints(model: &WorldModel) -> Result<[[usize; 3]; 2]> {
    let idx = &model.index;
    let joint = |name: String| {
        idx.joints.iter().position(|j| j.name == name).ok_or_else(|| {
            MetaError::Invalid(format!(
                "the body {} has no joint `{name}`: CARRY and PUTDOWN episodes start with the box put into \
                 the hands by a pose of the built-in humanoid's arm joints (`<side>_shoulder_y`, \
                 `<side>_shoulder_z`, `<side>_elbow`)",
                model.body.mjcf_path.display()
            ))
        })
    };
    let mut arms = [[0; 3]; 2];
    for (arm, side) in arms.iter_mut().zip(["left", "right"]) {
        *arm = [
            joint(format!("{side}_shoulder_y"))?,
            joint(format!("{side}_shoulder_z"))?,
            joint(format!("{side}_elbow"))?,
        ];
    }
    Ok(arms)
}

/// This episode's depth and width (m) of box or ball `b` (its x and y edges, or its diameter).
fn box_extent(world: &World, b: usize) -> Result<(f64, f64)> {
    match world.model().scenario.scenario.props.get(b) {
        Some(Prop::Box(_) | Prop::Ball(_)) => {
            let [depth, width, _] = world.prop_extent(b);
            Ok((depth, width))
        }
        _ => Err(MetaError::Invalid(format!("prop {b} is not a box or a ball"))),
    }
}

/// Stands the character at `(x, y)` facing `yaw` in one of `pool`'s states (drawn with `rng`),
/// keeping its motion, with box `b` between its hands, turned the way the hands face each other
/// and moving as the pelvis does.
pub fn place_from_pool(
    world: &mut World,
    pool: &Pool,
    b: usize,
    x: f64,
    y: f64,
    yaw: f64,
    rng: &mut impl Rng,
) -> Result<()> {
    let state = &pool.states[rng.random_range(0..pool.states.len())];
    state.apply(world, x, y, yaw).map_err(|e| MetaError::Invalid(format!("a hold_from state: {e}")))?;
    let (_, width) = box_extent(world, b)?;
    world.fit_hands_round(width);
    let idx = &world.model().index;
    let (l, r) = (world.body_position(idx.hands[0]), world.body_position(idx.hands[1]));
    let centre = [(l[0] + r[0]) / 2.0, (l[1] + r[1]) / 2.0, (l[2] + r[2]) / 2.0];
    let box_yaw = (-(l[0] - r[0])).atan2(l[1] - r[1]);
    let (s, c) = yaw.sin_cos();
    let v = state.velocity;
    let velocity = [c * v[0] - s * v[1], s * v[0] + c * v[1], v[2]];
    world.set_free_prop(b, centre, yaw_quat(box_yaw.to_degrees()), velocity, [0.0; 3])?;
    Ok(())
}

/// Stands the character at `(x, y)` facing `yaw` (radians) with its arms forward and free prop
/// `b` (a box or a ball) held between its hands, both touching it, everything at rest: the start
/// of a CARRY or PUTDOWN phase, a caught ball. The arm pose is searched over the shoulder twist and the elbow so
/// that the hands are as far apart as the box is wide; bodies without `*shoulder_y`,
/// `*shoulder_z` and `*elbow` joints on both sides ([`holding_joints`]; the warehouse checks
/// this when its scenario loads), or a box no pose fits, are an error.
pub fn place_holding(world: &mut World, b: usize, x: f64, y: f64, yaw: f64) -> Result<()> {
    let model = std::sync::Arc::clone(world.model());
    let (depth, width) = box_extent(world, b)?;
    let idx = &model.index;
    let arm = holding_joints(&model)?;
    let mj = model.mj_model();
    let hand_radius = |hand: usize| {
        (0..mj.geom_bodyid().len())
            .filter(|&g| mj.geom_bodyid()[g] as usize == hand)
            .map(|g| mj.geom_rbound()[g])
            .fold(0.0, f64::max)
    };
    let radii = [hand_radius(idx.hands[0]), hand_radius(idx.hands[1])];
    let standing = model.standing_qpos().to_vec();
    let root = [x, y, standing[idx.root_qpos + 2]];
    let quat = yaw_quat(yaw.to_degrees());
    let mut pose: Vec<f64> = idx.joints.iter().map(|j| standing[j.qpos]).collect();
    let want = width - 2.0 * HOLD_SQUEEZE_M;
    let (s, c) = yaw.sin_cos();
    // The hands' gap error of one arm pose (None when the hands are not level and in front).
    let mut try_pose = |world: &mut World, lift: f64, twist: f64, elbow: f64| -> Result<Option<(f64, Vec<f64>)>> {
        for (k, a) in arm.iter().enumerate() {
            let mirror = if k == 0 { 1.0 } else { -1.0 };
            let clamp = |j: usize, v: f64| v.clamp(idx.joints[j].range[0], idx.joints[j].range[1]);
            pose[a[0]] = clamp(a[0], lift.to_radians());
            pose[a[1]] = clamp(a[1], (mirror * twist).to_radians());
            pose[a[2]] = clamp(a[2], elbow.to_radians());
        }
        world.set_pose(root, quat, &pose)?;
        let (l, r) = (world.body_position(idx.hands[0]), world.body_position(idx.hands[1]));
        let gap = (l[0] - r[0]).hypot(l[1] - r[1]) - radii[0] - radii[1];
        // Both hands in front of the chest by more than half the box's depth, at one height.
        let forward = |p: [f64; 3]| c * (p[0] - x) + s * (p[1] - y);
        let ahead = forward(l).min(forward(r)) > 0.5 * depth + 0.12;
        let level = (l[2] - r[2]).abs() < 0.02;
        Ok((ahead && level).then(|| ((gap - want).abs(), pose.clone())))
    };
    let mut best: Option<(f64, Vec<f64>)> = None;
    let keep = |best: &mut Option<(f64, Vec<f64>)>, found: Option<(f64, Vec<f64>)>| {
        if let Some((err, p)) = found
            && best.as_ref().is_none_or(|(e, _)| err < *e)
        {
            *best = Some((err, p));
        }
    };
    for lift in [-60f64, -75.0, -45.0] {
        for twist in [90f64, -90.0] {
            // Coarse elbow steps of 4°, then 1° around the best of them.
            let mut coarse: Option<(f64, f64)> = None;
            for elbow in (0..=30).map(|k| f64::from(k) * 4.0) {
                if let Some((err, p)) = try_pose(world, lift, twist, elbow)? {
                    if coarse.is_none_or(|(e, _)| err < e) {
                        coarse = Some((err, elbow));
                    }
                    keep(&mut best, Some((err, p)));
                }
            }
            if let Some((_, centre)) = coarse {
                for elbow in (-3..=3).map(|k| centre + f64::from(k)).filter(|e| (0.0..=120.0).contains(e)) {
                    let found = try_pose(world, lift, twist, elbow)?;
                    keep(&mut best, found);
                }
            }
        }
        if best.as_ref().is_some_and(|(e, _)| *e < 0.25 * HOLD_FIT_TOLERANCE_M) {
            break; // a close fit at this shoulder angle; the others are fallbacks
        }
    }
    let Some((err, pose)) = best.filter(|(e, _)| *e < HOLD_FIT_TOLERANCE_M) else {
        return Err(MetaError::Invalid(format!(
            "place_holding: no arm pose puts the hands {width:.2} m apart around prop {b}"
        )));
    };
    tracing::trace!(err, "holding pose");
    world.set_pose(root, quat, &pose)?;
    let (l, r) = (world.body_position(idx.hands[0]), world.body_position(idx.hands[1]));
    let centre = [(l[0] + r[0]) / 2.0, (l[1] + r[1]) / 2.0, (l[2] + r[2]) / 2.0];
    let box_yaw = (-(l[0] - r[0])).atan2(l[1] - r[1]); // the box's +y from the right hand to the left
    world.set_free_prop(b, centre, yaw_quat(box_yaw.to_degrees()), [0.0; 3], [0.0; 3])?;
    let hands = world.contacts().hands_on_prop(b);
    if hands != [true, true] {
        return Err(MetaError::Invalid(format!("place_holding: prop {b} ended up touching hands {hands:?}")));
    }
    Ok(())
}
