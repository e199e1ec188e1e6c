//! Writer round trips (parse → write → parse) and channel orders checked against
//! hand-computed forward kinematics.

use repertoire_mocap::{
    AmcOptions, BvhOptions, BvhWriteOptions, Clip, DeepMimicLayout, LengthUnit, Vec3, parse_bvh, read_amc, read_asf,
    read_bvh, read_deepmimic, write_bvh,
};
use std::path::PathBuf;

const DATA: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/../../mocap");

const BVH_FILES: [&str; 9] = [
    "cmu-subject16-30fps/16_11_walk_veer_left.bvh",
    "cmu-subject16-30fps/16_13_walk_veer_right.bvh",
    "cmu-subject16-30fps/16_15_walk.bvh",
    "cmu-subject16-30fps/16_17_walk_90deg_left_turn.bvh",
    "cmu-subject16-30fps/16_19_walk_90deg_right_turn.bvh",
    "cmu-subject16-30fps/16_33_slow_walk_stop.bvh",
    "cmu-120fps/113_26_walk_and_carry.bvh",
    "retargeted-60fps/115_06_pick_up_box_bend_knees.bvh",
    "bvh-other/mocapbank_sit_down_stand_up.bvh",
];

fn data(rel: &str) -> PathBuf {
    PathBuf::from(DATA).join(rel)
}

/// Formatting with 6 decimals of a degree rounds each angle by at most 5e-7°.
const ANGLE_TOL_RAD: f64 = 2e-6 * std::f64::consts::PI / 180.0;

fn assert_same_clip(a: &Clip, b: &Clip, pos_tol: f64, what: &str) {
    let (sa, sb) = (&a.skeleton, &b.skeleton);
    assert_eq!(sa.len(), sb.len(), "{what}");
    for (ja, jb) in sa.joints.iter().zip(&sb.joints) {
        assert_eq!(ja.name, jb.name, "{what}");
        assert_eq!(ja.parent, jb.parent, "{what}");
        assert!((ja.offset - jb.offset).norm() < pos_tol, "{what}: {}", ja.name);
        match (ja.end_site, jb.end_site) {
            (Some(x), Some(y)) => assert!((x - y).norm() < pos_tol, "{what}"),
            (None, None) => {}
            _ => panic!("{what}: end site of {} differs", ja.name),
        }
    }
    let (ma, mb) = (&a.motion, &b.motion);
    assert_eq!(ma.frame_count(), mb.frame_count(), "{what}");
    assert!((ma.frame_time - mb.frame_time).abs() < 1e-8, "{what}");
    for (i, (qa, qb)) in ma.rotations.iter().zip(&mb.rotations).enumerate() {
        let d = qa.angle_to(*qb);
        assert!(d < ANGLE_TOL_RAD, "{what}: rotation {i} differs by {}°", d.to_degrees());
    }
    for (ta, tb) in ma.translations.iter().zip(&mb.translations) {
        assert!((*ta - *tb).norm() < pos_tol, "{what}: {ta:?} vs {tb:?}");
    }
}

#[test]
fn every_bvh_round_trips_in_metres_and_keeps_its_angles() {
    for rel in BVH_FILES {
        let a = read_bvh(data(rel), &BvhOptions::default()).unwrap();
        let text = write_bvh(&a.skeleton, &a.motion, &BvhWriteOptions::default()).unwrap();
        let b = parse_bvh(text.as_bytes(), &BvhOptions::default()).unwrap();
        assert_eq!(b.units.unit, LengthUnit::Metre, "{rel}: the metre output is recognised");
        assert_same_clip(&a, &b, 1e-6, rel);
        // Same channel layout, and the same Euler angles, not just the same rotations.
        for (ja, jb) in a.skeleton.joints.iter().zip(&b.skeleton.joints) {
            assert_eq!(ja.channels, jb.channels, "{rel}");
        }
        let (ra, rb) = (a.motion.raw.as_ref().unwrap(), b.motion.raw.as_ref().unwrap());
        let mut k = 0;
        for j in &a.skeleton.joints {
            for c in &j.channels {
                if matches!(c, repertoire_mocap::Channel::Rotation(_)) {
                    for f in 0..a.motion.frame_count() {
                        let (x, y) = (ra.frame(f).unwrap()[k], rb.frame(f).unwrap()[k]);
                        assert!((x - y).abs() < 1e-6, "{rel}: frame {f} {} {x} vs {y}", j.name);
                    }
                }
                k += 1;
            }
        }
    }
}

