//! The skill spec (RON): which clip, what the policy observes, the imitation and goal rewards,
//! how episodes start and end, and the network and PPO settings.

use repertoire_files::FieldError;
use std::path::{Path, PathBuf};

use std::collections::BTreeMap;

use repertoire_learn::ppo::PpoConfig;
use repertoire_scenes::Feature;
use repertoire_scenes::throw::ThrowSpec;
use serde::{Deserialize, Serialize};

use crate::error::{Result, SkillError};

/// Where a skill's reference clip comes from.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ClipRef {
    /// The clip file: BVH, ASF/AMC, DeepMimic `.txt`, keyframe `.ron`, or a retargeted
    /// `.clip.ron` / `.npy`. Relative paths are relative to the spec file; `pack:NAME` is a file
    /// of the clip pack `scripts/setup.sh` installs in `third_party/clips`.
    pub file: String,
    /// A retarget map overriding the shipped one (relative to the spec file).
    #[serde(default)]
    pub map: Option<String>,
    /// Use only `[start, end)` seconds of the clip.
    #[serde(default)]
    pub cut_s: Option<(f64, f64)>,
    /// Mirror left and right (turn_right from a left turn).
    #[serde(default)]
    pub mirror: bool,
    /// Treat the clip as a cycle whose phase wraps.
    #[serde(default)]
    pub looping: bool,
    /// Hold the clip's last frame this long (s) once it has played: training episodes and
    /// `skill eval` trials run on that long past the clip's end (within `episode_s`), and a
    /// meta-controller that keeps choosing the skill keeps holding the pose (a sit stays
    /// seated) instead of replaying the clip from its first frame (a turn). 0: no hold.
    #[serde(default)]
    pub hold_s: f64,
    /// Hold the clip's first frame this long (s) before it plays: a lead-in that gives a
    /// character arriving in motion from another skill (a turn's end pose, moving at walking
    /// speed) time to stop before the clip moves on. Applies to every start; 0: none.
    #[serde(default)]
    pub lead_s: f64,
    /// Raise the root by up to this much (m), in proportion to how low the clip sits: fully
    /// at its lowest frame, not at all at its highest. For a sit clip whose actor sat lower
    /// than this body's pelvis can rest on the scene's chair.
    #[serde(default)]
    pub seat_lift_m: f64,
    /// Joints held at these angles (degrees) in every frame, after cutting and mirroring: the
    /// walk cycle with the arms held forward round a box (carry).
    #[serde(default)]
    pub pose_deg: BTreeMap<String, f64>,
}

/// Weight and sharpness of one imitation term: `weight · exp(−scale · error²)`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Term {
    /// Weight in the reward sum.
    pub weight: f32,
    /// The `k` in `exp(−k·e²)`.
    pub scale: f64,
}

/// The imitation reward's terms. The default is Chao et al.'s sitting reward (0.5·pose +
/// 0.05·velocity) plus DeepMimic's end-effector term and a root term.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct Imitation {
    /// Joint angles: Σ over joints of the wrapped angle difference².
    pub pose: Term,
    /// Joint velocities: Σ of the velocity difference².
    pub velocity: Term,
    /// End effectors relative to the pelvis in its heading frame: Σ of the distance².
    pub end_effector: Term,
    /// Pelvis height, pitch and roll: their differences².
    pub root: Term,
}

impl Default for Imitation {
    fn default() -> Self {
        Imitation {
            pose: Term { weight: 0.5, scale: 1.0 },
            velocity: Term { weight: 0.05, scale: 0.1 },
            end_effector: Term { weight: 0.15, scale: 40.0 },
            root: Term { weight: 0.1, scale: 10.0 },
        }
    }
}

/// A 2-D walking target: where it is drawn, when it counts as reached or is replaced, and how
/// the goal term pays for approaching it (the fields of [`Goal::Target`], which document them).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Steering {
    /// Distance range of the target (m).
    pub distance_m: (f64, f64),
    /// Azimuth range (degrees either side of the heading).
    pub azimuth_deg: f64,
    /// Arrival radius (m); 0: one target per episode.
    #[serde(default)]
    pub reach_m: f64,
    /// Sharpness of the target-heading speed term; 0: the sigmoid on the distance's rate.
    #[serde(default)]
    pub speed_scale: f64,
    /// Sharpness of the facing term; 0: none.
    #[serde(default)]
    pub facing_scale: f64,
    /// Seconds after which a target not reached is replaced; 0: never.
    #[serde(default)]
    pub retarget_s: f64,
}

