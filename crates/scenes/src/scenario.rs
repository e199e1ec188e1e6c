//! The scenario file: body, props, spawn zones, rates, task, skills and curriculum, in RON.
//!
//! A scenario is parsed strictly (unknown fields are rejected) and then checked for consistency
//! (references between its parts, rates that divide). Every error names the file, the line and
//! the column, and says what is wrong in one sentence.

use crate::error::{Location, Result, SceneError};
use crate::param::Param;
use crate::throw::ThrowSpec;
use rand::Rng;
use serde::{Deserialize, Serialize};
use std::collections::{BTreeMap, HashSet};
use std::path::{Path, PathBuf};

/// How far (degrees) the pelvis heading may be from the chair's front for a pelvis on the seat
/// to count as seated: the sit task's default `facing_deg`, and `skill eval`'s test for a sit.
pub const SEATED_FACING_DEG: f64 = 60.0;

/// Why `name` cannot name a skill, or `None` when it can. A skill's name is its folder in a
/// library and its name in specs, graphs and reports: a lowercase letter, then lowercase
/// letters, digits and `_`. Which skills exist is the library's to say, when it loads them.
pub fn skill_name_problem(name: &str) -> Option<String> {
    let mut chars = name.chars();
    let ok = chars.next().is_some_and(|c| c.is_ascii_lowercase())
        && chars.all(|c| c.is_ascii_lowercase() || c.is_ascii_digit() || c == '_');
    (!ok).then(|| {
        format!(
            "skill name `{name}`: a skill is named by a lowercase letter, then lowercase letters, digits and `_` \
             (it is a library folder)"
        )
    })
}

/// A whole scenario as written in its RON file.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Scenario {
    /// Short name, used in run folders and reports.
    pub name: String,
    /// One or two sentences for people reading the file.
    #[serde(default)]
    pub description: String,
    /// The character's body.
    #[serde(default)]
    pub body: BodySource,
    /// Physics, control and meta-controller rates.
    #[serde(default)]
    pub rates: Rates,
    /// Props placed in the world.
    #[serde(default)]
    pub props: Vec<Prop>,
    /// Where the character may start an episode.
    #[serde(default)]
    pub spawn: Vec<Zone>,
    /// What the character must do and how success is judged.
    #[serde(default)]
    pub task: Task,
    /// The skills the meta-controller may use.
    #[serde(default)]
    pub skills: Vec<String>,
    /// Which skill may follow which (absent: any listed skill may follow any other).
    #[serde(default)]
    pub skill_graph: Option<SkillGraphSpec>,
    /// Zone curriculum for training the meta-controller.
    #[serde(default)]
    pub curriculum: Option<Curriculum>,
    /// What the high level drives: the discrete skills (default) or a learned latent space.
    #[serde(default)]
    pub low_level: LowLevel,
    /// What the props a skill observes (named after its training scene's props, e.g. lift's
    /// `"pedestal"`) stand for here; a name not bound means this scenario's prop of that name.
    #[serde(default, skip_serializing_if = "BTreeMap::is_empty")]
    pub bind: BTreeMap<String, PropBinding>,
    /// Steering around props: the target a target-taking skill (walk_to) is given at each
    /// decision is turned aside when the straight way to it passes close to one of them.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub detour: Option<Detour>,
    /// What counts as a fall ([`crate::fall`]; every task, skill and evaluation in this scene
    /// uses it). Absent: the defaults.
    #[serde(default, skip_serializing_if = "crate::fall::FallRule::is_default")]
    pub fall: crate::fall::FallRule,
}

/// Steering around props (a navigation layer under the meta-controller). At every decision the
/// 2-D target a target-taking skill (walk_to) is given is checked against a circle of
/// `radius_m` around each prop of `around`: when the straight line from the pelvis to the
/// target passes through one before the target is reached, the target is turned, at the same
/// distance, onto the circle's tangent on the side the line passed, so the walker skirts the
/// prop; re-checked every decision, the tangents trace a way round it (from inside a circle the
/// target turns square to the centre and outwards). A target short of the way's closest point
/// to the prop (in front of it, approached from that side) stands. `detour: (around: ["chair"],
/// radius_m: 0.7)` is meant to keep a walker from cutting past the chair (a walk skill trained
/// in an empty arena does not see it); with the library's walk_to it did not (stop 39).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Detour {
    /// Props to walk around (names of the scenario's props).
    pub around: Vec<String>,
    /// Radius of the circle kept clear around each prop's centre (m).
    pub radius_m: f64,
}

/// What a prop named in a skill's observation resolves to in a scenario (see `Scenario::bind`).
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub enum PropBinding {
    /// This scenario's prop of that name, always.
    Prop(String),
    /// The warehouse task's focal pedestal: the box's pedestal during GOTO and LIFT, the target
    /// during CARRY and PUTDOWN. It is read when a skill starts playing and held while it plays,
    /// so a frozen skill never sees its pedestal jump mid-motion when a phase completes.
    Focal,
}

/// The low level a scenario's high-level controller acts through.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize, Default)]
pub enum LowLevel {
    /// The meta-controller picks among the frozen skills of the library (and a 2-D target).
    #[default]
    Skills,
    /// A high-level policy emits a latent `z ∈ (−2, 2)^d` that the frozen decoder of the
    /// latent model in this folder (holding `latent.ron`, relative to the scenario file) turns
    /// into joint actions each control tick.
    Latent(PathBuf),
}

/// The skill graph of a scenario: the skills an episode may start with and the allowed
/// transitions. Continuing the current skill is always allowed. A fixed-order chain
/// (walk → turn_left → sit) is a graph with one path.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SkillGraphSpec {
    /// Skills an episode may start with.
    pub start: Vec<String>,
    /// Allowed transitions `(from, to)`.
    pub edges: Vec<(String, String)>,
    /// Preconditions on switching to a skill (a state machine's transition conditions): a
    /// guarded skill may be chosen only while its guard holds; once chosen it may continue.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub guards: Vec<SkillGuard>,
}

