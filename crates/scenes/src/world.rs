//! The simulated world: one compiled scene shared by many [`World`]s that step in parallel.
//!
//! [`WorldModel`] is built once from a scenario (body + props + floor compiled by MuJoCo) and
//! resolves every name the world needs to an id. Each [`World`] owns its `mjData` (and, only when
//! a free prop's size or mass is drawn per episode, its own copy of the model) and offers what
//! skills and tasks need: reset to a pose, set the full state for reference-state
//! initialisation, step one control tick, named observations and contact queries.

use crate::body::{BodyDef, BodyIndex, compile};
use crate::compose::{scene_mjcf, yaw_quat};
use crate::error::{Result, SceneError};
use crate::fall::{FALL_STATE_LEN, Fall, FallMonitor, FallRule, FallSigns, Part, PropUse};
use crate::math::{Frame, wrap_angle};
use crate::scenario::{BodySource, Facing, Prop, ScenarioFile, Zone};
use mujoco_rs::prelude::*;
use rand::Rng;
use rayon::prelude::*;
use std::f64::consts::PI;
use std::sync::Arc;

/// How far each hand reaches into an object put between the hands (m): MuJoCo's soft contacts
/// then press it from both sides.
pub const HOLD_SQUEEZE_M: f64 = 0.015;

/// How far the hands' gap may be from an object's width less the squeeze before
/// [`World::fit_hands_round`] moves the arms (m).
pub const HOLD_FIT_TOLERANCE_M: f64 = 0.01;

/// How a prop is held in place.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum PropMount {
    /// Fixed (a mocap body): moved only between episodes.
    Fixed {
        /// Index into mocap_pos / mocap_quat.
        mocap: usize,
    },
    /// Free: a free joint moved by physics.
    Free {
        /// qpos address of its free joint.
        qpos: usize,
        /// qvel address of its free joint.
        dof: usize,
    },
}

/// A prop resolved to MuJoCo ids.
#[derive(Debug, Clone)]
pub struct PropIndex {
    /// The prop's name.
    pub name: String,
    /// Its body id.
    pub body: usize,
    /// How it is held.
    pub mount: PropMount,
    /// Its geoms.
    pub geoms: Vec<usize>,
    /// The geom that matters for tasks: the chair's seat, the pedestal's top, the box, the ball,
    /// the bucket's bottom.
    pub key_geom: usize,
    /// Height the fixed prop was built at (chair seat, pedestal top); lower draws sink it.
    pub built_height: f64,
}

/// Numbers per prop placement in a [`World::snapshot`].
const PLACEMENT_LEN: usize = 7;

/// A prop's placement in the current episode.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PropPlacement {
    /// Position of the prop's frame (fixed props: on the floor, free props: their centre).
    pub pos: [f64; 3],
    /// Heading in radians.
    pub yaw: f64,
    /// Height of its top surface (chair seat, pedestal top; free props: their top).
    pub top: f64,
    /// Size scale drawn for a free prop (1 otherwise).
    pub scale: f64,
    /// Mass drawn for a free prop (0 for fixed props).
    pub mass: f64,
}

/// One compiled scene, shared by any number of [`World`]s.
pub struct WorldModel {
    /// The scenario it was built from.
    pub scenario: ScenarioFile,
    /// The body and its map.
    pub body: BodyDef,
    /// The body map resolved to ids in the scene.
    pub index: BodyIndex,
    /// The composed MJCF that MuJoCo compiled.
    pub mjcf: String,
    /// Props in scenario order, resolved.
    pub props: Vec<PropIndex>,
    /// The floor geom: the scene's, or the body file's own ground plane when it brings one.
    pub floor_geom: usize,
    /// Whether the floor is the body file's own ground plane.
    pub own_floor: bool,
    /// The body's torque motors driven as PD servos ([`crate::body::MotorPd`]).
    pub pd_motors: Vec<crate::body::PdMotor>,
    /// How far the default pose was lowered onto the floor (m; negative: raised), by the body
    /// map's `stand_on_floor`.
    pub lowered_by: f64,
    model: Arc<MjModel>,
    geom_body: Vec<usize>,
    geom_prop: Vec<Option<usize>>,
    substeps: usize,
    /// Per model body, how the fall test's contact rules treat it.
    parts: Vec<Part>,
    /// Per prop, what the fall test lets touch it.
    prop_use: Vec<PropUse>,
    /// The pelvis height below which the fall test calls it low (m).
    pelvis_min: f64,
    /// The feet's lowest point above the floor in the standing pose (m).
    clearance: f64,
}

/// How far the feet's lowest point may be off the floor in the standing pose before a body is
/// refused as floating or sunken (m).
pub const SOLE_TOLERANCE_M: f64 = 0.02;

/// The lowest point of the geoms of the feet (their subtrees) at the model's default pose,
/// above the floor (z = 0).
pub fn sole_clearance(model: &MjModel, index: &BodyIndex) -> f64 {
    let parent: Vec<usize> = model.body_parentid().iter().map(|&p| p as usize).collect();
    let mut data = MjData::new(model);
    data.forward();
    let (types, sizes, bodies) = (model.geom_type(), model.geom_size(), model.geom_bodyid());
    let (pos, mat) = (data.geom_xpos(), data.geom_xmat());
    use mujoco_rs::wrappers::mj_model::MjtGeomBase as MjtGeom;
    let mut lowest = f64::INFINITY;
    for g in 0..bodies.len() {
        let b = bodies[g] as usize;
        if !index.feet.iter().any(|&f| crate::body::in_subtree(&parent, b, f)) {
            continue;
        }
        let (s, r) = (sizes[g], [mat[g][6], mat[g][7], mat[g][8]]);
        let reach = match types[g] {
            MjtGeom::mjGEOM_SPHERE => s[0],
            MjtGeom::mjGEOM_CAPSULE => r[2].abs() * s[1] + s[0],
            MjtGeom::mjGEOM_CYLINDER => r[2].abs() * s[1] + s[0] * (1.0 - r[2] * r[2]).max(0.0).sqrt(),
            MjtGeom::mjGEOM_BOX => r[0].abs() * s[0] + r[1].abs() * s[1] + r[2].abs() * s[2],
            MjtGeom::mjGEOM_ELLIPSOID => ((r[0] * s[0]).powi(2) + (r[1] * s[1]).powi(2) + (r[2] * s[2]).powi(2)).sqrt(),
            _ => model.geom_rbound()[g],
        };
        lowest = lowest.min(pos[g][2] - reach);
    }
    if lowest.is_finite() { lowest } else { 0.0 }
}

/// The pelvis's height in the model's default pose (m): what the fall rule's `pelvis_below`
/// is a fraction of.
pub fn standing_pelvis_height(model: &MjModel, index: &BodyIndex) -> f64 {
    let mut data = MjData::new(model);
    data.kinematics();
    data.xpos()[index.pelvis][2]
}

/// Where `body`'s map asks for it (`stand_on_floor`), moves `model`'s default pose up or
/// down until the feet's lowest point is on the floor. Returns how far it was lowered (m) and
/// the clearance left.
pub fn stand_on_floor(model: &mut MjModel, index: &BodyIndex, body: &BodyDef) -> (f64, f64) {
    let clearance = sole_clearance(model, index);
    if body.map.stand_on_floor && clearance.abs() > 1e-4 {
        model.qpos0_mut()[index.root_qpos + 2] -= clearance;
        (clearance, sole_clearance(model, index))
    } else {
        (0.0, clearance)
    }
}

