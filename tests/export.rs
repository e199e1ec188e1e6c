//! Exports of a real rollout (the committed walk skill, recorded by `skill play`): the BVH
//! re-imports through the project's own parser with the same per-body rotations as MuJoCo's
//! kinematics of the recorded qpos, the same frame count and frame time; the .npy holds qpos.

mod common;

use std::path::Path;
use std::process::{Command, Output};

use repertoire::scenes::{Recording, World};
use repertoire_clip::export::rotation_from_y_up;
use repertoire_mocap::{BvhOptions, LengthUnit, Quat, read_bvh};

fn repertoire(args: &[&str]) -> Output {
    let out = Command::new(env!("CARGO_BIN_EXE_repertoire")).args(args).output().expect("run repertoire");
    assert!(out.status.success(), "{args:?}: {}", String::from_utf8_lossy(&out.stderr));
    out
}

fn q(v: [f64; 4]) -> Quat {
    Quat::new(v[0], v[1], v[2], v[3])
}

#[test]
fn bvh_and_npy_of_a_walk_round_trip() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let dir = common::temp_dir("export");
    let rec_path = dir.join("walk.rec");
    let spec = root.join("specs/walk.ron");
    let lib = root.join("library");
    repertoire(
        &["skill", "play", spec.to_str().unwrap(), "--record", rec_path.to_str().unwrap()]
            .into_iter()
            .chain(["--library", lib.to_str().unwrap(), "--seed", "4"])
            .collect::<Vec<_>>(),
    );
    let (bvh, npy) = (dir.join("walk.bvh"), dir.join("walk.npy"));
    repertoire(&["export", rec_path.to_str().unwrap(), "--bvh", bvh.to_str().unwrap(), "--npy", npy.to_str().unwrap()]);

    let rec = Recording::load(&rec_path).expect("recording");
    assert!(rec.frames() > 100, "{} frames", rec.frames());
    let clip = read_bvh(&bvh, &BvhOptions { unit: Some(LengthUnit::Metre), ..Default::default() }).expect("parse BVH");
    let (sk, motion) = (&clip.skeleton, &clip.motion);
    assert_eq!(motion.frame_count(), rec.frames());
    assert!((motion.frame_time - 1.0 / rec.header.control_hz).abs() < 1e-8, "frame time {}", motion.frame_time);
    let character: Vec<usize> = rec.header.character();
    assert_eq!(sk.len(), character.len());

    // MuJoCo's own kinematics of each recorded qpos: every body's rotation in its parent.
    let model = common::default_model();
    let mut world: World = model.new_world();
    let zeros = vec![0.0; world.data().qvel().len()];
    let mut worst: f64 = 0.0;
    for f in 0..rec.frames() {
        world.set_state(rec.qpos_at(f), &zeros).expect("recorded qpos fits the scene");
        let xquat = world.data().xquat();
        let xpos = world.data().xpos();
        let frame = motion.frame(f).expect("frame");
        for (k, &b) in character.iter().enumerate() {
            let joint = &sk.joints[k];
            assert_eq!(joint.name, rec.header.bodies[b].name);
            let body = b + 1; // the recording leaves the world body out
            let parent = rec.header.bodies[b].parent.map_or(0, |p| p + 1);
            let want = if k == 0 { q(xquat[body]) } else { q(xquat[parent]).conjugate() * q(xquat[body]) };
            let got = rotation_from_y_up(frame.rotations[k]);
            worst = worst.max(got.angle_to(want));
        }
        let t = frame.translations[0];
        let p = xpos[model.index.pelvis];
        let err = ((t.x - p[0]).powi(2) + (t.y - p[2]).powi(2) + (t.z + p[1]).powi(2)).sqrt();
        assert!(err < 1e-5, "frame {f}: root position off by {err} m");
    }
    assert!(worst < 1e-4, "a joint rotation differs by {worst} rad");

    let bytes = std::fs::read(&npy).expect("npy");
    assert_eq!(&bytes[..8], b"\x93NUMPY\x01\x00");
    let header_len = u16::from_le_bytes([bytes[8], bytes[9]]) as usize;
    assert_eq!((10 + header_len) % 64, 0);
    let (rows, cols, values) = repertoire_clip::io::parse_npy(&bytes).expect("valid npy");
    assert_eq!((rows, cols), (rec.frames(), rec.header.nq));
    assert_eq!(values, rec.qpos);
}