/// A precondition on switching to `skill`: the pelvis within `within_m` (horizontally) of the
/// prop `near`'s centre (a prop of the scenario, or a name its `bind` map binds: `"pedestal"`
/// bound to `Focal` is the warehouse's focal pedestal at the decision).
/// `(skill: "sit", near: "chair", within_m: 0.9)` keeps a controller from
/// starting a sit a metre or more from the chair, which no sit absorbs.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SkillGuard {
    /// The guarded skill.
    pub skill: String,
    /// The prop it must be near.
    pub near: String,
    /// Largest horizontal pelvis–prop distance at which the skill may be chosen (m).
    pub within_m: f64,
}

/// Where the body comes from.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, Default)]
pub enum BodySource {
    /// A body shipped with Repertoire.
    #[default]
    Humanoid,
    /// A user MJCF body with a RON body map; paths are relative to the scenario file.
    Mjcf {
        /// The MJCF file holding the body (and its actuators and sensors).
        file: PathBuf,
        /// The RON body map naming the pelvis, feet, hands, head and actuated joints.
        map: PathBuf,
    },
}

/// Simulation rates in Hz.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct Rates {
    /// Physics steps per second (MuJoCo timestep = 1 / physics_hz).
    pub physics_hz: u32,
    /// Skill-policy decisions per second; must divide `physics_hz`.
    pub control_hz: u32,
    /// Meta-controller decisions per second; must divide `control_hz`.
    pub meta_hz: u32,
}

impl Default for Rates {
    fn default() -> Self {
        Self { physics_hz: 240, control_hz: 60, meta_hz: 2 }
    }
}

impl Rates {
    /// Physics steps per control tick.
    pub fn substeps(&self) -> usize {
        (self.physics_hz / self.control_hz.max(1)) as usize
    }

    /// Control ticks per meta-controller decision.
    pub fn ticks_per_meta_step(&self) -> usize {
        (self.control_hz / self.meta_hz.max(1)) as usize
    }
}

/// A placement on the floor: position in metres and heading in degrees about +z. The position
/// is `(x, y)` plus an optional polar offset of `radius` metres at `angle_deg` (counter-clockwise
/// from +x), so `(radius: (2.5, 3.5), angle_deg: (-30, 30))` puts a prop 2.5–3.5 m from `(x, y)`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Pose {
    /// x in metres (the centre of the polar offset).
    #[serde(default = "zero")]
    pub x: Param,
    /// y in metres (the centre of the polar offset).
    #[serde(default = "zero")]
    pub y: Param,
    /// Distance from `(x, y)` in metres (0: at `(x, y)`).
    #[serde(default = "zero")]
    pub radius: Param,
    /// Direction of the `radius` offset in degrees, counter-clockwise from +x.
    #[serde(default = "zero")]
    pub angle_deg: Param,
    /// Height of the prop's base above the floor in metres (free props: above what they rest on).
    #[serde(default = "zero")]
    pub z: Param,
    /// Heading in degrees, counter-clockwise about +z; a chair faces its +x.
    #[serde(default = "zero")]
    pub yaw_deg: Param,
}

fn zero() -> Param {
    Param::Fixed(0.0)
}

impl Default for Pose {
    fn default() -> Self {
        Self { x: zero(), y: zero(), radius: zero(), angle_deg: zero(), z: zero(), yaw_deg: zero() }
    }
}

impl Pose {
    /// The floor position at every range's middle.
    pub fn nominal_xy(&self) -> (f64, f64) {
        let (r, a) = (self.radius.nominal(), self.angle_deg.nominal().to_radians());
        (self.x.nominal() + r * a.cos(), self.y.nominal() + r * a.sin())
    }

    /// A floor position for one episode (fixed values draw nothing from `rng`).
    pub fn sample_xy(&self, rng: &mut impl Rng) -> (f64, f64) {
        let (x, y) = (self.x.sample(rng), self.y.sample(rng));
        let (r, a) = (self.radius.sample(rng), self.angle_deg.sample(rng).to_radians());
        (x + r * a.cos(), y + r * a.sin())
    }
}

/// A prop in the world. Chairs, pedestals and buckets are fixed in place (moved only between
/// episodes); boxes and balls are free bodies.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub enum Prop {
    /// A chair: seat, back and four legs; its seat geom is `NAME/seat`.
    Chair(Chair),
    /// A free box (for lift and carry).
    Box(BoxProp),
    /// A fixed pedestal (a table-like block boxes rest on).
    Pedestal(Pedestal),
    /// A free ball (for catch).
    Ball(Ball),
    /// A fixed open bucket (for toss).
    Bucket(Bucket),
}

/// A chair facing its +x.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Chair {
    /// Unique prop name.
    pub name: String,
    /// Where it stands.
    #[serde(default)]
    pub at: Pose,
    /// Height of the seat's top surface in metres.
    #[serde(default = "Chair::default_seat_height")]
    pub seat_height: Param,
    /// Seat width (across, along the chair's y) in metres.
    #[serde(default = "Chair::default_seat_width")]
    pub seat_width: f64,
    /// Seat depth (front to back, along the chair's x) in metres.
    #[serde(default = "Chair::default_seat_depth")]
    pub seat_depth: f64,
    /// Height of the back above the seat in metres; 0 for a stool.
    #[serde(default = "Chair::default_back_height")]
    pub back_height: f64,
}

impl Chair {
    fn default_seat_height() -> Param {
        Param::Fixed(0.45)
    }
    fn default_seat_width() -> f64 {
        0.46
    }
    fn default_seat_depth() -> f64 {
        0.42
    }
    fn default_back_height() -> f64 {
        0.42
    }
}

/// A free box.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct BoxProp {
    /// Unique prop name.
    pub name: String,
    /// Where it starts (ignored in x/y when `on` names a prop: it then sits centred on that prop).
    #[serde(default)]
    pub at: Pose,
    /// Full edge lengths (x, y, z) in metres, before `scale`.
    #[serde(default = "BoxProp::default_size")]
    pub size: (f64, f64, f64),
    /// Uniform scale of `size`, per episode.
    #[serde(default = "one")]
    pub scale: Param,
    /// Mass in kg.
    #[serde(default = "BoxProp::default_mass")]
    pub mass: Param,
    /// A pedestal or chair to rest on at the start of an episode.
    #[serde(default)]
    pub on: Option<String>,
}

