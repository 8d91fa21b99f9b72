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

/// zstd level of [`encode_compressed`]: zstd's default, which takes the trajectory chunks of a
/// default run from 461 to 228 bytes per decision (docs/distributed.md "The compact trajectory").
const ZSTD_LEVEL: i32 = 3;

/// [`encode`] with the body compressed by zstd (a frame that states its decompressed size):
/// `magic`, `version`, then the frame.
pub fn encode_compressed<T: Serialize>(
    magic: &[u8; 8],
    version: u32,
    value: &T,
    what: &str,
) -> Result<Vec<u8>, CodecError> {
    compress(&encode(magic, version, value, what)?, what)
}

/// A blob of [`encode`] with its body compressed as [`encode_compressed`] writes it (tests
/// write hostile bodies byte by byte and compress them so).
pub fn compress(blob: &[u8], what: &str) -> Result<Vec<u8>, CodecError> {
    let (header, body) = blob.split_at(12.min(blob.len()));
    let frame = zstd::bulk::compress(body, ZSTD_LEVEL).map_err(|e| CodecError::Encode {
        what: what.to_string(),
        message: format!("zstd: {e}"),
    })?;
    let mut out = Vec::with_capacity(header.len() + frame.len());
    out.extend_from_slice(header);
    out.extend_from_slice(&frame);
    Ok(out)
}

/// Decodes a blob written by [`encode_compressed`], at most `limit` bytes compressed. The
/// frame's stated decompressed size is charged to `budget_bytes` before anything is allocated
/// (a frame that states none, or more than the budget, is refused; one that decompresses to
/// another size too), and the value's collections to what is left of it
/// ([`decode_budgeted`]).
pub fn decode_compressed_budgeted<T: DeserializeOwned>(
    magic: &[u8; 8],
    version: u32,
    bytes: &[u8],
    limit: usize,
    budget_bytes: usize,
    what: &str,
) -> Result<T, CodecError> {
    check_header(magic, version, bytes, limit, what)?;
    let frame = &bytes[12..];
    let decode_error = |message: String| CodecError::Decode {
        what: what.to_string(),
        message,
    };
    let stated = match zstd::zstd_safe::get_frame_content_size(frame) {
        Ok(Some(n)) => n,
        Ok(None) => return Err(decode_error("a zstd frame without its size".into())),
        Err(_) => return Err(decode_error("not a zstd frame".into())),
    };
    let size = usize::try_from(stated)
        .ok()
        .filter(|&n| n <= budget_bytes.min(MAX_BLOB_BYTES))
        .ok_or_else(|| CodecError::OverBudget {
            what: what.to_string(),
            budget: budget_bytes,
            message: format!("a body of {stated} bytes"),
        })?;
    let body =
        zstd::bulk::decompress(frame, size).map_err(|e| decode_error(format!("zstd: {e}")))?;
    if body.len() != size {
        return Err(decode_error(format!(
            "the zstd frame states {size} bytes and holds {}",
            body.len()
        )));
    }
    within_budget(budget_bytes - size, budget_bytes, || {
        decode_body(&body, what)
    })
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
    within_budget(budget_bytes, budget_bytes, || {
        decode_inner(magic, version, bytes, limit, what)
    })
}

/// `decode` with `left` bytes of allocation budget; a decoding error it caused by running out
/// is reported as over the message's `budget_bytes`.
fn within_budget<T>(
    left: usize,
    budget_bytes: usize,
    decode: impl FnOnce() -> Result<T, CodecError>,
) -> Result<T, CodecError> {
    let (out, exceeded) = crate::budget::with_budget(left, decode);
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
    check_header(magic, version, bytes, limit, what)?;
    decode_body(&bytes[12..], what)
}

/// The checks of every blob: its size against `limit`, its magic and format version.
fn check_header(
    magic: &[u8; 8],
    version: u32,
    bytes: &[u8],
    limit: usize,
    what: &str,
) -> Result<(), CodecError> {
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
    Ok(())
}

