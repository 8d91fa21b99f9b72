//! The compact text forms a command line passes, parsed with errors that name the bad token,
//! and written back by `Display` (which parses to the same value).
//!
//! A link ([`LinkImpairment`]): comma-separated `key=value` items, each at most once, or `none`
//! (or nothing) for no impairment:
//! - `delay=50ms`, `jitter=20ms`: durations, with a unit `ms`, `s` or `min` (decimals allowed,
//!   rounded to the millisecond);
//! - `rate=10mbit`: a rate in bits per second with `bit`, `kbit`, `mbit` or `gbit` (decimal
//!   prefixes, as `tc` writes them), or in bytes per second with `B/s`, `kB/s`, `MB/s`, `GB/s`;
//!   `rate=none` for none;
//! - `burst=64KiB`: the token bucket in bytes, with `B`, `kB`, `MB`, `KiB` or `MiB`.
//!
//! Example: `delay=50ms,jitter=20ms,rate=10mbit`.
//!
//! Faults ([`Fault`]): comma-separated `KIND@START+DURATION` items (`stall`, `partition`) or
//! `reset@START`, times as durations above, from the relay's origin; `none` (or nothing) for
//! none. Example: `stall@10s+3s,partition@30s+20s,reset@50s`.
//!
//! Units are case-insensitive.

use std::fmt;
use std::str::FromStr;

use crate::fault::{Fault, FaultKind};
use crate::link::LinkImpairment;

/// A spec that does not parse: the token at fault and why.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("`{token}`: {reason}")]
pub struct SpecError {
    /// The item (or the part of it) that is wrong, as written.
    pub token: String,
    /// What is wrong with it, and what is expected.
    pub reason: String,
}

fn bad(token: &str, reason: impl Into<String>) -> SpecError {
    SpecError {
        token: token.to_string(),
        reason: reason.into(),
    }
}

/// The items of a comma-separated spec; none for `""` or `none`.
fn items(spec: &str) -> Result<Vec<&str>, SpecError> {
    let spec = spec.trim();
    if spec.is_empty() || spec.eq_ignore_ascii_case("none") {
        return Ok(vec![]);
    }
    spec.split(',')
        .map(str::trim)
        .map(|item| {
            if item.is_empty() {
                Err(bad(spec, "empty item (two commas, or a trailing one)"))
            } else {
                Ok(item)
            }
        })
        .collect()
}

/// Splits `50ms` into `(50.0, "ms")`; the number must be finite and not negative.
fn number_and_unit(token: &str) -> Result<(f64, String), SpecError> {
    let split = token
        .find(|c: char| !(c.is_ascii_digit() || c == '.'))
        .unwrap_or(token.len());
    let (number, unit) = token.split_at(split);
    if number.is_empty() {
        return Err(bad(token, "expected a number"));
    }
    let value: f64 = number
        .parse()
        .map_err(|_| bad(token, format!("`{number}` is not a number")))?;
    if !value.is_finite() {
        return Err(bad(token, "not a finite number"));
    }
    Ok((value, unit.trim().to_ascii_lowercase()))
}

/// Rounds `value × scale` to a `u64`, refusing what does not fit.
fn scaled(token: &str, value: f64, scale: f64) -> Result<u64, SpecError> {
    let v = (value * scale).round();
    if v > u64::MAX as f64 {
        return Err(bad(token, "too large"));
    }
    Ok(v as u64)
}

/// A duration in milliseconds.
pub fn parse_duration_ms(token: &str) -> Result<u64, SpecError> {
    let (value, unit) = number_and_unit(token)?;
    let scale = match unit.as_str() {
        "ms" => 1.0,
        "s" => 1000.0,
        "min" => 60_000.0,
        "" => return Err(bad(token, "missing unit (ms, s or min)")),
        u => return Err(bad(token, format!("unknown unit `{u}` (ms, s or min)"))),
    };
    scaled(token, value, scale)
}

