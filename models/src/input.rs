//! Reading input files: the one place where every reader of the project gets a file's bytes or text.
//!
//! - Only a regular file is read (after following symlinks): a FIFO, a directory or a device named
//!   `.toml`, `.bvh` or `.safetensors` is refused from its metadata, without being opened, where
//!   reading it would block forever or never end.
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

/// Why a file could not be read as input (the file itself is named by the caller).
#[derive(Debug, Error)]
pub enum ReadError {
    /// A directory, FIFO, socket or device.
    #[error("not a regular file (a directory, FIFO or device)")]
    NotRegular,
    /// The file system's error (missing file, no permission, …).
    #[error("{0}")]
    Io(#[from] std::io::Error),
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

/// The bytes of `path`, which must be a regular file: its metadata is checked before it is opened.
pub fn read_regular(path: &Path) -> Result<Vec<u8>, ReadError> {
    if !std::fs::metadata(path)?.is_file() {
        return Err(ReadError::NotRegular);
    }
    Ok(std::fs::read(path)?)
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

/// The UTF-8 text of the regular file `path` ([`read_regular`], [`text_from_bytes`]).
pub fn read_text(path: &Path) -> Result<String, ReadError> {
    text_from_bytes(read_regular(path)?)
}

#[cfg(test)]
mod tests {
    use super::*;

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
