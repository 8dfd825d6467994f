//! How every command writes: never over a file it read, and its outputs as a set.
//!
//! - [`Outputs::input`] records each file or directory a command reads (the clip, the checkpoint
//!   directory, the config, the character), and also those read implicitly ([`Outputs::input_clip`]:
//!   the joint-mapping file beside a clip; [`Outputs::input_character`]: the profile beside a
//!   character, a URDF's mesh files, a `.gltf` creature's buffers and images); [`Outputs::check`] refuses an output path
//!   that is one of them (same file, also through a symlink or a hard link) or lies inside an input
//!   directory, or that is a directory where a file is written.
//! - [`Planned`] gathers every output path of a command with what writes it, before any work: two
//!   writers of one path (two clips' derived files, `--out x.json`) are refused, naming both.
//! - [`Outputs::stage`] and [`Outputs::stage_dir`] hand out a temporary sibling of each output
//!   (`.<name>.ace-tmp-<pid>`); the command writes there, and [`Outputs::commit`] renames every one of
//!   them into place only after all were written. On an error, dropping the [`Outputs`] removes the
//!   temporaries: nothing new is left and the previous outputs stay as they were.
//! - [`install_signal_cleanup`] removes the live temporaries on SIGINT and SIGTERM; temporaries of
//!   runs killed harder (SIGKILL, power loss) are removed by the next run that writes beside them
//!   ([`remove_stale_temporaries`]).

use std::collections::BTreeSet;
use std::fs;
use std::path::{Path, PathBuf};
use std::sync::Mutex;

use ace::models::temporary::pid_of as temporary_pid;
use anyhow::{Context, Result, bail};

/// Temporaries of this process not yet renamed into place, for the signal handler.
static LIVE: Mutex<BTreeSet<PathBuf>> = Mutex::new(BTreeSet::new());

/// Folders whose writers make their own temporaries (training's checkpoint directories), swept by the
/// signal handler for this process' ([`watch_dir`]).
static WATCHED: Mutex<BTreeSet<PathBuf>> = Mutex::new(BTreeSet::new());

/// Installs a SIGINT/SIGTERM handler that removes this process' live temporaries (and those in the
/// [`watch_dir`] folders) and exits with status 130. Call once, at start-up.
pub fn install_signal_cleanup() {
    let _ = ctrlc::set_handler(|| {
        // LIVE stays locked until the process is gone: no output is staged or committed after the
        // sweep.
        let live = LIVE.lock().unwrap_or_else(|e| e.into_inner());
        remove_live_temporaries(&live);
        let watched = WATCHED.lock().unwrap_or_else(|e| e.into_inner());
        for dir in watched.iter() {
            remove_own_temporaries(dir);
        }
        eprintln!("interrupted: temporary outputs removed, previous outputs left as they were");
        // `_exit`, not `exit`: the main thread is still running (generating a dataset, inside
        // libtorch), and `exit` would run atexit handlers and libtorch's static destructors under it,
        // which crashed the process now and then (killed by a signal instead of exiting with 130).
        // SAFETY: `_exit` ends the process at once; nothing runs after it.
        unsafe { libc::_exit(130) }
    });
}

/// Removes the live temporaries and, beside them, those of the writers underneath (named with this
/// process' id, see [`remove_stale_temporaries`]).
fn remove_live_temporaries(live: &BTreeSet<PathBuf>) {
    for p in live.iter() {
        let _ = if p.is_dir() {
            fs::remove_dir_all(p)
        } else {
            fs::remove_file(p)
        };
        let Some(dir) = p.parent() else { continue };
        remove_own_temporaries(dir);
    }
}

/// Removes this process' temporaries in `dir` (named with its id, see [`remove_stale_temporaries`]).
fn remove_own_temporaries(dir: &Path) {
    let me = std::process::id();
    for e in fs::read_dir(dir).into_iter().flatten().flatten() {
        if temporary_pid(&e.file_name().to_string_lossy()) == Some(me) {
            let q = e.path();
            let _ = if q.is_dir() {
                fs::remove_dir_all(&q)
            } else {
                fs::remove_file(&q)
            };
        }
    }
}

/// For a folder a command writes into through writers of its own (training's checkpoint directory,
/// whose weights and records are saved under temporary names and renamed): removes the temporaries
/// that runs killed harder left there ([`remove_stale_temporaries`]) and has the signal handler
/// remove this process' on SIGINT or SIGTERM.
pub fn watch_dir(dir: &Path) {
    remove_stale_temporaries(dir);
    let dir = fs::canonicalize(dir).unwrap_or_else(|_| dir.to_path_buf());
    WATCHED.lock().unwrap_or_else(|e| e.into_inner()).insert(dir);
}

