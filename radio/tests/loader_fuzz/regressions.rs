//! The valid samples and the real data files load, and the cases the property tests once
//! found stay fixed.

use super::*;

#[test]
fn the_valid_samples_load() {
    for r in judge_geojson(&valid_geojson().to_string()) {
        assert!(r.is_ok(), "{r:?}");
    }
    assert_eq!(
        judge_cells(cells_text(&valid_cells()).as_bytes()).ok(),
        Some(3)
    );
    let specs = judge_sites(".csv", sites_csv(&valid_sites_rows()).as_bytes()).expect("csv");
    assert_eq!(specs.len(), 3);
    let specs = judge_sites(".toml", SITES_TOML.as_bytes()).expect("toml");
    assert_eq!(specs.len(), 2);
}

#[test]
fn the_real_data_files_load() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("..");
    let text = std::fs::read_to_string(root.join("data/nyc_midtown_buildings.geojson"))
        .expect("buildings file");
    let b = parse_buildings(
        &text,
        Path::new("buildings"),
        &projection(),
        BuildingDetail::Parts,
        BIG,
    )
    .expect("real buildings");
    assert!(b.len() > 1000, "{}", b.len());
    let c = read_cells_csv(&root.join("data/nyc_midtown_cells.csv"), &projection())
        .expect("real cells");
    assert!(c.len() > 10, "{}", c.len());
}

#[test]
fn regression_sites_toml_error_names_the_line_not_the_site_number() {
    // Errors of the second `[[site]]` (line 9) said `FILE:2:` (its position in the file).
    let text = SITES_TOML.replace("y_m = 60.0\n", "");
    let msg = judge_sites(".toml", text.as_bytes()).expect_err("no y_m");
    assert!(msg.contains(".toml:9:") && msg.contains("y_m"), "{msg}");
}

#[test]
fn regression_sites_csv_blank_line_shifts_the_reported_line() {
    // The reported line counts blank lines and quoted line breaks (not record number + 2).
    let text = format!("{SITES_HEADER}\n\na,10,20,30,,,,\n\"b\nc\",1,2,3,,,,\nd,5,,,,,,\n");
    let msg = judge_sites(".csv", text.as_bytes()).expect_err("no y_m");
    assert!(msg.contains(".csv:6:") && msg.contains("y_m"), "{msg}");
}

#[test]
fn regression_sites_csv_type_error_names_the_column() {
    // The error names the column, not the CSV deserialiser's 0-based field index ("field 2"),
    // also for `kind` and `boresights_deg`, which the deserialiser's message does not name.
    let text = format!("{SITES_HEADER}\na,10,abc,30,,,,\n");
    let msg = judge_sites(".csv", text.as_bytes()).expect_err("abc");
    assert!(
        msg.contains(".csv:2:") && msg.contains("column `y_m`"),
        "{msg}"
    );
    let text = format!("{SITES_HEADER}\na,10,20,30,giant,,,\n");
    let msg = judge_sites(".csv", text.as_bytes()).expect_err("giant");
    assert!(msg.contains(".csv:2:") && msg.contains("kind"), "{msg}");
    let text = format!("{SITES_HEADER}\na,10,20,30,,18446744073709551616,,\n");
    let msg = judge_sites(".csv", text.as_bytes()).expect_err("u128");
    assert!(
        msg.contains(".csv:2:") && msg.contains("boresights_deg"),
        "{msg}"
    );
}

#[test]
fn regression_geojson_kind_of_the_wrong_type_is_an_error() {
    // A `kind` that is not a string, or a `has_parts` that is not a bool, is an error (not
    // "building" or false, which would extrude an outline on top of its own parts).
    for (pointer, raw, name) in [
        ("/features/0/properties/kind", "5", "kind"),
        ("/features/0/properties/kind", "[\"building\"]", "kind"),
        ("/features/1/properties/has_parts", "\"true\"", "has_parts"),
        ("/features/1/properties/has_parts", "1", "has_parts"),
    ] {
        let text = geojson_with(pointer, raw);
        for r in judge_geojson(&text) {
            let msg = r.expect_err(raw);
            assert!(msg.contains(name) && msg.contains("feature"), "{msg}");
        }
    }
}

#[test]
fn regression_cells_csv_blank_line_shifts_the_reported_line() {
    // The reader's record position is taken before the blank lines it skips: a bad row after a
    // blank line is reported on its own line, not one line early.
    let text = format!("{CELLS_HEADER}\n40.75,-73.98,LTE,,,1,7,1,,x\n\n40.75,NaN,LTE,,,2,8,1,,x\n");
    let (e, path) = judge_cells(text.as_bytes()).expect_err("NaN");
    let msg = e.to_string();
    assert!(
        msg.contains(&format!("{}:4:", path.display())) && msg.contains("lon"),
        "{msg}"
    );
}

#[test]
fn regression_geojson_ring_around_the_globe_is_rejected() {
    // A footprint spanning the globe is refused: the footprint index would size its grid by it
    // and abort the process ("memory allocation of 23336352326448 bytes failed").
    let mut v = valid_geojson();
    v["features"][0]["geometry"]["coordinates"] =
        json!([[[-180, -90], [180, -90], [180, 90], [-180, 90], [-180, -90]]]);
    for r in judge_geojson(&v.to_string()) {
        let msg = r.expect_err("a ring around the globe");
        assert!(msg.contains("feature 0") && msg.contains("spans"), "{msg}");
    }
}

#[test]
fn regression_geojson_hole_outside_the_outer_ring_is_rejected() {
    // A hole beside (or larger than) its outer ring is refused: it would give a negative
    // footprint area and walls where the footprint has none.
    let outer = rect(LON0, LAT0, 1e-4, 1e-4)[0].clone();
    for hole in [
        rect(LON0 + 1e-3, LAT0, 1e-4, 1e-4)[0].clone(),
        rect(LON0 - 1e-4, LAT0 - 1e-4, 3e-4, 3e-4)[0].clone(),
    ] {
        let mut v = valid_geojson();
        v["features"][0]["geometry"]["coordinates"] = json!([outer, hole]);
        for r in judge_geojson(&v.to_string()) {
            let msg = r.expect_err("a hole outside");
            assert!(msg.contains("feature 0") && msg.contains("hole 1"), "{msg}");
        }
    }
}
