//! Every clip in the repository's mocap/ parses with the expected size, rate and skeleton, and the
//! motion makes physical sense (height, heading).

use repertoire_mocap::{
    AmcOptions, BvhOptions, Clip, DeepMimicLayout, ErrorKind, LengthUnit, UnitBasis, UpAxis, parse_bvh, read_amc,
    read_asf, read_bvh, read_deepmimic,
};
use std::path::PathBuf;

const DATA: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/../../mocap");

fn data(rel: &str) -> PathBuf {
    PathBuf::from(DATA).join(rel)
}

fn bvh(rel: &str) -> Clip {
    read_bvh(data(rel), &BvhOptions::default()).unwrap_or_else(|e| panic!("{e}"))
}

/// (file, frames, fps, joints, guessed unit)
const BVH_FILES: [(&str, usize, f64, usize, LengthUnit); 9] = [
    ("cmu-subject16-30fps/16_11_walk_veer_left.bvh", 133, 30.0, 19, LengthUnit::Centimetre),
    ("cmu-subject16-30fps/16_13_walk_veer_right.bvh", 111, 30.0, 19, LengthUnit::Centimetre),
    ("cmu-subject16-30fps/16_15_walk.bvh", 117, 30.0, 19, LengthUnit::Centimetre),
    ("cmu-subject16-30fps/16_17_walk_90deg_left_turn.bvh", 129, 30.0, 19, LengthUnit::Centimetre),
    ("cmu-subject16-30fps/16_19_walk_90deg_right_turn.bvh", 102, 30.0, 19, LengthUnit::Centimetre),
    ("cmu-subject16-30fps/16_33_slow_walk_stop.bvh", 71, 30.0, 19, LengthUnit::Centimetre),
    ("cmu-120fps/113_26_walk_and_carry.bvh", 1318, 120.0, 31, LengthUnit::Cmu),
    ("retargeted-60fps/115_06_pick_up_box_bend_knees.bvh", 178, 60.0, 16, LengthUnit::Centimetre),
    ("bvh-other/mocapbank_sit_down_stand_up.bvh", 455, 30.0, 19, LengthUnit::Centimetre),
];

#[test]
fn every_bvh_parses_with_expected_shape_and_unit_guess() {
    for (rel, frames, fps, joints, unit) in BVH_FILES {
        let c = bvh(rel);
        assert_eq!(c.motion.frame_count(), frames, "{rel}");
        assert!((c.motion.fps() - fps).abs() < 0.01, "{rel}: {}", c.motion.fps());
        assert_eq!(c.skeleton.len(), joints, "{rel}");
        assert_eq!(c.units.unit, unit, "{rel}");
        assert_eq!(c.units.basis, UnitBasis::Guessed, "{rel}");
        assert_eq!(c.skeleton.up, UpAxis::Y);
        let raw = c.motion.raw.as_ref().unwrap();
        assert_eq!(raw.values.len(), frames * c.skeleton.channel_count(), "{rel}");
    }
}

/// Height of the character in frame `f`: highest minus lowest joint or end site, metres.
fn height(c: &Clip, f: usize) -> f64 {
    let pose = c.motion.world_pose(&c.skeleton, f).unwrap();
    let ys = pose.positions.iter().chain(pose.end_sites.iter().flatten()).map(|p| p.y);
    let (lo, hi) = ys.fold((f64::MAX, f64::MIN), |(lo, hi), y| (lo.min(y), hi.max(y)));
    hi - lo
}

#[test]
fn full_body_bvh_skeletons_are_person_sized_in_metres() {
    for rel in [
        "cmu-subject16-30fps/16_15_walk.bvh",
        "cmu-120fps/113_26_walk_and_carry.bvh",
        "bvh-other/mocapbank_sit_down_stand_up.bvh",
    ] {
        let c = bvh(rel);
        let h = height(&c, 0);
        assert!((1.3..2.1).contains(&h), "{rel}: height {h}");
        let rest = c.skeleton.rest_height();
        assert!((1.3..2.1).contains(&rest), "{rel}: rest height {rest}");
    }
    // 115_06 has no legs, but its hips are about 0.85 m above the floor.
    let c = bvh("retargeted-60fps/115_06_pick_up_box_bend_knees.bvh");
    let hips = c.motion.root_translation(0).unwrap();
    assert!((0.7..1.0).contains(&hips.y), "{hips:?}");
}

