//! The task a meta environment runs: where an episode starts, what the meta-controller observes
//! beyond proprioception, the per-tick success and failure tests, the decision reward and the
//! per-episode figures. [`TaskSpec`] is resolved once from the scenario; every environment keeps
//! a [`TaskState`] for its current episode. Sitting, the warehouse and the toss are the three.

use rand::Rng;
use repertoire_scenes::math::wrap_angle;
use repertoire_scenes::scenario::{Task as ScenarioTask, WarehousePhase};
use repertoire_scenes::{Feature, SitApproach, SitFall, World, WorldModel};
use repertoire_skill::reference::to_heading;

use crate::error::{MetaError, Result};
use crate::judge::SitJudge;
use crate::tasks::toss::{TossFacts, TossJudge, TossSpec, ball_velocity};
use crate::tasks::warehouse::{WarehouseFacts, WarehouseJudge, WarehouseSpec, place_from_pool, place_holding};

/// Names of the sitting task's per-episode figures in `StepOutcome::terms`.
pub const SIT_TERMS: [&str; 5] = ["success", "min_distance", "fell", "seconds", "switches"];
/// Names of the warehouse task's per-episode figures.
pub const WAREHOUSE_TERMS: [&str; 7] = ["success", "phases", "fell", "seconds", "switches", "dropped", "start_phase"];
/// Names of the toss task's per-episode figures.
pub const TOSS_TERMS: [&str; 7] = ["success", "caught", "fell", "seconds", "switches", "dropped", "bucket_s"];

/// Horizontal distance from a pedestal's centre at which a LIFT episode starts (m).
const LIFT_START_M: f64 = 0.45;
/// Horizontal distance from the target pedestal's centre at which a PUTDOWN episode starts (m).
const PUTDOWN_START_M: f64 = 0.55;

/// A task resolved to prop indices of one scene.
#[derive(Debug, Clone, PartialEq)]
pub enum TaskSpec {
    /// Sit on a chair: 1 per decision seated, else `0.5·(−V_sit)` (or the approach to where a
    /// sit starts, [`SitApproach::Spot`]); success after `hold_s`
    /// seconds seated without a break. Seated: the pelvis on the seat, heading within `facing`
    /// of the chair's front ([`World::seated_on`]).
    Sit {
        /// The chair (prop index).
        seat: usize,
        /// Seconds of contact that count as success.
        hold_s: f64,
        /// Largest angle between the pelvis heading and the chair's front that counts as
        /// seated (radians; π: any contact).
        facing: f64,
        /// What the reward pays for while not seated.
        approach: SitApproach,
        /// What a fall does to the approach reward paid so far.
        on_fall: SitFall,
        /// Taken from a decision's reward when the character touched the chair during it
        /// outside the sit (the scenario's `touch_penalty`; see [`TaskState::decision_reward`]).
        touch_penalty: f64,
    },
    /// The warehouse (see [`crate::tasks::warehouse`]).
    Warehouse(WarehouseSpec),
    /// The toss (see [`crate::tasks::toss`]).
    Toss(TossSpec),
}

/// What an episode is made to start with instead of drawing it (evaluation grids).
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct EpisodeOverride {
    /// Start at `(x, y)` in the frame of the task's [`TaskSpec::frame_prop`] (x: its front, y:
    /// its left) facing the prop turned by the third value (radians, counter-clockwise), instead
    /// of in a spawn zone.
    pub start: Option<(f64, f64, f64)>,
    /// The warehouse phase to start in.
    pub phase: Option<WarehousePhase>,
    /// The toss's forward and sideways ball speeds (m/s).
    pub throw: Option<(f64, f64)>,
}