/// The value of a bincode `body`, which it must fill exactly.
fn decode_body<T: DeserializeOwned>(body: &[u8], what: &str) -> Result<T, CodecError> {
    let (value, used): (T, usize) =
        bincode::serde::decode_from_slice(body, config()).map_err(|e| CodecError::Decode {
            what: what.to_string(),
            message: e.to_string(),
        })?;
    if used != body.len() {
        return Err(CodecError::Trailing {
            what: what.to_string(),
            len: body.len() - used,
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

    type V = (u32, Vec<f32>, String);

    fn compressed(v: &V) -> Vec<u8> {
        encode_compressed(b"TESTBLOB", 3, v, "t").expect("encode")
    }

    /// A compressed blob reads back; the budget is charged with the frame's stated size before
    /// anything is allocated, so a small frame cannot make the reader allocate what it states.
    #[test]
    fn a_compressed_blob_reads_back_within_its_budget() {
        let v: V = (7, vec![0.25; 10_000], "zstd".into());
        let b = compressed(&v);
        assert!(
            b.len() < 1_000,
            "{} bytes: the repeated values compress",
            b.len()
        );
        let back: V =
            decode_compressed_budgeted(b"TESTBLOB", 3, &b, 1 << 20, 1 << 20, "t").expect("decode");
        assert_eq!(back, v);
        // 40 kB of body against a budget of 20 kB: refused on the frame's stated size, before
        // decompressing (the body's `Vec<f32>` would be refused later, so the message tells).
        let e = decode_compressed_budgeted::<V>(b"TESTBLOB", 3, &b, 1 << 20, 20_000, "msg")
            .unwrap_err();
        assert!(
            matches!(e, CodecError::OverBudget { .. }) && e.to_string().contains("a body of"),
            "{e}"
        );
        // What the body's collections allocate counts against what the frame left of it.
        #[derive(serde::Serialize, serde::Deserialize, Debug)]
        struct Budgeted {
            #[serde(deserialize_with = "crate::budget::vec")]
            v: Vec<f32>,
        }
        let b = encode_compressed(b"TESTBLOB", 3, &Budgeted { v: v.1 }, "t").expect("encode");
        let read = |budget| {
            decode_compressed_budgeted::<Budgeted>(b"TESTBLOB", 3, &b, 1 << 20, budget, "msg")
        };
        let e = read(50_000).unwrap_err();
        assert!(matches!(e, CodecError::OverBudget { .. }), "{e}");
        assert_eq!(read(90_000).expect("body and vector fit").v.len(), 10_000);
    }

    /// Frames that lie or are broken are clear errors, never a panic or an unbounded allocation.
    #[test]
    fn a_bad_frame_is_a_clear_error() {
        let v: V = (7, vec![0.25; 1_000], "zstd".into());
        let b = compressed(&v);
        let read = |bytes: &[u8]| {
            decode_compressed_budgeted::<V>(b"TESTBLOB", 3, bytes, 1 << 20, 1 << 20, "msg")
        };
        // Not a zstd frame: an uncompressed blob of the same kind.
        let plain = encode(b"TESTBLOB", 3, &v, "t").expect("encode");
        let e = read(&plain).unwrap_err();
        assert!(
            e.to_string().contains("msg") && e.to_string().contains("zstd"),
            "{e}"
        );
        // A frame without its stated size (streamed by an encoder that did not know it).
        let mut sizeless = b[..12].to_vec();
        let body = bincode::serde::encode_to_vec(&v, config()).expect("body");
        let mut enc = zstd::stream::Encoder::new(Vec::new(), 3).expect("encoder");
        enc.include_contentsize(false).expect("no size");
        std::io::Write::write_all(&mut enc, &body).expect("write");
        sizeless.extend_from_slice(&enc.finish().expect("frame"));
        let e = read(&sizeless).unwrap_err();
        assert!(e.to_string().contains("without its size"), "{e}");
        // A frame whose stated size is smaller than what it holds.
        let mut small = b[..12].to_vec();
        let mut enc = zstd::stream::Encoder::new(Vec::new(), 3).expect("encoder");
        enc.set_pledged_src_size(Some(body.len() as u64))
            .expect("pledge");
        std::io::Write::write_all(&mut enc, &body).expect("write");
        let mut frame = enc.finish().expect("frame");
        // The frame header's content size field: patch it to state fewer bytes.
        let honest = zstd::zstd_safe::get_frame_content_size(&frame).expect("size");
        assert_eq!(honest, Some(body.len() as u64));
        let at = frame
            .windows(2)
            .position(|w| u16::from_le_bytes([w[0], w[1]]) as usize + 256 == body.len())
            .expect("a 2-byte content size field");
        frame[at..at + 2].copy_from_slice(&((body.len() - 256 - 100) as u16).to_le_bytes());
        small.extend_from_slice(&frame);
        let e = read(&small).unwrap_err();
        assert!(matches!(e, CodecError::Decode { .. }), "{e}");
        // Truncated and corrupted frames.
        for cut in [13, b.len() / 2, b.len() - 1] {
            assert!(read(&b[..cut]).is_err(), "cut at {cut}");
        }
        let mut flipped = b.clone();
        for i in (12..flipped.len()).step_by(7) {
            flipped[i] ^= 0x5a;
            let _ = read(&flipped);
        }
    }
}