impl ScenarioFile {
    /// The scenario's body: the built-in humanoid or its MJCF file and map, loaded.
    pub fn body_def(&self) -> Result<BodyDef> {
        match &self.scenario.body {
            BodySource::Humanoid => Ok(BodyDef::humanoid()),
            BodySource::Mjcf { file, map } => BodyDef::load(&self.resolve(file), &self.resolve(map)),
        }
    }
}

impl WorldModel {
    /// Builds the scene of `scenario`: loads its body, checks it alone, composes the scene and
    /// compiles it.
    pub fn build(scenario: ScenarioFile) -> Result<Self> {
        let body = scenario.body_def()?;
        let (alone, _) = body.check()?;
        let mjcf = scene_mjcf(&body, &scenario.scenario, crate::compose::ground_plane(&alone).is_some())?;
        let mut model = compile(&mjcf, &scenario.path)?;
        let pd_motors = crate::body::drive_motors_as_pd(&mut model, &body)?;
        let index = BodyIndex::resolve(&model, &body)?;
        // The first plane on the world body: the body file's own ground when it has one (the
        // scene then adds none, see compose::scene_mjcf), else the scene's floor.
        let floor_geom = crate::compose::ground_plane(&model)
            .ok_or_else(|| SceneError::Usage("the scene has no floor geom".into()))?;
        let own_floor = model.geom_matid()[floor_geom] < 0
            || model.name_to_id(MjtObjBase::mjOBJ_MATERIAL, "repertoire_grid")
                != Some(model.geom_matid()[floor_geom] as usize);

        let geom_body: Vec<usize> = model.geom_bodyid().iter().map(|&b| b as usize).collect();
        let mut geom_prop = vec![None; geom_body.len()];
        let mut props = Vec::new();
        for (i, prop) in scenario.scenario.props.iter().enumerate() {
            let name = prop.name();
            let body_id = model.name_to_id(MjtObjBase::mjOBJ_BODY, name).ok_or_else(|| {
                scenario.invalid(Some(name), format!("prop `{name}` has a name the body already uses"))
            })?;
            if index.is_character[body_id] {
                return Err(scenario.invalid(Some(name), format!("prop `{name}` has the name of a body part")));
            }
            let geoms: Vec<usize> = (0..geom_body.len()).filter(|&g| geom_body[g] == body_id).collect();
            for &g in &geoms {
                geom_prop[g] = Some(i);
            }
            let key = match prop {
                Prop::Chair(_) => "seat",
                Prop::Pedestal(_) => "top",
                Prop::Box(_) => "box",
                Prop::Ball(_) => "ball",
                Prop::Bucket(_) => "bottom",
            };
            let key_geom = model
                .name_to_id(MjtObjBase::mjOBJ_GEOM, &format!("{name}/{key}"))
                .ok_or_else(|| SceneError::Usage(format!("prop `{name}` lost its `{key}` geom")))?;
            let mount = if prop.is_free() {
                let j = model.body_jntadr()[body_id] as usize;
                PropMount::Free { qpos: model.jnt_qposadr()[j] as usize, dof: model.jnt_dofadr()[j] as usize }
            } else {
                PropMount::Fixed { mocap: model.body_mocapid()[body_id] as usize }
            };
            let built_height = match prop {
                Prop::Chair(c) => c.seat_height.max(),
                Prop::Pedestal(p) => p.height.max(),
                Prop::Bucket(_) => 0.02,
                Prop::Box(_) | Prop::Ball(_) => 0.0,
            };
            props.push(PropIndex { name: name.to_string(), body: body_id, mount, geoms, key_geom, built_height });
        }

        let substeps = scenario.scenario.rates.substeps();
        let parent: Vec<usize> = model.body_parentid().iter().map(|&p| p as usize).collect();
        let parts = crate::fall::parts(&index, &parent);
        let prop_use = scenario
            .scenario
            .props
            .iter()
            .map(|p| match p {
                Prop::Chair(_) => PropUse::Seat,
                Prop::Pedestal(_) | Prop::Bucket(_) => PropUse::Stand,
                Prop::Box(_) | Prop::Ball(_) => PropUse::Handled,
            })
            .collect();
        // A body map may ask for the default pose to be moved onto the floor (a third-party file
        // whose root stands at another height, used without an edit).
        let (lowered_by, clearance) = stand_on_floor(&mut model, &index, &body);
        let model = Arc::new(model);
        let pelvis_min = scenario.scenario.fall.pelvis_below * standing_pelvis_height(&model, &index);
        if clearance.abs() > SOLE_TOLERANCE_M {
            let (what, how) = if clearance > 0.0 { ("above", "lower") } else { ("below", "raise") };
            return Err(SceneError::Invalid {
                file: body.mjcf_path.clone(),
                loc: None,
                message: format!(
                    "in its default pose (every joint at 0) the lowest point of the feet is {:.1} cm {what} the floor: the \
                     character would {} at every start, and clips retargeted onto it would be judged against the wrong floor; \
                     {how} the root body's `pos` by {:.3} m in this file, or set `stand_on_floor: true` in its body map to \
                     have the default pose moved there (at most {:.0} cm off is taken as standing)",
                    100.0 * clearance.abs(),
                    if clearance > 0.0 { "drop" } else { "start inside the floor" },
                    clearance.abs(),
                    100.0 * SOLE_TOLERANCE_M
                ),
            });
        }
        Ok(Self {
            scenario,
            body,
            index,
            mjcf,
            props,
            floor_geom,
            own_floor,
            pd_motors,
            lowered_by,
            model,
            geom_body,
            geom_prop,
            substeps,
            parts,
            prop_use,
            pelvis_min,
            clearance,
        })
    }

    /// How far the lowest point of the feet is above the floor in the standing pose (m;
    /// negative: inside it), what `scene check` reports.
    pub fn sole_clearance(&self) -> f64 {
        self.clearance
    }

    /// The compiled MuJoCo model.
    pub fn mj_model(&self) -> &Arc<MjModel> {
        &self.model
    }

    /// Physics steps per control tick.
    pub fn substeps(&self) -> usize {
        self.substeps
    }

    /// Seconds per control tick.
    pub fn control_dt(&self) -> f64 {
        1.0 / f64::from(self.scenario.scenario.rates.control_hz)
    }

    /// What counts as a fall in this scene.
    pub fn fall_rule(&self) -> &FallRule {
        &self.scenario.scenario.fall
    }

    /// Index of the prop called `name`.
    pub fn prop_id(&self, name: &str) -> Option<usize> {
        self.props.iter().position(|p| p.name == name)
    }

    /// The standing pose: the model's default configuration (every joint at 0, feet on the floor).
    pub fn standing_qpos(&self) -> &[f64] {
        self.model.qpos0()
    }

    /// Turns off actuation (every actuator force is zero), for a limp body. Must be called
    /// before any world is made from this model.
    pub fn disable_actuation(&mut self) -> Result<()> {
        let model = Arc::get_mut(&mut self.model)
            .ok_or_else(|| SceneError::Usage("disable_actuation must come before worlds are made".into()))?;
        model.opt_mut().disableflags |= MjtDisableBit::mjDSBL_ACTUATION as i32;
        Ok(())
    }

    /// A new world of this scene, standing at the origin with nominal props.
    pub fn new_world(self: &Arc<Self>) -> World {
        World::new(Arc::clone(self))
    }
}