#[test]
fn writing_in_the_source_unit_reproduces_raw_values() {
    let rel = "cmu-subject16-30fps/16_15_walk.bvh";
    let a = read_bvh(data(rel), &BvhOptions::default()).unwrap();
    let opts = BvhWriteOptions { unit: LengthUnit::Centimetre, crlf: true, ..BvhWriteOptions::default() };
    let text = write_bvh(&a.skeleton, &a.motion, &opts).unwrap();
    assert!(text.contains("\r\n"));
    assert!(text.starts_with("HIERARCHY\r\nROOT pelvis\r\n{\r\n\tOFFSET 0.000000 0.000000 0.000000\r\n"));
    let b = parse_bvh(text.as_bytes(), &BvhOptions::default()).unwrap();
    assert_eq!(b.units.unit, LengthUnit::Centimetre);
    let (ra, rb) = (a.motion.raw.unwrap(), b.motion.raw.unwrap());
    for (x, y) in ra.values.iter().zip(&rb.values) {
        assert!((x - y).abs() < 1e-6, "{x} vs {y}");
    }
}

/// World positions of all joints and end sites, frame by frame, joints in name order (BVH
/// writes joints depth-first, which may reorder them).
fn all_positions(c: &Clip) -> Vec<Vec3> {
    let mut order: Vec<usize> = (0..c.skeleton.len()).collect();
    order.sort_by_key(|&i| c.skeleton.joints[i].name.clone());
    (0..c.motion.frame_count())
        .flat_map(|f| {
            let p = c.motion.world_pose(&c.skeleton, f).unwrap();
            order.iter().flat_map(|&i| std::iter::once(p.positions[i]).chain(p.end_sites[i])).collect::<Vec<_>>()
        })
        .collect()
}

#[test]
fn asf_amc_and_deepmimic_export_to_bvh_with_the_same_pose() {
    let asf = read_asf(data("asf-amc/01.asf"), None).unwrap();
    let opts = AmcOptions::default();
    let mut amc = read_amc(data("asf-amc/01_01.amc"), &asf, &opts).unwrap();
    // Keep the test quick: 300 frames are plenty.
    amc.motion.translations.truncate(300 * amc.skeleton.len());
    amc.motion.rotations.truncate(300 * amc.skeleton.len());
    amc.motion.raw = None;
    let dm = read_deepmimic(data("deepmimic-format/pybullet_walker_turn_left1.txt"), &DeepMimicLayout::humanoid3d())
        .unwrap();
    for (what, clip) in [("01_01.amc", amc), ("turn_left1", dm)] {
        let text = write_bvh(&clip.skeleton, &clip.motion, &BvhWriteOptions::default()).unwrap();
        let back = parse_bvh(text.as_bytes(), &BvhOptions::default()).unwrap();
        assert_eq!(back.units.unit, LengthUnit::Metre, "{what}");
        assert_eq!(back.skeleton.len(), clip.skeleton.len(), "{what}");
        assert!(back.skeleton.joints.iter().all(|j| j.channels.len() == 3 || j.channels.len() == 6));
        let (pa, pb) = (all_positions(&clip), all_positions(&back));
        assert_eq!(pa.len(), pb.len(), "{what}");
        for (x, y) in pa.iter().zip(&pb) {
            assert!((*x - *y).norm() < 1e-5, "{what}: {x:?} vs {y:?}");
        }
    }
}

// --- Channel orders against hand-computed rotations. ---

type M3 = [[f64; 3]; 3];

fn rot(axis: char, deg: f64) -> M3 {
    let (s, c) = deg.to_radians().sin_cos();
    match axis {
        'X' => [[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]],
        'Y' => [[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]],
        _ => [[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]],
    }
}

fn mul(a: M3, b: M3) -> M3 {
    let mut m = [[0.0; 3]; 3];
    for (i, row) in m.iter_mut().enumerate() {
        for (j, v) in row.iter_mut().enumerate() {
            *v = (0..3).map(|k| a[i][k] * b[k][j]).sum();
        }
    }
    m
}

