//! The warehouse and toss scenario files: they parse, compile and draw their props per episode;
//! malformed task sections are refused naming the file, the line and what is wrong.

use rand::SeedableRng;
use rand::rngs::StdRng;
use repertoire_scenes::error::FileError;
use repertoire_scenes::scenario::{SitApproach, SitFall, SpotAround, Task, WarehousePhase};
use repertoire_scenes::{Feature, Location, ObservationLayout, ScenarioFile, SceneError, World, WorldModel};
use std::path::{Path, PathBuf};
use std::sync::Arc;

fn shipped(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../../scenarios").join(name)
}

fn parse(text: &str) -> Result<ScenarioFile, SceneError> {
    ScenarioFile::parse(Path::new("task.ron"), text.to_string())
}

#[test]
fn the_warehouse_file_holds_the_papers_numbers_and_draws_pedestals_per_episode() {
    let file = ScenarioFile::load(shipped("warehouse.ron")).expect("warehouse.ron is valid");
    let Task::Warehouse(w) = &file.scenario.task else { panic!("{:?}", file.scenario.task) };
    assert_eq!(w.pedestals, ["pedestal_a", "pedestal_b"]);
    assert_eq!((w.reach_m, w.rest_contacts, w.time_limit_s), (0.65, 4, 15.0));
    assert_eq!(w.start_phases, WarehousePhase::ALL);
    let model = Arc::new(WorldModel::build(file).expect("compiles"));
    let [a, b, crate_] = ["pedestal_a", "pedestal_b", "box"].map(|n| model.prop_id(n).unwrap());
    let mut world = model.new_world();
    let mut rng = StdRng::seed_from_u64(5);
    let mut distances = Vec::new();
    for _ in 0..20 {
        world.reset_in_zone("middle", &mut rng).unwrap();
        let p = world.placements();
        for ped in [a, b] {
            let d = p[ped].pos[0].hypot(p[ped].pos[1]);
            assert!((2.5 - 1e-9..=3.5 + 1e-9).contains(&d), "pedestal {ped} at {d} m from the origin");
            assert!((0.45..=0.75).contains(&p[ped].top), "height {}", p[ped].top);
            distances.push(d);
        }
        assert!(p[a].pos[0] > 0.0 && p[b].pos[0] < 0.0, "on opposite sides");
        assert!((0.75..=1.25).contains(&p[crate_].scale) && (2.0..=7.0).contains(&p[crate_].mass));
        // The box starts centred on pedestal_a, its bottom on the top.
        let c = world.body_position(model.props[crate_].body);
        assert!((c[0] - p[a].pos[0]).abs() < 1e-9 && (c[1] - p[a].pos[1]).abs() < 1e-9);
        assert!((c[2] - (p[a].top + 0.15 * p[crate_].scale)).abs() < 1e-9);
    }
    distances.sort_by(f64::total_cmp);
    assert!(distances[distances.len() - 1] - distances[0] > 0.5, "the distance varies: {distances:?}");
}

#[test]
fn the_toss_file_holds_the_papers_throw() {
    let file = ScenarioFile::load(shipped("toss.ron")).expect("toss.ron is valid");
    let Task::Toss(t) = &file.scenario.task else { panic!("{:?}", file.scenario.task) };
    assert_eq!((t.throw.v_x.min(), t.throw.v_x.max()), (1.5, 4.5));
    assert_eq!((t.throw.lateral.min(), t.throw.lateral.max()), (-0.75, 0.75));
    assert_eq!((t.throw.d_z.min(), t.throw.d_z.max()), (0.1, 0.4));
    assert_eq!(t.ball, "ball");
    let model = Arc::new(WorldModel::build(file).expect("compiles"));
    let ball = model.prop_id("ball").unwrap();
    let mut world = model.new_world();
    let mut rng = StdRng::seed_from_u64(2);
    world.reset_in_zone("middle", &mut rng).unwrap();
    let p = world.placements()[ball];
    assert!((0.95..=1.5).contains(&p.scale) && (2.0..=4.0).contains(&p.mass), "{p:?}");
}

