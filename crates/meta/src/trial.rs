//! One sitting trial's outcome ([`Trial`]), as every evaluation reports it and every arena
//! ([`crate::controller::Arena`]) makes it from a finished episode.

use repertoire_scenes::FallCause;
use repertoire_scenes::world::PropPlacement;
use serde::{Deserialize, Serialize};

/// One trial's outcome.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Trial {
    /// Trial index (its seed stream).
    pub index: usize,
    /// Spawn zone.
    pub zone: String,
    /// Start position and heading.
    pub start: (f64, f64, f64),
    /// Start position in the chair's frame (x: in front of it, y: its left).
    pub local_start: (f64, f64),
    /// Which side of the chair it started on (`left`, `right`, seen from the chair).
    pub side: String,
    /// 3 s of unbroken seat contact reached.
    pub success: bool,
    /// Ended by a fall.
    pub fell: bool,
    /// Why, by the fall test ([`repertoire_scenes::FallCause::name`], or `diverged`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub fall_cause: Option<String>,
    /// Smallest pelvis-to-seat distance (m).
    pub min_distance: f64,
    /// Seconds simulated.
    pub seconds: f64,
    /// Skills in the order chosen.
    pub skills: Vec<String>,
    /// The skill playing when the character first touched the chair (`None`: it never did).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub touched: Option<String>,
    /// Decisions a searching controller (the planner, the lookahead, the oracle's check)
    /// simulated in copies of the episode: its cost. 0 for one acting from its observation.
    #[serde(default, skip_serializing_if = "is_zero")]
    pub simulated: u64,
}

fn is_zero(n: &u64) -> bool {
    *n == 0
}

impl Trial {
    /// A finished sitting trial from its start, the placement of the task's frame prop (the
    /// chair) and the episode's figures (`terms`: success, min distance, fell, seconds, ...).
    pub(crate) fn from_episode(
        index: usize,
        zone: &str,
        start: (f64, f64, f64),
        frame: PropPlacement,
        terms: &[f32],
        skills: Vec<String>,
    ) -> Trial {
        let (x, y, _) = start;
        // Side in the chair's frame: +y of the chair is its left.
        let (s, c) = frame.yaw.sin_cos();
        let local_x = c * (x - frame.pos[0]) + s * (y - frame.pos[1]);
        let local_y = -s * (x - frame.pos[0]) + c * (y - frame.pos[1]);
        Trial {
            index,
            zone: zone.to_string(),
            start,
            local_start: (local_x, local_y),
            side: if local_y >= 0.0 { "left".into() } else { "right".into() },
            success: terms[0] > 0.5,
            fell: terms[2] > 0.5,
            fall_cause: fall_cause(terms[2]),
            min_distance: f64::from(terms[1]),
            seconds: f64::from(terms[3]),
            skills,
            touched: None,
            simulated: 0,
        }
    }
}

/// The cause named by an episode's `fell` figure (see [`crate::env::fall_term`]).
pub fn fall_cause(fell: f32) -> Option<String> {
    (fell > 0.5).then(|| FallCause::from_code(fell.round() as u8).map_or("diverged", FallCause::name).to_string())
}
