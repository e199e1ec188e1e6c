#![no_main]
//! DeepMimic JSON parsing never panics.

use libfuzzer_sys::fuzz_target;
use repertoire_mocap::{DeepMimicLayout, parse_deepmimic};

fuzz_target!(|data: &[u8]| {
    let _ = parse_deepmimic(data, &DeepMimicLayout::humanoid3d());
});
