//! File handling shared by the motion prior ([`super::checkpoint`], [`super::prior`]) and the
//! adversarial stage ([`super::ace`], [`super::train_ace`]): checksums and records of weights files,
//! synced writes, safetensors weights checked against a `VarStore`, loss logs kept across resumed runs,
//! and the per-step random generators that make resumed runs draw what uninterrupted ones would.

use std::collections::BTreeMap;
use std::fs;
use std::io::{BufRead, BufReader, Write};
use std::path::{Path, PathBuf};

use rand::SeedableRng;
use rand_pcg::Pcg64;
use safetensors::{Dtype, SafeTensors};
use serde::de::DeserializeOwned;
use serde::{Deserialize, Serialize};
use serde_json::Value;
use tch::{Kind, Tensor, nn};

use super::checkpoint::LearnError;

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

/// Reads a whole file; a missing one is [`LearnError::MissingFile`].
pub(crate) fn read_file(path: &Path) -> Result<Vec<u8>, LearnError> {
    match fs::read(path) {
        Ok(b) => Ok(b),
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => {
            Err(LearnError::MissingFile { path: path.into() })
        }
        Err(e) => Err(LearnError::io(path, e)),
    }
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
    let value: Value = serde_json::from_slice(&bytes).map_err(|e| corrupt(format!("not valid JSON: {e}")))?;
    let format = |problem: String| LearnError::Format {
        path: path.into(),
        problem,
    };
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

/// Writes `bytes` to `path` (created or truncated) and waits until they are on disk.
pub(crate) fn write_synced(path: &Path, bytes: &[u8]) -> Result<(), LearnError> {
    (|| {
        let mut f = fs::File::create(path)?;
        f.write_all(bytes)?;
        f.sync_all()
    })()
    .map_err(|e| LearnError::io(path, e))
}

/// Checks the safetensors file `name` against the variables of `vs` and against `record`, then copies
/// it into them: no tensor that is not a variable, every variable present with its shape and as F32,
/// the content the one recorded. Messages call the network `network` (e.g. "prior") and name
/// `described_in`, the metadata file that describes it and records the weights.
pub(crate) fn load_weights(
    files: &CheckpointFiles,
    name: &str,
    record: &FileRecord,
    vs: &nn::VarStore,
    network: &str,
    described_in: &str,
) -> Result<(), LearnError> {
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
    let vars: BTreeMap<String, Tensor> = vs.variables().into_iter().collect();
    let mut stored = st.names();
    stored.sort();
    if let Some(extra) = stored.into_iter().find(|n| !vars.contains_key(*n)) {
        return Err(mismatch(format!(
            "tensor `{extra}` is not a variable of the {network} `{described_in}` describes"
        )));
    }
    for (name, var) in &vars {
        let t = st
            .tensor(name)
            .map_err(|_| mismatch(format!("tensor `{name}` is missing")))?;
        let shape: Vec<i64> = t.shape().iter().map(|&d| d as i64).collect();
        if shape != var.size() {
            return Err(mismatch(format!(
                "tensor `{name}` has shape {shape:?}, `{described_in}` gives {:?}",
                var.size()
            )));
        }
        if t.dtype() != Dtype::F32 {
            return Err(corrupt(format!(
                "tensor `{name}` has dtype {:?}, expected F32",
                t.dtype()
            )));
        }
        let bad = t
            .data()
            .chunks_exact(4)
            .filter(|b| !f32::from_le_bytes([b[0], b[1], b[2], b[3]]).is_finite())
            .count();
        if bad > 0 {
            return Err(corrupt(format!(
                "tensor `{name}` holds {bad} non-finite value(s) (NaN or infinity): the {network} weights are \
                 damaged (a diverged training run?); retrain or restore them"
            )));
        }
    }
    record.verify(path, &bytes, described_in)?;
    tch::no_grad(|| -> Result<(), LearnError> {
        for (name, var) in &vars {
            let t = st.tensor(name).expect("checked above");
            let src = Tensor::f_from_data_size(t.data(), &var.size(), Kind::Float)?;
            var.shallow_clone().f_copy_(&src)?;
        }
        Ok(())
    })
}

/// Opens the loss log `path` for appending after `step` steps: a fresh file holding `header` when `step`
/// is 0, else the existing rows of steps before `step` are kept (later ones came after the last
/// checkpoint and are redone). Also returns the seconds logged by the last kept row, read from column
/// `seconds_column` (counted from 0, the step being column 0).
pub(crate) fn open_losses(
    path: &Path,
    step: usize,
    header: &str,
    seconds_column: usize,
) -> Result<(fs::File, f64), LearnError> {
    debug_assert_eq!(header.split(',').nth(seconds_column), Some("seconds"));
    let mut kept = vec![header.to_string()];
    let mut seconds = 0.0;
    if step > 0 && path.exists() {
        let f = fs::File::open(path).map_err(|e| LearnError::io(path, e))?;
        for line in BufReader::new(f).lines().skip(1) {
            let line = line.map_err(|e| LearnError::io(path, e))?;
            let row_step = line.split(',').next().and_then(|s| s.parse::<usize>().ok());
            if row_step.is_some_and(|s| s < step) {
                seconds = line
                    .split(',')
                    .nth(seconds_column)
                    .and_then(|s| s.parse().ok())
                    .unwrap_or(seconds);
                kept.push(line);
            }
        }
    }
    let tmp = path.with_extension("csv.tmp");
    let mut text = kept.join("\n");
    text.push('\n');
    fs::write(&tmp, text)
        .and_then(|_| fs::rename(&tmp, path))
        .map_err(|e| LearnError::io(path, e))?;
    let f = fs::OpenOptions::new()
        .append(true)
        .open(path)
        .map_err(|e| LearnError::io(path, e))?;
    Ok((f, seconds))
}

/// The generator of optimiser step `step` of a run seeded with `seed`: a step's draws do not depend on
/// how the run got there, so a resumed run draws what an uninterrupted one would. Runs that must not
/// share draws for the same seed and step pass different `stream`s (the prior's is 0).
pub(crate) fn step_rng(seed: u64, stream: u64, step: usize) -> Pcg64 {
    Pcg64::seed_from_u64(seed ^ stream ^ (step as u64 + 1).wrapping_mul(0x9e37_79b9_7f4a_7c15))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::learn::prior::test_support::scratch_dir;

    #[test]
    fn checksum_is_fnv1a() {
        // Published FNV-1a 64 test vectors.
        assert_eq!(fnv1a64(b""), 0xcbf29ce484222325);
        assert_eq!(fnv1a64(b"a"), 0xaf63dc4c8601ec8c);
        assert_eq!(fnv1a64(b"foobar"), 0x85944171f73967e8);
    }

    #[test]
    fn loss_log_keeps_earlier_steps_and_their_seconds() {
        let dir = scratch_dir("files_losses");
        let path = dir.join("losses.csv");
        let header = "step,loss,seconds,note";
        fs::write(
            &path,
            format!("{header}\n0,1.5,2.25,a\n1,1.25,4.5,b\n2,1.0,7.0,c\n"),
        )
        .unwrap();
        let (mut f, seconds) = open_losses(&path, 2, header, 2).unwrap();
        assert_eq!(seconds, 4.5);
        writeln!(f, "2,0.5,9.0,d").unwrap();
        drop(f);
        let text = fs::read_to_string(&path).unwrap();
        assert_eq!(
            text,
            format!("{header}\n0,1.5,2.25,a\n1,1.25,4.5,b\n2,0.5,9.0,d\n")
        );
        // A fresh run starts the log over.
        let (_, seconds) = open_losses(&path, 0, header, 2).unwrap();
        assert_eq!(seconds, 0.0);
        assert_eq!(fs::read_to_string(&path).unwrap(), format!("{header}\n"));
        fs::remove_dir_all(&dir).unwrap();
    }
}
