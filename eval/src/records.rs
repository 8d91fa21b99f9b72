//! Evaluation records: one file per method and seed (`OUT/records/<method>__seed<k>.bin`,
//! the one codec with its own magic and version), every step of every flight, with what the
//! metrics need from the configuration; the report is computed from these alone.

use crate::error::refused;
use crate::error::{Context, EvalError};
use crate::metrics::MetricRules;
use crate::record::FlightRecord;
use dupac_common::codec;
use std::path::{Path, PathBuf};

/// Magic and version of a records file (`OUT/records/<method>__seed<k>.bin`).
pub const RECORDS_MAGIC: &[u8; 8] = b"DUPACEVR";
pub const RECORDS_VERSION: u32 = 5;

/// The records of one method and seed, with what the metrics need from the configuration.
#[derive(Debug, serde::Serialize, serde::Deserialize)]
pub struct RecordsFile {
    pub method: String,
    pub seed: u32,
    /// What the metrics need from the run's configuration.
    pub rules: MetricRules,
    pub flights: Vec<FlightRecord>,
}

/// Writes one records file into `dir` (atomically), and the same records as gzip-compressed CSV
/// for readers without this binary (pandas: `pd.read_csv(path)`): `<stem>.flights.csv.gz`, a
/// row per flight, and `<stem>.steps.csv.gz`, a row per step with its flight's index
/// (`flight`, 0-based in the flights file). The `.bin` is what `--report-only` reads.
pub fn write_records(dir: &Path, rec: &RecordsFile) -> Result<(), EvalError> {
    let stem = format!("{}__seed{}", rec.method, rec.seed);
    let bytes = codec::encode(RECORDS_MAGIC, RECORDS_VERSION, rec, "eval records")?;
    dupac_common::fsio::write_plain(&dir.join(format!("{stem}.bin")), &bytes)?;
    let (flights, steps) = records_csv(rec).context("encoding the records as CSV")?;
    dupac_common::fsio::write_plain(
        &dir.join(format!("{stem}.flights.csv.gz")),
        &gzip(&flights)?,
    )?;
    Ok(dupac_common::fsio::write_plain(
        &dir.join(format!("{stem}.steps.csv.gz")),
        &gzip(&steps)?,
    )?)
}

fn gzip(bytes: &[u8]) -> Result<Vec<u8>, EvalError> {
    use std::io::Write;
    let mut z = flate2::write::GzEncoder::new(Vec::new(), flate2::Compression::default());
    z.write_all(bytes).context("compressing the records")?;
    z.finish().context("compressing the records")
}

/// The columns of the per-step CSV, the one layout of a flight's steps (the records'
/// `<stem>.steps.csv.gz`, `dupac fly`'s `steps.csv`, `dupac plan`'s `flight_<path>.csv`).
const STEP_COLUMNS: [&str; 19] = [
    "method",
    "seed",
    "flight",
    "pair_id",
    "step",
    "x_m",
    "y_m",
    "z_m",
    "serving",
    "serving_rsrp_dbm",
    "measured_serving_rsrp_dbm",
    "best_site",
    "best_rsrp_dbm",
    "sinr_db",
    "class",
    "best_class",
    "los",
    "handover",
    "ping_pong",
];

/// The flights and steps CSVs of `rec` (numbers as Rust prints them: each f32 reads back to the
/// same value).
fn records_csv(rec: &RecordsFile) -> Result<(Vec<u8>, Vec<u8>), csv::Error> {
    let mut f = csv::Writer::from_writer(Vec::new());
    f.write_record([
        "method",
        "seed",
        "flight",
        "pair_id",
        "bin_m",
        "shortest_m",
        "straight_m",
        "outcome",
        "source_x_m",
        "source_y_m",
        "source_z_m",
        "destination_x_m",
        "destination_y_m",
        "destination_z_m",
        "remaining_m",
        "start_serving",
        "steps",
    ])?;
    let mut s = csv::Writer::from_writer(Vec::new());
    s.write_record(STEP_COLUMNS)?;
    let seed = rec.seed.to_string();
    for (i, fl) in rec.flights.iter().enumerate() {
        let (idx, pair) = (i.to_string(), fl.pair_id.to_string());
        let outcome = fl.outcome.name();
        let start = fl.start_serving.to_string();
        f.write_record([
            rec.method.as_str(),
            &seed,
            &idx,
            &pair,
            &fl.bin_m.to_string(),
            &fl.shortest_m.to_string(),
            &fl.straight_m.to_string(),
            outcome,
            &fl.source_m[0].to_string(),
            &fl.source_m[1].to_string(),
            &fl.source_m[2].to_string(),
            &fl.destination_m[0].to_string(),
            &fl.destination_m[1].to_string(),
            &fl.destination_m[2].to_string(),
            &fl.remaining_m.to_string(),
            &start,
            &fl.steps.len().to_string(),
        ])?;
        step_rows(&mut s, &rec.method, &seed, i, fl)?;
    }
    Ok((csv_bytes(f)?, csv_bytes(s)?))
}

