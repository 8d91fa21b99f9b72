//! The one binary codec of DUPAC (serde + bincode 2, pinned `=2.0.1`: 3.0.0 on the registry is a
//! placeholder and the crate is unmaintained, so nothing else names bincode and it can be
//! swapped here). Every encoded blob starts with an 8-byte magic naming its kind and a
//! little-endian `u32` format version, so a file of the wrong kind or an old format is a clear
//! error, and decoding is bounded by a hard size cap.

use serde::Serialize;
use serde::de::DeserializeOwned;
use std::path::Path;

/// Errors of encoding, decoding and the atomic file helpers; each names what it was reading.
#[derive(Debug, thiserror::Error)]
pub enum CodecError {
    #[error("{what}: {len} bytes exceed the limit of {limit}")]
    TooLarge {
        what: String,
        len: usize,
        limit: usize,
    },
    #[error("{what}: not a {expected} blob (bad magic)")]
    BadMagic { what: String, expected: String },
    #[error("{what}: decoding would allocate more than its budget of {budget} bytes: {message}")]
    OverBudget {
        what: String,
        budget: usize,
        message: String,
    },
    #[error(
        "{what}: a binary {magic} message, not JSON: its sender is another DUPAC build (this one sends and reads stats and control messages as JSON)"
    )]
    Binary { what: String, magic: String },
    #[error("{what}: format version {got}, this build reads {want}")]
    Version { what: String, got: u32, want: u32 },
    #[error("{what}: cannot decode: {message}")]
    Decode { what: String, message: String },
    #[error("{what}: {len} trailing bytes after the value")]
    Trailing { what: String, len: usize },
    #[error("cannot encode {what}: {message}")]
    Encode { what: String, message: String },
    #[error(transparent)]
    Fs(#[from] crate::fsio::FsError),
    #[error("{path}: {cause}")]
    Io {
        path: String,
        /// The OS error, part of this error's message (not its `source()`, so that a printed
        /// chain shows it once).
        cause: std::io::Error,
    },
}

/// Hard cap on any decoded blob (checkpoints of large networks included).
pub const MAX_BLOB_BYTES: usize = 1 << 30;

fn config() -> impl bincode::config::Config {
    bincode::config::standard().with_limit::<MAX_BLOB_BYTES>()
}

/// Encodes `value` behind `magic` and `version`.
pub fn encode<T: Serialize>(
    magic: &[u8; 8],
    version: u32,
    value: &T,
    what: &str,
) -> Result<Vec<u8>, CodecError> {
    let mut out = Vec::with_capacity(1024);
    out.extend_from_slice(magic);
    out.extend_from_slice(&version.to_le_bytes());
    let body = bincode::serde::encode_to_vec(value, config()).map_err(|e| CodecError::Encode {
        what: what.to_string(),
        message: e.to_string(),
    })?;
    out.extend_from_slice(&body);
    Ok(out)
}

/// Decodes a blob written by [`encode`] with the same `magic` and `version`, at most `limit`
/// bytes; `what` names the source (file, message) in errors.
pub fn decode<T: DeserializeOwned>(
    magic: &[u8; 8],
    version: u32,
    bytes: &[u8],
    limit: usize,
    what: &str,
) -> Result<T, CodecError> {
    decode_inner(magic, version, bytes, limit, what)
}

/// [`decode`] with at most `budget_bytes` allocated for the value's collections (checked while
/// decoding, before each allocation: [`crate::budget`]); network messages are decoded so.
pub fn decode_budgeted<T: DeserializeOwned>(
    magic: &[u8; 8],
    version: u32,
    bytes: &[u8],
    limit: usize,
    budget_bytes: usize,
    what: &str,
) -> Result<T, CodecError> {
    let (out, exceeded) = crate::budget::with_budget(budget_bytes, || {
        decode_inner(magic, version, bytes, limit, what)
    });
    match out {
        Err(CodecError::Decode { what, message }) if exceeded => Err(CodecError::OverBudget {
            what,
            budget: budget_bytes,
            message,
        }),
        out => out,
    }
}

