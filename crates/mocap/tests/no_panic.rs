//! Property tests: arbitrary bytes and mutated real files never make a parser panic.

use proptest::prelude::*;
use repertoire_mocap::{
    AmcOptions, Asf, BvhOptions, DeepMimicLayout, parse_amc, parse_asf, parse_bvh, parse_deepmimic,
};
use std::sync::OnceLock;

const DATA: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/../../mocap");

fn read(rel: &str) -> Vec<u8> {
    std::fs::read(format!("{DATA}/{rel}")).unwrap()
}

/// The first `lines` lines of a file.
fn head(bytes: &[u8], lines: usize) -> Vec<u8> {
    let mut n = 0;
    let end = bytes
        .iter()
        .position(|&b| {
            n += usize::from(b == b'\n');
            n == lines
        })
        .map_or(bytes.len(), |i| i + 1);
    bytes[..end].to_vec()
}

/// A BVH file cut to its first three frames, with the frame count rewritten.
fn bvh_head(rel: &str) -> Vec<u8> {
    let text = String::from_utf8(read(rel)).unwrap();
    let lines: Vec<&str> = text.split_inclusive('\n').collect();
    let time = lines.iter().position(|l| l.starts_with("Frame Time")).unwrap();
    let mut out = String::new();
    for l in &lines[..time + 4] {
        if l.starts_with("Frames:") {
            out.push_str("Frames: 3\r\n");
        } else {
            out.push_str(l);
        }
    }
    out.into_bytes()
}

struct Seeds {
    bvh: Vec<Vec<u8>>,
    asf: Vec<u8>,
    amc: Vec<u8>,
    json: Vec<u8>,
    skeleton: Asf,
}

/// Small real inputs: BVH headers with a few frames, the ASF, three AMC frames, a DeepMimic
/// clip cut to three frames.
fn seeds() -> &'static Seeds {
    static SEEDS: OnceLock<Seeds> = OnceLock::new();
    SEEDS.get_or_init(|| {
        let bvh = vec![
            bvh_head("cmu-subject16-30fps/16_15_walk.bvh"),
            bvh_head("cmu-120fps/113_26_walk_and_carry.bvh"),
            bvh_head("retargeted-60fps/115_06_pick_up_box_bend_knees.bvh"),
        ];
        let asf = read("asf-amc/01.asf");
        let amc = head(&read("asf-amc/01_01.amc"), 3 + 3 * 30);
        let json_full = String::from_utf8(read("deepmimic-format/pybullet_walker_walk_forward.txt")).unwrap();
        // Cut after the third frame: the closing "]" of a frame is on its own tab-indented line.
        let mut cut = 0;
        for _ in 0..3 {
            cut += json_full[cut..].find("\t\t]").unwrap() + 3;
        }
        let json = format!("{}\n\t],\n\t\"Loop\": \"wrap\"\n}}\n", &json_full[..cut]).into_bytes();
        let skeleton = parse_asf(&asf, None).unwrap();
        Seeds { bvh, asf, amc, json, skeleton }
    })
}

#[test]
fn seeds_are_valid() {
    let s = seeds();
    for b in &s.bvh {
        parse_bvh(b, &BvhOptions::default()).unwrap();
    }
    let clip = parse_amc(&s.amc, &s.skeleton, &AmcOptions::default()).unwrap();
    assert_eq!(clip.motion.frame_count(), 3);
    let clip = parse_deepmimic(&s.json, &DeepMimicLayout::humanoid3d()).unwrap();
    assert_eq!(clip.motion.frame_count(), 3);
}

include!("support/dict.rs");

#[derive(Clone, Debug)]
enum Edit {
    Flip(usize, u8),
    Set(usize, u8),
    Delete(usize, usize),
    Insert(usize, usize),
    Duplicate(usize, usize),
    Truncate(usize),
}

fn edit() -> impl Strategy<Value = Edit> {
    prop_oneof![
        (any::<usize>(), 0u8..8).prop_map(|(i, b)| Edit::Flip(i, b)),
        (any::<usize>(), any::<u8>()).prop_map(|(i, b)| Edit::Set(i, b)),
        (any::<usize>(), 1usize..64).prop_map(|(i, n)| Edit::Delete(i, n)),
        (any::<usize>(), 0..DICT.len()).prop_map(|(i, k)| Edit::Insert(i, k)),
        (any::<usize>(), 1usize..256).prop_map(|(i, n)| Edit::Duplicate(i, n)),
        any::<usize>().prop_map(Edit::Truncate),
    ]
}

