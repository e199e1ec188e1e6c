#![no_main]
//! BVH parsing never panics, and a parsed clip writes and re-parses.

use libfuzzer_sys::fuzz_target;
use repertoire_mocap::{BvhOptions, BvhWriteOptions, parse_bvh, write_bvh};

fuzz_target!(|data: &[u8]| {
    if let Ok(clip) = parse_bvh(data, &BvhOptions::default())
        && let Ok(text) = write_bvh(&clip.skeleton, &clip.motion, &BvhWriteOptions::default())
    {
        let _ = parse_bvh(text.as_bytes(), &BvhOptions::default());
    }
});