impl BoxProp {
    fn default_size() -> (f64, f64, f64) {
        (0.3, 0.3, 0.3)
    }
    fn default_mass() -> Param {
        Param::Fixed(4.0)
    }
}

fn one() -> Param {
    Param::Fixed(1.0)
}

/// A fixed block with a flat top.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Pedestal {
    /// Unique prop name.
    pub name: String,
    /// Where it stands.
    #[serde(default)]
    pub at: Pose,
    /// Height of the top surface in metres.
    #[serde(default = "Pedestal::default_height")]
    pub height: Param,
    /// Top size (x, y) in metres.
    #[serde(default = "Pedestal::default_top")]
    pub top: (f64, f64),
}

impl Pedestal {
    fn default_height() -> Param {
        Param::Fixed(0.6)
    }
    fn default_top() -> (f64, f64) {
        (0.4, 0.4)
    }
}

/// A free ball.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Ball {
    /// Unique prop name.
    pub name: String,
    /// Where it starts.
    #[serde(default)]
    pub at: Pose,
    /// Radius in metres, before `scale`.
    #[serde(default = "Ball::default_radius")]
    pub radius: f64,
    /// Uniform scale of `radius`, per episode.
    #[serde(default = "one")]
    pub scale: Param,
    /// Mass in kg.
    #[serde(default = "Ball::default_mass")]
    pub mass: Param,
    /// A pedestal or chair to rest on at the start of an episode.
    #[serde(default)]
    pub on: Option<String>,
}

impl Ball {
    fn default_radius() -> f64 {
        0.12
    }
    fn default_mass() -> Param {
        Param::Fixed(0.5)
    }
}

/// A fixed open bucket.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Bucket {
    /// Unique prop name.
    pub name: String,
    /// Where it stands.
    #[serde(default)]
    pub at: Pose,
    /// Inner radius in metres.
    #[serde(default = "Bucket::default_radius")]
    pub radius: f64,
    /// Wall height in metres.
    #[serde(default = "Bucket::default_height")]
    pub height: f64,
}

impl Bucket {
    fn default_radius() -> f64 {
        0.25
    }
    fn default_height() -> f64 {
        0.3
    }
}

impl Prop {
    /// The prop's unique name.
    pub fn name(&self) -> &str {
        match self {
            Prop::Chair(p) => &p.name,
            Prop::Box(p) => &p.name,
            Prop::Pedestal(p) => &p.name,
            Prop::Ball(p) => &p.name,
            Prop::Bucket(p) => &p.name,
        }
    }

    /// Where it is placed.
    pub fn pose(&self) -> &Pose {
        match self {
            Prop::Chair(p) => &p.at,
            Prop::Box(p) => &p.at,
            Prop::Pedestal(p) => &p.at,
            Prop::Ball(p) => &p.at,
            Prop::Bucket(p) => &p.at,
        }
    }

    /// The kind as a lower-case word (`chair`, `box`, ...).
    pub fn kind(&self) -> &'static str {
        match self {
            Prop::Chair(_) => "chair",
            Prop::Box(_) => "box",
            Prop::Pedestal(_) => "pedestal",
            Prop::Ball(_) => "ball",
            Prop::Bucket(_) => "bucket",
        }
    }

    /// True for props that move under physics (boxes, balls); the rest are fixed in place.
    pub fn is_free(&self) -> bool {
        matches!(self, Prop::Box(_) | Prop::Ball(_))
    }

    /// The prop this one rests on at the start of an episode, if any.
    pub fn rests_on(&self) -> Option<&str> {
        match self {
            Prop::Box(p) => p.on.as_deref(),
            Prop::Ball(p) => p.on.as_deref(),
            _ => None,
        }
    }
}

/// A spawn zone: a ring sector around a prop (or the origin), in the prop's frame.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Zone {
    /// Unique zone name (`front`, `sides`, `behind`, ...).
    pub name: String,
    /// The prop whose frame the sector is in; the world origin when absent.
    #[serde(default)]
    pub around: Option<String>,
    /// Distance from the prop's centre in metres.
    pub radius: Param,
    /// Angle in degrees from the prop's +x (its front), counter-clockwise. A range may wrap past
    /// 180 (e.g. `(150, 210)` is behind).
    pub angle_deg: Param,
    /// Also use the sector mirrored across the prop's x axis (angle → −angle), each half of the
    /// time: `angle_deg: (60, 120), mirrored: true` is both sides.
    #[serde(default)]
    pub mirrored: bool,
    /// Which way the character faces at the start.
    #[serde(default)]
    pub facing: Facing,
}

/// The character's initial heading in a zone.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, Default)]
pub enum Facing {
    /// Towards the zone's prop, plus a uniform jitter of ± `jitter_deg`.
    Toward {
        /// Half-width of the uniform jitter in degrees.
        #[serde(default)]
        jitter_deg: f64,
    },
    /// Away from the zone's prop, plus a uniform jitter of ± `jitter_deg`.
    Away {
        /// Half-width of the uniform jitter in degrees.
        #[serde(default)]
        jitter_deg: f64,
    },
    /// A uniformly random heading.
    #[default]
    Uniform,
    /// A heading in world degrees (fixed or a range).
    World(Param),
}

