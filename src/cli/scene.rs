//! `repertoire scene check|mjcf FILE`.

use anyhow::Result;
use clap::Subcommand;
use mujoco_rs::prelude::MjtObjBase;
use repertoire_scenes::scenario::{Facing, Prop, PropBinding, SitApproach, SitFall, Task};
use repertoire_scenes::{Param, WorldModel};
use std::path::PathBuf;
use std::sync::Arc;

#[derive(Debug, Subcommand)]
pub enum SceneCommand {
    /// Validate a scenario and print its body, degrees of freedom, props and zones.
    Check {
        /// Scenario RON file (default: the built-in scenarios/sit.ron).
        file: Option<PathBuf>,
    },
    /// Print the composed MJCF that MuJoCo compiles for a scenario.
    Mjcf {
        /// Scenario RON file (default: the built-in scenarios/sit.ron).
        file: Option<PathBuf>,
    },
}

pub fn run(cmd: SceneCommand) -> Result<()> {
    match cmd {
        SceneCommand::Check { file } => check(file),
        SceneCommand::Mjcf { file } => {
            let model = WorldModel::build(super::load_scenario(file.as_ref())?)?;
            print!("{}", model.mjcf);
            Ok(())
        }
    }
}

fn check(file: Option<PathBuf>) -> Result<()> {
    let scenario = super::load_scenario(file.as_ref())?;
    let model = Arc::new(WorldModel::build(scenario)?);
    let s = &model.scenario.scenario;
    let mass: f64 =
        model.mj_model().body_mass().iter().zip(&model.index.is_character).filter(|(_, c)| **c).map(|(m, _)| m).sum();
    let world = model.new_world();
    // Standing height: the top of the highest geom of the head body.
    let mj = model.mj_model();
    let height = (0..mj.ffi().ngeom as usize)
        .filter(|&g| mj.geom_bodyid()[g] as usize == model.index.head)
        .map(|g| world.data().geom_xpos()[g][2] + mj.geom_rbound()[g])
        .fold(0.0, f64::max);

    println!("scenario  {} ({})", s.name, model.scenario.path.display());
    if !s.description.is_empty() {
        println!("          {}", s.description);
    }
    print_body(&model, mass, height);
    let floor = model.mj_model().id_to_name(MjtObjBase::mjOBJ_GEOM, model.floor_geom).unwrap_or("(unnamed)");
    println!("floor     `{floor}`{}", if model.own_floor { ", the body file's own ground plane" } else { "" });
    println!(
        "rates     physics {} Hz, control {} Hz ({} substeps), meta {} Hz",
        s.rates.physics_hz,
        s.rates.control_hz,
        model.substeps(),
        s.rates.meta_hz
    );
    println!(
        "model     nbody {}, ngeom {}, nq {}, nv {}, nu {}, MuJoCo {}",
        mj.nbody(),
        mj.ngeom(),
        mj.nq(),
        mj.nv(),
        mj.nu(),
        repertoire_scenes::mujoco_version()
    );
    print_props(s);
    print_zones(s);
    println!("task      {}", describe_task(&s.task));
    println!("skills    {}", if s.skills.is_empty() { "none".into() } else { s.skills.join(", ") });
    if let Some(g) = &s.skill_graph {
        println!("graph     start {}; {} transitions", g.start.join(", "), g.edges.len());
        for guard in &g.guards {
            println!("  guard   {} only within {} m of {}", guard.skill, guard.within_m, guard.near);
        }
    }
    if !s.bind.is_empty() {
        let bound: Vec<String> = s
            .bind
            .iter()
            .map(|(name, to)| match to {
                PropBinding::Prop(p) => format!("{name} → {p}"),
                PropBinding::Focal => format!("{name} → the focal pedestal"),
            })
            .collect();
        println!("bind      skills' props: {}", bound.join(", "));
    }
    print_levels(&model);
    println!("ok");
    Ok(())
}

