//! Joint-position clips (`.npy`/`.npz` with a `.joints.ron` declaration), made here from a real
//! CMU walk: the joints' world positions retarget to the motion the BVH itself gives, in the
//! BVH's own joint names with its map, and in SMPL's 22-joint layout with the shipped SMPL map;
//! bad declarations and arrays are refused with the file and the place named.

use std::io::Write;
use std::path::{Path, PathBuf};

use repertoire_clip::map::LoadedMap;
use repertoire_clip::{ClipBody, ClipSource, RetargetOptions, Retargeted, import, retarget};

const WALK: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/../../mocap/cmu-subject16-30fps/16_15_walk.bvh");
/// Frames of the walk used (2 s at 30 fps: keeps the test quick in the dev profile).
const FRAMES: usize = 60;

fn temp_dir(test: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("repertoire-positions-{}-{test}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).expect("temp dir");
    dir
}

/// A NumPy v1.0 array of `shape`, little-endian f8 (`f32: false`) or f4.
fn npy(shape: &[usize], values: &[f64], f32: bool) -> Vec<u8> {
    let dims: Vec<String> = shape.iter().map(|d| d.to_string()).collect();
    let descr = if f32 { "<f4" } else { "<f8" };
    let mut header = format!("{{'descr': '{descr}', 'fortran_order': False, 'shape': ({},), }}", dims.join(", "));
    header.push_str(&" ".repeat((64 - (10 + header.len() + 1) % 64) % 64));
    header.push('\n');
    let mut out = b"\x93NUMPY\x01\x00".to_vec();
    out.extend_from_slice(&(header.len() as u16).to_le_bytes());
    out.extend_from_slice(header.as_bytes());
    for &v in values {
        if f32 {
            out.extend_from_slice(&(v as f32).to_le_bytes());
        } else {
            out.extend_from_slice(&v.to_le_bytes());
        }
    }
    out
}

/// The first `FRAMES` frames of the walk as its map reads them, and that map.
fn walk() -> (repertoire_mocap::Clip, LoadedMap) {
    let (mut clip, map) =
        import(&ClipSource::from_path(Path::new(WALK), None).unwrap(), None).expect("the walk imports");
    let n = FRAMES * clip.motion.joint_count;
    clip.motion.translations.truncate(n);
    clip.motion.rotations.truncate(n);
    clip.motion.raw = None;
    (clip, map)
}

/// World positions of `joints` (by a function of the frame's joint positions) per frame.
fn positions(
    clip: &repertoire_mocap::Clip,
    pick: &dyn Fn(&[repertoire_mocap::Vec3]) -> Vec<repertoire_mocap::Vec3>,
) -> Vec<f64> {
    let mut out = Vec::new();
    for f in 0..clip.motion.frame_count() {
        let pose = clip.motion.world_pose(&clip.skeleton, f).expect("frame");
        for p in pick(&pose.positions) {
            out.extend([p.x, p.y, p.z]);
        }
    }
    out
}

fn declaration(fps: f64, joints: &[String], parents: &[i64], extra: &str) -> String {
    let names: Vec<String> = joints.iter().map(|j| format!("{j:?}")).collect();
    let parents: Vec<String> = parents.iter().map(|p| p.to_string()).collect();
    format!(
        "(\n    fps: {fps:?},\n    joints: [{}],\n    parents: [{}],\n{extra})\n",
        names.join(", "),
        parents.join(", ")
    )
}

fn run(clip: &repertoire_mocap::Clip, path: &Path, map: &LoadedMap) -> Retargeted {
    let body = ClipBody::humanoid().expect("built-in humanoid");
    retarget(clip, path, map, &body, &RetargetOptions::default()).unwrap_or_else(|e| panic!("{}: {e}", path.display()))
}

fn max_difference(a: &[f64], b: &[f64]) -> f64 {
    assert_eq!(a.len(), b.len());
    a.iter().zip(b).map(|(x, y)| (x - y).abs()).fold(0.0, f64::max)
}

#[test]
fn the_positions_of_a_bvh_retarget_to_the_motion_of_the_bvh() {
    let dir = temp_dir("same");
    let (clip, map) = walk();
    let direct = run(&clip, Path::new(WALK), &map);

    // Its joints' positions in its own names, f8, with the shipped map made a positions map.
    let sk = &clip.skeleton;
    let names: Vec<String> = sk.joints.iter().map(|j| j.name.clone()).collect();
    let parents: Vec<i64> = sk.joints.iter().map(|j| j.parent.map_or(-1, |p| p as i64)).collect();
    let values = positions(&clip, &|p| p.to_vec());
    let array = dir.join("walk.npy");
    std::fs::write(&array, npy(&[FRAMES, names.len(), 3], &values, false)).unwrap();
    std::fs::write(dir.join("walk.joints.ron"), declaration(clip.motion.fps(), &names, &parents, "")).unwrap();
    let map_text = map.text.replace("format: Bvh", "format: Positions").replace("unit: Some(Centimetre),", "");
    assert_ne!(map_text, map.text);
    let map_file = dir.join("cmu16.positions.ron");
    std::fs::write(&map_file, map_text).unwrap();

    let source = ClipSource::from_path(&array, None).expect("an .npy with its declaration");
    let (positions_clip, positions_map) = import(&source, Some(LoadedMap::load(&map_file).unwrap())).expect("imports");
    assert_eq!(positions_clip.motion.frame_count(), FRAMES);
    let via = run(&positions_clip, &array, &positions_map);
    assert_eq!(via.clip.fps, direct.clip.fps);
    let d = max_difference(&via.clip.qpos, &direct.clip.qpos);
    assert!(d < 1e-9, "qpos differs by {d}");
}

/// SMPL's 22 joints from the CMU subject-16 skeleton: the joints the two share by anatomy, and
/// spine1/spine2 a third and two thirds of the way from the pelvis to the thorax, the head 10 cm
/// above the base of the neck.
const SMPL: [&str; 22] = [
    "pelvis",
    "left_hip",
    "right_hip",
    "spine1",
    "left_knee",
    "right_knee",
    "spine2",
    "left_ankle",
    "right_ankle",
    "spine3",
    "left_foot",
    "right_foot",
    "neck",
    "left_collar",
    "right_collar",
    "head",
    "left_shoulder",
    "right_shoulder",
    "left_elbow",
    "right_elbow",
    "left_wrist",
    "right_wrist",
];
const SMPL_PARENTS: [i64; 22] = [-1, 0, 0, 0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 9, 9, 12, 13, 14, 16, 17, 18, 19];

fn smpl_of_cmu(clip: &repertoire_mocap::Clip) -> Vec<f64> {
    let j = |n: &str| clip.skeleton.joint_index(n).unwrap_or_else(|| panic!("CMU joint {n}"));
    let cmu = [
        "pelvis",
        "lfemur",
        "rfemur",
        "",
        "ltibia",
        "rtibia",
        "",
        "lfoot",
        "rfoot",
        "thorax",
        "ltoes",
        "rtoes",
        "head",
        "lclavicle",
        "rclavicle",
        "",
        "lhumerus",
        "rhumerus",
        "lradius",
        "rradius",
        "lhand",
        "rhand",
    ]
    .map(|n| (!n.is_empty()).then(|| j(n)));
    let (pelvis, thorax, neck) = (j("pelvis"), j("thorax"), j("head"));
    positions(clip, &|p| {
        (0..22)
            .map(|k| match (k, cmu[k]) {
                (_, Some(c)) => p[c],
                (3, None) => p[pelvis] + (p[thorax] - p[pelvis]) * (1.0 / 3.0),
                (6, None) => p[pelvis] + (p[thorax] - p[pelvis]) * (2.0 / 3.0),
                _ => p[neck] + repertoire_mocap::Vec3::new(0.0, 0.1, 0.0),
            })
            .collect()
    })
}

#[test]
fn an_smpl_layout_npz_picks_the_shipped_smpl_map_and_moves_the_body_as_the_bvh_does() {
    let dir = temp_dir("smpl");
    let (clip, mut map) = walk();
    // Centimetres in f4, flattened to (frames, 66), inside an .npz beside another array.
    let values: Vec<f64> = smpl_of_cmu(&clip).iter().map(|v| v * 100.0).collect();
    let array = dir.join("walk.npz");
    {
        let mut zip = zip::ZipWriter::new(std::fs::File::create(&array).unwrap());
        let opts = zip::write::SimpleFileOptions::default().compression_method(zip::CompressionMethod::Deflated);
        zip.start_file("joints.npy", opts).unwrap();
        zip.write_all(&npy(&[FRAMES, 66], &values, true)).unwrap();
        zip.start_file("text.npy", opts).unwrap();
        zip.write_all(&npy(&[1, 1], &[0.0], true)).unwrap();
        zip.finish().unwrap();
    }
    let names: Vec<String> = SMPL.iter().map(|s| s.to_string()).collect();
    let decl = dir.join("walk.joints.ron");
    std::fs::write(&decl, declaration(30.0, &names, &SMPL_PARENTS, "    unit: Centimetre,\n")).unwrap();
    let source = ClipSource::from_path(&array, None).unwrap();
    let e = import(&source, None).unwrap_err().to_string();
    assert!(e.contains("walk.joints.ron") && e.contains("joints, text") && e.contains("array"), "{e}");

    std::fs::write(
        &decl,
        declaration(30.0, &names, &SMPL_PARENTS, "    unit: Centimetre,\n    array: Some(\"joints\"),\n"),
    )
    .unwrap();
    let (smpl, smpl_map) = import(&source, None).expect("the SMPL layout imports");
    assert_eq!(smpl_map.map.name, "smpl22-positions");
    let via = run(&smpl, &array, &smpl_map);
    // The BVH goes through its own map with the SMPL map's body points (the two maps place the
    // spine for their own skeletons): this compares the import, not the maps.
    for point in &mut map.map.points {
        let smpl_point = smpl_map.point(point.role).expect("the SMPL map has every role the BVH map has");
        (point.target, point.offset, point.weight) = (smpl_point.target.clone(), smpl_point.offset, smpl_point.weight);
    }
    let direct = run(&clip, Path::new(WALK), &map);
    // The mapped joints are the BVH's, stored as f4 centimetres: the same motion within 1 mm
    // of root travel and a hundredth of a radian.
    let d = max_difference(&via.clip.qpos, &direct.clip.qpos);
    assert!(d < 0.01, "qpos differs by {d}");
}

#[test]
fn bad_declarations_and_arrays_are_refused_where_they_are_wrong() {
    let dir = temp_dir("bad");
    let names: Vec<String> = ["a", "b", "c"].map(String::from).to_vec();
    let array = dir.join("m.npy");
    let decl = dir.join("m.joints.ron");
    std::fs::write(&array, npy(&[4, 3, 3], &[0.0; 36], false)).unwrap();
    let e = ClipSource::from_path(&array, None).unwrap_err().to_string();
    assert!(e.contains("m.joints.ron") && e.contains("declaration"), "{e}");

    let cases: [(f64, &[i64], &str); 3] = [
        (30.0, &[-1, 0], "2 parents for 3 joints"),
        (30.0, &[-1, 2, 0], "joint 1 (`b`) has parent 2"),
        (0.0, &[-1, 0, 0], "fps must be a positive number"),
    ];
    for (fps, parents, want) in cases {
        std::fs::write(&decl, declaration(fps, &names, parents, "")).unwrap();
        let e = import(&ClipSource::from_path(&array, None).unwrap(), None).unwrap_err().to_string();
        assert!(e.contains("m.joints.ron:") && e.contains(want), "{want}: {e}");
    }
    // Four joints declared over an array of three.
    let four: Vec<String> = ["a", "b", "c", "d"].map(String::from).to_vec();
    std::fs::write(&decl, declaration(30.0, &four, &[-1, 0, 0, 0], "")).unwrap();
    let e = import(&ClipSource::from_path(&array, None).unwrap(), None).unwrap_err().to_string();
    assert!(e.contains("m.npy") && e.contains("4 declared joints"), "{e}");
    // No shipped map knows joints a, b, c: the error lists them.
    std::fs::write(&decl, declaration(30.0, &names, &[-1, 0, 0], "")).unwrap();
    let e = import(&ClipSource::from_path(&array, None).unwrap(), None).unwrap_err().to_string();
    assert!(e.contains("joint-positions") && e.contains("smpl22-positions"), "{e}");
}