/// The output paths a command will write, each with what writes it, gathered before any work: two
/// writers of one path (`a/walk.bvh` and `b/walk.metrics.bvh` both making `walk.metrics.json`, or
/// `walk.bvh` and `walk.BVH` both making `walk.glb`) are refused up front, naming both. Paths that
/// differ only in case count as one, as they are on the file systems that ignore it.
#[derive(Debug, Default)]
pub struct Planned {
    seen: std::collections::HashMap<String, (PathBuf, String)>,
}

impl Planned {
    /// No paths yet.
    pub fn new() -> Planned {
        Planned::default()
    }

    /// Records that `writer` (e.g. "the trajectory of a/walk.bvh") writes `path`; fails, naming both
    /// writers and ending with `advice`, when another already does.
    pub fn add(&mut self, path: &Path, writer: String, advice: &str) -> Result<()> {
        let key = lexical(path).to_string_lossy().to_lowercase();
        if let Some((first, other)) = self.seen.get(&key) {
            let case = if first != path { format!(" (as {}: output names ignore case)", first.display()) } else { String::new() };
            bail!(
                "{}: both {other} and {writer} would be written there{case}; {advice}",
                path.display()
            );
        }
        self.seen.insert(key, (path.to_path_buf(), writer));
        Ok(())
    }

    /// The paths recorded, in no particular order.
    pub fn paths(&self) -> impl Iterator<Item = &Path> + '_ {
        self.seen.values().map(|(p, _)| p.as_path())
    }
}

/// `path` with `.` components dropped and `a/..` pairs folded, without touching the file system.
fn lexical(path: &Path) -> PathBuf {
    use std::path::Component;
    let mut out = PathBuf::new();
    for c in path.components() {
        match c {
            Component::CurDir => {}
            Component::ParentDir if matches!(out.components().next_back(), Some(Component::Normal(_))) => {
                out.pop();
            }
            c => out.push(c),
        }
    }
    out
}

/// An input a command read.
#[derive(Debug)]
struct Input {
    path: PathBuf,
    canonical: PathBuf,
    is_dir: bool,
    what: String,
}

/// The inputs a command read and the outputs it is writing (see the module docs).
#[derive(Debug, Default)]
pub struct Outputs {
    inputs: Vec<Input>,
    /// (temporary, final) pairs, in the order staged.
    staged: Vec<(PathBuf, PathBuf)>,
}

impl Outputs {
    /// No inputs and no outputs yet.
    pub fn new() -> Outputs {
        Outputs::default()
    }

    /// Records that the command reads `path` (a file or a directory; `what` names it in errors, e.g.
    /// "the input clip"). A path that does not exist is ignored.
    pub fn input(&mut self, path: &Path, what: &str) -> &mut Outputs {
        if let Ok(canonical) = fs::canonicalize(path) {
            self.inputs.push(Input {
                path: path.to_path_buf(),
                is_dir: canonical.is_dir(),
                canonical,
                what: what.to_string(),
            });
        }
        self
    }

    /// Records a clip and the joint-mapping file read with it: `mapping` (`--mapping`) when given, else
    /// `<clip>.mapping.toml` beside it, which the importer reads when it is there.
    pub fn input_clip(&mut self, clip: &Path, what: &str, mapping: Option<&Path>) -> &mut Outputs {
        self.input(clip, what);
        match mapping {
            Some(m) => self.input(m, "the joint-mapping file"),
            None => {
                let beside = ace::models::human::clip::mapping_path_beside(clip);
                self.input(&beside, &format!("the joint-mapping file read with {}", clip.display()))
            }
        }
    }

    /// Records a character file (`--character`: a URDF or a glTF creature) and the files read with
    /// it: the profile beside it (`<name>.profile.toml`), a URDF's mesh files and a `.gltf` creature's
    /// external buffers and images.
    pub fn input_character(&mut self, path: &Path) -> &mut Outputs {
        self.input(path, "the character file");
        let profile = ace::models::morphology::Profile::path_beside(path);
        self.input(&profile, "the character's profile");
        if ace::models::character::is_gltf(path) {
            // The character was loaded from it already, so it parses; were it to fail now, loading it
            // again would fail before anything is written.
            for f in ace::models::character::gltf::external_files(path).unwrap_or_default() {
                self.input(&f, "a file of the character's model (buffer or image)");
            }
        } else {
            for f in ace::models::urdf::mesh_files(path) {
                self.input(&f, "a mesh file of the character");
            }
        }
        self
    }

