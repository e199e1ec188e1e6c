//! Delivered states: where a meta-controller actually hands the character to a skill.
//!
//! Fine-tuning from predecessors' end poses (the sitting paper's transition stage) starts a sit
//! from the successful ends of whole turns, with the chair where the sit's clip expects it. A
//! 2 Hz controller does not deliver that: it switches mid-stride and mid-turn, with the chair
//! off to one side or a step too far. [`deliver`] plays a controller's episodes and, at every
//! decision the skill is not already running, records the character's state with the seat's
//! pose in the character's heading frame ([`PoolState::seat`]), keeping those whose seat lies
//! within a window around where the skill expects it. The result is an ordinary end-pose pool:
//! `repertoire skill finetune sit.ron --from FILE.ron` starts sit episodes from it with the chair
//! where the controller left it. The states at which the controller did switch to the skill are
//! kept apart too ([`Delivery::handover_pool`]), window or not: where the skill is really started.
//! A skill without a seat goal (the stand before the sit) has no window: every decision before
//! it is kept, each with the seat's pose, which its spec's `delivered_seat` puts the chair at.

use std::sync::Arc;

use rayon::prelude::*;
use repertoire_learn::env::Env;
use repertoire_scenes::math::wrap_angle;
use repertoire_skill::pool::{Pool, PoolState};
use serde::{Deserialize, Serialize};

use crate::controller::Controller;
use crate::env::{MetaEnv, MetaSetup};
use crate::error::{MetaError, Result};
use crate::task::TaskSpec;

/// Which decision states count as deliveries to the skill.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct DeliveryWindow {
    /// Where the skill expects the seat at its clip's first frame, in the character's heading
    /// frame: metres ahead, metres to the left, yaw relative to the heading
    /// (`SkillSetup::seat_at_start`).
    pub expected: [f64; 3],
    /// Farthest the seat may stand from `expected` (m).
    pub max_offset_m: f64,
    /// Largest turn of the seat away from `expected` (degrees).
    pub max_turn_deg: f64,
}

impl DeliveryWindow {
    /// Whether a seat at `seat` (heading frame, as [`PoolState::seat`]) lies inside.
    pub fn contains(&self, seat: [f64; 3]) -> bool {
        let [ex, ey, eyaw] = self.expected;
        let offset = ((seat[0] - ex).powi(2) + (seat[1] - ey).powi(2)).sqrt();
        offset <= self.max_offset_m && wrap_angle(seat[2] - eyaw).abs().to_degrees() <= self.max_turn_deg
    }
}

/// What [`deliver`] recorded.
#[derive(Debug, Clone)]
pub struct Delivery {
    /// The kept states (at most the requested number, an even spread over all in the window).
    pub pool: Pool,
    /// The states at which the controller did switch to the skill, in or out of the window
    /// (at most the requested number, an even spread): where the skill is actually started,
    /// the distribution a fine-tune for this controller wants.
    pub handover_pool: Pool,
    /// Decisions seen with the skill not running.
    pub decisions: usize,
    /// Of those, decisions whose seat lay in the window (all of them without a window).
    pub in_window: usize,
    /// Decisions at which the controller did switch to the skill.
    pub handovers: usize,
    /// Of those, handovers with the seat in the window (where the skill expects it).
    pub handovers_in_window: usize,
    /// Episodes that succeeded.
    pub successes: usize,
    /// Of those, episodes whose last handover to the skill had the seat in the window.
    pub successes_in_window: usize,
    /// Episodes played.
    pub episodes: usize,
}