/// One simulated world: the character, the props and the physics state.
pub struct World {
    pub(crate) shared: Arc<WorldModel>,
    pub(crate) data: MjData<Arc<MjModel>>,
    placements: Vec<PropPlacement>,
    owns_model: bool,
    /// Whether the last change was a physics step rather than a state set by hand: MuJoCo's
    /// derived quantities (body poses, sensors, contacts) then belong to the state before the
    /// last substep, not to the present one.
    stepped: bool,
    /// The integration state ([`BEFORE_LAST`]) before the last substep of the last step, so a
    /// snapshot can be restored with the same derived quantities (see [`World::restore`]).
    before_last: Vec<f64>,
    /// The hands' grip level in [0, 1]: what [`World::set_grip`] wrote to the grip actuators'
    /// controls, kept to write again after MuJoCo's reset zeroes them.
    grip: f64,
    /// The fall test's running state ([`crate::fall`]).
    pub(crate) fall: FallMonitor,
}

/// What of MuJoCo's state [`World`] keeps from before a step's last substep: time, qpos, qvel,
/// activations and the solver's warm start (ctrl and mocap poses do not change within a step).
const BEFORE_LAST: u32 = MjtState::mjSTATE_TIME as u32
    | MjtState::mjSTATE_QPOS as u32
    | MjtState::mjSTATE_QVEL as u32
    | MjtState::mjSTATE_ACT as u32
    | MjtState::mjSTATE_WARMSTART as u32;

impl World {
    /// A world of `shared`'s scene, standing at the origin with nominal props.
    pub fn new(shared: Arc<WorldModel>) -> Self {
        let data = MjData::new(Arc::clone(&shared.model));
        let placements = shared
            .scenario
            .scenario
            .props
            .iter()
            .zip(&shared.props)
            .map(|(p, idx)| {
                let at = p.pose();
                let (x, y) = at.nominal_xy();
                PropPlacement {
                    pos: [x, y, 0.0],
                    yaw: at.yaw_deg.nominal().to_radians(),
                    top: idx.built_height,
                    scale: 1.0,
                    mass: 0.0,
                }
            })
            .collect();
        let before_last = vec![0.0; shared.model.state_size(BEFORE_LAST)];
        let mut world = Self {
            shared,
            data,
            placements,
            owns_model: false,
            stepped: false,
            before_last,
            grip: 0.0,
            fall: FallMonitor::default(),
        };
        world.forward();
        world.restart_fall_test();
        world
    }

    /// The shared scene.
    pub fn model(&self) -> &Arc<WorldModel> {
        &self.shared
    }

    /// MuJoCo's data, for anything this API does not cover.
    pub fn data(&self) -> &MjData<Arc<MjModel>> {
        &self.data
    }

    /// Simulated time in seconds since the last reset.
    pub fn time(&self) -> f64 {
        self.data.time()
    }

    /// Sets the simulated time (kinematic playback, where no step advances it).
    pub fn set_time(&mut self, seconds: f64) {
        self.data.set_time(seconds);
    }

    /// Where each prop is this episode.
    pub fn placements(&self) -> &[PropPlacement] {
        &self.placements
    }

    /// Starts an episode: draws the props, then stands the character at `(x, y)` facing `yaw`.
    pub fn reset(&mut self, rng: &mut impl Rng, x: f64, y: f64, yaw: f64) {
        self.data.reset();
        self.set_grip(self.grip); // MuJoCo's reset zeroes every control
        self.sample_props(rng);
        self.place_standing(x, y, yaw);
    }

    /// Draws every prop's pose, size and mass for a new episode (per the scenario's ranges).
    pub fn sample_props(&mut self, rng: &mut impl Rng) {
        let shared = Arc::clone(&self.shared);
        let props = &shared.scenario.scenario.props;
        let mut new_scales: Vec<(usize, f64, f64)> = Vec::new();
        for (i, prop) in props.iter().enumerate() {
            if prop.rests_on().is_some() {
                continue; // placed once its base is known, below
            }
            self.placements[i] = self.draw_placement(prop, &shared.props[i], None, rng, &mut new_scales);
        }
        for (i, prop) in props.iter().enumerate() {
            if let Some(base) = prop.rests_on() {
                let b = shared.prop_id(base).expect("validated reference");
                let base = self.placements[b];
                self.placements[i] = self.draw_placement(prop, &shared.props[i], Some(base), rng, &mut new_scales);
            }
        }
        if !new_scales.is_empty() {
            self.rescale_free_props(&new_scales);
        }
        for (i, idx) in shared.props.iter().enumerate() {
            let p = self.placements[i];
            let q = yaw_quat(p.yaw.to_degrees());
            match idx.mount {
                PropMount::Fixed { mocap } => {
                    self.data.mocap_pos_mut()[mocap] = p.pos;
                    self.data.mocap_quat_mut()[mocap] = q;
                }
                PropMount::Free { qpos, dof } => {
                    let qp = self.data.qpos_mut();
                    qp[qpos..qpos + 3].copy_from_slice(&p.pos);
                    qp[qpos + 3..qpos + 7].copy_from_slice(&q);
                    self.data.qvel_mut()[dof..dof + 6].fill(0.0);
                }
            }
        }
        self.forward();
    }

    fn draw_placement(
        &self,
        prop: &Prop,
        idx: &PropIndex,
        base: Option<PropPlacement>,
        rng: &mut impl Rng,
        rescale: &mut Vec<(usize, f64, f64)>,
    ) -> PropPlacement {
        let at = prop.pose();
        let (mut x, mut y) = at.sample_xy(rng);
        let z = at.z.sample(rng);
        let yaw = at.yaw_deg.sample(rng).to_radians();
        let floor = match base {
            Some(b) => {
                x = b.pos[0];
                y = b.pos[1];
                b.top
            }
            None => 0.0,
        };
        match prop {
            Prop::Chair(c) => {
                let h = c.seat_height.sample(rng);
                PropPlacement { pos: [x, y, h - idx.built_height], yaw, top: h, scale: 1.0, mass: 0.0 }
            }
            Prop::Pedestal(p) => {
                let h = p.height.sample(rng);
                PropPlacement { pos: [x, y, h - idx.built_height], yaw, top: h, scale: 1.0, mass: 0.0 }
            }
            Prop::Bucket(_) => PropPlacement { pos: [x, y, 0.0], yaw, top: idx.built_height, scale: 1.0, mass: 0.0 },
            Prop::Box(b) => {
                let (s, m) = (b.scale.sample(rng), b.mass.sample(rng));
                // A fixed scale other than 1 is applied too (the model is built at scale 1).
                if b.scale.is_random() || b.mass.is_random() || s != 1.0 {
                    rescale.push((idx.body, s, m));
                }
                let half = 0.5 * b.size.2 * s;
                PropPlacement { pos: [x, y, floor + z + half], yaw, top: floor + z + 2.0 * half, scale: s, mass: m }
            }
            Prop::Ball(b) => {
                let (s, m) = (b.scale.sample(rng), b.mass.sample(rng));
                // A fixed scale other than 1 is applied too (the model is built at scale 1).
                if b.scale.is_random() || b.mass.is_random() || s != 1.0 {
                    rescale.push((idx.body, s, m));
                }
                let r = b.radius * s;
                PropPlacement { pos: [x, y, floor + z + r], yaw, top: floor + z + 2.0 * r, scale: s, mass: m }
            }
        }
    }

