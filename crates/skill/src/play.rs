//! `skill play`: one episode of a library skill with its mean action, recorded frame by frame
//! with the reference clip as a ghost (for `repertoire replay` and `repertoire export`).

use std::sync::Arc;

use rand::SeedableRng;
use repertoire_humanoid::HumanoidEnv;
use repertoire_learn::env::{Env, EnvRng};
use repertoire_scenes::{Annotation, RecordOptions, Recorder, Recording};

use crate::error::Result;
use crate::eval::StartFrom;
use crate::imitation::{ImitationTask, TERM_NAMES, TaskSettings};
use crate::library::LibrarySkill;
use crate::skill::SkillSetup;
use crate::spec::Init;

/// How a played episode ended.
#[derive(Debug, Clone, PartialEq)]
pub struct Played {
    /// The recording (frame 0 is the start state, then one frame per control step).
    pub recording: Recording,
    /// Control steps taken.
    pub steps: u32,
    /// Whether it ended in a fall.
    pub fell: bool,
    /// Whether the pelvis was on the seat at the end (sit).
    pub on_seat: bool,
    /// Whether an object goal's state held at the end (box raised, held, put down, ball caught).
    pub object_done: bool,
    /// Undiscounted return.
    pub episode_return: f64,
}

/// Plays one episode of `skill` (seeded by `seed`, starting as `start` says) and records it.
pub fn play(setup: &SkillSetup, skill: &mut LibrarySkill, start: StartFrom, seed: u64) -> Result<Played> {
    skill.check_fits(&setup.model)?;
    let mut settings: TaskSettings = (*setup.settings).clone();
    settings.init = match (start, &settings.init) {
        (StartFrom::ClipStart, _) => Init::Start,
        (StartFrom::Predecessors, Init::Pools { from, .. }) => Init::pools(from.clone()),
        (StartFrom::Predecessors, _) => {
            return Err(crate::SkillError::Invalid(format!(
                "skill `{}` has no predecessor pools: its spec's init is not Pools",
                setup.spec.spec.name
            )));
        }
    };
    let settings = Arc::new(settings);
    let name = setup.spec.spec.name.clone();
    let mut env = HumanoidEnv::with_layout(
        &setup.model,
        Arc::clone(&setup.layout),
        ImitationTask::new(Arc::clone(&settings)),
        setup.max_steps,
    );
    let mut terms: Vec<String> = TERM_NAMES.iter().map(|s| s.to_string()).collect();
    terms.push("reward".into());
    let mut recorder = Recorder::new(
        &setup.model,
        RecordOptions {
            title: format!(
                "{name}: skill play, seed {seed}, from {}",
                match start {
                    StartFrom::ClipStart => "the clip start",
                    StartFrom::Predecessors => "a predecessor's end pose",
                }
            ),
            skills: vec![name],
            terms,
            phase: "reference frame".into(),
            ghost: Some(settings.reference.name.clone()),
            capacity: setup.max_steps as usize + 1,
        },
    );
    let mut rng = EnvRng::seed_from_u64(seed);
    let (od, ad) = (env.obs_dim(), env.act_dim());
    let mut obs = vec![0.0f32; od];
    let mut act = vec![0.0f32; ad];
    let mut ghost = vec![0.0f64; env.world().data().qpos().len()];
    let mut values = [0.0f32; TERM_NAMES.len() + 1];
    env.reset(&mut rng, &mut obs);
    let record = |env: &HumanoidEnv<ImitationTask>, rec: &mut Recorder, ghost: &mut [f64], values: &[f32]| {
        env.task().reference_qpos(env.world(), ghost);
        let phase = env.task().phase() as f64;
        rec.record(env.world(), &Annotation { skill: Some(0), phase, terms: values, ghost_qpos: Some(ghost) });
    };
    record(&env, &mut recorder, &mut ghost, &values);
    let mut episode_return = 0.0;
    loop {
        skill.policy.act(&obs, &mut act);
        act.iter_mut().for_each(|a| *a = a.clamp(-1.0, 1.0));
        let out = env.step(&act, &mut obs);
        episode_return += f64::from(out.reward);
        values[..TERM_NAMES.len()].copy_from_slice(&out.terms[..TERM_NAMES.len()]);
        values[TERM_NAMES.len()] = out.reward;
        record(&env, &mut recorder, &mut ghost, &values);
        if out.terminated || out.truncated {
            return Ok(Played {
                recording: recorder.finish(),
                steps: env.steps(),
                fell: out.terminated,
                on_seat: out.terms[5] > 0.5,
                object_done: out.terms[6] > 0.5,
                episode_return,
            });
        }
    }
}
