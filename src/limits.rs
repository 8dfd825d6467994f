//! Bounds of the command-line options, checked by the argument parser before any work (an error names
//! the option and the valid range).

/// Most threads `--threads` may ask libtorch for.
pub const MAX_THREADS: i64 = 1024;

/// Most clips `ace retarget FOLDER --jobs` runs at once: each worker loads its own networks.
pub const MAX_JOBS: usize = 256;

/// Longest `ace eval --seconds` rollout (one hour).
pub const MAX_SECONDS: f32 = 3600.0;

/// `--frames`: 1 to [`ace::models::dataset::MAX_FRAMES`].
pub fn frames(s: &str) -> Result<usize, String> {
    let max = ace::models::dataset::MAX_FRAMES;
    s.parse::<usize>()
        .ok()
        .filter(|n| (1..=max).contains(n))
        .ok_or_else(|| format!("expected a frame count from 1 to {max}"))
}

/// `--seconds`: at least one frame at the project's rate (a rollout of 0 frames has nothing to
/// score), at most [`MAX_SECONDS`].
pub fn seconds(s: &str) -> Result<f32, String> {
    let fps = ace::models::human_set::PROJECT_FPS;
    s.parse::<f32>()
        .ok()
        .filter(|v| (*v * fps).round() >= 1.0 && *v <= MAX_SECONDS)
        .ok_or_else(|| format!("expected seconds from one frame (1/{fps}) to {MAX_SECONDS}"))
}

/// A count of at least 1.
pub fn at_least_one(s: &str) -> Result<usize, String> {
    s.parse::<usize>()
        .ok()
        .filter(|n| *n >= 1)
        .ok_or_else(|| "expected a whole number of at least 1".to_string())
}

/// `--jobs`: 1 to [`MAX_JOBS`].
pub fn jobs(s: &str) -> Result<usize, String> {
    s.parse::<usize>()
        .ok()
        .filter(|n| (1..=MAX_JOBS).contains(n))
        .ok_or_else(|| format!("expected a number of clips at once from 1 to {MAX_JOBS}"))
}
