//! The OpenStreetMap tags of a building's height, read as metres: `height`, `min_height`,
//! `building:levels`, `roof:levels`, `roof:height`, `building:min_level` (the Simple 3D Buildings
//! scheme of the OSM wiki, <https://wiki.openstreetmap.org/wiki/Simple_3D_Buildings>).
//!
//! Lengths follow the wiki's `Key:height` and `Map_Features/Units`: metres by default (`12`,
//! `12.5`, `12 m`), feet and inches as `40'`, `7'4"` or `40 ft`; a decimal comma, a list
//! (`12;15`) or an approximation (`~12`) is not a length. Levels are counted in storeys of
//! [`HeightRules::level_height_m`] metres (default [`DEFAULT_LEVEL_HEIGHT_M`]).

use serde_json::{Map, Value};

/// Metres per storey when a height is estimated from levels: the OSM wiki's default height of a
/// level, "3 meters (height used for 3D rendering when height tags are not used)"
/// (<https://wiki.openstreetmap.org/wiki/Key:roof:levels>).
pub const DEFAULT_LEVEL_HEIGHT_M: f64 = 3.0;
/// Metres per international foot.
const FOOT_M: f64 = 0.3048;
/// Metres per inch.
const INCH_M: f64 = 0.0254;
/// The most levels a tag may give: above the tallest building's 163 storeys.
const MAX_LEVELS: f64 = 300.0;
/// Lengths at or above this are no building's (m): the city loader's bound on a roof height.
pub const MAX_HEIGHT_M: f64 = 2000.0;

/// A tag whose value is present but not what its key means (`height=tall`).
#[derive(Debug, Clone, PartialEq)]
pub struct TagError {
    /// The key, e.g. `height`.
    pub tag: String,
    /// The value as found.
    pub value: String,
    /// Why it was refused.
    pub why: String,
}

impl std::fmt::Display for TagError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "tag `{}` = {:?}: {}", self.tag, self.value, self.why)
    }
}

/// The tags of one feature: a GeoJSON `properties` object whose values are strings (or numbers,
/// as some converters write them).
#[derive(Debug, Clone, Copy)]
pub struct Tags<'a>(pub &'a Map<String, Value>);

impl Tags<'_> {
    /// The value of `key` as text: `None` when absent, null or empty; a number as written; any
    /// other JSON type is an error.
    pub fn get(&self, key: &str) -> Result<Option<String>, TagError> {
        match self.0.get(key) {
            None | Some(Value::Null) => Ok(None),
            Some(Value::String(s)) if s.trim().is_empty() => Ok(None),
            Some(Value::String(s)) => Ok(Some(s.trim().to_string())),
            Some(Value::Number(n)) => Ok(Some(n.to_string())),
            Some(v) => Err(TagError {
                tag: key.into(),
                value: v.to_string(),
                why: "expected a string or a number".into(),
            }),
        }
    }

    /// The value of `key` as a length in metres ([`parse_length_m`]).
    pub fn length_m(&self, key: &str) -> Result<Option<f64>, TagError> {
        self.parsed(key, parse_length_m)
    }

    /// The value of `key` as a count of levels ([`parse_levels`]).
    pub fn levels(&self, key: &str) -> Result<Option<f64>, TagError> {
        self.parsed(key, parse_levels)
    }

    fn parsed(
        &self,
        key: &str,
        parse: fn(&str) -> Result<f64, String>,
    ) -> Result<Option<f64>, TagError> {
        let Some(v) = self.get(key)? else {
            return Ok(None);
        };
        parse(&v).map(Some).map_err(|why| TagError {
            tag: key.into(),
            value: v,
            why,
        })
    }
}

/// A length tag in metres: `12`, `12.5`, `-3`, `12 m`, `12m`, `12 metres`, `40'`, `40 ft`,
/// `7'4"`, `4"`. Errors say why (`12,5`: a decimal comma; `12;15`: several values).
pub fn parse_length_m(value: &str) -> Result<f64, String> {
    let s = value.trim();
    if s.contains(';') {
        return Err("several values; one length expected".into());
    }
    if s.contains(',') {
        return Err("a decimal comma; OSM lengths use a point (12.5)".into());
    }
    // Feet and inches: 7'4", 7' 4", 40', 4".
    if let Some((feet, rest)) = s.split_once('\'') {
        let feet = number(feet)?;
        let rest = rest.trim();
        let inches = match rest.strip_suffix('"') {
            Some(i) => number(i)?,
            None if rest.is_empty() => 0.0,
            None => return Err(format!("{rest:?} after the feet; inches end in '\"'")),
        };
        return finite_length(feet * FOOT_M + inches * INCH_M);
    }
    if let Some(inches) = s.strip_suffix('"') {
        return finite_length(number(inches)? * INCH_M);
    }
    let split = s.find(|c: char| c.is_ascii_alphabetic()).unwrap_or(s.len());
    let (num, unit) = s.split_at(split);
    let scale = match unit.trim() {
        "" | "m" | "meter" | "meters" | "metre" | "metres" => 1.0,
        "ft" | "feet" | "foot" => FOOT_M,
        other => return Err(format!("unknown unit {other:?} (m, ft or feet'inches\")")),
    };
    finite_length(number(num)? * scale)
}