/// Where the body's free root is and what Repertoire added or turned to get it.
fn describe_root(model: &WorldModel) -> String {
    use repertoire::scenes::body::{ADDED_ROOT_JOINT, UPRIGHT_FRAME};
    let m = model.mj_model();
    let name = |b: usize| m.id_to_name(MjtObjBase::mjOBJ_BODY, b).unwrap_or("?").to_string();
    let index = &model.index;
    let pelvis = name(index.pelvis_part);
    let added = model.body.mjcf.contains(&format!("name=\"{ADDED_ROOT_JOINT}\""));
    match model.body.map.upright {
        Some((w, x, y, z)) if name(index.root_body) == UPRIGHT_FRAME => format!(
            "free joint `{ADDED_ROOT_JOINT}` added (the file has none) on `{UPRIGHT_FRAME}`, which holds the pelvis `{pelvis}` \
             turned upright by the map's ({w}, {x}, {y}, {z})"
        ),
        _ if added => format!("free joint `{ADDED_ROOT_JOINT}` added on the pelvis `{pelvis}` (the file has none)"),
        _ if index.root_body != index.pelvis => {
            format!("the free joint is on `{}`; the pelvis `{pelvis}` hangs from it", name(index.root_body))
        }
        _ => format!("the pelvis `{pelvis}`'s own free joint"),
    }
}

/// The body: file, DoF, mass, standing height and pose, joints, motors driven as PD servos.
fn print_body(model: &WorldModel, mass: f64, height: f64) {
    println!("body      {} (hash {})", model.body.mjcf_path.display(), model.body.content_hash());
    println!("          {} actuated DoF, {:.1} kg, standing height {:.2} m", model.index.dof(), mass, height);
    println!(
        "          standing pose: the feet's lowest point {:.1} mm {} the floor",
        1000.0 * model.sole_clearance().abs(),
        if model.sole_clearance() >= 0.0 { "above" } else { "below" }
    );
    if model.lowered_by != 0.0 {
        println!(
            "          default pose moved {:.1} cm {} onto the floor (the body map's stand_on_floor)",
            100.0 * model.lowered_by.abs(),
            if model.lowered_by > 0.0 { "down" } else { "up" }
        );
    }
    println!("          root: {}", describe_root(model));
    println!("          joints: {}", model.index.joints.iter().map(|j| j.name.as_str()).collect::<Vec<_>>().join(" "));
    if !model.pd_motors.is_empty() {
        let each: Vec<String> = model
            .pd_motors
            .iter()
            .map(|m| {
                let peak = m.max_torque.map_or("unlimited".into(), |t| format!("{t:.0}"));
                format!("{} {:.0}/{:.0}/{peak}", m.joint, m.kp, m.kv)
            })
            .collect();
        println!(
            "          {} torque motors driven as PD servos (kp N·m/rad / kv N·m·s/rad / peak N·m): {}",
            model.pd_motors.len(),
            each.join(", ")
        );
    }
}

/// The scenario's props, one line each.
fn print_props(s: &repertoire_scenes::Scenario) {
    println!("props     {}", s.props.len());
    for p in &s.props {
        let at = p.pose();
        let detail = match p {
            Prop::Chair(c) => format!(
                "seat height {} m, {}×{} m, back {} m",
                c.seat_height, c.seat_width, c.seat_depth, c.back_height
            ),
            Prop::Box(b) => {
                format!("{}×{}×{} m × scale {}, {} kg{}", b.size.0, b.size.1, b.size.2, b.scale, b.mass, on(&b.on))
            }
            Prop::Pedestal(p) => format!("top {}×{} m at height {} m", p.top.0, p.top.1, p.height),
            Prop::Ball(b) => format!("radius {} m × scale {}, {} kg{}", b.radius, b.scale, b.mass, on(&b.on)),
            Prop::Bucket(b) => format!("radius {} m, height {} m", b.radius, b.height),
        };
        let polar = if at.radius == Param::Fixed(0.0) {
            String::new()
        } else {
            format!(" + {} m at {}°", at.radius, at.angle_deg)
        };
        println!("  {:<8} {:<10} at x {} y {}{polar} yaw {}°  {}", p.kind(), p.name(), at.x, at.y, at.yaw_deg, detail);
    }
}

