//! Checkpoint files as bytes: the records that tie metadata to weights files (size and checksum), the
//! checkpoint's files on disk or in memory, JSON metadata checked for kind and version, and safetensors
//! weights checked against the shapes a configuration gives (`read_weights`).

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use safetensors::{Dtype, SafeTensors};
use serde::de::DeserializeOwned;
use serde::{Deserialize, Serialize};
use serde_json::Value;

use super::LearnError;

/// A weights file's size and FNV-1a 64 checksum.
#[derive(Clone, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct FileRecord {
    /// File name inside the checkpoint directory.
    pub file: String,
    /// Size in bytes.
    pub bytes: u64,
    /// FNV-1a 64 of the content, 16 hex digits.
    pub fnv1a64: String,
}

impl FileRecord {
    /// The record of `bytes` stored as `file`.
    pub fn of(file: &str, bytes: &[u8]) -> FileRecord {
        FileRecord {
            file: file.into(),
            bytes: bytes.len() as u64,
            fnv1a64: format!("{:016x}", fnv1a64(bytes)),
        }
    }

    /// Whether `other` records the same content (size and checksum), whatever the file names.
    pub fn same_content(&self, other: &FileRecord) -> bool {
        self.bytes == other.bytes && self.fnv1a64 == other.fnv1a64
    }

    /// Fails with [`LearnError::CorruptFile`] naming `path` unless `bytes` match the record.
    pub fn verify(&self, path: &Path, bytes: &[u8], recorded_in: &str) -> Result<(), LearnError> {
        if *self == FileRecord::of(&self.file, bytes) {
            return Ok(());
        }
        Err(LearnError::CorruptFile {
            path: path.into(),
            problem: format!(
                "its content differs from the one `{recorded_in}` records ({} bytes, checksum {}); the \
                 files are not from the same save",
                self.bytes, self.fnv1a64
            ),
        })
    }
}

/// FNV-1a, 64 bits: a cheap checksum that ties a metadata file to the weights files it records.
pub(crate) fn fnv1a64(bytes: &[u8]) -> u64 {
    bytes.iter().fold(0xcbf2_9ce4_8422_2325u64, |h, &b| {
        (h ^ u64::from(b)).wrapping_mul(0x0000_0100_0000_01b3)
    })
}

/// Reads a whole regular file ([`crate::input::read_regular`]: a FIFO or a directory is refused
/// without being opened); a missing one is [`LearnError::MissingFile`].
pub(crate) fn read_file(path: &Path) -> Result<Vec<u8>, LearnError> {
    use crate::input::ReadError;
    crate::input::read_regular(path, crate::input::MAX_DATA_BYTES).map_err(|e| match e {
        e if e.is_not_found() => LearnError::MissingFile { path: path.into() },
        ReadError::Io(e) => LearnError::io(path, e),
        other => LearnError::Format {
            path: path.into(),
            problem: other.to_string(),
        },
    })
}

/// The files of a checkpoint directory, read from disk or handed over in memory (by an asset reader,
/// say). Either way errors name `dir/<file>`.
#[derive(Clone, Debug)]
pub struct CheckpointFiles {
    dir: PathBuf,
    memory: Option<BTreeMap<String, Vec<u8>>>,
}

impl CheckpointFiles {
    /// The files in directory `dir`.
    pub fn on_disk(dir: &Path) -> CheckpointFiles {
        CheckpointFiles {
            dir: dir.to_path_buf(),
            memory: None,
        }
    }

    /// Files already read, by file name; `dir` is where they came from, for messages.
    pub fn in_memory(dir: &Path, files: BTreeMap<String, Vec<u8>>) -> CheckpointFiles {
        CheckpointFiles {
            dir: dir.to_path_buf(),
            memory: Some(files),
        }
    }

    /// The directory (the source, for files in memory).
    pub fn dir(&self) -> &Path {
        &self.dir
    }

    /// The path of file `name`, as messages name it.
    pub fn path(&self, name: &str) -> PathBuf {
        self.dir.join(name)
    }

    /// The content of file `name`; a missing one is [`LearnError::MissingFile`].
    pub fn read(&self, name: &str) -> Result<Vec<u8>, LearnError> {
        match &self.memory {
            // `--checkpoint dir/config.json` read `dir/config.json/config.json`: "Not a directory".
            None if self.dir.is_file() => Err(LearnError::Format {
                path: self.dir.clone(),
                problem: "a file, not a checkpoint folder (the folder that holds config.json, ace.json and their weights)".into(),
            }),
            None => read_file(&self.path(name)),
            Some(files) => files
                .get(name)
                .cloned()
                .ok_or_else(|| LearnError::MissingFile { path: self.path(name) }),
        }
    }
}