    /// Fails, naming both, when writing the file `out` would overwrite an input or write inside an
    /// input directory; also when `out` is a directory (renaming a file onto it would fail after the
    /// other outputs were already in place).
    pub fn check(&self, out: &Path) -> Result<()> {
        self.check_inputs(out)?;
        if out.is_dir() {
            bail!(
                "{}: refusing to write there: it is a directory, and this output is a file; remove the directory \
                 or choose another output path",
                out.display()
            );
        }
        // `out/` names a folder, which the rename into place at the end could not make a file of.
        if out.as_os_str().to_string_lossy().ends_with(std::path::MAIN_SEPARATOR) {
            bail!("{}: a folder's name (it ends in `{}`), and this output is a file: give a file name", out.display(), std::path::MAIN_SEPARATOR);
        }
        Ok(())
    }

    /// [`Outputs::check`] for an output folder (`out` may be a folder, but not a file).
    pub fn check_dir(&self, out: &Path) -> Result<()> {
        self.check_inputs(out)?;
        if out.exists() && !out.is_dir() {
            bail!(
                "{}: refusing to write there: it is a file, and this output is a folder; choose another output path",
                out.display()
            );
        }
        Ok(())
    }

    /// Fails, naming both, when writing `out` would overwrite an input or write inside an input
    /// directory.
    fn check_inputs(&self, out: &Path) -> Result<()> {
        let target = resolve(out)?;
        for i in &self.inputs {
            let same = target == i.canonical || same_file(&target, &i.canonical);
            if same {
                bail!(
                    "{}: refusing to write there: it is {} ({}) this command reads; choose another output path",
                    out.display(),
                    i.what,
                    i.path.display()
                );
            }
            if i.is_dir && target.starts_with(&i.canonical) {
                bail!(
                    "{}: refusing to write there: it is inside {} ({}) this command reads, whose files it \
                     would overwrite; choose an output path outside it",
                    out.display(),
                    i.what,
                    i.path.display()
                );
            }
        }
        Ok(())
    }

    /// The temporary sibling to write `out` into (checked with [`Outputs::check`]; its folder is
    /// created, and stale temporaries of killed runs in it are removed).
    pub fn stage(&mut self, out: &Path) -> Result<PathBuf> {
        self.check(out)?;
        self.stage_checked(out)
    }

    /// [`Outputs::stage`] once `out` is checked.
    fn stage_checked(&mut self, out: &Path) -> Result<PathBuf> {
        if self.staged.iter().any(|(_, f)| f == out) {
            bail!("{}: written twice by the same command", out.display());
        }
        let parent = out
            .parent()
            .filter(|p| !p.as_os_str().is_empty())
            .unwrap_or(Path::new("."));
        fs::create_dir_all(parent)
            .with_context(|| format!("{}: cannot create its folder {}", out.display(), parent.display()))?;
        remove_stale_temporaries(parent);
        let name = out
            .file_name()
            .with_context(|| format!("{}: not a file name", out.display()))?;
        // The temporary keeps the output's extension: writers pick the format by it (`.gltf` is JSON).
        let tmp = ace::models::temporary::beside(&parent.join(name), out.extension().and_then(|e| e.to_str()));
        LIVE.lock().unwrap_or_else(|e| e.into_inner()).insert(tmp.clone());
        if tmp.is_dir() {
            let _ = fs::remove_dir_all(&tmp);
        } else {
            let _ = fs::remove_file(&tmp);
        }
        self.staged.push((tmp.clone(), out.to_path_buf()));
        Ok(tmp)
    }

    /// [`Outputs::stage`] for a folder: the command writes the folder's files into the returned
    /// (created, empty) temporary folder; [`Outputs::commit`] moves each of them into `dir`, keeping the
    /// files of `dir` it did not write.
    pub fn stage_dir(&mut self, dir: &Path) -> Result<PathBuf> {
        self.check_dir(dir)?;
        let tmp = self.stage_checked(dir)?;
        fs::create_dir_all(&tmp)
            .with_context(|| format!("{}: cannot create the folder {}", dir.display(), tmp.display()))?;
        Ok(tmp)
    }

