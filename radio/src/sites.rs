//! Ground base stations (GBS): plain data, placement from LTE cell estimates, and user sites files.

use crate::pathloss::Scenario;
use dupac_common::geometry::Point;
use dupac_common::ids::SiteId;
use serde::{Deserialize, Serialize};

/// Site class (spec/radio.md §5 item 10): `macro` when the antenna is above the surrounding
/// rooftops (TR 36.777 UMa), else `micro` (UMi).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum SiteKind {
    Micro,
    Macro,
}

impl SiteKind {
    /// The TR 36.777 scenario whose path loss applies.
    pub fn scenario(self) -> Scenario {
        match self {
            SiteKind::Micro => Scenario::Umi,
            SiteKind::Macro => Scenario::Uma,
        }
    }
}

/// One GBS: a 3-sector site (spec/radio.md §2, D12).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Site {
    pub id: SiteId,
    /// Human-readable origin, e.g. `enb:12345` or a user-given name.
    pub name: String,
    /// Antenna position (m; stored as `[x, y, z]`), z = antenna height above ground.
    #[serde(with = "dupac_common::geometry::serde_point")]
    pub position_m: Point,
    pub kind: SiteKind,
    /// Sector boresights (deg, CCW from east).
    pub boresights_deg: Vec<f64>,
    /// Electrical downtilt (deg).
    pub electrical_tilt_deg: f64,
    /// Reference-signal power per RE (dBm).
    pub tx_power_dbm: f64,
    /// How the antenna is mounted: `roof` of a building, or a street `pole`.
    pub mount: Mount,
}

/// How a site's antenna is mounted.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Mount {
    /// On the roof of the building with this id, at roof + mast.
    Roof { building: String, roof_m: f64 },
    /// On a street pole.
    Pole,
    /// Given by the user's sites file.
    User,
}

/// One row of a user sites file (CSV or TOML `[[site]]`). Unset fields follow the placement rule
/// and the radio defaults.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SiteSpec {
    pub name: Option<String>,
    /// Local position (m); give either `x_m`/`y_m` or `lon_deg`/`lat_deg`.
    pub x_m: Option<f64>,
    pub y_m: Option<f64>,
    pub lon_deg: Option<f64>,
    pub lat_deg: Option<f64>,
    /// Antenna height above ground (m); default: rooftop/pole rule.
    pub z_m: Option<f64>,
    #[serde(default, deserialize_with = "de_kind")]
    pub kind: Option<SiteKind>,
    /// Boresights (deg); in CSV a `;`-separated list such as `30;150;270`.
    #[serde(default, deserialize_with = "de_boresights")]
    pub boresights_deg: Option<Vec<f64>>,
    pub tilt_deg: Option<f64>,
    pub tx_power_dbm: Option<f64>,
}

/// [`SiteKind`], with the field named in the error (the CSV reader names no column for it).
fn de_kind<'de, D: serde::Deserializer<'de>>(d: D) -> Result<Option<SiteKind>, D::Error> {
    Option::<SiteKind>::deserialize(d).map_err(|e| serde::de::Error::custom(format!("kind: {e}")))
}