/// A rate in bytes per second.
pub fn parse_rate_bytes_per_s(token: &str) -> Result<u64, SpecError> {
    let (value, unit) = number_and_unit(token)?;
    let bytes_per_unit = match unit.as_str() {
        "bit" => 1.0 / 8.0,
        "kbit" => 1e3 / 8.0,
        "mbit" => 1e6 / 8.0,
        "gbit" => 1e9 / 8.0,
        "b/s" => 1.0,
        "kb/s" => 1e3,
        "mb/s" => 1e6,
        "gb/s" => 1e9,
        "" => {
            return Err(bad(
                token,
                "missing unit (bit, kbit, mbit, gbit per second, or B/s, kB/s, MB/s, GB/s)",
            ));
        }
        u => {
            return Err(bad(
                token,
                format!("unknown unit `{u}` (bit, kbit, mbit, gbit, or B/s, kB/s, MB/s, GB/s)"),
            ));
        }
    };
    let rate = scaled(token, value, bytes_per_unit)?;
    if rate == 0 {
        return Err(bad(token, "a rate under 1 byte/s forwards nothing"));
    }
    Ok(rate)
}

/// A size in bytes (a plain number is bytes).
pub fn parse_bytes(token: &str) -> Result<u64, SpecError> {
    let (value, unit) = number_and_unit(token)?;
    let scale = match unit.as_str() {
        "" | "b" => 1.0,
        "kb" => 1e3,
        "mb" => 1e6,
        "kib" => 1024.0,
        "mib" => 1024.0 * 1024.0,
        u => {
            return Err(bad(
                token,
                format!("unknown unit `{u}` (B, kB, MB, KiB, MiB)"),
            ));
        }
    };
    let n = scaled(token, value, scale)?;
    if n == 0 {
        return Err(bad(token, "must be at least 1 byte"));
    }
    Ok(n)
}

/// Parses a link spec (see the module documentation).
pub fn parse_link(spec: &str) -> Result<LinkImpairment, SpecError> {
    let mut link = LinkImpairment::NONE;
    let mut seen: Vec<&str> = vec![];
    for item in items(spec)? {
        let Some((key, value)) = item.split_once('=') else {
            return Err(bad(
                item,
                "expected KEY=VALUE with KEY one of delay, jitter, rate, burst",
            ));
        };
        let (key, value) = (key.trim(), value.trim());
        if seen.contains(&key) {
            return Err(bad(item, format!("`{key}` given twice")));
        }
        seen.push(key);
        let in_item = |e: SpecError| bad(item, e.reason);
        match key {
            "delay" => link.delay_ms = parse_duration_ms(value).map_err(in_item)?,
            "jitter" => link.jitter_ms = parse_duration_ms(value).map_err(in_item)?,
            "rate" if value.eq_ignore_ascii_case("none") => link.rate_bytes_per_s = None,
            "rate" => link.rate_bytes_per_s = Some(parse_rate_bytes_per_s(value).map_err(in_item)?),
            "burst" => link.burst_bytes = Some(parse_bytes(value).map_err(in_item)?),
            _ => {
                return Err(bad(
                    item,
                    format!("unknown key `{key}` (delay, jitter, rate, burst)"),
                ));
            }
        }
    }
    Ok(link)
}

/// Parses one fault, `KIND@START+DURATION` or `reset@START`.
pub fn parse_fault(item: &str) -> Result<Fault, SpecError> {
    let item = item.trim();
    let Some((kind, times)) = item.split_once('@') else {
        return Err(bad(
            item,
            "expected KIND@START+DURATION (stall, partition) or reset@START",
        ));
    };
    let kind = match kind.trim() {
        "stall" => FaultKind::Stall,
        "reset" => FaultKind::Reset,
        "partition" => FaultKind::Partition,
        k => {
            return Err(bad(
                item,
                format!("unknown fault `{k}` (stall, reset, partition)"),
            ));
        }
    };
    let (at, duration) = match times.split_once('+') {
        Some((at, d)) => (at.trim(), Some(d.trim())),
        None => (times.trim(), None),
    };
    let in_item = |e: SpecError| bad(item, e.reason);
    let at_ms = parse_duration_ms(at).map_err(in_item)?;
    let duration_ms = match (kind, duration) {
        (FaultKind::Reset, None) => 0,
        (FaultKind::Reset, Some(_)) => return Err(bad(item, "a reset takes no +DURATION")),
        (_, None) => {
            return Err(bad(
                item,
                format!("a {} needs a +DURATION, e.g. +5s", kind.name()),
            ));
        }
        (_, Some(d)) => match parse_duration_ms(d).map_err(in_item)? {
            0 => return Err(bad(item, "the duration must be > 0")),
            d => d,
        },
    };
    Ok(Fault {
        at_ms,
        duration_ms,
        kind,
    })
}

