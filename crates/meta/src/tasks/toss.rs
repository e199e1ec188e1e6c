//! The toss task of Catch & Carry: a ball thrown at the walker from about 3 m must be caught and
//! put into a bucket. Caught: both hands touch the ball while it is off the floor. Failure: the
//! ball or a body part other than the feet touches the floor. Reward per decision: the seconds
//! the ball spent in the bucket, plus, once caught, `0.5·(−V)` with `V` the rate of change of the
//! ball's horizontal distance to the bucket (the sitting task's shaping, towards the bucket).

use rand::Rng;
use repertoire_scenes::scenario::{CatchPoint, Prop, Toss};
use repertoire_scenes::world::PropMount;
use repertoire_scenes::{Throw, ThrowSpec, World, WorldModel};

use crate::error::{MetaError, Result};

/// The toss task resolved to prop indices of one scene.
#[derive(Debug, Clone, PartialEq)]
pub struct TossSpec {
    /// The ball (prop index).
    pub ball: usize,
    /// The bucket (prop index).
    pub bucket: usize,
    /// How it is thrown.
    pub throw: ThrowSpec,
    /// Where it is aimed, relative to the walker.
    pub catch_at: CatchPoint,
    /// The bucket's inner radius and wall height (m).
    pub bucket_size: (f64, f64),
    /// The ball's radius before its per-episode scale (m).
    pub ball_radius: f64,
}

impl TossSpec {
    /// Resolves `task` in `world`'s scene.
    pub fn new(model: &WorldModel, task: &Toss) -> Result<Self> {
        let id = |name: &str| {
            model.prop_id(name).ok_or_else(|| MetaError::Invalid(format!("the toss task names no prop `{name}`")))
        };
        let (ball, bucket) = (id(&task.ball)?, id(&task.bucket)?);
        let props = &model.scenario.scenario.props;
        let (Prop::Ball(b), Prop::Bucket(k)) = (&props[ball], &props[bucket]) else {
            return Err(MetaError::Invalid("the toss task needs a ball and a bucket".into()));
        };
        Ok(TossSpec {
            ball,
            bucket,
            throw: task.throw,
            catch_at: task.catch_at,
            bucket_size: (k.radius, k.height),
            ball_radius: b.radius,
        })
    }

    /// The catch point in front of the walker as it stands now (world frame).
    pub fn target(&self, world: &World) -> [f64; 3] {
        let p = world.pelvis_frame().pos;
        let (s, c) = world.heading().sin_cos();
        [p[0] + self.catch_at.forward * c, p[1] + self.catch_at.forward * s, self.catch_at.height]
    }

    /// Draws a throw at the walker (from in front of it) and launches the ball; with `cell`
    /// `(v_x, lateral)`, that forward and sideways speed (a strike-zone grid cell), the rest drawn.
    pub fn launch(&self, world: &mut World, rng: &mut impl Rng, cell: Option<(f64, f64)>) -> Result<Throw> {
        let target = self.target(world);
        let yaw = world.heading();
        let throw = match cell {
            None => self.throw.sample(target, yaw, rng),
            Some((v_x, lateral)) => {
                let d_x = self.throw.distance_m.sample(rng);
                let d_z = self.throw.d_z.sample(rng);
                self.throw.throw_with(target, yaw, d_x, v_x, lateral, d_z, rng)
            }
        };
        throw.launch(world, self.ball)?;
        Ok(throw)
    }
}

/// What the toss tests read from the world in one control tick.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TossFacts {
    /// Which hands (left, right) touch the ball.
    pub hands_on_ball: [bool; 2],
    /// The ball touches the floor.
    pub ball_on_floor: bool,
    /// The fall test counted a fall ([`World::has_fallen`]).
    pub fallen: bool,
    /// The ball is inside the bucket (centre within its radius, below its rim).
    pub in_bucket: bool,
    /// Horizontal distance from the ball to the bucket's centre (m).
    pub to_bucket_m: f64,
}

