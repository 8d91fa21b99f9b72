//! Decoding under an allocation budget ("memory bounded by design").
//!
//! A cap on a message's bytes is not a cap on what decoding it allocates: an empty
//! [`crate::compact::CompactTrajectory`] is 29 bytes on the wire and ≈ 730 in memory, a `u32`
//! site 1 byte and 4. [`crate::codec::decode_budgeted`] therefore runs the decoder with a budget
//! in bytes (derived from the run's configuration, e.g. [`crate::validate::ChunkExpect::budget_bytes`])
//! and every collection of a network message is decoded through [`vec`] or [`map`], which
//! charge `len × size_of::<element>()` against it *before* allocating and fail the decode once it
//! is spent. Outside a budgeted decode (encoding, files) the helpers behave like serde's own.
//!
//! Why by hand: neither bincode 2's serde path (its `with_limit` is a compile-time constant and
//! not consulted for serde sequences) nor serde offers a per-call allocation limit; the budget is
//! a thread-local because serde's derive gives `deserialize_with` no context argument, and a
//! decode runs on one thread from start to end.

use serde::de::{Deserialize, Deserializer, Error, MapAccess, SeqAccess, Visitor};
use std::cell::Cell;
use std::collections::BTreeMap;
use std::fmt;
use std::marker::PhantomData;

thread_local! {
    /// Bytes left to the decode running on this thread (`None`: no budget).
    static LEFT: Cell<Option<usize>> = const { Cell::new(None) };
    /// The running decode asked for more than its budget.
    static EXCEEDED: Cell<bool> = const { Cell::new(false) };
}

/// Runs `f` (a decode) with `bytes` of allocation budget; restores the previous state after.
/// Returns `f`'s result and whether the budget was exceeded.
pub fn with_budget<R>(bytes: usize, f: impl FnOnce() -> R) -> (R, bool) {
    let before = LEFT.with(|l| l.replace(Some(bytes)));
    let exceeded_before = EXCEEDED.with(|e| e.replace(false));
    let out = f();
    LEFT.with(|l| l.set(before));
    let exceeded = EXCEEDED.with(|e| e.replace(exceeded_before));
    (out, exceeded)
}

/// Charges `bytes` to the running decode's budget; `what` names the collection in the error.
pub(crate) fn charge<E: Error>(bytes: usize, what: &str) -> Result<(), E> {
    LEFT.with(|l| match l.get() {
        None => Ok(()),
        Some(left) if bytes <= left => {
            l.set(Some(left - bytes));
            Ok(())
        }
        Some(left) => {
            EXCEEDED.with(|e| e.set(true));
            Err(E::custom(format_args!(
            "{what} needs {bytes} more bytes than the {left} left of this message's decoding budget"
            )))
        }
    })
}

struct VecVisitor<T>(PhantomData<T>);

impl<'de, T: Deserialize<'de>> Visitor<'de> for VecVisitor<T> {
    type Value = Vec<T>;

    fn expecting(&self, f: &mut fmt::Formatter) -> fmt::Result {
        f.write_str("a sequence")
    }

    fn visit_seq<A: SeqAccess<'de>>(self, mut seq: A) -> Result<Vec<T>, A::Error> {
        let elem = size_of::<T>().max(1);
        let hint = seq.size_hint().unwrap_or(0);
        charge::<A::Error>(hint.saturating_mul(elem), std::any::type_name::<Vec<T>>())?;
        let mut v = Vec::with_capacity(hint);
        while let Some(x) = seq.next_element()? {
            if v.len() >= hint {
                // Beyond the announced length (formats without one): charge as it grows.
                charge::<A::Error>(elem.saturating_mul(v.len().max(4)), "a growing sequence")?;
                v.reserve(v.len().max(4));
            }
            v.push(x);
        }
        Ok(v)
    }
}

/// `#[serde(deserialize_with = "crate::budget::vec")]`: a `Vec<T>` whose allocation is charged
/// to the running decode's budget before it happens.
pub fn vec<'de, D: Deserializer<'de>, T: Deserialize<'de>>(d: D) -> Result<Vec<T>, D::Error> {
    d.deserialize_seq(VecVisitor(PhantomData))
}

