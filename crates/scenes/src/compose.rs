//! Composes a scene's MJCF: the body's own document plus a floor, a light and the props.
//!
//! MJCF lets top-level sections repeat, so the scene is the body's text with one more
//! `<option>`, `<asset>` and `<worldbody>` appended before its closing `</mujoco>`. The body's
//! file is kept verbatim: MuJoCo's messages about it keep their line numbers (the body is also
//! compiled alone first, see [`crate::body::BodyDef::check`]). Prop geoms carry every contact
//! attribute explicitly, so defaults in a user's body never leak onto them.

use crate::body::BodyDef;
use crate::error::{Result, SceneError};
use crate::scenario::{Prop, Scenario};
use std::f64::consts::PI;
use std::fmt::Write;

/// Contact attributes every prop geom but a box's, and the floor, carry.
const CONTACT: &str = r#"condim="3" friction="1 0.05 0.01" contype="1" conaffinity="1" group="0" margin="0" gap="0""#;
/// A box's contacts: twice the sliding friction (MuJoCo takes the larger of the two geoms', so
/// this is what hands on a box get; a stand-in for the fingers the body's spherical hands lack)
/// and resistance to twisting about the contact normal (`condim="4"`, torsional friction 0.1 m,
/// about a palm's radius). Held between two spheres a box touches each at one point; with the
/// defaults it pivots about the line between the hands and slides out of the grip
/// (`examples/object_probe.rs` shows it). The library's lift keeps the box in 97.1 % of 1000
/// trials with these contacts and in 78.9 % with the defaults (`skill eval lift.ron`, the same
/// policy).
const GRIP_CONTACT: &str =
    r#"condim="4" friction="2 0.1 0.01" contype="1" conaffinity="1" group="0" margin="0" gap="0""#;

/// Force (N) with which each hand's grip pulls a touching object against it at full grip.
///
/// The body's hands are spheres without fingers. In scenes with a free object (a box or a
/// ball) each hand gets a MuJoCo adhesion actuator (`repertoire/grip/left`, `.../right`): at
/// grip level 1 it presses every geom the hand touches against the hand with this force,
/// spread over the hand's contacts, which is what lets friction hold a box while the walker
/// swings it through a stride. It acts only on contact, so an object not touched is not
/// pulled. A skill sets the level (its spec's `grip`, 0 by default; see
/// [`crate::World::set_grip`]); policies never see or drive it. 120 N against a box of at
/// most 7 kg (69 N) under friction 2 is several times what holding it needs, and well below
/// what the arms' actuators can pull apart.
pub const GRIP_FORCE_N: f64 = 120.0;
pub use crate::body::{ADDED_ACTUATOR_PREFIX, GRIP_ACTUATORS};

/// Number of wall segments of a bucket.
pub const BUCKET_WALLS: usize = 12;

