//! Open-loop probe of a skill's starts from its predecessors' end poses (what `skill finetune
//! --from` trains on). Episodes start from the pools; the skill's reference joint angles (or,
//! with `--hold0`, its first frame) go straight to the PD actuators, with no policy, optionally
//! blended in from the start pose over `--blend=S` seconds and with the start's velocities
//! scaled by `--momentum=K`. It prints each start's speed and when the body falls: whether the
//! clip alone can take the body from where its predecessors leave it.
//!
//! `cargo run --release --example transition_probe -- specs/sit.ron turn_left,turn_right [--hold0] [--blend=0.5] [--momentum=0]`

use rand::SeedableRng;
use repertoire_learn::env::{Env, EnvRng};
use repertoire_skill::spec::Init;
use repertoire_skill::{SkillSetup, SpecFile};
use std::path::Path;

fn main() -> anyhow::Result<()> {
    let args: Vec<String> = std::env::args().collect();
    let spec_path = args.get(1).map_or("specs/sit.ron", String::as_str);
    let from: Vec<String> =
        args.get(2).map_or("turn_left,turn_right", String::as_str).split(',').map(String::from).collect();
    let hold0 = args.iter().any(|a| a == "--hold0");
    let option = |name: &str, default: f64| -> anyhow::Result<f64> {
        args.iter().find_map(|a| a.strip_prefix(name)).map_or(Ok(default), |v| Ok(v.parse()?))
    };
    let (blend, momentum) = (option("--blend=", 0.0)?, option("--momentum=", 1.0)?);

    let mut spec = SpecFile::load(Path::new(spec_path))?;
    spec.spec.init = Init::pools(from);
    let setup = SkillSetup::new(spec, Path::new("library"))?;
    let r = &setup.settings.reference;
    let frames = r.frames();
    let mut env = setup.env();
    let mut obs = vec![0.0; env.obs_dim()];
    let mut rng = EnvRng::seed_from_u64(1);
    let blend_steps = (blend * 60.0).round() as usize;
    let (trials, mut falls) = (20, 0);
    let mut target = vec![0.0; r.dof];
    let mut action = vec![0.0f32; r.dof];
    for t in 0..trials {
        env.reset(&mut rng, &mut obs);
        if momentum != 1.0 {
            let w = env.world_mut();
            let q = w.data().qpos().to_vec();
            let v: Vec<f64> = w.data().qvel().iter().map(|x| x * momentum).collect();
            w.set_state(&q, &v)?;
        }
        let w = env.world();
        let v = w.data().qvel();
        let speed = v[0].hypot(v[1]);
        let start: Vec<f64> = w.model().index.joints.iter().map(|j| w.data().qpos()[j.qpos]).collect();
        let mut fell = None;
        for step in 0..frames + r.hold_steps {
            let f = if hold0 { 0 } else { (env.task().phase() + 1).min(frames - 1) };
            target.copy_from_slice(r.joints_at(f));
            if step < blend_steps {
                let a = (step + 1) as f64 / blend_steps as f64;
                let a = a * a * (3.0 - 2.0 * a);
                target.iter_mut().zip(&start).for_each(|(t, s0)| *t = (1.0 - a) * s0 + a * *t);
            }
            for (k, a) in action.iter_mut().enumerate() {
                *a = env.action_for(k, target[k]);
            }
            let out = env.step(&action, &mut obs);
            if out.terminated {
                fell = Some(step as f64 / 60.0);
                break;
            }
            if out.truncated {
                break;
            }
        }
        match fell {
            Some(s) => println!("start {t:2}: {speed:.2} m/s, fell after {s:.2} s"),
            None => println!("start {t:2}: {speed:.2} m/s, stayed up"),
        }
        falls += usize::from(fell.is_some());
    }
    println!("{falls} of {trials} starts fell");
    Ok(())
}
