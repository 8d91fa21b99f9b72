//! A minimal OSM PBF writer for the tests: one `OSMHeader` blob and one `OSMData` blob, both
//! uncompressed (`raw`), plain (not dense) nodes, protobuf encoded by hand after
//! `fileformat.proto` and `osmformat.proto` (<https://wiki.openstreetmap.org/wiki/PBF_Format>).

use super::{Data, MemberKind};

fn varint(buf: &mut Vec<u8>, mut v: u64) {
    while v >= 0x80 {
        buf.push((v as u8) | 0x80);
        v >>= 7;
    }
    buf.push(v as u8);
}

fn key(buf: &mut Vec<u8>, field: u64, wire: u64) {
    varint(buf, (field << 3) | wire);
}

fn int(buf: &mut Vec<u8>, field: u64, v: u64) {
    key(buf, field, 0);
    varint(buf, v);
}

fn bytes(buf: &mut Vec<u8>, field: u64, data: &[u8]) {
    key(buf, field, 2);
    varint(buf, data.len() as u64);
    buf.extend_from_slice(data);
}

fn packed(buf: &mut Vec<u8>, field: u64, values: impl IntoIterator<Item = u64>) {
    let mut inner = Vec::new();
    values.into_iter().for_each(|v| varint(&mut inner, v));
    bytes(buf, field, &inner);
}

fn zigzag(v: i64) -> u64 {
    ((v << 1) ^ (v >> 63)) as u64
}

/// Delta coding, then zigzag (`sint64` ids and refs).
fn deltas(values: &[i64]) -> Vec<u64> {
    let mut last = 0;
    values
        .iter()
        .map(|&v| {
            let d = v - last;
            last = v;
            zigzag(d)
        })
        .collect()
}

/// One file block: the BlobHeader's length, the BlobHeader, the Blob.
fn block(buf: &mut Vec<u8>, kind: &str, payload: &[u8]) {
    let mut blob = Vec::new();
    bytes(&mut blob, 1, payload); // raw
    int(&mut blob, 2, payload.len() as u64); // raw_size
    let mut header = Vec::new();
    bytes(&mut header, 1, kind.as_bytes()); // type
    int(&mut header, 3, blob.len() as u64); // datasize
    buf.extend_from_slice(&(header.len() as u32).to_be_bytes());
    buf.extend_from_slice(&header);
    buf.extend_from_slice(&blob);
}

/// The index of `s` in the string table, added when new.
fn sid(strings: &mut Vec<String>, s: &str) -> u64 {
    let k = strings.iter().position(|x| x == s).unwrap_or_else(|| {
        strings.push(s.to_string());
        strings.len() - 1
    });
    k as u64
}

/// An element's `keys` (2) and `vals` (3).
fn tags(buf: &mut Vec<u8>, strings: &mut Vec<String>, tags: &[(&str, &str)]) {
    let (keys, vals): (Vec<u64>, Vec<u64>) = tags
        .iter()
        .map(|(k, v)| (sid(strings, k), sid(strings, v)))
        .unzip();
    if !keys.is_empty() {
        packed(buf, 2, keys);
        packed(buf, 3, vals);
    }
}

/// `data` as an OSM PBF file (granularity 100: positions in 10⁻⁷ degrees as given).
pub fn write(data: &Data) -> Vec<u8> {
    let mut strings: Vec<String> = vec![String::new()];
    let mut nodes = Vec::new();
    for &(id, lon, lat) in &data.nodes {
        let mut n = Vec::new();
        int(&mut n, 1, zigzag(id));
        int(&mut n, 8, zigzag(lat));
        int(&mut n, 9, zigzag(lon));
        bytes(&mut nodes, 1, &n);
    }
    let mut ways = Vec::new();
    for (id, refs, t) in &data.ways {
        let mut w = Vec::new();
        int(&mut w, 1, *id as u64);
        tags(&mut w, &mut strings, t);
        packed(&mut w, 8, deltas(refs));
        bytes(&mut ways, 3, &w);
    }
    let mut relations = Vec::new();
    for (id, members, t) in &data.relations {
        let mut r = Vec::new();
        int(&mut r, 1, *id as u64);
        tags(&mut r, &mut strings, t);
        let roles: Vec<u64> = members.iter().map(|m| sid(&mut strings, m.2)).collect();
        packed(&mut r, 8, roles);
        let ids: Vec<i64> = members.iter().map(|m| m.1).collect();
        packed(&mut r, 9, deltas(&ids));
        let types = members.iter().map(|m| match m.0 {
            MemberKind::Node => 0,
            MemberKind::Way => 1,
            MemberKind::Relation => 2,
        });
        packed(&mut r, 10, types);
        bytes(&mut relations, 4, &r);
    }
    let mut table = Vec::new();
    for s in &strings {
        bytes(&mut table, 1, s.as_bytes());
    }
    let mut primitive = Vec::new();
    bytes(&mut primitive, 1, &table);
    for group in [nodes, ways, relations] {
        if !group.is_empty() {
            bytes(&mut primitive, 2, &group);
        }
    }
    let mut header = Vec::new();
    bytes(&mut header, 4, b"OsmSchema-V0.6");
    let mut file = Vec::new();
    block(&mut file, "OSMHeader", &header);
    block(&mut file, "OSMData", &primitive);
    file
}