fn de_boresights<'de, D: serde::Deserializer<'de>>(d: D) -> Result<Option<Vec<f64>>, D::Error> {
    #[derive(Deserialize)]
    #[serde(untagged)]
    enum Raw {
        List(Vec<f64>),
        Text(String),
        Number(f64),
    }
    let raw = Option::<Raw>::deserialize(d).map_err(|e| {
        serde::de::Error::custom(format!(
            "boresights_deg: expected an angle, a list of angles or `;`-separated angles ({e})"
        ))
    })?;
    match raw {
        None => Ok(None),
        Some(Raw::List(v)) => Ok(Some(v)),
        Some(Raw::Number(x)) => Ok(Some(vec![x])),
        Some(Raw::Text(s)) if s.trim().is_empty() => Ok(None),
        Some(Raw::Text(s)) => s
            .split(';')
            .map(|p| p.trim().parse::<f64>())
            .collect::<Result<Vec<_>, _>>()
            .map(Some)
            .map_err(|e| serde::de::Error::custom(format!("boresights_deg {s:?}: {e}"))),
    }
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct SitesToml {
    /// Spanned: errors of a site name the line of its `[[site]]` header.
    site: Vec<toml::Spanned<SiteSpec>>,
}

/// A site position before mounting (from a cell-site estimate or a procedural lattice).
#[derive(Debug, Clone, PartialEq)]
pub struct Candidate {
    pub name: String,
    pub xy_m: [f64; 2],
}

use crate::city::{Building, City};
use crate::error::RadioError;
use crate::geo::LocalProjection;
use dupac_common::config::{CityKind, RadioConfig, ScenarioConfig};
use std::collections::BTreeMap;
use std::path::Path;

/// Reads LTE cell estimates (`data/nyc_midtown_cells.csv`: columns `lat`, `lon`, `enb_id`, and
/// optionally `mcc`, `mnc`, …) and merges the cells of each eNodeB of one network (`mcc`, `mnc`,
/// `enb_id`; eNodeB ids are unique only within a network) into one site at their mean position,
/// named `enb:<enb_id>`, or `enb:<mcc>-<mnc>:<enb_id>` when the network is given. `path` is
/// relative to the working directory; the default Midtown path falls back to the built-in copy
/// ([`crate::bundled::read`]).
pub fn read_cells_csv(
    path: &Path,
    projection: &LocalProjection,
) -> Result<Vec<Candidate>, RadioError> {
    let table_err = |line: u64, message: String| RadioError::Table {
        path: path.to_path_buf(),
        line,
        message,
    };
    let (bytes, _) = crate::bundled::read(path)?;
    let bytes = bytes.as_ref();
    let mut reader = csv::ReaderBuilder::new()
        .has_headers(true)
        .trim(csv::Trim::All)
        .from_reader(bytes);
    let headers = reader
        .headers()
        .map_err(|e| table_err(1, e.to_string()))?
        .clone();
    let column = |name: &str| {
        headers
            .iter()
            .position(|h| h == name)
            .ok_or_else(|| table_err(1, format!("missing column `{name}` (header: {headers:?})")))
    };
    let (c_lat, c_lon, c_enb) = (column("lat")?, column("lon")?, column("enb_id")?);
    let (c_mcc, c_mnc) = (column("mcc").ok(), column("mnc").ok());
    let mut by_enb: BTreeMap<(String, String, u64), (f64, f64, usize)> = BTreeMap::new();
    for record in reader.records() {
        let record = record.map_err(|e| {
            let line = record_line(bytes, e.position());
            table_err(line, e.to_string())
        })?;
        let line = record_line(bytes, record.position());
        let field = |c: usize, name: &str| -> Result<&str, RadioError> {
            record
                .get(c)
                .filter(|s| !s.is_empty())
                .ok_or_else(|| table_err(line, format!("column `{name}` is empty")))
        };
        let num = |c: usize, name: &str| -> Result<f64, RadioError> {
            let s = field(c, name)?;
            s.parse::<f64>()
                .ok()
                .filter(|v| v.is_finite())
                .ok_or_else(|| {
                    table_err(
                        line,
                        format!("column `{name}`: {s:?} is not a finite number"),
                    )
                })
        };
        let lat = num(c_lat, "lat")?;
        let lon = num(c_lon, "lon")?;
        if lat.abs() > 90.0 || lon.abs() > 180.0 {
            return Err(table_err(
                line,
                format!("({lat}, {lon}) is not a WGS84 lat/lon"),
            ));
        }
        let s = field(c_enb, "enb_id")?;
        let enb: u64 = s
            .parse()
            .map_err(|_| table_err(line, format!("column `enb_id`: {s:?} is not an integer")))?;
        let network = |c: Option<usize>, name: &str| -> Result<String, RadioError> {
            let v = c.and_then(|c| record.get(c)).unwrap_or("");
            if v.chars().all(|ch| ch.is_ascii_digit()) {
                Ok(v.to_string())
            } else {
                Err(table_err(
                    line,
                    format!("column `{name}`: {v:?} is not a network code"),
                ))
            }
        };
        let key = (network(c_mcc, "mcc")?, network(c_mnc, "mnc")?, enb);
        let e = by_enb.entry(key).or_insert((0.0, 0.0, 0));
        e.0 += lon;
        e.1 += lat;
        e.2 += 1;
    }
    Ok(by_enb
        .into_iter()
        .map(|((mcc, mnc, enb), (slon, slat, n))| Candidate {
            name: if mcc.is_empty() && mnc.is_empty() {
                format!("enb:{enb}")
            } else {
                format!("enb:{mcc}-{mnc}:{enb}")
            },
            xy_m: projection.to_local_m(slon / n as f64, slat / n as f64),
        })
        .collect())
}

/// The line a CSV record starts on. The reader's position is taken before the blank lines it
/// skips ahead of the record, so these are counted here.
fn record_line(text: &[u8], pos: Option<&csv::Position>) -> u64 {
    let Some(pos) = pos else { return 1 };
    let rest = usize::try_from(pos.byte())
        .ok()
        .and_then(|b| text.get(b..))
        .unwrap_or_default();
    let blank = rest
        .iter()
        .take_while(|&&b| b == b'\n' || b == b'\r')
        .filter(|&&b| b == b'\n')
        .count();
    pos.line() + blank as u64
}

/// Reads a user sites file: TOML (`[[site]]` tables) when the name ends in `.toml`, else CSV with
/// a header naming [`SiteSpec`] fields (any subset; `x_m`+`y_m` or `lon_deg`+`lat_deg` required).
/// Each site comes with the line it starts on (its `[[site]]` header, or its CSV record).
pub fn read_sites_file(path: &Path) -> Result<Vec<(u64, SiteSpec)>, RadioError> {
    let text = std::fs::read_to_string(path).map_err(|e| RadioError::io(path, e))?;
    let specs: Vec<(u64, SiteSpec)> = if path.extension().is_some_and(|e| e == "toml") {
        let parsed: SitesToml = toml::from_str(&text).map_err(|e| RadioError::Sites {
            path: path.to_path_buf(),
            message: e.to_string(),
        })?;
        parsed
            .site
            .into_iter()
            .map(|s| {
                let start = s.span().start.min(text.len());
                let line = text.as_bytes()[..start]
                    .iter()
                    .filter(|&&b| b == b'\n')
                    .count() as u64
                    + 1;
                (line, s.into_inner())
            })
            .collect()
    } else {
        let table_err = |line: u64, message: String| RadioError::Table {
            path: path.to_path_buf(),
            line,
            message,
        };
        let mut reader = csv::ReaderBuilder::new()
            .has_headers(true)
            .trim(csv::Trim::All)
            .from_reader(text.as_bytes());
        let headers = reader
            .headers()
            .map_err(|e| table_err(1, e.to_string()))?
            .clone();
        let mut out = Vec::new();
        for record in reader.records() {
            let record = record.map_err(|e| {
                table_err(record_line(text.as_bytes(), e.position()), e.to_string())
            })?;
            let line = record_line(text.as_bytes(), record.position());
            let spec: SiteSpec = record.deserialize(Some(&headers)).map_err(|e| {
                let column = match e.kind() {
                    csv::ErrorKind::Deserialize { err, .. } => {
                        err.field().and_then(|f| headers.get(f as usize))
                    }
                    _ => None,
                };
                match column {
                    Some(name) => table_err(line, format!("column `{name}`: {e}")),
                    None => table_err(line, e.to_string()),
                }
            })?;
            out.push((line, spec));
        }
        out
    };
    if specs.is_empty() {
        return Err(RadioError::Sites {
            path: path.to_path_buf(),
            message: "no sites in file".into(),
        });
    }
    Ok(specs)
}

/// Places the scenario's M sites: from the user's sites file when given, else the
/// `n_sites` cell-site estimates (or procedural candidates) nearest the centre, each mounted on
/// the nearest roof within `roof_search_m` (antenna = roof + `roof_mast_m`) or on a pole, and
/// classed macro/micro against the median rooftop within `macro_radius_m`.
pub fn place_sites(
    cfg: &ScenarioConfig,
    radio: &RadioConfig,
    city: &City,
) -> Result<Vec<Site>, RadioError> {
    if let Some(path) = &cfg.sites_file {
        let specs = read_sites_file(path)?;
        return specs
            .into_iter()
            .enumerate()
            .map(|(i, (line, spec))| {
                resolve_spec(&spec, i, cfg, radio, city).map_err(|message| RadioError::Table {
                    path: path.clone(),
                    line,
                    message,
                })
            })
            .collect();
    }
    let (mut candidates, source) = match cfg.city {
        CityKind::Osm => {
            let projection = city
                .projection
                .unwrap_or_else(|| LocalProjection::centred_on(&cfg.area));
            (
                read_cells_csv(&cfg.cells_file, &projection)?,
                cfg.cells_file.clone(),
            )
        }
        CityKind::Procedural => {
            let generated = crate::city::procedural::generate(&cfg.procedural);
            let c = generated
                .site_candidates_m
                .into_iter()
                .enumerate()
                .map(|(i, xy_m)| Candidate {
                    name: format!("proc-site:{i}"),
                    xy_m,
                })
                .collect();
            (c, "scenario.procedural".into())
        }
    };
    if candidates.len() < cfg.n_sites {
        return Err(RadioError::Sites {
            path: source,
            message: format!(
                "{} distinct sites available, scenario.n_sites asks for {}",
                candidates.len(),
                cfg.n_sites
            ),
        });
    }
    candidates.sort_by(|a, b| {
        let da = a.xy_m[0].hypot(a.xy_m[1]);
        let db = b.xy_m[0].hypot(b.xy_m[1]);
        da.total_cmp(&db).then_with(|| a.name.cmp(&b.name))
    });
    candidates.truncate(cfg.n_sites);
    Ok(candidates
        .into_iter()
        .enumerate()
        .map(|(i, c)| {
            let (position_m, mount) = mount_site(city, c.xy_m, cfg);
            let kind = classify_kind(city, position_m, cfg.macro_radius_m);
            Site {
                id: SiteId(i as u16),
                name: c.name,
                position_m,
                kind,
                boresights_deg: radio.antenna.boresights_deg.clone(),
                electrical_tilt_deg: radio.antenna.electrical_tilt_deg,
                tx_power_dbm: radio.tx_power_dbm,
                mount,
            }
        })
        .collect())
}

/// Farthest site accepted from the scenario centre (m): far beyond any city model.
pub const MAX_SITE_RANGE_M: f64 = 100_000.0;
/// Highest antenna accepted (m above the ground): above the tallest masts.
pub const MAX_SITE_HEIGHT_M: f64 = 1_000.0;

fn resolve_spec(
    spec: &SiteSpec,
    i: usize,
    cfg: &ScenarioConfig,
    radio: &RadioConfig,
    city: &City,
) -> Result<Site, String> {
    let finite = |name: &str, v: Option<f64>| -> Result<Option<f64>, String> {
        match v {
            Some(x) if !x.is_finite() => Err(format!("field `{name}` = {x} is not finite")),
            other => Ok(other),
        }
    };
    let xy = match (
        finite("x_m", spec.x_m)?,
        finite("y_m", spec.y_m)?,
        finite("lon_deg", spec.lon_deg)?,
        finite("lat_deg", spec.lat_deg)?,
    ) {
        (Some(x), Some(y), None, None) => [x, y],
        (None, None, Some(lon), Some(lat)) => {
            let p = city
                .projection
                .ok_or("`lon_deg`/`lat_deg` need a real (OSM) city; use `x_m`/`y_m`")?;
            p.to_local_m(lon, lat)
        }
        _ => {
            return Err(
                "give exactly one position: `x_m` and `y_m`, or `lon_deg` and `lat_deg`".into(),
            );
        }
    };
    let by_lonlat = spec.x_m.is_none();
    for (name, v) in [("x_m", xy[0]), ("y_m", xy[1])] {
        let name = match (by_lonlat, name) {
            (true, "x_m") => "lon_deg",
            (true, _) => "lat_deg",
            (false, n) => n,
        };
        if v.abs() > MAX_SITE_RANGE_M {
            return Err(format!(
                "field `{name}`: {v:e} m east/north, more than {MAX_SITE_RANGE_M} m from the scenario centre"
            ));
        }
    }
    let (position_m, mount) = match finite("z_m", spec.z_m)? {
        Some(z) if z > 0.0 && z <= MAX_SITE_HEIGHT_M => (Point::new(xy[0], xy[1], z), Mount::User),
        Some(z) => {
            return Err(format!(
                "field `z_m` = {z} must be in (0, {MAX_SITE_HEIGHT_M}] (antenna height, m)"
            ));
        }
        None => mount_site(city, xy, cfg),
    };
    let kind = spec
        .kind
        .unwrap_or_else(|| classify_kind(city, position_m, cfg.macro_radius_m));
    let boresights_deg = spec
        .boresights_deg
        .clone()
        .unwrap_or_else(|| radio.antenna.boresights_deg.clone());
    if boresights_deg.is_empty() || boresights_deg.iter().any(|b| !b.is_finite()) {
        return Err("field `boresights_deg` must list finite angles".into());
    }
    let electrical_tilt_deg =
        finite("tilt_deg", spec.tilt_deg)?.unwrap_or(radio.antenna.electrical_tilt_deg);
    if !(-90.0..=90.0).contains(&electrical_tilt_deg) {
        return Err(format!(
            "field `tilt_deg` = {electrical_tilt_deg} not in [-90, 90]"
        ));
    }
    Ok(Site {
        id: SiteId(i as u16),
        name: spec.name.clone().unwrap_or_else(|| format!("site:{i}")),
        position_m,
        kind,
        boresights_deg,
        electrical_tilt_deg,
        tx_power_dbm: match finite("tx_power_dbm", spec.tx_power_dbm)? {
            Some(p) if !(-50.0..=80.0).contains(&p) => {
                return Err(format!("field `tx_power_dbm` = {p} not in [-50, 80] dBm"));
            }
            p => p.unwrap_or(radio.tx_power_dbm),
        },
        mount,
    })
}

/// Mounts an antenna near `xy_m`: on the nearest roof within `roof_search_m` (at the point of the
/// roof edge nearest `xy_m`, 1 m inside it, at the highest roof there + `roof_mast_m`) or on a
/// street pole of `pole_height_m`.
pub fn mount_site(city: &City, xy_m: [f64; 2], cfg: &ScenarioConfig) -> (Point, Mount) {
    let [x, y] = xy_m;
    let mut best: Option<(f64, [f64; 2], &Building)> = None;
    for i in city.index.near(x, y, cfg.roof_search_m) {
        let Some(b) = city.buildings.get(i as usize) else {
            continue;
        };
        let (d, q) = if b.contains_xy(x, y) {
            (0.0, nearest_on_rings(b, xy_m).1)
        } else {
            nearest_on_rings(b, xy_m)
        };
        if d <= cfg.roof_search_m && best.as_ref().is_none_or(|(bd, _, _)| d < *bd) {
            best = Some((d, q, b));
        }
    }
    match best {
        Some((d, q, b)) => {
            // Antennas stand at the roof edge (parapet) nearest the estimated position, 1 m
            // inside it, where they see down into the street; a mast in the middle of a large
            // roof would be shadowed by its own roof for every low UAV.
            let to_edge = (q[0] - x).hypot(q[1] - y);
            let on = if to_edge <= EDGE_SETBACK_M {
                if d > 0.0 { q } else { xy_m }
            } else {
                let (ux, uy) = ((q[0] - x) / to_edge, (q[1] - y) / to_edge);
                // Outside: step past the edge inwards; inside: stop short of the edge.
                let s = if d > 0.0 {
                    EDGE_SETBACK_M
                } else {
                    -EDGE_SETBACK_M
                };
                let p = [q[0] + s * ux, q[1] + s * uy];
                if b.contains_xy(p[0], p[1]) { p } else { q }
            };
            let roof_m = city.roof_height_m(on[0], on[1]).max(b.z_max_m);
            (
                Point::new(on[0], on[1], roof_m + cfg.roof_mast_m),
                Mount::Roof {
                    building: b.id.clone(),
                    roof_m,
                },
            )
        }
        None => (Point::new(x, y, cfg.pole_height_m), Mount::Pole),
    }
}

/// How far inside the roof edge a rooftop antenna stands (m).
const EDGE_SETBACK_M: f64 = 1.0;

/// Nearest point on a footprint's rings to `p` and its distance (m).
fn nearest_on_rings(b: &Building, p: [f64; 2]) -> (f64, [f64; 2]) {
    let mut best = (f64::INFINITY, p);
    for ring in std::iter::once(&b.outer_m).chain(b.holes_m.iter()) {
        for k in 0..ring.len() {
            let a = ring[k];
            let c = ring[(k + 1) % ring.len()];
            let (dx, dy) = (c[0] - a[0], c[1] - a[1]);
            let len2 = dx * dx + dy * dy;
            let t = if len2 > 0.0 {
                (((p[0] - a[0]) * dx + (p[1] - a[1]) * dy) / len2).clamp(0.0, 1.0)
            } else {
                0.0
            };
            let q = [a[0] + t * dx, a[1] + t * dy];
            let d = (q[0] - p[0]).hypot(q[1] - p[1]);
            if d < best.0 {
                best = (d, q);
            }
        }
    }
    best
}

/// Sampling step for the median rooftop height around a site (m).
const ROOFTOP_SAMPLE_M: f64 = 5.0;

/// `macro` when the antenna is above the median rooftop height of the built area within
/// `radius_m` (spec/radio.md §5 item 10), else `micro`. No buildings around: `macro`.
pub fn classify_kind(city: &City, antenna_m: Point, radius_m: f64) -> SiteKind {
    let mut roofs = Vec::new();
    let n = (radius_m / ROOFTOP_SAMPLE_M).ceil() as i64;
    for j in -n..=n {
        for i in -n..=n {
            let (dx, dy) = (i as f64 * ROOFTOP_SAMPLE_M, j as f64 * ROOFTOP_SAMPLE_M);
            if dx.hypot(dy) > radius_m {
                continue;
            }
            let r = city.roof_height_m(antenna_m[0] + dx, antenna_m[1] + dy);
            if r > 0.0 {
                roofs.push(r);
            }
        }
    }
    if roofs.is_empty() {
        return SiteKind::Macro;
    }
    roofs.sort_by(f64::total_cmp);
    let median = if roofs.len() % 2 == 1 {
        roofs[roofs.len() / 2]
    } else {
        0.5 * (roofs[roofs.len() / 2 - 1] + roofs[roofs.len() / 2])
    };
    if antenna_m[2] > median {
        SiteKind::Macro
    } else {
        SiteKind::Micro
    }
}