/// A count of levels: a number ≥ 0 (fractions are valid, the wiki's `Key:building:levels`), at
/// most [`MAX_LEVELS`].
pub fn parse_levels(value: &str) -> Result<f64, String> {
    let n = number(value)?;
    if !(0.0..=MAX_LEVELS).contains(&n) {
        return Err(format!("levels must be in [0, {MAX_LEVELS}]"));
    }
    Ok(n)
}

/// A count of levels that may be negative (`building:min_level` of a part starting below
/// ground), within ±[`MAX_LEVELS`].
fn parse_signed_levels(value: &str) -> Result<f64, String> {
    let n = number(value)?;
    if n.abs() > MAX_LEVELS {
        return Err(format!("levels must be in [-{MAX_LEVELS}, {MAX_LEVELS}]"));
    }
    Ok(n)
}

fn number(s: &str) -> Result<f64, String> {
    let s = s.trim();
    let ok = !s.is_empty()
        && s.chars()
            .all(|c| c.is_ascii_digit() || matches!(c, '.' | '-' | '+'));
    match s.parse::<f64>() {
        Ok(v) if ok && v.is_finite() => Ok(v),
        _ => Err(format!("{s:?} is not a number")),
    }
}

fn finite_length(m: f64) -> Result<f64, String> {
    if m.is_finite() && m.abs() < MAX_HEIGHT_M {
        Ok(m)
    } else {
        Err(format!("not a length within ±{MAX_HEIGHT_M} m"))
    }
}

/// How levels become metres.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct HeightRules {
    /// Metres per storey (`building:levels`, `roof:levels`, `building:min_level`).
    pub level_height_m: f64,
}

impl Default for HeightRules {
    fn default() -> Self {
        Self {
            level_height_m: DEFAULT_LEVEL_HEIGHT_M,
        }
    }
}

/// Where a roof height came from; [`HeightSource::label`] is the `height_source` property
/// written for it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum HeightSource {
    /// The `height` tag.
    Height,
    /// `building:levels` (+ `roof:height` or `roof:levels`) in storeys.
    Levels,
    /// The highest of the outline's `building:part`s.
    Parts,
    /// A part without its own height: its outline's tagged height.
    Outline,
    /// The 75th percentile of tagged outlines within a radius (m).
    Nearby(f64),
    /// The configured default (m).
    Default(f64),
}

impl HeightSource {
    /// The `height_source` text, in the vocabulary of `data/nyc_midtown_buildings.geojson`.
    pub fn label(self, rules: &HeightRules) -> String {
        match self {
            HeightSource::Height => "osm:height".into(),
            HeightSource::Levels => {
                format!("estimated:building:levels*{}m", rules.level_height_m)
            }
            HeightSource::Parts => "max_of_osm_building_parts".into(),
            HeightSource::Outline => "osm:height_of_outline".into(),
            HeightSource::Nearby(r) => format!("fallback:p75_of_tagged_buildings_within_{r}m"),
            HeightSource::Default(h) => format!("fallback:default_{h}m"),
        }
    }

    /// Whether the height was read from the feature's own tags.
    pub fn is_tagged(self) -> bool {
        matches!(self, HeightSource::Height | HeightSource::Levels)
    }
}