/// What the character must do.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub enum Task {
    /// Get the pelvis onto a chair's seat and keep it there.
    Sit {
        /// The chair whose seat counts.
        seat: String,
        /// Seconds of continuous pelvis–seat contact that count as success.
        #[serde(default = "Task::default_hold")]
        hold_s: f64,
        /// Episode length in seconds.
        #[serde(default = "Task::default_limit")]
        time_limit_s: f64,
        /// Seated means the pelvis on the seat *and* the pelvis heading within this many
        /// degrees of the way the chair faces (its +x): a character that falls forward onto the
        /// seat from the front, facing the backrest, touches it but does not sit. 180 counts
        /// any contact (the sitting paper's literal test).
        #[serde(default = "Task::default_facing")]
        facing_deg: f64,
        /// What the meta-controller's reward pays for before the character is seated.
        #[serde(default)]
        approach: SitApproach,
        /// What a fall does to the approach reward already paid.
        #[serde(default)]
        on_fall: SitFall,
        /// Taken from the reward of every decision in which the character touched the chair
        /// while a skill that is not terminal in the graph played (walking, turning, standing:
        /// not the sit). Most falls follow such a bump (stop 43: 8500 of the shipped
        /// controller's 14,611 failures in 30,000 trials; stop 44: a round trained with 0.5
        /// gained nothing). 0 (the default): the paper's reward.
        #[serde(default)]
        touch_penalty: f64,
    },
    /// Catch & Carry's warehouse: go to the pedestal holding the box, lift the box, carry it to
    /// another pedestal, put it down, and again (GOTO → LIFT → CARRY → PUTDOWN → GOTO …).
    Warehouse(Warehouse),
    /// Catch & Carry's toss: catch a ball thrown at the character and put it into a bucket.
    Toss(Toss),
    /// No task: the world just runs (for clips, benchmarks and free play).
    Free {
        /// Episode length in seconds.
        #[serde(default = "Task::default_limit")]
        time_limit_s: f64,
    },
}

/// The sit task's reward while not seated.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub enum SitApproach {
    /// The sitting paper's: `0.5·(−V_sit)`, the pelvis' approach speed to the seat's centre.
    /// It pays as well for falling onto the seat from the front as for sitting down on it.
    #[default]
    Seat,
    /// `0.5·(−dΦ/dt)` for `Φ = d + heading_m·|ψ|`: `d` the pelvis' horizontal distance to the
    /// spot `ahead_m` in front of the seat's centre (where a sit starts, the seat behind the
    /// pelvis) and `ψ` the angle between the pelvis heading and the way the chair faces. It
    /// pays for arriving where a sit begins, facing away from the backrest.
    Spot {
        /// Distance of the spot in front of the seat's centre (m).
        ahead_m: f64,
        /// Metres of distance one radian of heading error counts as.
        heading_m: f64,
        /// With it, the heading that counts depends on the distance `d`: from `d ≥ turn_within_m`
        /// the error is measured from the bearing towards the spot (walk there), at the spot
        /// from the way the chair faces (turn there), and the two errors are blended linearly
        /// in between, so turning away from the chair far from it costs instead of paying.
        /// `None` (the default): always from the way the chair faces.
        #[serde(default)]
        turn_within_m: Option<f64>,
        /// With it, `d` is measured round a disc kept clear about the chair (see [`SpotAround`])
        /// instead of in a straight line, so that walking past the chair towards the spot pays
        /// and walking into its back does not. `None` (the default): the straight distance.
        #[serde(default, skip_serializing_if = "Option::is_none")]
        around: Option<SpotAround>,
    },
}

/// The disc the Spot approach measures its distance round ([`SitApproach::Spot`]'s `around`):
/// centred `behind_m` behind the seat's centre (along the way the chair faces) with radius
/// `radius_m`, so that it covers the chair and a margin for the body while the spot, `ahead_m`
/// in front of the seat, lies outside it (`radius_m − behind_m < ahead_m`). The distance from a
/// pelvis outside the disc is the shortest way to the spot that does not cross it (straight,
/// or along a tangent, the circle and the spot's tangent); from inside, the way out radially plus
/// the way from where it leaves. Both are continuous, and along the chair's front axis it equals
/// the straight distance, so the sit's own descent onto the seat pays as it does without it.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SpotAround {
    /// Radius of the disc (m).
    pub radius_m: f64,
    /// How far the disc's centre lies behind the seat's centre (m).
    pub behind_m: f64,
}

/// What a fall does to the sit task's approach reward.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize)]
pub enum SitFall {
    /// The sitting paper's: the episode ends and keeps what it earned, so falling towards the
    /// seat (or turning to face away from it and falling) pays as much as walking there.
    #[default]
    Keep,
    /// The fall's decision pays back, negated, every approach reward the episode earned: a fallen
    /// character made no progress. What a seated decision earned stays.
    Forfeit,
}

/// A phase of the warehouse task, in the order they repeat.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub enum WarehousePhase {
    /// Walk to the pedestal the box is on.
    Goto,
    /// Take the box off it with both hands.
    Lift,
    /// Carry it to the target pedestal.
    Carry,
    /// Put it down on the target pedestal.
    PutDown,
}

impl WarehousePhase {
    /// Every phase in task order.
    pub const ALL: [WarehousePhase; 4] =
        [WarehousePhase::Goto, WarehousePhase::Lift, WarehousePhase::Carry, WarehousePhase::PutDown];

    /// Position in task order (0 = GOTO), the index of its one-hot observation.
    pub fn index(self) -> usize {
        self as usize
    }

    /// The phase after this one (PUTDOWN is followed by GOTO).
    pub fn next(self) -> Self {
        Self::ALL[(self.index() + 1) % Self::ALL.len()]
    }

    /// The paper's name (`GOTO`, `LIFT`, `CARRY`, `PUTDOWN`).
    pub fn label(self) -> &'static str {
        ["GOTO", "LIFT", "CARRY", "PUTDOWN"][self.index()]
    }
}

/// The warehouse task (Merel et al. 2020, Catch & Carry): the success test of each phase is
/// read from contacts.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Warehouse {
    /// The free box to move.
    #[serde(rename = "box")]
    pub box_: String,
    /// The pedestals the box moves between (at least two); the box starts `on` one of them.
    pub pedestals: Vec<String>,
    /// GOTO and CARRY end when the pelvis is this close (horizontally, m) to the focal
    /// pedestal's centre.
    #[serde(default = "Warehouse::default_reach")]
    pub reach_m: f64,
    /// PUTDOWN ends when the box touches the target pedestal at this many points or more.
    #[serde(default = "Warehouse::default_contacts")]
    pub rest_contacts: usize,
    /// Phases an episode may start in (drawn uniformly per episode).
    #[serde(default = "Warehouse::default_start")]
    pub start_phases: Vec<WarehousePhase>,
    /// Episode length in seconds.
    #[serde(default = "Warehouse::default_limit")]
    pub time_limit_s: f64,
    /// A skill whose successful end states (its library folder's `end_poses.ron`, written by
    /// `skill eval`) start CARRY and PUTDOWN episodes, the box put between the hands: the
    /// states the character is in after that skill (lift), so the skill that follows starts
    /// from what it was fine-tuned on. `None`: a standing pose with the arms fitted round the
    /// box.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub hold_from: Option<String>,
}

