//! Reading input files: the one place where every reader of the project gets a file's bytes or text.
//!
//! - Only a regular file is read (after following symlinks): a FIFO, a directory or a device named
//!   `.toml`, `.bvh` or `.safetensors` is refused from its metadata, without being opened, where
//!   reading it would block forever or never end.
//! - Each kind of file has a largest size ([`MAX_TEXT_BYTES`], [`MAX_BVH_BYTES`], [`MAX_MESH_BYTES`],
//!   [`MAX_DATA_BYTES`]), checked from the metadata too: a mistaken path (a disk image or a video
//!   named `.bvh`) fails at once instead of filling memory. Each bound is far above what the project's
//!   real inputs need.
//! - Text that is UTF-16 (with a byte-order mark, or without one: a NUL in every other byte of its
//!   start, which no UTF-8 text of the project's formats has) is refused with a hint to save it as
//!   UTF-8, rather than read as NUL-riddled garbage that the TOML, XML or JSON parser would report
//!   as a confusing syntax error; other invalid UTF-8 is refused with the line and offset of the first
//!   bad byte.
//!
//! The errors ([`ReadError`]) say the problem, not the file: each reader wraps them in its own error
//! naming the file, so that messages stay as they were (`walk.mapping.toml: not a regular file …`).
//! Binary formats (safetensors datasets and weights) use [`read_regular`] alone: their bytes may
//! start like a byte-order mark.

use std::path::Path;

use thiserror::Error;

/// The largest text file read: TOML configurations, joint mappings and profiles, URDF, and the JSON
/// records of checkpoints (the project's largest, a checkpoint's `ace.json`, is well under 1 MiB).
pub const MAX_TEXT_BYTES: u64 = 64 << 20;
/// The largest BVH clip read: two hours (the reader's bound) of 120 fps mocap with 100 joints is
/// about 1.5 GiB of text.
pub const MAX_BVH_BYTES: u64 = 2 << 30;
/// The largest mesh or glTF character file read.
pub const MAX_MESH_BYTES: u64 = 512 << 20;
/// The largest binary data file read: datasets and network weights (safetensors).
pub const MAX_DATA_BYTES: u64 = 4 << 30;