impl TaskSpec {
    /// The meta-controller's task of `model`'s scenario; `Free` has none.
    pub fn of(model: &WorldModel) -> Result<Self> {
        let sc = &model.scenario;
        match &sc.scenario.task {
            ScenarioTask::Sit { seat, hold_s, facing_deg, approach, on_fall, touch_penalty, .. } => {
                let seat = model.prop_id(seat).ok_or_else(|| MetaError::Invalid(format!("no seat prop `{seat}`")))?;
                Ok(TaskSpec::Sit {
                    seat,
                    hold_s: *hold_s,
                    facing: facing_deg.to_radians(),
                    approach: *approach,
                    on_fall: *on_fall,
                    touch_penalty: *touch_penalty,
                })
            }
            ScenarioTask::Warehouse(w) => Ok(TaskSpec::Warehouse(WarehouseSpec::new(model, w)?)),
            ScenarioTask::Toss(t) => Ok(TaskSpec::Toss(TossSpec::new(model, t)?)),
            ScenarioTask::Free { .. } => Err(MetaError::Invalid(format!(
                "{}: the meta-controller needs a Sit, Warehouse or Toss task, found Free",
                sc.path.display()
            ))),
        }
    }

    /// Reads what the task takes from the skill library: the warehouse's `hold_from` end
    /// states ([`WarehouseSpec::load_hold_pool`]).
    pub fn load_from_library(&mut self, model: &WorldModel, library: &std::path::Path) -> Result<()> {
        match self {
            TaskSpec::Warehouse(w) => w.load_hold_pool(model, library),
            _ => Ok(()),
        }
    }

    /// The task's name (`sit`, `warehouse`, `toss`).
    pub fn name(&self) -> &'static str {
        match self {
            TaskSpec::Sit { .. } => "sit",
            TaskSpec::Warehouse(_) => "warehouse",
            TaskSpec::Toss(_) => "toss",
        }
    }

    /// Features the controller observes after proprioception (the props' poses read by the
    /// world's layout).
    pub fn features(&self, model: &WorldModel) -> Vec<Feature> {
        let name = |p: usize| model.props[p].name.clone();
        match self {
            TaskSpec::Sit { seat, .. } => vec![Feature::PropPose(name(*seat))],
            TaskSpec::Warehouse(_) => Vec::new(),
            TaskSpec::Toss(t) => vec![Feature::PropPose(name(t.ball)), Feature::PropPose(name(t.bucket))],
        }
    }

    /// Observation values the task computes itself, after the layout's: the warehouse's phase
    /// one-hot, focal pedestal and box in the pelvis frame; the toss's ball velocity and caught flag.
    pub fn extra_dim(&self) -> usize {
        match self {
            TaskSpec::Sit { .. } => 0,
            TaskSpec::Warehouse(_) => WarehousePhase::ALL.len() + 5 + 5,
            TaskSpec::Toss(_) => 3 + 1,
        }
    }

    /// Names of the per-episode figures (`StepOutcome::terms`); success, fell, seconds and
    /// switches are at 0, 2, 3 and 4 for every task.
    pub fn term_names(&self) -> &'static [&'static str] {
        match self {
            TaskSpec::Sit { .. } => &SIT_TERMS,
            TaskSpec::Warehouse(_) => &WAREHOUSE_TERMS,
            TaskSpec::Toss(_) => &TOSS_TERMS,
        }
    }

    /// Names of the four values recorded per control tick in recordings.
    pub fn recorded_terms(&self) -> [&'static str; 4] {
        match self {
            TaskSpec::Sit { .. } => ["seat_distance", "seated", "seated_s", "min_distance"],
            TaskSpec::Warehouse(_) => ["phase", "phases_done", "focal_distance", "hands_on_box"],
            TaskSpec::Toss(_) => ["caught", "bucket_s", "ball_to_bucket", "hands_on_ball"],
        }
    }

    /// What a decision that bumps into the chair outside the sit costs (the sit task's
    /// `touch_penalty`; 0 for the other tasks).
    pub fn touch_penalty(&self) -> f64 {
        match self {
            TaskSpec::Sit { touch_penalty, .. } => *touch_penalty,
            _ => 0.0,
        }
    }

    /// The prop whose frame start positions are reported in (the chair, the box's first
    /// pedestal, the bucket).
    pub fn frame_prop(&self) -> usize {
        match self {
            TaskSpec::Sit { seat, .. } => *seat,
            TaskSpec::Warehouse(w) => w.pedestals[w.home],
            TaskSpec::Toss(t) => t.bucket,
        }
    }

    /// The prop the focal pedestal role ([`repertoire_scenes::scenario::PropBinding::Focal`])
    /// names before an episode runs (the box's first pedestal); `None`: the task has no such role.
    pub fn focal_home(&self) -> Option<usize> {
        match self {
            TaskSpec::Warehouse(w) => Some(w.pedestals[w.home]),
            TaskSpec::Sit { .. } | TaskSpec::Toss(_) => None,
        }
    }

    /// Whether an episode ends as soon as it succeeds (sitting); the warehouse and the toss run
    /// to the time limit, collecting reward.
    pub fn ends_on_success(&self) -> bool {
        matches!(self, TaskSpec::Sit { .. })
    }

    /// A fresh state for an episode (before [`TaskState::prepare`]).
    pub fn new_state(&self, control_hz: f64) -> TaskState {
        match self {
            TaskSpec::Sit { hold_s, .. } => {
                TaskState::Sit { judge: SitJudge::new(*hold_s, control_hz), last_potential: 0.0, paid: 0.0 }
            }
            TaskSpec::Warehouse(w) => TaskState::Warehouse(WarehouseJudge::new(
                WarehousePhase::Goto,
                w.home,
                (w.home + 1) % w.pedestals.len(),
            )),
            TaskSpec::Toss(_) => TaskState::Toss(TossJudge::new(0.0, 0.0, 0.0)),
        }
    }
}