/// The goal reward added to the imitation reward.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub enum Goal {
    /// Imitation only.
    None,
    /// Walk, stage 1: match the clip's root velocity in the heading frame,
    /// `weight · exp(−scale · ‖v − v̂‖²)`.
    RootVelocity {
        /// Weight.
        weight: f32,
        /// Sharpness.
        scale: f64,
    },
    /// Turns: match the clip's heading change since the episode start, pitch and roll,
    /// `weight · exp(−scale · (Δyaw error² + pitch error² + roll error²))`.
    Heading {
        /// Weight.
        weight: f32,
        /// Sharpness.
        scale: f64,
    },
    /// Walk, stage 2: a 2-D target `distance_m` away at an azimuth within ±`azimuth_deg` of the
    /// start heading; the policy observes `[sin ψ, cos ψ, distance]`; reward
    /// `weight / (1 + exp(10 · V))` with `V` the rate of change of the distance.
    Target {
        /// Weight.
        weight: f32,
        /// Distance range of the target (m).
        distance_m: (f64, f64),
        /// Azimuth range (degrees either side of the start heading).
        azimuth_deg: f64,
        /// Arrival radius (m): within it the target counts as reached (the goal term pays 1 on
        /// that step) and a new one is drawn from the same ranges around the current heading,
        /// so an episode walks to target after target. 0: one target per episode.
        #[serde(default)]
        reach_m: f64,
        /// Above 0, the goal term is DeepMimic's target-heading reward `exp(−speed_scale ·
        /// max(0, v_ref − v·u)²)`, with `u` the unit vector to the target, `v` the root's
        /// velocity and `v_ref` the clip's root speed at that frame (walk towards the target
        /// at the clip's pace), instead of the sigmoid on the distance's rate, which pays fully
        /// for any approach faster than about 0.3 m/s and so hardly for facing the target.
        #[serde(default)]
        speed_scale: f64,
        /// Above 0, half the goal term (off arrival) is `exp(−facing_scale · ψ²)`, `ψ` the angle
        /// between the pelvis heading and the direction to the target, the other half the term
        /// above. Walking straight on at the clip's pace, the speed term's error grows as
        /// `v²(1 − cos ψ)² ≈ v²ψ⁴/4`, flat for small misses; the facing term's as `ψ²`.
        #[serde(default)]
        facing_scale: f64,
        /// Above 0, a target not reached within this many seconds is replaced by a new one
        /// drawn the same way around the current heading (no pay): a walker that missed its
        /// target keeps getting ones it can still reach instead of one behind it for the rest
        /// of the episode. 0: only arrivals draw new targets.
        #[serde(default)]
        retarget_s: f64,
    },
    /// Sit: the chair `prop` is placed under the clip's seated pelvis; reward
    /// `weight / (1 + exp(10 · V))` with `V` the rate of change of the pelvis–seat-centre
    /// distance, or `weight` while the pelvis touches the seat.
    ///
    /// Each episode moves the chair off that spot by up to `jitter_m` (uniform in a disc) and
    /// turns it by up to ±`jitter_deg`, scaled by how far the start frame is from seated (full
    /// when standing, none when already seated), so the policy learns to sit on a chair that is
    /// not exactly where the clip's was, reading its pose from the observation.
    Seat {
        /// Weight.
        weight: f32,
        /// The chair's prop name in the skill's scene.
        prop: String,
        /// Largest chair offset from the clip's seat (m).
        #[serde(default)]
        jitter_m: f64,
        /// Largest chair turn from the clip's seat (degrees either way).
        #[serde(default)]
        jitter_deg: f64,
        /// How far in front of the clip's seated pelvis the seat centre lies (m, along the
        /// chair's facing): where the chair's legs and back clear the clip's legs and torso.
        #[serde(default)]
        forward_m: f64,
        /// Start every episode clear of the chair: a seated start whose pelvis sinks into the
        /// seat is lifted onto it, a chair overlapping a standing start is pushed back (≤ 20 cm).
        #[serde(default)]
        clear_start: bool,
    },
    /// Lift: the pedestal `pedestal` stands under the clip's hands at `grip_s` (seconds into the
    /// clip) with the box `prop` on it. Reward `weight · (0.5·hold + 0.5·raise)`: `hold` =
    /// `0.5·exp(−scale·d²) + 0.25` per hand touching the box (`d`: box centre to the hands'
    /// midpoint), `raise` = the box's height above the pedestal top over `lift_m` (at most 1,
    /// 0 while no hand touches it). Done: raised ≥ 80 % of `lift_m` in a hand, off the floor.
    Lift {
        /// Weight.
        weight: f32,
        /// The box's prop name.
        prop: String,
        /// The pedestal's prop name.
        pedestal: String,
        /// When the clip's hands close on the box (s).
        grip_s: f64,
        /// How far to raise the box's bottom above the pedestal top (m).
        lift_m: f64,
        /// Sharpness of the hold term (1/m²).
        #[serde(default = "default_hold_scale")]
        scale: f64,
        /// Each episode moves the pedestal off the clip's spot by up to `jitter_m` (uniform in
        /// a disc) and turns it, with the box on it, by up to ±`jitter_deg` about its centre,
        /// scaled by how far the start frame is from the grip (full at the clip's first frame
        /// and from a predecessor's end pose, none once gripped): where a walk arrives, the
        /// pedestal is seldom exactly under the clip's hands or square to them.
        #[serde(default, skip_serializing_if = "is_zero")]
        jitter_m: f64,
        /// See `jitter_m` (degrees either way).
        #[serde(default, skip_serializing_if = "is_zero")]
        jitter_deg: f64,
    },
    /// Carry: the box `prop` starts between the clip's hands; reward
    /// `weight · (0.6·hold + 0.4·exp(−speed_scale·‖v − v̂‖²))` with `hold` as for [`Goal::Lift`]
    /// and `v̂` the clip's root velocity in the heading frame. Done: a hand on the box, its
    /// centre within 0.2 m of the hands' midpoint, off the floor.
    Carry {
        /// Weight.
        weight: f32,
        /// The box's prop name.
        prop: String,
        /// Sharpness of the hold term (1/m²).
        #[serde(default = "default_hold_scale")]
        scale: f64,
        /// Sharpness of the velocity term.
        #[serde(default = "default_speed_scale")]
        speed_scale: f64,
        /// Above 0, the box counts as dropped (the episode ends) once its centre is more than
        /// this far (m) from the hands' midpoint: held out of both hands' reach, hanging from
        /// one gripping hand or cradled on the forearms, it is no longer carried between them.
        /// 0: only the floor drops it.
        #[serde(default, skip_serializing_if = "is_zero")]
        hold_m: f64,
        /// With a target, carry steers: the policy observes a 2-D target as walk stage 2's does
        /// (`[sin ψ, cos ψ, distance]`, drawn, reached and replaced the same way) and the
        /// velocity term gives way to walk stage 2's target term, so the meta-controller can
        /// send the box anywhere (the warehouse's other pedestal) rather than straight ahead.
        #[serde(default, skip_serializing_if = "Option::is_none")]
        target: Option<Steering>,
    },
    /// Put down: the pedestal stands under the clip's hands at `release_s`; the box starts in
    /// the hands before it, on the pedestal after. Reward `weight · (0.5 + 0.5·released)` once
    /// the box rests on the pedestal (≥ 4 contacts), else `weight · 0.5·exp(−scale·d²)` with `d`
    /// the box centre's distance to its resting place on the pedestal top. Done: resting on
    /// the pedestal, no hand on it.
    PutDown {
        /// Weight.
        weight: f32,
        /// The box's prop name.
        prop: String,
        /// The pedestal's prop name.
        pedestal: String,
        /// When the clip's hands let go of the box (s).
        release_s: f64,
        /// Sharpness of the placement term (1/m²).
        #[serde(default = "default_hold_scale")]
        scale: f64,
        /// As for [`Goal::Lift`]: the pedestal off the clip's spot by up to `jitter_m`, turned
        /// by up to ±`jitter_deg`, full at the clip's first frame and none once released.
        #[serde(default, skip_serializing_if = "is_zero")]
        jitter_m: f64,
        /// See `jitter_m` (degrees either way).
        #[serde(default, skip_serializing_if = "is_zero")]
        jitter_deg: f64,
    },
    /// Catch: the ball `prop` is thrown (per `throw`, from in front) at the clip's hands'
    /// midpoint at `catch_s`, arriving then: its forward speed is drawn from `throw.v_x` and
    /// its distance is what that speed covers in the time left (the spec's `distance_m` is not
    /// used; with `free_timing` it is, and the ball arrives when it arrives); starts at or after
    /// `catch_s` (less than 0.25 s before) put it in the hands.
    /// Reward `weight · hold` as for [`Goal::Lift`]; the ball on the floor ends the episode.
    /// Done: off the floor, in a hand or within 0.2 m of the hands' midpoint.
    Catch {
        /// Weight.
        weight: f32,
        /// The ball's prop name.
        prop: String,
        /// When the clip's hands meet the ball (s).
        catch_s: f64,
        /// How the ball is thrown.
        #[serde(default)]
        throw: ThrowSpec,
        /// Sharpness of the hold term (1/m²).
        #[serde(default = "default_hold_scale")]
        scale: f64,
        /// Throw as a scenario does (the toss): the distance drawn from `throw.distance_m`
        /// and the ball arriving whenever that takes at its speed (d/v_x), not at `catch_s`.
        /// The policy must then time the catch from the ball's pose and velocity.
        #[serde(default, skip_serializing_if = "is_false")]
        free_timing: bool,
    },
}