fn mutate(seed: &[u8], edits: &[Edit]) -> Vec<u8> {
    let mut v = seed.to_vec();
    for e in edits {
        let len = v.len().max(1);
        match *e {
            Edit::Flip(i, b) => {
                if let Some(x) = v.get_mut(i % len) {
                    *x ^= 1 << b;
                }
            }
            Edit::Set(i, b) => {
                if let Some(x) = v.get_mut(i % len) {
                    *x = b;
                }
            }
            Edit::Delete(i, n) => {
                let s = i % len;
                let e = (s + n).min(v.len());
                if s < e {
                    v.drain(s..e);
                }
            }
            Edit::Insert(i, k) => {
                let at = (i % len).min(v.len());
                v.splice(at..at, DICT[k].bytes());
            }
            Edit::Duplicate(i, n) => {
                let s = (i % len).min(v.len());
                let e = (s + n).min(v.len());
                let chunk = v[s..e].to_vec();
                v.splice(e..e, chunk);
            }
            Edit::Truncate(i) => v.truncate(i % len),
        }
    }
    v
}

fn all_parsers(bytes: &[u8]) {
    let s = seeds();
    let _ = parse_bvh(bytes, &BvhOptions::default());
    let _ = parse_asf(bytes, None);
    let _ = parse_amc(bytes, &s.skeleton, &AmcOptions::default());
    let _ = parse_deepmimic(bytes, &DeepMimicLayout::humanoid3d());
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 512, ..ProptestConfig::default() })]

    #[test]
    fn arbitrary_bytes_never_panic(bytes in proptest::collection::vec(any::<u8>(), 0..512)) {
        all_parsers(&bytes);
    }

    #[test]
    fn mutated_bvh_never_panics(
        which in 0usize..3,
        edits in proptest::collection::vec(edit(), 1..12),
        skip in any::<bool>(),
    ) {
        let input = mutate(&seeds().bvh[which], &edits);
        let opts = BvhOptions { unit: None, skip_first_frame: skip };
        if let Ok(clip) = parse_bvh(&input, &opts) {
            // A clip that parses is consistent.
            prop_assert_eq!(clip.motion.rotations.len(), clip.motion.frame_count() * clip.skeleton.len());
        }
    }

    #[test]
    fn mutated_asf_never_panics(edits in proptest::collection::vec(edit(), 1..12)) {
        let input = mutate(&seeds().asf, &edits);
        if let Ok(asf) = parse_asf(&input, None) {
            // Whatever skeleton came out, the real AMC must not panic against it.
            let _ = parse_amc(&seeds().amc, &asf, &AmcOptions::default());
        }
    }

    #[test]
    fn mutated_amc_never_panics(edits in proptest::collection::vec(edit(), 1..12)) {
        let input = mutate(&seeds().amc, &edits);
        let _ = parse_amc(&input, &seeds().skeleton, &AmcOptions::default());
    }

    #[test]
    fn mutated_deepmimic_never_panics(edits in proptest::collection::vec(edit(), 1..12)) {
        let input = mutate(&seeds().json, &edits);
        let _ = parse_deepmimic(&input, &DeepMimicLayout::humanoid3d());
    }

    #[test]
    fn euler_round_trip_any_order(
        a in -3.1f64..3.1, b in -1.5f64..1.5, c in -3.1f64..3.1, k in 0usize..6,
    ) {
        use repertoire_mocap::{Axis::*, EulerOrder};
        let orders = [[X, Y, Z], [X, Z, Y], [Y, X, Z], [Y, Z, X], [Z, X, Y], [Z, Y, X]];
        let order = EulerOrder::new(orders[k]).unwrap();
        let q = order.to_quat([a, b, c]);
        let back = order.from_quat(q);
        prop_assert!(order.to_quat(back).angle_to(q) < 1e-9);
        prop_assert!((back[0] - a).abs() < 1e-7 && (back[1] - b).abs() < 1e-7 && (back[2] - c).abs() < 1e-7);
    }
}
