//! The JSON codec of the messages any zenoh client reads: the learner's and the actors' stats
//! ([`LearnerStats`], [`ActorStats`]) and the run's control messages ([`ControlMsg`]).
//! Publishers set zenoh's encoding to `application/json`; trajectories and weights stay binary
//! ([`crate::msg::encode_msg`]).
//!
//! A message is one JSON object: `schema` ([`JSON_SCHEMA_VERSION`]) first, `kind` second (what
//! the message is: `learner_stats`, `actor_stats` or `control`), then the message's own fields
//! under their Rust names (units in the names; the header's numbers as JSON integers):
//!
//! ```json
//! {"schema":1,"kind":"actor_stats","header":{"schema_version":10,"run_id":"r",
//!  "learner_incarnation":7,"actor":3,"sender_incarnation":11,"seq":42,"policy_version":5,
//!  "config_fingerprint":9,"sent_unix_ms":1790000000000},"num_envs":4,"env_steps":1024,
//!  "steps_per_s":250.0,"chunks_sent":4,"swaps":2,"last_swap_latency_ms":null,"episodes":6}
//! ```
//!
//! Decoding treats the bytes as hostile, as the binary codec does: a message over its
//! [`MsgLimits::bytes`] is refused before it is parsed, its collections are charged to
//! [`MsgLimits::budget_bytes`] before they are allocated ([`crate::budget`]; serde_json also
//! refuses nesting deeper than 128 where it builds values), and it must be exactly one object of this schema and of an
//! expected kind, with no unknown field and nothing after it. JSON has no NaN or infinity, so a
//! decoded number is always finite; a value that may be missing is `null` (`Option`).

use crate::codec::CodecError;
use crate::msg::{ActorStats, ControlMsg, LearnerStats, MsgLimits, StatsMsg};
use serde::Serialize;
use serde::de::value::MapAccessDeserializer;
use serde::de::{DeserializeOwned, Error as _, IgnoredAny, MapAccess, Visitor};
use std::fmt;

/// Version of the JSON layout (the `schema` field): the field names, types, units and meanings
/// of the messages below and of everything they contain. Bumped on any change; a reader checks
/// it and reads one version only.
pub const JSON_SCHEMA_VERSION: u32 = 1;

/// The magic of the binary stats and control messages of other DUPAC builds (`DUPACSTA`,
/// `DUPACCTL`): recognised to refuse them by name.
const BINARY_MAGIC_PREFIX: &[u8] = b"DUPAC";

/// A message of the JSON codec.
pub trait JsonMessage: Sized {
    /// What the message is called in errors.
    const NAME: &'static str;

    /// Encodes the message: schema, kind, fields.
    fn to_json(&self) -> Result<Vec<u8>, serde_json::Error>;

    /// Reads the fields that follow `schema` and `kind`, refusing a `kind` this type is not.
    fn read_fields<'de, A: MapAccess<'de>>(kind: &str, fields: A) -> Result<Self, A::Error>;
}

/// One message's `kind` and type.
trait Kind: Serialize + DeserializeOwned {
    const KIND: &'static str;
}

impl Kind for LearnerStats {
    const KIND: &'static str = "learner_stats";
}
impl Kind for ActorStats {
    const KIND: &'static str = "actor_stats";
}
impl Kind for ControlMsg {
    const KIND: &'static str = "control";
}

/// The encoded form: `schema`, `kind`, then the body's fields in their declared order.
#[derive(Serialize)]
struct Envelope<'a, B> {
    schema: u32,
    kind: &'static str,
    #[serde(flatten)]
    body: &'a B,
}

fn envelope<B: Kind>(body: &B) -> Result<Vec<u8>, serde_json::Error> {
    serde_json::to_vec(&Envelope {
        schema: JSON_SCHEMA_VERSION,
        kind: B::KIND,
        body,
    })
}

fn fields<'de, B: Kind, A: MapAccess<'de>>(kind: &str, fields: A) -> Result<B, A::Error> {
    if kind != B::KIND {
        return Err(A::Error::custom(format_args!(
            "kind {kind:?}, expected {:?}",
            B::KIND
        )));
    }
    B::deserialize(MapAccessDeserializer::new(fields))
}

