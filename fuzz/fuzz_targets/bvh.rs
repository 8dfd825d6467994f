//! BVH import (parse, joint matching, unit and axis detection, plausibility checks, resampling).
#![no_main]
use ace_models::human::{HumanClip, ImportOptions};
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let text = String::from_utf8_lossy(data);
    if let Err(e) = HumanClip::from_bvh_str(&text, "fuzz.bvh", &ImportOptions { fps: Some(30.0), mapping: None }) {
        assert!(e.to_string().starts_with("fuzz.bvh"), "{e}");
    }
});