#[test]
fn six_channels_on_every_joint_animate_translations() {
    let c = bvh("retargeted-60fps/115_06_pick_up_box_bend_knees.bvh");
    assert!(c.skeleton.joints.iter().all(|j| j.channels.len() == 6));
    // Spine's position channels repeat its offset (0, 10, 0) cm.
    let spine = c.skeleton.joint_index("Spine").unwrap();
    let t = c.motion.frame(5).unwrap().translations[spine];
    assert!((t.y - 0.10).abs() < 1e-6, "{t:?}");
}

#[test]
fn rest_pose_frame_can_be_skipped() {
    let rel = "cmu-120fps/113_26_walk_and_carry.bvh";
    let full = bvh(rel);
    let raw = full.motion.raw.as_ref().unwrap();
    assert!(raw.frame(0).unwrap().iter().all(|v| *v == 0.0), "frame 0 is the rest pose");
    let opts = BvhOptions { skip_first_frame: true, ..BvhOptions::default() };
    let skipped = read_bvh(data(rel), &opts).unwrap();
    assert_eq!(skipped.motion.frame_count(), 1317);
    assert_eq!(skipped.motion.frame(0).unwrap().rotations, full.motion.frame(1).unwrap().rotations);
}

#[test]
fn explicit_unit_is_used_and_reported() {
    let opts = BvhOptions { unit: Some(LengthUnit::Cmu), skip_first_frame: false };
    let c = read_bvh(data("cmu-120fps/113_26_walk_and_carry.bvh"), &opts).unwrap();
    assert_eq!(c.units.basis, UnitBasis::Explicit);
    // LeftUpLeg OFFSET 1.55766 -1.60504 1.11378 CMU units.
    let j = c.skeleton.joint_index("LeftUpLeg").unwrap();
    assert!((c.skeleton.joints[j].offset.x - 1.55766 * 0.056444).abs() < 1e-5);
}

/// Unwrapped change of the root heading about +y from the start to the end of the clip,
/// degrees, averaging 5 frames at each end.
fn heading_change(c: &Clip) -> f64 {
    let n = c.motion.frame_count();
    let mut unwrapped = Vec::with_capacity(n);
    let mut prev: Option<f64> = None;
    for f in 0..n {
        let h = c.motion.root_rotation(f).unwrap().heading(UpAxis::Y);
        let h = match prev {
            Some(p) => repertoire_mocap::math::wrap_near(h, p),
            None => h,
        };
        unwrapped.push(h);
        prev = Some(h);
    }
    let k = 5.min(n);
    let start: f64 = unwrapped[..k].iter().sum::<f64>() / k as f64;
    let end: f64 = unwrapped[n - k..].iter().sum::<f64>() / k as f64;
    (end - start).to_degrees()
}

#[test]
fn heading_turns_left_positive_right_negative() {
    // README: 16_17 turns left 94°, 16_19 right 92°; 16_11 veers left 39°, 16_13 right 49°.
    for (rel, expect) in [
        ("cmu-subject16-30fps/16_17_walk_90deg_left_turn.bvh", 94.0),
        ("cmu-subject16-30fps/16_19_walk_90deg_right_turn.bvh", -92.0),
        ("cmu-subject16-30fps/16_11_walk_veer_left.bvh", 39.0),
        ("cmu-subject16-30fps/16_13_walk_veer_right.bvh", -49.0),
    ] {
        let d = heading_change(&bvh(rel));
        assert!(d.signum() == f64::signum(expect), "{rel}: {d:.1}°");
        assert!((d - expect).abs() < 25.0, "{rel}: {d:.1}° vs {expect}°");
    }
}

