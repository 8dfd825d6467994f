//! The editor's command line: a character file that cannot be opened is an error naming it, before any
//! window opens (no display needed), never a panic.

use std::path::PathBuf;
use std::process::Command;

#[test]
fn a_broken_character_on_the_command_line_is_an_error_naming_it() {
    let dir = PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join("editor-command-line");
    std::fs::create_dir_all(&dir).unwrap();
    let broken = dir.join("broken.glb");
    std::fs::write(&broken, b"glTF\x02\x00\x00\x00 cut short").unwrap();
    for (character, says) in [(broken.to_str().unwrap(), "malformed glTF"), ("dragon", "no character `dragon`")] {
        let out = Command::new(env!("CARGO_BIN_EXE_ace-editor")).args(["--character", character]).output().unwrap();
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(1), "{stderr}");
        assert!(!stderr.contains("panicked"), "{stderr}");
        assert!(stderr.contains(character) && stderr.contains(says), "{stderr}");
    }
}
