//! The run's metrics as TensorBoard event files (`events.out.tfevents.dupac` in the run
//! directory), beside `metrics.jsonl`: one scalar per metric per update, at the update's
//! `global_step`, under the metric's own name (CleanRL's tags: `charts/SPS`,
//! `losses/value_loss`, …).
//!
//! Written by hand: the format is a TFRecord stream (length, masked CRC-32C of the length, data,
//! masked CRC-32C of the data) of `Event` protocol buffers (tensorflow/core/util/event.proto)
//! holding `Summary.Value{tag, simple_value}`; of the crates that write it, tensorboard-rs
//! brings protobuf 2 and image decoding for this and has not been released since 2021. Only
//! CRC-32C comes from a crate.

use crate::error::{Context, RunError};
use dupac_common::fsio::write_atomic_with;
use dupac_common::metric;
use dupac_learner::learner::MetricsRow;
use std::io::Write;
use std::path::{Path, PathBuf};
use std::time::{SystemTime, UNIX_EPOCH};

/// The event file's name in the run directory (TensorBoard reads every `*tfevents*` file).
pub const EVENT_FILE: &str = "events.out.tfevents.dupac";

/// An open event file, appended to once per metrics row.
pub struct EventFile {
    path: PathBuf,
    file: std::fs::File,
}

impl EventFile {
    /// Writes `dir/events.out.tfevents.dupac` anew (atomically) with `rows` (the rows a
    /// resumed run keeps) and opens it to append the next ones.
    pub fn create(dir: &Path, rows: &[MetricsRow]) -> Result<EventFile, RunError> {
        let path = dir.join(EVENT_FILE);
        let now = unix_s();
        write_atomic_with(&path, |w| {
            w.write_all(&record(&event(now, 0, Some("brain.Event:2"), &[])))?;
            for r in rows {
                w.write_all(&row_record(now, r))?;
            }
            Ok(())
        })?;
        let file = std::fs::OpenOptions::new()
            .append(true)
            .open(&path)
            .context_with(|| format!("opening {}", path.display()))?;
        Ok(EventFile { path, file })
    }

    /// Appends one metrics row as scalars at its `global_step`.
    pub fn push(&mut self, row: &MetricsRow) -> Result<(), RunError> {
        self.file
            .write_all(&row_record(unix_s(), row))
            .context_with(|| format!("writing {}", self.path.display()))
    }

    /// Flushes to the file (the operating system's buffers; a checkpoint calls it).
    pub fn flush(&mut self) {
        self.file.flush().ok();
    }
}

fn unix_s() -> f64 {
    SystemTime::now()
        .duration_since(UNIX_EPOCH)
        .map(|d| d.as_secs_f64())
        .unwrap_or(0.0)
}

fn row_record(wall_time_s: f64, row: &MetricsRow) -> Vec<u8> {
    let step = row
        .get(metric::GLOBAL_STEP)
        .copied()
        .unwrap_or(0.0)
        .max(0.0) as i64;
    let scalars: Vec<(&str, f32)> = row
        .iter()
        .filter(|(k, _)| k.as_str() != metric::GLOBAL_STEP)
        .map(|(k, v)| (k.as_str(), *v as f32))
        .collect();
    record(&event(wall_time_s, step, None, &scalars))
}

/// Appends the varint encoding of `v` (protocol buffers).
fn varint(out: &mut Vec<u8>, mut v: u64) {
    while v >= 0x80 {
        out.push((v as u8) | 0x80);
        v >>= 7;
    }
    out.push(v as u8);
}

/// Appends a length-delimited field (wire type 2).
fn bytes_field(out: &mut Vec<u8>, field: u32, bytes: &[u8]) {
    varint(out, u64::from(field << 3 | 2));
    varint(out, bytes.len() as u64);
    out.extend_from_slice(bytes);
}