/// Parses a fault schedule (see the module documentation).
pub fn parse_faults(spec: &str) -> Result<Vec<Fault>, SpecError> {
    items(spec)?.into_iter().map(parse_fault).collect()
}

impl FromStr for LinkImpairment {
    type Err = SpecError;
    fn from_str(s: &str) -> Result<Self, SpecError> {
        parse_link(s)
    }
}

impl FromStr for Fault {
    type Err = SpecError;
    fn from_str(s: &str) -> Result<Self, SpecError> {
        parse_fault(s)
    }
}

/// Milliseconds as the spec writes them: whole seconds in `s`, otherwise `ms`.
struct Ms(u64);

impl fmt::Display for Ms {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        if self.0.is_multiple_of(1000) && self.0 > 0 {
            write!(f, "{}s", self.0 / 1000)
        } else {
            write!(f, "{}ms", self.0)
        }
    }
}

impl fmt::Display for LinkImpairment {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let mut items = vec![];
        if self.delay_ms > 0 {
            items.push(format!("delay={}", Ms(self.delay_ms)));
        }
        if self.jitter_ms > 0 {
            items.push(format!("jitter={}", Ms(self.jitter_ms)));
        }
        if let Some(rate) = self.rate_bytes_per_s {
            let bits = rate.saturating_mul(8);
            let r = if bits.is_multiple_of(1_000_000_000) {
                format!("{}gbit", bits / 1_000_000_000)
            } else if bits.is_multiple_of(1_000_000) {
                format!("{}mbit", bits / 1_000_000)
            } else if bits.is_multiple_of(1000) {
                format!("{}kbit", bits / 1000)
            } else {
                format!("{rate}B/s")
            };
            items.push(format!("rate={r}"));
        }
        if let Some(burst) = self.burst_bytes {
            items.push(format!("burst={burst}B"));
        }
        if items.is_empty() {
            f.write_str("none")
        } else {
            f.write_str(&items.join(","))
        }
    }
}

