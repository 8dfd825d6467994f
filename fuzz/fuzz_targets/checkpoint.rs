//! Checkpoint loading from memory. The input holds the four files of a checkpoint (`config.json`,
//! `prior.safetensors`, `ace.json`, `generator.safetensors`): each of the first three as a 4-byte
//! little-endian length and its bytes, the last as the rest. They load through the pure-Rust runtime
//! (`ace_models::runtime`), the loader a game ships, so the target needs no libtorch.
#![no_main]
use std::collections::BTreeMap;
use std::path::Path;

use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let names = ["config.json", "prior.safetensors", "ace.json", "generator.safetensors"];
    let mut rest = data;
    let mut files = BTreeMap::new();
    for (k, name) in names.iter().enumerate() {
        let part = if k == 3 || rest.len() < 4 {
            std::mem::take(&mut rest)
        } else {
            let n = (u32::from_le_bytes(rest[..4].try_into().unwrap()) as usize).min(rest.len() - 4);
            let (part, tail) = rest[4..].split_at(n);
            rest = tail;
            part
        };
        files.insert(name.to_string(), part.to_vec());
    }
    let files = ace_models::checkpoint::CheckpointFiles::in_memory(Path::new("fuzz-checkpoint"), files);
    if let Err(e) = ace_models::runtime::Retargeter::load_files(&files) {
        assert!(e.to_string().contains("fuzz-checkpoint"), "{e}");
    }
});
