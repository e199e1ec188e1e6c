//! Probe of an object skill's reference-state starts: the clip's joint angles go straight to the
//! PD actuators (no policy; or, with `--policy=LIBRARY`, the library skill acts) and, every few
//! ticks, it prints the object's pose relative to the pelvis and which hands touch it, until the
//! object touches the floor or the body falls, and then which of the two ended the episode:
//! whether the clip's grip holds the object at all, and how a trained policy loses it.
//!
//! `--grip=X` overrides the spec's grip level (0 lets go, 1 grips; see `World::set_grip`).
//!
//! `cargo run --release --example object_probe -- specs/carry.ron [--starts=5] [--policy=library] [--grip=0]`

use rand::SeedableRng;
use repertoire_learn::env::{Env, EnvRng};
use repertoire_skill::{SkillSetup, SpecFile};
use std::path::Path;

fn main() -> anyhow::Result<()> {
    let args: Vec<String> = std::env::args().collect();
    let spec_path = args.get(1).map_or("specs/carry.ron", String::as_str);
    let option = |name: &str, default: usize| -> anyhow::Result<usize> {
        args.iter().find_map(|a| a.strip_prefix(name)).map_or(Ok(default), |v| Ok(v.parse()?))
    };
    let starts = option("--starts=", 5)?;
    let policy_lib = args.iter().find_map(|a| a.strip_prefix("--policy="));
    let spec = SpecFile::load(Path::new(spec_path))?;
    let Some((_, prop)) = spec.spec.goal.object() else { anyhow::bail!("{spec_path}: the goal has no object") };
    let prop = prop.to_string();
    let mut policy = match policy_lib {
        Some(lib) => Some(repertoire_skill::library::load(Path::new(lib), &spec.spec.name)?),
        None => None,
    };
    let setup = SkillSetup::new(spec, Path::new(policy_lib.unwrap_or("library")))?;
    let r = &setup.settings.reference;
    let frames = r.frames();
    let mut env = setup.env();
    let grip: Option<f64> = args.iter().find_map(|a| a.strip_prefix("--grip=")).map(str::parse).transpose()?;
    let p = env.world().model().prop_id(&prop).ok_or_else(|| anyhow::anyhow!("no prop `{prop}`"))?;
    let mut obs = vec![0.0; env.obs_dim()];
    let mut rng = EnvRng::seed_from_u64(1);
    let mut action = vec![0.0f32; r.dof];
    for t in 0..starts {
        env.reset(&mut rng, &mut obs);
        if let Some(g) = grip {
            env.world_mut().set_grip(g); // after the reset, which sets the spec's level
        }
        println!("start {t}: frame {}, grip {}", env.task().phase(), env.world().grip());
        for step in 0..setup.max_steps as usize {
            if let Some(skill) = policy.as_mut() {
                skill.policy.act(&obs, &mut action);
                action.iter_mut().for_each(|a| *a = a.clamp(-1.0, 1.0));
            } else {
                let f = (env.task().phase() + 1) % frames;
                for (k, a) in action.iter_mut().enumerate() {
                    *a = env.action_for(k, r.joints_at(f)[k]);
                }
            }
            let out = env.step(&action, &mut obs);
            let ended = out.terminated || out.truncated;
            if step % 6 != 0 && !ended {
                continue;
            }
            let w = env.world();
            let (rel, c) = (w.prop_relative(p), w.contacts());
            println!(
                "  {:.2} s: object ahead {:+.3} left {:+.3} up {:+.3} m, hands {:?}, on floor {}",
                (step + 1) as f64 / 60.0,
                rel[0],
                rel[1],
                rel[2],
                c.hands_on_prop(p),
                c.prop_on_floor(p)
            );
            if ended {
                let why = match (out.terminated, w.has_fallen(), c.prop_on_floor(p)) {
                    (false, ..) => "time limit",
                    (true, true, true) => "fell and dropped the object",
                    (true, true, false) => "fell",
                    (true, false, true) => "dropped the object",
                    (true, false, false) => "terminated",
                };
                println!("  ended after {:.2} s: {why}", (step + 1) as f64 / 60.0);
                break;
            }
        }
    }
    Ok(())
}