fn decode_inner<T: DeserializeOwned>(
    magic: &[u8; 8],
    version: u32,
    bytes: &[u8],
    limit: usize,
    what: &str,
) -> Result<T, CodecError> {
    if bytes.len() > limit.min(MAX_BLOB_BYTES) {
        return Err(CodecError::TooLarge {
            what: what.to_string(),
            len: bytes.len(),
            limit: limit.min(MAX_BLOB_BYTES),
        });
    }
    if bytes.len() < 12 || &bytes[..8] != magic {
        return Err(CodecError::BadMagic {
            what: what.to_string(),
            expected: String::from_utf8_lossy(magic).into_owned(),
        });
    }
    let got = u32::from_le_bytes([bytes[8], bytes[9], bytes[10], bytes[11]]);
    if got != version {
        return Err(CodecError::Version {
            what: what.to_string(),
            got,
            want: version,
        });
    }
    let (value, used): (T, usize) = bincode::serde::decode_from_slice(&bytes[12..], config())
        .map_err(|e| CodecError::Decode {
            what: what.to_string(),
            message: e.to_string(),
        })?;
    if used != bytes.len() - 12 {
        return Err(CodecError::Trailing {
            what: what.to_string(),
            len: bytes.len() - 12 - used,
        });
    }
    Ok(value)
}

/// Writes `bytes` to `path` atomically ([`crate::fsio::write_atomic`]: temporary file, fsync,
/// rename, directory fsync).
pub fn write_atomic(path: &Path, bytes: &[u8]) -> Result<(), CodecError> {
    Ok(crate::fsio::write_atomic(path, bytes)?)
}

/// Reads a whole file, refusing files over `limit` bytes before reading them.
pub fn read_limited(path: &Path, limit: usize) -> Result<Vec<u8>, CodecError> {
    let io = |cause| CodecError::Io {
        path: path.display().to_string(),
        cause,
    };
    let len = std::fs::metadata(path).map_err(io)?.len();
    if len > limit as u64 {
        return Err(CodecError::TooLarge {
            what: path.display().to_string(),
            len: len as usize,
            limit,
        });
    }
    std::fs::read(path).map_err(io)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn round_trip_and_clear_errors() {
        let v = (1u32, vec![1.5f32, -2.0], "x".to_string());
        let b = encode(b"TESTBLOB", 3, &v, "t").expect("encode");
        let back: (u32, Vec<f32>, String) =
            decode(b"TESTBLOB", 3, &b, 1 << 20, "t").expect("decode");
        assert_eq!(back, v);
        let e =
            decode::<(u32, Vec<f32>, String)>(b"OTHERBLB", 3, &b, 1 << 20, "f.bin").unwrap_err();
        assert!(
            e.to_string().contains("f.bin") && e.to_string().contains("magic"),
            "{e}"
        );
        let e = decode::<(u32, Vec<f32>, String)>(b"TESTBLOB", 4, &b, 1 << 20, "f").unwrap_err();
        assert!(
            matches!(
                e,
                CodecError::Version {
                    got: 3,
                    want: 4,
                    ..
                }
            ),
            "{e}"
        );
        let e = decode::<(u32, Vec<f32>, String)>(b"TESTBLOB", 3, &b[..b.len() - 2], 1 << 20, "f")
            .unwrap_err();
        assert!(matches!(e, CodecError::Decode { .. }), "{e}");
        let e = decode::<(u32, Vec<f32>, String)>(b"TESTBLOB", 3, &b, 8, "f").unwrap_err();
        assert!(matches!(e, CodecError::TooLarge { .. }), "{e}");
        // A length prefix claiming 2^40 elements is refused, not allocated.
        let mut evil = b.clone();
        evil.truncate(12 + 1);
        evil.extend_from_slice(&[0xfd, 0, 0, 0, 0, 0, 1, 0, 0]);
        assert!(decode::<(u32, Vec<f32>, String)>(b"TESTBLOB", 3, &evil, 1 << 20, "f").is_err());
    }
}