fn default_hold_scale() -> f64 {
    20.0
}

fn default_speed_scale() -> f64 {
    2.0
}

impl Goal {
    /// The goal term's weight in the reward sum.
    pub fn weight(&self) -> f32 {
        match self {
            Goal::None => 0.0,
            Goal::RootVelocity { weight, .. }
            | Goal::Heading { weight, .. }
            | Goal::Target { weight, .. }
            | Goal::Seat { weight, .. }
            | Goal::Lift { weight, .. }
            | Goal::Carry { weight, .. }
            | Goal::PutDown { weight, .. }
            | Goal::Catch { weight, .. } => *weight,
        }
    }

    /// The 2-D target a goal steers towards, if it has one: walk stage 2's ([`Goal::Target`])
    /// or a steering carry's.
    pub fn steering(&self) -> Option<Steering> {
        match self {
            &Goal::Target { distance_m, azimuth_deg, reach_m, speed_scale, facing_scale, retarget_s, .. } => {
                Some(Steering { distance_m, azimuth_deg, reach_m, speed_scale, facing_scale, retarget_s })
            }
            Goal::Carry { target, .. } => *target,
            _ => None,
        }
    }

    /// The free prop (box, ball) an object goal is about, with the goal's name.
    pub fn object(&self) -> Option<(&'static str, &str)> {
        match self {
            Goal::Lift { prop, .. } => Some(("Lift", prop)),
            Goal::Carry { prop, .. } => Some(("Carry", prop)),
            Goal::PutDown { prop, .. } => Some(("PutDown", prop)),
            Goal::Catch { prop, .. } => Some(("Catch", prop)),
            _ => None,
        }
    }

