#![no_main]
//! ASF and AMC parsing never panics: the input is split at the first NUL into ASF and AMC.

use libfuzzer_sys::fuzz_target;
use repertoire_mocap::{AmcOptions, parse_amc, parse_asf};

fuzz_target!(|data: &[u8]| {
    let (asf, amc) = match data.iter().position(|&b| b == 0) {
        Some(i) => (&data[..i], &data[i + 1..]),
        None => (data, &[][..]),
    };
    if let Ok(skeleton) = parse_asf(asf, None) {
        let _ = parse_amc(amc, &skeleton, &AmcOptions::default());
    }
});
