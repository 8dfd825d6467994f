//! Learning modules (libtorch through `tch`). The only part of `models` that knows tch.
//!
//! This file holds the bridge between the state vectors built by [`crate::human`] and
//! [`crate::character_state`] and tensors, and device selection. The method (paper §4–§6) is split by
//! what each part holds:
//! - [`nets`]: the building blocks (MLP, the mode-adaptive mixture-of-experts layer stack);
//! - [`prior`]: the motion prior (VAE encoder c and MANN decoder π) and its training (§4);
//! - [`psi`]: Ψ on tensors, the differentiable twin of [`crate::features`];
//! - [`ace`]: generator G and discriminator D with their losses (§5);
//! - [`train_ace`]: the adversarial training loop over human clips;
//! - [`fk`]: differentiable forward kinematics (end-effector points from joint positions);
//! - [`nkn`]: the NKN baseline of the paper's comparison (recurrent network, FK layer, adversarial
//!   and cycle losses);
//! - [`checkpoint`]: configs, normalisation statistics and weights on disk;
//! - `files`: file handling both stages share (checksums, weights loading, loss logs, step generators);
//! - [`retarget`]: inference, a human clip or pose stream to character states.

pub mod ace;
pub mod checkpoint;
pub mod files;
pub mod fk;
pub mod nets;
pub mod nkn;
pub mod prior;
pub mod psi;
pub mod retarget;
pub mod train_ace;

pub use crate::checkpoint::{ShapeError, limits};
pub use files::CheckpointFiles;
/// The device type inference and training take (libtorch's), for callers that do not use tch.
pub use tch::Device;

use tch::{Kind, Tensor};

/// The device training and inference run on: the first CUDA device when libtorch sees one, else the CPU.
pub fn default_device() -> Device {
    Device::cuda_if_available()
}

/// How many CUDA devices libtorch sees on this machine (0 with a CPU-only libtorch or no GPU).
pub fn cuda_devices() -> usize {
    usize::try_from(tch::Cuda::device_count()).unwrap_or(0)
}

/// Sets how many threads libtorch's CPU kernels use (intra-op parallelism).
pub fn set_threads(n: i32) {
    tch::set_num_threads(n.max(1));
}

/// Stacks equally wide state rows (frames × features) into a `[frames, width]` f32 tensor on `device`.
pub fn rows_to_tensor<R: AsRef<[f32]>>(rows: &[R], device: Device) -> Result<Tensor, ShapeError> {
    let width = rows.first().map_or(0, |r| r.as_ref().len());
    let mut flat = Vec::with_capacity(rows.len() * width);
    for (row, r) in rows.iter().enumerate() {
        let r = r.as_ref();
        if r.len() != width {
            return Err(ShapeError::Ragged { expected: width, row, found: r.len() });
        }
        flat.extend_from_slice(r);
    }
    Ok(Tensor::from_slice(&flat).view([rows.len() as i64, width as i64]).to_device(device))
}

/// The inverse of [`rows_to_tensor`]: a `[frames, width]` tensor back to rows, checking the width.
pub fn tensor_to_rows(t: &Tensor, width: usize) -> Result<Vec<Vec<f32>>, ShapeError> {
    let size = t.size();
    if size.len() != 2 || size[1] != width as i64 {
        return Err(ShapeError::Tensor { expected: width, found: size });
    }
    let flat: Vec<f32> = Vec::<f32>::try_from(t.to_kind(Kind::Float).to_device(Device::Cpu).flatten(0, -1))
        .map_err(|_| ShapeError::Tensor { expected: width, found: size.clone() })?;
    Ok(flat.chunks(width).map(<[f32]>::to_vec).collect())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rows_round_trip_through_libtorch() {
        let rows = vec![vec![1.0f32, 2.0, 3.0], vec![4.0, 5.0, 6.5]];
        let t = rows_to_tensor(&rows, Device::Cpu).unwrap();
        assert_eq!(t.size(), vec![2, 3]);
        assert_eq!(t.sum(Kind::Float).double_value(&[]), 21.5);
        assert_eq!(tensor_to_rows(&t, 3).unwrap(), rows);
    }

    #[test]
    fn wrong_shapes_are_named() {
        let ragged = vec![vec![1.0f32, 2.0], vec![3.0]];
        let e = rows_to_tensor(&ragged, Device::Cpu).unwrap_err();
        assert_eq!(e.to_string(), "state rows have inconsistent widths: row 0 has 2 values, row 1 has 1");
        let t = Tensor::zeros([4, 5], (Kind::Float, Device::Cpu));
        let e = tensor_to_rows(&t, 92).unwrap_err();
        assert!(e.to_string().contains("width 92") && e.to_string().contains("[4, 5]"), "{e}");
    }
}