    /// How far (m, degrees) an object goal moves and turns its pedestal off the clip's spot
    /// per episode at most ([`Goal::Lift`]'s and [`Goal::PutDown`]'s `jitter_m`, `jitter_deg`).
    pub fn pedestal_jitter(&self) -> (f64, f64) {
        match self {
            &Goal::Lift { jitter_m, jitter_deg, .. } | &Goal::PutDown { jitter_m, jitter_deg, .. } => {
                (jitter_m, jitter_deg)
            }
            _ => (0.0, 0.0),
        }
    }

    /// The fixed prop (pedestal) an object goal places under the clip's hands.
    pub fn pedestal(&self) -> Option<&str> {
        match self {
            Goal::Lift { pedestal, .. } | Goal::PutDown { pedestal, .. } => Some(pedestal),
            _ => None,
        }
    }
}

/// Where episodes start.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub enum Init {
    /// Reference-state initialisation: a uniformly random frame of the clip (not the last),
    /// with its velocities.
    Reference,
    /// The clip's first frame.
    Start,
    /// End poses of the predecessor skills (transition fine-tuning): with probability
    /// `fraction` a random state from their pools, else reference-state initialisation.
    Pools {
        /// Predecessor skills whose pools to draw from.
        from: Vec<String>,
        /// Share of episodes started from the pools.
        fraction: f64,
        /// The pool state's velocities (root and joints) are scaled by a factor drawn
        /// uniformly from this range per episode: a curriculum from frozen poses towards the
        /// predecessors' full momentum. `(1, 1)` (the default) starts them as recorded.
        #[serde(default = "full_speed")]
        speed: (f64, f64),
    },
}

