//! Where the CLI finds human clips for training and evaluation: `--humans FOLDER`, else the shared
//! mocap beside the project (`../shared/data/human`).

use std::path::{Component, Path, PathBuf};

use ace::models::human_set::{HumanSet, HumanSetOptions};
use anyhow::{Context, Result};

use crate::{characters, progress};

/// The human clip folder: `arg` when given, else the shared mocap beside the project, written without
/// `..` detours (`../shared/data/human` rather than `assets/../../shared/data/human`).
pub fn folder(arg: Option<&Path>) -> Result<PathBuf> {
    match arg {
        Some(f) => Ok(f.to_path_buf()),
        None => HumanSet::default_folder(&characters::assets_dir().join(".."))
            .map(|p| tidy(&p))
            .context("no human clips: ../shared/data/human is missing; pass --humans FOLDER"),
    }
}

/// Imports every clip below `folder` with a progress bar, listing the files it had to skip.
pub fn load(folder: &Path) -> Result<HumanSet> {
    let bar = progress::bar(0, "clips");
    bar.set_message(format!("importing {}", folder.display()));
    let humans = HumanSet::load(folder, &HumanSetOptions::default(), &mut |p| {
        bar.set_length(p.total as u64);
        bar.set_position(p.done as u64);
    })?;
    bar.finish_and_clear();
    for s in &humans.skipped {
        eprintln!("skipped {}: {}", s.path.display(), s.error);
    }
    Ok(humans)
}

/// `path` with `a/..` pairs removed lexically (leading `..` kept).
fn tidy(path: &Path) -> PathBuf {
    let mut out: Vec<Component> = Vec::new();
    for c in path.components() {
        match c {
            Component::CurDir => {}
            Component::ParentDir if matches!(out.last(), Some(Component::Normal(_))) => {
                out.pop();
            }
            c => out.push(c),
        }
    }
    if out.is_empty() { PathBuf::from(".") } else { out.iter().collect() }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn tidy_removes_detours_but_keeps_leading_parents() {
        assert_eq!(tidy(Path::new("assets/../../shared/data/human")), Path::new("../shared/data/human"));
        assert_eq!(tidy(Path::new("/a/b/../c/./d")), Path::new("/a/c/d"));
        assert_eq!(tidy(Path::new("a/..")), Path::new("."));
    }
}
