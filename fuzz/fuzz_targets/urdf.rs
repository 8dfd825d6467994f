//! URDF loading and morphology analysis.
#![no_main]
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let Ok(text) = std::str::from_utf8(data) else { return };
    match ace_models::urdf::parse_urdf(text, "fuzz.urdf", None) {
        Ok(tree) => {
            let _ = ace_models::morphology::Morphology::analyze(&tree);
        }
        Err(e) => assert!(e.to_string().starts_with("fuzz.urdf: "), "{e}"),
    }
});