fn full_speed() -> (f64, f64) {
    (1.0, 1.0)
}

impl Init {
    /// Starts from the end poses of `from` only, as recorded (evaluation).
    pub fn pools(from: Vec<String>) -> Self {
        Init::Pools { from, fraction: 1.0, speed: full_speed() }
    }

    /// Why these settings cannot start episodes, if they cannot (a spec's `init`, or the one
    /// `skill finetune` builds from its options).
    pub fn check(&self) -> std::result::Result<(), FieldError> {
        let Init::Pools { fraction, from, speed } = self else { return Ok(()) };
        if !(0.0..=1.0).contains(fraction) {
            return Err(FieldError::new("init.Pools.fraction", fraction, "it must be in [0, 1]"));
        }
        if !(speed.0.is_finite() && speed.1.is_finite() && 0.0 <= speed.0 && speed.0 <= speed.1) {
            return Err(FieldError::new(
                "init.Pools.speed",
                format!("{speed:?}"),
                "it must be a range (lo, hi) with 0 ≤ lo ≤ hi",
            ));
        }
        if from.is_empty() {
            return Err(FieldError::new("init.Pools.from", "[]", "it must name a predecessor skill"));
        }
        Ok(())
    }
}

/// When an episode ends early.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct Termination {
    /// End when a body part other than the feet (and, for sit, the pelvis on the seat)
    /// touches the floor.
    pub fall: bool,
    /// End when the pelvis is lower than this (m).
    pub min_height: f64,
}

impl Default for Termination {
    fn default() -> Self {
        Termination { fall: true, min_height: 0.3 }
    }
}

/// A fixed prop (a chair) put in the way of a steering goal's targets: the walk learns to go
/// round what it observes (the spec's features should include the prop's `PropPose`), for
/// scenarios where its target lies beside furniture. At every new target, with probability `chance`, the prop is moved onto the straight way
/// from the pelvis to the target, `along` that way (fractions of the distance) and up to
/// `offset_m` to either side, facing anywhere, unless that spot is nearer the pelvis than
/// `clearance_m`; otherwise it stays where it stands (an episode's first target instead puts
/// it 1.5–4 m off in any direction, never nearer than `clearance_m`). Touching the prop ends
/// the episode unless `touch_ends` is false.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Obstacle {
    /// The fixed prop's name in the skill's scene.
    pub prop: String,
    /// Share of targets the prop is put in the way of, in [0, 1].
    pub chance: f64,
    /// Where on the way to the target (fractions of the pelvis-to-target distance, in (0, 2]:
    /// above 1 the prop stands beyond the target, as a chair does beyond the spot in front of it
    /// that a sitting controller walks to).
    pub along: (f64, f64),
    /// Largest sideways offset from the straight way (m).
    pub offset_m: f64,
    /// The prop's centre is never put nearer the pelvis than this (m).
    pub clearance_m: f64,
    /// Whether touching the prop ends the episode like a fall (the default); `false` lets the
    /// walk bump it and learn to stay up (only a real fall ends the episode then).
    #[serde(default = "yes", skip_serializing_if = "is_true")]
    pub touch_ends: bool,
}

fn yes() -> bool {
    true
}

fn is_true(b: &bool) -> bool {
    *b
}

impl Obstacle {
    /// Why these settings cannot place the prop, if they cannot.
    pub fn check(&self) -> std::result::Result<(), FieldError> {
        let (lo, hi) = self.along;
        if !(0.0..=1.0).contains(&self.chance) {
            return Err(FieldError::new("obstacle.chance", self.chance, "it must be in [0, 1]"));
        }
        if !(lo.is_finite() && hi.is_finite() && 0.0 < lo && lo <= hi && hi <= 2.0) {
            return Err(FieldError::new(
                "obstacle.along",
                format!("({lo}, {hi})"),
                "it must satisfy 0 < low ≤ high ≤ 2",
            ));
        }
        if !(self.offset_m.is_finite() && self.offset_m >= 0.0) {
            return Err(FieldError::new("obstacle.offset_m", self.offset_m, "it must be finite and ≥ 0"));
        }
        if !(self.clearance_m.is_finite() && self.clearance_m > 0.0 && self.clearance_m < 4.0) {
            return Err(FieldError::new("obstacle.clearance_m", self.clearance_m, "it must be in (0, 4) m"));
        }
        Ok(())
    }
}

