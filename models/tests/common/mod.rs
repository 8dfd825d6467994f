//! Helpers shared by the integration tests.

use std::path::PathBuf;

/// A folder of the shared data (`robots`, `creatures`), or `None` (with a message) when it is absent and
/// `ACE_ALLOW_MISSING_DATA=1`.
fn shared(folder: &str) -> Option<PathBuf> {
    let dir = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../shared/data").join(folder);
    if dir.is_dir() {
        return Some(dir);
    }
    if std::env::var("ACE_ALLOW_MISSING_DATA").is_ok_and(|v| v == "1") {
        eprintln!("skipping: shared {folder} data not found at {}", dir.display());
        return None;
    }
    panic!(
        "shared {folder} data not found at {} (set ACE_ALLOW_MISSING_DATA=1 to skip tests that need it)",
        dir.display()
    );
}

/// The shared robot URDFs (see [`shared`]).
#[allow(dead_code)]
pub fn robots() -> Option<PathBuf> {
    shared("robots")
}

/// The shared rigged glTF creatures (see [`shared`]).
#[allow(dead_code)]
pub fn creatures() -> Option<PathBuf> {
    shared("creatures")
}
