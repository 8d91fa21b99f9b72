//! The LTE cells CSV ([`read_cells_csv`]) and the user sites file ([`read_sites_file`],
//! CSV or TOML, and through [`place_sites`] the per-site checks), fuzzed: arbitrary and mutated
//! bytes never panic, a hostile field is refused naming its line, column or key.

use super::*;

pub(crate) const CELLS_HEADER: &str =
    "lat,lon,radio,mcc,mnc,cell_id,enb_id,local_cell_id,range_m,source";

/// Rows of the shape of `data/nyc_midtown_cells.csv`: (lat, lon, enb_id).
pub(crate) fn cells_text(rows: &[(f64, f64, u64)]) -> String {
    let mut s = format!("{CELLS_HEADER}\n");
    for (i, (lat, lon, enb)) in rows.iter().enumerate() {
        s.push_str(&format!(
            "{lat},{lon},LTE,,,{},{enb},{},,radiocells-2017\n",
            10_000_000 + i,
            i % 3 + 1
        ));
    }
    s
}

pub(crate) fn valid_cells() -> Vec<(f64, f64, u64)> {
    vec![
        (40.7675568, -73.9822783, 41156),
        (40.7596677, -73.9838201, 41169),
        (40.7600099, -73.9847174, 41169),
        (40.7590093, -73.9819709, 41170),
    ]
}

/// Reads cells text from a temporary file; checks the error names the file and a line ≥ 1.
pub(crate) fn judge_cells(text: &[u8]) -> Result<usize, (RadioError, PathBuf)> {
    let f = temp_file(".csv", text);
    let path = f.path().to_path_buf();
    match read_cells_csv(&path, &projection()) {
        Ok(c) => {
            assert!(
                c.iter().all(|c| c.xy_m.iter().all(|v| v.is_finite())),
                "{c:?}"
            );
            Ok(c.len())
        }
        Err(e) => {
            check_file_error(&e, &path);
            Err((e, path))
        }
    }
}

pub(crate) fn check_file_error(e: &RadioError, path: &Path) {
    let msg = e.to_string();
    let name = path.display().to_string();
    assert!(msg.contains(&name), "error without the file: {msg}");
    if let RadioError::Table { line, .. } = e {
        assert!(*line >= 1, "line 0 is no line: {msg}");
        assert!(msg.contains(&format!("{name}:{line}")), "{msg}");
    }
}

/// Cell (CSV field) values that do not belong in a numeric column.
pub(crate) const HOSTILE_CELLS: &[&str] = &[
    "",
    " ",
    "NaN",
    "nan",
    "inf",
    "-inf",
    "1e309",
    "1e308",
    "-1e308",
    "-91",
    "181",
    "-0",
    "abc",
    "0x10",
    "1_000",
    "-1",
    "18446744073709551616",
    "4.5",
    "\"40.75\"",
    "\"a,b\"",
    "\u{FEFF}1",
    "é",
];

pub(crate) const SITES_HEADER: &str = "name,x_m,y_m,z_m,kind,boresights_deg,tilt_deg,tx_power_dbm";

pub(crate) fn sites_csv(rows: &[[&str; 8]]) -> String {
    let mut s = format!("{SITES_HEADER}\n");
    for r in rows {
        s.push_str(&r.join(","));
        s.push('\n');
    }
    s
}

pub(crate) fn valid_sites_rows() -> Vec<[&'static str; 8]> {
    vec![
        ["a", "10", "20", "30", "macro", "0;120;240", "6", "18"],
        ["b", "-50", "40", "", "micro", "", "", ""],
        ["c", "100", "-100", "25", "", "45", "", "15"],
    ]
}

pub(crate) const SITES_TOML: &str = "# user sites\n\
[[site]]\nname = \"t\"\nx_m = 1.0\ny_m = 2.0\nz_m = 40.0\nkind = \"macro\"\n\n\
[[site]]\nname = \"u\"\nx_m = -30.0\ny_m = 60.0\nboresights_deg = [0.0, 120.0, 240.0]\ntilt_deg = 4.0\n";