/// Why a file could not be read as input (the file itself is named by the caller).
#[derive(Debug, Error)]
pub enum ReadError {
    /// A directory, FIFO, socket or device.
    #[error("not a regular file (a directory, FIFO or device)")]
    NotRegular,
    /// The file system's error (missing file, no permission, …).
    #[error("{0}")]
    Io(#[from] std::io::Error),
    /// Larger than the bound for its kind.
    #[error("the file is {size} bytes, more than the {max} bytes this kind of file may have")]
    TooLarge {
        /// The file's size.
        size: u64,
        /// The bound.
        max: u64,
    },
    /// UTF-16 text.
    #[error("the file is UTF-16 encoded; save it as UTF-8 (e.g. `iconv -f UTF-16 -t UTF-8`)")]
    Utf16,
    /// Neither UTF-8 nor UTF-16.
    #[error("not UTF-8 text (invalid byte at line {line}, byte offset {offset}); save it as UTF-8")]
    NotUtf8 {
        /// 1-based line of the first invalid byte.
        line: usize,
        /// Its byte offset in the file.
        offset: usize,
    },
}

impl ReadError {
    /// Whether the file does not exist.
    pub fn is_not_found(&self) -> bool {
        matches!(self, ReadError::Io(e) if e.kind() == std::io::ErrorKind::NotFound)
    }
}

/// The bytes of `path`, which must be a regular file of at most `max` bytes: its metadata is checked
/// before it is opened, and no more than `max` bytes are read should it grow meanwhile.
pub fn read_regular(path: &Path, max: u64) -> Result<Vec<u8>, ReadError> {
    use std::io::Read;
    let meta = std::fs::metadata(path)?;
    if !meta.is_file() {
        return Err(ReadError::NotRegular);
    }
    if meta.len() > max {
        return Err(ReadError::TooLarge { size: meta.len(), max });
    }
    let mut bytes = Vec::with_capacity(meta.len() as usize);
    std::fs::File::open(path)?.take(max + 1).read_to_end(&mut bytes)?;
    if bytes.len() as u64 > max {
        return Err(ReadError::TooLarge { size: bytes.len() as u64, max });
    }
    Ok(bytes)
}

/// Whether `bytes` look like UTF-16 text: a byte-order mark, or a NUL in every other byte of the first
/// 64 (at least 4 bytes).
pub fn looks_utf16(bytes: &[u8]) -> bool {
    let bom = bytes.starts_with(&[0xFF, 0xFE]) || bytes.starts_with(&[0xFE, 0xFF]);
    let head = &bytes[..bytes.len().min(64)];
    let nul_every_other = head.len() >= 4
        && (head.iter().step_by(2).all(|&b| b == 0) || head.iter().skip(1).step_by(2).all(|&b| b == 0));
    bom || nul_every_other
}

/// `bytes` as UTF-8 text: UTF-16 ([`looks_utf16`]) and invalid UTF-8 are errors. A UTF-8 byte-order
/// mark is dropped.
pub fn text_from_bytes(bytes: Vec<u8>) -> Result<String, ReadError> {
    if looks_utf16(&bytes) {
        return Err(ReadError::Utf16);
    }
    let mut text = String::from_utf8(bytes).map_err(|e| {
        let offset = e.utf8_error().valid_up_to();
        let line = e.as_bytes()[..offset].iter().filter(|&&b| b == b'\n').count() + 1;
        ReadError::NotUtf8 { line, offset }
    })?;
    if text.starts_with('\u{feff}') {
        text.drain(..3);
    }
    Ok(text)
}

/// The UTF-8 text of the regular file `path`, of at most [`MAX_TEXT_BYTES`] ([`read_regular`],
/// [`text_from_bytes`]).
pub fn read_text(path: &Path) -> Result<String, ReadError> {
    text_from_bytes(read_regular(path, MAX_TEXT_BYTES)?)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_file_over_its_kinds_bound_is_refused_before_it_is_read() {
        let dir = std::env::temp_dir().join(format!("ace-input-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("big.bvh");
        // A sparse file: its size is in the metadata, its bytes take no disk.
        std::fs::File::create(&path).unwrap().set_len(MAX_BVH_BYTES + 1).unwrap();
        let e = read_regular(&path, MAX_BVH_BYTES).unwrap_err();
        assert!(matches!(e, ReadError::TooLarge { size, max } if size == MAX_BVH_BYTES + 1 && max == MAX_BVH_BYTES), "{e}");
        assert_eq!(e.to_string(), format!("the file is {} bytes, more than the {MAX_BVH_BYTES} bytes this kind of file may have", MAX_BVH_BYTES + 1));
        std::fs::write(&path, b"HIERARCHY\n").unwrap();
        assert_eq!(read_regular(&path, 10).unwrap(), b"HIERARCHY\n");
        assert!(matches!(read_regular(&path, 9), Err(ReadError::TooLarge { size: 10, max: 9 })));
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn utf16_is_recognised_with_or_without_a_byte_order_mark() {
        let utf16le: Vec<u8> = "a = 1\n".encode_utf16().flat_map(u16::to_le_bytes).collect();
        let utf16be: Vec<u8> = "a = 1\n".encode_utf16().flat_map(u16::to_be_bytes).collect();
        for bytes in [utf16le.clone(), utf16be.clone(), [vec![0xFF, 0xFE], utf16le].concat(), [vec![0xFE, 0xFF], utf16be].concat()] {
            assert!(matches!(text_from_bytes(bytes), Err(ReadError::Utf16)));
        }
        assert_eq!(text_from_bytes(b"a = 1\n".to_vec()).unwrap(), "a = 1\n");
        assert_eq!(text_from_bytes(b"\xEF\xBB\xBFa = 1\n".to_vec()).unwrap(), "a = 1\n");
        assert_eq!(
            text_from_bytes(b"a = 1\nb = \xE9\n".to_vec()).unwrap_err().to_string(),
            "not UTF-8 text (invalid byte at line 2, byte offset 10); save it as UTF-8"
        );
    }
}