    /// Renames every staged output into place, in the order staged. Before the first rename, every
    /// target is checked again: a file output whose path has become a directory, or a folder output
    /// whose path has become a file, fails the commit with nothing renamed (the temporaries are
    /// removed). (Renames within a folder do not fail for want of space; should one still fail, the
    /// outputs not yet renamed are removed.)
    pub fn commit(mut self) -> Result<()> {
        for (tmp, out) in &self.staged {
            if tmp.is_dir() {
                if out.exists() && !out.is_dir() {
                    bail!("{}: cannot write this folder there: it is a file now; nothing was written", out.display());
                }
            } else if out.is_dir() {
                bail!(
                    "{}: cannot write this file there: it is a directory now; nothing was written",
                    out.display()
                );
            }
        }
        // LIVE is held across every rename, so the signal handler runs before the first (nothing new
        // is left) or after the last (the whole set is in place), never between two. It is released
        // before `self` drops, whose cleanup takes it again.
        let mut live = LIVE.lock().unwrap_or_else(|e| e.into_inner());
        while !self.staged.is_empty() {
            let (tmp, out) = self.staged.remove(0);
            let moved = if tmp.is_dir() {
                merge_dir(&tmp, &out)
            } else {
                fs::rename(&tmp, &out)
            };
            if tmp.is_dir() {
                let _ = fs::remove_dir_all(&tmp);
            }
            live.remove(&tmp);
            if let Err(e) = moved {
                drop(live);
                return Err(e).with_context(|| format!("moving {} into place as {}", tmp.display(), out.display()));
            }
        }
        Ok(())
    }
}

impl Drop for Outputs {
    /// Removes the temporaries of outputs never committed (the command failed).
    fn drop(&mut self) {
        let mut live = LIVE.lock().unwrap_or_else(|e| e.into_inner());
        for (tmp, _) in &self.staged {
            let _ = if tmp.is_dir() {
                fs::remove_dir_all(tmp)
            } else {
                fs::remove_file(tmp)
            };
            live.remove(tmp);
        }
    }
}

/// Moves the files of `from` into `to` (created when missing), subfolders recursively.
fn merge_dir(from: &Path, to: &Path) -> std::io::Result<()> {
    // Iterative: the depth is our own outputs' (a folder or two), but a walk never needs the stack.
    let mut pending = vec![(from.to_path_buf(), to.to_path_buf())];
    while let Some((src, dst)) = pending.pop() {
        fs::create_dir_all(&dst)?;
        for e in fs::read_dir(&src)? {
            let e = e?;
            let target = dst.join(e.file_name());
            if e.file_type()?.is_dir() {
                pending.push((e.path(), target));
            } else {
                fs::rename(e.path(), &target)?;
            }
        }
    }
    Ok(())
}

/// `path` made absolute with symlinks resolved as far as it exists (the rest appended as given).
fn resolve(path: &Path) -> Result<PathBuf> {
    let abs = if path.is_absolute() {
        path.to_path_buf()
    } else {
        std::env::current_dir()
            .context("reading the current directory")?
            .join(path)
    };
    let mut rest = Vec::new();
    let mut base = abs.as_path();
    loop {
        if let Ok(c) = fs::canonicalize(base) {
            let mut p = c;
            for part in rest.iter().rev() {
                p.push(part);
            }
            return Ok(p);
        }
        match (base.parent(), base.file_name()) {
            (Some(parent), Some(name)) => {
                rest.push(name.to_os_string());
                base = parent;
            }
            _ => return Ok(abs),
        }
    }
}

/// Whether two existing paths are the same file (hard links included).
fn same_file(a: &Path, b: &Path) -> bool {
    #[cfg(unix)]
    {
        use std::os::unix::fs::MetadataExt;
        match (fs::metadata(a), fs::metadata(b)) {
            (Ok(x), Ok(y)) => x.dev() == y.dev() && x.ino() == y.ino(),
            _ => false,
        }
    }
    #[cfg(not(unix))]
    {
        let _ = (a, b);
        false
    }
}