/// One episode's task state.
#[derive(Debug, Clone, PartialEq)]
pub enum TaskState {
    /// Sitting: the success judge and the last decision's approach potential.
    Sit {
        /// The success judge.
        judge: SitJudge,
        /// [`sit_potential`] at the end of the last decision (m).
        last_potential: f64,
        /// Approach reward paid so far this episode (what [`SitFall::Forfeit`] takes back).
        paid: f64,
    },
    /// The warehouse's phase judge.
    Warehouse(WarehouseJudge),
    /// The toss's judge.
    Toss(TossJudge),
}

/// Distance from the pelvis to the seat's top centre.
fn seat_distance(world: &World, seat: usize) -> f64 {
    let p = world.pelvis_frame().pos;
    let pl = world.placements()[seat];
    ((p[0] - pl.pos[0]).powi(2) + (p[1] - pl.pos[1]).powi(2) + (p[2] - pl.top).powi(2)).sqrt()
}

/// What the sit reward's approach term measures (it pays `0.5·(−dΦ/dt)`): the pelvis–seat
/// distance, or the distance to where a sit starts plus the heading error ([`SitApproach`]).
pub fn sit_potential(world: &World, seat: usize, approach: &SitApproach) -> f64 {
    match approach {
        SitApproach::Seat => seat_distance(world, seat),
        SitApproach::Spot { ahead_m, heading_m, turn_within_m, around } => {
            let p = world.pelvis_frame().pos;
            let pl = world.placements()[seat];
            let spot = [pl.pos[0] + ahead_m * pl.yaw.cos(), pl.pos[1] + ahead_m * pl.yaw.sin()];
            let d = match around {
                Some(a) => {
                    let centre = [pl.pos[0] - a.behind_m * pl.yaw.cos(), pl.pos[1] - a.behind_m * pl.yaw.sin()];
                    distance_round_disc([p[0], p[1]], spot, centre, a.radius_m)
                }
                None => (p[0] - spot[0]).hypot(p[1] - spot[1]),
            };
            let heading = world.heading();
            let away = wrap_angle(heading - pl.yaw).abs();
            let error = match turn_within_m {
                // Blending the two errors (not the two headings) keeps Φ continuous: the bearing
                // jumps only at the spot itself, where its weight is zero.
                Some(r) => {
                    let far = (d / r).min(1.0);
                    let toward = wrap_angle(heading - (spot[1] - p[1]).atan2(spot[0] - p[0])).abs();
                    (1.0 - far) * away + far * toward
                }
                None => away,
            };
            d + heading_m * error
        }
    }
}

