//! Batched episodes of a skill's imitation task under any [`Controller`] (a library skill with
//! action noise for the dataset, the latent model for one-shot imitation), reporting every
//! transition with the decoder's and encoder's inputs and every episode's normalised figures.

use std::sync::Arc;

use rand::SeedableRng;
use rayon::prelude::*;
use repertoire_humanoid::HumanoidEnv;
use repertoire_learn::env::{Env, EnvRng};
use repertoire_scenes::ObservationLayout;
use repertoire_skill::SkillSetup;
use repertoire_skill::imitation::{ImitationTask, TaskSettings};
use repertoire_skill::spec::Imitation;

use crate::reference::{reference_features, reference_size};

/// What chooses the actions of a batch of environments.
pub trait Controller {
    /// Environment slot `i` starts a new episode (forget its history).
    fn begin(&mut self, i: usize);
    /// Normalised actions `[B × A]` for the batch: `obs` is the skill policy's observation
    /// `[B × od]`, `proprio` the decoder's `[B × S]`, `reference` the encoder's `[B × F]`.
    fn act(&mut self, obs: &[f32], proprio: &[f32], reference: &[f32], actions: &mut [f32]);
}

/// When a rollout stops.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Budget {
    /// After this many transitions (the episodes running then are cut).
    Steps(u64),
    /// After this many whole episodes.
    Episodes(usize),
}

/// Settings of a rollout.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RolloutOptions {
    /// Reference frames ahead in the encoder's input.
    pub k: usize,
    /// Environments stepped together.
    pub batch: usize,
    /// Episode `e` starts from the state drawn by stream `e` of this seed, whatever controller
    /// runs it, so two controllers can be compared on the same starts.
    pub seed: u64,
    /// Standard deviation of the Gaussian noise added to the controller's actions (0: none);
    /// the noisy action is what the environment receives.
    pub noise_std: f32,
    /// When to stop.
    pub budget: Budget,
}

/// One control step as the dataset records it.
#[derive(Debug)]
pub struct Transition<'a> {
    /// The episode's number in this rollout.
    pub episode: u64,
    /// Control steps taken before this one in the episode.
    pub step: u32,
    /// The reference frame the character was at.
    pub frame: u32,
    /// The decoder's proprioceptive input at this step.
    pub proprio: &'a [f32],
    /// The encoder's reference features at this step.
    pub reference: &'a [f32],
    /// The controller's action (clipped to `[-1, 1]`).
    pub mean: &'a [f32],
    /// The action taken: `mean` plus noise, clipped.
    pub taken: &'a [f32],
    /// The imitation reward of the step (0 on a fall).
    pub reward: f32,
}

/// How one episode went.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct EpisodeEnd {
    /// The episode's number.
    pub episode: u64,
    /// The reference frame it started at.
    pub start_frame: u32,
    /// Control steps taken.
    pub length: u32,
    /// The longest it could have run from its start (to the clip's end or the time limit).
    pub max_length: u32,
    /// Sum of the imitation rewards.
    pub imitation_return: f64,
    /// Whether it ended in a fall.
    pub fell: bool,
}

impl EpisodeEnd {
    /// Length over the longest possible (MoCapAct's normalised episode length).
    pub fn normalized_length(&self) -> f64 {
        f64::from(self.length) / f64::from(self.max_length.max(1))
    }

    /// Return over the largest possible (the best reward per step over the longest possible
    /// length), MoCapAct's normalised episode reward.
    pub fn normalized_return(&self, best_per_step: f64) -> f64 {
        self.imitation_return / (best_per_step * f64::from(self.max_length.max(1))).max(1e-9)
    }
}

/// The largest imitation reward of one step.
pub fn best_imitation_reward(im: &Imitation) -> f64 {
    f64::from(im.pose.weight + im.velocity.weight + im.end_effector.weight + im.root.weight)
}