/// A skill spec, as written in `specs/*.ron`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SkillSpec {
    /// The skill's name: its library folder (see [`repertoire_scenes::scenario::skill_name_problem`]).
    pub name: String,
    /// The scene it trains in: a scenario file relative to the spec, or `builtin:sit`.
    pub scene: String,
    /// The reference clip.
    pub clip: ClipRef,
    /// What the policy observes (then the phase and the goal's values).
    #[serde(default = "Feature::proprioception")]
    pub features: Vec<Feature>,
    /// The imitation reward.
    #[serde(default)]
    pub imitation: Imitation,
    /// The goal reward.
    pub goal: Goal,
    /// Where episodes start.
    pub init: Init,
    /// Early termination.
    #[serde(default)]
    pub termination: Termination,
    /// Episode time limit (s): looping clips run this long, others end with the clip (and its
    /// hold) or this, whichever comes first.
    pub episode_s: f64,
    /// PPO iterations of `skill train`.
    pub iterations: usize,
    /// PPO and network settings.
    pub ppo: PpoConfig,
    /// The hands' grip level while the skill plays, in [0, 1]: in scenes with a free object
    /// each hand presses what it touches against itself with this fraction of
    /// `repertoire_scenes::compose::GRIP_FORCE_N` (a MuJoCo adhesion actuator standing in for
    /// fingers). The level is part of the skill, not of its policy: the meta-controller applies
    /// each skill's own while it plays. 0 (the default) lets go.
    #[serde(default, skip_serializing_if = "is_zero")]
    pub grip: f64,
    /// A prop put in the way of a steering goal's targets ([`Obstacle`]); none by default.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub obstacle: Option<Obstacle>,
    /// For a skill without a seat goal that a sitting controller hands over to before the sit
    /// (the stand): the fixed prop of its scene that a pool state recorded by `repertoire meta
    /// deliver` puts where the controller left the seat, so the skill trains with the chair
    /// where it will meet it. A state without a recorded seat leaves the prop where the scene
    /// puts it. A seat goal's chair always follows a delivered state; none by default.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub delivered_seat: Option<String>,
}

fn is_false(b: &bool) -> bool {
    !*b
}

fn is_zero(x: &f64) -> bool {
    *x == 0.0
}

/// A spec with the file it came from.
#[derive(Debug, Clone)]
pub struct SpecFile {
    /// The spec.
    pub spec: SkillSpec,
    /// Where it was read (relative paths in it are relative to its folder).
    pub path: PathBuf,
}

/// The folder of the clip pack (`REPERTOIRE_CLIPS`, else the repository's `third_party/clips`).
pub fn clip_pack_dir() -> PathBuf {
    std::env::var_os("REPERTOIRE_CLIPS")
        .map(PathBuf::from)
        .unwrap_or_else(|| Path::new(env!("CARGO_MANIFEST_DIR")).join("../../third_party/clips"))
}

impl SpecFile {
    /// Reads and checks a spec.
    pub fn load(path: &Path) -> Result<Self> {
        let text = std::fs::read_to_string(path).map_err(|e| SkillError::io(path, "cannot read the skill spec", e))?;
        Self::parse(path, &text)
    }

