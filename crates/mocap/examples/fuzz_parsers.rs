//! Deterministic fuzzing without nightly: runs N random and mutated inputs through each parser
//! and reports the time taken. A panic prints the offending input and exits non-zero.
//!
//! ```text
//! cargo run --release -p repertoire-mocap --example fuzz_parsers -- 1000000 [seed]
//! ```
//! Seeds are small cuts of the real clips in the repository's mocap/.

use repertoire_mocap::{
    AmcOptions, Asf, BvhOptions, DeepMimicLayout, parse_amc, parse_asf, parse_bvh, parse_deepmimic,
};
use std::panic::{AssertUnwindSafe, catch_unwind};
use std::time::Instant;

const DATA: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/../../mocap");

/// SplitMix64: tiny, fast, deterministic.
struct Rng(u64);

impl Rng {
    fn next(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }

    fn below(&mut self, n: usize) -> usize {
        if n == 0 { 0 } else { (self.next() % n as u64) as usize }
    }
}

include!("../tests/support/dict.rs");

fn mutate(rng: &mut Rng, seed: &[u8], out: &mut Vec<u8>) {
    out.clear();
    out.extend_from_slice(seed);
    for _ in 0..1 + rng.below(8) {
        let len = out.len().max(1);
        let i = rng.below(len).min(out.len());
        match rng.below(6) {
            0 => {
                if let Some(b) = out.get_mut(i) {
                    *b ^= 1 << rng.below(8);
                }
            }
            1 => {
                if let Some(b) = out.get_mut(i) {
                    *b = rng.next() as u8;
                }
            }
            2 => {
                let e = (i + 1 + rng.below(64)).min(out.len());
                out.drain(i..e);
            }
            3 => {
                let tok = DICT[rng.below(DICT.len())];
                out.splice(i..i, tok.bytes());
            }
            4 => {
                let e = (i + 1 + rng.below(256)).min(out.len());
                let chunk = out[i..e].to_vec();
                out.splice(e..e, chunk);
            }
            _ => out.truncate(i),
        }
    }
}

fn random(rng: &mut Rng, out: &mut Vec<u8>) {
    out.clear();
    let n = rng.below(256);
    // Mostly printable, sometimes any byte.
    let printable = rng.below(2) == 0;
    for _ in 0..n {
        let b = rng.next() as u8;
        out.push(if printable { b' ' + b % 95 } else { b });
    }
}

fn read(rel: &str) -> Vec<u8> {
    std::fs::read(format!("{DATA}/{rel}")).unwrap_or_else(|e| panic!("{rel}: {e}"))
}

fn cut_lines(bytes: &[u8], keep: usize) -> Vec<u8> {
    let text = String::from_utf8_lossy(bytes);
    text.split_inclusive('\n').take(keep).collect::<String>().into_bytes()
}

fn bvh_seed(rel: &str) -> Vec<u8> {
    let text = String::from_utf8_lossy(&read(rel)).into_owned();
    let lines: Vec<&str> = text.split_inclusive('\n').collect();
    let time = lines.iter().position(|l| l.starts_with("Frame Time")).unwrap_or(0);
    lines[..(time + 3).min(lines.len())]
        .iter()
        .map(|l| if l.starts_with("Frames:") { "Frames: 2\r\n" } else { l })
        .collect::<String>()
        .into_bytes()
}

fn json_seed() -> Vec<u8> {
    let text = String::from_utf8_lossy(&read("deepmimic-format/pybullet_walker_walk_forward.txt")).into_owned();
    let mut cut = 0;
    for _ in 0..2 {
        cut += text[cut..].find("\t\t]").map_or(0, |i| i + 3);
    }
    format!("{}\n\t],\n\t\"Loop\": \"wrap\"\n}}\n", &text[..cut]).into_bytes()
}

fn run(name: &str, n: u64, seed: u64, seeds: &[Vec<u8>], parse: &dyn Fn(&[u8]) -> bool) {
    let mut rng = Rng(seed);
    let mut buf = Vec::new();
    let mut ok = 0u64;
    let start = Instant::now();
    for i in 0..n {
        if rng.below(4) == 0 {
            random(&mut rng, &mut buf);
        } else {
            let s = &seeds[rng.below(seeds.len())];
            mutate(&mut rng, s, &mut buf);
        }
        match catch_unwind(AssertUnwindSafe(|| parse(&buf))) {
            Ok(true) => ok += 1,
            Ok(false) => {}
            Err(_) => {
                eprintln!("{name}: PANIC on input {i}: {:?}", String::from_utf8_lossy(&buf));
                std::process::exit(1);
            }
        }
    }
    let secs = start.elapsed().as_secs_f64();
    println!("{name:<10} {n} inputs in {secs:.2} s ({:.1} µs/input), {ok} parsed OK", secs * 1e6 / n as f64);
}

fn main() {
    let mut args = std::env::args().skip(1);
    let n: u64 = args.next().and_then(|s| s.parse().ok()).unwrap_or(100_000);
    let seed: u64 = args.next().and_then(|s| s.parse().ok()).unwrap_or(0x5EED);
    // Panics are caught and reported once; silence the default hook's backtrace spam.
    std::panic::set_hook(Box::new(|_| {}));

    let bvh = vec![
        bvh_seed("cmu-subject16-30fps/16_15_walk.bvh"),
        bvh_seed("cmu-120fps/113_26_walk_and_carry.bvh"),
        bvh_seed("retargeted-60fps/115_06_pick_up_box_bend_knees.bvh"),
    ];
    let asf_bytes = read("asf-amc/01.asf");
    let asf: Asf = parse_asf(&asf_bytes, None).expect("01.asf parses");
    let amc = cut_lines(&read("asf-amc/01_01.amc"), 3 + 2 * 30);
    let json = json_seed();
    let layout = DeepMimicLayout::humanoid3d();

    let bvh_opts = BvhOptions::default();
    run("bvh", n, seed, &bvh, &|b| parse_bvh(b, &bvh_opts).is_ok());
    run("asf", n, seed, &[asf_bytes], &|b| parse_asf(b, None).is_ok());
    let amc_opts = AmcOptions::default();
    run("amc", n, seed, &[amc], &|b| parse_amc(b, &asf, &amc_opts).is_ok());
    run("deepmimic", n, seed, &[json], &|b| parse_deepmimic(b, &layout).is_ok());
}
