//! The TOML readers: dataset configuration, joint mappings and (with `--features learn`) the training
//! configurations, each checked.
#![no_main]
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let Ok(text) = std::str::from_utf8(data) else { return };
    #[cfg(feature = "learn")]
    {
        if let Ok(c) = toml::from_str::<ace_models::learn::ace::AceConfig>(text) {
            let _ = c.check();
        }
        if let Ok(c) = toml::from_str::<ace_models::learn::prior::PriorConfig>(text) {
            let _ = c.check();
        }
    }
    if let Ok(c) = toml::from_str::<ace_models::dataset::DatasetConfig>(text) {
        let _ = ace_models::dataset::check_config(&c);
    }
    let _ = ace_models::human::JointMapping::from_toml_str(text);
});
