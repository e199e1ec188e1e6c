//! Open-loop probe of a skill spec: the character is placed at the clip's first frame (the seat,
//! if any, where an episode would put it) and the reference joint angles are fed straight to
//! the PD actuators, with no policy. It shows what the clip asks of the body: what the start
//! pose touches (a shin inside the chair launches the body), how far the feet dip into the
//! floor over the clip, and how pelvis height and distance to the seat evolve until a fall.
//!
//! `cargo run --release --example sit_probe -- specs/sit.ron`

use mujoco_rs::prelude::MjtObjBase;
use repertoire_skill::imitation::ImitationTask;
use repertoire_skill::{SkillSetup, SpecFile};
use std::path::Path;
use std::sync::Arc;

fn main() -> anyhow::Result<()> {
    let spec = std::env::args().nth(1).unwrap_or_else(|| "specs/sit.ron".into());
    let setup = SkillSetup::new(SpecFile::load(Path::new(&spec))?, Path::new("library"))?;
    let model = Arc::clone(&setup.model);
    let chair = model.prop_id("chair");
    let r = &setup.settings.reference;
    let mut task = ImitationTask::new(Arc::clone(&setup.settings));
    println!("{spec}: {} frames at {:.0} Hz", r.frames(), 1.0 / r.dt);

    let mut worst = (0, 0.0f64);
    for f in 0..r.frames() {
        let mut probe = model.new_world();
        task.place_at_frame(&mut probe, f, 0.0, 0.0, 0.0);
        let d = probe.penetration_with_floor();
        if d > worst.1 {
            worst = (f, d);
        }
    }
    println!("deepest floor penetration over the reference frames: {:.4} m (frame {})", worst.1, worst.0);

    let mut world = model.new_world();
    task.place_at_frame(&mut world, 0, 0.0, 0.0, 0.0);
    let m = model.mj_model();
    let body_name = |g: i32| {
        let b = m.geom_bodyid()[g as usize] as usize;
        m.id_to_name(MjtObjBase::mjOBJ_BODY, b).unwrap_or("world").to_string()
    };
    for c in world.data().contact() {
        println!("frame 0 contact: {} – {}, depth {:.4} m", body_name(c.geom[0]), body_name(c.geom[1]), -c.dist);
    }
    if let Some(ch) = chair {
        println!("frame 0: the character sinks {:.4} m into the chair", world.penetration_with_prop(ch, None));
    }
    for f in 0..r.frames() {
        world.step(r.joints_at(f))?;
        let c = world.contacts();
        let p = world.pelvis_frame().pos;
        if f % 15 == 0 || c.fallen {
            let (seat, on) = chair.map_or((f64::NAN, false), |ch| {
                let pl = world.placements()[ch];
                (((p[0] - pl.pos[0]).powi(2) + (p[1] - pl.pos[1]).powi(2)).sqrt(), c.pelvis_on_prop(ch))
            });
            println!(
                "f {f:3}  pelvis z {:.3} (reference {:.3})  to seat {seat:.3} m  on seat {on}  fallen {}",
                p[2], r.height[f], c.fallen
            );
            if c.fallen {
                break;
            }
        }
    }
    Ok(())
}
