//! [`ImitationTask`]: track a reference clip (imitation reward) while reaching a goal (goal
//! reward), starting from reference states or from predecessor skills' end poses, ending on a
//! fall or when the clip runs out.

use std::f64::consts::{PI, TAU};
use std::sync::Arc;

use rand::{Rng, SeedableRng};
use repertoire_humanoid::{Task, TaskStep};
use repertoire_learn::env::{EnvRng, MAX_TERMS, StateError};
use repertoire_scenes::World;
use repertoire_scenes::math::wrap_angle;
use repertoire_scenes::world::spawn_point;

use crate::pool::{Pool, PoolState};
use crate::quat::{mul, rotate_z, yaw_quat};
use crate::reference::{END_EFFECTORS, Reference, local_end_effectors, to_heading};
use crate::spec::{Goal, Imitation, Init, Obstacle, Steering, Termination};
use repertoire_scenes::ThrowSpec;

/// Names of the reward terms and metrics each step reports (unweighted similarities in [0, 1],
/// then the goal term, whether the pelvis is on the seat, and whether an object goal's state is
/// reached: box raised, held, put down and released, ball caught).
pub const TERM_NAMES: [&str; 7] = ["pose", "velocity", "end_effector", "root", "goal", "on_seat", "object"];

/// An object goal's props and clip frames (lift, carry, put down, catch).
#[derive(Debug, Clone, PartialEq)]
pub struct ObjectSetup {
    /// The box or ball (a free prop).
    pub prop: usize,
    /// The pedestal and the reference frame under whose hands it stands.
    pub pedestal: Option<(usize, usize)>,
    /// For catch: the frame at which the ball reaches the hands.
    pub catch_frame: Option<usize>,
    /// Reference frames in which the clip holds the object: episodes starting in them start
    /// with it between the hands.
    pub held: std::ops::Range<usize>,
    /// Half the box's height or the ball's radius before the episode's scale (m).
    pub half: f64,
    /// The box's width across the hands (its y edge) or the ball's diameter, before the
    /// episode's scale (m).
    pub width: f64,
}

pub use repertoire_scenes::world::{HOLD_FIT_TOLERANCE_M, HOLD_SQUEEZE_M};

/// Everything about a skill's task that does not change between episodes; shared by all envs.
#[derive(Debug, Clone)]
pub struct TaskSettings {
    /// The reference at the control rate.
    pub reference: Reference,
    /// Imitation terms.
    pub imitation: Imitation,
    /// Goal.
    pub goal: Goal,
    /// Episode starts.
    pub init: Init,
    /// Early termination.
    pub termination: Termination,
    /// Predecessors' end poses (for [`Init::Pools`]).
    pub pools: Vec<Pool>,
    /// For [`Goal::Seat`]: the chair's prop index and its pose relative to the clip, as
    /// `(x, y, yaw)` in the clip's world.
    pub seat: Option<(usize, [f64; 3])>,
    /// For object goals: the box or ball, the pedestal, and the frames that hold it.
    pub object: Option<ObjectSetup>,
    /// The hands' grip level (the spec's `grip`), set on the world at every episode start.
    pub grip: f64,
    /// The prop put in the way of the walking targets (its index and the spec's settings).
    pub obstacle: Option<(usize, Obstacle)>,
    /// The spec's `delivered_seat`: the prop a delivered pool state's seat is put at, for a
    /// skill without a seat goal.
    pub delivered_seat: Option<usize>,
}

/// The imitation task of one environment.
#[derive(Debug)]
pub struct ImitationTask {
    settings: Arc<TaskSettings>,
    /// Current reference frame.
    phase: usize,
    /// Completed cycles of a looping clip.
    cycles: usize,
    /// Steps the last frame of a holding clip has been held.
    held: usize,
    /// Clip-to-world transform of this episode: rotate by `yaw` about +z, then map the clip's
    /// point `anchor` to `origin`.
    yaw: f64,
    anchor: [f64; 2],
    origin: [f64; 2],
    /// World heading at the start and the reference frame it matched.
    start_heading: f64,
    start_frame: usize,
    /// Goal state: the target (world xy) and the last distance to it or to the seat.
    target: [f64; 2],
    last_distance: f64,
    /// Steps since the current target was drawn or set (`Goal::Target::retarget_s`).
    target_steps: usize,
    /// This episode's chair offset from the clip's seat (world x, y, yaw).
    seat_offset: [f64; 3],
    /// This episode's pedestal offset from the clip's spot (world x, y, yaw; `jitter_m`).
    pedestal_offset: [f64; 3],
    /// Draws the next target after an arrival (`Goal::Target::reach_m`) or a timeout
    /// (`retarget_s`), seeded at reset.
    target_rng: EnvRng,
    /// Targets reached this episode.
    pub reached: u32,
    /// Whether the episode ended on a touch of the spec's obstacle (`touch_ends`); `skill eval`
    /// counts those apart from the falls they are scored as.
    pub touched: bool,
    joints: Vec<f64>,
}

