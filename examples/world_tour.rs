//! A tour of the world API on the default scenario: spawn in each zone, read observations,
//! step with PD targets, query contacts.
//!
//! `cargo run --release --example world_tour`

use rand::SeedableRng;
use rand::rngs::StdRng;
use repertoire::scenes::{Feature, ObservationLayout, ScenarioFile, WorldModel};
use std::sync::Arc;

fn main() -> anyhow::Result<()> {
    let model = Arc::new(WorldModel::build(ScenarioFile::builtin_default())?);
    let chair = model.prop_id("chair").expect("the default scenario has a chair");
    let mut features = Feature::proprioception();
    features.push(Feature::PropPose("chair".into()));
    let layout = ObservationLayout::new(&model, &features)?;
    println!("observation: {} values", layout.size);
    for e in &layout.entries {
        println!("  {:<18} [{}..{})", e.name, e.offset, e.offset + e.len);
    }

    let mut rng = StdRng::seed_from_u64(1);
    let mut world = model.new_world();
    let mut obs = vec![0.0f32; layout.size];
    for zone in ["front", "sides", "behind"] {
        let (x, y, yaw) = world.reset_in_zone(zone, &mut rng)?;
        let mut targets = vec![0.0; model.index.dof()];
        world.joint_angles(&mut targets);
        for _ in 0..60 {
            world.step(&targets)?;
        }
        world.observe(&layout, &mut obs);
        let c = world.contacts();
        let at = layout.entries.last().expect("chair feature").offset;
        println!(
            "{zone:<7} start ({x:+.2}, {y:+.2}) facing {:+4.0}°: after 1 s chair at ({:+.2}, {:+.2}) in the heading frame, \
             seat {:.2} m, fallen {}, pelvis on seat {}",
            yaw.to_degrees(),
            obs[at],
            obs[at + 1],
            world.placements()[chair].top,
            c.fallen,
            c.pelvis_on_prop(chair)
        );
    }
    Ok(())
}
