//! Helpers shared by the `ace` crate's integration tests.
#![allow(dead_code)]

/// The plugin's headless-test helpers (apps, stepping, the retargeting set-up), one copy for both crates.
#[path = "../../plugin/tests/support/mod.rs"]
pub mod support;
#[allow(unused_imports)] // rig_clip_in_bevy steps its app with it; other tests do not
pub use support::update_until;
/// The project's folder.
pub use support::project as root;

use std::path::{Path, PathBuf};

/// A file or folder of the shared data beside the project; `None` (skip, with a message) only with
/// `ACE_ALLOW_MISSING_DATA=1`.
pub fn shared(rel: &str) -> Option<PathBuf> {
    let p = root().join("../shared/data").join(rel);
    if p.exists() {
        return Some(p);
    }
    if std::env::var("ACE_ALLOW_MISSING_DATA").is_ok_and(|v| v == "1") {
        eprintln!("skipping: {} is missing", p.display());
        return None;
    }
    panic!("{} is missing: the shared data must stand beside the project (or set ACE_ALLOW_MISSING_DATA=1)", p.display());
}

/// Every file below `dir` (in every subfolder) with its bytes, by path relative to `dir`, sorted.
pub fn folder_bytes(dir: &Path) -> Vec<(String, Vec<u8>)> {
    let mut out = Vec::new();
    let mut pending = vec![dir.to_path_buf()];
    while let Some(d) = pending.pop() {
        for e in std::fs::read_dir(&d).unwrap() {
            let p = e.unwrap().path();
            let rel = p.strip_prefix(dir).unwrap().to_string_lossy().into_owned();
            if p.is_symlink() {
                // A link by where it leads (it may lead nowhere).
                out.push((rel, std::fs::read_link(&p).unwrap().into_os_string().into_encoded_bytes()));
            } else if p.is_dir() {
                pending.push(p);
            } else {
                out.push((rel, std::fs::read(&p).unwrap()));
            }
        }
    }
    out.sort();
    out
}