impl ImitationTask {
    /// A task over shared settings.
    pub fn new(settings: Arc<TaskSettings>) -> Self {
        let dof = settings.reference.dof;
        ImitationTask {
            settings,
            phase: 0,
            cycles: 0,
            held: 0,
            yaw: 0.0,
            anchor: [0.0; 2],
            origin: [0.0; 2],
            start_heading: 0.0,
            start_frame: 0,
            target: [0.0; 2],
            last_distance: 0.0,
            target_steps: 0,
            seat_offset: [0.0; 3],
            pedestal_offset: [0.0; 3],
            target_rng: EnvRng::seed_from_u64(0),
            reached: 0,
            touched: false,
            joints: vec![0.0; dof],
        }
    }

    /// The walking target (world xy) of a `Goal::Target` skill.
    pub fn target(&self) -> [f64; 2] {
        self.target
    }

    /// Moves the walking target (world xy), for tools and tests that set up a situation by hand.
    pub fn set_target(&mut self, target: [f64; 2], world: &World) {
        self.target = target;
        self.target_steps = 0;
        self.last_distance = self.goal_distance(world);
    }

    /// The shared settings.
    pub fn settings(&self) -> &Arc<TaskSettings> {
        &self.settings
    }

    /// The current reference frame.
    pub fn phase(&self) -> usize {
        self.phase
    }

    /// A clip-world point in this episode's world.
    fn to_world(&self, p: [f64; 2]) -> [f64; 2] {
        let d = rotate_z(self.yaw, [p[0] - self.anchor[0], p[1] - self.anchor[1], 0.0]);
        [self.origin[0] + d[0], self.origin[1] + d[1]]
    }

    /// Frames per cycle of a looping clip (its last frame is the next cycle's first).
    fn cycle_len(&self) -> usize {
        self.settings.reference.frames() - 1
    }

    /// Places the character in reference frame `f` at the spawn point `(x, y)` facing `heading`.
    fn place_reference(&mut self, world: &mut World, f: usize, x: f64, y: f64, heading: f64) {
        let r = &self.settings.reference;
        self.yaw = heading - r.heading[f];
        self.anchor = [r.root_pos[f][0], r.root_pos[f][1]];
        self.origin = [x, y];
        let v = r.root_qvel[f];
        let lin = rotate_z(self.yaw, [v[0], v[1], v[2]]);
        let root_vel = [lin[0], lin[1], lin[2], v[3], v[4], v[5]];
        let quat = mul(yaw_quat(self.yaw), r.root_quat[f]);
        world
            .set_motion([x, y, r.root_pos[f][2]], quat, r.joints_at(f), root_vel, Some(r.joint_vel_at(f)))
            .expect("reference frames are validated finite and sized to the body");
        self.phase = f;
    }

    /// Places the chair where the clip sits, in this episode's world.
    fn place_seat(&self, world: &mut World) {
        if let Some((prop, [sx, sy, syaw])) = self.settings.seat {
            let [x, y] = self.to_world([sx, sy]);
            let [dx, dy, dyaw] = self.seat_offset;
            world
                .move_prop(prop, x + dx, y + dy, wrap_angle(syaw + self.yaw + dyaw))
                .expect("the seat prop is validated");
        }
    }

    /// Starts an episode free of the chair: a pose placed by hand can sink into it (a seated
    /// frame on a lower seat than the clip's, a standing leg inside a chair the jitter moved)
    /// and MuJoCo would shoot it out. A low (seated) frame whose pelvis sinks into the seat
    /// (the key geom) is lifted onto it; a standing frame that overlaps the chair pushes the
    /// chair back along its own −x, at most 20 cm.
    fn separate_from_seat(&mut self, world: &mut World, prop: usize) {
        let r = &self.settings.reference;
        if r.lowness(self.phase) > 0.5 {
            let pelvis = world.model().index.pelvis;
            for _ in 0..4 {
                let depth = world.penetration_with_key_geom(prop, Some(pelvis));
                if depth <= 0.002 {
                    break;
                }
                world.lift_character(depth + 0.002);
            }
            return;
        }
        for _ in 0..10 {
            if world.penetration_with_prop(prop, None) <= 0.002 {
                break;
            }
            let pl = world.placements()[prop];
            let (s, c) = pl.yaw.sin_cos();
            world
                .move_prop(prop, pl.pos[0] - 0.02 * c, pl.pos[1] - 0.02 * s, pl.yaw)
                .expect("the seat prop is validated");
        }
    }