/// Plays `trials` seeded episodes per zone of `zones` with `controller` and records the states
/// at which it could hand the character to `skill` (see the module docs), keeping at most
/// `max_states`. Sitting scenarios only. `window: None` (a skill without a seat goal) keeps
/// every decision state.
#[allow(clippy::too_many_arguments)]
pub fn deliver(
    setup: &Arc<MetaSetup>,
    controller: &dyn Controller,
    skill: &str,
    zones: &[String],
    trials: usize,
    seed: u64,
    window: Option<DeliveryWindow>,
    max_states: usize,
) -> Result<Delivery> {
    let TaskSpec::Sit { seat, .. } = setup.task else {
        return Err(MetaError::Invalid(format!(
            "{}: delivered states need a sitting scenario (this is a {} task)",
            setup.model.scenario.path.display(),
            setup.task.name()
        )));
    };
    let Some(target) = setup.skills.iter().position(|s| s.name == skill) else {
        let names: Vec<&str> = setup.skills.iter().map(|s| s.name.as_str()).collect();
        return Err(MetaError::Invalid(format!(
            "{}: no skill `{skill}` in the graph (it has: {})",
            setup.model.scenario.path.display(),
            names.join(", ")
        )));
    };
    setup.check_zones(zones)?;
    let mut counts = Counts::default();
    let mut kept = Vec::new();
    let mut handed = Vec::new();
    for (zi, zone) in zones.iter().enumerate() {
        *setup.zones.write().expect("never poisoned") = vec![zone.clone()];
        let per_trial: Vec<(Counts, Vec<PoolState>, Vec<PoolState>)> = (0..trials)
            .into_par_iter()
            .map(|i| {
                let mut env = MetaEnv::new(Arc::clone(setup));
                let mut ctl = controller.start(setup);
                let mut rng = crate::env::trial_rng(seed, zi, trials, i);
                let mut obs = vec![0.0; env.obs_dim()];
                let mut act = vec![0.0; env.act_dim()];
                let mut mask = vec![true; setup.skills.len()];
                let mut c = Counts::default();
                let mut states = Vec::new();
                let mut handed = Vec::new();
                let mut last_inside = false;
                env.reset(&mut rng, &mut obs);
                loop {
                    let before = env.current() != Some(target);
                    let mut here = None;
                    if before {
                        c.decisions += 1;
                        let state = PoolState::capture_with_seat(env.world(), &env.world().placements()[seat]);
                        let inside = window.is_none_or(|w| state.seat.is_some_and(|s| w.contains(s)));
                        here = Some((state, inside));
                    }
                    ctl.act(&env, &obs, &mut mask, &mut act);
                    let out = env.step(&act, &mut obs);
                    let handover = before && env.current() == Some(target);
                    if let Some((state, inside)) = here {
                        if handover {
                            c.handovers += 1;
                            c.handovers_in_window += usize::from(inside);
                            last_inside = inside;
                            handed.push(state.clone());
                        }
                        if inside {
                            states.push(state);
                        }
                    }
                    if out.terminated || out.truncated {
                        if out.terms[0] > 0.5 {
                            c.successes += 1;
                            c.successes_in_window += usize::from(last_inside);
                        }
                        return (c, states, handed);
                    }
                }
            })
            .collect();
        for (c, states, h) in per_trial {
            counts.decisions += c.decisions;
            counts.handovers += c.handovers;
            counts.handovers_in_window += c.handovers_in_window;
            counts.successes += c.successes;
            counts.successes_in_window += c.successes_in_window;
            kept.extend(states);
            handed.extend(h);
        }
    }
    let in_window = kept.len();
    let spread = |all: Vec<PoolState>| {
        let step = all.len().div_ceil(max_states.max(1)).max(1);
        all.into_iter().step_by(step).collect::<Vec<_>>()
    };
    let body_hash = setup.model.body.content_hash();
    let pool = Pool { skill: format!("delivered:{skill}"), body_hash: body_hash.clone(), states: spread(kept) };
    let handover_pool = Pool { skill: format!("handed-over:{skill}"), body_hash, states: spread(handed) };
    Ok(Delivery {
        pool,
        handover_pool,
        decisions: counts.decisions,
        in_window,
        handovers: counts.handovers,
        handovers_in_window: counts.handovers_in_window,
        successes: counts.successes,
        successes_in_window: counts.successes_in_window,
        episodes: trials * zones.len(),
    })
}

/// One episode's tallies.
#[derive(Default)]
struct Counts {
    decisions: usize,
    handovers: usize,
    handovers_in_window: usize,
    successes: usize,
    successes_in_window: usize,
}
