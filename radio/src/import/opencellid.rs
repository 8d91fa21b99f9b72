//! An OpenCelliD cell table → the cells CSV [`crate::sites::read_cells_csv`] reads.
//!
//! OpenCelliD's columns (its data exchange format, shared with Mozilla Location Service):
//! `radio,mcc,net,area,cell,unit,lon,lat,range,samples,changeable,created,updated,averageSignal`
//! ([`OPENCELLID_COLUMNS`]), with or without that header line, plain or gzip-compressed (as
//! OpenCelliD ships it; told by its magic bytes). Rows of the chosen `radio` whose position is inside the selection
//! box are kept, in file order, their positions as written; an LTE `cell` is the 28-bit E-UTRAN
//! cell identity, whose eNodeB id is `cell >> 8` and local cell id `cell & 0xFF` (3GPP TS
//! 36.413 §9.2.1.38); another radio's cell is a site of its own. The sites loader merges the
//! cells of one eNodeB of one network (`mcc`, `mnc`, `enb_id`) into one site.

use crate::error::RadioError;
use dupac_common::config::LonLatBox;
use serde::Serialize;
use std::collections::BTreeSet;
use std::io::Read;
use std::path::Path;

/// OpenCelliD's columns, in its order.
pub const OPENCELLID_COLUMNS: [&str; 14] = [
    "radio",
    "mcc",
    "net",
    "area",
    "cell",
    "unit",
    "lon",
    "lat",
    "range",
    "samples",
    "changeable",
    "created",
    "updated",
    "averageSignal",
];
/// The header of the cells CSV written (the columns of `data/nyc_midtown_cells.csv`).
pub const CELLS_HEADER: &str = "lat,lon,radio,mcc,mnc,cell_id,enb_id,local_cell_id,range_m,source";
/// LTE E-UTRAN cell identities have 28 bits.
const ECI_LIMIT: u64 = 1 << 28;
/// Warnings printed one by one before only the count is reported.
const MAX_WARNINGS: usize = 20;

/// Which rows are kept and how they are labelled.
#[derive(Debug, Clone, PartialEq)]
pub struct CellRules {
    /// The `radio` kept (`LTE`, `NR`, `UMTS`, `GSM`, `CDMA`), compared without case.
    pub radio: String,
    /// The `source` column written.
    pub source: String,
    /// A cell id that is not one of its radio's is an error (otherwise the row is skipped with
    /// a warning).
    pub strict: bool,
}

/// What the import did with the rows it read.
#[derive(Debug, Clone, Default, Serialize)]
pub struct CellCounts {
    pub rows: usize,
    pub other_radio: usize,
    pub outside: usize,
    /// LTE rows whose `cell` is not a 28-bit cell identity.
    pub invalid_cell: usize,
    pub kept: usize,
    /// Distinct sites among the kept rows (network and eNodeB).
    pub sites: usize,
}

/// The cells CSV text to write and the counts.
#[derive(Debug, Clone)]
pub struct ImportedCells {
    pub csv: String,
    pub counts: CellCounts,
}

/// Reads `path` (gzip when it starts with gzip's magic bytes `1f 8b`, RFC 1952, whatever its
/// name) and imports it ([`import_cells_from`]).
pub fn import_cells(
    path: &Path,
    select: &LonLatBox,
    rules: &CellRules,
) -> Result<ImportedCells, RadioError> {
    use std::io::BufRead;
    let file = std::fs::File::open(path).map_err(|e| RadioError::io(path, e))?;
    let mut reader = std::io::BufReader::new(file);
    let head = reader.fill_buf().map_err(|e| RadioError::io(path, e))?;
    if head.starts_with(&[0x1f, 0x8b]) {
        import_cells_from(
            flate2::read::MultiGzDecoder::new(reader),
            path,
            select,
            rules,
        )
    } else {
        import_cells_from(reader, path, select, rules)
    }
}