    /// Object-aware start: stands the pedestal under the clip's hands at its frame, then puts
    /// the box or ball between the hands when the start frame holds it, else on the pedestal,
    /// else (catch) throws it to arrive at the hands when the clip catches it.
    fn place_object(&self, world: &mut World, rng: &mut EnvRng) {
        let settings = Arc::clone(&self.settings);
        let Some(obj) = &settings.object else { return };
        let r = &settings.reference;
        let f = self.phase.min(r.frames() - 1);
        let half = obj.half * world.placements()[obj.prop].scale;
        let at = |g: usize| {
            let h = r.hands[g];
            let [x, y] = self.to_world([h[0], h[1]]);
            ([x, y, h[2]], wrap_angle(r.heading[g] + self.yaw))
        };
        if let Some((ped, g)) = obj.pedestal {
            let (p, yaw) = at(g);
            let [dx, dy, dyaw] = self.pedestal_offset;
            world.move_prop(ped, p[0] + dx, p[1] + dy, wrap_angle(yaw + dyaw)).expect("the pedestal is validated");
            if self.pedestal_offset != [0.0; 3] {
                clear_pedestal(world, ped);
            }
        }
        let (still, zero) = ([1.0, 0.0, 0.0, 0.0], [0.0; 3]);
        if obj.held.contains(&f) {
            // Between the body's own hands (a pool state's may differ from the reference's). A
            // box scaled this episode first gets the arms spread or closed to its width where
            // they would miss it or squeeze it hard; one at its built size is held as the clip
            // or the pool state holds it.
            let scale = world.placements()[obj.prop].scale;
            if scale != 1.0 {
                world.fit_hands_round(obj.width * scale);
            }
            let idx = &world.model().index;
            let [l, rt] = [world.body_position(idx.hands[0]), world.body_position(idx.hands[1])];
            let p = std::array::from_fn(|k| 0.5 * (l[k] + rt[k]));
            let yaw = world.heading();
            let (a, b) = if f + 1 < r.frames() { (f, f + 1) } else { (f.saturating_sub(1), f) };
            let v = if b > a {
                let d = std::array::from_fn(|k| (r.hands[b][k] - r.hands[a][k]) / r.dt);
                rotate_z(self.yaw, d)
            } else {
                zero
            };
            world.set_free_prop(obj.prop, p, yaw_quat(yaw), v, zero).expect("the object is a validated free prop");
        } else if let Some((ped, _)) = obj.pedestal {
            let pl = world.placements()[ped];
            world
                .set_free_prop(obj.prop, [pl.pos[0], pl.pos[1], pl.top + half], yaw_quat(pl.yaw), zero, zero)
                .expect("the object is a validated free prop");
        } else if let (Some(c), Goal::Catch { throw, free_timing, .. }) = (obj.catch_frame, &settings.goal) {
            let (target, yaw) = at(c);
            let throw = if *free_timing {
                throw.sample(target, yaw, rng)
            } else {
                let flight = c.saturating_sub(f).max(1) as f64 * r.dt;
                catch_throw(throw, target, yaw, flight, rng)
            };
            throw.launch(world, obj.prop).expect("catch throws are validated");
        } else {
            world.set_free_prop(obj.prop, at(f).0, still, zero, zero).expect("the object is a validated free prop");
        }
    }

    /// An object goal's term in [0, 1], whether its state is reached, and whether the object
    /// touches the floor (which ends the episode).
    ///
    /// `steer` is the target term of a steering goal (a carry with a target), which then takes
    /// the place of the carry's velocity term.
    fn object_goal(
        &self,
        world: &World,
        contacts: &repertoire_scenes::Contacts,
        f: usize,
        steer: Option<f32>,
    ) -> (f32, bool, bool) {
        let settings = &self.settings;
        let Some(obj) = &settings.object else { return (0.0, false, false) };
        let model = world.model();
        let idx = &model.index;
        let [l, rt] = [world.body_position(idx.hands[0]), world.body_position(idx.hands[1])];
        let mid: [f64; 3] = std::array::from_fn(|k| 0.5 * (l[k] + rt[k]));
        let c = world.body_frame(model.props[obj.prop].body).pos;
        let dist = |a: [f64; 3], b: [f64; 3]| (0..3).map(|k| (a[k] - b[k]).powi(2)).sum::<f64>().sqrt();
        let d = dist(c, mid);
        let on = contacts.hands_on_prop(obj.prop);
        let hands_on = usize::from(on[0]) + usize::from(on[1]);
        let dropped = contacts.prop_on_floor(obj.prop)
            || matches!(settings.goal, Goal::Carry { hold_m, .. } if hold_m > 0.0 && d > hold_m);
        let hold = |scale: f64| 0.5 * similarity(scale, d * d) + 0.25 * hands_on as f32;
        let half = obj.half * world.placements()[obj.prop].scale;
        match &settings.goal {
            Goal::Lift { lift_m, scale, .. } => {
                let top = obj.pedestal.map_or(0.0, |(p, _)| world.placements()[p].top);
                let raised = c[2] - half - top;
                let raise = if hands_on > 0 && !dropped { (raised / lift_m).clamp(0.0, 1.0) as f32 } else { 0.0 };
                (0.5 * hold(*scale) + 0.5 * raise, raised >= 0.8 * lift_m && hands_on > 0 && !dropped, dropped)
            }
            Goal::Carry { scale, speed_scale, .. } => {
                let pace = steer.unwrap_or_else(|| {
                    let v = world.root_velocity_heading();
                    let e = (v[0] - settings.reference.velocity[f][0]).powi(2)
                        + (v[1] - settings.reference.velocity[f][1]).powi(2);
                    similarity(*speed_scale, e)
                });
                let goal = 0.6 * hold(*scale) + 0.4 * pace;
                (goal, hands_on > 0 && d < 0.2 && !dropped, dropped)
            }
            Goal::PutDown { scale, .. } => {
                let Some((ped, _)) = obj.pedestal else { return (0.0, false, dropped) };
                let pl = world.placements()[ped];
                let resting = world.prop_contact_count(obj.prop, ped) >= 4;
                if resting {
                    let released = hands_on == 0;
                    (if released { 1.0 } else { 0.5 }, released && !dropped, dropped)
                } else {
                    let e = dist(c, [pl.pos[0], pl.pos[1], pl.top + half]);
                    (0.5 * similarity(*scale, e * e), false, dropped)
                }
            }
            Goal::Catch { scale, .. } => {
                let goal = if dropped { 0.0 } else { hold(*scale) };
                (goal, !dropped && (hands_on > 0 || d < 0.2), dropped)
            }
            _ => (0.0, false, false),
        }
    }