    /// Gives this world its own copy of the model (once) and sets free props' size and mass.
    fn rescale_free_props(&mut self, changes: &[(usize, f64, f64)]) {
        let base = &self.shared.model;
        let mut model: MjModel = if self.owns_model { self.data.model().clone() } else { (**base).clone() };
        for &(body, scale, mass) in changes {
            let nominal_mass = base.body_mass()[body];
            let ratio = if nominal_mass > 0.0 { mass / nominal_mass } else { 1.0 };
            model.body_mass_mut()[body] = mass;
            let inertia = base.body_inertia()[body];
            model.body_inertia_mut()[body] = inertia.map(|v| v * ratio * scale * scale);
            for g in (0..self.shared.geom_body.len()).filter(|&g| self.shared.geom_body[g] == body) {
                model.geom_size_mut()[g] = base.geom_size()[g].map(|v| v * scale);
                model.geom_rbound_mut()[g] = base.geom_rbound()[g] * scale;
                model.geom_aabb_mut()[g] = base.geom_aabb()[g].map(|v| v * scale);
            }
        }
        // Recompute the constants MuJoCo derives from masses and inertias at compile time
        // (subtree masses, the mass matrix at qpos0, ...), as the compiler would have.
        // SAFETY: `model` is a valid, exclusively owned mjModel; the scratch mjData is made for
        // it, used only by mj_setConst and freed right after.
        unsafe {
            let m = model.ffi_mut() as *mut mujoco_rs::mujoco_c::mjModel;
            let d = mujoco_rs::mujoco_c::mj_makeData(m);
            if !d.is_null() {
                mujoco_rs::mujoco_c::mj_setConst(m, d);
                mujoco_rs::mujoco_c::mj_deleteData(d);
            }
        }
        self.data.swap_model(Arc::new(model));
        self.owns_model = true;
    }

    /// Moves prop `p` to `(x, y)` on its current base height, facing `yaw` (radians), for the
    /// rest of the episode (a skill that needs the chair where its clip sits).
    pub fn move_prop(&mut self, p: usize, x: f64, y: f64, yaw: f64) -> Result<()> {
        let Some(idx) = self.shared.props.get(p) else {
            return Err(SceneError::Usage(format!(
                "move_prop: no prop {p}; the scene has {}",
                self.shared.props.len()
            )));
        };
        if ![x, y, yaw].iter().all(|v| v.is_finite()) {
            return Err(SceneError::Usage("move_prop: the pose holds a NaN or infinite value".into()));
        }
        let placement = &mut self.placements[p];
        placement.pos[0] = x;
        placement.pos[1] = y;
        placement.yaw = yaw;
        let (pos, q) = (placement.pos, yaw_quat(yaw.to_degrees()));
        match idx.mount {
            PropMount::Fixed { mocap } => {
                self.data.mocap_pos_mut()[mocap] = pos;
                self.data.mocap_quat_mut()[mocap] = q;
            }
            PropMount::Free { qpos, dof } => {
                let qp = self.data.qpos_mut();
                qp[qpos..qpos + 3].copy_from_slice(&pos);
                qp[qpos + 3..qpos + 7].copy_from_slice(&q);
                self.data.qvel_mut()[dof..dof + 6].fill(0.0);
            }
        }
        self.forward();
        Ok(())
    }

    /// Sets free prop `p`'s full state for the rest of the episode: centre `pos`, orientation
    /// `quat` (w, x, y, z), linear velocity `linvel` and angular velocity `angvel` (world frame,
    /// m/s and rad/s): a box put into the hands, a thrown ball. Fixed props are refused.
    pub fn set_free_prop(
        &mut self,
        p: usize,
        pos: [f64; 3],
        quat: [f64; 4],
        linvel: [f64; 3],
        angvel: [f64; 3],
    ) -> Result<()> {
        let Some(idx) = self.shared.props.get(p) else {
            return Err(SceneError::Usage(format!(
                "set_free_prop: no prop {p}; the scene has {}",
                self.shared.props.len()
            )));
        };
        let PropMount::Free { qpos, dof } = idx.mount else {
            return Err(SceneError::Usage(format!("set_free_prop: prop `{}` is fixed in place", idx.name)));
        };
        if !pos.iter().chain(&quat).chain(&linvel).chain(&angvel).all(|v| v.is_finite()) {
            return Err(SceneError::Usage(format!(
                "set_free_prop: the state of `{}` holds a NaN or infinite value",
                idx.name
            )));
        }
        let norm = quat.iter().map(|v| v * v).sum::<f64>().sqrt();
        if norm < 1e-9 {
            return Err(SceneError::Usage(format!("set_free_prop: zero quaternion for `{}`", idx.name)));
        }
        let qp = self.data.qpos_mut();
        qp[qpos..qpos + 3].copy_from_slice(&pos);
        for (k, v) in quat.iter().enumerate() {
            qp[qpos + 3 + k] = v / norm;
        }
        // MuJoCo's free-joint velocity: linear in the world frame, angular in the body frame.
        let q = [quat[0] / norm, quat[1] / norm, quat[2] / norm, quat[3] / norm];
        let local = rotate_inverse(q, angvel);
        let qv = self.data.qvel_mut();
        qv[dof..dof + 3].copy_from_slice(&linvel);
        qv[dof + 3..dof + 6].copy_from_slice(&local);
        let placement = &mut self.placements[p];
        placement.pos = pos;
        self.forward();
        Ok(())
    }

    /// Number of contacts between any geoms of props `a` and `b` right now (a box resting on a
    /// pedestal touches it at four or more points).
    pub fn prop_contact_count(&self, a: usize, b: usize) -> usize {
        let gp = &self.shared.geom_prop;
        self.data
            .contact()
            .iter()
            .filter(|c| {
                let (p1, p2) = (gp[c.geom[0] as usize], gp[c.geom[1] as usize]);
                (p1 == Some(a) && p2 == Some(b)) || (p1 == Some(b) && p2 == Some(a))
            })
            .count()
    }

    /// The gap between the hands' surfaces (m): the distance between the hand bodies less the
    /// largest bounding radius of each hand's geoms.
    pub fn hand_gap(&self) -> f64 {
        let idx = &self.shared.index;
        let mj = &self.shared.model;
        let radius = |hand: usize| {
            (0..mj.geom_bodyid().len())
                .filter(|&g| mj.geom_bodyid()[g] as usize == hand)
                .map(|g| mj.geom_rbound()[g])
                .fold(0.0, f64::max)
        };
        let (l, r) = (self.body_position(idx.hands[0]), self.body_position(idx.hands[1]));
        let d = ((l[0] - r[0]).powi(2) + (l[1] - r[1]).powi(2) + (l[2] - r[2]).powi(2)).sqrt();
        d - radius(idx.hands[0]) - radius(idx.hands[1])
    }

    /// Fits the arms round an object `width` m wide held between the hands: when the hands'
    /// gap is more than [`HOLD_FIT_TOLERANCE_M`] from `width` less [`HOLD_SQUEEZE_M`] a side,
    /// [`World::fit_hand_gap`] spreads or closes them to it; otherwise they stay as they are.
    pub fn fit_hands_round(&mut self, width: f64) {
        let want = width - 2.0 * HOLD_SQUEEZE_M;
        if (self.hand_gap() - want).abs() > HOLD_FIT_TOLERANCE_M {
            self.fit_hand_gap(want);
        }
    }

    /// Spreads or closes the arms until the hands' surfaces are `gap` m apart ([`World::hand_gap`]),
    /// to hold an object of that width: both `<side>_shoulder_z` joints (the arms' swing in and
    /// out) turned by equal and opposite angles up to 0.8 rad within their ranges, then, if
    /// that is not enough, both `<side>_shoulder_x` joints the same way. Velocities, the root
    /// and the other joints are kept, and the PD targets follow the new pose. Returns the gap
    /// then left from `gap` (m; the best the joints allow), or `None` for a body without those
    /// joints (left as it was).
    pub fn fit_hand_gap(&mut self, gap: f64) -> Option<f64> {
        let idx = &self.shared.index;
        let joint = |name: &str| idx.joints.iter().find(|j| j.name == name).map(|j| (j.qpos, j.range));
        let pairs = [
            (joint("left_shoulder_z")?, joint("right_shoulder_z")?),
            (joint("left_shoulder_x")?, joint("right_shoulder_x")?),
        ];
        let mut left = self.hand_gap() - gap;
        for (a, b) in pairs {
            if left.abs() < 0.001 {
                break;
            }
            left = self.fit_pair(a, b, gap);
        }
        self.hold_pose();
        self.forward();
        Some(left)
    }

