//! What the benches that read the shared mocap have in common.

use std::path::{Path, PathBuf};

/// `../shared/data` beside the project.
pub fn shared_data() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../../shared/data")
}

/// Every `.bvh` file below `dir`, in name order.
pub fn bvh_files(dir: &Path, out: &mut Vec<PathBuf>) {
    let Ok(entries) = std::fs::read_dir(dir) else { return };
    let mut entries: Vec<_> = entries.flatten().map(|e| e.path()).collect();
    entries.sort();
    for p in entries {
        if p.is_dir() {
            bvh_files(&p, out);
        } else if p.extension().is_some_and(|e| e == "bvh") {
            out.push(p);
        }
    }
}
