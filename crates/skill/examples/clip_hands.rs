//! Prints a clip's pelvis height and hands (midpoint relative to the pelvis in its heading
//! frame, world height, separation) every 0.1 s: a check for authoring object clips.
//! `cargo run -p repertoire-skill --example clip_hands -- FILE`

use std::path::Path;

use repertoire_clip::ClipBody;
use repertoire_scenes::{ScenarioFile, WorldModel};
use repertoire_skill::load_clip;
use repertoire_skill::reference::Reference;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let file = std::env::args().nth(1).ok_or("usage: clip_hands FILE")?;
    let model = WorldModel::build(ScenarioFile::builtin_default())?;
    let body = ClipBody::new(model.body.clone())?;
    let clip = load_clip(Path::new(&file), None, &body)?;
    let r = Reference::new(&clip, &body, 60.0)?;
    println!("  t     pelvis_z  hands_fwd  hands_left  hands_z(world)  separation");
    for f in (0..r.frames()).step_by(6) {
        let [l, rt, ..] = r.end_effectors[f];
        let mid = [(l[0] + rt[0]) / 2.0, (l[1] + rt[1]) / 2.0, (l[2] + rt[2]) / 2.0];
        let sep = ((l[0] - rt[0]).powi(2) + (l[1] - rt[1]).powi(2) + (l[2] - rt[2]).powi(2)).sqrt();
        println!(
            "{:5.2}  {:7.3}  {:9.3}  {:10.3}  {:14.3}  {:10.3}",
            f as f64 * r.dt,
            r.height[f],
            mid[0],
            mid[1],
            r.height[f] + mid[2],
            sep
        );
    }
    Ok(())
}
