//! Temporary files. Every writer writes its file under a temporary name beside it and renames it
//! into place, so that no reader sees half a file. The name, `.<file>.ace-tmp-<pid>` (with an
//! extension after it where a library picks the format by it), marks the file as the project's and
//! says which process wrote it: a later run removes those whose process is gone, and never touches a
//! user's own files, whatever they are called (`.notes.2024.tmp`, `.draft.tmp-7`).

use std::ffi::OsString;
use std::io::Write;
use std::path::{Path, PathBuf};

/// The marker in every temporary's name.
pub const MARKER: &str = "ace-tmp";

/// The temporary of `path` for this process: `.<file name>.ace-tmp-<pid>` beside it, then `.<ext>`
/// when given (libtorch picks a weights file's format by its extension).
pub fn beside(path: &Path, ext: Option<&str>) -> PathBuf {
    let mut name = OsString::from(".");
    name.push(path.file_name().unwrap_or_default());
    name.push(format!(".{MARKER}-{}", std::process::id()));
    if let Some(ext) = ext {
        name.push(".");
        name.push(ext);
    }
    path.with_file_name(name)
}

/// Writes `bytes` to `path` as a whole: into its temporary ([`beside`]), flushed to disk, then renamed
/// over `path`. On failure the temporary is removed and `path` is left as it was. A path that names
/// no file is refused.
pub fn write_atomically(path: &Path, bytes: &[u8]) -> std::io::Result<()> {
    if path.file_name().is_none() {
        return Err(std::io::Error::other("the path names no file"));
    }
    let tmp = beside(path, None);
    let result = (|| {
        let mut f = std::fs::File::create(&tmp)?;
        f.write_all(bytes)?;
        f.sync_all()?;
        std::fs::rename(&tmp, path)
    })();
    if result.is_err() {
        let _ = std::fs::remove_file(&tmp);
    }
    result
}

/// The process id in the name of a temporary ([`beside`]); `None` for any other name.
pub fn pid_of(name: &str) -> Option<u32> {
    let rest = name.strip_prefix('.')?;
    let mark = format!(".{MARKER}-");
    let at = rest.rfind(&mark)?;
    let tail = &rest[at + mark.len()..];
    let digits = tail.find(|c: char| !c.is_ascii_digit()).unwrap_or(tail.len());
    let after = &tail[digits..];
    if at == 0 || digits == 0 || !(after.is_empty() || after.starts_with('.')) {
        return None;
    }
    tail[..digits].parse().ok()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_temporary_names_its_file_and_process_and_nothing_else_is_one() {
        let me = std::process::id();
        let tmp = beside(Path::new("ck/generator.safetensors"), Some("safetensors"));
        assert_eq!(tmp, PathBuf::from(format!("ck/.generator.safetensors.ace-tmp-{me}.safetensors")));
        assert_eq!(beside(Path::new("walk.glb"), None), PathBuf::from(format!(".walk.glb.ace-tmp-{me}")));
        for name in [format!(".walk.glb.ace-tmp-{me}"), format!(".prior.safetensors.ace-tmp-{me}.safetensors")] {
            assert_eq!(pid_of(&name), Some(me), "{name}");
        }
        // A user's files, however close to one.
        for name in [
            "walk.glb",
            ".notes.txt",
            ".draft.2019.tmp",
            ".x.tmp-2024",
            ".walk.glb.4242.tmp",
            "walk.glb.ace-tmp-12",
            ".ace-tmp-12",
            ".walk.glb.ace-tmp-",
            ".walk.glb.ace-tmp-12x",
            ".walk.glb.ace-tmp-99999999999",
        ] {
            assert_eq!(pid_of(name), None, "{name}");
        }
    }

    #[test]
    fn an_atomic_write_replaces_the_file_or_leaves_it_and_no_temporary() {
        let dir = std::env::temp_dir().join(format!("ace_temporary_{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(dir.join("taken/inside")).unwrap();
        let file = dir.join("out.json");
        std::fs::write(&file, b"old").unwrap();
        write_atomically(&file, b"new").unwrap();
        assert_eq!(std::fs::read(&file).unwrap(), b"new");
        // A folder in the way (renaming a file over a non-empty folder fails): it stays, and so
        // does nothing of the write.
        assert!(write_atomically(&dir.join("taken"), b"new").is_err());
        assert!(dir.join("taken/inside").is_dir());
        let left: Vec<_> = std::fs::read_dir(&dir).unwrap().map(|e| e.unwrap().file_name()).collect();
        assert_eq!(left.len(), 2, "{left:?}");
        assert!(write_atomically(Path::new("/"), b"x").unwrap_err().to_string().contains("names no file"));
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
