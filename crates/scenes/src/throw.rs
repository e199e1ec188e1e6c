//! Ball throws towards the character (Catch & Carry's toss task): where the ball leaves from, how
//! fast, and the spin, drawn per episode so that it arrives at a chosen point.
//!
//! The ball leaves `d_x` in front of the catch point and `d_z` below it, with forward speed
//! `v_x` and a lateral speed; the vertical speed comes from the paper's formula
//! `v_z = (4.9·t_hit² + d_z) / t_hit`, `t_hit = d_x / v_x`, so that without air drag it rises by
//! `d_z` over the flight and reaches the catch point's height after `t_hit` seconds.

use crate::param::Param;
use rand::Rng;
use repertoire_files::FieldError;
use serde::{Deserialize, Serialize};

/// Half of standard gravity as the paper writes it (m/s²).
const HALF_G: f64 = 4.9;

/// How balls are thrown, as written in a scenario or skill spec.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct ThrowSpec {
    /// Horizontal distance from the launch point to the catch point, m.
    pub distance_m: Param,
    /// Speed towards the character, m/s.
    pub v_x: Param,
    /// Sideways speed, m/s (positive: to the thrower's left).
    pub lateral: Param,
    /// Height gained over the flight (catch point above launch point), m.
    pub d_z: Param,
    /// Largest spin about each axis, rad/s (uniform in ±spin).
    pub spin: f64,
}

impl Default for ThrowSpec {
    fn default() -> Self {
        ThrowSpec {
            distance_m: Param::Uniform(2.8, 3.2),
            v_x: Param::Uniform(1.5, 4.5),
            lateral: Param::Uniform(-0.75, 0.75),
            d_z: Param::Uniform(0.1, 0.4),
            spin: 6.0,
        }
    }
}

/// One drawn throw: the ball's start state and when it reaches the catch point.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Throw {
    /// Launch position, world frame (m).
    pub pos: [f64; 3],
    /// Launch velocity, world frame (m/s).
    pub linvel: [f64; 3],
    /// Spin, world frame (rad/s).
    pub angvel: [f64; 3],
    /// Seconds until the ball is over the catch point's line.
    pub t_hit: f64,
    /// Forward speed drawn (m/s).
    pub v_x: f64,
    /// Sideways speed drawn (m/s).
    pub lateral: f64,
}

impl ThrowSpec {
    /// Checks the ranges; `Err` names the first bad field (`throw.v_x`).
    pub fn validate(&self) -> std::result::Result<(), FieldError> {
        let positive = |p: Param, name: &str| {
            if p.min() > 0.0 && p.max().is_finite() {
                Ok(())
            } else {
                Err(FieldError::new(format!("throw.{name}"), format!("{p:?}"), "it must be positive and finite"))
            }
        };
        positive(self.distance_m, "distance_m")?;
        positive(self.v_x, "v_x")?;
        for (p, name) in [(self.lateral, "lateral"), (self.d_z, "d_z")] {
            if !(p.min().is_finite() && p.max().is_finite()) {
                return Err(FieldError::new(format!("throw.{name}"), format!("{p:?}"), "it must be finite"));
            }
        }
        if !(self.spin.is_finite() && self.spin >= 0.0) {
            return Err(FieldError::new("throw.spin", self.spin, "it must be ≥ 0"));
        }
        Ok(())
    }

    /// Draws a throw at the catch point `target` (world frame) from the direction `yaw`
    /// (radians: the ball comes from `target + distance·(cos yaw, sin yaw)`).
    pub fn sample(&self, target: [f64; 3], yaw: f64, rng: &mut impl Rng) -> Throw {
        let d_x = self.distance_m.sample(rng);
        let v_x = self.v_x.sample(rng);
        let lateral = self.lateral.sample(rng);
        let d_z = self.d_z.sample(rng);
        self.throw_with(target, yaw, d_x, v_x, lateral, d_z, rng)
    }

    /// A throw with the given distance and speeds (a grid cell of the strike-zone figure); the
    /// spin is still drawn.
    #[allow(clippy::too_many_arguments)]
    pub fn throw_with(
        &self,
        target: [f64; 3],
        yaw: f64,
        d_x: f64,
        v_x: f64,
        lateral: f64,
        d_z: f64,
        rng: &mut impl Rng,
    ) -> Throw {
        let t_hit = d_x / v_x;
        let v_z = (HALF_G * t_hit * t_hit + d_z) / t_hit;
        let (s, c) = yaw.sin_cos();
        // The thrower faces −(cos yaw, sin yaw); its left is (sin yaw, −cos yaw).
        let pos = [target[0] + d_x * c, target[1] + d_x * s, target[2] - d_z];
        let linvel = [-v_x * c + lateral * s, -v_x * s - lateral * c, v_z];
        let mut spin = || if self.spin > 0.0 { rng.random_range(-self.spin..=self.spin) } else { 0.0 };
        let angvel = [spin(), spin(), spin()];
        Throw { pos, linvel, angvel, t_hit, v_x, lateral }
    }
}