impl Warehouse {
    fn default_reach() -> f64 {
        0.65
    }
    fn default_contacts() -> usize {
        4
    }
    fn default_start() -> Vec<WarehousePhase> {
        WarehousePhase::ALL.to_vec()
    }
    fn default_limit() -> f64 {
        15.0
    }
}

/// Where the ball is aimed, relative to the character at the throw.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CatchPoint {
    /// Metres in front of the pelvis.
    pub forward: f64,
    /// Height above the floor in metres.
    pub height: f64,
}

impl Default for CatchPoint {
    fn default() -> Self {
        CatchPoint { forward: 0.4, height: 1.2 }
    }
}

/// The toss task (Catch & Carry): a ball is thrown at the character at the start of the episode;
/// it must catch it (both hands on it, off the floor) and put it into the bucket.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Toss {
    /// The free ball that is thrown.
    pub ball: String,
    /// The bucket it goes into.
    pub bucket: String,
    /// How the ball is thrown (defaults: the paper's ranges).
    #[serde(default)]
    pub throw: ThrowSpec,
    /// Where the ball is aimed.
    #[serde(default)]
    pub catch_at: CatchPoint,
    /// Episode length in seconds.
    #[serde(default = "Toss::default_limit")]
    pub time_limit_s: f64,
}

impl Toss {
    fn default_limit() -> f64 {
        10.0
    }
}

impl Default for Task {
    fn default() -> Self {
        Task::Free { time_limit_s: Task::default_limit() }
    }
}

impl Task {
    fn default_hold() -> f64 {
        3.0
    }
    fn default_limit() -> f64 {
        20.0
    }
    fn default_facing() -> f64 {
        SEATED_FACING_DEG
    }

    /// Episode length in seconds.
    pub fn time_limit_s(&self) -> f64 {
        match self {
            Task::Sit { time_limit_s, .. } | Task::Free { time_limit_s } => *time_limit_s,
            Task::Warehouse(w) => w.time_limit_s,
            Task::Toss(t) => t.time_limit_s,
        }
    }

    /// The task's name as written in the file (`Sit`, `Warehouse`, `Toss`, `Free`).
    pub fn kind(&self) -> &'static str {
        match self {
            Task::Sit { .. } => "Sit",
            Task::Warehouse(_) => "Warehouse",
            Task::Toss(_) => "Toss",
            Task::Free { .. } => "Free",
        }
    }
}

/// The zone curriculum: start in the first zone, move on when the success rate is high enough
/// (or, with `max_episodes`, when the zone's episode budget is spent).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Curriculum {
    /// Zone names, easiest first.
    pub zones: Vec<String>,
    /// Windowed success rate at which training moves to the next zone.
    #[serde(default = "Curriculum::default_advance")]
    pub advance_at: f64,
    /// Number of recent episodes the success rate is measured over.
    #[serde(default = "Curriculum::default_window")]
    pub window: usize,
    /// Keep the zones already passed open after advancing (episodes then start uniformly in
    /// any unlocked zone, so skills for the easy zones are not forgotten); `false`: only the
    /// current zone.
    #[serde(default = "Curriculum::default_keep_passed")]
    pub keep_passed: bool,
    /// Also move on after this many episodes in a zone even if its success rate never reached
    /// `advance_at` (a budget per zone, so that a threshold the skills cannot reach yet does not
    /// hold training in the first zone for the whole run); `None` (the default): only the
    /// threshold moves on, the sitting paper's rule.
    #[serde(default)]
    pub max_episodes: Option<u64>,
}

impl Curriculum {
    fn default_advance() -> f64 {
        0.8
    }
    fn default_window() -> usize {
        200
    }
    fn default_keep_passed() -> bool {
        true
    }
}

/// A scenario together with the file it came from (for messages and relative paths).
#[derive(Debug, Clone)]
pub struct ScenarioFile {
    /// The parsed, validated scenario.
    pub scenario: Scenario,
    /// The file path (`<built-in>/...` for the shipped default).
    pub path: PathBuf,
    /// The file's text.
    pub text: String,
}

/// Name under which the built-in default scenario is reported.
pub const DEFAULT_SCENARIO_NAME: &str = "<built-in>/scenarios/sit.ron";
const DEFAULT_SCENARIO: &str = include_str!("../../../scenarios/sit.ron");

impl ScenarioFile {
    /// Reads, parses and validates a scenario file.
    pub fn load(path: impl AsRef<Path>) -> Result<Self> {
        let path = path.as_ref();
        let text = std::fs::read_to_string(path).map_err(|source| SceneError::unreadable(path, source))?;
        Self::parse(path, text)
    }

    /// The built-in default scenario (`scenarios/sit.ron`, compiled into the binary).
    pub fn builtin_default() -> Self {
        Self::parse(Path::new(DEFAULT_SCENARIO_NAME), DEFAULT_SCENARIO.to_string())
            .expect("the built-in scenario is checked by the test suite")
    }

    /// Parses and validates scenario text; `path` is used for messages and relative paths.
    pub fn parse(path: &Path, text: String) -> Result<Self> {
        let scenario: Scenario = ron::Options::default()
            .with_default_extension(
                ron::extensions::Extensions::IMPLICIT_SOME | ron::extensions::Extensions::UNWRAP_VARIANT_NEWTYPES,
            )
            .from_str(&text)
            .map_err(|e| SceneError::from_ron(path, e))?;
        let file = Self { scenario, path: path.to_path_buf(), text };
        file.validate()?;
        Ok(file)
    }

    /// The latent model folder the scenario's high level drives (resolved against the scenario's
    /// folder), or `None` for the discrete skills.
    pub fn latent_dir(&self) -> Option<PathBuf> {
        match &self.scenario.low_level {
            LowLevel::Skills => None,
            LowLevel::Latent(dir) => Some(self.resolve(dir)),
        }
    }