/// Hostile TOML values for a `key = value` line.
pub(crate) const HOSTILE_TOML: &[&str] = &[
    "nan",
    "inf",
    "-inf",
    "1e308",
    "-1e308",
    "0",
    "-1",
    "\"12\"",
    "\"\"",
    "\"1;x;3\"",
    "true",
    "[]",
    "[nan]",
    "[\"a\"]",
    "{}",
    "\"giant\"",
    "9223372036854775807",
    "",
    "[",
];

pub(crate) fn judge_sites(suffix: &str, text: &[u8]) -> Result<Vec<(u64, SiteSpec)>, String> {
    let f = temp_file(suffix, text);
    let path = f.path().to_path_buf();
    match read_sites_file(&path) {
        Ok(specs) => {
            assert!(!specs.is_empty());
            let lines = String::from_utf8_lossy(text).lines().count() as u64;
            for (line, _) in &specs {
                assert!(
                    *line >= 1 && *line <= lines.max(1),
                    "line {line} of {lines}"
                );
            }
            // The per-site checks (position, height, angles) name the file and line too.
            let mut cfg = city_config();
            cfg.sites_file = Some(path.clone());
            match place_sites(&cfg, &Config::default().radio, city()) {
                Ok(sites) => {
                    assert_eq!(sites.len(), specs.len());
                    Ok(specs)
                }
                Err(e) => {
                    check_file_error(&e, &path);
                    Err(e.to_string())
                }
            }
        }
        Err(e) => {
            check_file_error(&e, &path);
            Err(e.to_string())
        }
    }
}

pub(crate) fn city_config() -> ScenarioConfig {
    let mut sc = ScenarioConfig {
        city: CityKind::Procedural,
        name: "procedural".into(),
        ..ScenarioConfig::default()
    };
    sc.procedural.size_m = 400.0;
    sc
}