impl HeightRules {
    /// The roof height from the feature's own tags: `height`, else `building:levels` storeys
    /// plus the roof (`roof:height`, else `roof:levels` storeys: the wiki's `building:levels`
    /// excludes the roof, `height` includes it). `None` when neither is tagged. A value that is
    /// not a height is an error naming the tag; a zero or negative `height` is one too.
    pub fn roof_m(&self, tags: Tags) -> Result<Option<(f64, HeightSource)>, TagError> {
        if let Some(h) = tags.length_m("height")? {
            if h <= 0.0 {
                return Err(TagError {
                    tag: "height".into(),
                    value: tags.get("height")?.unwrap_or_default(),
                    why: "a roof height must be above the ground".into(),
                });
            }
            return Ok(Some((h, HeightSource::Height)));
        }
        let Some(levels) = tags.levels("building:levels")? else {
            return Ok(None);
        };
        let roof_m = match tags.length_m("roof:height")? {
            Some(r) => r.max(0.0),
            None => tags.levels("roof:levels")?.unwrap_or(0.0) * self.level_height_m,
        };
        let h = levels * self.level_height_m + roof_m;
        if h <= 0.0 {
            // `building:levels=0` is a roof on pillars or a ruin: no height from it.
            return Ok(None);
        }
        if h >= MAX_HEIGHT_M {
            // The loader refuses a roof at or above MAX_HEIGHT_M: a mistagged count, not a tower.
            return Err(TagError {
                tag: "building:levels".into(),
                value: tags.get("building:levels")?.unwrap_or_default(),
                why: format!("with the roof, {h:.0} m: not a roof height below {MAX_HEIGHT_M} m"),
            });
        }
        Ok(Some((h, HeightSource::Levels)))
    }

    /// The bottom of the feature (m above ground): `min_height`, else `building:min_level`
    /// storeys (or the older `min_level`), else 0.
    pub fn bottom_m(&self, tags: Tags) -> Result<f64, TagError> {
        if let Some(h) = tags.length_m("min_height")? {
            return Ok(h);
        }
        // Levels skipped below a part may be negative (a part starting underground): the
        // loader cuts a negative bottom at the ground.
        let levels = match tags.parsed("building:min_level", parse_signed_levels)? {
            Some(l) => Some(l),
            None => tags.parsed("min_level", parse_signed_levels)?,
        };
        Ok(levels.unwrap_or(0.0) * self.level_height_m)
    }
}

/// The `p`-th quantile (0…1) of `values` by linear interpolation between closest ranks (NumPy's
/// default); `None` for no values. Sorts `values`.
pub fn quantile(values: &mut [f64], p: f64) -> Option<f64> {
    if values.is_empty() {
        return None;
    }
    values.sort_by(f64::total_cmp);
    let pos = p.clamp(0.0, 1.0) * (values.len() - 1) as f64;
    let (lo, hi) = (pos.floor() as usize, pos.ceil() as usize);
    Some(values[lo] + (values[hi] - values[lo]) * (pos - lo as f64))
}

#[cfg(test)]
mod tests {
    use super::*;
    use serde_json::json;

    fn tags(v: Value) -> Map<String, Value> {
        v.as_object().expect("object").clone()
    }

    #[test]
    fn lengths_in_metres_feet_and_inches() {
        for (text, m) in [
            ("12", 12.0),
            ("12.5", 12.5),
            (" 12 m", 12.0),
            ("12m", 12.0),
            ("12 metres", 12.0),
            ("-3", -3.0),
            ("40'", 40.0 * 0.3048),
            ("40 ft", 40.0 * 0.3048),
            ("7'4\"", 7.0 * 0.3048 + 4.0 * 0.0254),
            ("7' 4\"", 7.0 * 0.3048 + 4.0 * 0.0254),
            ("4\"", 4.0 * 0.0254),
        ] {
            let got = parse_length_m(text).unwrap_or_else(|e| panic!("{text}: {e}"));
            assert!((got - m).abs() < 1e-9, "{text}: {got} ≠ {m}");
        }
    }

    #[test]
    fn what_is_not_a_length_says_why() {
        for (text, why) in [
            ("12,5", "decimal comma"),
            ("12;15", "several values"),
            ("~12", "not a number"),
            ("tall", "unknown unit"),
            ("12 km", "unknown unit"),
            ("1e9", "unknown unit"),
            ("99999", "within"),
            ("", "not a number"),
            ("7'4", "inches end"),
        ] {
            let e = parse_length_m(text).expect_err(text);
            assert!(e.contains(why), "{text}: {e}");
        }
    }

    #[test]
    fn levels_are_non_negative_counts() {
        assert_eq!(parse_levels("4"), Ok(4.0));
        assert_eq!(parse_levels("2.5"), Ok(2.5));
        assert!(parse_levels("-1").is_err());
        assert!(parse_levels("1000").is_err());
        assert!(parse_levels("3-4").is_err());
    }