#[test]
fn malformed_task_sections_are_located_and_explained() {
    const PROPS: &str = r#"props: [
        Pedestal(name: "a", at: (x: 3.0, y: 0.0)),
        Pedestal(name: "b", at: (x: -3.0, y: 0.0)),
        Box(name: "crate", on: "a"),
        Ball(name: "ball"),
        Bucket(name: "bucket"),
        Chair(name: "chair"),
    ],"#;
    let cases = [
        // (task, expected message, expected line)
        (r#"Warehouse(box: "crate", pedestals: ["a", "b"], reach: 0.65)"#, "unknown field `reach`", 11),
        (r#"Warehouse(box: "crate", pedestals: ["a", "table"])"#, "`table`, which is not in `props`", 11),
        (r#"Warehouse(box: "crate", pedestals: ["a", "chair"])"#, "`chair` is a chair, not a pedestal", 9),
        (r#"Warehouse(box: "ball", pedestals: ["a", "b"])"#, "`ball` is a ball, not a box", 7),
        (r#"Warehouse(box: "crate", pedestals: ["a"])"#, "at least two pedestals", 11),
        (r#"Warehouse(box: "crate", pedestals: ["b", "chair"])"#, "`chair` is a chair", 9),
        (r#"Warehouse(box: "crate", pedestals: ["a", "b"], reach_m: -1.0)"#, "reach_m must be positive", 11),
        (r#"Warehouse(box: "crate", pedestals: ["a", "b"], start_phases: [])"#, "no start phase", 11),
        (r#"Warehouse(box: "crate", pedestals: ["a", "b"], start_phases: [Walk])"#, "Walk", 11),
        (r#"Warehouse(box: "crate", pedestals: ["a", "b"], rest_contacts: 0)"#, "rest_contacts", 11),
        (r#"Warehouse(box: "crate", pedestals: ["a", "b"], reach_m: "far")"#, "", 11),
        (
            r#"Warehouse(box: "crate", pedestals: ["a", "b"], hold_from: "juggle")"#,
            "hold_from names skill `juggle`",
            11,
        ),
        (r#"Toss(ball: "crate", bucket: "bucket")"#, "`crate` is a box, not a ball", 6),
        (r#"Toss(ball: "ball", bucket: "a")"#, "`a` is a pedestal, not a bucket", 4),
        (
            r#"Toss(ball: "ball", bucket: "bucket", throw: (v_x: (0.0, 2.0)))"#,
            "`throw.v_x` is Uniform(0.0, 2.0); it must be positive",
            11,
        ),
        (r#"Toss(ball: "ball", bucket: "bucket", throw: (v_x: (3.0, 2.0)))"#, "low end above its high end", 11),
        (r#"Toss(ball: "ball", bucket: "bucket", throw: (speed: 2.0))"#, "unknown field `speed`", 11),
        (r#"Toss(ball: "ball", bucket: "bucket", catch_at: (forward: 0.4, height: 0.0))"#, "catch_at", 11),
        (r#"Toss(ball: "ball", bucket: "bucket", time_limit_s: 0.0)"#, "time_limit_s", 11),
    ];
    for (task, expect, line) in cases {
        let text = format!("Scenario(\n    name: \"t\",\n    {PROPS}\n    task: {task},\n)");
        let err = parse(&text).err().unwrap_or_else(|| panic!("accepted: {task}"));
        let msg = err.to_string();
        assert!(msg.starts_with("task.ron:"), "names the file: {msg}");
        assert!(msg.contains(expect), "{task}\n→ {msg}");
        let loc = match &err {
            SceneError::File(FileError::Ron { loc, .. }) => Some(*loc),
            SceneError::Invalid { loc, .. } => *loc,
            other => panic!("{other:?}"),
        };
        let Some(Location { line: got, .. }) = loc else { panic!("no location: {msg}") };
        assert_eq!(got, line, "{task}\n→ {msg}");
    }
    // A box that does not start on a warehouse pedestal.
    let text = r#"Scenario(name: "t", props: [Pedestal(name: "a"), Pedestal(name: "b"), Box(name: "crate")],
        task: Warehouse(box: "crate", pedestals: ["a", "b"]))"#;
    assert!(parse(text).unwrap_err().to_string().contains("must start `on` one of the warehouse pedestals"));
    // A polar placement with a bad range.
    let text = r#"Scenario(name: "t", props: [Pedestal(name: "a", at: (radius: (3.5, 2.5)))])"#;
    assert!(parse(text).unwrap_err().to_string().contains("low end above its high end"));
}

#[test]
fn prop_bindings_parse_and_bad_ones_are_located() {
    use repertoire_scenes::scenario::PropBinding;
    let file = ScenarioFile::load(shipped("warehouse.ron")).unwrap();
    assert_eq!(file.scenario.bind.get("pedestal"), Some(&PropBinding::Focal));
    assert_eq!(file.scenario.bind.len(), 1);
    let file = ScenarioFile::load(shipped("toss.ron")).unwrap();
    assert_eq!(file.scenario.bind.get("box"), Some(&PropBinding::Prop("ball".into())));
    // The sitting scenario binds nothing, and writes no `bind` when serialised.
    let sit = ScenarioFile::builtin_default();
    assert!(sit.scenario.bind.is_empty());
    assert!(!ron::to_string(&sit.scenario).unwrap().contains("bind"));

    const HEAD: &str = r#"Scenario(
    name: "t",
    props: [Pedestal(name: "a"), Pedestal(name: "b"), Box(name: "crate", on: "a"), Chair(name: "chair")],"#;
    let warehouse = r#"task: Warehouse(box: "crate", pedestals: ["a", "b"]),"#;
    let sit = r#"task: Sit(seat: "chair"),"#;
    let cases = [
        // (task, bind, expected message, expected line)
        (warehouse, r#"bind: {"pedestal": Prop("table")},"#, "`bind`'s `pedestal` refers to prop `table`", 5),
        (warehouse, r#"bind: {"pedestal": Nearest},"#, "Nearest", 5),
        (warehouse, r#"bind: {"my pedestal": Focal},"#, "must be a prop name", 5),
        (
            sit,
            r#"bind: {"pedestal": Focal},"#,
            "maps `pedestal` to Focal, the warehouse's focal pedestal, but the task is Sit",
            5,
        ),
    ];
    for (task, bind, expect, line) in cases {
        let text = format!("{HEAD}\n    {task}\n    {bind}\n)");
        let err = parse(&text).err().unwrap_or_else(|| panic!("accepted: {bind}"));
        let msg = err.to_string();
        assert!(msg.starts_with("task.ron:") && msg.contains(expect), "{bind}\n→ {msg}");
        let loc = match &err {
            SceneError::File(FileError::Ron { loc, .. }) => Some(*loc),
            SceneError::Invalid { loc, .. } => *loc,
            other => panic!("{other:?}"),
        };
        assert_eq!(loc.map(|l| l.line), Some(line), "{bind}\n→ {msg}");
    }
    // A binding to an existing prop is accepted in any task.
    let text = format!("{HEAD}\n    {sit}\n    bind: {{\"seat\": Prop(\"chair\")}},\n)");
    assert_eq!(parse(&text).unwrap().scenario.bind.get("seat"), Some(&PropBinding::Prop("chair".into())));

    // The sit task counts as seated only facing within `facing_deg` of the chair's front: 60
    // by default, any angle in (0, 180]; others are refused, naming the field.
    match parse(&format!("{HEAD}\n    {sit}\n)")).unwrap().scenario.task {
        Task::Sit { facing_deg, .. } => assert_eq!(facing_deg, 60.0),
        other => panic!("{other:?}"),
    }
    for bad in ["0.0", "-10.0", "181.0"] {
        let text = format!("{HEAD}\n    task: Sit(seat: \"chair\", facing_deg: {bad}),\n)");
        let msg = parse(&text).err().unwrap_or_else(|| panic!("accepted facing_deg {bad}")).to_string();
        assert!(msg.starts_with("task.ron:") && msg.contains("facing_deg"), "{bad} → {msg}");
    }
    let text = format!("{HEAD}\n    task: Sit(seat: \"chair\", facing_deg: 180.0),\n)");
    assert!(parse(&text).is_ok(), "180 counts any contact");

    // The approach reward: the seat (the paper's) by default, or a spot in front of it.
    match parse(&format!("{HEAD}\n    {sit}\n)")).unwrap().scenario.task {
        Task::Sit { approach, .. } => assert_eq!(approach, SitApproach::Seat),
        other => panic!("{other:?}"),
    }
    let text = format!("{HEAD}\n    task: Sit(seat: \"chair\", approach: Spot(ahead_m: 0.4, heading_m: 0.3)),\n)");
    match parse(&text).unwrap().scenario.task {
        Task::Sit { approach, .. } => {
            assert_eq!(approach, SitApproach::Spot { ahead_m: 0.4, heading_m: 0.3, turn_within_m: None, around: None })
        }
        other => panic!("{other:?}"),
    }
    let text = format!(
        "{HEAD}\n    task: Sit(seat: \"chair\", approach: Spot(ahead_m: 0.4, heading_m: 0.3, \
         around: (radius_m: 0.6, behind_m: 0.3))),\n)"
    );
    match parse(&text).unwrap().scenario.task {
        Task::Sit { approach: SitApproach::Spot { around: Some(a), .. }, .. } => {
            assert_eq!(a, SpotAround { radius_m: 0.6, behind_m: 0.3 })
        }
        other => panic!("{other:?}"),
    }
    for bad in [
        "Spot(ahead_m: -0.4, heading_m: 0.3)",
        "Spot(ahead_m: 0.4, heading_m: -1.0)",
        "Spot(ahead_m: 0.4, heading_m: 0.3, around: (radius_m: 0.0, behind_m: 0.3))",
        "Spot(ahead_m: 0.4, heading_m: 0.3, around: (radius_m: 0.6, behind_m: -0.1))",
        // The spot inside the disc: 0.6 − 0.1 ≥ 0.4.
        "Spot(ahead_m: 0.4, heading_m: 0.3, around: (radius_m: 0.6, behind_m: 0.1))",
    ] {
        let text = format!("{HEAD}\n    task: Sit(seat: \"chair\", approach: {bad}),\n)");
        let msg = parse(&text).err().unwrap_or_else(|| panic!("accepted {bad}")).to_string();
        assert!(msg.starts_with("task.ron:") && msg.contains("approach"), "{bad} → {msg}");
    }

    // What a fall does to the approach reward: kept (the paper's) by default, or forfeited.
    match parse(&format!("{HEAD}\n    {sit}\n)")).unwrap().scenario.task {
        Task::Sit { on_fall, .. } => assert_eq!(on_fall, SitFall::Keep),
        other => panic!("{other:?}"),
    }
    let text = format!("{HEAD}\n    task: Sit(seat: \"chair\", on_fall: Forfeit),\n)");
    match parse(&text).unwrap().scenario.task {
        Task::Sit { on_fall, .. } => assert_eq!(on_fall, SitFall::Forfeit),
        other => panic!("{other:?}"),
    }
    // Touching the chair outside the sit costs nothing by default (the paper's reward).
    match parse(&format!("{HEAD}\n    {sit}\n)")).unwrap().scenario.task {
        Task::Sit { touch_penalty, .. } => assert_eq!(touch_penalty, 0.0),
        other => panic!("{other:?}"),
    }
    let text = format!("{HEAD}\n    task: Sit(seat: \"chair\", touch_penalty: 0.25),\n)");
    match parse(&text).unwrap().scenario.task {
        Task::Sit { touch_penalty, .. } => assert_eq!(touch_penalty, 0.25),
        other => panic!("{other:?}"),
    }
    for bad in ["-0.5", "inf"] {
        let text = format!("{HEAD}\n    task: Sit(seat: \"chair\", touch_penalty: {bad}),\n)");
        let msg = parse(&text).err().unwrap_or_else(|| panic!("accepted {bad}")).to_string();
        assert!(msg.starts_with("task.ron:") && msg.contains("touch_penalty"), "{bad} → {msg}");
    }
    let text = format!("{HEAD}\n    task: Sit(seat: \"chair\", on_fall: Refund),\n)");
    let msg = parse(&text).err().map(|e| e.to_string()).unwrap_or_else(|| panic!("accepted an unknown on_fall"));
    assert!(msg.starts_with("task.ron:") && msg.contains("Refund"), "{msg}");
}

#[test]
fn a_ball_of_any_drawn_mass_falls_at_standard_gravity() {
    // Masses drawn per episode (2–4 kg around a nominal 3 kg) change the ball's inertia, not
    // how fast it falls; before MuJoCo's derived constants were recomputed it fell at g·m/3.
    let model = Arc::new(WorldModel::build(ScenarioFile::load(shipped("toss.ron")).unwrap()).unwrap());
    let ball = model.prop_id("ball").unwrap();
    let mut world = model.new_world();
    let mut rng = StdRng::seed_from_u64(12);
    let mut masses = Vec::new();
    for _ in 0..5 {
        world.reset_in_zone("middle", &mut rng).unwrap();
        masses.push(world.placements()[ball].mass);
        world.set_free_prop(ball, [3.0, 2.0, 3.0], [1.0, 0.0, 0.0, 0.0], [0.0, 0.0, 2.0], [0.0, 0.0, 3.0]).unwrap();
        let hold: Vec<f64> = {
            let mut a = vec![0.0; model.index.dof()];
            world.joint_angles(&mut a);
            a
        };
        let ticks = 18;
        for _ in 0..ticks {
            world.step(&hold).unwrap();
        }
        let t = ticks as f64 * model.control_dt();
        let z = world.body_position(model.props[ball].body)[2];
        let expected = 3.0 + 2.0 * t - 0.5 * 9.81 * t * t;
        assert!((z - expected).abs() < 0.005, "mass {}: z {z} vs {expected}", masses.last().unwrap());
    }
    assert!(masses.iter().any(|&m| (m - 3.0).abs() > 0.3), "masses away from the nominal were drawn: {masses:?}");
}

#[test]
fn every_shipped_scenario_builds_and_the_paper_reward_variant_differs_from_sit_only_in_its_reward() {
    let dir = shipped("sit.ron").parent().unwrap().to_path_buf();
    let mut built = Vec::new();
    for f in std::fs::read_dir(&dir).unwrap() {
        let f = f.unwrap().path();
        if f.extension().is_some_and(|e| e == "ron") {
            let file = ScenarioFile::load(&f).unwrap_or_else(|e| panic!("{}: {e}", f.display()));
            WorldModel::build(file).unwrap_or_else(|e| panic!("{}: {e}", f.display()));
            built.push(f.file_name().unwrap().to_string_lossy().into_owned());
        }
    }
    assert!(built.len() >= 5 && built.iter().any(|n| n == "sit_paper_reward.ron"), "{built:?}");
    let sit = ScenarioFile::load(shipped("sit.ron")).unwrap().scenario;
    match &sit.task {
        Task::Sit { approach, .. } => {
            assert_eq!(*approach, SitApproach::Spot { ahead_m: 0.4, heading_m: 0.3, turn_within_m: None, around: None })
        }
        other => panic!("{other:?}"),
    }
    let mut paper = ScenarioFile::load(shipped("sit_paper_reward.ron")).unwrap().scenario;
    match &mut paper.task {
        Task::Sit { approach, .. } => {
            assert_eq!(*approach, SitApproach::Seat);
            *approach = SitApproach::Spot { ahead_m: 0.4, heading_m: 0.3, turn_within_m: None, around: None };
        }
        other => panic!("{other:?}"),
    }
    paper.name = sit.name.clone();
    assert_eq!(paper, sit, "the same scene, skills, zones and success test");
}

#[test]
fn the_forfeit_touch_and_round_variants_differ_from_sit_only_in_their_reward() {
    let sit = ScenarioFile::load(shipped("sit.ron")).unwrap().scenario;
    let mut forfeit = ScenarioFile::load(shipped("sit_forfeit.ron")).unwrap().scenario;
    match &mut forfeit.task {
        Task::Sit { on_fall, touch_penalty, .. } => {
            assert_eq!((*on_fall, *touch_penalty), (SitFall::Forfeit, 0.0));
            *on_fall = SitFall::Keep;
        }
        other => panic!("{other:?}"),
    }
    let mut touch = ScenarioFile::load(shipped("sit_touch.ron")).unwrap().scenario;
    match &mut touch.task {
        Task::Sit { on_fall, touch_penalty, .. } => {
            assert_eq!((*on_fall, *touch_penalty), (SitFall::Keep, 0.5));
            *touch_penalty = 0.0;
        }
        other => panic!("{other:?}"),
    }
    let mut round = ScenarioFile::load(shipped("sit_round.ron")).unwrap().scenario;
    match &mut round.task {
        Task::Sit { approach: SitApproach::Spot { around, .. }, .. } => {
            assert_eq!(around.take(), Some(SpotAround { radius_m: 0.6, behind_m: 0.3 }));
        }
        other => panic!("{other:?}"),
    }
    for mut variant in [forfeit, touch, round] {
        variant.name = sit.name.clone();
        assert_eq!(variant, sit, "the same scene, skills, zones and success test");
    }
}

#[test]
fn the_guarded_sit_variant_differs_from_sit_only_in_its_guard() {
    let sit = ScenarioFile::load(shipped("sit.ron")).unwrap().scenario;
    let mut guarded = ScenarioFile::load(shipped("sit_guard.ron")).unwrap().scenario;
    let graph = guarded.skill_graph.as_mut().expect("a graph");
    assert_eq!(graph.guards.len(), 1);
    let guard = graph.guards.pop().unwrap();
    assert_eq!((guard.skill.as_str(), guard.near.as_str(), guard.within_m), ("sit", "chair", 0.8));
    assert_eq!(guarded, sit, "the same scene, skills, graph and task");
}

#[test]
fn a_fixed_scale_other_than_one_resizes_the_box_too() {
    // Before stop 31 only a scale drawn from a range reached the geometry: `scale: (1.5, 1.5)`
    // was reported in the placement while the box kept its built size.
    for (scale, half) in [("(1.5, 1.5)", 0.15), ("(1.0, 1.0)", 0.1), ("(0.5, 1.5)", f64::NAN)] {
        let text = format!(
            r#"Scenario(
    name: "scaled_box",
    body: Humanoid,
    props: [Box(name: "box", at: (x: 2.0, y: 0.0, z: 0.0, yaw_deg: 0.0), size: (0.2, 0.2, 0.2), scale: {scale}, mass: 2.0)],
    spawn: [Zone(name: "origin", radius: (0.0, 0.1), angle_deg: (-180.0, 180.0), facing: Uniform)],
    task: Free(time_limit_s: 5.0),
    skills: ["walk"],
)"#
        );
        let file = ScenarioFile::parse(Path::new("scaled_box.ron"), text).expect("scene");
        let model = Arc::new(WorldModel::build(file).expect("builds"));
        let b = model.prop_id("box").unwrap();
        let mut world = World::new(Arc::clone(&model));
        world.reset_in_zone("origin", &mut StdRng::seed_from_u64(4)).unwrap();
        let s = world.placements()[b].scale;
        let half = if half.is_nan() { 0.1 * s } else { half };
        let m = world.data().model();
        let geom = (0..m.geom_bodyid().len()).find(|&g| m.geom_bodyid()[g] as usize == model.props[b].body).unwrap();
        assert!((m.geom_size()[geom][0] - half).abs() < 1e-12, "scale {scale}: half edge {}", m.geom_size()[geom][0]);
        // Resting on the floor at its scaled half height.
        assert!((world.body_position(model.props[b].body)[2] - half).abs() < 1e-9);
        // And observed at that size (`PropSize`), after the pose.
        let features = [Feature::RootHeight, Feature::PropPose("box".into()), Feature::PropSize("box".into())];
        let layout = ObservationLayout::new(&model, &features).expect("layout");
        assert_eq!(layout.size, 1 + 5 + 3);
        let mut obs = vec![0.0f32; layout.size];
        world.observe(&layout, &mut obs);
        for v in &obs[6..9] {
            assert!((f64::from(*v) - 2.0 * half).abs() < 1e-6, "scale {scale}: observed size {:?}", &obs[6..9]);
        }
    }
    // Only a box's or a ball's size is observed.
    let file = ScenarioFile::load(shipped("warehouse.ron")).unwrap();
    let model = WorldModel::build(file).unwrap();
    let err = ObservationLayout::new(&model, &[Feature::PropSize("pedestal_a".into())]).unwrap_err().to_string();
    assert!(err.contains("prop_size:pedestal_a") && err.contains("is a pedestal"), "{err}");
}

#[test]
fn the_detour_variant_differs_from_sit_only_in_its_detour() {
    let sit = ScenarioFile::load(shipped("sit.ron")).unwrap().scenario;
    let mut detour = ScenarioFile::load(shipped("sit_detour.ron")).unwrap().scenario;
    let d = detour.detour.take().expect("a detour");
    assert_eq!((d.around.as_slice(), d.radius_m), (&["chair".to_string()][..], 0.7));
    detour.name = sit.name.clone();
    assert_eq!(detour, sit, "the same scene, skills, graph and task");
}

#[test]
fn the_walk_around_variant_is_sit_with_walk_around_in_walk_tos_place() {
    let sit = ScenarioFile::load(shipped("sit.ron")).unwrap().scenario;
    let mut around = ScenarioFile::load(shipped("sit_around.ron")).unwrap().scenario;
    assert!(around.skills.iter().any(|s| s == "walk_around") && !around.skills.iter().any(|s| s == "walk_to"));
    let back = |s: &mut String| {
        if s == "walk_around" {
            *s = "walk_to".into();
        }
    };
    around.skills.iter_mut().for_each(back);
    let g = around.skill_graph.as_mut().expect("a graph");
    g.start.iter_mut().for_each(back);
    g.edges.iter_mut().for_each(|(a, b)| {
        back(a);
        back(b);
    });
    around.name = sit.name.clone();
    assert_eq!(around, sit, "the same scene, task, zones and graph");
}