fn apply(m: M3, v: [f64; 3]) -> Vec3 {
    let r: Vec<f64> = (0..3).map(|i| (0..3).map(|k| m[i][k] * v[k]).sum()).collect();
    Vec3::new(r[0], r[1], r[2])
}

/// A two-joint chain; `root_order` and `joint_order` are three letters.
fn chain_bvh(root_order: &str, joint_order: &str, frame: &str) -> String {
    let ch = |o: &str| o.chars().map(|c| format!("{c}rotation")).collect::<Vec<_>>().join(" ");
    format!(
        "HIERARCHY\nROOT root\n{{\n\tOFFSET 0 0 0\n\tCHANNELS 6 Xposition Yposition Zposition {}\n\
         \tJOINT arm\n\t{{\n\t\tOFFSET 0 1 0\n\t\tCHANNELS 3 {}\n\t\tEnd Site\n\t\t{{\n\
         \t\t\tOFFSET 0 1 0\n\t\t}}\n\t}}\n}}\nMOTION\nFrames: 1\nFrame Time: 0.1\n{frame}\n",
        ch(root_order),
        ch(joint_order)
    )
}

fn metres() -> BvhOptions {
    BvhOptions { unit: Some(LengthUnit::Metre), skip_first_frame: false }
}

#[test]
fn xyz_and_yxz_orders_compose_in_listed_order() {
    // Root XYZ (90, 90, 0) = Rx(90) Ry(90): the arm's start (0,1,0) goes to (0,0,1).
    // Arm YXZ (90, 90, 0) = Ry(90) Rx(90): the end site goes to (0,1,1).
    let text = chain_bvh("XYZ", "YXZ", "0 0 0 90 90 0 90 90 0");
    let c = parse_bvh(text.as_bytes(), &metres()).unwrap();
    let p = c.motion.world_pose(&c.skeleton, 0).unwrap();
    assert!((p.positions[1] - Vec3::new(0.0, 0.0, 1.0)).norm() < 1e-12, "{:?}", p.positions[1]);
    let end = p.end_sites[1].unwrap();
    assert!((end - Vec3::new(0.0, 1.0, 1.0)).norm() < 1e-12, "{end:?}");
}

#[test]
fn every_order_matches_matrix_products() {
    let orders = ["XYZ", "XZY", "YXZ", "YZX", "ZXY", "ZYX"];
    let (r_angles, j_angles) = ([30.0, -45.0, 60.0], [-20.0, 75.0, 110.0]);
    for ro in orders {
        for jo in orders {
            let frame = format!(
                "1 2 3 {} {} {} {} {} {}",
                r_angles[0], r_angles[1], r_angles[2], j_angles[0], j_angles[1], j_angles[2]
            );
            let c = parse_bvh(chain_bvh(ro, jo, &frame).as_bytes(), &metres()).unwrap();
            let m = |order: &str, a: [f64; 3]| {
                let mut it = order.chars().zip(a).map(|(ax, d)| rot(ax, d));
                let first = it.next().unwrap();
                it.fold(first, mul)
            };
            let root = m(ro, r_angles);
            let arm = mul(root, m(jo, j_angles));
            let base = Vec3::new(1.0, 2.0, 3.0);
            let arm_pos = base + apply(root, [0.0, 1.0, 0.0]);
            let end_pos = arm_pos + apply(arm, [0.0, 1.0, 0.0]);
            let p = c.motion.world_pose(&c.skeleton, 0).unwrap();
            assert!((p.positions[1] - arm_pos).norm() < 1e-12, "{ro} {jo}");
            assert!((p.end_sites[1].unwrap() - end_pos).norm() < 1e-12, "{ro} {jo}");
            // And the writer keeps the order and the angles.
            let text = write_bvh(&c.skeleton, &c.motion, &BvhWriteOptions::default()).unwrap();
            let back = parse_bvh(text.as_bytes(), &metres()).unwrap();
            let raw = back.motion.raw.unwrap();
            let vals = raw.frame(0).unwrap();
            for (k, want) in r_angles.iter().chain(&j_angles).enumerate() {
                assert!((vals[3 + k] - want).abs() < 1e-6, "{ro} {jo}: {vals:?}");
            }
        }
    }
}