    /// A steering goal's target term at frame `f`: 1 on arriving (within `reach_m`; a new
    /// target is then drawn around the current heading), else the approach term (DeepMimic's
    /// target-heading speed term or the sigmoid on the distance's rate) with, above 0
    /// `facing_scale`, a facing term for half.
    fn steer_term(&mut self, world: &World, st: &Steering, f: usize) -> f32 {
        let r = &self.settings.reference;
        if st.reach_m > 0.0 && self.goal_distance(world) < st.reach_m {
            // Arrived: a new target ahead, from the same ranges around the current heading.
            let p = world.pelvis_frame().pos;
            let next = draw_target(&mut self.target_rng, [p[0], p[1]], world.heading(), st.distance_m, st.azimuth_deg);
            self.set_target(next, world);
            self.reached += 1;
            return 1.0;
        }
        let p = world.pelvis_frame().pos;
        let (dx, dy) = (self.target[0] - p[0], self.target[1] - p[1]);
        let norm = (dx * dx + dy * dy).sqrt().max(1e-9);
        let approach = if st.speed_scale > 0.0 {
            let d = world.root_dof_velocity();
            let toward = (d[0] * dx + d[1] * dy) / norm;
            let v_ref = (r.velocity[f][0].powi(2) + r.velocity[f][1].powi(2)).sqrt();
            similarity(st.speed_scale, (v_ref - toward).max(0.0).powi(2))
        } else {
            let speed = (norm - self.last_distance) / r.dt;
            (1.0 / (1.0 + (10.0 * speed).exp())) as f32
        };
        self.last_distance = norm;
        if st.facing_scale > 0.0 {
            let psi = wrap_angle(dy.atan2(dx) - world.heading());
            0.5 * approach + 0.5 * similarity(st.facing_scale, psi * psi)
        } else {
            approach
        }
    }

    /// Distance from the pelvis to the seat centre (or to the walk target), for the goal.
    fn goal_distance(&self, world: &World) -> f64 {
        let p = world.pelvis_frame().pos;
        match (&self.settings.goal, self.settings.seat) {
            (Goal::Seat { .. }, Some((prop, _))) => {
                let pl = world.placements()[prop];
                let d = [p[0] - pl.pos[0], p[1] - pl.pos[1], p[2] - pl.top];
                (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt()
            }
            _ => ((p[0] - self.target[0]).powi(2) + (p[1] - self.target[1]).powi(2)).sqrt(),
        }
    }

    /// The reference heading change from the episode start to the current phase, across cycles.
    fn reference_turn(&self) -> f64 {
        let r = &self.settings.reference;
        let per_cycle = r.heading[r.frames() - 1] - r.heading[0];
        r.heading[self.phase] - r.heading[self.start_frame] + self.cycles as f64 * per_cycle
    }
}

impl ImitationTask {
    /// Places the character in reference frame `f` at `(x, y)` facing `heading`, at the
    /// frame's velocities, and makes `f` the current phase (tests, viewers).
    pub fn place_at_frame(&mut self, world: &mut World, f: usize, x: f64, y: f64, heading: f64) {
        self.place_reference(world, f, x, y, heading);
        self.seat_offset = [0.0; 3];
        self.pedestal_offset = [0.0; 3];
        self.place_seat(world);
        // A fixed stream: a throw drawn here is the same on every call.
        self.place_object(world, &mut <EnvRng as rand::SeedableRng>::seed_from_u64(f as u64));
        self.start_frame = f;
        self.start_heading = world.heading();
        self.cycles = 0;
        self.held = 0;
        self.last_distance = self.goal_distance(world);
    }

    /// Completed cycles of a looping clip this episode.
    pub fn cycles(&self) -> usize {
        self.cycles
    }