    /// Resolves a path written in the scenario relative to the scenario's folder.
    pub fn resolve(&self, relative: &Path) -> PathBuf {
        if relative.is_absolute() || self.path.starts_with("<built-in>") {
            return relative.to_path_buf();
        }
        self.path.parent().unwrap_or(Path::new(".")).join(relative)
    }

    /// An error about this file, located at the first occurrence of `needle` when given.
    pub fn invalid(&self, needle: Option<&str>, message: impl Into<String>) -> SceneError {
        SceneError::Invalid {
            file: self.path.clone(),
            loc: needle.and_then(|n| Location::find_quoted(&self.text, n)),
            message: message.into(),
        }
    }

    fn validate(&self) -> Result<()> {
        let s = &self.scenario;
        if s.name.trim().is_empty() {
            return Err(self.invalid(Some("name"), "the scenario needs a non-empty `name`"));
        }

        let r = s.rates;
        if r.physics_hz == 0 || r.control_hz == 0 || r.meta_hz == 0 {
            return Err(self.invalid(Some("rates"), "rates must be positive"));
        }
        if !r.physics_hz.is_multiple_of(r.control_hz) {
            return Err(self.invalid(
                Some("control_hz"),
                format!(
                    "control_hz ({}) must divide physics_hz ({}) so each control tick is a whole \
                     number of physics steps",
                    r.control_hz, r.physics_hz
                ),
            ));
        }
        if !r.control_hz.is_multiple_of(r.meta_hz) {
            return Err(self.invalid(
                Some("meta_hz"),
                format!("meta_hz ({}) must divide control_hz ({})", r.meta_hz, r.control_hz),
            ));
        }

        let mut names = HashSet::new();
        for prop in &s.props {
            let name = prop.name();
            if name.is_empty() || name.contains('/') || name.chars().any(char::is_whitespace) {
                return Err(
                    self.invalid(Some(name), format!("prop name `{name}` must be non-empty, without spaces or `/`"))
                );
            }
            if !names.insert(name) {
                return Err(self.invalid(Some(name), format!("two props are named `{name}`")));
            }
            self.validate_prop(prop)?;
        }
        for prop in &s.props {
            if let Some(base) = prop.rests_on() {
                match self.prop(base) {
                    None => {
                        return Err(self.unknown_prop(base, &format!("`{}`'s `on`", prop.name())));
                    }
                    Some(Prop::Pedestal(_) | Prop::Chair(_)) => {}
                    Some(other) => {
                        return Err(self.invalid(
                            Some(base),
                            format!(
                                "`{}` can rest on a pedestal or a chair, not on {} `{base}`",
                                prop.name(),
                                other.kind()
                            ),
                        ));
                    }
                }
            }
        }

        let mut zones = HashSet::new();
        for zone in &s.spawn {
            if !zones.insert(zone.name.as_str()) {
                return Err(self.invalid(Some(&zone.name), format!("two spawn zones are named `{}`", zone.name)));
            }
            if let Some(around) = &zone.around
                && self.prop(around).is_none()
            {
                return Err(self.unknown_prop(around, &format!("zone `{}`", zone.name)));
            }
            if zone.radius.min() < 0.0 {
                return Err(self.invalid(Some(&zone.name), format!("zone `{}` has a negative radius", zone.name)));
            }
            if zone.around.is_none() && matches!(zone.facing, Facing::Toward { .. } | Facing::Away { .. }) {
                return Err(self.invalid(
                    Some(&zone.name),
                    format!("zone `{}` faces toward/away from a prop but names none in `around`", zone.name),
                ));
            }
        }

        match &s.task {
            Task::Sit { seat, hold_s, time_limit_s, facing_deg, approach, touch_penalty, .. } => {
                if !(touch_penalty.is_finite() && *touch_penalty >= 0.0) {
                    return Err(self.invalid(
                        Some("touch_penalty"),
                        format!("the sit task's touch_penalty must be finite and ≥ 0, got {touch_penalty}"),
                    ));
                }
                if !(*facing_deg > 0.0 && *facing_deg <= 180.0) {
                    return Err(self.invalid(
                        Some("facing_deg"),
                        format!("the sit task's facing_deg must be in (0, 180], got {facing_deg}"),
                    ));
                }
                if let SitApproach::Spot { ahead_m, heading_m, turn_within_m, around } = approach {
                    if !(ahead_m.is_finite() && *ahead_m >= 0.0 && heading_m.is_finite() && *heading_m >= 0.0) {
                        return Err(self.invalid(
                            Some("approach"),
                            format!(
                                "the sit task's Spot approach needs ahead_m and heading_m ≥ 0, got {ahead_m} and {heading_m}"
                            ),
                        ));
                    }
                    if let Some(r) = turn_within_m
                        && !(r.is_finite() && *r > 0.0)
                    {
                        return Err(self.invalid(
                            Some("turn_within_m"),
                            format!("the sit task's Spot approach needs turn_within_m > 0 (metres), got {r}"),
                        ));
                    }
                    if let Some(SpotAround { radius_m, behind_m }) = around {
                        if !(radius_m.is_finite() && *radius_m > 0.0 && behind_m.is_finite() && *behind_m >= 0.0) {
                            return Err(self.invalid(
                                Some("around"),
                                format!(
                                    "the sit task's Spot approach needs around's radius_m > 0 and behind_m ≥ 0 \
                                     (metres), got {radius_m} and {behind_m}"
                                ),
                            ));
                        }
                        if radius_m - behind_m >= *ahead_m {
                            return Err(self.invalid(
                                Some("around"),
                                format!(
                                    "the sit task's Spot approach puts its spot inside the disc it goes round: \
                                     radius_m − behind_m ({radius_m} − {behind_m}) must be less than ahead_m ({ahead_m})"
                                ),
                            ));
                        }
                    }
                }
                match self.prop(seat) {
                    Some(Prop::Chair(_)) => {}
                    Some(other) => {
                        return Err(self.invalid(
                            Some(seat),
                            format!("the sit task's seat `{seat}` is a {}, not a chair", other.kind()),
                        ));
                    }
                    None => return Err(self.unknown_prop(seat, "the sit task's `seat`")),
                }
                let ordered = *hold_s > 0.0 && *time_limit_s > *hold_s;
                if !ordered {
                    return Err(self.invalid(
                        Some("hold_s"),
                        format!("the sit task needs 0 < hold_s ({hold_s}) < time_limit_s ({time_limit_s})"),
                    ));
                }
            }
            Task::Free { time_limit_s } => {
                let positive = *time_limit_s > 0.0;
                if !positive {
                    return Err(self.invalid(Some("time_limit_s"), "time_limit_s must be positive"));
                }
            }
            Task::Warehouse(w) => self.validate_warehouse(w)?,
            Task::Toss(t) => self.validate_toss(t)?,
        }

        if let LowLevel::Latent(dir) = &s.low_level {
            let resolved = self.resolve(dir);
            if !resolved.join("latent.ron").is_file() {
                return Err(self.invalid(
                    Some(&dir.display().to_string()),
                    format!(
                        "low_level: no latent model in `{}` (expected {}; train one with `repertoire latent train`)",
                        dir.display(),
                        resolved.join("latent.ron").display()
                    ),
                ));
            }
        }

        for (name, binding) in &s.bind {
            self.validate_binding(name, binding)?;
        }

        let mut skills = HashSet::new();
        for skill in &s.skills {
            if let Some(problem) = skill_name_problem(skill) {
                return Err(self.invalid(Some(skill), problem));
            }
            if !skills.insert(skill.as_str()) {
                return Err(self.invalid(Some(skill), format!("skill `{skill}` is listed twice")));
            }
        }

        if let Some(g) = &s.skill_graph {
            if g.start.is_empty() {
                return Err(self.invalid(Some("skill_graph"), "the skill graph names no start skill"));
            }
            let guarded = g.guards.iter().map(|guard| &guard.skill);
            for name in g.start.iter().chain(g.edges.iter().flat_map(|(a, b)| [a, b])).chain(guarded) {
                if !skills.contains(name.as_str()) {
                    return Err(self.invalid(
                        Some(name),
                        format!(
                            "the skill graph names `{name}`, which `skills` does not list ({})",
                            s.skills.join(", ")
                        ),
                    ));
                }
            }
            let mut seen = HashSet::new();
            for guard in &g.guards {
                if !seen.insert(guard.skill.as_str()) {
                    return Err(self
                        .invalid(Some(&guard.skill), format!("skill `{}` has two guards; give it one", guard.skill)));
                }
                if !s.props.iter().any(|p| p.name() == guard.near) && !s.bind.contains_key(&guard.near) {
                    return Err(self.invalid(
                        Some(&guard.near),
                        format!(
                            "the guard on `{}` names prop `{}`, which the scenario neither has nor binds",
                            guard.skill, guard.near
                        ),
                    ));
                }
                if !(guard.within_m.is_finite() && guard.within_m > 0.0) {
                    return Err(self.invalid(
                        Some(&guard.near),
                        format!("the guard on `{}` needs `within_m` > 0 (it is {})", guard.skill, guard.within_m),
                    ));
                }
            }
        }

        if let Some(d) = &s.detour {
            if d.around.is_empty() {
                return Err(self.invalid(Some("detour"), "the detour names no prop to walk around"));
            }
            for name in &d.around {
                if !s.props.iter().any(|p| p.name() == name.as_str()) {
                    return Err(self.invalid(
                        Some(name),
                        format!(
                            "the detour names prop `{name}`, which the scenario does not have ({})",
                            s.props.iter().map(|p| p.name()).collect::<Vec<_>>().join(", ")
                        ),
                    ));
                }
            }
            if !(d.radius_m.is_finite() && d.radius_m > 0.0) {
                return Err(
                    self.invalid(Some("radius_m"), format!("the detour needs `radius_m` > 0 (it is {})", d.radius_m))
                );
            }
        }

        if let Err(e) = s.fall.check() {
            return Err(self.invalid(Some("fall"), e.to_string()));
        }

        if let Some(c) = &s.curriculum {
            if c.zones.is_empty() {
                return Err(self.invalid(Some("curriculum"), "the curriculum lists no zones"));
            }
            for z in &c.zones {
                if !zones.contains(z.as_str()) {
                    return Err(self.invalid(
                        Some(z),
                        format!(
                            "the curriculum names zone `{z}`, but `spawn` has only: {}",
                            s.spawn.iter().map(|z| z.name.as_str()).collect::<Vec<_>>().join(", ")
                        ),
                    ));
                }
            }
            if !(c.advance_at > 0.0 && c.advance_at <= 1.0) || c.window == 0 {
                return Err(self.invalid(
                    Some("advance_at"),
                    "the curriculum needs 0 < advance_at <= 1 and a window of at least 1 episode",
                ));
            }
            if c.max_episodes == Some(0) {
                return Err(self.invalid(
                    Some("max_episodes"),
                    "the curriculum's `max_episodes` must be at least 1 (leave it out to move on only at `advance_at`)",
                ));
            }
        }
        Ok(())
    }