pub(crate) fn city() -> &'static City {
    static CITY: OnceLock<City> = OnceLock::new();
    CITY.get_or_init(|| City::load(&city_config()).expect("procedural city"))
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(512))]

    // ----- cells CSV -----

    #[test]
    fn cells_arbitrary_bytes_never_panic(bytes in proptest::collection::vec(any::<u8>(), 0..256)) {
        let _ = judge_cells(&bytes);
    }

    #[test]
    fn cells_mutated_bytes_never_panic(
        flips in proptest::collection::vec((any::<usize>(), any::<u8>()), 0..6),
        cut in any::<usize>(),
        tail in proptest::collection::vec(any::<u8>(), 0..24),
    ) {
        let bytes = mutate(cells_text(&valid_cells()).into_bytes(), flips, cut, tail);
        let _ = judge_cells(&bytes);
    }

    #[test]
    fn cells_hostile_fields_name_the_line_and_column(
        row in 0usize..4,
        column in prop::sample::select(vec![0usize, 1, 6]),
        value in prop::sample::select(HOSTILE_CELLS),
        blank in 0usize..3,
    ) {
        let text = cells_text(&valid_cells());
        let mut lines: Vec<String> = text.lines().map(str::to_string).collect();
        let mut fields: Vec<&str> = lines[row + 1].split(',').collect();
        fields[column] = value;
        lines[row + 1] = fields.join(",");
        // Blank lines before the changed row (the reader skips them).
        for _ in 0..blank {
            lines.insert(row + 1, String::new());
        }
        if let Err((e, path)) = judge_cells(lines.join("\n").as_bytes()) {
            let msg = e.to_string();
            // The line of the row that was changed (line 1 is the header).
            let at = format!("{}:{}:", path.display(), row + 2 + blank);
            prop_assert!(msg.contains(&at), "{value:?} in column {column}: {msg}");
            let name = ["lat", "lon", "", "", "", "", "enb_id"][column];
            prop_assert!(
                msg.contains(name) || msg.contains("fields") || msg.contains("WGS84"),
                "{value:?} in column {column}: {msg}"
            );
        }
    }

    // ----- sites files -----

    #[test]
    fn sites_arbitrary_bytes_never_panic(
        bytes in proptest::collection::vec(any::<u8>(), 0..256),
        toml in any::<bool>(),
    ) {
        let _ = judge_sites(if toml { ".toml" } else { ".csv" }, &bytes);
    }

    #[test]
    fn sites_mutated_bytes_never_panic(
        flips in proptest::collection::vec((any::<usize>(), any::<u8>()), 0..6),
        cut in any::<usize>(),
        tail in proptest::collection::vec(any::<u8>(), 0..24),
        toml in any::<bool>(),
    ) {
        let (suffix, text) = if toml {
            (".toml", SITES_TOML.to_string())
        } else {
            (".csv", sites_csv(&valid_sites_rows()))
        };
        let bytes = mutate(text.into_bytes(), flips, cut, tail);
        let _ = judge_sites(suffix, &bytes);
    }

    #[test]
    fn sites_csv_hostile_fields_name_the_line(
        row in 0usize..3,
        column in 0usize..8,
        value in prop::sample::select(HOSTILE_CELLS),
    ) {
        let mut rows = valid_sites_rows();
        rows[row][column] = value;
        let text = sites_csv(&rows);
        if let Err(msg) = judge_sites(".csv", text.as_bytes()) {
            let name = SITES_HEADER.split(',').nth(column).expect("column");
            prop_assert!(
                msg.contains(&format!(".csv:{}:", row + 2)) && msg.contains(name),
                "{value:?} in column {column}: {msg}"
            );
        }
    }

    #[test]
    fn sites_csv_errors_name_the_line_of_the_record(
        blanks in proptest::collection::vec(0usize..3, 4),
        multiline in proptest::collection::vec(any::<bool>(), 3),
        bad in 0usize..3,
    ) {
        // Blank lines between records and names quoted across lines: the reported line is where
        // the bad record starts.
        let mut text = format!("{SITES_HEADER}\n");
        let mut line = 2;
        let mut bad_line = 0;
        for (i, row) in valid_sites_rows().iter().enumerate() {
            for _ in 0..blanks[i] {
                text.push('\n');
                line += 1;
            }
            let mut row = row.map(str::to_string);
            if multiline[i] {
                row[0] = format!("\"{}\nsecond line\"", row[0]);
            }
            if i == bad {
                row[2] = String::new(); // no y_m: no position
                bad_line = line;
            }
            text.push_str(&row.join(","));
            text.push('\n');
            line += 1 + usize::from(multiline[i]);
        }
        for _ in 0..blanks[3] {
            text.push('\n');
        }
        let msg = judge_sites(".csv", text.as_bytes()).expect_err("a site without y_m");
        prop_assert!(msg.contains(&format!(".csv:{bad_line}:")) && msg.contains("y_m"), "{text}: {msg}");
    }

    #[test]
    fn sites_toml_hostile_values_name_the_line(
        line in 0usize..13,
        value in prop::sample::select(HOSTILE_TOML),
    ) {
        let mut lines: Vec<String> = SITES_TOML.lines().map(str::to_string).collect();
        let at = line % lines.len();
        let Some((key, _)) = lines[at].split_once(" = ") else {
            return Ok(());
        };
        let key = key.to_string();
        lines[at] = format!("{key} = {value}");
        // The `[[site]]` header of the site holding the key.
        let header = (0..=at).rev().find(|&l| lines[l] == "[[site]]").expect("header") + 1;
        if let Err(msg) = judge_sites(".toml", lines.join("\n").as_bytes()) {
            // A value left open (`[`, `"`) is noticed on a later line.
            let parse_line = msg
                .split_once("at line ")
                .and_then(|(_, r)| r.split(|c: char| !c.is_ascii_digit()).next())
                .and_then(|n| n.parse::<usize>().ok());
            prop_assert!(
                parse_line.is_some_and(|n| n == at + 1 || n > at + 1 && value == "[")
                    || msg.contains(&format!(".toml:{header}:")) && msg.contains(&key),
                "{key} = {value}: {msg}"
            );
        }
    }
}
