//! Human training and evaluation data: folders of BVH clips as x^h sequences, split by clip.
//!
//! [`HumanSet::load`] imports every `.bvh` file below a folder (recursively, in sorted order) at the
//! project frame rate ([`PROJECT_FPS`]) and keeps, per clip, its x^h rows ([`HumanClip::states`]: the
//! first frame takes its velocities from the forward difference to the second) and its body length
//! ([`human_body_length`]). Files that fail to import are listed in [`HumanSet::skipped`] with their
//! error rather than failing the whole set; a folder without a single usable clip is an error.
//!
//! **Split.** A clip is held out (for evaluation) when a seeded 64-bit hash of its path relative to the
//! folder (with `/` separators) falls below `held_out_fraction` of the hash range. The decision depends
//! on nothing but the path and the seed, so adding or removing files never moves another clip across
//! the split, and a split recorded in a checkpoint ([`HumanSplit`], serde) can be checked against the
//! folder later. Two guards keep both sides usable: if no clip falls below the threshold (a small set),
//! the clip with the smallest hash is held out; if every clip does, the one with the largest hash is
//! trained on.

use std::fs;
use std::path::{Path, PathBuf};
use std::sync::Mutex;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::mpsc;

use serde::{Deserialize, Serialize};
use thiserror::Error;

use crate::dataset::statistics;
use crate::features::human_body_length;
use crate::human::{HumanClip, ImportOptions, layout};

/// The frame rate every learning stage works at (frames per second).
pub const PROJECT_FPS: f32 = 30.0;

/// Where the shared human data sits relative to the repository root.
pub const DEFAULT_FOLDER: &str = "../shared/data/human";

/// One x^h row.
pub type HumanRow = [f32; layout::DIM];

/// How a [`HumanSet`] is loaded.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct HumanSetOptions {
    /// Frame rate clips are resampled to.
    pub fps: f32,
    /// Fraction of clips held out from training (0 ≤ f < 1).
    pub held_out_fraction: f32,
    /// Seed of the split hash.
    pub split_seed: u64,
    /// Clips with fewer frames are skipped (at least 2, so that every frame has a velocity).
    pub min_frames: usize,
    /// Import threads (0: as many as the machine has cores).
    pub threads: usize,
}

impl Default for HumanSetOptions {
    fn default() -> Self {
        HumanSetOptions {
            fps: PROJECT_FPS,
            held_out_fraction: 0.1,
            split_seed: 0,
            min_frames: 2,
            threads: 0,
        }
    }
}

/// One imported clip.
#[derive(Clone, Debug, PartialEq)]
pub struct HumanSetClip {
    /// Clip name (the file stem).
    pub name: String,
    /// The file it was read from.
    pub path: PathBuf,
    /// Its path relative to the set's folder, `/`-separated (the key of the split).
    pub relative: String,
    /// x^h per frame at the set's frame rate.
    pub states: Vec<HumanRow>,
    /// The human's body length (m), [`human_body_length`].
    pub body_length: f32,
}

/// A file that could not be used, with the reason.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct SkippedFile {
    /// The file.
    pub path: PathBuf,
    /// The import error (it names the file) or why the clip is unusable.
    pub error: String,
}

/// The held-out split of a human set, by relative clip path.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct HumanSplit {
    /// Seed of the split hash.
    pub seed: u64,
    /// Fraction of clips asked to be held out.
    pub held_out_fraction: f32,
    /// Relative paths of the training clips, sorted.
    pub train: Vec<String>,
    /// Relative paths of the held-out clips, sorted.
    pub held_out: Vec<String>,
}

impl HumanSplit {
    /// Splits relative paths (see the module docs for the rule and its two guards).
    pub fn new<S: AsRef<str>>(relative: &[S], seed: u64, held_out_fraction: f32) -> HumanSplit {
        let mut keyed: Vec<(u64, &str)> = relative
            .iter()
            .map(|r| (split_hash(r.as_ref(), seed), r.as_ref()))
            .collect();
        keyed.sort_unstable();
        let threshold = (f64::from(held_out_fraction.clamp(0.0, 1.0)) * 2f64.powi(64)).min(u64::MAX as f64);
        let mut held = keyed.iter().filter(|(h, _)| (*h as f64) < threshold).count();
        if held_out_fraction > 0.0 && held == 0 && keyed.len() >= 2 {
            held = 1;
        }
        if held == keyed.len() && !keyed.is_empty() {
            held -= 1;
        }
        let sorted = |v: &[(u64, &str)]| {
            let mut s: Vec<String> = v.iter().map(|(_, r)| r.to_string()).collect();
            s.sort();
            s
        };
        HumanSplit {
            seed,
            held_out_fraction,
            held_out: sorted(&keyed[..held]),
            train: sorted(&keyed[held..]),
        }
    }