/// Removes temporaries left in `dir` by runs that no longer exist (killed with SIGKILL, say): the
/// files and folders named as [`ace::models::temporary`] names them whose process is gone. Only
/// where processes can be looked up (`/proc`).
pub fn remove_stale_temporaries(dir: &Path) {
    if !Path::new("/proc/self").exists() {
        return;
    }
    let Ok(entries) = fs::read_dir(dir) else { return };
    for e in entries.flatten() {
        let name = e.file_name().to_string_lossy().into_owned();
        let Some(pid) = temporary_pid(&name) else { continue };
        if pid == std::process::id() || Path::new(&format!("/proc/{pid}")).exists() {
            continue;
        }
        let p = e.path();
        let _ = if p.is_dir() {
            fs::remove_dir_all(&p)
        } else {
            fs::remove_file(&p)
        };
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `--out trail/` failed only at the end, when the rename into place could not make a file of it.
    #[test]
    fn an_output_named_like_a_folder_is_refused_before_any_work() {
        let dir = std::env::temp_dir().join(format!("ace-output-slash-{}", std::process::id()));
        let outputs = Outputs::new();
        for name in ["trail/", "x.gltf/"] {
            let out = PathBuf::from(format!("{}/{name}", dir.display()));
            let e = outputs.check(&out).unwrap_err().to_string();
            assert!(e.starts_with(&out.display().to_string()) && e.contains("a folder's name (it ends in `/`)"), "{e}");
        }
        outputs.check(&dir.join("trail")).unwrap();
        assert!(!dir.exists(), "checking writes nothing");
    }

    #[test]
    fn a_commit_onto_a_directory_renames_nothing() {
        let dir = std::env::temp_dir().join(format!("ace-output-commit-{}", std::process::id()));
        let _ = fs::remove_dir_all(&dir);
        fs::create_dir_all(&dir).unwrap();
        let (glb, metrics) = (dir.join("out.glb"), dir.join("out.metrics.json"));
        fs::write(&glb, b"previous").unwrap();
        let mut outputs = Outputs::new();
        fs::write(outputs.stage(&glb).unwrap(), b"new").unwrap();
        fs::write(outputs.stage(&metrics).unwrap(), b"new").unwrap();
        // A directory appears where the second output goes, after it was staged: the commit checks
        // every target before its first rename.
        fs::create_dir(&metrics).unwrap();
        assert_eq!(
            outputs.commit().unwrap_err().to_string(),
            format!("{}: cannot write this file there: it is a directory now; nothing was written", metrics.display())
        );
        assert_eq!(fs::read(&glb).unwrap(), b"previous");
        let mut names: Vec<String> = fs::read_dir(&dir).unwrap().map(|e| e.unwrap().file_name().to_string_lossy().into_owned()).collect();
        names.sort();
        assert_eq!(names, ["out.glb", "out.metrics.json"], "the temporaries are gone");
        // Staged or checked up front, it is refused before anything is written.
        let refused = format!(
            "{}: refusing to write there: it is a directory, and this output is a file; remove the directory or \
             choose another output path",
            metrics.display()
        );
        assert_eq!(Outputs::new().stage(&metrics).unwrap_err().to_string(), refused);
        assert_eq!(Outputs::new().check(&metrics).unwrap_err().to_string(), refused);
        fs::remove_dir_all(&dir).unwrap();
    }

    /// The signal handler takes LIVE before it removes temporaries and exits, so what another thread
    /// sees under LIVE is what a SIGINT during a commit would leave: the whole new set or none of it.
    #[test]
    fn under_the_signal_handlers_lock_a_commit_is_whole_or_not_begun() {
        use std::sync::Arc;
        use std::sync::atomic::{AtomicBool, Ordering};
        let dir = std::env::temp_dir().join(format!("ace-output-whole-{}", std::process::id()));
        let _ = fs::remove_dir_all(&dir);
        fs::create_dir_all(&dir).unwrap();
        let (glb, json) = (dir.join("o.glb"), dir.join("o.json"));
        fs::write(&glb, "0").unwrap();
        fs::write(&json, "0").unwrap();
        let stop = Arc::new(AtomicBool::new(false));
        let looker = {
            let (stop, glb, json) = (stop.clone(), glb.clone(), json.clone());
            std::thread::spawn(move || {
                let mut mixed = Vec::new();
                while !stop.load(Ordering::Relaxed) {
                    let _live = LIVE.lock().unwrap_or_else(|e| e.into_inner());
                    let (a, b) = (fs::read(&glb).ok(), fs::read(&json).ok());
                    if a != b {
                        mixed.push((a, b));
                    }
                }
                mixed
            })
        };
        for k in 1..=300 {
            let mut outputs = Outputs::new();
            fs::write(outputs.stage(&glb).unwrap(), k.to_string()).unwrap();
            fs::write(outputs.stage(&json).unwrap(), k.to_string()).unwrap();
            outputs.commit().unwrap();
        }
        stop.store(true, Ordering::Relaxed);
        let mixed = looker.join().unwrap();
        assert!(mixed.is_empty(), "{} looks saw a new output beside an old one, e.g. {:?}", mixed.len(), mixed.first());
        assert_eq!(fs::read(&json).unwrap(), b"300");
        fs::remove_dir_all(&dir).unwrap();
    }

}