impl fmt::Display for Fault {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}@{}", self.kind.name(), Ms(self.at_ms))?;
        if self.kind != FaultKind::Reset || self.duration_ms > 0 {
            write!(f, "+{}", Ms(self.duration_ms))?;
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn links_parse() {
        assert_eq!(
            parse_link("delay=50ms,jitter=20ms,rate=10mbit").unwrap(),
            LinkImpairment::delay(50, 20).with_rate(1_250_000)
        );
        assert_eq!(parse_link("").unwrap(), LinkImpairment::NONE);
        assert_eq!(parse_link(" none ").unwrap(), LinkImpairment::NONE);
        let l = parse_link(" rate = 2.5MB/s , burst=64KiB, delay=0.25s ").unwrap();
        assert_eq!(l.rate_bytes_per_s, Some(2_500_000));
        assert_eq!(l.burst_bytes, Some(65_536));
        assert_eq!(l.delay_ms, 250);
        assert_eq!(
            parse_link("rate=100kbit").unwrap().rate_bytes_per_s,
            Some(12_500)
        );
        assert_eq!(
            parse_link("rate=1Gbit").unwrap().rate_bytes_per_s,
            Some(125_000_000)
        );
        assert_eq!(parse_link("rate=none").unwrap().rate_bytes_per_s, None);
        assert_eq!(parse_link("delay=1min").unwrap().delay_ms, 60_000);
        assert_eq!(parse_link("burst=1500").unwrap().burst_bytes, Some(1500));
    }

    #[test]
    fn faults_parse() {
        assert_eq!(
            parse_faults("partition@30s+20s, stall@10s+3s,reset@50s").unwrap(),
            [
                Fault::partition(30_000, 20_000),
                Fault::stall(10_000, 3_000),
                Fault::reset(50_000),
            ]
        );
        assert_eq!(parse_faults("").unwrap(), []);
        assert_eq!(parse_faults("none").unwrap(), []);
        assert_eq!(
            parse_faults("stall@250ms+1.5s").unwrap(),
            [Fault::stall(250, 1500)]
        );
    }

    /// Every bad spec's error names the offending token.
    #[test]
    fn bad_specs_name_the_token() {
        let cases = [
            ("delay=50", "delay=50", "missing unit"),
            ("delay=50ms,jitter=2xs", "jitter=2xs", "unknown unit `xs`"),
            ("delay=50ms,lag=3ms", "lag=3ms", "unknown key `lag`"),
            ("delay=50ms,delay=3ms", "delay=3ms", "given twice"),
            ("rate=10mb", "rate=10mb", "unknown unit `mb`"),
            ("rate=0mbit", "rate=0mbit", "forwards nothing"),
            ("rate=fast", "rate=fast", "expected a number"),
            ("delay=-5ms", "delay=-5ms", "expected a number"),
            ("delay=1.2.3s", "delay=1.2.3s", "not a number"),
            ("burst=0", "burst=0", "at least 1 byte"),
            ("delay", "delay", "KEY=VALUE"),
            (
                "delay=5ms,,rate=1mbit",
                "delay=5ms,,rate=1mbit",
                "empty item",
            ),
        ];
        for (spec, token, reason) in cases {
            let e = parse_link(spec).unwrap_err();
            assert_eq!(e.token, token, "{spec}: {e}");
            assert!(e.reason.contains(reason), "{spec}: {e}");
            assert!(e.to_string().contains(&format!("`{token}`")), "{e}");
        }
        let cases = [
            ("stall@1s+2s,crash@3s", "crash@3s", "unknown fault `crash`"),
            ("stall@1s", "stall@1s", "needs a +DURATION"),
            ("partition@1s+0s", "partition@1s+0s", "> 0"),
            ("reset@5s+1s", "reset@5s+1s", "no +DURATION"),
            ("reset@5", "reset@5", "missing unit"),
            ("reset", "reset", "KIND@START"),
            ("stall@1s+2h", "stall@1s+2h", "unknown unit `h`"),
        ];
        for (spec, token, reason) in cases {
            let e = parse_faults(spec).unwrap_err();
            assert_eq!(e.token, token, "{spec}: {e}");
            assert!(e.reason.contains(reason), "{spec}: {e}");
        }
    }

    #[test]
    fn display_parses_back() {
        let links = [
            LinkImpairment::NONE,
            LinkImpairment::delay(50, 20).with_rate(1_250_000),
            LinkImpairment::delay(1500, 0).with_rate(12_345),
            LinkImpairment {
                burst_bytes: Some(4096),
                ..LinkImpairment::delay(0, 7).with_rate(125_000_000)
            },
        ];
        for l in links {
            assert_eq!(parse_link(&l.to_string()).unwrap(), l, "{l}");
        }
        assert_eq!(
            LinkImpairment::delay(50, 20)
                .with_rate(1_250_000)
                .to_string(),
            "delay=50ms,jitter=20ms,rate=10mbit"
        );
        let faults = [
            Fault::stall(10_000, 3_000),
            Fault::partition(250, 1_500),
            Fault::reset(0),
        ];
        for f in faults {
            assert_eq!(parse_fault(&f.to_string()).unwrap(), f, "{f}");
        }
        assert_eq!(
            Fault::partition(30_000, 20_000).to_string(),
            "partition@30s+20s"
        );
    }
}