    /// True when `relative` is one of the held-out clips.
    pub fn is_held_out(&self, relative: &str) -> bool {
        self.held_out
            .binary_search_by(|p| p.as_str().cmp(relative))
            .is_ok()
    }
}

/// Mean and standard deviation of each x^h entry (floored at [`crate::dataset::STD_FLOOR`]).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct HumanStats {
    /// Mean per entry.
    pub mean: Vec<f32>,
    /// Standard deviation per entry.
    pub std: Vec<f32>,
}

/// What [`HumanSet::load`] reports while it imports.
#[derive(Clone, Copy, Debug)]
pub struct HumanSetProgress<'a> {
    /// Files finished (imported or skipped).
    pub done: usize,
    /// Files in total.
    pub total: usize,
    /// The file just finished.
    pub file: &'a Path,
}

/// Why a human set could not be loaded.
#[derive(Debug, Error)]
pub enum HumanSetError {
    /// The folder is missing or cannot be listed.
    #[error("{}: cannot list the human clip folder: {error}", path.display())]
    Folder {
        /// The folder (or a subfolder).
        path: PathBuf,
        /// The I/O error (in the message, not a source, which `{:#}` would print again).
        error: std::io::Error,
    },
    /// Not one file could be used.
    #[error(
        "{}: no usable BVH clips ({} file(s) found{})",
        folder.display(),
        skipped.len(),
        skipped.first().map_or(String::new(), |s| format!("; first problem: {}", s.error))
    )]
    NoClips {
        /// The folder.
        folder: PathBuf,
        /// Every file found, with its problem.
        skipped: Vec<SkippedFile>,
    },
    /// Invalid options.
    #[error("invalid human set options: {0}")]
    Options(String),
}

/// Human clips of a folder tree with their held-out split (see the module docs).
#[derive(Clone, Debug)]
pub struct HumanSet {
    /// The folder the clips were read from.
    pub folder: PathBuf,
    /// Frame rate of the states.
    pub fps: f32,
    /// Usable clips, sorted by relative path.
    pub clips: Vec<HumanSetClip>,
    /// Files that could not be used.
    pub skipped: Vec<SkippedFile>,
    /// The held-out split over `clips`.
    pub split: HumanSplit,
}

impl HumanSet {
    /// `repo_root/../shared/data/human` when that folder exists.
    pub fn default_folder(repo_root: &Path) -> Option<PathBuf> {
        let dir = repo_root.join(DEFAULT_FOLDER);
        dir.is_dir().then_some(dir)
    }

    /// Imports every `.bvh` file below `folder` (see the module docs). `progress` is called on the
    /// calling thread after each file.
    pub fn load(
        folder: &Path,
        opts: &HumanSetOptions,
        progress: &mut dyn FnMut(HumanSetProgress<'_>),
    ) -> Result<HumanSet, HumanSetError> {
        if !(opts.fps.is_finite() && opts.fps > 0.0) {
            return Err(HumanSetError::Options(format!(
                "fps must be positive, not {}",
                opts.fps
            )));
        }
        if !(0.0..1.0).contains(&opts.held_out_fraction) {
            return Err(HumanSetError::Options(format!(
                "held_out_fraction must be in [0, 1), not {}",
                opts.held_out_fraction
            )));
        }
        let files = find_bvh_files(folder)?;
        let results = import_all(folder, &files, opts, progress);

        let mut clips = Vec::new();
        let mut skipped = Vec::new();
        for r in results {
            match r {
                Ok(c) => clips.push(c),
                Err(s) => skipped.push(s),
            }
        }
        if clips.is_empty() {
            return Err(HumanSetError::NoClips {
                folder: folder.to_path_buf(),
                skipped,
            });
        }
        clips.sort_by(|a, b| a.relative.cmp(&b.relative));
        let relative: Vec<&str> = clips.iter().map(|c| c.relative.as_str()).collect();
        let split = HumanSplit::new(&relative, opts.split_seed, opts.held_out_fraction);
        Ok(HumanSet {
            folder: folder.to_path_buf(),
            fps: opts.fps,
            clips,
            skipped,
            split,
        })
    }

    /// The training clips.
    pub fn train_clips(&self) -> impl Iterator<Item = &HumanSetClip> + '_ {
        self.clips.iter().filter(|c| !self.split.is_held_out(&c.relative))
    }

