//! The object skills (lift, carry, put down, catch) against real MuJoCo: their specs load and
//! name real props, episodes start with the box or ball where the clip has it, the goal rewards
//! prefer the object in the hands (raised, placed, caught) to the object dropped, a dropped
//! object ends the episode, and a tiny training runs end to end.

use std::path::{Path, PathBuf};

use rand::SeedableRng;
use repertoire_learn::env::{Env, EnvRng};
use repertoire_scenes::World;
use repertoire_skill::imitation::ImitationTask;
use repertoire_skill::train::{TrainOptions, train};
use repertoire_skill::{SkillSetup, SpecFile, library};

fn specs() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../../specs")
}

fn temp(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("repertoire-objects-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).expect("temp dir");
    dir
}

fn setup(spec: &str) -> SkillSetup {
    let spec = SpecFile::load(&specs().join(spec)).expect("the shipped spec parses");
    SkillSetup::new(spec, &temp("lib")).expect("the shipped spec builds")
}

/// Where the object is, and the hands' midpoint.
fn object_and_hands(world: &World, prop: usize) -> ([f64; 3], [f64; 3]) {
    let idx = &world.model().index;
    let [l, r] = [world.body_position(idx.hands[0]), world.body_position(idx.hands[1])];
    let c = world.body_frame(world.model().props[prop].body).pos;
    (c, std::array::from_fn(|k| 0.5 * (l[k] + r[k])))
}

fn dist(a: [f64; 3], b: [f64; 3]) -> f64 {
    (0..3).map(|k| (a[k] - b[k]).powi(2)).sum::<f64>().sqrt()
}

const GOAL: usize = 4;
const OBJECT: usize = 6;

#[test]
fn object_specs_load_and_replay_their_clips() {
    for spec in [
        "lift.ron",
        "lift_any_box.ron",
        "carry.ron",
        "carry_any_box.ron",
        "put_down.ron",
        "catch.ron",
        "catch_grip.ron",
        "catch_heavy.ron",
        "catch_toss.ron",
    ] {
        let s = setup(spec);
        let obj = s.settings.object.as_ref().unwrap_or_else(|| panic!("{spec}: no object setup"));
        assert!(!obj.held.is_empty(), "{spec}: the clip never holds its object");
        let mut env = s.env();
        let mut task = ImitationTask::new(s.settings.clone());
        let frames = s.settings.reference.frames();
        for f in (0..frames).step_by((frames / 6).max(1)) {
            task.place_at_frame(env.world_mut(), f, 0.5, -1.0, 2.0);
            let out = task.score(env.world(), f);
            assert!(out.terms[0] > 0.999 && out.terms[2] > 0.999, "{spec} frame {f}: {:?}", out.terms);
            assert!(out.terms.iter().all(|t| t.is_finite()));
        }
    }
}

#[test]
fn bad_object_props_are_refused_with_the_spec_named() {
    let path = specs().join("lift.ron");
    let text = std::fs::read_to_string(&path).unwrap();
    let bad = text.replace("prop: \"box\"", "prop: \"crate\"");
    let err = SkillSetup::new(SpecFile::parse(&path, &bad).expect("parses"), &temp("bad"))
        .err()
        .expect("unknown prop")
        .to_string();
    assert!(err.contains("lift.ron") && err.contains("`crate`") && err.contains("lacks"), "{err}");
    let bad = text.replace("pedestal: \"pedestal\"", "pedestal: \"box\"");
    let err = SkillSetup::new(SpecFile::parse(&path, &bad).expect("parses"), &temp("bad"))
        .err()
        .expect("a box as pedestal")
        .to_string();
    assert!(err.contains("`box`") && err.contains("not a fixed pedestal"), "{err}");
    let bad = text.replace("grip_s: 1.2", "grip_s: 9.0");
    let err = SkillSetup::new(SpecFile::parse(&path, &bad).expect("parses"), &temp("bad"))
        .err()
        .expect("grip past the clip")
        .to_string();
    assert!(err.contains("grip_s") && err.contains("past the clip's end"), "{err}");
    let bad = text.replace("lift_m: 0.3", "lift_m: -0.3");
    let err = SpecFile::parse(&path, &bad).expect_err("negative lift").to_string();
    assert!(err.contains("lift.ron") && err.contains("lift_m"), "{err}");
    let bad = text.replace("lift_m: 0.3", "lift_m: 0.3, jitter_m: -0.1");
    let err = SpecFile::parse(&path, &bad).expect_err("negative jitter").to_string();
    assert!(err.contains("lift.ron") && err.contains("jitter_m"), "{err}");
    let path = specs().join("catch.ron");
    let text = std::fs::read_to_string(&path).unwrap();
    let bad = text.replace("v_x: (2.0, 4.0)", "v_x: (-2.0, 4.0)");
    let err = SpecFile::parse(&path, &bad).expect_err("negative throw speed").to_string();
    assert!(err.contains("catch.ron") && err.contains("v_x"), "{err}");
    let path = specs().join("carry.ron");
    let text = std::fs::read_to_string(&path).unwrap();
    let bad = text.replace("\"right_elbow\": 55.0", "\"right_wrist\": 55.0");
    let err = SkillSetup::new(SpecFile::parse(&path, &bad).expect("parses"), &temp("bad"))
        .err()
        .expect("unknown joint")
        .to_string();
    assert!(err.contains("carry.ron") && err.contains("right_wrist"), "{err}");
    let bad = text.replace("grip: 1.0", "grip: 1.5");
    let err = SpecFile::parse(&path, &bad).expect_err("grip above 1").to_string();
    assert!(err.contains("carry.ron") && err.contains("grip must be between 0 and 1"), "{err}");
    let bad = text.replace("hold_m: 0.2", "hold_m: -0.2");
    let err = SpecFile::parse(&path, &bad).expect_err("negative hold_m").to_string();
    assert!(err.contains("carry.ron") && err.contains("hold_m"), "{err}");
}

#[test]
fn lift_starts_with_the_box_where_the_clip_has_it_and_rewards_raising_it() {
    let s = setup("lift.ron");
    let obj = s.settings.object.clone().expect("object");
    let (ped, _) = obj.pedestal.expect("pedestal");
    let mut env = s.env();
    let mut rng = EnvRng::seed_from_u64(11);
    let mut obs = vec![0.0; env.obs_dim()];
    let (mut held, mut on_pedestal) = (0, 0);
    for _ in 0..30 {
        env.reset(&mut rng, &mut obs);
        assert!(obs.iter().all(|v| v.is_finite()));
        let w = env.world();
        let (c, hands) = object_and_hands(w, obj.prop);
        if obj.held.contains(&env.task().phase()) {
            assert!(dist(c, hands) < 0.01, "a held frame starts with the box {:.3} m off the hands", dist(c, hands));
            held += 1;
        } else {
            let pl = w.placements()[ped];
            assert!((c[0] - pl.pos[0]).abs() < 1e-6 && (c[1] - pl.pos[1]).abs() < 1e-6);
            assert!((c[2] - (pl.top + 0.15)).abs() < 0.01, "box centre {} on a {} top", c[2], pl.top);
            on_pedestal += 1;
        }
    }
    assert!(held > 0 && on_pedestal > 0, "{held} held starts, {on_pedestal} on the pedestal");

    // At the clip's end the box is held at the chest: raised and between the hands.
    let mut task = ImitationTask::new(s.settings.clone());
    let last = s.settings.reference.frames() - 1;
    task.place_at_frame(env.world_mut(), last, 0.0, 0.0, 0.3);
    let (c, hands) = object_and_hands(env.world(), obj.prop);
    assert!(dist(c, hands) < 0.01);
    let up = task.score(env.world(), last);
    assert!(up.terms[OBJECT] > 0.5, "a box held at the chest counts as lifted: {:?}", up.terms);
    assert!(!up.terminated);
    // The same pose with the box still on the pedestal scores less and is not lifted.
    let pl = env.world().placements()[ped];
    env.world_mut()
        .set_free_prop(obj.prop, [pl.pos[0], pl.pos[1], pl.top + 0.15], [1.0, 0.0, 0.0, 0.0], [0.0; 3], [0.0; 3])
        .unwrap();
    let down = task.score(env.world(), last);
    assert!(down.terms[GOAL] < up.terms[GOAL] - 0.3, "{} vs {}", down.terms[GOAL], up.terms[GOAL]);
    assert!(down.terms[OBJECT] < 0.5 && !down.terminated);
    // On the floor: dropped, which ends the episode with no reward.
    env.world_mut().set_free_prop(obj.prop, [3.0, 3.0, 0.149], [1.0, 0.0, 0.0, 0.0], [0.0; 3], [0.0; 3]).unwrap();
    let dropped = task.score(env.world(), last);
    assert!(dropped.terminated && dropped.reward == 0.0 && dropped.terms[OBJECT] < 0.5, "{dropped:?}");
}

#[test]
fn carry_prefers_the_box_between_the_hands_to_the_box_on_the_floor() {
    let s = setup("carry.ron");
    let obj = s.settings.object.clone().expect("object");
    let mut env = s.env();
    let mut rng = EnvRng::seed_from_u64(4);
    let mut obs = vec![0.0; env.obs_dim()];
    for _ in 0..10 {
        env.reset(&mut rng, &mut obs);
        let (c, hands) = object_and_hands(env.world(), obj.prop);
        assert!(dist(c, hands) < 0.01, "carry starts with the box in the hands");
        // The arms are held round the box in every frame of the walk.
        let r = &s.settings.reference;
        let f = env.task().phase();
        let [l, rt, ..] = r.end_effectors[f];
        let gap = dist(l, rt);
        assert!((0.33..0.40).contains(&gap), "hands {gap:.3} m apart at frame {f}");
    }
    let mut task = ImitationTask::new(s.settings.clone());
    task.place_at_frame(env.world_mut(), 10, 0.0, 0.0, 0.0);
    let held = task.score(env.world(), 10);
    assert!(held.terms[OBJECT] > 0.5 && !held.terminated, "{:?}", held.terms);
    assert_eq!(env.world().grip(), 1.0, "carry grips (the spec's `grip`), set at every episode start");
    // Hanging from one hand, 0.25 m below the hands' midpoint: off the floor, yet not carried
    // between the hands (`hold_m: 0.2`), so the episode ends as for a drop.
    let (_, hands) = object_and_hands(env.world(), obj.prop);
    let below = [hands[0], hands[1], hands[2] - 0.25];
    env.world_mut().set_free_prop(obj.prop, below, [1.0, 0.0, 0.0, 0.0], [0.0; 3], [0.0; 3]).unwrap();
    let slipped = task.score(env.world(), 10);
    assert!(slipped.terminated && slipped.reward == 0.0 && slipped.terms[OBJECT] < 0.5, "{slipped:?}");
    let just = [hands[0], hands[1], hands[2] - 0.15];
    env.world_mut().set_free_prop(obj.prop, just, [1.0, 0.0, 0.0, 0.0], [0.0; 3], [0.0; 3]).unwrap();
    assert!(!task.score(env.world(), 10).terminated, "0.15 m off the midpoint is still held");
    env.world_mut().set_free_prop(obj.prop, [2.0, 0.0, 0.149], [1.0, 0.0, 0.0, 0.0], [0.0; 3], [0.0; 3]).unwrap();
    let floor = task.score(env.world(), 10);
    assert!(floor.terminated && floor.reward < held.reward && floor.terms[GOAL] < held.terms[GOAL]);
}

#[test]
fn put_down_rewards_the_box_resting_on_the_pedestal_and_released() {
    let s = setup("put_down.ron");
    let obj = s.settings.object.clone().expect("object");
    let (ped, g) = obj.pedestal.expect("pedestal");
    let mut env = s.env();
    let mut task = ImitationTask::new(s.settings.clone());
    // Before the release the box starts in the hands.
    task.place_at_frame(env.world_mut(), 5, 0.0, 0.0, -1.0);
    let (c, hands) = object_and_hands(env.world(), obj.prop);
    assert!(dist(c, hands) < 0.01);
    let carrying = task.score(env.world(), 5);
    assert!(carrying.terms[OBJECT] < 0.5);
    // At the end of the clip (hands off, standing) the box rests on the pedestal: let it settle.
    let last = s.settings.reference.frames() - 1;
    assert!(last > g);
    task.place_at_frame(env.world_mut(), last, 0.0, 0.0, -1.0);
    let mut w = env.world().model().new_world();
    w.restore(&{
        let mut snap = Vec::new();
        env.world().snapshot(&mut snap);
        snap
    })
    .unwrap();
    let ctrl: Vec<f64> = s.settings.reference.joints_at(last).to_vec();
    for _ in 0..30 {
        w.step(&ctrl).unwrap();
    }
    let contacts = w.prop_contact_count(obj.prop, ped);
    assert!(contacts >= 4, "the box rests on the pedestal with {contacts} contacts");
    let placed = task.score(&w, last);
    assert!(placed.terms[OBJECT] > 0.5 && (placed.terms[GOAL] - 1.0).abs() < 1e-6, "{:?}", placed.terms);
    assert!(placed.terms[GOAL] > carrying.terms[GOAL]);
}

#[test]
fn catch_throws_the_ball_at_the_hands_and_ends_when_it_lands() {
    let s = setup("catch.ron");
    let obj = s.settings.object.clone().expect("object");
    let c = obj.catch_frame.expect("catch frame");
    let r = &s.settings.reference;
    let mut env = s.env();
    let mut task = ImitationTask::new(s.settings.clone());
    // From the clip's start: the ball is in flight and passes the clip's catch point when the
    // clip catches (the body stands still with its arms down, out of the way).
    task.place_at_frame(env.world_mut(), 0, 0.0, 0.0, 0.0);
    let mut w = env.world().model().new_world();
    let mut snap = Vec::new();
    env.world().snapshot(&mut snap);
    w.restore(&snap).unwrap();
    let (ball0, _) = object_and_hands(&w, obj.prop);
    assert!(ball0[0] > 1.0, "the ball starts in front: {ball0:?}");
    // The policy sees it coming: towards the character at the drawn speed (2–4 m/s), rising.
    let v = w.prop_velocity_relative(obj.prop);
    assert!((-4.1..-1.9).contains(&v[0]) && v[1].abs() < 0.3 && v[2] > 0.0, "ball velocity {v:?}");
    let target = [r.hands[c][0] - r.root_pos[0][0], r.hands[c][1] - r.root_pos[0][1], r.hands[c][2]];
    let ctrl = r.joints_at(0).to_vec();
    let mut closest = f64::INFINITY;
    for _ in 0..c + 3 {
        w.step(&ctrl).unwrap();
        let (b, _) = object_and_hands(&w, obj.prop);
        closest = closest.min(dist(b, target));
    }
    assert!(closest < 0.1, "the ball passes {closest:.3} m from the catch point");
    // Caught (at a frame past the catch): in the hands, counted as caught.
    let f = r.frames() - 1;
    task.place_at_frame(env.world_mut(), f, 0.0, 0.0, 0.0);
    let caught = task.score(env.world(), f);
    assert!(caught.terms[OBJECT] > 0.5 && !caught.terminated, "{:?}", caught.terms);
    // In the air far from the hands: less goal, not caught, not over.
    env.world_mut().set_free_prop(obj.prop, [2.0, 0.0, 1.5], [1.0, 0.0, 0.0, 0.0], [0.0; 3], [0.0; 3]).unwrap();
    let away = task.score(env.world(), f);
    assert!(away.terms[GOAL] < caught.terms[GOAL] - 0.3 && away.terms[OBJECT] < 0.5 && !away.terminated);
    // On the floor: the episode ends.
    env.world_mut().set_free_prop(obj.prop, [2.0, 0.0, 0.119], [1.0, 0.0, 0.0, 0.0], [0.0; 3], [0.0; 3]).unwrap();
    let landed = task.score(env.world(), f);
    assert!(landed.terminated && landed.terms[GOAL] == 0.0, "{landed:?}");
}

#[test]
fn catch_toss_throws_as_the_toss_does_and_the_ball_arrives_when_it_arrives() {
    let s = setup("catch_toss.ron");
    assert_eq!(s.spec.spec.grip, 1.0, "catch_toss grips");
    let obj = s.settings.object.clone().expect("object");
    let c = obj.catch_frame.expect("catch frame");
    let r = &s.settings.reference;
    let dt = 1.0 / f64::from(s.model.scenario.scenario.rates.control_hz);
    let mut env = s.env();
    let mut task = ImitationTask::new(s.settings.clone());
    let mut arrivals = Vec::new();
    // Starts before the catch throw (each frame draws its own throw).
    for f in 0..6 {
        task.place_at_frame(env.world_mut(), f, 0.0, 0.0, 0.0);
        let mut w = env.world().model().new_world();
        let mut snap = Vec::new();
        env.world().snapshot(&mut snap);
        w.restore(&snap).unwrap();
        let target = [r.hands[c][0] - r.root_pos[f][0], r.hands[c][1] - r.root_pos[f][1], r.hands[c][2]];
        let (ball0, _) = object_and_hands(&w, obj.prop);
        // Launched from the toss's distance (2.8–3.2 m in front of the catch point; `target`
        // is the clip's catch point to within a few cm), not from wherever its speed would
        // have had it arrive at the clip's catch.
        let (d, slack) = (ball0[0] - target[0], 0.1);
        assert!(
            (2.8 - slack..=3.2 + slack).contains(&d) && (ball0[1] - target[1]).abs() < slack,
            "frame {f}: launched {d:.3} m out: {ball0:?}"
        );
        let v = w.prop_velocity_relative(obj.prop);
        let v_x = -v[0];
        assert!((1.5..=4.5).contains(&v_x) && v[1].abs() <= 0.75 + 1e-9, "frame {f}: ball velocity {v:?}");
        // It crosses the catch point's line at d / v_x, the toss's t_hit.
        let ctrl = r.joints_at(f).to_vec();
        let mut crossed = None;
        for k in 1..=((d / v_x / dt) as usize + 10) {
            w.step(&ctrl).unwrap();
            let (b, _) = object_and_hands(&w, obj.prop);
            if b[0] <= target[0] {
                crossed = Some(k as f64 * dt);
                break;
            }
        }
        let t = crossed.expect("the ball reaches the catch point's line");
        assert!((t - d / v_x).abs() <= slack / v_x + dt, "frame {f}: crossed at {t:.3} s, t_hit {:.3} s", d / v_x);
        arrivals.push(f as f64 * dt + t);
    }
    // Not at the clip's catch every time: the arrivals spread with the throws.
    let (lo, hi) = arrivals.iter().fold((f64::INFINITY, 0.0f64), |(lo, hi), &t| (lo.min(t), hi.max(t)));
    assert!(hi - lo > 0.1, "every ball arrives at {lo:.3}–{hi:.3} s (the clip catches at {:.3} s)", c as f64 * dt);
}

#[test]
fn a_tiny_catch_training_runs_end_to_end() {
    let lib = temp("train");
    let s = setup("catch.ron");
    let opts = TrainOptions::quick(&lib, &lib.join("run"), 2, 4, 3);
    let out = train(&s, &opts).expect("train");
    assert_eq!(out.history.len(), 2);
    let csv = std::fs::read_to_string(out.run_dir.join("metrics.csv")).expect("metrics");
    assert!(csv.lines().next().unwrap_or("").contains("object"), "{csv}");
    let skill = library::load(&lib, "catch").expect("load");
    skill.check_fits(&s.model).expect("fits its scene");
}

#[test]
fn mocap_variants_parse_and_build_on_the_shipped_mocap() {
    for spec in ["lift_115_06.ron", "carry_113_26.ron"] {
        let file = SpecFile::load(&specs().join(spec)).expect("the variant parses");
        let clip = file.resolve(&file.spec.clip.file);
        assert!(clip.exists(), "{spec}: its clip {} ships in the repository's mocap/", clip.display());
        let s = SkillSetup::new(file, &temp("mocap")).expect("the variant builds on the real mocap");
        let obj = s.settings.object.clone().expect("object");
        let mut env = s.env();
        let mut task = ImitationTask::new(s.settings.clone());
        let f = obj.held.start + 5;
        task.place_at_frame(env.world_mut(), f, 0.0, 0.0, 0.0);
        let (c, hands) = object_and_hands(env.world(), obj.prop);
        assert!(dist(c, hands) < 0.01, "{spec}: held frame {f} starts with the box in the hands");
        let out = task.score(env.world(), f);
        assert!(out.terms[0] > 0.999 && !out.terminated, "{spec}: {:?}", out.terms);
    }
}

#[test]
fn the_steering_carry_observes_its_target_and_is_paid_for_heading_to_it() {
    let straight = setup("carry.ron");
    let s = setup("carry_to.ron");
    assert_eq!(s.spec.spec.name, "carry", "carry_to.ron trains the library's carry");
    let mut env = s.env();
    assert_eq!(env.obs_dim(), straight.env().obs_dim() + 3, "the target's [sin ψ, cos ψ, distance]");
    let mut task = ImitationTask::new(s.settings.clone());
    // Frame 10 of the walk, at the origin facing +x, moving at the clip's pace.
    let score_with_target = |task: &mut ImitationTask, env: &mut repertoire_skill::SkillEnv, t: [f64; 2]| {
        task.place_at_frame(env.world_mut(), 10, 0.0, 0.0, 0.0);
        task.set_target(t, env.world());
        task.score(env.world(), 10)
    };
    let ahead = score_with_target(&mut task, &mut env, [3.0, 0.0]);
    let behind = score_with_target(&mut task, &mut env, [-3.0, 0.0]);
    let side = score_with_target(&mut task, &mut env, [0.0, 3.0]);
    assert!(!ahead.terminated && ahead.terms[OBJECT] > 0.5, "{:?}", ahead.terms);
    assert!(
        ahead.terms[GOAL] > side.terms[GOAL] && side.terms[GOAL] > behind.terms[GOAL],
        "the goal pays for heading to the target: ahead {} side {} behind {}",
        ahead.terms[GOAL],
        side.terms[GOAL],
        behind.terms[GOAL]
    );
    // Arriving pays the steering part in full and draws the next target 1.5–4 m away.
    let arrived = score_with_target(&mut task, &mut env, [0.2, 0.0]);
    assert_eq!(task.reached, 1);
    assert!(arrived.terms[GOAL] > ahead.terms[GOAL]);
    let p = env.world().pelvis_frame().pos;
    let next = task.target();
    let d = ((next[0] - p[0]).powi(2) + (next[1] - p[1]).powi(2)).sqrt();
    assert!((1.4..4.1).contains(&d), "the next target is {d:.2} m away");
}

#[test]
fn a_skill_is_refused_by_a_spec_whose_goal_gives_it_other_inputs() {
    let lib = temp("steer-lib");
    let s = setup("carry.ron");
    train(&s, &TrainOptions::quick(&lib, &lib.join("run"), 1, 2, 3)).expect("a one-iteration carry trains");
    let mut skill = library::load(&lib, "carry").expect("saved");
    let steer = SkillSetup::new(SpecFile::load(&specs().join("carry_to.ron")).unwrap(), &lib).unwrap();
    let err =
        repertoire_skill::eval::evaluate(&steer, &mut skill, repertoire_skill::eval::StartFrom::ClipStart, 2, 2, 1)
            .expect_err("a straight carry does not fit the steering spec")
            .to_string();
    assert!(err.contains("manifest.ron") && err.contains("carry_to.ron") && err.contains("--warm-start"), "{err}");
}

#[test]
fn a_box_scaled_for_the_episode_gets_the_arms_fitted_round_it() {
    let text = std::fs::read_to_string(specs().join("carry_box.ron")).unwrap();
    let spec = std::fs::read_to_string(specs().join("carry.ron")).unwrap();
    let fixed = "size: (0.3, 0.3, 0.3), mass: 2.0)";
    assert!(text.contains(fixed), "carry_box.ron no longer holds {fixed}");
    for scale in [0.75, 1.0, 1.25] {
        let dir = temp(&format!("scaled-{scale}"));
        let scaled = format!("size: (0.3, 0.3, 0.3), scale: ({scale}, {scale}), mass: 2.0)");
        std::fs::write(dir.join("carry_box.ron"), text.replace(fixed, &scaled)).unwrap();
        std::fs::write(dir.join("carry.ron"), &spec).unwrap();
        let s = SkillSetup::new(SpecFile::load(&dir.join("carry.ron")).unwrap(), &dir).expect("builds");
        let obj = s.settings.object.clone().expect("object");
        let mut env = s.env();
        let mut rng = EnvRng::seed_from_u64(9);
        let mut obs = vec![0.0; env.obs_dim()];
        // The hands reach HOLD_SQUEEZE_M into each side of the box.
        let want = 0.3 * scale - 2.0 * repertoire_skill::imitation::HOLD_SQUEEZE_M;
        for _ in 0..6 {
            env.reset(&mut rng, &mut obs);
            let w = env.world();
            assert_eq!(w.placements()[obj.prop].scale, scale);
            let gap = w.hand_gap();
            assert!((gap - want).abs() < 0.01, "box ×{scale}: hands {gap:.3} m apart, want {want:.3}");
            assert_eq!(w.contacts().hands_on_prop(obj.prop), [true, true], "box ×{scale}: both hands touch it");
            let (c, hands) = object_and_hands(w, obj.prop);
            assert!(dist(c, hands) < 0.01);
            if scale == 1.0 {
                // The box the clip's arms were posed for: they are left as the clip has them.
                let f = env.task().phase();
                let mut q = vec![0.0; w.model().index.dof()];
                w.joint_angles(&mut q);
                let r = &s.settings.reference;
                assert!(q.iter().zip(r.joints_at(f)).all(|(a, b)| (a - b).abs() < 1e-9), "frame {f} untouched");
            }
        }
        let _ = std::fs::remove_dir_all(&dir);
    }
}

#[test]
fn carry_any_box_sees_this_episodes_box_size_and_draws_the_warehouses_boxes() {
    let s = setup("carry_any_box.ron");
    let obj = s.settings.object.clone().expect("object");
    let size = s.layout.entries.iter().find(|e| e.name == "prop_size:box").expect("the size is observed");
    assert_eq!(size.len, 3);
    let mut env = s.env();
    let mut rng = EnvRng::seed_from_u64(12);
    let mut obs = vec![0.0; env.obs_dim()];
    let (mut small, mut large) = (f64::MAX, f64::MIN);
    for _ in 0..12 {
        // The policy's input is normalised; the world's own observation holds the raw size.
        env.reset(&mut rng, &mut obs);
        let w = env.world();
        let scale = w.placements()[obj.prop].scale;
        let mut raw = vec![0.0f32; s.layout.size];
        w.observe(&s.layout, &mut raw);
        for v in &raw[size.offset..size.offset + 3] {
            assert!((f64::from(*v) - 0.3 * scale).abs() < 1e-6, "observed {v}, box ×{scale}");
        }
        assert!((2.0..=7.0).contains(&w.placements()[obj.prop].mass));
        (small, large) = (small.min(scale), large.max(scale));
        assert_eq!(w.contacts().hands_on_prop(obj.prop), [true, true], "box ×{scale} between both hands");
    }
    assert!(small < 0.9 && large > 1.1, "the scale varies over ×0.75–1.25: {small:.2}–{large:.2}");
}

#[test]
fn lift_any_box_moves_its_pedestal_off_the_clip_spot_before_the_grip_only() {
    // The same spec without the jitter puts the pedestal on the clip's spot; episodes drawn from
    // the same seed start alike up to the jitter (spawn, frame and box are drawn before it).
    let text = std::fs::read_to_string(specs().join("lift_any_box.ron")).unwrap();
    let jitter = ", jitter_m: 0.25, jitter_deg: 45.0)";
    assert!(text.contains(jitter), "lift_any_box.ron no longer holds {jitter}");
    let dir = temp("still");
    std::fs::copy(specs().join("pedestal_boxes.ron"), dir.join("pedestal_boxes.ron")).unwrap();
    std::fs::create_dir_all(dir.join("clips")).unwrap();
    std::fs::copy(specs().join("clips/lift.keys.ron"), dir.join("clips/lift.keys.ron")).unwrap();
    std::fs::write(dir.join("lift_any_box.ron"), text.replace(jitter, ")")).unwrap();
    let still = SkillSetup::new(SpecFile::load(&dir.join("lift_any_box.ron")).unwrap(), &dir).expect("builds");
    let moved = setup("lift_any_box.ron");
    let obj = moved.settings.object.clone().expect("object");
    let (ped, grip) = obj.pedestal.expect("pedestal");
    let (mut before, mut after, mut far, mut turned) = (0, 0, 0, 0);
    for seed in 0..40 {
        let mut at = Vec::new();
        for s in [&still, &moved] {
            let mut env = s.env();
            let mut obs = vec![0.0; env.obs_dim()];
            env.reset(&mut EnvRng::seed_from_u64(seed), &mut obs);
            assert!(obs.iter().all(|v| v.is_finite()));
            let w = env.world();
            let (pl, phase) = (w.placements()[ped], env.task().phase());
            let bx = w.placements()[obj.prop];
            if phase < grip {
                // The box sits on the pedestal's top; nothing sinks into the pedestal.
                let (c, _) = object_and_hands(w, obj.prop);
                assert!((c[0] - pl.pos[0]).abs() < 1e-6 && (c[1] - pl.pos[1]).abs() < 1e-6);
                assert!(
                    (c[2] - (pl.top + 0.15 * bx.scale)).abs() < 0.01,
                    "box centre {:.3} on a {:.3} top",
                    c[2],
                    pl.top
                );
                assert!(
                    w.penetration_with_prop(ped, None) <= 0.002,
                    "seed {seed}: the body starts inside the pedestal"
                );
            }
            at.push((pl.pos, pl.yaw, phase));
        }
        let [(p0, y0, f0), (p1, y1, f1)] = [at[0], at[1]];
        assert_eq!(f0, f1, "seed {seed}: the jitter changed the start frame");
        let d = ((p1[0] - p0[0]).powi(2) + (p1[1] - p0[1]).powi(2)).sqrt();
        let turn = (y1 - y0 + std::f64::consts::PI).rem_euclid(std::f64::consts::TAU) - std::f64::consts::PI;
        if f0 < grip {
            // At most 0.25 m off, scaled down towards the grip, and at most 20 cm more pushed clear.
            let s = (grip - f0) as f64 / grip as f64;
            assert!(d <= 0.25 * s + 0.2 + 1e-9, "seed {seed} frame {f0}: {d:.3} m off");
            assert!(turn.abs() <= 45f64.to_radians() * s + 1e-9, "seed {seed} frame {f0}: turned {turn:.3}");
            before += 1;
            far += usize::from(d > 0.1);
            turned += usize::from(turn.abs() > 15f64.to_radians());
        } else {
            assert!(d < 1e-9 && turn.abs() < 1e-9, "seed {seed}: a held start (frame {f0}) moved the pedestal");
            after += 1;
        }
    }
    assert!(before > 5 && after > 5, "{before} starts before the grip, {after} after");
    assert!(far > 0 && turned > 0, "the jitter moved {far} and turned {turned} of {before} pedestals noticeably");
    let _ = std::fs::remove_dir_all(&dir);
}