/// Runs episodes of `setup`'s skill with `settings` (its task, usually with the init
/// overridden) under `ctrl`; calls `on_step` for every transition and `on_end` for every episode
/// that finishes (not those a [`Budget::Steps`] cuts).
pub fn rollout(
    setup: &SkillSetup,
    settings: &Arc<TaskSettings>,
    proprio_layout: &Arc<ObservationLayout>,
    ctrl: &mut dyn Controller,
    opts: &RolloutOptions,
    on_step: &mut dyn FnMut(&Transition<'_>),
    on_end: &mut dyn FnMut(&EpisodeEnd),
) {
    let batch = match opts.budget {
        Budget::Episodes(n) => opts.batch.clamp(1, n.max(1)),
        Budget::Steps(_) => opts.batch.max(1),
    };
    let mut envs: Vec<HumanoidEnv<ImitationTask>> = (0..batch)
        .map(|_| {
            HumanoidEnv::with_layout(
                &setup.model,
                Arc::clone(&setup.layout),
                ImitationTask::new(Arc::clone(settings)),
                setup.max_steps,
            )
        })
        .collect();
    let (od, ad) = (envs[0].obs_dim(), envs[0].act_dim());
    let dof = settings.reference.dof;
    let (sd, fd) = (proprio_layout.size, reference_size(opts.k, dof));
    let mut obs = vec![0.0f32; batch * od];
    let mut proprio = vec![0.0f32; batch * sd];
    let mut reference = vec![0.0f32; batch * fd];
    let mut mean = vec![0.0f32; batch * ad];
    let mut taken = vec![0.0f32; batch * ad];
    let mut episode = vec![0u64; batch];
    let mut start_frame = vec![0u32; batch];
    let mut max_len = vec![0u32; batch];
    let mut returns = vec![0.0f64; batch];
    let mut active = vec![false; batch];
    let mut frames_before = vec![0u32; batch];
    let mut steps_before = vec![0u32; batch];
    let mut noise = EnvRng::seed_from_u64(opts.seed ^ 0x006e_6f69_7365);
    let im = settings.imitation;
    let frames = settings.reference.frames() as u32;
    let (looping, hold) = (settings.reference.looping, settings.reference.hold_steps as u32);
    let mut started = 0u64;
    let mut transitions = 0u64;
    let may_start = |started: u64| match opts.budget {
        Budget::Episodes(n) => started < n as u64,
        Budget::Steps(_) => true,
    };

    let begin = |i: usize,
                 env: &mut HumanoidEnv<ImitationTask>,
                 o: &mut [f32],
                 started: &mut u64,
                 ctrl: &mut dyn Controller,
                 start_frame: &mut u32,
                 max_len: &mut u32,
                 episode: &mut u64| {
        let mut rng = EnvRng::seed_from_u64(opts.seed);
        rng.set_stream(*started + 1);
        env.reset(&mut rng, o);
        *episode = *started;
        *started += 1;
        *start_frame = env.task().phase() as u32;
        let left = if looping { setup.max_steps } else { (frames - 1 - *start_frame + hold).min(setup.max_steps) };
        *max_len = left.max(1);
        ctrl.begin(i);
    };
    for i in 0..batch {
        if may_start(started) {
            begin(
                i,
                &mut envs[i],
                &mut obs[i * od..(i + 1) * od],
                &mut started,
                ctrl,
                &mut start_frame[i],
                &mut max_len[i],
                &mut episode[i],
            );
            active[i] = true;
        }
    }
    while active.iter().any(|&a| a) {
        if let Budget::Steps(n) = opts.budget
            && transitions >= n
        {
            break;
        }
        for (i, env) in envs.iter().enumerate() {
            env.world().observe(proprio_layout, &mut proprio[i * sd..(i + 1) * sd]);
            reference_features(env.task(), env.world(), opts.k, &mut reference[i * fd..(i + 1) * fd]);
        }
        ctrl.act(&obs, &proprio, &reference, &mut mean);
        for (m, t) in mean.iter_mut().zip(taken.iter_mut()) {
            *m = m.clamp(-1.0, 1.0);
            let eps = if opts.noise_std > 0.0 { repertoire_learn::policy::standard_normal(&mut noise) } else { 0.0 };
            *t = (*m + opts.noise_std * eps).clamp(-1.0, 1.0);
        }
        for (i, env) in envs.iter().enumerate() {
            frames_before[i] = env.task().phase() as u32;
            steps_before[i] = env.steps();
        }
        let outcomes: Vec<_> = envs
            .par_iter_mut()
            .zip(obs.par_chunks_mut(od))
            .zip(taken.par_chunks(ad))
            .zip(active.par_iter())
            .map(|(((env, o), a), &on)| on.then(|| env.step(a, o)))
            .collect();
        for (i, out) in outcomes.into_iter().enumerate() {
            let Some(out) = out else { continue };
            let reward = if out.terminated {
                0.0
            } else {
                im.pose.weight * out.terms[0]
                    + im.velocity.weight * out.terms[1]
                    + im.end_effector.weight * out.terms[2]
                    + im.root.weight * out.terms[3]
            };
            if let Budget::Steps(n) = opts.budget
                && transitions >= n
            {
                active[i] = false;
                continue;
            }
            transitions += 1;
            on_step(&Transition {
                episode: episode[i],
                step: steps_before[i],
                frame: frames_before[i],
                proprio: &proprio[i * sd..(i + 1) * sd],
                reference: &reference[i * fd..(i + 1) * fd],
                mean: &mean[i * ad..(i + 1) * ad],
                taken: &taken[i * ad..(i + 1) * ad],
                reward,
            });
            returns[i] += f64::from(reward);
            if !(out.terminated || out.truncated) {
                continue;
            }
            on_end(&EpisodeEnd {
                episode: episode[i],
                start_frame: start_frame[i],
                length: envs[i].steps(),
                max_length: max_len[i],
                imitation_return: returns[i],
                fell: out.terminated,
            });
            returns[i] = 0.0;
            if may_start(started) {
                begin(
                    i,
                    &mut envs[i],
                    &mut obs[i * od..(i + 1) * od],
                    &mut started,
                    ctrl,
                    &mut start_frame[i],
                    &mut max_len[i],
                    &mut episode[i],
                );
            } else {
                active[i] = false;
            }
        }
    }
}