/// The rows of flight `fl` (index `flight` in its file) of `method` (training seed `seed`) in
/// the per-step CSV ([`STEP_COLUMNS`]).
fn step_rows(
    s: &mut csv::Writer<Vec<u8>>,
    method: &str,
    seed: &str,
    flight: usize,
    fl: &FlightRecord,
) -> Result<(), csv::Error> {
    let (idx, pair) = (flight.to_string(), fl.pair_id.to_string());
    let b = |x: bool| if x { "1" } else { "0" };
    for (k, st) in fl.steps.iter().enumerate() {
        s.write_record([
            method,
            seed,
            &idx,
            &pair,
            &(k + 1).to_string(),
            &st.position_m[0].to_string(),
            &st.position_m[1].to_string(),
            &st.position_m[2].to_string(),
            &st.serving.to_string(),
            &st.serving_rsrp_dbm.to_string(),
            &st.measured_serving_rsrp_dbm.to_string(),
            &st.best_site.to_string(),
            &st.best_rsrp_dbm.to_string(),
            &st.sinr_db.to_string(),
            st.class.name(),
            st.best_class.name(),
            b(st.los),
            b(st.handover),
            b(st.ping_pong),
        ])?;
    }
    Ok(())
}

/// A CSV writer's bytes.
fn csv_bytes(w: csv::Writer<Vec<u8>>) -> Result<Vec<u8>, csv::Error> {
    w.into_inner().map_err(|e| csv::Error::from(e.into_error()))
}

/// Writes the steps of `flights`, flown by `method` (training `seed`), into `path` (atomically)
/// as the per-step CSV of the records: what `dupac fly` (`steps.csv`) and `dupac plan`
/// (`flight_<path>.csv`) write.
pub fn write_steps_csv(
    path: &Path,
    method: &str,
    seed: u32,
    flights: &[FlightRecord],
) -> Result<(), EvalError> {
    let bytes = (|| {
        let mut s = csv::Writer::from_writer(Vec::new());
        s.write_record(STEP_COLUMNS)?;
        for (i, fl) in flights.iter().enumerate() {
            step_rows(&mut s, method, &seed.to_string(), i, fl)?;
        }
        csv_bytes(s)
    })()
    .context_with(|| format!("encoding {} as CSV", path.display()))?;
    Ok(dupac_common::fsio::write_plain(path, &bytes)?)
}

/// The `.bin` files of `dir` (not of its subfolders), in name order.
pub(crate) fn bin_files(dir: &Path) -> Result<Vec<PathBuf>, EvalError> {
    let mut paths: Vec<PathBuf> = std::fs::read_dir(dir)
        .context_with(|| format!("reading {}", dir.display()))?
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.is_file() && p.extension().is_some_and(|x| x == "bin"))
        .collect();
    paths.sort();
    Ok(paths)
}

/// Every records file of `dir`, in name order.
pub fn read_records(dir: &Path) -> Result<Vec<RecordsFile>, EvalError> {
    bin_files(dir)?
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
            let k = &r.rules;
            if !(k.interruption_steps.is_finite()
                && k.interruption_steps >= 0.0
                && k.site_regret_threshold_db.is_finite())
            {
                return Err(refused!(
                    "{}: metric rules {k:?}: not finite or negative",
                    p.display()
                ));
            }
            Ok(r)
        })
        .collect()
}

/// The file beside the records that names the pairs they flew (`records/split.txt`: its first
/// line `split: NAME (…)`, then `file: PATH`), so that `--report-only` reports it too.
pub const SPLIT_FILE: &str = "split.txt";

/// Writes [`SPLIT_FILE`] into `dir` (atomically): `line` (`split: …`) and the pairs file.
pub fn write_split(dir: &Path, line: &str, pairs_file: &Path) -> Result<(), EvalError> {
    let text = format!("{line}\nfile: {}\n", pairs_file.display());
    Ok(dupac_common::fsio::write_plain(
        &dir.join(SPLIT_FILE),
        text.as_bytes(),
    )?)
}

/// The `split: …` line of [`SPLIT_FILE`] in `dir`; `None` when the records have none (an
/// evaluation from before the splits were recorded) or it cannot be read.
pub fn read_split(dir: &Path) -> Option<String> {
    let text = std::fs::read_to_string(dir.join(SPLIT_FILE)).ok()?;
    let line = text.lines().next()?.trim();
    line.starts_with("split: ").then(|| line.to_string())
}
