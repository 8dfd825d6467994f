//! The shared data for the unit tests (`../shared/data` beside the repository; integration tests have
//! their own in `tests/common`), the bundled characters and clips, and the closeness check of
//! vectors. A test that needs shared data fails when it is missing, unless `ACE_ALLOW_MISSING_DATA=1`
//! says to skip what needs it.

use std::path::PathBuf;

/// Whether a missing shared file may be skipped (`ACE_ALLOW_MISSING_DATA=1`).
pub(crate) fn allow_missing() -> bool {
    std::env::var("ACE_ALLOW_MISSING_DATA").is_ok_and(|v| v == "1")
}

/// `path` when it exists; `None`, saying so, when it is missing and missing data is allowed.
///
/// # Panics
/// When `path` is missing and missing data is not allowed.
pub(crate) fn require(path: PathBuf, what: &str) -> Option<PathBuf> {
    if path.exists() {
        return Some(path);
    }
    if allow_missing() {
        eprintln!("SKIPPED: {what} not found at {} (ACE_ALLOW_MISSING_DATA=1)", path.display());
        return None;
    }
    panic!("{what} not found at {}: put the shared data beside the repository, or set ACE_ALLOW_MISSING_DATA=1", path.display());
}

/// A character bundled in `assets/characters` (`spot`, `crab`, `stretch`), loaded as the CLI loads it.
pub(crate) fn bundled_character(name: &str) -> (crate::kinematics::KinematicTree, crate::morphology::Morphology) {
    let path = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join(format!("../assets/characters/{name}.urdf"));
    crate::morphology::load_character(&path).unwrap_or_else(|e| panic!("{e}"))
}

/// A clip bundled in `assets/motions` (`walk`, `reach`, `wave`), imported with the default options.
pub(crate) fn bundled_clip(name: &str) -> crate::human::HumanClip {
    let path = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join(format!("../assets/motions/{name}.bvh"));
    crate::human::HumanClip::from_bvh_file(&path, &crate::human::ImportOptions::default()).unwrap_or_else(|e| panic!("{e}"))
}

/// Whether `a` and `b` have the same length and every pair of entries is within `tol`.
pub(crate) fn close(a: &[f32], b: &[f32], tol: f32) -> bool {
    a.len() == b.len() && a.iter().zip(b).all(|(x, y)| (x - y).abs() <= tol)
}