#[test]
fn clip_play_records_the_clip_frame_by_frame() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let clip = root.join("third_party/clips/deepmimic/walk_forward.txt");
    assert!(clip.exists(), "{} is missing: run scripts/setup.sh (the clip pack)", clip.display());
    let dir = common::temp_dir("clip-play");
    let (rec_path, bvh) = (dir.join("walk.rec"), dir.join("walk.bvh"));
    repertoire(&["clip", "play", clip.to_str().unwrap(), "--record", rec_path.to_str().unwrap()]);
    let rec = Recording::load(&rec_path).expect("recording");
    assert!(rec.frames() > 30 && rec.header.props.is_empty() && rec.header.ghost.is_none());
    assert!(rec.skill.iter().all(|&s| s == -1));
    for f in [0, rec.frames() / 2, rec.frames() - 1] {
        let (p, _) = rec.pose(f, rec.header.root);
        let q = rec.qpos_at(f);
        assert!((0..3).all(|k| (p[k] - q[k]).abs() < 1e-5), "frame {f}: pelvis {p:?} vs root qpos {:?}", &q[..3]);
        assert!((f64::from(rec.phase[f]) - f as f64).abs() < 1e-9);
    }
    repertoire(&["export", rec_path.to_str().unwrap(), "--bvh", bvh.to_str().unwrap()]);
    let back = read_bvh(&bvh, &BvhOptions { unit: Some(LengthUnit::Metre), ..Default::default() }).expect("parse");
    assert_eq!(back.motion.frame_count(), rec.frames());
}

#[test]
fn replay_and_export_refuse_bad_input_with_the_file_named() {
    let dir = common::temp_dir("replay-bad");
    let run = |args: &[&str]| Command::new(env!("CARGO_BIN_EXE_repertoire")).args(args).output().expect("run");
    let refused = |out: Output, needles: &[&str]| {
        let err = String::from_utf8_lossy(&out.stderr).into_owned();
        assert!(!out.status.success(), "accepted: {err}");
        assert!(!err.contains("panicked"), "panicked: {err}");
        for n in needles {
            assert!(err.contains(n), "`{n}` not in: {err}");
        }
    };
    let garbage = common::write(&dir, "garbage.rec", "HIERARCHY\nROOT hips\n");
    let g = garbage.to_str().unwrap();
    refused(
        run(&["replay", g, "-o", dir.join("g.html").to_str().unwrap()]),
        &["garbage.rec", "not a Repertoire recording"],
    );
    refused(
        run(&["export", g, "--npy", dir.join("g.npy").to_str().unwrap()]),
        &["garbage.rec", "not a Repertoire recording"],
    );
    refused(run(&["replay", dir.join("none.rec").to_str().unwrap()]), &["none.rec", "cannot read"]);
    let empty = dir.join("empty");
    std::fs::create_dir_all(&empty).unwrap();
    refused(run(&["replay", empty.to_str().unwrap()]), &["empty", "no recordings"]);
    refused(run(&["replay", dir.to_str().unwrap()]), &["garbage.rec", "not a Repertoire recording"]);

    // A real recording, but no three.js where --web points: the message says to run setup.
    let clip = Path::new(env!("CARGO_MANIFEST_DIR")).join("third_party/clips/deepmimic/walk_forward.txt");
    let rec = dir.join("walk.rec");
    repertoire(&["clip", "play", clip.to_str().unwrap(), "--record", rec.to_str().unwrap()]);
    let out = run(&["replay", rec.to_str().unwrap(), "--web", dir.join("no-web").to_str().unwrap()]);
    refused(out, &["three.core.js", "scripts/setup.sh"]);
    assert!(!dir.join("walk.html").exists(), "no half page is left behind");
    refused(run(&["export", rec.to_str().unwrap()]), &["nothing to export"]);
}