    /// The prop `name` must exist and be of kind `kind`; `role` names the field for messages.
    fn expect_prop(&self, name: &str, kind: &str, role: &str) -> Result<&Prop> {
        match self.prop(name) {
            Some(p) if p.kind() == kind => Ok(p),
            Some(other) => {
                Err(self.invalid(Some(name), format!("{role} `{name}` is a {}, not a {kind}", other.kind())))
            }
            None => Err(self.unknown_prop(name, role)),
        }
    }

    /// One `bind` entry: a prop-like name bound to an existing prop or to a role the task has.
    fn validate_binding(&self, name: &str, binding: &PropBinding) -> Result<()> {
        if name.is_empty() || name.contains('/') || name.chars().any(char::is_whitespace) {
            return Err(self.invalid(
                Some("bind"),
                format!("`bind` key `{name}` must be a prop name: non-empty, without spaces or `/`"),
            ));
        }
        match binding {
            PropBinding::Prop(target) => {
                if self.prop(target).is_none() {
                    return Err(self.unknown_prop(target, &format!("`bind`'s `{name}`")));
                }
            }
            PropBinding::Focal => {
                if !matches!(self.scenario.task, Task::Warehouse(_)) {
                    return Err(self.invalid(
                        Some(name),
                        format!(
                            "`bind` maps `{name}` to Focal, the warehouse's focal pedestal, but the task is {}",
                            self.scenario.task.kind()
                        ),
                    ));
                }
            }
        }
        Ok(())
    }