/// Builds the scene MJCF for `scenario` around `body`; `own_ground`: the body's file brings its
/// own ground plane ([`ground_plane`] of the body compiled alone), so the scene adds no floor.
pub fn scene_mjcf(body: &BodyDef, scenario: &Scenario, own_ground: bool) -> Result<String> {
    let close = body
        .mjcf
        .rfind("</mujoco>")
        .ok_or_else(|| SceneError::Mjcf { file: body.mjcf_path.clone(), message: "no closing </mujoco> tag".into() })?;
    let mut out = String::with_capacity(body.mjcf.len() + 4096);
    out.push_str(&body.mjcf[..close]);

    let timestep = 1.0 / f64::from(scenario.rates.physics_hz);
    let _ = writeln!(out, "  <!-- Added by Repertoire for scenario `{}` -->", xml_escape(&scenario.name));
    let integrator = if body.mjcf.contains("integrator=") { "" } else { r#" integrator="implicitfast""# };
    let _ = writeln!(out, r#"  <option timestep="{timestep:.9}"{integrator}/>"#);
    out.push_str(
        r#"  <asset>
    <texture name="repertoire_grid" type="2d" builtin="checker" rgb1="0.32 0.36 0.40" rgb2="0.26 0.30 0.34" width="256" height="256" mark="edge" markrgb="0.45 0.48 0.52"/>
    <material name="repertoire_grid" texture="repertoire_grid" texrepeat="1 1" texuniform="true" reflectance="0.1"/>
  </asset>
  <worldbody>
    <light name="repertoire_sun" directional="true" pos="0 0 6" dir="0.2 0.3 -1" diffuse="0.8 0.8 0.8"/>
"#,
    );
    // A body file that brings its own ground plane (gymnasium's humanoid does) stands on it; a
    // second plane under it would double every foot contact.
    if !own_ground {
        let _ = writeln!(
            out,
            r#"    <geom name="floor" type="plane" size="0 0 0.05" material="repertoire_grid" rgba="1 1 1 1" {CONTACT}/>"#
        );
    }
    for prop in &scenario.props {
        prop_mjcf(&mut out, prop);
    }
    out.push_str("  </worldbody>\n");
    if scenario.props.iter().any(|p| matches!(p, Prop::Box(_) | Prop::Ball(_))) {
        out.push_str("  <actuator>\n");
        for (name, hand) in GRIP_ACTUATORS.iter().zip([&body.map.left_hand, &body.map.right_hand]) {
            let _ = writeln!(
                out,
                r#"    <adhesion name="{name}" body="{}" ctrlrange="0 1" gain="{GRIP_FORCE_N}"/>"#,
                xml_escape(hand)
            );
        }
        out.push_str("  </actuator>\n");
    }
    check_names(body, &out[close..])?;
    out.push_str(&body.mjcf[close..]);
    Ok(out)
}

/// Refuses a body whose MJCF names an element the way the scene's own of that kind is named
/// (a `floor` geom, a prop's geom, a light, a material): MuJoCo would report the repeated name
/// at a line of the composed model, which the user cannot see; this names the line of their
/// file.
fn check_names(body: &BodyDef, added: &str) -> Result<()> {
    let ours: std::collections::HashSet<(String, String)> =
        named_elements(added).into_iter().map(|(kind, name, _)| (kind, name)).collect();
    for (kind, name, line) in named_elements(&body.mjcf) {
        if ours.contains(&(kind.clone(), name.clone())) {
            return Err(SceneError::Invalid {
                file: body.mjcf_path.clone(),
                loc: Some(crate::error::Location { line, col: 1 }),
                message: format!(
                    "the body's <{kind} name=\"{name}\"> has the name of a {kind} the scene adds (its floor, light, \
                     materials and props); rename it in this file"
                ),
            });
        }
    }
    Ok(())
}

/// The first plane geom on the world body of `model`: the ground.
pub fn ground_plane(model: &mujoco_rs::prelude::MjModel) -> Option<usize> {
    use mujoco_rs::wrappers::mj_model::MjtGeomBase;
    (0..model.geom_type().len())
        .find(|&g| model.geom_bodyid()[g] == 0 && model.geom_type()[g] == MjtGeomBase::mjGEOM_PLANE)
}

/// Every `<kind … name="…"` in `text`: (kind, name, 1-based line).
fn named_elements(text: &str) -> Vec<(String, String, usize)> {
    let mut out = Vec::new();
    for (i, _) in text.match_indices(" name=\"") {
        let Some(open) = text[..i].rfind('<') else { continue };
        if text[open..i].contains('>') {
            continue; // an attribute outside a tag
        }
        let kind: String = text[open + 1..].chars().take_while(|c| c.is_ascii_alphanumeric() || *c == '_').collect();
        let start = i + " name=\"".len();
        let Some(len) = text[start..].find('"') else { continue };
        let line = text[..open].matches('\n').count() + 1;
        out.push((kind, text[start..start + len].to_string(), line));
    }
    out
}

/// Quaternion (w x y z) of a heading about +z, in degrees.
pub fn yaw_quat(yaw_deg: f64) -> [f64; 4] {
    let h = 0.5 * yaw_deg * PI / 180.0;
    [h.cos(), 0.0, 0.0, h.sin()]
}

fn prop_mjcf(out: &mut String, prop: &Prop) {
    let name = xml_escape(prop.name());
    let at = prop.pose();
    let q = yaw_quat(at.yaw_deg.nominal());
    let (x, y) = at.nominal_xy();
    let geom_with = |out: &mut String, part: &str, attrs: String, rgba: &str, contact: &str| {
        let _ = writeln!(out, r#"      <geom name="{name}/{part}" {attrs} rgba="{rgba}" {contact}/>"#);
    };
    let geom = |out: &mut String, part: &str, attrs: String, rgba: &str| geom_with(out, part, attrs, rgba, CONTACT);
    match prop {
        Prop::Chair(c) => {
            // Built at the tallest seat height; lower heights sink the (static) chair into the floor.
            let h = c.seat_height.max();
            let (d, w) = (c.seat_depth, c.seat_width);
            let _ = writeln!(
                out,
                r#"    <body name="{name}" mocap="true" pos="{x} {y} 0" quat="{} {} {} {}">"#,
                q[0], q[1], q[2], q[3]
            );
            let wood = "0.55 0.38 0.22 1";
            geom(
                out,
                "seat",
                format!(r#"type="box" pos="0 0 {}" size="{} {} 0.025""#, h - 0.025, d / 2.0, w / 2.0),
                wood,
            );
            if c.back_height > 0.0 {
                geom(
                    out,
                    "back",
                    format!(
                        r#"type="box" pos="{} 0 {}" size="0.02 {} {}""#,
                        -d / 2.0 + 0.02,
                        h + c.back_height / 2.0,
                        w / 2.0,
                        c.back_height / 2.0
                    ),
                    wood,
                );
            }
            for (i, (sx, sy)) in [(1.0, 1.0), (1.0, -1.0), (-1.0, 1.0), (-1.0, -1.0)].into_iter().enumerate() {
                let (lx, ly) = (sx * (d / 2.0 - 0.03), sy * (w / 2.0 - 0.03));
                geom(
                    out,
                    &format!("leg{i}"),
                    format!(r#"type="capsule" fromto="{lx} {ly} {} {lx} {ly} 0.02" size="0.02""#, h - 0.05),
                    wood,
                );
            }
            let _ = writeln!(out, "    </body>");
        }
        Prop::Pedestal(p) => {
            let h = p.height.max();
            let _ = writeln!(
                out,
                r#"    <body name="{name}" mocap="true" pos="{x} {y} 0" quat="{} {} {} {}">"#,
                q[0], q[1], q[2], q[3]
            );
            geom(
                out,
                "top",
                format!(r#"type="box" pos="0 0 {}" size="{} {} {}""#, h / 2.0, p.top.0 / 2.0, p.top.1 / 2.0, h / 2.0),
                "0.5 0.5 0.55 1",
            );
            let _ = writeln!(out, "    </body>");
        }
        Prop::Bucket(b) => {
            let _ = writeln!(
                out,
                r#"    <body name="{name}" mocap="true" pos="{x} {y} 0" quat="{} {} {} {}">"#,
                q[0], q[1], q[2], q[3]
            );
            let blue = "0.25 0.45 0.75 1";
            geom(out, "bottom", format!(r#"type="cylinder" pos="0 0 0.01" size="{} 0.01""#, b.radius + 0.01), blue);
            let half_chord = b.radius * (PI / BUCKET_WALLS as f64).tan() + 0.01;
            for i in 0..BUCKET_WALLS {
                let a = 2.0 * PI * i as f64 / BUCKET_WALLS as f64;
                let wq = yaw_quat(a.to_degrees());
                let r = b.radius + 0.01;
                geom(
                    out,
                    &format!("wall{i}"),
                    format!(
                        r#"type="box" pos="{} {} {}" quat="{} 0 0 {}" size="0.01 {half_chord} {}""#,
                        r * a.cos(),
                        r * a.sin(),
                        b.height / 2.0,
                        wq[0],
                        wq[3],
                        b.height / 2.0
                    ),
                    blue,
                );
            }
            let _ = writeln!(out, "    </body>");
        }
        Prop::Box(b) => {
            let (sx, sy, sz) = (b.size.0 / 2.0, b.size.1 / 2.0, b.size.2 / 2.0);
            let _ = writeln!(
                out,
                r#"    <body name="{name}" pos="{x} {y} {}" quat="{} {} {} {}">"#,
                sz + at.z.nominal(),
                q[0],
                q[1],
                q[2],
                q[3]
            );
            free_joint(out, &name);
            geom_with(
                out,
                "box",
                format!(r#"type="box" size="{sx} {sy} {sz}" mass="{}""#, b.mass.nominal()),
                "0.72 0.55 0.32 1",
                GRIP_CONTACT,
            );
            let _ = writeln!(out, "    </body>");
        }
        Prop::Ball(b) => {
            let _ = writeln!(out, r#"    <body name="{name}" pos="{x} {y} {}">"#, b.radius + at.z.nominal());
            free_joint(out, &name);
            geom(
                out,
                "ball",
                format!(r#"type="sphere" size="{}" mass="{}""#, b.radius, b.mass.nominal()),
                "0.85 0.3 0.2 1",
            );
            let _ = writeln!(out, "    </body>");
        }
    }
}

fn free_joint(out: &mut String, name: &str) {
    // Explicit zeros so a body file's joint defaults (damping, armature) never slow a prop down.
    let _ = writeln!(
        out,
        r#"      <joint name="{name}/free" type="free" damping="0" armature="0" stiffness="0" frictionloss="0"/>"#
    );
}

fn xml_escape(s: &str) -> String {
    s.replace('&', "&amp;").replace('<', "&lt;").replace('>', "&gt;").replace('"', "&quot;")
}