    /// [`World::fit_hand_gap`] with one pair of joints (qpos address and range each): the
    /// error left, the pair set to the best turn found.
    fn fit_pair(&mut self, a: (usize, [f64; 2]), b: (usize, [f64; 2]), gap: f64) -> f64 {
        let start = (self.data.qpos()[a.0], self.data.qpos()[b.0]);
        // Equal and opposite turns (the arms are mirror images); both signs are tried.
        let error_at = |world: &mut World, turn: f64| {
            let qp = world.data.qpos_mut();
            qp[a.0] = (start.0 - turn).clamp(a.1[0], a.1[1]);
            qp[b.0] = (start.1 + turn).clamp(b.1[0], b.1[1]);
            world.data.kinematics();
            world.hand_gap() - gap
        };
        let mut best = (error_at(self, 0.0), 0.0);
        let consider = |world: &mut World, turn: f64, best: &mut (f64, f64)| {
            let e = error_at(world, turn);
            if e.abs() < best.0.abs() {
                *best = (e, turn);
            }
        };
        for k in -16..=16 {
            consider(self, f64::from(k) * 0.05, &mut best);
        }
        let centre = best.1;
        for k in -10..=10 {
            consider(self, centre + f64::from(k) * 0.005, &mut best);
        }
        error_at(self, best.1)
    }

    /// Stands the character in the default pose at `(x, y)` on the floor, facing `yaw`
    /// (radians, counter-clockwise from +x), at rest.
    pub fn place_standing(&mut self, x: f64, y: f64, yaw: f64) {
        let idx = &self.shared.index;
        let qpos0 = self.shared.model.qpos0();
        let r = idx.root_qpos;
        let qp = self.data.qpos_mut();
        for j in &idx.joints {
            qp[j.qpos] = qpos0[j.qpos];
        }
        qp[r] = x;
        qp[r + 1] = y;
        qp[r + 2] = qpos0[r + 2];
        // Turned about z from the default orientation of the root (identity unless the free
        // root is a part other than the pelvis, or the file turns it).
        let q0 = [qpos0[r + 3], qpos0[r + 4], qpos0[r + 5], qpos0[r + 6]];
        qp[r + 3..r + 7].copy_from_slice(&crate::math::quat_mul(yaw_quat(yaw.to_degrees()), q0));
        self.data.qvel_mut()[idx.root_dof..idx.root_dof + 6].fill(0.0);
        for j in &idx.joints {
            self.data.qvel_mut()[j.dof] = 0.0;
        }
        self.hold_pose();
        self.forward();
        self.restart_fall_test();
    }

    /// Sets the character's pose: root position, root orientation (w x y z) and the actuated
    /// joint angles in map order; velocities are zeroed and PD targets set to the pose.
    pub fn set_pose(&mut self, root_pos: [f64; 3], root_quat: [f64; 4], joints: &[f64]) -> Result<()> {
        self.set_motion(root_pos, root_quat, joints, [0.0; 6], None)
    }

    /// Sets the character's pose and velocities, as reference-state initialisation needs:
    /// `root_vel` is the free joint's qvel (linear velocity in the world frame, angular velocity
    /// in the root's frame, MuJoCo's convention), `joint_vel` the actuated joints' velocities in
    /// map order (`None`: at rest). PD targets are set to the pose; the props are untouched.
    pub fn set_motion(
        &mut self,
        root_pos: [f64; 3],
        root_quat: [f64; 4],
        joints: &[f64],
        root_vel: [f64; 6],
        joint_vel: Option<&[f64]>,
    ) -> Result<()> {
        let idx = &self.shared.index;
        let dof = idx.dof();
        if joints.len() != dof || joint_vel.is_some_and(|v| v.len() != dof) {
            return Err(SceneError::Usage(format!(
                "set_motion: {} joint angles and {} velocities given, the body has {dof} actuated joints",
                joints.len(),
                joint_vel.map_or(dof, <[f64]>::len)
            )));
        }
        let all = root_pos.iter().chain(&root_quat).chain(joints).chain(&root_vel).chain(joint_vel.unwrap_or(&[]));
        if all.clone().any(|v| !v.is_finite()) {
            return Err(SceneError::Usage("set_motion: the state holds a NaN or infinite value".into()));
        }
        let r = idx.root_qpos;
        let qp = self.data.qpos_mut();
        qp[r..r + 3].copy_from_slice(&root_pos);
        qp[r + 3..r + 7].copy_from_slice(&root_quat);
        for (j, &a) in idx.joints.iter().zip(joints) {
            qp[j.qpos] = a;
        }
        let qv = self.data.qvel_mut();
        qv[idx.root_dof..idx.root_dof + 6].copy_from_slice(&root_vel);
        for (k, j) in idx.joints.iter().enumerate() {
            qv[j.dof] = joint_vel.map_or(0.0, |v| v[k]);
        }
        self.hold_pose();
        self.forward();
        self.restart_fall_test();
        Ok(())
    }

    /// Sets the full physics state (qpos and qvel of the whole scene, props included), as
    /// reference-state initialisation needs.
    pub fn set_state(&mut self, qpos: &[f64], qvel: &[f64]) -> Result<()> {
        let (nq, nv) = (self.data.qpos().len(), self.data.qvel().len());
        if qpos.len() != nq || qvel.len() != nv {
            return Err(SceneError::Usage(format!(
                "set_state: got {} qpos and {} qvel values, the scene has {nq} and {nv}",
                qpos.len(),
                qvel.len()
            )));
        }
        if qpos.iter().chain(qvel).any(|v| !v.is_finite()) {
            return Err(SceneError::Usage("set_state: the state holds a NaN or infinite value".into()));
        }
        self.data.qpos_mut().copy_from_slice(qpos);
        self.data.qvel_mut().copy_from_slice(qvel);
        self.hold_pose();
        self.forward();
        self.restart_fall_test();
        Ok(())
    }

    /// Length of [`World::snapshot`]'s output for this scene.
    pub fn snapshot_len(&self) -> usize {
        let d = &self.data;
        1 + d.qpos().len()
            + 2 * d.qvel().len()
            + d.act().len()
            + d.ctrl().len()
            + 7 * d.mocap_pos().len()
            + PLACEMENT_LEN * self.placements.len()
            + 1
            + self.before_last.len()
            + FALL_STATE_LEN
    }

    /// Everything that decides this world's future, as numbers: time, qpos, qvel, activations,
    /// PD targets, the solver's warm start, mocap poses and the props' placements (with free
    /// props' drawn sizes and masses), then whether the world was last stepped and, if so, its
    /// integration state before the last substep. [`World::restore`] of it makes what the world
    /// reports and its next steps identical, bit for bit.
    pub fn snapshot(&self, out: &mut Vec<f64>) {
        let d = &self.data;
        out.clear();
        out.push(d.time());
        out.extend_from_slice(d.qpos());
        out.extend_from_slice(d.qvel());
        out.extend_from_slice(d.act());
        out.extend_from_slice(d.ctrl());
        out.extend_from_slice(d.qacc_warmstart());
        out.extend(d.mocap_pos().iter().flatten());
        out.extend(d.mocap_quat().iter().flatten());
        for p in &self.placements {
            out.extend_from_slice(&p.pos);
            out.extend_from_slice(&[p.yaw, p.top, p.scale, p.mass]);
        }
        out.push(f64::from(u8::from(self.stepped)));
        if self.stepped {
            out.extend_from_slice(&self.before_last);
        } else {
            out.extend(std::iter::repeat_n(0.0, self.before_last.len()));
        }
        self.fall.snapshot(out);
    }