    /// The reference pose of the current phase placed in this episode's world (the ghost a
    /// viewer draws): `qpos` becomes `world`'s qpos with the character's root and actuated
    /// joints set to the reference's. A looping clip's root carries on cycle after cycle.
    pub fn reference_qpos(&self, world: &World, qpos: &mut [f64]) {
        let r = &self.settings.reference;
        let f = self.phase.min(r.frames() - 1);
        qpos.copy_from_slice(world.data().qpos());
        let ([x, y], turned) = self.clip_root(f, self.cycles);
        let idx = &world.model().index;
        let q = mul(yaw_quat(self.yaw + turned), r.root_quat[f]);
        let root = idx.root_qpos;
        qpos[root..root + 3].copy_from_slice(&[x, y, r.root_pos[f][2]]);
        qpos[root + 3..root + 7].copy_from_slice(&q);
        for (j, &a) in idx.joints.iter().zip(r.joints_at(f)) {
            qpos[j.qpos] = a;
        }
    }

    /// The reference frame `ahead` control steps after the current phase, placed in this
    /// episode's world: its frame index, root position and heading (world). A looping clip
    /// carries on across cycles; a clip that ends holds its last frame.
    pub fn reference_ahead(&self, ahead: usize) -> (usize, [f64; 3], f64) {
        let r = &self.settings.reference;
        let (f, cycles) = if r.looping {
            let total = self.phase + ahead;
            (total % self.cycle_len(), self.cycles + total / self.cycle_len())
        } else {
            ((self.phase + ahead).min(r.frames() - 1), self.cycles)
        };
        let ([x, y], turned) = self.clip_root(f, cycles);
        (f, [x, y, r.root_pos[f][2]], r.heading[f] + self.yaw + turned)
    }

    /// Frame `f`'s root (world xy) after `cycles` completed cycles, and the heading those cycles
    /// turned: each cycle of a looping clip starts where the last one ended.
    fn clip_root(&self, f: usize, cycles: usize) -> ([f64; 2], f64) {
        let r = &self.settings.reference;
        let mut p = [r.root_pos[f][0], r.root_pos[f][1]];
        let mut turned = 0.0;
        if r.looping {
            let last = r.frames() - 1;
            let dh = r.heading[last] - r.heading[0];
            let (p0, pl) = (r.root_pos[0], r.root_pos[last]);
            for _ in 0..cycles {
                let d = rotate_z(dh, [p[0] - p0[0], p[1] - p0[1], 0.0]);
                p = [pl[0] + d[0], pl[1] + d[1]];
                turned += dh;
            }
        }
        (self.to_world(p), turned)
    }

