//! The TOML readers, each checked: the training configurations (ACE and motion prior, from
//! `ace_models::checkpoint`, which needs no libtorch), the dataset configuration, character profiles
//! and joint mappings.
#![no_main]
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let Ok(text) = std::str::from_utf8(data) else { return };
    if let Ok(c) = toml::from_str::<ace_models::checkpoint::ace::AceConfig>(text) {
        let _ = c.check();
    }
    if let Ok(c) = toml::from_str::<ace_models::checkpoint::prior::PriorConfig>(text) {
        let _ = c.check();
    }
    if let Ok(c) = toml::from_str::<ace_models::dataset::DatasetConfig>(text) {
        let _ = ace_models::dataset::check_config(&c);
    }
    if let Err(e) = ace_models::morphology::Profile::from_toml(text, "fuzz.profile.toml") {
        assert!(e.to_string().starts_with("fuzz.profile.toml: "), "{e}");
    }
    let _ = ace_models::human::JointMapping::from_toml_str(text);
});
