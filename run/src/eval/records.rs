//! Evaluation records: one file per method and seed (`OUT/records/<method>__seed<k>.bin`,
//! the one codec with its own magic and version), every step of every flight, with what the
//! metrics need from the configuration; the report is computed from these alone.

use super::refused;
use crate::error::{Context, RunError};
use dupac_actor::record::FlightRecord;
use dupac_common::codec;
use std::path::{Path, PathBuf};

/// Magic and version of a records file (`OUT/records/<method>__seed<k>.bin`).
pub const RECORDS_MAGIC: &[u8; 8] = b"DUPACEVR";
pub const RECORDS_VERSION: u32 = 3;

/// The records of one method and seed, with what the metrics need from the configuration.
#[derive(Debug, serde::Serialize, serde::Deserialize)]
pub struct RecordsFile {
    pub method: String,
    pub seed: u32,
    pub ping_pong_window_steps: u32,
    /// `env.site_regret_threshold_db` of the run (dB).
    pub site_regret_threshold_db: f64,
    /// Serving site before the first step, per flight (same order as `flights`).
    pub start_serving: Vec<u16>,
    pub flights: Vec<FlightRecord>,
}

/// Writes one records file into `dir` (atomically).
pub fn write_records(dir: &Path, rec: &RecordsFile) -> Result<(), RunError> {
    let bytes = codec::encode(RECORDS_MAGIC, RECORDS_VERSION, rec, "eval records")?;
    crate::run_dir::write_plain(
        &dir.join(format!("{}__seed{}.bin", rec.method, rec.seed)),
        &bytes,
    )
}

/// Every records file of `dir`, in name order.
pub fn read_records(dir: &Path) -> Result<Vec<RecordsFile>, RunError> {
    let mut paths: Vec<PathBuf> = std::fs::read_dir(dir)
        .context_with(|| format!("reading {}", dir.display()))?
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.extension().is_some_and(|x| x == "bin"))
        .collect();
    paths.sort();
    paths
        .iter()
        .map(|p| {
            let bytes = codec::read_limited(p, codec::MAX_BLOB_BYTES)?;
            let r: RecordsFile = codec::decode(
                RECORDS_MAGIC,
                RECORDS_VERSION,
                &bytes,
                codec::MAX_BLOB_BYTES,
                &p.display().to_string(),
            )?;
            if r.start_serving.len() != r.flights.len() {
                return Err(refused!(
                    "{}: {} start sites for {} flights",
                    p.display(),
                    r.start_serving.len(),
                    r.flights.len()
                ));
            }
            Ok(r)
        })
        .collect()
}