    /// The held-out clips.
    pub fn held_out_clips(&self) -> impl Iterator<Item = &HumanSetClip> + '_ {
        self.clips.iter().filter(|c| self.split.is_held_out(&c.relative))
    }

    /// Frames over all clips.
    pub fn frames(&self) -> usize {
        self.clips.iter().map(|c| c.states.len()).sum()
    }

    /// x^h mean and standard deviation over the training clips' frames.
    pub fn train_statistics(&self) -> HumanStats {
        let flat: Vec<f32> = self
            .train_clips()
            .flat_map(|c| c.states.iter().flatten().copied())
            .collect();
        let (mean, std) = statistics(&flat, layout::DIM);
        HumanStats { mean, std }
    }
}

/// Imports one clip for a set; the error is already a [`SkippedFile`].
pub fn import_clip(folder: &Path, path: &Path, opts: &HumanSetOptions) -> Result<HumanSetClip, SkippedFile> {
    let skip = |error: String| SkippedFile {
        path: path.to_path_buf(),
        error,
    };
    let import = ImportOptions {
        fps: Some(opts.fps),
        mapping: None,
    };
    let clip = HumanClip::from_bvh_file(path, &import).map_err(|e| skip(e.to_string()))?;
    if clip.frames.len() < opts.min_frames.max(2) {
        return Err(skip(format!(
            "{}: {} frame(s) at {} fps, fewer than the {} needed",
            path.display(),
            clip.frames.len(),
            opts.fps,
            opts.min_frames.max(2)
        )));
    }
    let states: Vec<HumanRow> = clip.states().into_iter().map(|s| s.0).collect();
    if let Some(t) = states.iter().position(|r| r.iter().any(|v| !v.is_finite())) {
        return Err(skip(format!(
            "{}: frame {t} has non-finite state values",
            path.display()
        )));
    }
    let relative = path
        .strip_prefix(folder)
        .unwrap_or(path)
        .components()
        .map(|c| c.as_os_str().to_string_lossy())
        .collect::<Vec<_>>()
        .join("/");
    Ok(HumanSetClip {
        name: clip.name.clone(),
        path: path.to_path_buf(),
        relative,
        body_length: human_body_length(&clip),
        states,
    })
}

