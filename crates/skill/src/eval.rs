//! `skill eval`: many seeded trials of a library skill with its mean action, from the clip's
//! start and from its predecessors' end poses (the sitting paper's Table 2), with MoCapAct's
//! normalised episode length and return; successful end states become the skill's end-pose pool.

use std::sync::Arc;

use rayon::prelude::*;
use repertoire_humanoid::HumanoidEnv;
use repertoire_learn::env::{Env, EnvRng};
use repertoire_scenes::SEATED_FACING_DEG;
use serde::{Deserialize, Serialize};

use rand::{Rng, SeedableRng};

use crate::error::Result;
use crate::imitation::{ImitationTask, TaskSettings};
use crate::library::LibrarySkill;
use crate::motion::{MotionMeter, MotionQuality};
use crate::pool::{Pool, PoolState};
use crate::skill::SkillSetup;
use crate::spec::{Goal, Init};

/// Where evaluation episodes start.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub enum StartFrom {
    /// The clip's first frame.
    ClipStart,
    /// A random end pose of a predecessor skill (needs their pools).
    Predecessors,
}

/// What an evaluation measured.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct EvalReport {
    /// The skill.
    pub skill: String,
    /// Where trials started.
    pub start: StartFrom,
    /// Trials run.
    pub trials: usize,
    /// Trials that reached the end of the clip (or the time limit) without falling and, for
    /// sit, seated (the pelvis on the seat, its heading within `SEATED_FACING_DEG` of the
    /// chair's front, not fallen onto it facing the backrest); for object goals, with the
    /// object's state reached (box raised, held, put down and released, ball caught).
    pub successes: usize,
    /// Trials that ended in a fall (or, for object goals, with the object on the floor).
    pub falls: usize,
    /// `successes / trials`.
    pub success_rate: f64,
    /// Mean of episode length / the longest possible length (MoCapAct).
    pub normalized_length: f64,
    /// Mean of return / (the largest reward per step × the longest possible length).
    pub normalized_return: f64,
    /// Mean undiscounted return.
    pub mean_return: f64,
    /// Walk stage 2 (`Goal::Target` with an arrival radius): targets reached per trial.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub targets_per_trial: Option<f64>,
    /// A spec with an `obstacle` whose touch ends the episode: how many of the `falls` were
    /// such touches (the character may still have been on its feet).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub touches: Option<usize>,
    /// How the trials moved ([`crate::motion`]), means over them.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub motion: Option<MotionQuality>,
}