/// An `Event{wall_time = 1, step = 2, file_version = 3 | summary = 5}` with one
/// `Summary.Value{tag = 1, simple_value = 2}` per scalar.
fn event(
    wall_time_s: f64,
    step: i64,
    file_version: Option<&str>,
    scalars: &[(&str, f32)],
) -> Vec<u8> {
    let mut e = Vec::new();
    e.push(1 << 3 | 1);
    e.extend_from_slice(&wall_time_s.to_le_bytes());
    e.push(2 << 3);
    varint(&mut e, step as u64);
    if let Some(v) = file_version {
        bytes_field(&mut e, 3, v.as_bytes());
    }
    if !scalars.is_empty() {
        let mut summary = Vec::new();
        for (tag, v) in scalars {
            let mut value = Vec::new();
            bytes_field(&mut value, 1, tag.as_bytes());
            value.push(2 << 3 | 5);
            value.extend_from_slice(&v.to_le_bytes());
            bytes_field(&mut summary, 1, &value);
        }
        bytes_field(&mut e, 5, &summary);
    }
    e
}

/// CRC-32C masked as TFRecord does: rotated right by 15 bits plus a constant.
fn masked_crc(data: &[u8]) -> u32 {
    let c = crc32c::crc32c(data);
    (c.rotate_right(15)).wrapping_add(0xa282_ead8)
}

/// One TFRecord: length (u64 LE), its masked CRC, the data, its masked CRC.
fn record(data: &[u8]) -> Vec<u8> {
    let len = (data.len() as u64).to_le_bytes();
    let mut r = Vec::with_capacity(data.len() + 16);
    r.extend_from_slice(&len);
    r.extend_from_slice(&masked_crc(&len).to_le_bytes());
    r.extend_from_slice(data);
    r.extend_from_slice(&masked_crc(data).to_le_bytes());
    r
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The CRC-32C check value of the standard ("123456789" → 0xE3069283), and TFRecord's mask.
    #[test]
    fn crc32c_and_its_mask_are_tfrecords() {
        assert_eq!(crc32c::crc32c(b"123456789"), 0xE306_9283);
        // TensorFlow's mask, ((c >> 15) | (c << 17)) + 0xa282ead8, worked by hand.
        assert_eq!(masked_crc(b"123456789"), 0xC78A_B0E5);
    }

    /// A record frames its data with its length and both CRCs; a scalar's bytes are where the
    /// protocol buffer puts them.
    #[test]
    fn a_record_holds_the_event_and_its_checks() {
        let e = event(1.5, 300, None, &[("charts/SPS", 2.0)]);
        let r = record(&e);
        let len = u64::from_le_bytes(r[..8].try_into().unwrap()) as usize;
        assert_eq!(len, e.len());
        assert_eq!(
            u32::from_le_bytes(r[8..12].try_into().unwrap()),
            masked_crc(&r[..8])
        );
        assert_eq!(&r[12..12 + len], &e[..]);
        assert_eq!(
            u32::from_le_bytes(r[12 + len..].try_into().unwrap()),
            masked_crc(&e)
        );
        // wall_time (double, field 1), step (varint 300 = ac 02, field 2).
        assert_eq!(e[0], 0x09);
        assert_eq!(&e[1..9], &1.5f64.to_le_bytes());
        assert_eq!(&e[9..12], &[0x10, 0xac, 0x02]);
        // The tag, then the float (field 2, wire type 5).
        let tag = b"charts/SPS";
        let at = e.windows(tag.len()).position(|w| w == tag).unwrap() + tag.len();
        assert_eq!(e[at], 0x15);
        assert_eq!(&e[at + 1..at + 5], &2.0f32.to_le_bytes());
    }

    /// A resumed run's event file holds the kept rows, then the new ones.
    #[test]
    fn create_writes_the_kept_rows_and_push_appends() {
        let dir = tempfile::tempdir().unwrap();
        let row = |s: f64| {
            MetricsRow::from([
                (metric::GLOBAL_STEP.to_string(), s),
                (metric::SPS.to_string(), 7.0),
            ])
        };
        let mut f = EventFile::create(dir.path(), &[row(100.0)]).unwrap();
        f.push(&row(200.0)).unwrap();
        f.flush();
        let bytes = std::fs::read(dir.path().join(EVENT_FILE)).unwrap();
        let mut at = 0;
        let mut n = 0;
        while at < bytes.len() {
            let len = u64::from_le_bytes(bytes[at..at + 8].try_into().unwrap()) as usize;
            let data = &bytes[at + 12..at + 12 + len];
            assert_eq!(
                u32::from_le_bytes(bytes[at + 12 + len..at + 16 + len].try_into().unwrap()),
                masked_crc(data)
            );
            at += 16 + len;
            n += 1;
        }
        assert_eq!(n, 3, "the version event and two rows");
    }
}
