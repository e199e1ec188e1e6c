//! Motion quality: how a rollout moves, measured the same way on the skill's reference clip, so a
//! skill can be held to its reference (foot slip, foot clearance, torso tilt, arm swing, jerk,
//! turn angle) and to how closely it tracked it (the mean pose and end-effector terms).
//!
//! A foot is in stance while its body is within [`STANCE_MARGIN_M`] of its standing height (the
//! same rule for the simulation and for the clip played kinematically, which has no contact
//! forces); slip is its horizontal speed while it stays in stance, clearance the highest it rises
//! over that height in each completed swing.

use repertoire_scenes::math::wrap_angle;
use repertoire_scenes::{World, WorldModel};
use serde::{Deserialize, Serialize};

use crate::reference::{Reference, to_heading};

/// A foot within this of its standing height (m) is in stance.
pub const STANCE_MARGIN_M: f64 = 0.02;

/// Motion figures of one or more rollouts (means over them).
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
pub struct MotionQuality {
    /// Mean horizontal speed of a foot in stance (m/s).
    pub foot_slip_m_s: f64,
    /// Mean of each swing's highest foot lift over its standing height (m).
    pub clearance_m: f64,
    /// Mean angle of the torso's up axis from vertical (degrees).
    pub torso_tilt_deg: f64,
    /// Mean range of each hand's forward offset from the pelvis, heading frame (m).
    pub arm_swing_m: f64,
    /// Mean magnitude of the pelvis position's third derivative (m/s³).
    pub jerk_m_s3: f64,
    /// Heading change from the first to the last tick, unwrapped (degrees, left positive).
    pub turn_deg: f64,
    /// Mean imitation pose term (1 = on the reference's joint angles); none for the reference.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub pose_term: Option<f64>,
    /// Mean imitation end-effector term; none for the reference.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub end_effector_term: Option<f64>,
}

impl MotionQuality {
    /// The mean of `items` (each one rollout's figures); `None` for none.
    pub fn mean(items: &[MotionQuality]) -> Option<MotionQuality> {
        if items.is_empty() {
            return None;
        }
        let n = items.len() as f64;
        let avg = |f: fn(&MotionQuality) -> f64| items.iter().map(f).sum::<f64>() / n;
        let avg_opt = |f: fn(&MotionQuality) -> Option<f64>| {
            let v: Vec<f64> = items.iter().filter_map(f).collect();
            (!v.is_empty()).then(|| v.iter().sum::<f64>() / v.len() as f64)
        };
        Some(MotionQuality {
            foot_slip_m_s: avg(|m| m.foot_slip_m_s),
            clearance_m: avg(|m| m.clearance_m),
            torso_tilt_deg: avg(|m| m.torso_tilt_deg),
            arm_swing_m: avg(|m| m.arm_swing_m),
            jerk_m_s3: avg(|m| m.jerk_m_s3),
            turn_deg: avg(|m| m.turn_deg),
            pose_term: avg_opt(|m| m.pose_term),
            end_effector_term: avg_opt(|m| m.end_effector_term),
        })
    }
}

/// Accumulates [`MotionQuality`] over one rollout, one [`MotionMeter::observe`] per control tick.
#[derive(Debug, Clone)]
pub struct MotionMeter {
    dt: f64,
    stance_z: f64,
    ticks: usize,
    feet: Option<[[f64; 3]; 2]>,
    in_stance: [bool; 2],
    swing_top: [f64; 2],
    slip: (f64, usize),
    clearance: (f64, usize),
    tilt: f64,
    hand_fwd: [(f64, f64); 2],
    pelvis: Vec<[f64; 3]>,
    jerk: (f64, usize),
    heading: Option<f64>,
    turned: f64,
    terms: (f64, f64, usize),
}

impl MotionMeter {
    /// A meter for rollouts in `model`'s scene (one tick: its control period).
    pub fn new(model: &std::sync::Arc<WorldModel>) -> Self {
        let mut world = model.new_world();
        world.place_standing(0.0, 0.0, 0.0);
        let stance_z = model.index.feet.iter().map(|&f| world.body_position(f)[2]).sum::<f64>() / 2.0;
        Self::empty(model.control_dt(), stance_z)
    }

    fn empty(dt: f64, stance_z: f64) -> Self {
        Self {
            dt,
            stance_z,
            ticks: 0,
            feet: None,
            in_stance: [true; 2],
            swing_top: [0.0; 2],
            slip: (0.0, 0),
            clearance: (0.0, 0),
            tilt: 0.0,
            hand_fwd: [(f64::INFINITY, f64::NEG_INFINITY); 2],
            pelvis: Vec::with_capacity(4),
            jerk: (0.0, 0),
            heading: None,
            turned: 0.0,
            terms: (0.0, 0.0, 0),
        }
    }

