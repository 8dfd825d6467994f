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

/// Runs Khronos' glTF validator (installed by `scripts/setup.sh`) on `path` through
/// `scripts/validate-gltf.mjs`; panics when it reports an error. Returns the report's issue counts and
/// message codes, or `None` (with a message) when the validator is missing and
/// `ACE_ALLOW_MISSING_DATA=1`.
#[allow(dead_code)]
pub fn khronos_validate(path: &std::path::Path) -> Option<serde_json::Value> {
    let root = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("..");
    let installed = root.join(".local/node/node_modules/gltf-validator");
    let missing = |why: String| {
        if std::env::var("ACE_ALLOW_MISSING_DATA").is_ok_and(|v| v == "1") {
            eprintln!("SKIPPED glTF validation: {why} (ACE_ALLOW_MISSING_DATA=1)");
            return None;
        }
        panic!("{why}: run scripts/setup.sh to install Khronos' glTF validator (or set ACE_ALLOW_MISSING_DATA=1)");
    };
    if !installed.is_dir() {
        return missing(format!("{} not found", installed.display()));
    }
    let out = match std::process::Command::new("node").arg(root.join("scripts/validate-gltf.mjs")).arg(path).output() {
        Ok(o) => o,
        Err(e) => return missing(format!("cannot run `node`: {e}")),
    };
    let report: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap_or_else(|e| {
        panic!("the validator printed no JSON report ({e}); stderr: {}", String::from_utf8_lossy(&out.stderr))
    });
    let issues = &report["issues"];
    assert_eq!(
        issues["numErrors"],
        0,
        "{} has glTF errors: {}",
        path.display(),
        serde_json::to_string_pretty(issues).unwrap()
    );
    assert!(out.status.success(), "the validator exited with {}", out.status);
    let mut codes: Vec<String> = issues["messages"]
        .as_array()
        .unwrap()
        .iter()
        .filter_map(|m| m["code"].as_str().map(str::to_owned))
        .collect();
    codes.sort();
    codes.dedup();
    eprintln!(
        "validator: {} — {} errors, {} warnings, {} infos, {} hints {codes:?}",
        path.display(),
        issues["numErrors"],
        issues["numWarnings"],
        issues["numInfos"],
        issues["numHints"],
    );
    Some(issues.clone())
}
