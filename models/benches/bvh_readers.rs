//! The project's BVH reader against `bvh_anim` (the crate the project's card names): parse
//! throughput on the shared mocap, and what each does with the malformed files of the reliability
//! work, printed as two tables.
//!
//! ```text
//! cargo bench -p ace_models --no-default-features --bench bvh_readers
//! ```
//! Both readers are timed on parsing alone (text to joints and channel values), best of three. Each
//! malformed case runs in a child process of this binary, so a reader that aborts or overflows its
//! stack is reported as a crash instead of ending the run. "Ours" is the whole import
//! (`HumanClip::from_bvh_str`), what a user of the project gets; `bvh_anim` is its parser, which the
//! import would call instead of ours.

use std::path::Path;
use std::process::Command;
use std::time::Instant;

use ace_models::human::bvh::Bvh;
use ace_models::human::{HumanClip, ImportOptions};

#[path = "common/mod.rs"]
mod common;
use common::{bvh_files, shared_data};

/// The bundled walk clip, the base of most malformed cases.
fn walk() -> String {
    std::fs::read_to_string(Path::new(env!("CARGO_MANIFEST_DIR")).join("../assets/motions/walk.bvh")).unwrap()
}

/// A chain of `depth` joints under the root, one frame of motion.
fn deep_chain(depth: usize) -> String {
    let mut s = String::from("HIERARCHY\nROOT Hips\n{\nOFFSET 0 0 0\nCHANNELS 6 Xposition Yposition Zposition Zrotation Xrotation Yrotation\n");
    for i in 0..depth {
        s.push_str(&format!("JOINT j{i}\n{{\nOFFSET 0 1 0\nCHANNELS 3 Zrotation Xrotation Yrotation\n"));
    }
    s.push_str("End Site\n{\nOFFSET 0 1 0\n}\n");
    for _ in 0..=depth {
        s.push_str("}\n");
    }
    s.push_str("MOTION\nFrames: 1\nFrame Time: 0.033333\n");
    s.push_str(&vec!["0"; 6 + 3 * depth].join(" "));
    s.push('\n');
    s
}

/// The walk with its first motion line's values passed through `f(index, value)`.
fn first_frame(f: impl Fn(usize, &str) -> String) -> String {
    let text = walk();
    let mut out = String::new();
    let mut seen_time = false;
    let mut done = false;
    for line in text.lines() {
        if seen_time && !done && !line.trim().is_empty() {
            let values: Vec<String> = line.split_whitespace().enumerate().map(|(i, v)| f(i, v)).collect();
            out.push_str(&values.join(" "));
            done = true;
        } else {
            out.push_str(line);
        }
        seen_time |= line.starts_with("Frame Time");
        out.push('\n');
    }
    out
}

/// The malformed inputs: each a name and the file's bytes.
fn cases() -> Vec<(&'static str, Vec<u8>)> {
    let w = walk();
    let utf16: Vec<u8> = [0xFF, 0xFE].into_iter().chain(w.encode_utf16().flat_map(|u| u.to_le_bytes())).collect();
    vec![
        ("the bundled walk (well-formed)", w.clone().into_bytes()),
        ("`Frames: 1000000000000` in a 150-frame file", w.replace("Frames: 150", "Frames: 1000000000000").into_bytes()),
        ("more motion lines than `Frames:`", w.replace("Frames: 150", "Frames: 149").into_bytes()),
        ("fewer motion lines than `Frames:` (truncated)", w.replace("Frames: 150", "Frames: 151").into_bytes()),
        ("`Frame Time: 1e-9`", w.replace("Frame Time: 0.033333", "Frame Time: 1e-9").into_bytes()),
        ("`Frame Time: 0`", w.replace("Frame Time: 0.033333", "Frame Time: 0").into_bytes()),
        ("a 30,000-deep joint chain", deep_chain(30_000).into_bytes()),
        ("duplicate joint names", w.replacen("JOINT Spine1", "JOINT Spine", 1).into_bytes()),
        ("1e30 as the root's x position", first_frame(|i, v| if i == 0 { "1e30".into() } else { v.into() }).into_bytes()),
        ("NaN in a motion line", first_frame(|i, v| if i == 4 { "NaN".into() } else { v.into() }).into_bytes()),
        ("a word in a motion line", first_frame(|i, v| if i == 4 { "abc".into() } else { v.into() }).into_bytes()),
        ("a motion line one value short", first_frame(|i, v| if i == 0 { String::new() } else { v.into() }).into_bytes()),
        ("a multi-byte character ending a keyword (`Frames\u{e9}:`)", w.replace("Frames:", "Frames\u{e9}:").into_bytes()),
        ("`CHANNELS 7` with six names", w.replacen("CHANNELS 6", "CHANNELS 7", 1).into_bytes()),
        ("an unclosed joint brace", w.replacen("  }\n", "\n", 1).into_bytes()),
        ("no MOTION section", w[..w.find("MOTION").unwrap()].as_bytes().to_vec()),
        ("an empty file", Vec::new()),
        ("UTF-16 with a byte-order mark", utf16),
    ]
}