    fn validate_warehouse(&self, w: &Warehouse) -> Result<()> {
        let crate_ = self.expect_prop(&w.box_, "box", "the warehouse task's `box`")?;
        if w.pedestals.len() < 2 {
            return Err(self.invalid(
                Some("pedestals"),
                format!("the warehouse task needs at least two pedestals, got {}", w.pedestals.len()),
            ));
        }
        let mut seen = HashSet::new();
        for p in &w.pedestals {
            self.expect_prop(p, "pedestal", "the warehouse task's `pedestals`")?;
            if !seen.insert(p.as_str()) {
                return Err(self.invalid(Some(p), format!("the warehouse task lists pedestal `{p}` twice")));
            }
        }
        match crate_.rests_on() {
            Some(base) if w.pedestals.iter().any(|p| p == base) => {}
            _ => {
                return Err(self.invalid(
                    Some(&w.box_),
                    format!(
                        "box `{}` must start `on` one of the warehouse pedestals ({})",
                        w.box_,
                        w.pedestals.join(", ")
                    ),
                ));
            }
        }
        if !(w.reach_m > 0.0 && w.reach_m.is_finite()) {
            return Err(self.invalid(Some("reach_m"), format!("reach_m must be positive, got {}", w.reach_m)));
        }
        if w.rest_contacts == 0 {
            return Err(self.invalid(Some("rest_contacts"), "rest_contacts must be at least 1"));
        }
        if w.start_phases.is_empty() {
            return Err(self.invalid(Some("start_phases"), "the warehouse task lists no start phase"));
        }
        if !(w.time_limit_s > 0.0 && w.time_limit_s.is_finite()) {
            return Err(self.invalid(Some("time_limit_s"), "time_limit_s must be positive"));
        }
        if let Some(skill) = &w.hold_from
            && !self.scenario.skills.iter().any(|s| s == skill)
        {
            return Err(self.invalid(
                Some("hold_from"),
                format!(
                    "hold_from names skill `{skill}`, which `skills` does not list ({})",
                    self.scenario.skills.join(", ")
                ),
            ));
        }
        Ok(())
    }

    fn validate_toss(&self, t: &Toss) -> Result<()> {
        self.expect_prop(&t.ball, "ball", "the toss task's `ball`")?;
        self.expect_prop(&t.bucket, "bucket", "the toss task's `bucket`")?;
        if let Some(Prop::Ball(b)) = self.prop(&t.ball)
            && b.on.is_some()
        {
            return Err(self.invalid(Some(&t.ball), format!("the thrown ball `{}` cannot start `on` a prop", t.ball)));
        }
        t.throw.validate().map_err(|e| self.invalid(Some("throw"), format!("the toss task: {e}")))?;
        let c = t.catch_at;
        if !(c.height > 0.0 && c.height.is_finite() && c.forward.is_finite()) {
            return Err(self.invalid(
                Some("catch_at"),
                format!("catch_at needs a finite forward offset and a positive height, got {c:?}"),
            ));
        }
        if !(t.time_limit_s > 0.0 && t.time_limit_s.is_finite()) {
            return Err(self.invalid(Some("time_limit_s"), "time_limit_s must be positive"));
        }
        Ok(())
    }

    fn validate_prop(&self, prop: &Prop) -> Result<()> {
        let name = prop.name();
        let positive = |what: &str, v: f64| {
            if v > 0.0 && v.is_finite() {
                Ok(())
            } else {
                Err(self.invalid(Some(name), format!("{} `{name}`: {what} must be positive", prop.kind())))
            }
        };
        match prop {
            Prop::Chair(c) => {
                positive("seat_height", c.seat_height.min())?;
                positive("seat_width", c.seat_width)?;
                positive("seat_depth", c.seat_depth)?;
                if c.back_height < 0.0 {
                    return Err(self.invalid(Some(name), format!("chair `{name}`: back_height must be >= 0")));
                }
            }
            Prop::Box(b) => {
                positive("size", b.size.0.min(b.size.1).min(b.size.2))?;
                positive("scale", b.scale.min())?;
                positive("mass", b.mass.min())?;
            }
            Prop::Pedestal(p) => {
                positive("height", p.height.min())?;
                positive("top", p.top.0.min(p.top.1))?;
            }
            Prop::Ball(b) => {
                positive("radius", b.radius)?;
                positive("scale", b.scale.min())?;
                positive("mass", b.mass.min())?;
            }
            Prop::Bucket(b) => {
                positive("radius", b.radius)?;
                positive("height", b.height)?;
            }
        }
        Ok(())
    }

    fn unknown_prop(&self, name: &str, referrer: &str) -> SceneError {
        let known: Vec<&str> = self.scenario.props.iter().map(Prop::name).collect();
        self.invalid(
            Some(name),
            format!(
                "{referrer} refers to prop `{name}`, which is not in `props` (props: {})",
                if known.is_empty() { "none".to_string() } else { known.join(", ") }
            ),
        )
    }

    /// The prop called `name`, if any.
    pub fn prop(&self, name: &str) -> Option<&Prop> {
        self.scenario.props.iter().find(|p| p.name() == name)
    }
}

#[cfg(test)]
mod tests {
    use super::skill_name_problem;

    #[test]
    fn a_skill_is_named_like_a_folder() {
        for good in ["walk", "turn_left_wide", "sit2", "moonwalk"] {
            assert_eq!(skill_name_problem(good), None, "{good}");
        }
        for bad in ["", "Walk", "2sit", "walk-to", "walk to", "../sit", "_walk"] {
            let problem = skill_name_problem(bad).unwrap_or_else(|| panic!("`{bad}` was accepted"));
            assert!(problem.contains(&format!("`{bad}`")), "{problem}");
        }
    }
}