    /// Restores a [`World::snapshot`]; a snapshot of another scene (wrong length) or holding a
    /// NaN is refused and leaves the world untouched.
    pub fn restore(&mut self, state: &[f64]) -> Result<()> {
        if state.len() != self.snapshot_len() {
            return Err(SceneError::Usage(format!(
                "restore: the snapshot has {} values, this scene needs {}",
                state.len(),
                self.snapshot_len()
            )));
        }
        if let Some(k) = state.iter().position(|v| !v.is_finite()) {
            return Err(SceneError::Usage(format!("restore: snapshot value {k} is not a finite number")));
        }
        // The fall test's state closes the snapshot; a bad one is refused before anything changes.
        let mut fall = FallMonitor::default();
        fall.restore(&state[state.len() - FALL_STATE_LEN..]).map_err(|e| SceneError::Usage(format!("restore: {e}")))?;
        let mut rest = state;
        let mut take = |n: usize| {
            let (head, tail) = rest.split_at(n);
            rest = tail;
            head
        };
        let nv = self.data.qvel().len();
        let time = take(1)[0];
        self.data.set_time(time);
        let n = self.data.qpos().len();
        self.data.qpos_mut().copy_from_slice(take(n));
        self.data.qvel_mut().copy_from_slice(take(nv));
        let n = self.data.act().len();
        self.data.act_mut().copy_from_slice(take(n));
        let n = self.data.ctrl().len();
        self.data.ctrl_mut().copy_from_slice(take(n));
        // The grip level lives in its actuators' ctrl, so the snapshot carries it.
        if let Some(&g) = self.shared.index.grip.first() {
            self.grip = self.data.ctrl()[g];
        }
        let warm = take(nv);
        let nmocap = self.data.mocap_pos().len();
        for (dst, src) in self.data.mocap_pos_mut().iter_mut().zip(take(3 * nmocap).chunks(3)) {
            dst.copy_from_slice(src);
        }
        for (dst, src) in self.data.mocap_quat_mut().iter_mut().zip(take(4 * nmocap).chunks(4)) {
            dst.copy_from_slice(src);
        }
        let mut rescale = Vec::new();
        for (i, src) in take(PLACEMENT_LEN * self.placements.len()).chunks(PLACEMENT_LEN).enumerate() {
            let p =
                PropPlacement { pos: [src[0], src[1], src[2]], yaw: src[3], top: src[4], scale: src[5], mass: src[6] };
            if let Prop::Box(_) | Prop::Ball(_) = self.shared.scenario.scenario.props[i] {
                let current = self.placements[i];
                if (p.scale, p.mass) != (current.scale, current.mass) || self.owns_model {
                    rescale.push((self.shared.props[i].body, p.scale, p.mass));
                }
            }
            self.placements[i] = p;
        }
        if !rescale.is_empty() {
            self.rescale_free_props(&rescale);
        }
        let stepped = take(1)[0] != 0.0;
        let before_last = take(self.before_last.len());
        take(FALL_STATE_LEN); // read before anything was changed (above)
        self.fall = fall;
        if stepped {
            // The last substep again, from where it started: MuJoCo's derived quantities then
            // belong to that state, as they did in the world the snapshot was taken of (a
            // forward pass would compute them for the present state, and every later step
            // would drift from the original's).
            self.data.set_state(before_last, BEFORE_LAST).map_err(|e| SceneError::Usage(format!("restore: {e}")))?;
            self.data.step();
            self.before_last.copy_from_slice(before_last);
            self.stepped = true;
        } else {
            self.forward();
            self.data.qacc_warmstart_mut().copy_from_slice(warm);
        }
        Ok(())
    }

    /// Sets the hands' grip level (clamped to [0, 1]) for the following steps: each hand then
    /// presses what it touches against itself with `level` × [`crate::compose::GRIP_FORCE_N`].
    /// It stays until set again (resets keep it; a [`World::snapshot`] carries it in the grip
    /// actuators' controls). A scene without a free object has no grip actuators and ignores it.
    pub fn set_grip(&mut self, level: f64) {
        self.grip = if level.is_finite() { level.clamp(0.0, 1.0) } else { 0.0 };
        let ctrl = self.data.ctrl_mut();
        for &g in &self.shared.index.grip {
            ctrl[g] = self.grip;
        }
    }

    /// The grip level the next steps apply.
    pub fn grip(&self) -> f64 {
        self.grip
    }

    /// Whether the scene has grip actuators on the hands.
    pub fn has_grip(&self) -> bool {
        !self.shared.index.grip.is_empty()
    }

    /// Sets every PD target to the current joint angle (so the body holds its pose).
    fn hold_pose(&mut self) {
        let idx = &self.shared.index;
        for j in &idx.joints {
            let a = self.data.qpos()[j.qpos].clamp(j.ctrl_range[0], j.ctrl_range[1]);
            self.data.ctrl_mut()[j.actuator] = a;
        }
    }

    /// One control tick: PD targets `action` (one per actuated joint, in map order; clipped to
    /// each actuator's range) held for `physics_hz / control_hz` physics steps. A wrong length or
    /// a NaN action is an error and leaves the world untouched.
    pub fn step(&mut self, action: &[f64]) -> Result<()> {
        let joints = &self.shared.index.joints;
        if action.len() != joints.len() {
            return Err(SceneError::Usage(format!(
                "step: {} actions given, the body has {} actuated joints",
                action.len(),
                joints.len()
            )));
        }
        if let Some(k) = action.iter().position(|a| !a.is_finite()) {
            return Err(SceneError::Usage(format!("step: action {k} ({}) is not a finite number", joints[k].name)));
        }
        let ctrl = self.data.ctrl_mut();
        for (j, &a) in joints.iter().zip(action) {
            ctrl[j.actuator] = a.clamp(j.ctrl_range[0], j.ctrl_range[1]);
        }
        for i in 0..self.shared.substeps {
            if i + 1 == self.shared.substeps {
                self.data.read_state_into(BEFORE_LAST, &mut self.before_last);
            }
            self.data.step();
        }
        self.stepped = self.shared.substeps > 0;
        self.check_fall(self.shared.control_dt());
        Ok(())
    }

    /// Runs the fall test on what the world shows now, `dt` seconds after its last check.
    pub(crate) fn check_fall(&mut self, dt: f64) {
        let signs = self.fall_signs();
        let time = self.data.time();
        self.fall.update(&self.shared.scenario.scenario.fall, &signs, self.shared.pelvis_min, dt, time);
    }

    /// Forgets any fall and its timers and checks the rules that count at once (a new episode,
    /// a state set by hand).
    fn restart_fall_test(&mut self) {
        self.fall.reset();
        self.check_fall(0.0);
    }