impl TossFacts {
    /// Reads the facts from `world`.
    pub fn measure(world: &World, spec: &TossSpec) -> Self {
        let contacts = world.contacts();
        let ball = world.body_position(world.model().props[spec.ball].body);
        let bucket = world.placements()[spec.bucket].pos;
        let to_bucket_m = (ball[0] - bucket[0]).hypot(ball[1] - bucket[1]);
        let (radius, height) = spec.bucket_size;
        TossFacts {
            hands_on_ball: contacts.hands_on_prop(spec.ball),
            ball_on_floor: contacts.prop_on_floor(spec.ball),
            fallen: world.has_fallen(),
            in_bucket: to_bucket_m < radius && ball[2] < bucket[2] + height,
            to_bucket_m,
        }
    }

    /// Whether the ball is caught: both hands on it, off the floor.
    pub fn caught(&self) -> bool {
        self.hands_on_ball == [true, true] && !self.ball_on_floor
    }

    /// Whether the episode has failed: the ball or a non-foot body part on the floor.
    pub fn failed(&self) -> bool {
        self.fallen || self.ball_on_floor
    }
}

/// Judges one toss episode, tick by tick.
#[derive(Debug, Clone, PartialEq)]
pub struct TossJudge {
    /// The ball has been caught (stays true).
    pub caught: bool,
    /// The episode has failed.
    pub failed: bool,
    /// The ball was dropped onto the floor.
    pub dropped: bool,
    /// Seconds the ball has spent in the bucket.
    pub bucket_s: f64,
    /// Seconds in the bucket since the last reward.
    pending_s: f64,
    /// Ball-to-bucket distance at the last reward (m).
    last_distance: f64,
    /// The throw's forward and sideways speeds (m/s).
    pub throw: (f64, f64),
}

impl TossJudge {
    /// A judge for a ball thrown with forward speed `v_x` and sideways speed `lateral`, starting
    /// `distance` metres from the bucket.
    pub fn new(v_x: f64, lateral: f64, distance: f64) -> Self {
        TossJudge {
            caught: false,
            failed: false,
            dropped: false,
            bucket_s: 0.0,
            pending_s: 0.0,
            last_distance: distance,
            throw: (v_x, lateral),
        }
    }

    /// Records one control tick of `dt` seconds.
    pub fn tick(&mut self, facts: &TossFacts, dt: f64) {
        if self.failed {
            return;
        }
        if facts.in_bucket && !facts.ball_on_floor {
            self.bucket_s += dt;
            self.pending_s += dt;
        }
        if facts.failed() {
            self.failed = true;
            self.dropped = facts.ball_on_floor;
            return;
        }
        if facts.caught() {
            self.caught = true;
        }
    }

    /// The reward of a decision that lasted `seconds` and ended with the ball `distance` metres
    /// from the bucket.
    pub fn take_reward(&mut self, distance: f64, seconds: f64) -> f32 {
        let shaping = if self.caught && !self.failed && seconds > 0.0 {
            0.5 * (self.last_distance - distance) / seconds
        } else {
            0.0
        };
        self.last_distance = distance;
        (std::mem::take(&mut self.pending_s) + shaping) as f32
    }

    /// Whether the ball is or was in the bucket.
    pub fn delivered(&self) -> bool {
        self.bucket_s > 0.0
    }

    /// The judge's state as numbers (checkpoints).
    pub fn snapshot(&self) -> [f64; 8] {
        [
            f64::from(u8::from(self.caught)),
            f64::from(u8::from(self.failed)),
            f64::from(u8::from(self.dropped)),
            self.bucket_s,
            self.pending_s,
            self.last_distance,
            self.throw.0,
            self.throw.1,
        ]
    }

    /// Restores [`TossJudge::snapshot`]'s output.
    pub fn restore(&mut self, s: &[f64]) {
        self.caught = s[0] != 0.0;
        self.failed = s[1] != 0.0;
        self.dropped = s[2] != 0.0;
        self.bucket_s = s[3];
        self.pending_s = s[4];
        self.last_distance = s[5];
        self.throw = (s[6], s[7]);
    }
}

/// The ball's linear velocity (world frame, m/s).
pub fn ball_velocity(world: &World, spec: &TossSpec) -> [f64; 3] {
    match world.model().props[spec.ball].mount {
        PropMount::Free { dof, .. } => {
            let v = &world.data().qvel()[dof..dof + 3];
            [v[0], v[1], v[2]]
        }
        PropMount::Fixed { .. } => [0.0; 3],
    }
}
