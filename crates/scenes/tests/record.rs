//! Recordings: a real rollout written and read back exactly; files that are cut short, changed
//! or not recordings at all are refused with the file named.

use std::path::PathBuf;
use std::sync::Arc;

use rand::SeedableRng;
use rand::rngs::StdRng;
use repertoire_scenes::{Annotation, RecordOptions, Recorder, Recording, ScenarioFile, WorldModel};

fn temp(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("repertoire-record-{}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("temp dir");
    dir.join(name)
}

/// 40 control ticks of the default scene holding a slightly bent pose, with a ghost standing
/// 0.5 m to the side.
fn rollout() -> Recording {
    let model = Arc::new(WorldModel::build(ScenarioFile::builtin_default()).expect("default scene"));
    let mut world = model.new_world();
    let mut rng = StdRng::seed_from_u64(3);
    world.reset_in_zone("front", &mut rng).expect("zone");
    let options = RecordOptions {
        title: "hold".into(),
        skills: vec!["hold".into(), "other".into()],
        terms: vec!["height".into(), "tick".into()],
        phase: "tick".into(),
        ghost: Some("standing".into()),
        capacity: 41,
    };
    let mut rec = Recorder::new(&model, options);
    let mut action = vec![0.0; model.index.dof()];
    world.joint_angles(&mut action);
    action[0] += 0.2;
    let mut ghost = world.data().qpos().to_vec();
    for tick in 0..=40 {
        if tick > 0 {
            world.step(&action).expect("step");
        }
        ghost.copy_from_slice(world.data().qpos());
        ghost[model.index.root_qpos + 1] += 0.5;
        let terms = [world.root_height() as f32, tick as f32];
        let a = Annotation { skill: Some(tick % 2), phase: tick as f64, terms: &terms, ghost_qpos: Some(&ghost) };
        rec.record(&world, &a);
    }
    rec.finish()
}

#[test]
fn a_rollout_round_trips_exactly() {
    let rec = rollout();
    assert_eq!(rec.frames(), 41);
    assert_eq!(rec.header.bodies.iter().filter(|b| b.character).count(), 15);
    assert!(rec.header.geoms.iter().any(|g| g.name == "chair/seat"));
    // The ghost stands 0.5 m to the side of the body: same height, y + 0.5.
    let character = rec.header.character();
    let (p, _) = rec.pose(7, rec.header.root);
    let g = &rec.ghost[(7 * character.len() + character.iter().position(|&b| b == rec.header.root).unwrap()) * 7..];
    assert!((f64::from(g[1]) - p[1] - 0.5).abs() < 1e-5 && (f64::from(g[2]) - p[2]).abs() < 1e-5);

    let path = temp("hold.rec");
    rec.save(&path).expect("save");
    let back = Recording::load(&path).expect("load");
    assert!(back.header == rec.header, "the header changed on the way");
    assert!(back == rec, "the frames changed on the way");
    // The body holds a pose standing: both feet on the floor from the first step on (it is
    // placed a hair above the floor), kept in the file.
    let on: Vec<_> = back.contacts.iter().map(|c| c.feet_on_floor).collect();
    assert!(on[1..].iter().all(|&f| f == [true, true]), "the feet's floor contact {on:?}");
    let feet = back.header.feet.expect("format 2 names the feet");
    assert!(
        feet.iter().all(|&b| back.header.bodies[b].name.contains("foot")),
        "{:?}",
        feet.map(|b| &back.header.bodies[b].name)
    );
    // 41 frames of a 15-body character plus a chair, with a ghost: a few tens of kB.
    let size = std::fs::metadata(&path).unwrap().len();
    assert!(size < 100_000, "{size} bytes");
}

#[test]
fn damaged_files_are_refused_with_the_file_named() {
    let rec = rollout();
    let bytes = rec.to_bytes();
    let check = |name: &str, content: &[u8], expect: &str| {
        let path = temp(name);
        std::fs::write(&path, content).unwrap();
        let err = Recording::load(&path).expect_err(name).to_string();
        assert!(err.starts_with(&path.display().to_string()), "{err}");
        assert!(err.contains(expect), "{name}: {err}");
    };
    check("cut.rec", &bytes[..bytes.len() - 100], "cut short");
    check("cut-header.rec", &bytes[..30], "cut short");
    check("empty.rec", b"", "not a Repertoire recording");
    check("text.rec", b"HIERARCHY\nROOT hips\n", "not a Repertoire recording");
    let mut flipped = bytes.clone();
    let k = bytes.len() - 500;
    flipped[k] ^= 0x10;
    check("flipped.rec", &flipped, "checksum mismatch");
    let mut header = bytes.clone();
    header[13] = b'#';
    check("header.rec", &header, "header line 1 column");
    // The bytes' problems are typed: a reader can tell a file that is not a recording from a
    // damaged one or a newer format.
    use repertoire_scenes::RecordingError;
    assert_eq!(Recording::from_bytes(b"HIERARCHY"), Err(RecordingError::NotARecording));
    assert_eq!(Recording::from_bytes(&flipped), Err(RecordingError::Checksum));
    assert!(matches!(Recording::from_bytes(&bytes[..bytes.len() - 100]), Err(RecordingError::Length { .. })));
    assert!(matches!(Recording::from_bytes(&header), Err(RecordingError::Header { line: 1, .. })));
    let missing = temp("missing.rec");
    let err = Recording::load(&missing).expect_err("missing").to_string();
    assert!(err.contains("missing.rec") && err.contains("cannot read"), "{err}");
}

#[test]
fn a_recorder_hands_out_an_episode_and_starts_the_next_one_empty() {
    let model = Arc::new(WorldModel::build(ScenarioFile::builtin_default()).expect("default scene"));
    let mut world = model.new_world();
    world.reset_in_zone("front", &mut StdRng::seed_from_u64(3)).expect("zone");
    let options =
        RecordOptions { title: "t".into(), skills: vec!["s".into()], capacity: 4, ..RecordOptions::default() };
    let mut rec = Recorder::new(&model, options);
    let frame = |rec: &mut Recorder, world: &repertoire_scenes::World| {
        rec.record(world, &Annotation { skill: Some(0), phase: 0.0, terms: &[], ghost_qpos: None })
    };
    for _ in 0..3 {
        frame(&mut rec, &world);
    }
    let first = rec.take();
    assert_eq!((first.frames(), rec.len()), (3, 0));
    frame(&mut rec, &world);
    frame(&mut rec, &world);
    rec.restart();
    frame(&mut rec, &world);
    let second = rec.finish();
    assert_eq!(second.frames(), 1);
    // The same header but for the frame count.
    let mut h = second.header.clone();
    h.frames = first.header.frames;
    assert_eq!(h, first.header);
    assert_eq!(second.qpos_at(0), first.qpos_at(0));
}