/// Runs one case in this process (the child's side) and prints one line: `ok N`, or `err MESSAGE`.
fn run_case(reader: &str, index: usize) {
    let (_, bytes) = cases().swap_remove(index);
    let file = format!("case{index}.bvh");
    let line = match reader {
        "ours" => match std::str::from_utf8(&bytes) {
            // Not UTF-8: the reader is handed the file, as the CLI would.
            Err(_) => {
                let dir = std::env::temp_dir().join(format!("ace-bvh-readers-{}", std::process::id()));
                std::fs::create_dir_all(&dir).unwrap();
                let path = dir.join(&file);
                std::fs::write(&path, &bytes).unwrap();
                let result = HumanClip::from_bvh_file(&path, &ImportOptions::default());
                let _ = std::fs::remove_dir_all(&dir);
                match result {
                    Ok(c) => format!("ok {}", c.frames.len()),
                    Err(e) => format!("err {e}"),
                }
            }
            Ok(text) => match HumanClip::from_bvh_str(text, &file, &ImportOptions::default()) {
                Ok(c) => format!("ok {}", c.frames.len()),
                Err(e) => format!("err {e}"),
            },
        },
        _ => match bvh_anim::from_bytes(&bytes) {
            Ok(b) => format!("ok {}", b.frames().len()),
            Err(e) => format!("err {e}"),
        },
    };
    println!("{}", line.replace('\n', " "));
}

/// What a reader did with case `index`, run in a child process: its line, or how the child died.
fn outcome(reader: &str, index: usize) -> String {
    let out = Command::new(std::env::current_exe().unwrap())
        .env("ACE_BVH_CASE", format!("{reader}:{index}"))
        // A reader that allocates from a header count is stopped at 4 GiB, not the machine's memory.
        .env("ACE_BVH_CASE_LIMIT", "1")
        .output()
        .expect("the bench re-runs itself for each case");
    let stdout = String::from_utf8_lossy(&out.stdout);
    match stdout.lines().last() {
        Some(l) if out.status.success() => l.to_string(),
        _ => {
            let stderr = String::from_utf8_lossy(&out.stderr);
            let why = if stderr.contains("memory allocation") || stderr.contains("capacity overflow") {
                "allocation failure".to_string()
            } else if stderr.contains("overflowed its stack") {
                "stack overflow".to_string()
            } else if stderr.contains("panicked") {
                format!("panic: {}", stderr.lines().find(|l| !l.contains("panicked")).unwrap_or("").trim())
            } else {
                format!("{}", out.status)
            };
            format!("crash ({why})")
        }
    }
}

/// A table cell: the outcome, shortened.
fn cell(outcome: &str) -> String {
    let short: String = outcome.chars().take(110).collect();
    let short = if short.len() < outcome.len() { format!("{short}…") } else { short };
    short.replace('|', "\\|")
}

fn limit_memory() {
    // SAFETY: setrlimit on this process only, before any allocation of note.
    #[cfg(target_os = "linux")]
    unsafe {
        #[repr(C)]
        struct Rlimit {
            cur: u64,
            max: u64,
        }
        unsafe extern "C" {
            fn setrlimit(resource: i32, rlim: *const Rlimit) -> i32;
        }
        const RLIMIT_AS: i32 = 9;
        let gib4 = 4u64 << 30;
        setrlimit(RLIMIT_AS, &Rlimit { cur: gib4, max: gib4 });
    }
}

fn main() {
    if let Ok(case) = std::env::var("ACE_BVH_CASE") {
        if std::env::var("ACE_BVH_CASE_LIMIT").is_ok() {
            limit_memory();
        }
        let (reader, index) = case.split_once(':').unwrap();
        run_case(reader, index.parse().unwrap());
        return;
    }
    let mut files = Vec::new();
    bvh_files(&shared_data().join("human"), &mut files);
    if files.is_empty() {
        eprintln!("no BVH files under {}; the shared data must stand beside the project", shared_data().display());
        std::process::exit(1);
    }
    let texts: Vec<(String, String)> =
        files.iter().map(|p| (p.display().to_string(), std::fs::read_to_string(p).unwrap())).collect();
    let bytes: usize = texts.iter().map(|(_, t)| t.len()).sum();

    println!("| reader (parse only) | files parsed | frames | time (best of 3) | throughput |");
    println!("|---|---:|---:|---:|---:|");
    let time = |parse: &dyn Fn(&str, &str) -> Option<usize>| {
        let mut best = f64::MAX;
        let (mut parsed, mut frames) = (0, 0);
        for _ in 0..3 {
            let start = Instant::now();
            let counts: Vec<usize> = texts.iter().filter_map(|(n, t)| parse(t, n)).collect();
            best = best.min(start.elapsed().as_secs_f64());
            (parsed, frames) = (counts.len(), counts.iter().sum());
        }
        (parsed, frames, best)
    };
    let rows: [(&str, &dyn Fn(&str, &str) -> Option<usize>); 2] = [
        ("ours (`Bvh::parse`)", &|t, n| Bvh::parse(t, n).ok().map(|b| b.frame_count)),
        ("`bvh_anim` 0.4 (`from_bytes`)", &|t, _| bvh_anim::from_bytes(t.as_bytes()).ok().map(|b| b.frames().len())),
    ];
    for (name, parse) in rows {
        let (parsed, frames, best) = time(parse);
        println!(
            "| {name} | {parsed} of {} | {frames} | {best:.3} s | {:.0} MB/s |",
            texts.len(),
            bytes as f64 / 1e6 / best
        );
    }

    println!();
    println!("| malformed input | ours (the whole import) | `bvh_anim` |");
    println!("|---|---|---|");
    for (index, (name, _)) in cases().iter().enumerate() {
        println!("| {name} | {} | {} |", cell(&outcome("ours", index)), cell(&outcome("bvh_anim", index)));
    }
}