    /// Parses and checks spec text; `path` is used in messages and for relative paths.
    pub fn parse(path: &Path, text: &str) -> Result<Self> {
        let spec: SkillSpec = repertoire_files::parse_ron(path, text)?;
        let bad = |m: String| Err(SkillError::Invalid(format!("{}: {m}", path.display())));
        if let Some(problem) = repertoire_scenes::scenario::skill_name_problem(&spec.name) {
            return bad(problem);
        }
        if !(spec.episode_s.is_finite() && spec.episode_s > 0.0) {
            return bad(format!("episode_s must be positive, got {}", spec.episode_s));
        }
        if let Some((a, b)) = spec.clip.cut_s
            && !(0.0 <= a && a < b)
        {
            return bad(format!("clip cut_s ({a}, {b}) must satisfy 0 ≤ start < end"));
        }
        if !(spec.clip.hold_s.is_finite() && spec.clip.hold_s >= 0.0) {
            return bad(format!("clip hold_s must be finite and ≥ 0, got {}", spec.clip.hold_s));
        }
        if spec.clip.looping && spec.clip.hold_s > 0.0 {
            return bad("clip cannot both loop and hold its last frame (`looping` and `hold_s`)".into());
        }
        if !(spec.clip.lead_s.is_finite() && (0.0..=10.0).contains(&spec.clip.lead_s)) {
            return bad(format!("clip lead_s must be between 0 and 10 s, got {}", spec.clip.lead_s));
        }
        if spec.clip.looping && spec.clip.lead_s > 0.0 {
            return bad("clip cannot both loop and lead in with its first frame (`looping` and `lead_s`)".into());
        }
        if let Err(e) = spec.init.check() {
            return bad(e.to_string());
        }
        for (name, v) in &spec.clip.pose_deg {
            if !v.is_finite() {
                return bad(format!("clip pose_deg `{name}` is not finite"));
            }
        }
        let goal_times: &[(&str, f64)] = match &spec.goal {
            Goal::Lift { grip_s, lift_m, scale, .. } => {
                if !(lift_m.is_finite() && *lift_m > 0.0) {
                    return bad(format!("goal Lift lift_m must be positive, got {lift_m}"));
                }
                &[("grip_s", *grip_s), ("scale", *scale)]
            }
            Goal::Carry { scale, speed_scale, hold_m, .. } => {
                &[("scale", *scale), ("speed_scale", *speed_scale), ("hold_m", *hold_m)]
            }
            Goal::PutDown { release_s, scale, .. } => &[("release_s", *release_s), ("scale", *scale)],
            Goal::Catch { catch_s, throw, scale, .. } => {
                if let Err(e) = throw.validate() {
                    return Err(SkillError::Invalid(format!("{}: goal Catch: {e}", path.display())));
                }
                &[("catch_s", *catch_s), ("scale", *scale)]
            }
            _ => &[],
        };
        let (jm, jd) = spec.goal.pedestal_jitter();
        if !(jm.is_finite() && (0.0..=1.0).contains(&jm)) {
            return bad(format!("goal jitter_m must be between 0 and 1 m, got {jm}"));
        }
        if !(jd.is_finite() && (0.0..=180.0).contains(&jd)) {
            return bad(format!("goal jitter_deg must be between 0 and 180, got {jd}"));
        }
        for (name, v) in goal_times {
            if !(v.is_finite() && *v >= 0.0) {
                return bad(format!("goal {name} must be finite and ≥ 0, got {v}"));
            }
        }
        if spec.ppo.num_envs == 0 || spec.ppo.num_steps == 0 {
            return bad("ppo num_envs and num_steps must be positive".into());
        }
        if let Some(st) = spec.goal.steering() {
            let (lo, hi) = st.distance_m;
            if !(lo.is_finite() && hi.is_finite() && 0.0 < lo && lo <= hi) {
                return bad(format!("the goal's target distance_m ({lo}, {hi}) must satisfy 0 < low ≤ high"));
            }
            if !(0.0..=180.0).contains(&st.azimuth_deg) {
                return bad(format!("the goal's target azimuth_deg must be between 0 and 180, got {}", st.azimuth_deg));
            }
            for (name, v) in [
                ("reach_m", st.reach_m),
                ("speed_scale", st.speed_scale),
                ("facing_scale", st.facing_scale),
                ("retarget_s", st.retarget_s),
            ] {
                if !(v.is_finite() && v >= 0.0) {
                    return bad(format!("the goal's target {name} must be finite and ≥ 0, got {v}"));
                }
            }
        }
        if !(0.0..=1.0).contains(&spec.grip) {
            return bad(format!("grip must be between 0 and 1, got {}", spec.grip));
        }
        if let Some(o) = &spec.obstacle {
            if spec.goal.steering().is_none() {
                return bad(format!(
                    "obstacle `{}` needs a goal with a walking target (Target, or Carry with one)",
                    o.prop
                ));
            }
            if let Err(e) = o.check() {
                return bad(e.to_string());
            }
        }
        Ok(SpecFile { spec, path: path.to_path_buf() })
    }

    /// Resolves a path written in the spec: `pack:NAME` in the clip pack, relative paths
    /// against the spec's folder.
    pub fn resolve(&self, file: &str) -> PathBuf {
        if let Some(name) = file.strip_prefix("pack:") {
            return clip_pack_dir().join(name);
        }
        let p = Path::new(file);
        if p.is_absolute() { p.to_path_buf() } else { self.path.parent().unwrap_or(Path::new(".")).join(p) }
    }
}