/// Length of the shortest way from `from` to `to` (a point outside the disc) that does not cross
/// the disc of radius `radius` about `centre`: the straight line where it clears the disc, else
/// the tangent from `from`, the arc and the tangent to `to`. From inside the disc it is the way
/// out along the radius plus the way on from where it leaves (so it is continuous across the
/// circle; at the very centre it leaves towards `to`).
pub fn distance_round_disc(from: [f64; 2], to: [f64; 2], centre: [f64; 2], radius: f64) -> f64 {
    let (mut fx, mut fy) = (from[0] - centre[0], from[1] - centre[1]);
    let (tx, ty) = (to[0] - centre[0], to[1] - centre[1]);
    let rt = tx.hypot(ty).max(radius);
    let mut rf = fx.hypot(fy);
    let mut out = 0.0;
    if rf < radius {
        // Out along the radius first (not by recursion: the exit point, rounded, may lie a hair
        // inside the circle again).
        let (ux, uy) = if rf > 1e-12 { (fx / rf, fy / rf) } else { (tx / rt, ty / rt) };
        out = radius - rf;
        (fx, fy, rf) = (radius * ux, radius * uy, radius);
    }
    let from = [centre[0] + fx, centre[1] + fy];
    // The angle between the two points seen from the centre, and how much of it each point's
    // tangent covers: the straight way is blocked exactly when the tangents do not meet.
    let between = (fx * ty - fy * tx).atan2(fx * tx + fy * ty).abs();
    let (af, at) = ((radius / rf).min(1.0).acos(), (radius / rt).min(1.0).acos());
    out + if between <= af + at {
        (to[0] - from[0]).hypot(to[1] - from[1])
    } else {
        (rf * rf - radius * radius).max(0.0).sqrt()
            + (rt * rt - radius * radius).max(0.0).sqrt()
            + radius * (between - af - at)
    }
}

impl TaskState {
    /// Starts an episode's task after the world was reset in a spawn zone with the character at
    /// `start`: draws the warehouse's start phase and puts the character (and box) where that
    /// phase begins. Returns whether the character was moved (then no start-pool state applies).
    pub fn prepare(
        &mut self,
        spec: &TaskSpec,
        world: &mut World,
        rng: &mut impl Rng,
        control_hz: f64,
        start: (f64, f64, f64),
        over: &EpisodeOverride,
    ) -> bool {
        *self = spec.new_state(control_hz);
        let (TaskSpec::Warehouse(w), TaskState::Warehouse(judge)) = (spec, &mut *self) else {
            return false;
        };
        let phase = over.phase.unwrap_or_else(|| {
            let k = if w.start_phases.len() > 1 { rng.random_range(0..w.start_phases.len()) } else { 0 };
            w.start_phases[k]
        });
        let n = w.pedestals.len();
        let source = w.home;
        let target = if n > 2 { (source + rng.random_range(1..n)) % n } else { (source + 1) % n };
        *judge = WarehouseJudge::new(phase, source, target);
        let near = |world: &World, pedestal: usize, d: f64, rng: &mut dyn rand::RngCore| {
            let at = world.placements()[w.pedestals[pedestal]].pos;
            let a = rng.random_range(-std::f64::consts::PI..std::f64::consts::PI);
            (at[0] + d * a.cos(), at[1] + d * a.sin(), a + std::f64::consts::PI)
        };
        let placed = match phase {
            WarehousePhase::Goto => return false,
            WarehousePhase::Lift => {
                let (x, y, yaw) = near(world, source, LIFT_START_M, rng);
                world.place_standing(x, y, yaw);
                Ok(())
            }
            WarehousePhase::Carry | WarehousePhase::PutDown => {
                let (x, y, yaw) = match phase {
                    WarehousePhase::Carry => start,
                    _ => near(world, target, PUTDOWN_START_M, rng),
                };
                match &w.hold_pool {
                    Some(pool) => place_from_pool(world, pool, w.box_prop, x, y, yaw, rng),
                    None => place_holding(world, w.box_prop, x, y, yaw),
                }
            }
        };
        match placed {
            Ok(()) => true,
            Err(e) => {
                // A body the holding pose does not fit starts in GOTO instead (said in the log).
                tracing::warn!(phase = phase.label(), error = %e, "cannot start holding the box; starting in GOTO");
                *judge = WarehouseJudge::new(WarehousePhase::Goto, source, target);
                world.place_standing(start.0, start.1, start.2);
                true
            }
        }
    }