    /// What the fall test reads from the world now: the first part touching the floor that may
    /// not, the first part on a prop not meant for it, and the pelvis' and head's heights.
    pub fn fall_signs(&self) -> FallSigns {
        let shared = &*self.shared;
        let idx = &shared.index;
        let hands_ok = shared.scenario.scenario.fall.hands_on_floor;
        let mut signs = FallSigns { pelvis: idx.pelvis, head: idx.head, ..FallSigns::default() };
        for c in self.data.contact() {
            let (g1, g2) = (c.geom[0] as usize, c.geom[1] as usize);
            for (g, other) in [(g1, g2), (g2, g1)] {
                let b = shared.geom_body[g];
                let part = shared.parts[b];
                if matches!(part, Part::World | Part::Foot) {
                    continue;
                }
                if other == shared.floor_geom && !(hands_ok && part == Part::Hand) {
                    signs.floor.get_or_insert(b);
                }
                if let Some(p) = shared.geom_prop[other]
                    && shared.prop_use[p].forbids(part)
                {
                    signs.prop.get_or_insert((b, p));
                }
            }
        }
        let pelvis = self.body_position(idx.pelvis)[2];
        signs.pelvis_z = pelvis;
        signs.head_over_pelvis = self.body_position(idx.head)[2] - pelvis;
        signs
    }

    /// The fall, once the fall test counted one this episode ([`crate::fall`]).
    pub fn fall(&self) -> Option<Fall> {
        self.fall.fall()
    }

    /// Recomputes MuJoCo's derived quantities for the present state (after a state was set by
    /// hand).
    pub(crate) fn forward(&mut self) {
        self.data.forward();
        self.stepped = false;
    }

    /// Actuated joint angles in map order.
    pub fn joint_angles(&self, out: &mut [f64]) {
        let qpos = self.data.qpos();
        for (o, j) in out.iter_mut().zip(&self.shared.index.joints) {
            *o = qpos[j.qpos];
        }
    }

    /// Actuated joint velocities in map order.
    pub fn joint_velocities(&self, out: &mut [f64]) {
        let qvel = self.data.qvel();
        for (o, j) in out.iter_mut().zip(&self.shared.index.joints) {
            *o = qvel[j.dof];
        }
    }

    /// The pelvis frame (position and orientation) in world coordinates.
    pub fn pelvis_frame(&self) -> Frame {
        self.body_frame(self.shared.index.pelvis)
    }

    /// A body's frame in world coordinates.
    pub fn body_frame(&self, body: usize) -> Frame {
        Frame { pos: self.data.xpos()[body], rot: self.data.xmat()[body] }
    }

    /// A body's position in world coordinates.
    pub fn body_position(&self, body: usize) -> [f64; 3] {
        self.data.xpos()[body]
    }

    /// The character's centre of mass.
    pub fn center_of_mass(&self) -> [f64; 3] {
        self.data.subtree_com()[self.shared.index.root_body]
    }

    /// Height of the pelvis above the floor.
    pub fn root_height(&self) -> f64 {
        self.data.xpos()[self.shared.index.pelvis][2]
    }

    /// The pelvis's heading (yaw, radians): the direction its +x axis points on the floor.
    pub fn heading(&self) -> f64 {
        self.pelvis_frame().yaw()
    }

    /// Whether the character sits on prop `seat`: the pelvis touches it and the pelvis heading
    /// is within `facing` radians of the way the prop faces (its +x). Falling forward onto a
    /// seat from the front, facing the backrest, touches it without sitting.
    pub fn seated_on(&self, seat: usize, facing: f64) -> bool {
        self.contacts().pelvis_on_prop(seat) && wrap_angle(self.heading() - self.placements()[seat].yaw).abs() <= facing
    }

    /// Pelvis pitch and roll in radians (Z-Y-X Euler angles).
    pub fn pitch_roll(&self) -> (f64, f64) {
        let f = self.pelvis_frame();
        (f.pitch(), f.roll())
    }

    /// The root's linear velocity in the world frame.
    pub fn root_dof_velocity(&self) -> [f64; 3] {
        let d = self.shared.index.root_dof;
        let v = &self.data.qvel()[d..d + 3];
        [v[0], v[1], v[2]]
    }

    /// The root's linear velocity in the heading frame (x forward, y left, z up).
    pub fn root_velocity_heading(&self) -> [f64; 3] {
        let d = self.shared.index.root_dof;
        let v = &self.data.qvel()[d..d + 3];
        let (s, c) = self.heading().sin_cos();
        [c * v[0] + s * v[1], -s * v[0] + c * v[1], v[2]]
    }

    /// Foot touch sensors (left, right, ...) above `threshold` newtons.
    pub fn foot_touch(&self, threshold: f64, out: &mut [bool]) {
        let sd = self.data.sensordata();
        for (o, &adr) in out.iter_mut().zip(&self.shared.index.foot_touch) {
            *o = sd[adr] > threshold;
        }
    }

    /// A free box's edge lengths or a ball's diameter (three times) this episode, after its
    /// per-episode scale (m); zeros for any other prop.
    pub fn prop_extent(&self, prop: usize) -> [f64; 3] {
        let s = self.placements[prop].scale;
        match &self.shared.scenario.scenario.props[prop] {
            Prop::Box(b) => [b.size.0 * s, b.size.1 * s, b.size.2 * s],
            Prop::Ball(b) => [2.0 * b.radius * s; 3],
            _ => [0.0; 3],
        }
    }

    /// A prop's pose relative to the pelvis, in the heading frame: `[dx, dy, dz, sin Δyaw, cos Δyaw]`.
    pub fn prop_relative(&self, prop: usize) -> [f64; 5] {
        let idx = &self.shared.props[prop];
        let (pos, yaw) = match idx.mount {
            PropMount::Fixed { .. } => {
                let p = self.placements[prop];
                ([p.pos[0], p.pos[1], p.top], p.yaw)
            }
            PropMount::Free { .. } => {
                let f = self.body_frame(idx.body);
                (f.pos, f.yaw())
            }
        };
        let pelvis = self.pelvis_frame();
        let heading = pelvis.yaw();
        let (s, c) = heading.sin_cos();
        let d = [pos[0] - pelvis.pos[0], pos[1] - pelvis.pos[1], pos[2] - pelvis.pos[2]];
        let dyaw = wrap_angle(yaw - heading);
        [c * d[0] + s * d[1], -s * d[0] + c * d[1], d[2], dyaw.sin(), dyaw.cos()]
    }

    /// What is touching what right now (one pass over MuJoCo's contact list).
    pub fn contacts(&self) -> Contacts {
        let shared = &*self.shared;
        let idx = &shared.index;
        let mut out = Contacts::default();
        for c in self.data.contact() {
            let (g1, g2) = (c.geom[0] as usize, c.geom[1] as usize);
            for (g, other) in [(g1, g2), (g2, g1)] {
                let b = shared.geom_body[g];
                if other == shared.floor_geom {
                    if idx.is_character[b] && !idx.floor_ok[b] {
                        out.fallen = true;
                    }
                    if let Some(side) = idx.foot_of[b] {
                        out.feet_on_floor[side] = true;
                    }
                    if let Some(p) = shared.geom_prop[g] {
                        out.prop_on_floor |= 1 << p.min(63);
                    }
                }
                if let Some(p) = shared.geom_prop[other] {
                    let bit = 1u64 << p.min(63);
                    if b == idx.pelvis_part && other == shared.props[p].key_geom {
                        out.pelvis_on |= bit;
                    }
                    if let Some(side) = idx.hand_of[b] {
                        out.hand_on[side] |= bit;
                    }
                    if idx.is_character[b] {
                        out.character_on |= bit;
                    }
                }
            }
        }
        out
    }

    /// The deepest interpenetration (m, 0 when none) between the character (or only its body
    /// `body`) and prop `p` in the current contacts: how far a pose placed by hand (a seated
    /// reference frame on a chair of another height) sinks into the prop.
    pub fn penetration_with_prop(&self, p: usize, body: Option<usize>) -> f64 {
        self.penetration(body, |other| self.shared.geom_prop[other] == Some(p))
    }