impl JsonMessage for LearnerStats {
    const NAME: &'static str = "learner stats";
    fn to_json(&self) -> Result<Vec<u8>, serde_json::Error> {
        envelope(self)
    }
    fn read_fields<'de, A: MapAccess<'de>>(kind: &str, f: A) -> Result<Self, A::Error> {
        fields(kind, f)
    }
}

impl JsonMessage for ActorStats {
    const NAME: &'static str = "actor stats";
    fn to_json(&self) -> Result<Vec<u8>, serde_json::Error> {
        envelope(self)
    }
    fn read_fields<'de, A: MapAccess<'de>>(kind: &str, f: A) -> Result<Self, A::Error> {
        fields(kind, f)
    }
}

impl JsonMessage for ControlMsg {
    const NAME: &'static str = "control";
    fn to_json(&self) -> Result<Vec<u8>, serde_json::Error> {
        envelope(self)
    }
    fn read_fields<'de, A: MapAccess<'de>>(kind: &str, f: A) -> Result<Self, A::Error> {
        fields(kind, f)
    }
}

/// Either stats message, told apart by its `kind`.
impl JsonMessage for StatsMsg {
    const NAME: &'static str = "stats";
    fn to_json(&self) -> Result<Vec<u8>, serde_json::Error> {
        match self {
            StatsMsg::Learner(s) => envelope(s),
            StatsMsg::Actor(s) => envelope(s),
        }
    }
    fn read_fields<'de, A: MapAccess<'de>>(kind: &str, f: A) -> Result<Self, A::Error> {
        match kind {
            LearnerStats::KIND => fields(kind, f).map(StatsMsg::Learner),
            ActorStats::KIND => fields(kind, f).map(StatsMsg::Actor),
            _ => Err(A::Error::custom(format_args!(
                "kind {kind:?}, expected {:?} or {:?}",
                LearnerStats::KIND,
                ActorStats::KIND
            ))),
        }
    }
}

/// Encodes `msg` as JSON (publish it with zenoh's encoding `application/json`).
pub fn encode_json<M: JsonMessage>(msg: &M) -> Result<Vec<u8>, CodecError> {
    msg.to_json().map_err(|e| CodecError::Encode {
        what: M::NAME.to_string(),
        message: e.to_string(),
    })
}

/// What the envelope's visitor found: the message, or another schema (the rest skipped).
enum Read<M> {
    Message(M),
    Schema(u64),
}

struct EnvelopeVisitor<M>(std::marker::PhantomData<M>);

impl<'de, M: JsonMessage> Visitor<'de> for EnvelopeVisitor<M> {
    type Value = Read<M>;

    fn expecting(&self, f: &mut fmt::Formatter) -> fmt::Result {
        write!(f, "a JSON object starting with \"schema\" and \"kind\"")
    }

    fn visit_map<A: MapAccess<'de>>(self, mut map: A) -> Result<Read<M>, A::Error> {
        expect_key(&mut map, "schema")?;
        let schema: u64 = map.next_value()?;
        if schema != u64::from(JSON_SCHEMA_VERSION) {
            // Read to the end without keeping anything, so the error names the schema.
            while map.next_entry::<IgnoredAny, IgnoredAny>()?.is_some() {}
            return Ok(Read::Schema(schema));
        }
        expect_key(&mut map, "kind")?;
        let kind: String = map.next_value()?;
        M::read_fields(&kind, map).map(Read::Message)
    }
}

/// Reads the next key of `map`, which must be `want`.
fn expect_key<'de, A: MapAccess<'de>>(map: &mut A, want: &'static str) -> Result<(), A::Error> {
    match map.next_key::<String>()? {
        Some(k) if k == want => Ok(()),
        Some(k) => Err(A::Error::custom(format_args!(
            "field {k:?} where {want:?} was expected"
        ))),
        None => Err(A::Error::missing_field(want)),
    }
}