    /// Scores `world` against reference frame `f`: the reward, whether it fell, and the terms.
    pub fn score(&mut self, world: &World, f: usize) -> TaskStep {
        let settings = Arc::clone(&self.settings);
        let r = &settings.reference;
        let im = &settings.imitation;
        world.joint_angles(&mut self.joints);
        let pose_err: f64 = self.joints.iter().zip(r.joints_at(f)).map(|(a, b)| wrap_angle(a - b).powi(2)).sum();
        world.joint_velocities(&mut self.joints);
        let vel_err: f64 = self.joints.iter().zip(r.joint_vel_at(f)).map(|(a, b)| (a - b).powi(2)).sum();
        let idx = &world.model().index;
        let pelvis = world.pelvis_frame();
        let bodies = [idx.hands[0], idx.hands[1], idx.feet[0], idx.feet[1], idx.head];
        let ee: [[f64; 3]; END_EFFECTORS] = bodies.map(|b| world.body_position(b));
        let ee = local_end_effectors(&pelvis, ee);
        let ee_err: f64 =
            ee.iter().zip(&r.end_effectors[f]).map(|(a, b)| (0..3).map(|k| (a[k] - b[k]).powi(2)).sum::<f64>()).sum();
        let (pitch, roll) = (pelvis.pitch(), pelvis.roll());
        let root_err = (pelvis.pos[2] - r.height[f]).powi(2)
            + wrap_angle(pitch - r.pitch_roll[f][0]).powi(2)
            + wrap_angle(roll - r.pitch_roll[f][1]).powi(2);

        let contacts = world.contacts();
        let on_seat = settings.seat.is_some_and(|(p, _)| contacts.pelvis_on_prop(p));
        let steering = settings.goal.steering();
        if let Some(st) = steering {
            self.target_steps += 1;
            if st.retarget_s > 0.0 && self.target_steps as f64 * r.dt >= st.retarget_s {
                let p = world.pelvis_frame().pos;
                let next =
                    draw_target(&mut self.target_rng, [p[0], p[1]], world.heading(), st.distance_m, st.azimuth_deg);
                self.set_target(next, world);
            }
        }
        let steer = steering.map(|st| self.steer_term(world, &st, f));
        let object = self.object_goal(world, &contacts, f, steer);
        let goal = match &settings.goal {
            Goal::None => 0.0,
            Goal::RootVelocity { scale, .. } => {
                let v = world.root_velocity_heading();
                let e = (v[0] - r.velocity[f][0]).powi(2) + (v[1] - r.velocity[f][1]).powi(2);
                similarity(*scale, e)
            }
            Goal::Heading { scale, .. } => {
                let turned = wrap_angle(world.heading() - self.start_heading);
                let e = wrap_angle(turned - self.reference_turn()).powi(2)
                    + wrap_angle(pitch - r.pitch_roll[f][0]).powi(2)
                    + wrap_angle(roll - r.pitch_roll[f][1]).powi(2);
                similarity(*scale, e)
            }
            Goal::Target { .. } => steer.unwrap_or(0.0),
            Goal::Seat { .. } => {
                let d = self.goal_distance(world);
                let speed = (d - self.last_distance) / r.dt;
                self.last_distance = d;
                if on_seat { 1.0 } else { (1.0 / (1.0 + (10.0 * speed).exp())) as f32 }
            }
            Goal::Lift { .. } | Goal::Carry { .. } | Goal::PutDown { .. } | Goal::Catch { .. } => object.0,
        };
        let goal_weight = settings.goal.weight();

        let mut terms = [0.0; MAX_TERMS];
        terms[0] = similarity(im.pose.scale, pose_err);
        terms[1] = similarity(im.velocity.scale, vel_err);
        terms[2] = similarity(im.end_effector.scale, ee_err);
        terms[3] = similarity(im.root.scale, root_err);
        terms[4] = goal;
        terms[5] = if on_seat { 1.0 } else { 0.0 };
        terms[6] = if object.1 { 1.0 } else { 0.0 };
        let t = &settings.termination;
        // A dropped box or ball ends the episode like a fall, and so does touching the obstacle.
        let bumped = settings.obstacle.as_ref().is_some_and(|(p, o)| o.touch_ends && contacts.character_on_prop(*p));
        let fell = (t.fall && world.has_fallen()) || pelvis.pos[2] < t.min_height || object.2 || bumped;
        self.touched = bumped;
        let reward = if fell {
            0.0
        } else {
            im.pose.weight * terms[0]
                + im.velocity.weight * terms[1]
                + im.end_effector.weight * terms[2]
                + im.root.weight * terms[3]
                + goal_weight * goal
        };
        TaskStep { reward, terminated: fell, truncated: false, terms }
    }
}

/// A target `distance_m` away from `from` at an azimuth within ±`azimuth_deg` of `heading`.
fn draw_target(rng: &mut EnvRng, from: [f64; 2], heading: f64, distance_m: (f64, f64), azimuth_deg: f64) -> [f64; 2] {
    let d = rng.random_range(distance_m.0..=distance_m.1.max(distance_m.0));
    let a = heading + rng.random_range(-azimuth_deg..=azimuth_deg.max(-azimuth_deg)).to_radians();
    [from[0] + d * a.cos(), from[1] + d * a.sin()]
}

/// Puts the obstacle `(prop, settings)` in the way from the pelvis to `target` with probability
/// `chance` (see [`Obstacle`]); failing that, on an episode's `first` target, 1.5–4 m off the
/// pelvis in any direction. Never nearer the pelvis than the clearance; facing anywhere.
fn place_obstacle(obstacle: &(usize, Obstacle), target: [f64; 2], world: &mut World, rng: &mut EnvRng, first: bool) {
    let (prop, o) = obstacle;
    let p = world.pelvis_frame().pos;
    let (dx, dy) = (target[0] - p[0], target[1] - p[1]);
    let d = (dx * dx + dy * dy).sqrt();
    let yaw = rng.random_range(-PI..PI);
    if rng.random_bool(o.chance) && d > 1e-6 {
        let u = rng.random_range(o.along.0..=o.along.1);
        let side = rng.random_range(-o.offset_m..=o.offset_m);
        let (ex, ey) = (dx / d, dy / d);
        let at = [p[0] + u * dx - side * ey, p[1] + u * dy + side * ex];
        if (at[0] - p[0]).hypot(at[1] - p[1]) >= o.clearance_m {
            world.move_prop(*prop, at[0], at[1], yaw).expect("the obstacle is a validated fixed prop");
            return;
        }
    }
    if first {
        let lo = o.clearance_m.max(1.5);
        let r = rng.random_range(lo..=lo.max(4.0));
        let a = rng.random_range(-PI..PI);
        world
            .move_prop(*prop, p[0] + r * a.cos(), p[1] + r * a.sin(), yaw)
            .expect("the obstacle is a validated fixed prop");
    }
}

/// `exp(−scale · e)`.
fn similarity(scale: f64, e: f64) -> f32 {
    (-scale * e).exp() as f32
}

impl Task for ImitationTask {
    fn term_names(&self) -> &[&'static str] {
        &TERM_NAMES
    }

    fn extra_obs_dim(&self) -> usize {
        3 + if self.settings.goal.steering().is_some() { 3 } else { 0 }
    }

    fn observe_extra(&self, world: &World, out: &mut [f32]) {
        let r = &self.settings.reference;
        let phi = self.phase as f64 / (r.frames() - 1) as f64;
        out[0] = (TAU * phi).sin() as f32;
        out[1] = (TAU * phi).cos() as f32;
        out[2] = phi as f32;
        if self.settings.goal.steering().is_some() {
            let p = world.pelvis_frame().pos;
            let d = to_heading(world.heading(), [self.target[0] - p[0], self.target[1] - p[1], 0.0]);
            let dist = (d[0] * d[0] + d[1] * d[1]).sqrt();
            let psi = d[1].atan2(d[0]);
            out[3] = psi.sin() as f32;
            out[4] = psi.cos() as f32;
            out[5] = dist as f32;
        }
    }

