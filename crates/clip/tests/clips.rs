//! Every file in the repository's mocap/ imports and retargets onto the built-in humanoid; clip
//! operations, files, keyframes and bad inputs.

use repertoire_clip::map::LoadedMap;
use repertoire_clip::{
    Clip, ClipBody, ClipSource, LoadedKeyframes, MotionMeasures, RetargetOptions, Retargeted, import, retarget,
};
use std::path::{Path, PathBuf};
use std::sync::OnceLock;

const MOCAP: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/../../mocap");
const KEYFRAMES: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/keyframes");
/// Retarget at most this many seconds of each file (keeps the test fast in the dev profile).
const MAX_SECONDS: f64 = 4.0;

fn body() -> &'static ClipBody {
    static BODY: OnceLock<ClipBody> = OnceLock::new();
    BODY.get_or_init(|| ClipBody::humanoid().expect("built-in humanoid"))
}

fn in_mocap(rel: &str) -> PathBuf {
    Path::new(MOCAP).join(rel)
}

fn temp_dir(test: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("repertoire-clip-{}-{test}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).expect("temp dir");
    dir
}

/// Imports and retargets the first `MAX_SECONDS` of a file in mocap/.
fn retargeted(rel: &str) -> Retargeted {
    let path = in_mocap(rel);
    let source = ClipSource::from_path(&path, None).expect("known type");
    let (mut mocap, map) = import(&source, None).unwrap_or_else(|e| panic!("{rel}: {e}"));
    let keep = ((MAX_SECONDS / mocap.motion.frame_time).round() as usize).max(2);
    if mocap.motion.frame_count() > keep {
        let n = keep * mocap.motion.joint_count;
        mocap.motion.translations.truncate(n);
        mocap.motion.rotations.truncate(n);
        mocap.motion.raw = None;
    }
    retarget(&mocap, &path, &map, body(), &RetargetOptions::default()).unwrap_or_else(|e| panic!("{rel}: {e}"))
}

fn all_mocap_files() -> Vec<String> {
    let mut out = Vec::new();
    for dir in std::fs::read_dir(MOCAP).expect("the repository's mocap/ folder exists") {
        let dir = dir.unwrap().path();
        if !dir.is_dir() {
            continue;
        }
        for f in std::fs::read_dir(&dir).unwrap() {
            let f = f.unwrap().path();
            let ext = f.extension().and_then(|e| e.to_str()).unwrap_or("");
            if matches!(ext, "bvh" | "amc" | "txt") {
                out.push(f.strip_prefix(MOCAP).unwrap().to_string_lossy().into_owned());
            }
        }
    }
    out.sort();
    out
}

#[test]
fn every_mocap_file_retargets_onto_the_humanoid() {
    let files = all_mocap_files();
    assert!(files.len() >= 15, "expected the 15 motion files of mocap/, found {files:?}");
    let mut frames = 0;
    let mut seconds = 0.0;
    for rel in &files {
        let rt = retargeted(rel);
        let (points, (mean_cm, max_cm)) = repertoire_clip::check::point_errors(&rt);
        // Bound: mean key-point error under 4 cm on every file (observed 0.2–2.5 cm).
        assert!(mean_cm < 4.0, "{rel}: mean key-point error {mean_cm:.2} cm; {points:?}");
        assert!(max_cm < 40.0, "{rel}: max key-point error {max_cm:.2} cm");
        let m = MotionMeasures::of(&rt.clip, body()).unwrap();
        assert!(m.foot_penetration_cm <= 1.0, "{rel}: feet {:.2} cm below the floor", m.foot_penetration_cm);
        rt.clip.validate().unwrap();
        rt.clip.check_body(body()).unwrap();
        frames += rt.clip.frame_count();
        seconds += rt.seconds;
    }
    eprintln!("retargeted {frames} frames in {seconds:.2} s ({:.0} frames/s)", frames as f64 / seconds);
}

#[test]
fn cmu_walks_keep_the_pelvis_level() {
    // The hip joints sit in front of the source's root and lumbar spine; maps that put those on
    // the body's axis tipped the pelvis back through every walk (cgspeed's 113_26 by 15.7° on
    // average, subject 16's 16_15 by 12.5°). A walking pelvis stays within a few degrees of level.
    for rel in ["cmu-120fps/113_26_walk_and_carry.bvh", "cmu-subject16-30fps/16_15_walk.bvh"] {
        let m = MotionMeasures::of(&retargeted(rel).clip, body()).unwrap();
        let (mean, low, high) = m.pelvis_pitch_deg;
        assert!(
            mean.abs() < 4.0 && low > -15.0 && high < 15.0,
            "{rel}: pelvis pitch {mean:.1}° ({low:.1}° to {high:.1}°)"
        );
    }
}

fn heading_change(clip: &Clip) -> f64 {
    clip.features(body()).unwrap().heading_change().to_degrees()
}

#[test]
fn turn_clips_have_the_right_heading_sign() {
    for (rel, sign) in [
        ("cmu-subject16-30fps/16_17_walk_90deg_left_turn.bvh", 1.0),
        ("cmu-subject16-30fps/16_19_walk_90deg_right_turn.bvh", -1.0),
        ("deepmimic-format/pybullet_walker_turn_left0.txt", 1.0),
        ("deepmimic-format/pybullet_walker_turn_left1.txt", 1.0),
        ("deepmimic-format/pybullet_walker_turn_right0.txt", -1.0),
        ("deepmimic-format/pybullet_walker_turn_right1.txt", -1.0),
    ] {
        let h = heading_change(&retargeted(rel).clip);
        assert!(h * sign > 20.0, "{rel}: heading change {h:+.1}°");
    }
}

#[test]
fn mirror_is_an_involution_and_turns_left_into_right() {
    let clip = retargeted("cmu-subject16-30fps/16_17_walk_90deg_left_turn.bvh").clip;
    let m = clip.mirrored(body()).unwrap();
    let mm = m.mirrored(body()).unwrap();
    let diff = clip.qpos.iter().zip(&mm.qpos).fold(0.0f64, |d, (a, b)| d.max((a - b).abs()));
    assert!(diff <= 1e-9, "mirror∘mirror differs by {diff}");
    let (h, hm) = (heading_change(&clip), heading_change(&m));
    assert!(h > 60.0 && hm < -60.0, "left turn {h:+.1}°, mirrored {hm:+.1}°");
    assert!((h + hm).abs() < 1.0, "mirrored heading change {hm} is not −{h}");
    // Mirroring keeps the feet out of the floor (the body is symmetric).
    assert!(MotionMeasures::of(&m, body()).unwrap().foot_penetration_cm < 1.0);
}

#[test]
fn reverse_cut_resample_and_loop() {
    let clip = retargeted("deepmimic-format/pybullet_walker_walk_forward.txt").clip;
    assert_eq!(clip.reversed().reversed(), clip);
    let n = clip.frame_count();
    assert_eq!(clip.reversed().frame(0), clip.frame(n - 1));

    let cut = clip.cut(5, 15).unwrap();
    assert_eq!(cut.frame_count(), 10);
    assert_eq!(cut.frame(0), clip.frame(5));
    assert!(clip.cut(10, 10).is_err() && clip.cut(0, n + 1).is_err());

    let up = clip.resampled(2.0 * clip.fps).unwrap();
    assert_eq!(up.frame_count(), 2 * (n - 1) + 1);
    assert_eq!(up.frame(2), clip.frame(1));
    for f in 0..up.frame_count() {
        let q = &up.frame(f).unwrap()[3..7];
        assert!((q.iter().map(|v| v * v).sum::<f64>() - 1.0).abs() < 1e-9);
    }
    let down = clip.resampled(clip.fps / 2.0).unwrap();
    assert_eq!(down.frame(1), clip.frame(2));

    let looped = clip.looped(3).unwrap();
    assert!(looped.looping);
    assert_eq!(looped.frame_count(), 3 * (n - 1) + 1);
    let f = clip.features(body()).unwrap();
    let lf = looped.features(body()).unwrap();
    // The root keeps going: three cycles travel about three times as far and turn three times as much.
    let drift = |c: &Clip| MotionMeasures::of(c, body()).unwrap().root_drift_m;
    assert!(
        (drift(&looped) - 3.0 * drift(&clip)).abs() < 0.15 * drift(&clip),
        "{} vs {}",
        drift(&looped),
        drift(&clip)
    );
    assert!((lf.heading_change() - 3.0 * f.heading_change()).abs() < 0.05);
    // Seamless: joint angles across a cycle boundary move no more than within a cycle.
    let step = |c: &Clip, i: usize| {
        let (a, b) = (c.frame(i).unwrap(), c.frame(i + 1).unwrap());
        (7..c.nq).map(|k| (a[k] - b[k]).abs()).fold(0.0, f64::max)
    };
    let within = (0..n - 1).map(|i| step(&clip, i)).fold(0.0, f64::max);
    assert!(step(&looped, n - 2) <= within + 0.05 && step(&looped, n - 1) <= within + 0.05);
}

#[test]
fn features_have_one_row_per_frame() {
    let clip = retargeted("cmu-subject16-30fps/16_15_walk.bvh").clip;
    let f = clip.features(body()).unwrap();
    let n = clip.frame_count();
    assert_eq!(f.qvel.len(), n * body().nv());
    assert_eq!((f.com.len(), f.end_effectors.len(), f.heading.len()), (n, n, n));
    // Walking forward: mean root speed in +x of roughly 1–1.8 m/s, the centre of mass at hip height.
    let vx = f.root_linear_velocity.iter().map(|v| v[0]).sum::<f64>() / n as f64;
    assert!((0.8..2.0).contains(&vx), "mean forward speed {vx}");
    assert!(f.com.iter().all(|c| (0.8..1.2).contains(&c[2])), "com heights");
    assert!(f.qvel.iter().chain(f.root_angular_velocity.iter().flatten()).all(|v| v.is_finite()));
}

#[test]
fn clips_round_trip_through_ron_and_npy() {
    let dir = temp_dir("round-trip");
    let clip = retargeted("cmu-subject16-30fps/16_33_slow_walk_stop.bvh").clip;
    for name in ["walk.clip.ron", "walk.npy"] {
        let path = dir.join(name);
        clip.save(&path).unwrap();
        let back = Clip::load(&path).unwrap();
        assert_eq!(back.qpos, clip.qpos, "{name}: values differ");
        assert_eq!(back.content_hash(), clip.content_hash(), "{name}");
        assert_eq!(
            (back.fps, back.nq, &back.body_hash, back.looping),
            (clip.fps, clip.nq, &clip.body_hash, clip.looping)
        );
    }
    assert!(dir.join("walk.meta.ron").exists());
    let mut other = clip.clone();
    other.qpos[40] += 1e-12;
    assert_ne!(other.content_hash(), clip.content_hash());
    // No temporary files are left behind.
    let leftovers: Vec<_> = std::fs::read_dir(&dir)
        .unwrap()
        .filter_map(|e| e.ok())
        .filter(|e| e.file_name().to_string_lossy().contains("partial"))
        .collect();
    assert!(leftovers.is_empty());
}

#[test]
fn nan_frames_short_clips_and_width_mismatches_are_rejected() {
    let dir = temp_dir("bad-clips");
    let clip = retargeted("deepmimic-format/pybullet_walker_walk_forward.txt").clip;
    let mut nan = clip.clone();
    nan.qpos[5 * clip.nq + 9] = f64::NAN;
    let msg = nan.validate().unwrap_err().to_string();
    assert!(msg.contains("frame 5"), "{msg}");
    // From a file, the message names the file and the frame.
    let npy = dir.join("nan.npy");
    clip.save(&npy).unwrap();
    std::fs::write(&npy, repertoire_clip::io::npy_bytes(&nan.qpos, nan.frame_count(), nan.nq)).unwrap();
    let msg = Clip::load(&npy).unwrap_err().to_string();
    assert!(msg.contains("nan.npy") && msg.contains("frame 5"), "{msg}");

    let short = clip.cut(0, 2).unwrap();
    let mut one = short.clone();
    one.qpos.truncate(clip.nq);
    assert!(one.validate().unwrap_err().to_string().contains("too short"));

    let mut narrow = clip.clone();
    narrow.nq = 30;
    narrow.qpos.truncate(30 * 10);
    let msg = narrow.check_body(body()).unwrap_err().to_string();
    assert!(msg.contains("30") && msg.contains("32"), "{msg}");

    // A BVH with a NaN channel value: the parser names the frame.
    let bvh = dir.join("nan.bvh");
    let text = std::fs::read_to_string(in_mocap("cmu-subject16-30fps/16_15_walk.bvh")).unwrap();
    let motion = text.find("Frame Time").unwrap();
    let lines: Vec<&str> = text[motion..].lines().collect();
    let bad_line = lines[3];
    let first = bad_line.split_whitespace().next().unwrap();
    let broken = text.replacen(bad_line, &bad_line.replacen(first, "nan", 1), 1);
    std::fs::write(&bvh, broken).unwrap();
    let source = ClipSource::from_path(&bvh, None).unwrap();
    let msg = repertoire_clip::check(&source, body(), None, None, &RetargetOptions::default()).unwrap_err().to_string();
    assert!(msg.contains("nan.bvh") && msg.contains("frame 2"), "{msg}");
}

#[test]
fn maps_naming_missing_joints_or_bodies_are_rejected_with_file_and_line() {
    let dir = temp_dir("bad-maps");
    let good = repertoire_clip::map::SHIPPED.iter().find(|(n, _)| n.starts_with("cmu-subject16")).unwrap().1;
    let path = in_mocap("cmu-subject16-30fps/16_15_walk.bvh");
    let source = ClipSource::from_path(&path, None).unwrap();

    let bad = dir.join("bad-joint.ron");
    std::fs::write(&bad, good.replace("\"ltibia\"", "\"lshin\"")).unwrap();
    let line = good.lines().position(|l| l.contains("\"ltibia\"")).unwrap() + 1;
    let msg = import(&source, Some(LoadedMap::load(&bad).unwrap())).unwrap_err().to_string();
    assert!(msg.contains("bad-joint.ron") && msg.contains(&format!(":{line}:")) && msg.contains("`lshin`"), "{msg}");

    let bad = dir.join("bad-body.ron");
    std::fs::write(&bad, good.replace("\"left_shin\"", "\"left_calf\"")).unwrap();
    let line = good.lines().position(|l| l.contains("\"left_shin\"")).unwrap() + 1;
    let (mocap, map) = import(&source, Some(LoadedMap::load(&bad).unwrap())).unwrap();
    let msg = retarget(&mocap, &path, &map, body(), &RetargetOptions::default()).unwrap_err().to_string();
    assert!(msg.contains("bad-body.ron") && msg.contains(&format!(":{line}:")) && msg.contains("`left_calf`"), "{msg}");

    // The default map is detected from the joint names; a skeleton no map fits is an error.
    let dm = ClipSource::from_path(&in_mocap("deepmimic-format/pybullet_walker_walk_forward.txt"), None).unwrap();
    assert_eq!(import(&dm, None).unwrap().1.map.name, "deepmimic-humanoid3d");
    let msg = import(&source, Some(repertoire_clip::map::shipped().unwrap().remove(5))).unwrap_err().to_string();
    assert!(msg.contains("DeepMimic"), "{msg}");
}

#[test]
fn keyframe_clips_load_and_do_what_they_say() {
    for name in ["catch", "lift"] {
        let kf = LoadedKeyframes::load(&Path::new(KEYFRAMES).join(format!("{name}.ron"))).unwrap();
        let clip = kf.to_clip(body()).unwrap();
        clip.check_body(body()).unwrap();
        assert_eq!(clip.name, name);
        let m = MotionMeasures::of(&clip, body()).unwrap();
        assert!(m.foot_penetration_cm < 0.01 && m.root_drift_m < 0.01, "{name}: {m:?}");
        let f = clip.features(body()).unwrap();
        let at = |t: f64| ((t * clip.fps).round() as usize).min(clip.frame_count() - 1);
        let [lh, rh, ..] = f.end_effectors[at(0.0)];
        assert!(lh[2] < 1.0 && rh[2] < 1.0, "{name}: hands hang at the start");
        if name == "catch" {
            // Reaching: both hands above the head's joint and in front of the body.
            let ee = f.end_effectors[at(0.75)];
            assert!(ee[0][2] > ee[4][2] && ee[1][2] > ee[4][2] && ee[0][0] > 0.1, "{ee:?}");
            // Caught: hands close together in front of the chest.
            let [l, r, ..] = f.end_effectors[at(2.0)];
            assert!((l[1] - r[1]).abs() < 0.3 && l[0] > 0.05 && (1.0..1.5).contains(&l[2]), "{l:?} {r:?}");
        } else {
            // Squatting: hands low, near the floor in front of the feet.
            let [l, _, lf, ..] = f.end_effectors[at(1.2)];
            assert!(l[2] < 0.45 && l[0] > lf[0], "{l:?} {lf:?}");
        }
    }
    // A mirrored catch is still a catch (the body is symmetric).
    let kf = LoadedKeyframes::load(&Path::new(KEYFRAMES).join("catch.ron")).unwrap();
    let clip = kf.to_clip(body()).unwrap();
    let m = clip.mirrored(body()).unwrap();
    let diff = clip.qpos.iter().zip(&m.qpos).fold(0.0f64, |d, (a, b)| d.max((a - b).abs()));
    assert!(diff < 1e-9, "the symmetric catch changes under mirroring by {diff}");
}

#[test]
fn keyframes_with_unknown_joints_are_located() {
    let text = "KeyframeClip(\n  name: \"x\",\n  keys: [\n    (t: 0.0),\n    (t: 1.0, joints: {\"left_wrist\": 10.0}),\n  ],\n)\n";
    let kf = LoadedKeyframes::parse(Path::new("wave.ron"), text.to_string()).unwrap();
    let msg = kf.to_clip(body()).unwrap_err().to_string();
    assert!(msg.starts_with("wave.ron:5:") && msg.contains("`left_wrist`"), "{msg}");
    let one = "KeyframeClip(name: \"x\", keys: [(t: 0.0)])";
    let msg =
        LoadedKeyframes::parse(Path::new("one.ron"), one.into()).unwrap().to_clip(body()).unwrap_err().to_string();
    assert!(msg.contains("at least 2"), "{msg}");
    let typo = "KeyframeClip(name: \"x\", keyz: [])";
    let msg = LoadedKeyframes::parse(Path::new("typo.ron"), typo.into()).unwrap_err().to_string();
    assert!(msg.contains("typo.ron:1:") && msg.contains("keyz"), "{msg}");
}

#[test]
fn cmu_walks_retarget_onto_dm_controls_cmu_humanoid() {
    // dm_control's CMU humanoid as it ships (scripts/setup.sh fetches it; y up, no free joint,
    // turned upright and stood on the floor by its map), through the scenario that names it, and
    // the committed map from CMU subject 16's BVH onto it. It is the CMU skeleton itself, so
    // the walks fit closely; each keeps the heading change it has on the built-in humanoid.
    let root = Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/../.."));
    let file = root.join("third_party/bodies/dm_control/humanoid_CMU_V2020.xml");
    assert!(file.exists(), "{} is missing: run scripts/setup.sh", file.display());
    let dm = ClipBody::from_arg(root.join("bodies/dm_control_cmu_humanoid.ron").to_str().unwrap()).expect("the body");
    assert_eq!(dm.index.dof(), 56);
    let map = root.join("bodies/dm_control_cmu_humanoid.cmu-subject16.bvh.ron");
    let options = RetargetOptions::default();
    for name in ["16_15_walk.bvh", "16_17_walk_90deg_left_turn.bvh"] {
        let source = ClipSource::from_path(&in_mocap(&format!("cmu-subject16-30fps/{name}")), None).unwrap();
        let on_dm = repertoire_clip::check(&source, &dm, Some(LoadedMap::load(&map).unwrap()), None, &options).unwrap();
        let built_in = repertoire_clip::check(&source, body(), None, None, &options).unwrap();
        let (mean, max) = on_dm.error_cm.unwrap();
        assert!(mean < 1.5 && max < 15.0, "{name}: key-point error mean {mean:.2} cm, max {max:.2} cm");
        let m = &on_dm.motion;
        assert!(m.foot_penetration_cm < 0.01, "{name}: feet {:.3} cm into the floor", m.foot_penetration_cm);
        assert!(m.foot_skate_cm_s < 30.0, "{name}: skate {:.1} cm/s", m.foot_skate_cm_s);
        // Heading change is the pelvis's from the first to the last frame, which swings a few
        // degrees with the gait (16_15: +4.8° on this body, +9.2° on the built-in one).
        let turn = (m.heading_change_deg - built_in.motion.heading_change_deg).abs();
        assert!(
            turn < 6.0,
            "{name}: turns {:.1}° against {:.1}°",
            m.heading_change_deg,
            built_in.motion.heading_change_deg
        );
        assert!((m.root_drift_m - built_in.motion.root_drift_m).abs() < 0.3, "{name}: drift {:.2} m", m.root_drift_m);
    }
}

#[test]
fn of_maps_that_take_a_skeleton_the_best_fitting_one_is_chosen() {
    // Two maps take subject 16's skeleton (every source joint is in it): the shipped one and a
    // copy with the hands' source joints swapped left for right. The fit (key-point error over
    // the first seconds) tells them apart, whichever comes first.
    let shipped =
        LoadedMap::parse(Path::new("cmu-subject16.bvh.ron"), include_str!("../maps/cmu-subject16.bvh.ron").to_string())
            .unwrap();
    let text = shipped
        .text
        .replace("name: \"cmu-subject16-bvh\"", "name: \"swapped\"")
        .replace("source: \"lhand\"", "source: \"SWAP\"")
        .replace("source: \"rhand\"", "source: \"lhand\"")
        .replace("source: \"SWAP\"", "source: \"rhand\"");
    let swapped = LoadedMap::parse(Path::new("swapped.ron"), text).unwrap();
    let source = ClipSource::from_path(&in_mocap("cmu-subject16-30fps/16_15_walk.bvh"), None).unwrap();
    let options = RetargetOptions::default();
    for order in [vec![swapped.clone(), shipped.clone()], vec![shipped.clone(), swapped.clone()]] {
        let first = order[0].map.name.clone();
        let (chosen, fits) = repertoire_clip::check::best_fit(&source, order, body(), &options).unwrap();
        assert_eq!(chosen.map.name, "cmu-subject16-bvh", "{fits:?}");
        assert_eq!(fits[0].0, first);
        let error = |name: &str| fits.iter().find(|(n, _)| n == name).unwrap().1;
        assert!(error("swapped") > 2.0 * error("cmu-subject16-bvh"), "{fits:?}");
    }
}
