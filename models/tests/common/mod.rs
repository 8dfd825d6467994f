//! Helpers shared by the integration tests.

use std::path::PathBuf;

#[allow(dead_code)]
/// The shared robot data, or `None` (with a message) when it is absent and `ACE_ALLOW_MISSING_DATA=1`.
pub fn robots() -> Option<PathBuf> {
    let dir = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../shared/data/robots");
    if dir.is_dir() {
        return Some(dir);
    }
    if std::env::var("ACE_ALLOW_MISSING_DATA").is_ok_and(|v| v == "1") {
        eprintln!("skipping: shared robot data not found at {}", dir.display());
        return None;
    }
    panic!(
        "shared robot data not found at {} (set ACE_ALLOW_MISSING_DATA=1 to skip tests that need it)",
        dir.display()
    );
}

/// The shared rigged glTF creatures, or `None` (with a message) when absent and
/// `ACE_ALLOW_MISSING_DATA=1`.
#[allow(dead_code)]
pub fn creatures() -> Option<PathBuf> {
    let dir = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../shared/data/creatures");
    if dir.is_dir() {
        return Some(dir);
    }
    if std::env::var("ACE_ALLOW_MISSING_DATA").is_ok_and(|v| v == "1") {
        eprintln!("skipping: shared creature data not found at {}", dir.display());
        return None;
    }
    panic!(
        "shared creature data not found at {} (set ACE_ALLOW_MISSING_DATA=1 to skip tests that need it)",
        dir.display()
    );
}