    fn reset(&mut self, world: &mut World, rng: &mut EnvRng) {
        let model = Arc::clone(world.model());
        let (x, y, heading) = match model.scenario.scenario.spawn.first() {
            Some(zone) => {
                let around = zone.around.as_deref().and_then(|n| model.prop_id(n)).map(|p| world.placements()[p]);
                spawn_point(zone, around, rng)
            }
            None => (0.0, 0.0, rng.random_range(-std::f64::consts::PI..std::f64::consts::PI)),
        };
        world.reset(rng, x, y, heading);
        world.set_grip(self.settings.grip);
        let settings = Arc::clone(&self.settings);
        let r = &settings.reference;
        let last = r.frames() - 1;
        let from_pool = match &settings.init {
            Init::Pools { fraction, speed, .. } => {
                let total: usize = settings.pools.iter().map(|p| p.states.len()).sum();
                if total > 0 && rng.random_bool(*fraction) {
                    let scale = if speed.0 < speed.1 { rng.random_range(speed.0..=speed.1) } else { speed.0 };
                    let mut k = rng.random_range(0..total);
                    let mut chosen = None;
                    for pool in &settings.pools {
                        if k < pool.states.len() {
                            chosen = Some(&pool.states[k]);
                            break;
                        }
                        k -= pool.states.len();
                    }
                    chosen.map(|s| (s, scale))
                } else {
                    None
                }
            }
            _ => None,
        };
        match (from_pool, &settings.init) {
            (Some((state, k)), _) => {
                apply_pool_state(state, world, x, y, heading, k);
                // The clip starts where the pool state stands: at its first frame, or, for a
                // cycle (walk), at the frame nearest the state's pose, so a character arriving
                // mid-stride is not asked to switch feet.
                let f = if r.looping { r.nearest_frame(&state.joints, &state.joint_vel) } else { 0 };
                self.yaw = heading - r.heading[f];
                self.anchor = [r.root_pos[f][0], r.root_pos[f][1]];
                self.origin = [x, y];
                self.phase = f;
            }
            (None, Init::Start) => self.place_reference(world, 0, x, y, heading),
            (None, _) => {
                let f = rng.random_range(0..last);
                self.place_reference(world, f, x, y, heading)
            }
        }
        self.seat_offset = match settings.goal {
            Goal::Seat { jitter_m, jitter_deg, .. } if jitter_m > 0.0 || jitter_deg > 0.0 => {
                // Full jitter while standing, none once seated: the rest of the clip must be
                // able to make up the difference.
                jitter(rng, 1.0 - r.lowness(self.phase), jitter_m, jitter_deg)
            }
            _ => [0.0; 3],
        };
        // A delivered state (recorded by a meta-controller) meets the seat where it stood.
        if let (Some((state, _)), Some((_, [sx, sy, syaw]))) = (from_pool, settings.seat)
            && let Some([wx, wy, wyaw]) = state.seat_in_world(x, y, heading)
        {
            let [ex, ey] = self.to_world([sx, sy]);
            self.seat_offset = [wx - ex, wy - ey, wrap_angle(wyaw - syaw - self.yaw)];
        }
        if let (Some((state, _)), None, Some(prop)) = (from_pool, settings.seat, settings.delivered_seat)
            && let Some([wx, wy, wyaw]) = state.seat_in_world(x, y, heading)
        {
            world.move_prop(prop, wx, wy, wyaw).expect("the delivered seat is a validated fixed prop");
        }
        // The pedestal's jitter: full before the clip's hands reach it, none once they hold
        // (lift) or have let go of (put_down) the box, which the rest of the clip assumes.
        self.pedestal_offset =
            match (settings.goal.pedestal_jitter(), settings.object.as_ref().and_then(|o| o.pedestal)) {
                ((jm, jd), Some((_, g))) if (jm > 0.0 || jd > 0.0) && self.phase < g => {
                    jitter(rng, (g - self.phase) as f64 / g as f64, jm, jd)
                }
                _ => [0.0; 3],
            };
        self.place_seat(world);
        if let (Some((prop, _)), Goal::Seat { clear_start: true, .. }) = (settings.seat, &settings.goal) {
            self.separate_from_seat(world, prop);
        }
        self.place_object(world, rng);
        self.cycles = 0;
        self.held = 0;
        self.start_frame = self.phase;
        self.start_heading = world.heading();
        self.reached = 0;
        self.touched = false;
        if let Some(st) = settings.goal.steering() {
            self.target = draw_target(rng, [x, y], heading, st.distance_m, st.azimuth_deg);
            self.target_steps = 0;
            if st.reach_m > 0.0 || st.retarget_s > 0.0 {
                self.target_rng = EnvRng::seed_from_u64(rng.random());
            }
        }
        if let Some(o) = &settings.obstacle {
            place_obstacle(o, self.target, world, rng, true);
        }
        self.last_distance = self.goal_distance(world);
    }

