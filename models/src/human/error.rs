//! Errors of the human motion importer. Every message names the file (or clip name) and the problem.

/// Why a BVH clip (or a joint-mapping file) could not be imported.
#[derive(Debug, thiserror::Error)]
pub enum HumanImportError {
    /// The file could not be read.
    #[error("{file}: cannot read: {error}")]
    Io {
        file: String,
        /// In the message, not a source, which `{:#}` would print again.
        error: std::io::Error,
    },
    /// Malformed BVH text: bad keyword, unbalanced braces, non-numeric value, wrong value count, …
    #[error("{file}, line {line}: {}", printable(message))]
    Parse {
        file: String,
        line: usize,
        message: String,
    },
    /// Fewer motion lines than the `Frames:` header declares.
    #[error(
        "{file}, line {line}: truncated: `Frames: {declared}` declared but only {found} motion lines present"
    )]
    Truncated {
        file: String,
        line: usize,
        declared: usize,
        found: usize,
    },
    /// Some canonical joints could not be matched to BVH joints.
    #[error(
        "{file}: unknown skeleton: could not map canonical joint(s) {}; BVH joints available: {}. \
         Name them in a joint-mapping file (e.g. `left_hand = \"MyLeftWrist\"`), passed with --mapping FILE \
         or saved as `<clip>.mapping.toml` beside the clip.",
        missing.join(", "),
        short_list(available)
    )]
    Unmapped {
        file: String,
        missing: Vec<String>,
        available: Vec<String>,
    },
    /// A joint-mapping file (or its use on a clip) is invalid.
    #[error("{file}: invalid joint mapping: {message}")]
    Mapping { file: String, message: String },
    /// The skeleton or motion is unusable (degenerate bones, no frames, implausible geometry).
    #[error("{file}: {message}")]
    Skeleton { file: String, message: String },
}

/// Names joined by commas; past 60, the first 60 and how many more (a 100,000-joint file must not
/// make a 2 MB message).
pub fn short_list(names: &[String]) -> String {
    const SHOWN: usize = 60;
    if names.len() <= SHOWN {
        names.join(", ")
    } else {
        format!(
            "{}, … and {} more",
            names[..SHOWN].join(", "),
            names.len() - SHOWN
        )
    }
}

/// `text` with its control characters escaped (`\u{0}`, `\t`): a message quotes what it found, and a
/// binary file (macOS's `._walk.bvh`) put NUL bytes and escape sequences on the terminal.
pub(crate) fn printable(text: &str) -> String {
    text.chars().map(|c| if c.is_control() { c.escape_default().to_string() } else { c.to_string() }).collect()
}
