//! The scenario file: body, props, spawn zones, rates, task, skills and curriculum, in RON.
//!
//! A scenario is parsed strictly (unknown fields are rejected) and then checked for consistency
//! (references between its parts, rates that divide). Every error names the file, the line and
//! the column, and says what is wrong in one sentence.

use crate::error::{Location, Result, SceneError};
use crate::param::Param;
use serde::{Deserialize, Serialize};
use std::collections::HashSet;
use std::path::{Path, PathBuf};

/// The skills the project knows how to train; a scenario may list only these.
pub const KNOWN_SKILLS: &[&str] = &["walk", "turn_left", "turn_right", "sit", "lift", "carry", "put_down", "catch"];

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

/// A placement on the floor: position in metres and heading in degrees about +z.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Pose {
    /// x in metres.
    pub x: Param,
    /// y in metres.
    pub y: Param,
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
        Self { x: zero(), y: zero(), z: zero(), yaw_deg: zero() }
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
    },
    /// No task: the world just runs (for clips, benchmarks and free play).
    Free {
        /// Episode length in seconds.
        #[serde(default = "Task::default_limit")]
        time_limit_s: f64,
    },
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

    /// Episode length in seconds.
    pub fn time_limit_s(&self) -> f64 {
        match *self {
            Task::Sit { time_limit_s, .. } | Task::Free { time_limit_s } => time_limit_s,
        }
    }
}

/// The zone curriculum: start in the first zone, move on when the success rate is high enough.
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
pub const DEFAULT_SCENARIO_NAME: &str = "<built-in>/scenes/sit.ron";
const DEFAULT_SCENARIO: &str = include_str!("../sit.ron");

impl ScenarioFile {
    /// Reads, parses and validates a scenario file.
    pub fn load(path: impl AsRef<Path>) -> Result<Self> {
        let path = path.as_ref();
        let text =
            std::fs::read_to_string(path).map_err(|source| SceneError::Io { file: path.to_path_buf(), source })?;
        Self::parse(path, text)
    }

    /// The built-in default scenario (`scenes/sit.ron`, compiled into the binary).
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
            Task::Sit { seat, hold_s, time_limit_s } => {
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
        }

        let mut skills = HashSet::new();
        for skill in &s.skills {
            if !KNOWN_SKILLS.contains(&skill.as_str()) {
                return Err(self.invalid(
                    Some(skill),
                    format!("unknown skill `{skill}`; known skills: {}", KNOWN_SKILLS.join(", ")),
                ));
            }
            if !skills.insert(skill.as_str()) {
                return Err(self.invalid(Some(skill), format!("skill `{skill}` is listed twice")));
            }
        }

        if let Some(g) = &s.skill_graph {
            if g.start.is_empty() {
                return Err(self.invalid(Some("skill_graph"), "the skill graph names no start skill"));
            }
            for name in g.start.iter().chain(g.edges.iter().flat_map(|(a, b)| [a, b])) {
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