    /// Levels and roof adding up past the loader's limit are a tag error (ignored, or refused
    /// with `--strict`), never a building the loader would refuse after the files are written.
    #[test]
    fn levels_and_roof_past_the_limit_are_a_tag_error() {
        let r = HeightRules::default();
        let t = tags(json!({"building:levels": "300", "roof:height": "1999"}));
        let e = r.roof_m(Tags(&t)).expect_err("past the limit");
        assert_eq!(e.tag, "building:levels");
        let t = tags(json!({"building:levels": "300"}));
        assert!(
            r.roof_m(Tags(&t))
                .expect("ok")
                .is_some_and(|(h, _)| h < MAX_HEIGHT_M)
        );
    }

    #[test]
    fn height_wins_then_levels_with_the_roof() {
        let r = HeightRules::default();
        let t = tags(json!({"height": "40'", "building:levels": "10"}));
        let (h, s) = r.roof_m(Tags(&t)).expect("ok").expect("some");
        assert!((h - 12.192).abs() < 1e-9 && s == HeightSource::Height);
        let t = tags(json!({"building:levels": 4, "roof:levels": "1"}));
        assert_eq!(
            r.roof_m(Tags(&t)).expect("ok"),
            Some((15.0, HeightSource::Levels))
        );
        let t = tags(json!({"building:levels": "4", "roof:height": "2 m", "roof:levels": "1"}));
        assert_eq!(
            r.roof_m(Tags(&t)).expect("ok"),
            Some((14.0, HeightSource::Levels))
        );
        let r35 = HeightRules {
            level_height_m: 3.5,
        };
        let t = tags(json!({"building:levels": "10"}));
        assert_eq!(r35.roof_m(Tags(&t)).expect("ok").map(|x| x.0), Some(35.0));
        let t = tags(json!({"building": "yes", "building:levels": "0"}));
        assert_eq!(r.roof_m(Tags(&t)).expect("ok"), None);
        let t = tags(json!({"building": "yes"}));
        assert_eq!(r.roof_m(Tags(&t)).expect("ok"), None);
    }

    #[test]
    fn bad_values_name_the_tag() {
        let r = HeightRules::default();
        let t = tags(json!({"height": "tall"}));
        let e = r.roof_m(Tags(&t)).expect_err("bad");
        assert_eq!(e.tag, "height");
        assert!(e.to_string().contains("\"tall\""), "{e}");
        let t = tags(json!({"height": "0"}));
        assert_eq!(r.roof_m(Tags(&t)).expect_err("zero").tag, "height");
        let t = tags(json!({"building:levels": "many"}));
        assert_eq!(r.roof_m(Tags(&t)).expect_err("bad").tag, "building:levels");
        let t = tags(json!({"height": true}));
        assert!(r.roof_m(Tags(&t)).expect_err("bool").why.contains("string"));
        let t = tags(json!({"min_height": "x"}));
        assert_eq!(r.bottom_m(Tags(&t)).expect_err("bad").tag, "min_height");
    }

    #[test]
    fn bottom_from_min_height_or_min_level() {
        let r = HeightRules::default();
        let t = tags(json!({"min_height": "12.5", "building:min_level": "2"}));
        assert_eq!(r.bottom_m(Tags(&t)), Ok(12.5));
        let t = tags(json!({"building:min_level": "2"}));
        assert_eq!(r.bottom_m(Tags(&t)), Ok(6.0));
        let t = tags(json!({"min_level": "1"}));
        assert_eq!(r.bottom_m(Tags(&t)), Ok(3.0));
        let t = tags(json!({"building:min_level": "-1"}));
        assert_eq!(
            r.bottom_m(Tags(&t)),
            Ok(-3.0),
            "cut at the ground by the loader"
        );
        let t = tags(json!({}));
        assert_eq!(r.bottom_m(Tags(&t)), Ok(0.0));
    }

    #[test]
    fn quantile_interpolates_like_numpy() {
        assert_eq!(quantile(&mut [], 0.75), None);
        assert_eq!(quantile(&mut [5.0], 0.75), Some(5.0));
        // numpy.percentile([10, 20, 30, 40], 75) = 32.5
        assert_eq!(quantile(&mut [40.0, 10.0, 30.0, 20.0], 0.75), Some(32.5));
    }

    #[test]
    fn source_labels_match_the_midtown_vocabulary() {
        let r = HeightRules {
            level_height_m: 3.5,
        };
        assert_eq!(HeightSource::Height.label(&r), "osm:height");
        assert_eq!(
            HeightSource::Levels.label(&r),
            "estimated:building:levels*3.5m"
        );
        assert_eq!(
            HeightSource::Nearby(150.0).label(&r),
            "fallback:p75_of_tagged_buildings_within_150m"
        );
        assert_eq!(HeightSource::Parts.label(&r), "max_of_osm_building_parts");
    }
}