    /// Finishes an episode's start once the character stands where it begins: the sitting
    /// judge's first tick, the toss's throw.
    pub fn begin(&mut self, spec: &TaskSpec, world: &mut World, rng: &mut impl Rng, over: &EpisodeOverride) {
        match (spec, self) {
            (TaskSpec::Sit { seat, approach, .. }, TaskState::Sit { judge, last_potential, .. }) => {
                *last_potential = sit_potential(world, *seat, approach);
                judge.tick(false, seat_distance(world, *seat));
            }
            (TaskSpec::Toss(t), TaskState::Toss(judge)) => {
                // A launch only fails on a non-positive flight time, which validation rules out.
                let (v_x, lateral) = match t.launch(world, rng, over.throw) {
                    Ok(throw) => (throw.v_x, throw.lateral),
                    Err(e) => {
                        tracing::warn!(error = %e, "throw refused");
                        (0.0, 0.0)
                    }
                };
                let facts = TossFacts::measure(world, t);
                *judge = TossJudge::new(v_x, lateral, facts.to_bucket_m);
            }
            _ => {}
        }
    }

    /// Judges one control tick of `dt` seconds; returns whether the episode has failed by the
    /// task's own test (the box or ball on the floor; falls are the environment's).
    pub fn tick(&mut self, spec: &TaskSpec, world: &World, dt: f64) -> bool {
        match (spec, self) {
            (TaskSpec::Sit { seat, facing, .. }, TaskState::Sit { judge, .. }) => {
                judge.tick(world.seated_on(*seat, *facing), seat_distance(world, *seat));
                false
            }
            (TaskSpec::Warehouse(w), TaskState::Warehouse(judge)) => {
                let facts = WarehouseFacts::measure(world, w, judge.source, judge.target);
                judge.tick(&facts, w);
                judge.failed
            }
            (TaskSpec::Toss(t), TaskState::Toss(judge)) => {
                judge.tick(&TossFacts::measure(world, t), dt);
                judge.failed
            }
            _ => false,
        }
    }

    /// The focal pedestal's prop now (the box's pedestal during GOTO and LIFT, the target's
    /// during CARRY and PUTDOWN); `None` outside the warehouse.
    pub fn focal_prop(&self, spec: &TaskSpec) -> Option<usize> {
        match (spec, self) {
            (TaskSpec::Warehouse(w), TaskState::Warehouse(judge)) => w.pedestals.get(judge.focal()).copied(),
            _ => None,
        }
    }

    /// Whether the episode has succeeded: 3 s seated; a full warehouse cycle (four phases);
    /// the ball in the bucket.
    pub fn succeeded(&self) -> bool {
        match self {
            TaskState::Sit { judge, .. } => judge.succeeded,
            TaskState::Warehouse(j) => j.completed >= WarehousePhase::ALL.len() as u32,
            TaskState::Toss(j) => j.delivered(),
        }
    }

    /// The reward of a decision that ran `seconds` and ended with a fall when `fell`. `bumped`:
    /// the character touched the task's frame prop (the chair) during the decision while a
    /// skill that is not terminal played; sitting pays the scenario's `touch_penalty` for it.
    pub fn decision_reward(&mut self, spec: &TaskSpec, world: &World, fell: bool, bumped: bool, seconds: f64) -> f32 {
        match (spec, self) {
            (
                TaskSpec::Sit { seat, facing, approach, on_fall, touch_penalty, .. },
                TaskState::Sit { last_potential, paid, .. },
            ) => {
                let d = sit_potential(world, *seat, approach);
                let on_seat = world.seated_on(*seat, *facing);
                let reward = if fell {
                    match on_fall {
                        SitFall::Keep => 0.0,
                        SitFall::Forfeit => -std::mem::take(paid),
                    }
                } else if on_seat {
                    1.0
                } else {
                    let r = 0.5 * -(d - *last_potential) / seconds;
                    *paid += r;
                    r
                };
                *last_potential = d;
                let bump = if bumped { *touch_penalty } else { 0.0 };
                (reward - bump) as f32
            }
            (TaskSpec::Warehouse(_), TaskState::Warehouse(judge)) => judge.take_reward(),
            (TaskSpec::Toss(t), TaskState::Toss(judge)) => {
                judge.take_reward(TossFacts::measure(world, t).to_bucket_m, seconds)
            }
            _ => 0.0,
        }
    }