    /// As [`World::penetration_with_prop`], with prop `p`'s key geom only (a chair's seat).
    pub fn penetration_with_key_geom(&self, p: usize, body: Option<usize>) -> f64 {
        let key = self.shared.props.get(p).map(|prop| prop.key_geom);
        self.penetration(body, |other| Some(other) == key)
    }

    /// The deepest interpenetration (m, 0 when none) between the character and the floor: how
    /// far a pose placed by hand (a reference frame whose feet dip below the floor) sinks in.
    pub fn penetration_with_floor(&self) -> f64 {
        let floor = self.shared.floor_geom;
        self.penetration(None, |other| other == floor)
    }

    fn penetration(&self, body: Option<usize>, wanted: impl Fn(usize) -> bool) -> f64 {
        let shared = &*self.shared;
        let mut deepest = 0.0f64;
        for c in self.data.contact() {
            let (g1, g2) = (c.geom[0] as usize, c.geom[1] as usize);
            for (g, other) in [(g1, g2), (g2, g1)] {
                let b = shared.geom_body[g];
                let ours = body.map_or(shared.index.is_character[b], |want| b == want);
                if ours && wanted(other) {
                    deepest = deepest.max(-c.dist);
                }
            }
        }
        deepest
    }

    /// Raises the character by `dz` metres (its root only; props, velocities and PD targets
    /// unchanged).
    pub fn lift_character(&mut self, dz: f64) {
        let r = self.shared.index.root_qpos;
        self.data.qpos_mut()[r + 2] += dz;
        self.forward();
        self.restart_fall_test();
    }

    /// True once the fall test ([`crate::fall`]) counted a fall this episode: a part not
    /// allowed on the floor touched it, a part lay on a prop not meant for it, the pelvis went
    /// low or the head stayed below it.
    pub fn has_fallen(&self) -> bool {
        self.fall.fall().is_some()
    }
}

/// A summary of the contacts in a world, as bit sets over prop indices (props past 63 share
/// the last bit).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct Contacts {
    /// A body part not allowed on the floor (the map's `floor_contact_allowed`) touches it now.
    /// One sign the fall test reads; [`World::has_fallen`] is the test.
    pub fallen: bool,
    /// Props whose key geom (the seat, ...) the pelvis touches.
    pub pelvis_on: u64,
    /// Props each hand (left, right) touches.
    pub hand_on: [u64; 2],
    /// Props any part of the character touches.
    pub character_on: u64,
    /// Props touching the floor.
    pub prop_on_floor: u64,
    /// Which feet (left, right; toes included) touch the floor.
    pub feet_on_floor: [bool; 2],
}

impl Contacts {
    /// True when the pelvis touches prop `p`'s key geom (a chair's seat).
    pub fn pelvis_on_prop(&self, p: usize) -> bool {
        self.pelvis_on & (1 << p.min(63)) != 0
    }

    /// True when any body of the character touches prop `p`.
    pub fn character_on_prop(&self, p: usize) -> bool {
        self.character_on & (1 << p.min(63)) != 0
    }

    /// Which hands (left, right) touch prop `p`.
    pub fn hands_on_prop(&self, p: usize) -> [bool; 2] {
        let bit = 1 << p.min(63);
        [self.hand_on[0] & bit != 0, self.hand_on[1] & bit != 0]
    }

    /// True when prop `p` touches the floor (a ball that dropped).
    pub fn prop_on_floor(&self, p: usize) -> bool {
        self.prop_on_floor & (1 << p.min(63)) != 0
    }
}

/// Draws a start position and heading in a spawn zone, given the zone's prop placement.
pub fn spawn_point(zone: &Zone, around: Option<PropPlacement>, rng: &mut impl Rng) -> (f64, f64, f64) {
    let (cx, cy, cyaw) = around.map_or((0.0, 0.0, 0.0), |p| (p.pos[0], p.pos[1], p.yaw));
    let radius = zone.radius.sample(rng);
    let mut angle = zone.angle_deg.sample(rng).to_radians();
    if zone.mirrored && rng.random_bool(0.5) {
        angle = -angle;
    }
    let world_angle = cyaw + angle;
    let (x, y) = (cx + radius * world_angle.cos(), cy + radius * world_angle.sin());
    let toward = (cy - y).atan2(cx - x);
    let jitter =
        |j: f64, rng: &mut dyn rand::RngCore| if j > 0.0 { rng.random_range(-j..=j).to_radians() } else { 0.0 };
    let yaw = match zone.facing {
        Facing::Toward { jitter_deg } => toward + jitter(jitter_deg, rng),
        Facing::Away { jitter_deg } => toward + PI + jitter(jitter_deg, rng),
        Facing::Uniform => rng.random_range(-PI..PI),
        Facing::World(p) => p.sample(rng).to_radians(),
    };
    (x, y, wrap_angle(yaw))
}

impl World {
    /// Starts an episode in spawn zone `zone`: draws the props, then a start point in the zone.
    pub fn reset_in_zone(&mut self, zone: &str, rng: &mut impl Rng) -> Result<(f64, f64, f64)> {
        let shared = Arc::clone(&self.shared);
        let z = shared.scenario.scenario.spawn.iter().find(|z| z.name == zone).ok_or_else(|| {
            SceneError::Usage(format!("no spawn zone `{zone}` in {}", shared.scenario.path.display()))
        })?;
        self.data.reset();
        self.set_grip(self.grip); // MuJoCo's reset zeroes every control
        self.sample_props(rng);
        let around = z.around.as_deref().and_then(|n| shared.prop_id(n)).map(|p| self.placements[p]);
        let (x, y, yaw) = spawn_point(z, around, rng);
        self.place_standing(x, y, yaw);
        Ok((x, y, yaw))
    }
}

/// Steps every world one control tick in parallel; `actions` holds one row of
/// `dof` values per world.
pub fn step_parallel(worlds: &mut [World], actions: &[f64]) -> Result<()> {
    let Some(first) = worlds.first() else { return Ok(()) };
    let dof = first.shared.index.dof();
    if actions.len() != dof * worlds.len() {
        return Err(SceneError::Usage(format!(
            "step_parallel: {} actions for {} worlds of {dof} actuated joints",
            actions.len(),
            worlds.len()
        )));
    }
    worlds.par_iter_mut().zip(actions.par_chunks(dof)).try_for_each(|(w, a)| w.step(a))
}

/// Rotates world vector `v` into the frame of unit quaternion `q` (w, x, y, z): q⁻¹ v q.
fn rotate_inverse(q: [f64; 4], v: [f64; 3]) -> [f64; 3] {
    let (w, x, y, z) = (q[0], -q[1], -q[2], -q[3]);
    // t = 2 (u × v), v' = v + w t + u × t, with u = (x, y, z).
    let t = [2.0 * (y * v[2] - z * v[1]), 2.0 * (z * v[0] - x * v[2]), 2.0 * (x * v[1] - y * v[0])];
    [
        v[0] + w * t[0] + (y * t[2] - z * t[1]),
        v[1] + w * t[1] + (z * t[0] - x * t[2]),
        v[2] + w * t[2] + (x * t[1] - y * t[0]),
    ]
}

impl crate::throw::Throw {
    /// Puts free prop `ball` in flight on this throw.
    pub fn launch(&self, world: &mut World, ball: usize) -> Result<()> {
        if !(self.t_hit.is_finite() && self.t_hit > 0.0) {
            return Err(SceneError::Usage(format!("throw: flight time {} is not positive", self.t_hit)));
        }
        world.set_free_prop(ball, self.pos, [1.0, 0.0, 0.0, 0.0], self.linvel, self.angvel)
    }
}