/// Reads the JSON metadata file `name` of a checkpoint: its `kind` must be `kind` and its
/// `format_version` `version`, checked before the rest so that another file or version gets a plain
/// error; `what` names the expected kind in that error ("a motion-prior checkpoint").
pub(crate) fn read_json<T: DeserializeOwned>(
    files: &CheckpointFiles,
    name: &str,
    kind: &str,
    version: u32,
    what: &str,
) -> Result<T, LearnError> {
    let bytes = files.read(name)?;
    let path = files.path(name);
    let path = path.as_path();
    let corrupt = |problem: String| LearnError::CorruptFile {
        path: path.into(),
        problem,
    };
    let format = |problem: String| LearnError::Format {
        path: path.into(),
        problem,
    };
    // UTF-16 JSON would be "not valid JSON" at its first byte: say what it is.
    let text = crate::input::text_from_bytes(bytes).map_err(|e| format(e.to_string()))?;
    let value: Value = serde_json::from_str(&text).map_err(|e| corrupt(format!("not valid JSON: {e}")))?;
    match value.get("kind").and_then(Value::as_str) {
        Some(k) if k == kind => {}
        other => {
            return Err(format(format!(
                "not {what} (kind {}, expected `{kind}`)",
                other.map_or("missing".to_string(), |k| format!("`{k}`"))
            )));
        }
    }
    match value.get("format_version").and_then(Value::as_u64) {
        Some(v) if v == u64::from(version) => {}
        v => {
            return Err(format(format!(
                "format version {} is not supported (this build reads version {version})",
                v.map_or("(none)".to_string(), |v| v.to_string())
            )));
        }
    }
    serde_json::from_value(value).map_err(|e| corrupt(e.to_string()))
}

/// The tensors of a weights file after `read_weights` checked them: F32 values by name, row-major.
#[derive(Debug)]
pub struct Weights {
    tensors: BTreeMap<String, (Vec<usize>, Vec<f32>)>,
}

impl Weights {
    /// The shape and values of tensor `name`, which `read_weights` was asked for.
    pub fn get(&self, name: &str) -> (&[usize], &[f32]) {
        let (shape, values) = self.tensors.get(name).unwrap_or_else(|| panic!("tensor `{name}` was not read"));
        (shape, values)
    }
}

/// Checks the safetensors file `name` against `expected` (tensor name → shape) and against `record`,
/// and returns the expected tensors: every one present with its shape and as F32, finite, the content
/// the one recorded; with `only`, a stored tensor that is not expected is an error too. Messages call
/// the network `network` (e.g. "prior") and name `described_in`, the metadata file that describes it
/// and records the weights.
pub(crate) fn read_weights(
    files: &CheckpointFiles,
    name: &str,
    record: &FileRecord,
    expected: &BTreeMap<String, Vec<usize>>,
    only: bool,
    network: &str,
    described_in: &str,
) -> Result<Weights, LearnError> {
    let bytes = files.read(name)?;
    let path = files.path(name);
    let path = path.as_path();
    let corrupt = |problem: String| LearnError::CorruptFile {
        path: path.into(),
        problem,
    };
    let mismatch = |problem: String| LearnError::ShapeMismatch {
        path: path.into(),
        problem,
    };
    let st = SafeTensors::deserialize(&bytes).map_err(|e| {
        corrupt(format!(
            "not a readable safetensors file ({} bytes): {e}",
            bytes.len()
        ))
    })?;
    // Sorted, so that the first problem reported does not depend on hash order.
    let mut stored = st.names();
    stored.sort();
    if let Some(extra) = stored.into_iter().find(|n| only && !expected.contains_key(*n)) {
        return Err(mismatch(format!(
            "tensor `{extra}` is not a variable of the {network} `{described_in}` describes"
        )));
    }
    let mut tensors = BTreeMap::new();
    for (name, want) in expected {
        let t = st
            .tensor(name)
            .map_err(|_| mismatch(format!("tensor `{name}` is missing")))?;
        if t.shape() != want.as_slice() {
            return Err(mismatch(format!(
                "tensor `{name}` has shape {:?}, `{described_in}` gives {want:?}",
                t.shape()
            )));
        }
        if t.dtype() != Dtype::F32 {
            return Err(corrupt(format!(
                "tensor `{name}` has dtype {:?}, expected F32",
                t.dtype()
            )));
        }
        let values: Vec<f32> = t
            .data()
            .chunks_exact(4)
            .map(|b| f32::from_le_bytes([b[0], b[1], b[2], b[3]]))
            .collect();
        let bad = values.iter().filter(|v| !v.is_finite()).count();
        if bad > 0 {
            return Err(corrupt(format!(
                "tensor `{name}` holds {bad} non-finite value(s) (NaN or infinity): the {network} weights are \
                 damaged (a diverged training run?); retrain or restore them"
            )));
        }
        tensors.insert(name.clone(), (want.clone(), values));
    }
    record.verify(path, &bytes, described_in)?;
    Ok(Weights { tensors })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn checksum_is_fnv1a() {
        // Published FNV-1a 64 test vectors.
        assert_eq!(fnv1a64(b""), 0xcbf29ce484222325);
        assert_eq!(fnv1a64(b"a"), 0xaf63dc4c8601ec8c);
        assert_eq!(fnv1a64(b"foobar"), 0x85944171f73967e8);
    }
}
