//! Rigged glTF creatures: the glTF/GLB reader, the rig and body-plan analysis, and a short clip's poses.
#![no_main]
use std::path::Path;

use ace_models::character::{clips::clip_poses, creature_from_document, gltf::open_bytes};
use ace_models::morphology::Profile;
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let path = Path::new("fuzz.glb");
    let opened = open_bytes(data, path, &|uri| Err(format!("no file `{uri}` beside a fuzzed input")));
    let (doc, buffers) = match opened {
        Ok(d) => d,
        Err(e) => {
            assert!(e.to_string().contains("fuzz.glb"), "{e}");
            return;
        }
    };
    match creature_from_document(&doc, &buffers, path, &Profile::default()) {
        // Sampling is bounded by the clip caps; a short clip keeps each run quick.
        Ok(c) => {
            if let Some(k) = c.rig.animations.iter().position(|a| a.duration_s <= 5.0) {
                for pose in clip_poses(&c, k, 30.0) {
                    assert!(pose.q.iter().all(|x| x.is_finite()), "a clip pose is not finite");
                }
            }
        }
        Err(e) => assert!(e.to_string().contains("fuzz.glb"), "{e}"),
    }
});