#[test]
fn asf_amc_parses_and_stands_upright() {
    let asf = read_asf(data("asf-amc/01.asf"), None).unwrap();
    assert_eq!(asf.units.unit, LengthUnit::Cmu);
    assert_eq!(asf.units.basis, UnitBasis::Declared);
    assert_eq!(asf.skeleton.len(), 31);
    let femur = &asf.skeleton.joints[asf.skeleton.joint_index("lfemur").unwrap()];
    assert_eq!(femur.channels.len(), 3);
    assert_eq!(femur.limits.len(), 3);
    assert!((femur.limits[0].min + 160f64.to_radians()).abs() < 1e-12);

    let clip = read_amc(data("asf-amc/01_01.amc"), &asf, &AmcOptions::default()).unwrap();
    assert_eq!(clip.motion.frame_count(), 2751);
    assert!((clip.motion.fps() - 120.0).abs() < 1e-9);
    assert_eq!(clip.skeleton.channel_count(), 62);

    let s = &clip.skeleton;
    let head = s.joint_index("head").unwrap();
    let lfoot = s.joint_index("lfoot").unwrap();
    let rfoot = s.joint_index("rfoot").unwrap();
    for f in [0, 1000, 2750] {
        let pose = clip.motion.world_pose(s, f).unwrap();
        let p = &pose.positions;
        assert!(p[head].y > p[lfoot].y + 1.0 && p[head].y > p[rfoot].y + 1.0, "frame {f}");
    }
    // Standing height in frame 0: end of the head bone to the lower toe tip. CMU's head bone
    // stops short of the crown, so this reads about 10 cm under the subject's stature.
    let pose = clip.motion.world_pose(s, 0).unwrap();
    let top = pose.end_sites[head].unwrap().y;
    let bottom = pose.end_sites.iter().flatten().map(|p| p.y).fold(f64::MAX, f64::min);
    let h = top - bottom;
    let rest = s.rest_height();
    assert!((1.5..1.9).contains(&h), "height {h}");
    assert!((1.5..1.9).contains(&rest), "rest height {rest}");
    // Thigh: femur length 7.1578 CMU units = 0.404 m.
    let thigh = s.joints[s.joint_index("ltibia").unwrap()].offset.norm();
    assert!((thigh - 7.1578 * 0.056444).abs() < 1e-4, "thigh {thigh}");
}

#[test]
fn deepmimic_walker_clips_parse_and_turn_the_right_way() {
    let layout = DeepMimicLayout::humanoid3d();
    // README: turning per cycle +30°, +56°, −99°, −53°; the walk goes straight.
    for (name, turn) in [
        ("pybullet_walker_walk_forward.txt", 0.0),
        ("pybullet_walker_turn_left0.txt", 30.0),
        ("pybullet_walker_turn_left1.txt", 56.0),
        ("pybullet_walker_turn_right0.txt", -99.0),
        ("pybullet_walker_turn_right1.txt", -53.0),
    ] {
        let c = read_deepmimic(data(&format!("deepmimic-format/{name}")), &layout).unwrap_or_else(|e| panic!("{e}"));
        assert_eq!(c.motion.frame_count(), 38, "{name}");
        assert!((c.motion.fps() - 30.0).abs() < 1e-9, "{name}");
        assert_eq!(c.skeleton.len(), 13, "{name}");
        assert_eq!(c.looping, Some(true), "{name}");
        let h = height(&c, 0);
        assert!((1.2..1.9).contains(&h), "{name}: height {h}");
        let d = heading_change(&c);
        assert!((d - turn).abs() < 20.0, "{name}: turned {d:.1}° vs {turn}°");
    }
}

#[test]
fn crlf_and_lf_give_identical_clips() {
    for (rel, ..) in BVH_FILES {
        let bytes = std::fs::read(data(rel)).unwrap();
        assert!(bytes.windows(2).any(|w| w == b"\r\n"), "{rel} is CRLF");
        let lf: Vec<u8> = bytes.iter().copied().filter(|&b| b != b'\r').collect();
        let a = parse_bvh(&bytes, &BvhOptions::default()).unwrap();
        let b = parse_bvh(&lf, &BvhOptions::default()).unwrap();
        assert_eq!(a, b, "{rel}");
    }
}

#[test]
fn nan_frame_is_rejected_naming_file_line_and_frame() {
    let text = std::fs::read_to_string(data("cmu-subject16-30fps/16_15_walk.bvh")).unwrap();
    let mut lines: Vec<String> = text.split('\n').map(str::to_string).collect();
    // Line 120 (index 119) is frame 0; poison frame 5's fifth value (pelvis Xrotation).
    let mut vals: Vec<String> = lines[124].split(' ').map(str::to_string).collect();
    vals[4] = "nan".into();
    lines[124] = vals.join(" ");
    let poisoned = lines.join("\n");

    let dir = std::env::temp_dir().join(format!("repertoire-mocap-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join("16_15_walk.bvh");
    std::fs::write(&path, poisoned).unwrap();
    let err = read_bvh(&path, &BvhOptions::default()).unwrap_err();
    std::fs::remove_dir_all(&dir).ok();

    assert_eq!(err.kind(), Some(&ErrorKind::NonFinite { frame: 5, field: "pelvis Xrotation".into() }));
    let msg = err.to_string();
    assert!(msg.contains("16_15_walk.bvh:125:"), "{msg}");
    assert!(msg.ends_with("frame 5: non-finite value in pelvis Xrotation"), "{msg}");
}