struct MapVisitor<K, V>(PhantomData<(K, V)>);

impl<'de, K: Deserialize<'de> + Ord, V: Deserialize<'de>> Visitor<'de> for MapVisitor<K, V> {
    type Value = BTreeMap<K, V>;

    fn expecting(&self, f: &mut fmt::Formatter) -> fmt::Result {
        f.write_str("a map")
    }

    fn visit_map<A: MapAccess<'de>>(self, mut map: A) -> Result<BTreeMap<K, V>, A::Error> {
        // A B-tree node holds up to 11 entries; charge each entry its share plus a node pointer.
        let entry = size_of::<(K, V)>() + 2 * size_of::<usize>();
        let mut m = BTreeMap::new();
        while let Some((k, v)) = map.next_entry()? {
            charge::<A::Error>(entry, std::any::type_name::<BTreeMap<K, V>>())?;
            m.insert(k, v);
        }
        Ok(m)
    }
}

/// `#[serde(deserialize_with = "crate::budget::map")]`: a `BTreeMap` charged per entry.
pub fn map<'de, D, K, V>(d: D) -> Result<BTreeMap<K, V>, D::Error>
where
    D: Deserializer<'de>,
    K: Deserialize<'de> + Ord,
    V: Deserialize<'de>,
{
    d.deserialize_map(MapVisitor(PhantomData))
}

/// `#[serde(deserialize_with = "crate::budget::string")]`: a `String` charged by its length.
pub fn string<'de, D: Deserializer<'de>>(d: D) -> Result<String, D::Error> {
    let s = String::deserialize(d)?;
    charge::<D::Error>(s.len(), "a string")?;
    Ok(s)
}

#[cfg(test)]
mod tests {
    use super::*;
    use serde::{Deserialize, Serialize};

    #[derive(Debug, PartialEq, Serialize, Deserialize)]
    struct Rows {
        #[serde(deserialize_with = "vec")]
        rows: Vec<Row>,
    }

    #[derive(Debug, PartialEq, Serialize, Deserialize)]
    struct Row {
        #[serde(deserialize_with = "vec")]
        values: Vec<u64>,
    }

    fn encode(r: &Rows) -> Vec<u8> {
        bincode::serde::encode_to_vec(r, bincode::config::standard()).expect("encode")
    }

    fn decode(b: &[u8]) -> Result<Rows, bincode::error::DecodeError> {
        bincode::serde::decode_from_slice(b, bincode::config::standard()).map(|(r, _)| r)
    }

    #[test]
    fn a_decode_within_its_budget_is_unchanged() {
        let r = Rows {
            rows: vec![
                Row {
                    values: vec![1, 2, 3],
                },
                Row { values: vec![] },
            ],
        };
        let b = encode(&r);
        let need = 2 * size_of::<Row>() + 3 * 8;
        assert_eq!(with_budget(need, || decode(&b)).0.expect("fits"), r);
        assert_eq!(decode(&b).expect("no budget"), r);
    }

    #[test]
    fn an_amplifying_message_is_refused_before_it_allocates() {
        // 100 000 empty rows: 100 001 bytes on the wire, 2.4 MB decoded.
        let r = Rows {
            rows: (0..100_000).map(|_| Row { values: vec![] }).collect(),
        };
        let b = encode(&r);
        assert!(b.len() < 110_000);
        let (e, exceeded) = with_budget(1 << 20, || decode(&b));
        let e = e.expect_err("over budget");
        assert!(exceeded);
        assert!(e.to_string().contains("decoding budget"), "{e}");
        // The budget is per decode: the thread's state is restored after.
        assert!(decode(&b).is_ok());
        // One byte short of the exact need is refused too.
        let small = Rows {
            rows: vec![Row { values: vec![7] }],
        };
        let b = encode(&small);
        let need = size_of::<Row>() + 8;
        assert!(with_budget(need, || decode(&b)).0.is_ok());
        assert!(with_budget(need - 1, || decode(&b)).0.is_err());
    }
}