    /// Starts a new rollout.
    pub fn reset(&mut self) {
        *self = Self::empty(self.dt, self.stance_z);
    }

    /// Reads one tick of `world`.
    pub fn observe(&mut self, world: &World) {
        let idx = &world.model().index;
        let feet = idx.feet.map(|f| world.body_position(f));
        for k in 0..2 {
            let stance = feet[k][2] < self.stance_z + STANCE_MARGIN_M;
            if let Some(prev) = self.feet {
                if stance && self.in_stance[k] {
                    let d = (feet[k][0] - prev[k][0]).hypot(feet[k][1] - prev[k][1]);
                    self.slip.0 += d / self.dt;
                    self.slip.1 += 1;
                }
                if !stance {
                    self.swing_top[k] = self.swing_top[k].max(feet[k][2] - self.stance_z);
                } else if !self.in_stance[k] {
                    self.clearance.0 += self.swing_top[k];
                    self.clearance.1 += 1;
                }
            }
            if stance {
                self.swing_top[k] = 0.0;
            }
            self.in_stance[k] = stance;
        }
        self.feet = Some(feet);

        let torso = world.body_frame(idx.torso);
        self.tilt += torso.rot[8].clamp(-1.0, 1.0).acos().to_degrees();

        let pelvis = world.pelvis_frame();
        let heading = pelvis.yaw();
        for (k, &hand) in idx.hands.iter().enumerate() {
            let h = world.body_position(hand);
            let fwd = to_heading(heading, [h[0] - pelvis.pos[0], h[1] - pelvis.pos[1], 0.0])[0];
            self.hand_fwd[k] = (self.hand_fwd[k].0.min(fwd), self.hand_fwd[k].1.max(fwd));
        }

        if self.pelvis.len() == 4 {
            self.pelvis.remove(0);
        }
        self.pelvis.push(pelvis.pos);
        if let [a, b, c, d] = self.pelvis[..] {
            let j: f64 = (0..3).map(|i| (d[i] - 3.0 * c[i] + 3.0 * b[i] - a[i]).powi(2)).sum::<f64>().sqrt();
            self.jerk.0 += j / self.dt.powi(3);
            self.jerk.1 += 1;
        }

        if let Some(prev) = self.heading {
            self.turned += wrap_angle(heading - prev);
        }
        self.heading = Some(heading);
        self.ticks += 1;
    }

    /// Adds one tick's imitation pose and end-effector terms.
    pub fn observe_terms(&mut self, pose: f32, end_effector: f32) {
        self.terms.0 += f64::from(pose);
        self.terms.1 += f64::from(end_effector);
        self.terms.2 += 1;
    }

    /// The rollout's figures so far.
    pub fn quality(&self) -> MotionQuality {
        let mean = |(sum, n): (f64, usize)| if n > 0 { sum / n as f64 } else { 0.0 };
        let swing: Vec<f64> = self.hand_fwd.iter().filter(|(lo, hi)| hi >= lo).map(|(lo, hi)| hi - lo).collect();
        MotionQuality {
            foot_slip_m_s: mean(self.slip),
            clearance_m: mean(self.clearance),
            torso_tilt_deg: mean((self.tilt, self.ticks)),
            arm_swing_m: if swing.is_empty() { 0.0 } else { swing.iter().sum::<f64>() / swing.len() as f64 },
            jerk_m_s3: mean(self.jerk),
            turn_deg: self.turned.to_degrees(),
            pose_term: (self.terms.2 > 0).then(|| self.terms.0 / self.terms.2 as f64),
            end_effector_term: (self.terms.2 > 0).then(|| self.terms.1 / self.terms.2 as f64),
        }
    }
}

/// The reference clip's figures: every frame placed kinematically on the body in `model`'s
/// scene (pose and velocities, no physics), measured by the same meter. A cycle is measured
/// over one period.
pub fn reference_quality(model: &std::sync::Arc<WorldModel>, reference: &Reference) -> MotionQuality {
    let mut meter = MotionMeter::new(model);
    let mut world = model.new_world();
    let dof = reference.dof;
    for f in 0..reference.root_pos.len() {
        let joints = &reference.joints[f * dof..(f + 1) * dof];
        let vel = &reference.joint_vel[f * dof..(f + 1) * dof];
        if world
            .set_motion(reference.root_pos[f], reference.root_quat[f], joints, reference.root_qvel[f], Some(vel))
            .is_ok()
        {
            meter.observe(&world);
        }
    }
    meter.quality()
}
