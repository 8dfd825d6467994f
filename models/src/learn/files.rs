//! File handling of training shared by the motion prior ([`super::checkpoint`], [`super::prior`]) and
//! the adversarial stage ([`super::ace`], [`super::train_ace`]): safetensors weights loaded into a
//! `VarStore`, loss logs kept across resumed runs, and the per-step random generators that make resumed
//! runs draw what uninterrupted ones would. The files themselves (records, checksums, metadata) are
//! [`crate::checkpoint::files`].

use std::collections::BTreeMap;
use std::fs;
use std::io::{BufRead, BufReader, Write};
use std::path::Path;

use rand::SeedableRng;
use rand_pcg::Pcg64;
use tch::{Tensor, nn};

pub use crate::checkpoint::files::{CheckpointFiles, FileRecord};
pub(crate) use crate::checkpoint::files::{read_file, read_json, read_weights};
use crate::checkpoint::LearnError;

/// Writes `bytes` to `path` (created or truncated) and waits until they are on disk.
pub(crate) fn write_synced(path: &Path, bytes: &[u8]) -> Result<(), LearnError> {
    (|| {
        let mut f = fs::File::create(path)?;
        f.write_all(bytes)?;
        f.sync_all()
    })()
    .map_err(|e| LearnError::io(path, e))
}

/// Checks the safetensors file `name` against the variables of `vs` and against `record` (see
/// [`read_weights`]: no tensor that is not a variable, every variable present with its shape and as
/// F32, the content the one recorded), then copies it into them.
pub(crate) fn load_weights(
    files: &CheckpointFiles,
    name: &str,
    record: &FileRecord,
    vs: &nn::VarStore,
    network: &str,
    described_in: &str,
) -> Result<(), LearnError> {
    let vars: BTreeMap<String, Tensor> = vs.variables().into_iter().collect();
    let shapes = vars
        .iter()
        .map(|(name, v)| (name.clone(), v.size().iter().map(|&d| d as usize).collect()))
        .collect();
    let weights = read_weights(files, name, record, &shapes, true, network, described_in)?;
    tch::no_grad(|| -> Result<(), LearnError> {
        for (name, var) in &vars {
            let (_, values) = weights.get(name);
            let src = Tensor::f_from_slice(values)?.f_view(var.size().as_slice())?;
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
        // A FIFO would block the resume forever.
        if !fs::metadata(path).map_err(|e| LearnError::io(path, e))?.is_file() {
            return Err(LearnError::Format {
                path: path.into(),
                problem: crate::input::ReadError::NotRegular.to_string(),
            });
        }
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
    // Through a project temporary, so that a run killed before the rename leaves one the next run
    // recognises and removes.
    let mut text = kept.join("\n");
    text.push('\n');
    crate::temporary::write_atomically(path, text.as_bytes()).map_err(|e| LearnError::io(path, e))?;
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