/// Imports `files` on a few worker threads; results in `files` order.
fn import_all(
    folder: &Path,
    files: &[PathBuf],
    opts: &HumanSetOptions,
    progress: &mut dyn FnMut(HumanSetProgress<'_>),
) -> Vec<Result<HumanSetClip, SkippedFile>> {
    let threads = match opts.threads {
        0 => std::thread::available_parallelism().map_or(1, |n| n.get()),
        n => n,
    }
    .min(files.len().max(1));
    let next = AtomicUsize::new(0);
    let slots: Mutex<Vec<Option<Result<HumanSetClip, SkippedFile>>>> =
        Mutex::new((0..files.len()).map(|_| None).collect());
    let (tx, rx) = mpsc::channel::<usize>();
    std::thread::scope(|s| {
        for _ in 0..threads {
            let tx = tx.clone();
            let (next, slots) = (&next, &slots);
            s.spawn(move || {
                loop {
                    let i = next.fetch_add(1, Ordering::Relaxed);
                    let Some(path) = files.get(i) else { break };
                    let r = import_clip(folder, path, opts);
                    slots.lock().expect("no worker panics while holding the lock")[i] = Some(r);
                    if tx.send(i).is_err() {
                        break;
                    }
                }
            });
        }
        drop(tx);
        for (done, i) in rx.iter().enumerate() {
            progress(HumanSetProgress {
                done: done + 1,
                total: files.len(),
                file: &files[i],
            });
        }
    });
    slots
        .into_inner()
        .expect("workers finished")
        .into_iter()
        .map(|r| r.expect("every file was imported"))
        .collect()
}

/// Every `.bvh` file (any case) below `folder`, in every subfolder, sorted by path: the clips a folder
/// of mocap holds (symlinked folders are followed, each folder once).
pub fn find_bvh_files(folder: &Path) -> Result<Vec<PathBuf>, HumanSetError> {
    let mut files = Vec::new();
    find_bvh(folder, &mut files)?;
    files.sort();
    Ok(files)
}

/// Every `.bvh` file (any case) below `dir`, in every subfolder. Iterative, and each folder is
/// visited once: a symlink loop must neither recurse forever nor list the same clip twice. The
/// metadata macOS leaves in copied and zipped folders (`._walk.bvh` beside each clip, `__MACOSX/`)
/// are not clips.
fn find_bvh(dir: &Path, out: &mut Vec<PathBuf>) -> Result<(), HumanSetError> {
    let mut pending = vec![dir.to_path_buf()];
    let mut seen = std::collections::HashSet::new();
    while let Some(dir) = pending.pop() {
        let err = |error| HumanSetError::Folder {
            path: dir.clone(),
            error,
        };
        if !seen.insert(fs::canonicalize(&dir).map_err(err)?) {
            continue;
        }
        let mut subdirs = Vec::new();
        for entry in fs::read_dir(&dir).map_err(err)? {
            let path = entry.map_err(err)?.path();
            let name = path.file_name().unwrap_or_default().to_string_lossy();
            if name.starts_with("._") || name == "__MACOSX" {
                continue;
            }
            if path.is_dir() {
                subdirs.push(path);
            } else if path.extension().is_some_and(|e| e.eq_ignore_ascii_case("bvh")) {
                out.push(path);
            }
        }
        // Reversed onto the stack, so folders are walked in the order listed, as before.
        pending.extend(subdirs.into_iter().rev());
    }
    Ok(())
}

/// FNV-1a over the path's bytes, then a SplitMix64 finaliser mixed with the seed: stable across
/// platforms and releases (unlike the standard library's hasher).
fn split_hash(relative: &str, seed: u64) -> u64 {
    let mut h: u64 = 0xcbf2_9ce4_8422_2325;
    for b in relative.bytes() {
        h ^= u64::from(b);
        h = h.wrapping_mul(0x0100_0000_01b3);
    }
    let mut z = h ^ seed.wrapping_mul(0x9e37_79b9_7f4a_7c15);
    z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
    z ^ (z >> 31)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn repo() -> PathBuf {
        PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("..")
    }

    /// A folder copied from a Mac holds `._<clip>.bvh` metadata beside each clip and a `__MACOSX`
    /// folder of them in zip files: they were retargeted, failed and failed the batch.
    #[test]
    fn macos_metadata_files_are_not_clips() {
        let dir = std::env::temp_dir().join(format!("ace-find-bvh-{}", std::process::id()));
        let _ = fs::remove_dir_all(&dir);
        for f in ["walk.bvh", "._walk.bvh", "__MACOSX/._walk.bvh", "__MACOSX/run.bvh", "takes/._run.BVH", "takes/run.BVH"] {
            fs::create_dir_all(dir.join(f).parent().unwrap()).unwrap();
            fs::write(dir.join(f), b"\0\x05\x16\x07").unwrap();
        }
        let found = find_bvh_files(&dir).unwrap();
        assert_eq!(found, [dir.join("takes/run.BVH"), dir.join("walk.bvh")]);
        fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn split_is_by_clip_deterministic_and_stable_when_files_are_added() {
        let paths: Vec<String> = (0..400)
            .map(|i| format!("set{}/clip_{i:03}.bvh", i % 7))
            .collect();
        let a = HumanSplit::new(&paths, 3, 0.1);
        assert_eq!(a, HumanSplit::new(&paths, 3, 0.1));
        assert_eq!(a.train.len() + a.held_out.len(), 400);
        // About 10 %: a binomial(400, 0.1) lies in 20..=60 with overwhelming probability.
        assert!(
            (20..=60).contains(&a.held_out.len()),
            "{} held out",
            a.held_out.len()
        );
        // Adding files does not move any existing clip across the split.
        let mut more = paths.clone();
        more.extend((0..100).map(|i| format!("new/extra_{i}.bvh")));
        let b = HumanSplit::new(&more, 3, 0.1);
        for p in &paths {
            assert_eq!(a.is_held_out(p), b.is_held_out(p), "{p}");
        }
        // Another seed gives another split.
        assert_ne!(a.held_out, HumanSplit::new(&paths, 4, 0.1).held_out);
        // Both sides stay non-empty on tiny sets; nothing is held out at fraction 0.
        let two = HumanSplit::new(&["a.bvh", "b.bvh"], 0, 0.1);
        assert_eq!((two.train.len(), two.held_out.len()), (1, 1));
        assert!(HumanSplit::new(&paths, 3, 0.0).held_out.is_empty());
    }

    #[test]
    fn bundled_clips_load_with_states_body_lengths_and_statistics() {
        let folder = repo().join("assets/motions");
        let opts = HumanSetOptions {
            held_out_fraction: 0.3,
            ..HumanSetOptions::default()
        };
        let mut calls = Vec::new();
        let set = HumanSet::load(&folder, &opts, &mut |p| calls.push((p.done, p.total))).unwrap();
        assert_eq!(set.clips.len(), 3, "skipped: {:?}", set.skipped);
        assert_eq!(calls.last(), Some(&(3, 3)));
        let names: Vec<&str> = set.clips.iter().map(|c| c.relative.as_str()).collect();
        assert_eq!(names, ["reach.bvh", "walk.bvh", "wave.bvh"]);
        let walk = &set.clips[1];
        let direct = HumanClip::from_bvh_file(
            &walk.path,
            &ImportOptions {
                fps: Some(30.0),
                mapping: None,
            },
        )
        .unwrap();
        assert_eq!(walk.states.len(), direct.frames.len());
        assert!((1.4..2.1).contains(&walk.body_length), "{}", walk.body_length);
        // Every row is the clip's x^h, the first one included (its velocity from the next frame).
        let want = direct.states();
        assert!(walk.states.iter().zip(&want).all(|(a, b)| *a == b.0));
        // Walking forward at about 1.2 m/s (the clip's pelvis also sways).
        let vx = walk.states[30][layout::ROOT_LINEAR_VELOCITY.start];
        assert!((0.8..1.6).contains(&vx), "forward velocity {vx}");
        // The split holds out whole clips and the statistics cover exactly the training frames.
        assert_eq!(set.train_clips().count() + set.held_out_clips().count(), 3);
        assert!(set.held_out_clips().count() >= 1 && set.train_clips().count() >= 1);
        let stats = set.train_statistics();
        let n: usize = set.train_clips().map(|c| c.states.len()).sum();
        let h = layout::ROOT_HEIGHT.start;
        let mean_h = set
            .train_clips()
            .flat_map(|c| c.states.iter().map(|r| f64::from(r[h])))
            .sum::<f64>()
            / n as f64;
        assert!((f64::from(stats.mean[h]) - mean_h).abs() < 1e-5);
        assert!(stats.std.iter().all(|s| *s >= crate::dataset::STD_FLOOR));
    }

    #[test]
    fn broken_files_are_listed_and_an_empty_folder_is_an_error() {
        let dir = std::env::temp_dir().join(format!("ace_human_set_{}", std::process::id()));
        let _ = fs::remove_dir_all(&dir);
        fs::create_dir_all(dir.join("sub")).unwrap();
        fs::write(dir.join("sub/broken.bvh"), "HIERARCHY\nROOT Hips {\n").unwrap();
        let e = HumanSet::load(&dir, &HumanSetOptions::default(), &mut |_| {}).unwrap_err();
        let msg = e.to_string();
        assert!(
            msg.contains(&dir.display().to_string()) && msg.contains("no usable BVH clips"),
            "{msg}"
        );
        fs::copy(repo().join("assets/motions/wave.bvh"), dir.join("wave.bvh")).unwrap();
        let set = HumanSet::load(&dir, &HumanSetOptions::default(), &mut |_| {}).unwrap();
        assert_eq!(set.clips.len(), 1);
        assert_eq!(set.skipped.len(), 1);
        assert!(
            set.skipped[0].error.contains("broken.bvh"),
            "{}",
            set.skipped[0].error
        );
        let missing =
            HumanSet::load(&dir.join("nope"), &HumanSetOptions::default(), &mut |_| {}).unwrap_err();
        assert!(missing.to_string().contains("nope"), "{missing}");
        fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn shared_human_data_imports_when_present() {
        // One collection only, to stay fast: import and split still run on real files.
        let Some(sub) = crate::test_data::require(repo().join(DEFAULT_FOLDER).join("xia_style"), "the shared xia_style clips")
        else {
            return;
        };
        let set = HumanSet::load(&sub, &HumanSetOptions::default(), &mut |_| {}).unwrap();
        assert!(!set.clips.is_empty());
        for c in &set.clips {
            assert!(c.states.len() >= 2 && c.body_length > 1.0, "{}", c.relative);
        }
        let again = HumanSet::load(&sub, &HumanSetOptions::default(), &mut |_| {}).unwrap();
        assert_eq!(set.split, again.split);
    }
}
