//! End-pose pools: states in which a skill ended successfully, stored independent of where the
//! character stood and which way it faced, so a successor skill can start from them anywhere.

use std::path::Path;

use repertoire_scenes::World;
use repertoire_scenes::math::wrap_angle;
use repertoire_scenes::world::PropPlacement;
use serde::{Deserialize, Serialize};

use crate::error::{Result, SkillError};
use crate::quat::{mul, yaw_of, yaw_quat};
use crate::reference::to_heading;

/// One character state with its position and heading factored out.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct PoolState {
    /// Pelvis (root) height.
    pub height: f64,
    /// Root orientation with its heading removed (w x y z).
    pub quat: [f64; 4],
    /// Root linear velocity in the heading frame.
    pub velocity: [f64; 3],
    /// Root angular velocity (root frame, MuJoCo's qvel convention).
    pub angular: [f64; 3],
    /// Actuated joint angles, map order.
    pub joints: Vec<f64>,
    /// Actuated joint velocities, map order.
    pub joint_vel: Vec<f64>,
    /// The skill's reference frame at this state (so a successor that continues the same skill,
    /// like the meta-controller starting mid-walk, knows where in the clip it is).
    #[serde(default)]
    pub phase: usize,
    /// Where the seat stood when the state was recorded, in the state's heading frame: metres
    /// ahead of and to the left of the root, and its yaw relative to the heading. States a
    /// meta-controller delivered (`repertoire meta deliver`) carry it, and a sit fine-tuned from
    /// them meets the chair where the controller left it; predecessors' end poses do not, and
    /// the chair stands where the clip expects it.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub seat: Option<[f64; 3]>,
}

impl PoolState {
    /// Captures `world`'s character.
    pub fn capture(world: &World) -> Self {
        let idx = &world.model().index;
        let (q, v) = (world.data().qpos(), world.data().qvel());
        let (r, d) = (idx.root_qpos, idx.root_dof);
        let quat = [q[r + 3], q[r + 4], q[r + 5], q[r + 6]];
        let (_, yaw) = root_position_and_yaw(world);
        PoolState {
            height: q[r + 2],
            quat: mul(yaw_quat(-yaw), quat),
            velocity: to_heading(yaw, [v[d], v[d + 1], v[d + 2]]),
            angular: [v[d + 3], v[d + 4], v[d + 5]],
            joints: idx.joints.iter().map(|j| q[j.qpos]).collect(),
            joint_vel: idx.joints.iter().map(|j| v[j.dof]).collect(),
            phase: 0,
            seat: None,
        }
    }

    /// [`PoolState::capture`] with the pose of the seat (its placement) kept in the state's
    /// heading frame.
    pub fn capture_with_seat(world: &World, seat: &PropPlacement) -> Self {
        let mut state = Self::capture(world);
        let ([x, y], yaw) = root_position_and_yaw(world);
        let d = to_heading(yaw, [seat.pos[0] - x, seat.pos[1] - y, 0.0]);
        state.seat = Some([d[0], d[1], wrap_angle(seat.yaw - yaw)]);
        state
    }

    /// Where this state's recorded seat stands in the world, `(x, y, yaw)`, once the state is
    /// applied at `(x, y)` facing `yaw` (see [`PoolState::seat`]).
    pub fn seat_in_world(&self, x: f64, y: f64, yaw: f64) -> Option<[f64; 3]> {
        self.seat.map(|[dx, dy, dyaw]| {
            let (s, c) = yaw.sin_cos();
            [x + c * dx - s * dy, y + s * dx + c * dy, wrap_angle(yaw + dyaw)]
        })
    }

    /// Puts the character in this state at `(x, y)` facing `yaw`.
    pub fn apply(&self, world: &mut World, x: f64, y: f64, yaw: f64) -> Result<()> {
        self.apply_at_speed(world, x, y, yaw, 1.0)
    }

    /// [`PoolState::apply`] with every velocity (root and joints) scaled by `k`: `0` freezes
    /// the pose, `1` keeps the recorded momentum.
    pub fn apply_at_speed(&self, world: &mut World, x: f64, y: f64, yaw: f64, k: f64) -> Result<()> {
        let (s, c) = yaw.sin_cos();
        let v = self.velocity.map(|v| k * v);
        let w = self.angular.map(|w| k * w);
        let root_vel = [c * v[0] - s * v[1], s * v[0] + c * v[1], v[2], w[0], w[1], w[2]];
        let pose = mul(yaw_quat(yaw), self.quat);
        if k == 1.0 {
            world.set_motion([x, y, self.height], pose, &self.joints, root_vel, Some(&self.joint_vel))?;
        } else {
            let joint_vel: Vec<f64> = self.joint_vel.iter().map(|v| k * v).collect();
            world.set_motion([x, y, self.height], pose, &self.joints, root_vel, Some(&joint_vel))?;
        }
        Ok(())
    }
}

/// The root's ground position and heading (the yaw of its orientation).
fn root_position_and_yaw(world: &World) -> ([f64; 2], f64) {
    let r = world.model().index.root_qpos;
    let q = world.data().qpos();
    ([q[r], q[r + 1]], yaw_of([q[r + 3], q[r + 4], q[r + 5], q[r + 6]]))
}

/// The end states of one skill.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct Pool {
    /// The skill that produced them.
    pub skill: String,
    /// The body's content hash.
    pub body_hash: String,
    /// The states.
    pub states: Vec<PoolState>,
}

impl Pool {
    /// Reads a pool written by [`Pool::save`].
    pub fn load(path: &Path) -> Result<Self> {
        let text =
            std::fs::read_to_string(path).map_err(|e| SkillError::io(path, "cannot read the end-pose pool", e))?;
        let pool: Pool = ron::from_str(&text).map_err(|e| SkillError::ron(path, e))?;
        if let Some(k) = pool.states.iter().position(|s| {
            let all = [s.height]
                .into_iter()
                .chain(s.quat)
                .chain(s.velocity)
                .chain(s.angular)
                .chain(s.seat.into_iter().flatten());
            all.chain(s.joints.iter().copied()).chain(s.joint_vel.iter().copied()).any(|x| !x.is_finite())
        }) {
            return Err(SkillError::Invalid(format!("{}: state {k} holds a NaN or infinite value", path.display())));
        }
        Ok(pool)
    }

    /// Writes the pool atomically (temp file, then rename).
    pub fn save(&self, path: &Path) -> Result<()> {
        let text = ron::ser::to_string_pretty(self, ron::ser::PrettyConfig::new().depth_limit(1))
            .map_err(|e| SkillError::Invalid(format!("{}: cannot serialise the pool: {e}", path.display())))?;
        crate::library::write_atomic(path, text.as_bytes())
    }
}