    fn step(&mut self, world: &mut World, _action: &[f32]) -> TaskStep {
        let settings = Arc::clone(&self.settings);
        let r = &settings.reference;
        // Advance the phase to the frame the character should now be at.
        let mut done_with_clip = false;
        if r.looping {
            self.phase += 1;
            if self.phase >= self.cycle_len() {
                self.phase = 0;
                self.cycles += 1;
            }
        } else {
            let last = r.frames() - 1;
            if self.phase == last {
                self.held += 1;
            }
            self.phase = (self.phase + 1).min(last);
            done_with_clip = self.phase == last && self.held >= r.hold_steps;
        }
        let target = self.target;
        let mut out = self.score(world, self.phase);
        if let Some(o) = &settings.obstacle
            && self.target != target
            && !out.terminated
        {
            // A new target (arrival or timeout): perhaps the obstacle moves into its way.
            place_obstacle(o, self.target, world, &mut self.target_rng, false);
        }
        out.truncated = done_with_clip && !out.terminated;
        out
    }

    fn snapshot(&self, out: &mut Vec<f64>) {
        out.extend_from_slice(&[
            self.phase as f64,
            self.cycles as f64,
            self.yaw,
            self.anchor[0],
            self.anchor[1],
            self.origin[0],
            self.origin[1],
            self.start_heading,
            self.start_frame as f64,
            self.target[0],
            self.target[1],
            self.last_distance,
            self.held as f64,
            self.target_steps as f64,
        ]);
    }

    fn restore(&mut self, s: &[f64]) -> Result<(), StateError> {
        if s.len() != 14 {
            return Err(StateError::length("imitation task snapshot", 14, s.len()));
        }
        self.phase = s[0] as usize;
        self.cycles = s[1] as usize;
        self.yaw = s[2];
        self.anchor = [s[3], s[4]];
        self.origin = [s[5], s[6]];
        self.start_heading = s[7];
        self.start_frame = s[8] as usize;
        self.target = [s[9], s[10]];
        self.last_distance = s[11];
        self.held = s[12] as usize;
        self.target_steps = s[13] as usize;
        if self.phase >= self.settings.reference.frames() {
            return Err(StateError::OutOfRange {
                what: "imitation task snapshot's phase".into(),
                value: s[0],
                count: self.settings.reference.frames(),
                of: "clip frames",
            });
        }
        Ok(())
    }
}

/// A catch throw at `target` from the direction `yaw` that arrives after `flight` seconds: the
/// forward speed, sideways speed, rise and spin are drawn from `spec`, the distance is what the
/// forward speed covers in `flight`.
pub fn catch_throw(
    spec: &ThrowSpec,
    target: [f64; 3],
    yaw: f64,
    flight: f64,
    rng: &mut EnvRng,
) -> repertoire_scenes::Throw {
    let v_x = spec.v_x.sample(rng);
    let lateral = spec.lateral.sample(rng);
    let d_z = spec.d_z.sample(rng);
    spec.throw_with(target, yaw, v_x * flight, v_x, lateral, d_z, rng)
}

/// A prop's offset `[x, y, yaw]` off its spot: up to `scale · radius_m` away (uniform in a disc)
/// and turned by up to ±`scale · turn_deg` (the seat's and the pedestal's jitter).
fn jitter(rng: &mut EnvRng, scale: f64, radius_m: f64, turn_deg: f64) -> [f64; 3] {
    let radius = scale * radius_m * rng.random_range(0.0f64..=1.0).sqrt();
    let angle = rng.random_range(-std::f64::consts::PI..std::f64::consts::PI);
    let turn = scale * turn_deg.to_radians() * rng.random_range(-1.0f64..=1.0);
    [radius * angle.cos(), radius * angle.sin(), turn]
}

/// Pushes a pedestal the jitter moved into the character away from the pelvis, 2 cm at a time
/// and at most 20 cm, so that MuJoCo does not shoot the two apart at the first step.
fn clear_pedestal(world: &mut World, ped: usize) {
    for _ in 0..10 {
        if world.penetration_with_prop(ped, None) <= 0.002 {
            break;
        }
        let pl = world.placements()[ped];
        let pelvis = world.pelvis_frame().pos;
        let (dx, dy) = (pl.pos[0] - pelvis[0], pl.pos[1] - pelvis[1]);
        let n = (dx * dx + dy * dy).sqrt().max(1e-9);
        world
            .move_prop(ped, pl.pos[0] + 0.02 * dx / n, pl.pos[1] + 0.02 * dy / n, pl.yaw)
            .expect("the pedestal is validated");
    }
}

fn apply_pool_state(state: &PoolState, world: &mut World, x: f64, y: f64, heading: f64, k: f64) {
    state.apply_at_speed(world, x, y, heading, k).expect("pool states are validated on load");
}
