//! Which format a buildings file is in, told by its content whatever its name: PBF by its first
//! BlobHeader, XML by a leading `<?xml` or `<osm`, JSON by a leading `{` and then its top-level
//! keys (`elements`: Overpass JSON; anything else: GeoJSON).

use serde::Deserialize;
use serde::de::IgnoredAny;

/// A buildings file's format.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Format {
    /// `.osm.pbf`: OSM's protobuf blobs (<https://wiki.openstreetmap.org/wiki/PBF_Format>).
    Pbf,
    /// `.osm`: OSM XML (<https://wiki.openstreetmap.org/wiki/OSM_XML>).
    Xml,
    /// Overpass API JSON: `{"elements": [...]}`.
    OverpassJson,
    /// A GeoJSON `FeatureCollection` (also what is neither of the others but starts with `{`,
    /// so that the GeoJSON reader reports what is wrong with it).
    GeoJson,
}

impl Format {
    /// Its name in messages.
    pub fn name(self) -> &'static str {
        match self {
            Format::Pbf => "OSM PBF",
            Format::Xml => "OSM XML",
            Format::OverpassJson => "Overpass JSON",
            Format::GeoJson => "GeoJSON",
        }
    }
}

/// Bytes of the file [`sniff`] needs: a BlobHeader's length and its type string.
pub const SNIFF_BYTES: usize = 32;

/// The format `head` (the file's first [`SNIFF_BYTES`] bytes, or all of a shorter file)
/// begins as, or `None` when it is none of them. JSON is told apart by [`json_kind`].
pub fn sniff(head: &[u8]) -> Option<Format> {
    if is_pbf(head) {
        return Some(Format::Pbf);
    }
    let text = head.strip_prefix(b"\xEF\xBB\xBF").unwrap_or(head);
    let start = text.iter().position(|b| !b.is_ascii_whitespace());
    let text = &text[start.unwrap_or(text.len())..];
    if text.starts_with(b"<?xml") || text.starts_with(b"<osm") {
        Some(Format::Xml)
    } else if text.starts_with(b"{") || text.is_empty() {
        // Empty: the GeoJSON reader says so, as it always has.
        Some(Format::GeoJson)
    } else {
        None
    }
}

/// A PBF file starts with a 4-byte big-endian BlobHeader length and the BlobHeader, whose
/// field 1 (`type`, tag byte 0x0A) is the string `OSMHeader`.
fn is_pbf(head: &[u8]) -> bool {
    const TYPE: &[u8] = b"OSMHeader";
    let Some(len) = head.get(..4) else {
        return false;
    };
    let len = u32::from_be_bytes([len[0], len[1], len[2], len[3]]);
    (11..64 * 1024).contains(&len)
        && head.get(4) == Some(&0x0A)
        && head.get(5) == Some(&(TYPE.len() as u8))
        && head.get(6..6 + TYPE.len()) == Some(TYPE)
}

/// The top-level keys that tell GeoJSON from Overpass JSON (values skipped, not kept).
#[derive(Deserialize)]
struct Keys {
    elements: Option<IgnoredAny>,
    features: Option<IgnoredAny>,
}

/// Overpass JSON when `text` is a JSON object with `elements` and no `features`; GeoJSON
/// otherwise. Text that is no valid JSON goes to the reader it most resembles (`"elements"` and
/// no `"features"` in it: Overpass), which reports where it breaks.
pub fn json_kind(text: &str) -> Format {
    match serde_json::from_str::<Keys>(text) {
        Ok(Keys {
            elements: Some(_),
            features: None,
        }) => Format::OverpassJson,
        Ok(_) => Format::GeoJson,
        Err(_) if text.contains("\"elements\"") && !text.contains("\"features\"") => {
            Format::OverpassJson
        }
        Err(_) => Format::GeoJson,
    }
}