    /// Writes the task's per-episode figures into `terms` (index 1 and from 5 on).
    pub fn terms(&self, terms: &mut [f32]) {
        match self {
            TaskState::Sit { judge, .. } => terms[1] = judge.min_distance as f32,
            TaskState::Warehouse(j) => {
                terms[1] = j.completed as f32;
                terms[5] = f32::from(u8::from(j.dropped));
                terms[6] = j.start_phase.index() as f32;
            }
            TaskState::Toss(j) => {
                terms[1] = f32::from(u8::from(j.caught));
                terms[5] = f32::from(u8::from(j.dropped));
                terms[6] = j.bucket_s as f32;
            }
        }
    }

    /// The task's observation values (see [`TaskSpec::extra_dim`]).
    pub fn observe(&self, spec: &TaskSpec, world: &World, out: &mut [f32]) {
        match (spec, self) {
            (TaskSpec::Warehouse(w), TaskState::Warehouse(judge)) => {
                let k = WarehousePhase::ALL.len();
                out[..k].fill(0.0);
                out[judge.phase.index()] = 1.0;
                let pedestal = world.prop_relative(w.pedestals[judge.focal()]);
                let crate_ = world.prop_relative(w.box_prop);
                for (o, v) in out[k..k + 10].iter_mut().zip(pedestal.iter().chain(&crate_)) {
                    *o = *v as f32;
                }
            }
            (TaskSpec::Toss(t), TaskState::Toss(judge)) => {
                let v = to_heading(world.heading(), ball_velocity(world, t));
                for (o, x) in out[..3].iter_mut().zip(v) {
                    *o = x as f32;
                }
                out[3] = f32::from(u8::from(judge.caught));
            }
            _ => {}
        }
    }

    /// The four values recorded per control tick (see [`TaskSpec::recorded_terms`]).
    pub fn recorded(&self, spec: &TaskSpec, world: &World, control_dt: f64) -> [f32; 4] {
        match (spec, self) {
            (TaskSpec::Sit { seat, facing, .. }, TaskState::Sit { judge, .. }) => [
                seat_distance(world, *seat) as f32,
                f32::from(u8::from(world.seated_on(*seat, *facing))),
                (f64::from(judge.streak()) * control_dt) as f32,
                judge.min_distance as f32,
            ],
            (TaskSpec::Warehouse(w), TaskState::Warehouse(judge)) => {
                let facts = WarehouseFacts::measure(world, w, judge.source, judge.target);
                let focal = if judge.focal() == judge.source { facts.to_source_m } else { facts.to_target_m };
                let hands = facts.hands_on_box.iter().filter(|&&h| h).count();
                [judge.phase.index() as f32, judge.completed as f32, focal as f32, hands as f32]
            }
            (TaskSpec::Toss(t), TaskState::Toss(judge)) => {
                let facts = TossFacts::measure(world, t);
                let hands = facts.hands_on_ball.iter().filter(|&&h| h).count();
                [f32::from(u8::from(judge.caught)), judge.bucket_s as f32, facts.to_bucket_m as f32, hands as f32]
            }
            _ => [0.0; 4],
        }
    }

    /// The state as numbers (checkpoints); [`TaskState::restore`] reads it back.
    pub fn snapshot(&self) -> Vec<f64> {
        match self {
            TaskState::Sit { judge, last_potential, paid } => vec![
                *last_potential,
                f64::from(judge.streak()),
                f64::from(u8::from(judge.succeeded)),
                judge.min_distance,
                *paid,
            ],
            TaskState::Warehouse(j) => j.snapshot().to_vec(),
            TaskState::Toss(j) => j.snapshot().to_vec(),
        }
    }

    /// Number of values [`TaskState::snapshot`] writes.
    pub fn snapshot_len(&self) -> usize {
        match self {
            TaskState::Sit { .. } => 5,
            TaskState::Warehouse(_) | TaskState::Toss(_) => 8,
        }
    }

    /// Restores a [`TaskState::snapshot`] of the same task.
    pub fn restore(&mut self, s: &[f64]) {
        match self {
            TaskState::Sit { judge, last_potential, paid } => {
                *last_potential = s[0];
                judge.restore(s[1] as u32, s[2] != 0.0, s[3]);
                *paid = s[4];
            }
            TaskState::Warehouse(j) => j.restore(s),
            TaskState::Toss(j) => j.restore(s),
        }
    }
}