/// Imports the OpenCelliD rows of `input` (streamed: only kept rows are held); `path` names the
/// source in errors.
pub fn import_cells_from(
    input: impl Read,
    path: &Path,
    select: &LonLatBox,
    rules: &CellRules,
) -> Result<ImportedCells, RadioError> {
    let err = |line: u64, message: String| RadioError::Table {
        path: path.to_path_buf(),
        line,
        message,
    };
    if rules.source.contains([',', '"', '\n', '\r']) {
        return Err(RadioError::Import {
            message: format!(
                "source label {:?}: no commas, quotes or line breaks",
                rules.source
            ),
        });
    }
    let want = rules.radio.to_ascii_uppercase();
    let mut reader = csv::ReaderBuilder::new()
        .has_headers(false)
        .trim(csv::Trim::All)
        // A marked blank line is one field; a short row fails on its first missing column.
        .flexible(true)
        .from_reader(MarkBlankLines::new(input));
    let mut records = reader
        .records()
        .filter(|r| !matches!(r, Ok(rec) if rec.len() == 1 && rec[0].is_empty()));
    let first = match records.next() {
        None => return Err(err(1, "file is empty".into())),
        Some(r) => r.map_err(|e| err(line_of(&e), e.to_string()))?,
    };
    let header = first.get(0).is_some_and(|f| {
        f.trim_start_matches('\u{feff}')
            .eq_ignore_ascii_case("radio")
    });
    let names: Vec<String> = if header {
        first
            .iter()
            .map(|f| f.trim_start_matches('\u{feff}').to_string())
            .collect()
    } else {
        OPENCELLID_COLUMNS.iter().map(|c| c.to_string()).collect()
    };
    let column = |name: &str| {
        names
            .iter()
            .position(|h| h.eq_ignore_ascii_case(name))
            .ok_or_else(|| {
                err(
                    1,
                    format!(
                        "missing column `{name}` (OpenCelliD's columns: {})",
                        OPENCELLID_COLUMNS.join(",")
                    ),
                )
            })
    };
    let (c_radio, c_mcc, c_net, c_cell) = (
        column("radio")?,
        column("mcc")?,
        column("net")?,
        column("cell")?,
    );
    let (c_lon, c_lat, c_range) = (column("lon")?, column("lat")?, column("range").ok());
    let mut counts = CellCounts::default();
    let mut sites = BTreeSet::new();
    let mut warned = 0usize;
    let mut csv = String::from(CELLS_HEADER);
    csv.push_str("\r\n");
    let rest = if header { None } else { Some(Ok(first)) };
    for record in rest.into_iter().chain(records) {
        let record = record.map_err(|e| err(line_of(&e), e.to_string()))?;
        let line = record.position().map_or(0, csv::Position::line);
        counts.rows += 1;
        let field = |c: usize| record.get(c).unwrap_or("");
        if !field(c_radio).eq_ignore_ascii_case(&want) {
            counts.other_radio += 1;
            continue;
        }
        let coord = |c: usize, name: &str, limit: f64| -> Result<f64, RadioError> {
            field(c)
                .parse::<f64>()
                .ok()
                .filter(|v| v.is_finite() && v.abs() <= limit)
                .ok_or_else(|| {
                    err(
                        line,
                        format!("column `{name}`: {:?} is not a WGS84 {name}", field(c)),
                    )
                })
        };
        let (lon, lat) = (coord(c_lon, "lon", 180.0)?, coord(c_lat, "lat", 90.0)?);
        if !(lon >= select.lon_min_deg
            && lon <= select.lon_max_deg
            && lat >= select.lat_min_deg
            && lat <= select.lat_max_deg)
        {
            counts.outside += 1;
            continue;
        }
        let int = |c: usize, name: &str| -> Result<Option<u64>, RadioError> {
            let s = field(c);
            if s.is_empty() {
                return Ok(None);
            }
            s.parse::<u64>().map(Some).map_err(|_| {
                err(
                    line,
                    format!("column `{name}`: {s:?} is not a non-negative integer"),
                )
            })
        };
        let (mcc, net) = (int(c_mcc, "mcc")?, int(c_net, "net")?);
        let cell =
            int(c_cell, "cell")?.ok_or_else(|| err(line, "column `cell` is empty".into()))?;
        let range = match c_range.map(field).filter(|s| !s.is_empty()) {
            Some(s) if s.parse::<f64>().is_ok_and(|v| v.is_finite() && v >= 0.0) => s,
            Some(s) => {
                return Err(err(
                    line,
                    format!("column `range`: {s:?} is not a range in metres"),
                ));
            }
            None => "",
        };
        let (enb, local) = if want == "LTE" {
            if cell >= ECI_LIMIT {
                let why = format!("column `cell`: {cell} is not a 28-bit LTE cell identity");
                if rules.strict {
                    return Err(err(line, format!("{why} (--strict)")));
                }
                counts.invalid_cell += 1;
                warned += 1;
                if warned <= MAX_WARNINGS {
                    tracing::warn!(file = %path.display(), line, "{why}: row skipped");
                }
                continue;
            }
            (cell >> 8, (cell & 0xFF).to_string())
        } else {
            (cell, String::new())
        };
        let text = |v: Option<u64>| v.map(|x| x.to_string()).unwrap_or_default();
        let (mcc, mnc) = (text(mcc), text(net));
        csv.push_str(&format!(
            "{},{},{want},{mcc},{mnc},{cell},{enb},{local},{range},{}\r\n",
            field(c_lat),
            field(c_lon),
            rules.source
        ));
        sites.insert((mcc, mnc, enb));
        counts.kept += 1;
    }
    if warned > MAX_WARNINGS {
        tracing::warn!(file = %path.display(), more = warned - MAX_WARNINGS, "further rows skipped");
    }
    counts.sites = sites.len();
    Ok(ImportedCells { csv, counts })
}