/// Runs `trials` episodes of `skill` in `setup`'s environment, `batch` at a time in parallel,
/// starting as `start` says. Returns the report and the successful end states.
pub fn evaluate(
    setup: &SkillSetup,
    skill: &mut LibrarySkill,
    start: StartFrom,
    trials: usize,
    batch: usize,
    seed: u64,
) -> Result<(EvalReport, Vec<PoolState>)> {
    skill.check_fits(&setup.model)?;
    let mut settings: TaskSettings = (*setup.settings).clone();
    settings.init = match start {
        StartFrom::ClipStart => Init::Start,
        StartFrom::Predecessors => match &setup.spec.spec.init {
            Init::Pools { from, .. } if settings.pools.iter().any(|p| !p.states.is_empty()) => {
                Init::pools(from.clone())
            }
            Init::Pools { from, .. } => {
                return Err(crate::SkillError::Invalid(format!(
                    "the end-pose pools of {} hold no states (their skills never succeeded in `skill eval`)",
                    from.join(", ")
                )));
            }
            _ => {
                return Err(crate::SkillError::Invalid(format!(
                    "skill `{}` has no predecessor pools: its spec's init is not Pools",
                    setup.spec.spec.name
                )));
            }
        },
    };
    let settings = Arc::new(settings);
    let batch = batch.clamp(1, trials.max(1));
    let mut envs: Vec<HumanoidEnv<ImitationTask>> = (0..batch)
        .map(|_| {
            HumanoidEnv::with_layout(
                &setup.model,
                Arc::clone(&setup.layout),
                ImitationTask::new(Arc::clone(&settings)),
                setup.max_steps,
            )
        })
        .collect();
    let (od, ad) = (envs[0].obs_dim(), envs[0].act_dim());
    if skill.policy.obs_dim() != od {
        return Err(crate::SkillError::Mismatch {
            path: skill.dir.join("manifest.ron"),
            message: format!(
                "skill `{}` observes {} values, the spec {} gives {od} (its goal's inputs differ); \
                 train the skill with this spec (`skill train SPEC --warm-start` grows its input)",
                skill.manifest.name,
                skill.policy.obs_dim(),
                setup.spec.path.display()
            ),
        });
    }
    let mut rngs: Vec<EnvRng> = (0..batch)
        .map(|i| {
            let mut r = EnvRng::seed_from_u64(seed);
            r.set_stream(i as u64 + 1);
            r
        })
        .collect();
    let mut obs = vec![0.0f32; batch * od];
    let mut actions = vec![0.0f32; batch * ad];
    let mut returns = vec![0.0f64; batch];
    let mut max_len = vec![0u32; batch];
    let mut active = vec![true; batch];
    let mut started = 0usize;

    let max_reward_per_step = {
        let im = &settings.imitation;
        let goal = settings.goal.weight();
        f64::from(im.pose.weight + im.velocity.weight + im.end_effector.weight + im.root.weight + goal)
    };
    let frames = settings.reference.frames() as u32;
    let (looping, hold) = (settings.reference.looping, settings.reference.hold_steps as u32);
    let mut report = EvalReport {
        skill: setup.spec.spec.name.clone(),
        start,
        trials: 0,
        successes: 0,
        falls: 0,
        success_rate: 0.0,
        normalized_length: 0.0,
        normalized_return: 0.0,
        mean_return: 0.0,
        targets_per_trial: settings.goal.steering().filter(|st| st.reach_m > 0.0).map(|_| 0.0),
        touches: settings.obstacle.as_ref().filter(|(_, o)| o.touch_ends).map(|_| 0),
        motion: None,
    };
    let mut meters: Vec<MotionMeter> = (0..batch).map(|_| MotionMeter::new(&setup.model)).collect();
    let mut motion = Vec::with_capacity(trials);
    let mut pool = Vec::new();
    // A cycle (walk) has no end pose: every trial ends at the same phase of it. Its pool takes
    // the state at a random moment of each successful trial instead (drawn from a stream of its
    // own, so the trials themselves are unchanged), covering the whole cycle.
    let mut moments = EnvRng::seed_from_u64(seed ^ 0x6d6f_6d65_6e74);
    let mut capture_at = vec![0u32; batch];
    let mut captured: Vec<Option<PoolState>> = vec![None; batch];

    let begin = |env: &mut HumanoidEnv<ImitationTask>, rng: &mut EnvRng, o: &mut [f32]| -> u32 {
        env.reset(rng, o);
        // The longest this episode can run: to the clip's end, or the time limit.
        let left = if looping {
            setup.max_steps
        } else {
            (frames - 1 - env.task().phase() as u32 + hold).min(setup.max_steps)
        };
        left.max(1)
    };
    let mut draw_moment = |len: u32| if looping { moments.random_range(1..=len.max(1)) } else { 0 };
    for i in 0..batch {
        if started < trials {
            max_len[i] = begin(&mut envs[i], &mut rngs[i], &mut obs[i * od..(i + 1) * od]);
            meters[i].observe(envs[i].world());
            capture_at[i] = draw_moment(max_len[i]);
            started += 1;
        } else {
            active[i] = false;
        }
    }
    while active.iter().any(|&a| a) {
        skill.policy.act(&obs, &mut actions);
        let outcomes: Vec<_> = envs
            .par_iter_mut()
            .zip(obs.par_chunks_mut(od))
            .zip(actions.par_chunks_mut(ad))
            .zip(active.par_iter())
            .map(|(((env, o), a), &on)| {
                if !on {
                    return None;
                }
                a.iter_mut().for_each(|x| *x = x.clamp(-1.0, 1.0));
                Some(env.step(a, o))
            })
            .collect();
        for (i, out) in outcomes.into_iter().enumerate() {
            let Some(out) = out else { continue };
            returns[i] += f64::from(out.reward);
            let env = &mut envs[i];
            meters[i].observe(env.world());
            meters[i].observe_terms(out.terms[0], out.terms[2]);
            if looping && !out.terminated && env.steps() == capture_at[i] {
                let mut state = PoolState::capture(env.world());
                state.phase = env.task().phase();
                captured[i] = Some(state);
            }
            if !(out.terminated || out.truncated) {
                continue;
            }
            let len = env.steps();
            let seated = settings.seat.is_some_and(|(p, _)| env.world().seated_on(p, SEATED_FACING_DEG.to_radians()));
            let object_done = out.terms[6] > 0.5;
            let success = !out.terminated
                && match settings.goal {
                    Goal::Seat { .. } => seated,
                    _ if settings.goal.object().is_some() => object_done,
                    _ => true,
                };
            report.trials += 1;
            report.falls += usize::from(out.terminated);
            report.successes += usize::from(success);
            report.normalized_length += f64::from(len) / f64::from(max_len[i]);
            report.normalized_return += returns[i] / (max_reward_per_step * f64::from(max_len[i])).max(1e-9);
            report.mean_return += returns[i];
            if let Some(t) = report.targets_per_trial.as_mut() {
                *t += f64::from(env.task().reached);
            }
            if let Some(t) = report.touches.as_mut() {
                *t += usize::from(out.terminated && env.task().touched);
            }
            if success {
                let state = captured[i].take().unwrap_or_else(|| {
                    let mut state = PoolState::capture(env.world());
                    state.phase = env.task().phase();
                    state
                });
                pool.push(state);
            }
            captured[i] = None;
            returns[i] = 0.0;
            motion.push(meters[i].quality());
            meters[i].reset();
            if started < trials {
                max_len[i] = begin(env, &mut rngs[i], &mut obs[i * od..(i + 1) * od]);
                meters[i].observe(env.world());
                capture_at[i] = draw_moment(max_len[i]);
                started += 1;
            } else {
                active[i] = false;
            }
        }
    }
    let n = report.trials.max(1) as f64;
    report.success_rate = report.successes as f64 / n;
    report.normalized_length /= n;
    report.normalized_return /= n;
    report.mean_return /= n;
    if let Some(t) = report.targets_per_trial.as_mut() {
        *t /= n;
    }
    report.motion = MotionQuality::mean(&motion);
    Ok((report, pool))
}

/// The pool of `skill` from its successful end states.
pub fn pool_of(setup: &SkillSetup, states: Vec<PoolState>) -> Pool {
    Pool { skill: setup.spec.spec.name.clone(), body_hash: setup.model.body.content_hash(), states }
}