/// Decodes a JSON message within `limits`; `origin` (the key expression) names it in errors.
/// Refused: more bytes than `limits.bytes` (unparsed), collections over `limits.budget_bytes`,
/// a binary DUPAC message, another [`JSON_SCHEMA_VERSION`], another kind, an unknown or missing
/// field, anything that is not one JSON object.
pub fn decode_json<M: JsonMessage>(
    bytes: &[u8],
    limits: MsgLimits,
    origin: &str,
) -> Result<M, CodecError> {
    let what = format!("{} on {origin}", M::NAME);
    if bytes.len() > limits.bytes {
        return Err(CodecError::TooLarge {
            what,
            len: bytes.len(),
            limit: limits.bytes,
        });
    }
    if bytes.starts_with(BINARY_MAGIC_PREFIX) {
        let magic = &bytes[..bytes.len().min(8)];
        return Err(CodecError::Binary {
            what,
            magic: String::from_utf8_lossy(magic).into_owned(),
        });
    }
    let (out, exceeded) = crate::budget::with_budget(limits.budget_bytes, || {
        let mut de = serde_json::Deserializer::from_slice(bytes);
        let read = serde::Deserializer::deserialize_map(
            &mut de,
            EnvelopeVisitor::<M>(std::marker::PhantomData),
        )?;
        de.end()?;
        Ok::<_, serde_json::Error>(read)
    });
    match out {
        Ok(Read::Message(m)) => Ok(m),
        Ok(Read::Schema(got)) => Err(CodecError::Version {
            what,
            got: u32::try_from(got).unwrap_or(u32::MAX),
            want: JSON_SCHEMA_VERSION,
        }),
        Err(e) if exceeded => Err(CodecError::OverBudget {
            what,
            budget: limits.budget_bytes,
            message: e.to_string(),
        }),
        Err(e) => Err(CodecError::Decode {
            what,
            message: e.to_string(),
        }),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::ids::ActorId;
    use crate::msg::{ActorRow, ActorState, Command, Header, STATS_BUDGET_BYTES};
    use crate::validate::DropReason;
    use std::collections::BTreeMap;

    fn header(actor: ActorId) -> Header {
        let mut h = Header::new("run-1", 0x0123_4567_89ab_cdef, actor, u64::MAX);
        h.sender_incarnation = 11;
        h.seq = 42;
        h.policy_version = 5;
        h
    }

    fn learner() -> LearnerStats {
        LearnerStats {
            header: header(ActorId::LEARNER),
            update: 5,
            total_updates: 20,
            global_step: 1280,
            updates_per_s: 0.5,
            env_steps_per_s: 128.0,
            accepted_chunks: 9,
            drops: BTreeMap::from([("replay".to_string(), 2), ("garbage".to_string(), 1)]),
            actors: vec![
                ActorRow {
                    actor: ActorId(0),
                    state: ActorState::Alive,
                    steps_per_s: 64.0,
                    env_steps: 640,
                    chunks: 5,
                    policy_lag: 1,
                    last_seen_s: Some(0.25),
                },
                ActorRow {
                    actor: ActorId(1),
                    state: ActorState::Silent,
                    steps_per_s: 0.0,
                    env_steps: 0,
                    chunks: 0,
                    policy_lag: 5,
                    last_seen_s: None,
                },
            ],
            metrics: BTreeMap::from([("charts/episodic_return".to_string(), -3.5)]),
            done: false,
        }
    }

    fn actor() -> ActorStats {
        ActorStats {
            header: header(ActorId(3)),
            num_envs: 4,
            env_steps: 1024,
            steps_per_s: 250.0,
            chunks_sent: 4,
            swaps: 2,
            last_swap_latency_ms: None,
            episodes: 6,
        }
    }

    fn lim() -> MsgLimits {
        MsgLimits::both(STATS_BUDGET_BYTES)
    }

    fn json(bytes: &[u8]) -> serde_json::Value {
        serde_json::from_slice(bytes).expect("valid JSON")
    }

    #[test]
    fn every_json_message_round_trips() {
        let l = learner();
        let b = encode_json(&StatsMsg::Learner(l.clone())).expect("encode");
        assert_eq!(
            decode_json::<StatsMsg>(&b, lim(), "k").expect("decode"),
            StatsMsg::Learner(l.clone())
        );
        assert_eq!(
            decode_json::<LearnerStats>(&b, lim(), "k").expect("decode"),
            l
        );
        let a = actor();
        let b = encode_json(&a).expect("encode");
        assert_eq!(
            decode_json::<StatsMsg>(&b, lim(), "k").expect("decode"),
            StatsMsg::Actor(a.clone())
        );
        let a2 = ActorStats {
            last_swap_latency_ms: Some(12.5),
            ..a
        };
        let b = encode_json(&a2).expect("encode");
        assert_eq!(
            decode_json::<ActorStats>(&b, lim(), "k").expect("decode"),
            a2
        );
        let c = ControlMsg {
            header: header(ActorId::LEARNER),
            command: Command::Stop,
        };
        let b = encode_json(&c).expect("encode");
        assert_eq!(
            decode_json::<ControlMsg>(&b, lim(), "k").expect("decode"),
            c
        );
    }

    /// What another client reads: plain JSON with the schema first, the kind, and the fields
    /// under their names (a u64 incarnation exactly, `null` for a missing value).
    #[test]
    fn the_json_is_what_the_documentation_shows() {
        let b = encode_json(&StatsMsg::Learner(learner())).expect("encode");
        let text = std::str::from_utf8(&b).expect("UTF-8");
        assert!(
            text.starts_with(r#"{"schema":1,"kind":"learner_stats","header":{"#),
            "{text}"
        );
        let v = json(&b);
        assert_eq!(v["header"]["policy_version"], 5);
        assert_eq!(
            v["header"]["learner_incarnation"],
            0x0123_4567_89ab_cdef_u64
        );
        assert_eq!(v["header"]["config_fingerprint"], u64::MAX);
        assert_eq!(v["updates_per_s"], 0.5);
        assert_eq!(v["drops"]["replay"], 2);
        assert_eq!(v["actors"][0]["state"], "alive");
        assert_eq!(v["actors"][1]["last_seen_s"], serde_json::Value::Null);
        assert_eq!(v["metrics"]["charts/episodic_return"], -3.5);
        let c = encode_json(&ControlMsg {
            header: header(ActorId::LEARNER),
            command: Command::Stop,
        })
        .expect("encode");
        assert_eq!(json(&c)["command"], "stop");
        assert_eq!(json(&c)["kind"], "control");
    }

    fn refused<M: JsonMessage + fmt::Debug>(bytes: &[u8], limits: MsgLimits) -> CodecError {
        decode_json::<M>(bytes, limits, "dupac/r/stats/learner").expect_err("refused")
    }

    #[test]
    fn a_message_over_its_size_cap_is_refused_unparsed() {
        let b = encode_json(&learner()).expect("encode");
        let e = refused::<StatsMsg>(&b, MsgLimits::both(b.len() - 1));
        assert!(matches!(e, CodecError::TooLarge { .. }), "{e}");
        assert_eq!(DropReason::of_codec(&e), DropReason::TooLarge);
        assert!(decode_json::<StatsMsg>(&b, MsgLimits::both(b.len()), "k").is_ok());
        // Over the cap and not even JSON: refused by its size, before anything parses it.
        let junk = vec![b'['; 1 << 20];
        let e = refused::<StatsMsg>(&junk, MsgLimits::both(1 << 16));
        assert!(matches!(e, CodecError::TooLarge { .. }), "{e}");
    }

    #[test]
    fn an_amplifying_message_is_refused_while_decoding() {
        // 20 000 actor rows in 1.5 MB of JSON: within the byte cap, over a 256 KiB budget.
        let mut l = learner();
        l.actors = vec![l.actors[1].clone(); 20_000];
        let b = encode_json(&l).expect("encode");
        let limits = MsgLimits {
            bytes: 4 << 20,
            budget_bytes: 256 << 10,
        };
        assert!(b.len() < limits.bytes);
        let e = refused::<StatsMsg>(&b, limits);
        assert!(matches!(e, CodecError::OverBudget { .. }), "{e}");
        assert_eq!(DropReason::of_codec(&e), DropReason::TooLarge);
        // 100 000 levels of nesting in what a message of another schema carries: skipped
        // without recursion (serde_json ignores a value iteratively), no stack overflow.
        let deep = format!(
            r#"{{"schema":2,"x":{}{}}}"#,
            "[".repeat(100_000),
            "]".repeat(100_000)
        );
        let e = refused::<StatsMsg>(deep.as_bytes(), lim());
        assert!(matches!(e, CodecError::Version { got: 2, .. }), "{e}");
    }

    #[test]
    fn malformed_messages_are_refused_with_their_reason() {
        let good = String::from_utf8(encode_json(&actor()).expect("encode")).expect("UTF-8");
        let garbage = |text: &str, says: &str| {
            let e = refused::<StatsMsg>(text.as_bytes(), lim());
            assert!(matches!(e, CodecError::Decode { .. }), "{text}: {e}");
            assert_eq!(DropReason::of_codec(&e), DropReason::Garbage);
            assert!(
                e.to_string().contains(says),
                "{text}: {e} should say {says}"
            );
        };
        garbage("", "EOF");
        garbage("[1, 2]", "JSON object");
        garbage("{\"kind\":\"actor_stats\"}", "\"schema\" was expected");
        garbage(r#"{"schema":1}"#, "missing field `kind`");
        garbage(&good.replace("actor_stats", "weights"), "kind \"weights\"");
        garbage(
            &good.replace("\"episodes\":6", "\"episodes\":-6"),
            "invalid value",
        );
        garbage(
            &good.replace("\"episodes\":6", "\"episodes\":6,\"x\":1"),
            "unknown field",
        );
        garbage(
            &good.replace(",\"episodes\":6", ""),
            "missing field `episodes`",
        );
        garbage(&good.replace("250.0", "NaN"), "expected value");
        garbage(&good.replace("250.0", "1e999"), "out of range");
        garbage(&good.replace("\"run-1\"", "7"), "invalid type");
        garbage(&format!("{good} {{}}"), "trailing characters");
        garbage(&good[..good.len() - 1], "EOF");
        // A control message is not stats, nor stats a control message.
        let stop = encode_json(&ControlMsg {
            header: header(ActorId::LEARNER),
            command: Command::Stop,
        })
        .expect("encode");
        let e = refused::<StatsMsg>(&stop, lim());
        assert!(e.to_string().contains("kind \"control\""), "{e}");
        let e = decode_json::<ControlMsg>(good.as_bytes(), lim(), "k").expect_err("not control");
        assert!(e.to_string().contains("kind \"actor_stats\""), "{e}");
        let bad_command = String::from_utf8(stop)
            .expect("UTF-8")
            .replace("stop", "halt");
        let e = decode_json::<ControlMsg>(bad_command.as_bytes(), lim(), "k").expect_err("halt");
        assert!(e.to_string().contains("unknown variant"), "{e}");
    }

    #[test]
    fn another_schema_or_a_binary_message_is_refused_by_name() {
        let good = String::from_utf8(encode_json(&actor()).expect("encode")).expect("UTF-8");
        let newer = good.replacen("\"schema\":1", "\"schema\":2", 1);
        let e = refused::<StatsMsg>(newer.as_bytes(), lim());
        assert!(
            matches!(
                e,
                CodecError::Version {
                    got: 2,
                    want: 1,
                    ..
                }
            ),
            "{e}"
        );
        assert_eq!(DropReason::of_codec(&e), DropReason::Schema);
        let old = crate::codec::encode(b"DUPACSTA", 9, &actor(), "stats").expect("bincode");
        let e = refused::<StatsMsg>(&old, lim());
        assert!(matches!(e, CodecError::Binary { .. }), "{e}");
        assert!(e.to_string().contains("DUPACSTA"), "{e}");
        assert_eq!(DropReason::of_codec(&e), DropReason::Schema);
    }
}