fn line_of(e: &csv::Error) -> u64 {
    e.position().map_or(0, csv::Position::line)
}

/// Puts one space on every blank line, so that the csv reader (which skips blank lines without
/// counting them in its line numbers) numbers each record by its line in the file; the reader
/// then yields each blank line as one empty field, which the import skips.
struct MarkBlankLines<R> {
    inner: R,
    buf: Vec<u8>,
    pos: usize,
    line_start: bool,
    marked: bool,
}

impl<R: Read> MarkBlankLines<R> {
    fn new(inner: R) -> Self {
        MarkBlankLines {
            inner,
            buf: Vec::with_capacity(8192),
            pos: 0,
            line_start: true,
            marked: false,
        }
    }
}

impl<R: Read> Read for MarkBlankLines<R> {
    fn read(&mut self, out: &mut [u8]) -> std::io::Result<usize> {
        if out.is_empty() {
            return Ok(0);
        }
        if self.pos == self.buf.len() {
            self.buf.resize(8192, 0);
            let n = self.inner.read(&mut self.buf)?;
            self.buf.truncate(n);
            self.pos = 0;
        }
        let mut w = 0;
        while w < out.len() && self.pos < self.buf.len() {
            let b = self.buf[self.pos];
            if self.line_start && !self.marked && (b == b'\n' || b == b'\r') {
                out[w] = b' ';
                self.marked = true;
            } else {
                out[w] = b;
                self.pos += 1;
                self.line_start = b == b'\n';
                self.marked = false;
            }
            w += 1;
        }
        Ok(w)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const BOX: LonLatBox = LonLatBox {
        lon_min_deg: -74.0,
        lon_max_deg: -73.9,
        lat_min_deg: 40.7,
        lat_max_deg: 40.8,
    };

    fn rules() -> CellRules {
        CellRules {
            radio: "LTE".into(),
            source: "opencellid".into(),
            strict: false,
        }
    }

    fn run(text: &str) -> Result<ImportedCells, RadioError> {
        import_cells_from(text.as_bytes(), Path::new("cells.csv"), &BOX, &rules())
    }

    const HEADER: &str = "radio,mcc,net,area,cell,unit,lon,lat,range,samples,changeable,created,updated,averageSignal\n";

    #[test]
    fn lte_rows_in_the_box_become_cells_of_their_enodeb() {
        let text = format!(
            "{HEADER}LTE,310,410,1,10535937,7,-73.9822783,40.7675568,500,3,1,1,2,0\n\
             LTE,310,410,1,10535938,8,-73.98,40.76,,3,1,1,2,0\n\
             GSM,310,410,1,1234,,-73.98,40.76,500,3,1,1,2,0\n\
             LTE,310,410,1,10535939,8,-73.5,40.76,500,3,1,1,2,0\n\
             lte,311,480,1,10535937,8,-73.95,40.75,1000,3,1,1,2,-80\n"
        );
        let out = run(&text).expect("ok");
        let lines: Vec<&str> = out.csv.lines().collect();
        assert_eq!(lines[0], CELLS_HEADER);
        assert_eq!(
            lines[1],
            "40.7675568,-73.9822783,LTE,310,410,10535937,41156,1,500,opencellid"
        );
        assert_eq!(
            lines[2],
            "40.76,-73.98,LTE,310,410,10535938,41156,2,,opencellid"
        );
        assert_eq!(lines.len(), 4);
        let c = &out.counts;
        assert_eq!((c.rows, c.other_radio, c.outside, c.kept), (5, 1, 1, 3));
        assert_eq!(c.sites, 2, "one eNodeB on each of two networks");
        assert!(out.csv.ends_with("\r\n"));
    }

    #[test]
    fn a_file_without_header_uses_the_documented_order() {
        let out = run("LTE,310,410,1,256,7,-73.95,40.75,500,3,1,1,2,0\n").expect("ok");
        assert_eq!(out.counts.kept, 1);
        assert!(out.csv.contains(",256,1,0,500,"), "{}", out.csv);
    }

    #[test]
    fn bad_rows_name_the_file_line_and_column() {
        let e = run(&format!(
            "{HEADER}LTE,310,410,1,256,7,abc,40.75,500,3,1,1,2,0\n"
        ))
        .expect_err("lon");
        let s = e.to_string();
        assert!(s.contains("cells.csv:2") && s.contains("`lon`"), "{s}");
        let e = run(&format!(
            "{HEADER}LTE,310,x,1,256,7,-73.95,40.75,500,3,1,1,2,0\n"
        ))
        .expect_err("net");
        assert!(e.to_string().contains("`net`"), "{e}");
        let e = run(&format!("{HEADER}LTE,310,410,1,256\n")).expect_err("short");
        assert!(e.to_string().contains("cells.csv:2"), "{e}");
        let e = run("radio,mcc,cell,lon,lat\n").expect_err("no net");
        assert!(e.to_string().contains("`net`"), "{e}");
        let e = run("").expect_err("empty");
        assert!(e.to_string().contains("empty"), "{e}");
        // Blank lines count (LF and CRLF), before the header too; the rows around them are read.
        let e = run(&format!(
            "\n{HEADER}LTE,310,410,1,256,7,-73.95,40.75,500,3,1,1,2,0\n\r\n\nLTE,310,410,1,257,7,abc,40.75,500,3,1,1,2,0\n"
        ))
        .expect_err("lon");
        assert!(e.to_string().contains("cells.csv:6"), "{e}");
        let ok = run(&format!(
            "\n{HEADER}\r\nLTE,310,410,1,256,7,-73.95,40.75,500,3,1,1,2,0\n\n"
        ))
        .expect("blank lines skipped");
        assert_eq!(ok.counts.rows, 1);
    }

    #[test]
    fn an_lte_cell_beyond_28_bits_is_skipped_or_refused() {
        let text = format!("{HEADER}LTE,310,410,1,268435456,7,-73.95,40.75,500,3,1,1,2,0\n");
        let out = run(&text).expect("ok");
        assert_eq!((out.counts.invalid_cell, out.counts.kept), (1, 0));
        let strict = CellRules {
            strict: true,
            ..rules()
        };
        let e = import_cells_from(text.as_bytes(), Path::new("c.csv"), &BOX, &strict)
            .expect_err("strict");
        assert!(e.to_string().contains("c.csv:2") && e.to_string().contains("`cell`"));
    }

    #[test]
    fn gzip_files_are_read() {
        use std::io::Write;
        let dir = tempfile::tempdir().expect("tmp");
        // Told by its magic bytes, not its name.
        let path = dir.path().join("310.CSV.GZ");
        let mut gz = flate2::write::GzEncoder::new(Vec::new(), flate2::Compression::fast());
        gz.write_all(b"LTE,310,410,1,256,7,-73.95,40.75,500,3,1,1,2,0\n")
            .expect("gz");
        std::fs::write(&path, gz.finish().expect("gz")).expect("write");
        let out = import_cells(&path, &BOX, &rules()).expect("ok");
        assert_eq!(out.counts.kept, 1);
    }
}