/// The spawn zones, one line each.
fn print_zones(s: &repertoire_scenes::Scenario) {
    println!("zones     {}", s.spawn.len());
    for z in &s.spawn {
        let facing = match z.facing {
            Facing::Toward { jitter_deg } => format!("toward ±{jitter_deg}°"),
            Facing::Away { jitter_deg } => format!("away ±{jitter_deg}°"),
            Facing::Uniform => "uniform".into(),
            Facing::World(p) => format!("world {}°", p),
        };
        println!(
            "  {:<8} around {:<8} radius {} m, angle {}°{}, facing {}",
            z.name,
            z.around.as_deref().unwrap_or("origin"),
            z.radius,
            z.angle_deg,
            if z.mirrored { " and mirrored" } else { "" },
            facing
        );
    }
}

/// The low level (skills or a latent model) and the curriculum.
fn print_levels(model: &WorldModel) {
    let s = &model.scenario.scenario;
    match model.scenario.latent_dir() {
        None => println!("low level skills (the meta-controller picks among them)"),
        Some(dir) => println!("low level latent model {} (a high-level policy over z ∈ (−2, 2)^d)", dir.display()),
    }
    match &s.curriculum {
        Some(c) => println!(
            "curriculum {} (advance at {:.0} % over {} episodes{}{})",
            c.zones.join(" → "),
            c.advance_at * 100.0,
            c.window,
            c.max_episodes.map_or_else(String::new, |m| format!(" or after {m} episodes in a zone")),
            if c.keep_passed { ", passed zones stay open" } else { ", one zone at a time" }
        ),
        None => println!("curriculum none"),
    }
}

fn on(base: &Option<String>) -> String {
    base.as_ref().map(|b| format!(", on {b}")).unwrap_or_default()
}

/// One line for people: what the task asks and how it is judged.
fn describe_task(task: &Task) -> String {
    match task {
        Task::Sit { seat, hold_s, time_limit_s, facing_deg, approach, on_fall, touch_penalty } => format!(
            "Sit on `{seat}`: pelvis on the seat, facing within {facing_deg}° of the chair's front, for {hold_s} s \
             within {time_limit_s} s; {}{}{}",
            match approach {
                SitApproach::Seat => "rewarded for approaching the seat".to_string(),
                SitApproach::Spot { ahead_m, turn_within_m, around, .. } => format!(
                    "rewarded for approaching the spot {ahead_m} m in front of the seat{}, {}",
                    match around {
                        Some(a) => format!(
                            " the way round a disc of {} m about {} m behind the seat's centre",
                            a.radius_m, a.behind_m
                        ),
                        None => String::new(),
                    },
                    match turn_within_m {
                        Some(r) => format!("facing it beyond {r} m and turning within"),
                        None => "facing away from it".to_string(),
                    }
                ),
            },
            match on_fall {
                SitFall::Keep => "",
                SitFall::Forfeit => "; a fall forfeits that reward",
            },
            if *touch_penalty > 0.0 {
                format!("; touching the chair before the sit costs {touch_penalty} per decision")
            } else {
                String::new()
            }
        ),
        Task::Warehouse(w) => format!(
            "Warehouse: move `{}` between {}; reach {} m, {} resting contacts, episodes start in {}; {} s",
            w.box_,
            w.pedestals.iter().map(|p| format!("`{p}`")).collect::<Vec<_>>().join(", "),
            w.reach_m,
            w.rest_contacts,
            w.start_phases.iter().map(|p| format!("{p:?}")).collect::<Vec<_>>().join(", "),
            w.time_limit_s
        ),
        Task::Toss(t) => format!(
            "Toss: catch `{}` (thrown from {} m at v_x {} m/s, lateral {} m/s, rising {} m, spin ±{} rad/s, \
             aimed {} m ahead at {} m) and put it in `{}`; {} s",
            t.ball,
            t.throw.distance_m,
            t.throw.v_x,
            t.throw.lateral,
            t.throw.d_z,
            t.throw.spin,
            t.catch_at.forward,
            t.catch_at.height,
            t.bucket,
            t.time_limit_s
        ),
        Task::Free { time_limit_s } => format!("Free: no task, {time_limit_s} s episodes"),
    }
}
