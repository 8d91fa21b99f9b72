//! Opening a Zenoh session from the connection arguments every DUPAC process shares
//! (`--config`, `--mode`, `--connect`, `--listen`, `--no-multicast-scouting`, as in zenoh's own
//! examples). Flags override the file; without either, zenoh's defaults apply (peer mode with
//! multicast scouting: processes on one LAN find each other).

use std::path::PathBuf;

/// Errors of opening a session.
#[derive(Debug, thiserror::Error)]
pub enum NetError {
    #[error("zenoh configuration {path}: {message}")]
    ConfigFile { path: String, message: String },
    #[error("zenoh configuration key {key}: {message}")]
    ConfigKey { key: String, message: String },
    #[error("endpoint {endpoint:?}: {message}")]
    Endpoint { endpoint: String, message: String },
    #[error("cannot open the zenoh session: {0}")]
    Open(String),
}

/// The transports this build of zenoh speaks (Cargo.toml's zenoh features).
pub const PROTOCOLS: [&str; 2] = ["tcp", "tls"];

/// Checks an endpoint as `--connect` and `--listen` take it, `PROTOCOL/HOST:PORT` with an
/// optional `?metadata` and `#config` (`tcp/10.0.0.1:7447`, `tls/[::1]:7447`,
/// `tcp/router.lan:7447`): a known protocol, a host that is an IPv4 address, an IPv6 address
/// in brackets or a DNS name, and a port in 0–65535. The message says what is wrong in words.
pub fn check_endpoint(endpoint: &str) -> Result<(), NetError> {
    let bad = |message: String| NetError::Endpoint {
        endpoint: endpoint.to_string(),
        message,
    };
    let form = "expected PROTOCOL/HOST:PORT, e.g. tcp/10.0.0.1:7447";
    let locator = endpoint.split(['?', '#']).next().unwrap_or_default();
    let Some((protocol, address)) = locator.split_once('/') else {
        return Err(bad(form.into()));
    };
    if !PROTOCOLS.contains(&protocol) {
        return Err(bad(format!(
            "unknown protocol {protocol:?} (this build speaks {})",
            PROTOCOLS.join(" and ")
        )));
    }
    let Some((host, port)) = address.rsplit_once(':') else {
        return Err(bad(format!("no port in {address:?}: {form}")));
    };
    if port.parse::<u16>().is_err() {
        return Err(bad(format!(
            "port {port:?} is not a number from 0 to 65535"
        )));
    }
    if let Some(v6) = host.strip_prefix('[').and_then(|h| h.strip_suffix(']')) {
        return v6
            .parse::<std::net::Ipv6Addr>()
            .map(|_| ())
            .map_err(|_| bad(format!("{v6:?} is not an IPv6 address")));
    }
    if host.is_empty() {
        return Err(bad(format!("no host in {address:?}: {form}")));
    }
    if host.bytes().all(|b| b.is_ascii_digit() || b == b'.') {
        return host.parse::<std::net::Ipv4Addr>().map(|_| ()).map_err(|_| {
            bad(format!(
                "{host} is not an IPv4 address (four numbers from 0 to 255, e.g. 10.0.0.1)"
            ))
        });
    }
    let label_ok = |l: &str| {
        !l.is_empty()
            && l.len() <= 63
            && !l.starts_with('-')
            && !l.ends_with('-')
            && l.bytes().all(|b| b.is_ascii_alphanumeric() || b == b'-')
    };
    if host.contains(':') {
        return Err(bad(format!(
            "{host:?}: an IPv6 address goes in brackets, e.g. tcp/[::1]:7447"
        )));
    }
    if host.len() > 253 || !host.trim_end_matches('.').split('.').all(label_ok) {
        return Err(bad(format!(
            "{host:?} is neither an IP address nor a host name"
        )));
    }
    Ok(())
}

/// A zenoh error in words: zenoh's errors carry the source file and line of the code that
/// raised them (`… at /path/to/zenoh-link-tcp/src/unicast.rs:123.`, also inside the brackets
/// of a list of errors) and chain their causes with ` - Caused by `; this keeps the words and
/// joins the causes with `: `.
pub fn zenoh_message(e: &dyn std::fmt::Display) -> String {
    let text = e.to_string();
    let mut out = String::with_capacity(text.len());
    let mut rest = text.as_str();
    while let Some(k) = rest.find(" at ") {
        let after = &rest[k + 4..];
        let end = after
            .find(|c: char| c.is_whitespace() || matches!(c, ']' | ')' | ','))
            .unwrap_or(after.len());
        if is_source_location(after[..end].trim_end_matches('.')) {
            out.push_str(&rest[..k]);
            rest = &after[end..];
        } else {
            out.push_str(&rest[..k + 4]);
            rest = after;
        }
    }
    out.push_str(rest);
    out.replace(" - Caused by ", ": ").trim().to_string()
}

/// `FILE.rs:LINE`.
fn is_source_location(s: &str) -> bool {
    s.rsplit_once(':').is_some_and(|(file, line)| {
        file.ends_with(".rs") && !line.is_empty() && line.bytes().all(|b| b.is_ascii_digit())
    })
}

/// The node's role in the Zenoh network.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Mode {
    Peer,
    Client,
    Router,
}

impl Mode {
    pub fn as_str(self) -> &'static str {
        match self {
            Mode::Peer => "peer",
            Mode::Client => "client",
            Mode::Router => "router",
        }
    }
}

/// Where and how to join the Zenoh network.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct ConnectOpts {
    /// A zenoh JSON5 configuration file (TLS, access control, …), applied first.
    pub config: Option<PathBuf>,
    pub mode: Option<Mode>,
    /// Endpoints to connect to, e.g. `tcp/10.0.0.1:7447`.
    pub connect: Vec<String>,
    /// Endpoints to listen on, e.g. `tcp/0.0.0.0:7447`.
    pub listen: Vec<String>,
    /// Turn multicast scouting off (loopback runs and multi-host runs with explicit endpoints).
    pub no_multicast_scouting: bool,
    /// zenoh's receive limit (`transport/link/rx/max_message_size`, bytes): a larger message is
    /// dropped by zenoh while it is reassembled, before it reaches DUPAC. Set from the run's
    /// configuration ([`dupac_common::msg::MsgLimits::run_max_bytes`]); `None` keeps the file's or
    /// zenoh's default (1 GiB).
    pub rx_max_message_bytes: Option<usize>,
}

fn json_list(items: &[String]) -> String {
    serde_json::to_string(items).unwrap_or_else(|_| "[]".into())
}

impl ConnectOpts {
    /// The zenoh configuration these options describe.
    pub fn zenoh_config(&self) -> Result<zenoh::Config, NetError> {
        let mut c = match &self.config {
            Some(p) => zenoh::Config::from_file(p).map_err(|e| NetError::ConfigFile {
                path: p.display().to_string(),
                message: zenoh_message(&e),
            })?,
            None => zenoh::Config::default(),
        };
        let mut set = |key: &str, value: String| {
            c.insert_json5(key, &value)
                .map_err(|e| NetError::ConfigKey {
                    key: key.to_string(),
                    message: zenoh_message(&e),
                })
        };
        if let Some(m) = self.mode {
            set("mode", format!("\"{}\"", m.as_str()))?;
        }
        for e in self.connect.iter().chain(&self.listen) {
            check_endpoint(e)?;
        }
        if !self.connect.is_empty() {
            set("connect/endpoints", json_list(&self.connect))?;
        }
        if !self.listen.is_empty() {
            set("listen/endpoints", json_list(&self.listen))?;
        }
        if self.no_multicast_scouting {
            set("scouting/multicast/enabled", "false".into())?;
        }
        if let Some(n) = self.rx_max_message_bytes {
            set("transport/link/rx/max_message_size", n.to_string())?;
        }
        Ok(c)
    }

    /// Opens the session (blocking).
    pub fn open(&self) -> Result<zenoh::Session, NetError> {
        use zenoh::Wait;
        let c = self.zenoh_config()?;
        zenoh::open(c)
            .wait()
            .map_err(|e| NetError::Open(zenoh_message(&e)))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn flags_land_in_the_zenoh_config() {
        let o = ConnectOpts {
            mode: Some(Mode::Client),
            connect: vec!["tcp/127.0.0.1:7447".into()],
            no_multicast_scouting: true,
            rx_max_message_bytes: Some(3 << 20),
            ..ConnectOpts::default()
        };
        let c = o.zenoh_config().expect("config");
        assert_eq!(
            c.get_json("transport/link/rx/max_message_size")
                .expect("rx limit"),
            (3 << 20).to_string()
        );
        assert_eq!(c.get_json("mode").expect("mode"), "\"client\"");
        assert!(
            c.get_json("connect/endpoints")
                .expect("endpoints")
                .contains("tcp/127.0.0.1:7447")
        );
        assert_eq!(
            c.get_json("scouting/multicast/enabled").expect("scouting"),
            "false"
        );
    }

    #[test]
    fn a_bad_endpoint_or_file_is_a_clear_error() {
        let o = ConnectOpts {
            connect: vec!["not-an-endpoint".into()],
            ..ConnectOpts::default()
        };
        let e = o.zenoh_config().expect_err("bad endpoint");
        assert!(
            e.to_string()
                .contains("\"not-an-endpoint\": expected PROTOCOL/HOST:PORT"),
            "{e}"
        );
        let o = ConnectOpts {
            config: Some("/nonexistent/zenoh.json5".into()),
            ..ConnectOpts::default()
        };
        let e = o.zenoh_config().expect_err("missing file");
        assert!(e.to_string().contains("/nonexistent/zenoh.json5"), "{e}");
        assert!(
            !e.to_string().contains(".rs:"),
            "no zenoh source location: {e}"
        );
    }

    #[test]
    fn endpoints_are_checked_in_words() {
        for good in [
            "tcp/10.0.0.1:7447",
            "tcp/0.0.0.0:0",
            "tls/[::1]:7447",
            "tcp/router.lan:7447",
            "tcp/localhost:7447?iface=lo",
            "tls/host:7447#root_ca_certificate=ca.pem",
        ] {
            check_endpoint(good).unwrap_or_else(|e| panic!("{good}: {e}"));
        }
        for (bad, why) in [
            ("tcp/300.1.1.1:7447", "300.1.1.1 is not an IPv4 address"),
            ("tcp/10.0.0.1:99999", "port \"99999\""),
            ("tcp/10.0.0.1", "no port"),
            ("udp/10.0.0.1:7447", "unknown protocol \"udp\""),
            ("10.0.0.1:7447", "expected PROTOCOL/HOST:PORT"),
            ("tcp/::1:7447", "in brackets"),
            ("tcp/[::g]:7447", "not an IPv6 address"),
            ("tcp/bad_host:7447", "neither an IP address nor a host name"),
            ("tcp/:7447", "no host"),
        ] {
            let e = check_endpoint(bad).expect_err(bad).to_string();
            assert!(e.contains(bad) && e.contains(why), "{bad}: {e}");
        }
    }

    #[test]
    fn zenoh_errors_lose_their_source_locations() {
        let raw = "Can not create a new TCP listener bound to tcp/10.9.9.9:7447: Cannot assign \
                   requested address at /home/ci/.cargo/registry/src/zenoh-link-tcp-1.10.2/src/\
                   unicast.rs:321. - Caused by Cannot assign requested address (os error 99) at \
                   /home/ci/zenoh-transport/src/manager.rs:77.";
        assert_eq!(
            zenoh_message(&raw),
            "Can not create a new TCP listener bound to tcp/10.9.9.9:7447: Cannot assign \
             requested address: Cannot assign requested address (os error 99)"
        );
        assert_eq!(
            zenoh_message(
                &"Can not create a new TCP listener bound to tcp/192.0.2.1:7447: [192.0.2.1:7447: \
                  Cannot assign requested address (os error 99) at /root/zenoh-link-commons/src/\
                  tcp.rs:61.]"
            ),
            "Can not create a new TCP listener bound to tcp/192.0.2.1:7447: [192.0.2.1:7447: \
             Cannot assign requested address (os error 99)]"
        );
        assert_eq!(
            zenoh_message(&"meet at noon: at 12.rs"),
            "meet at noon: at 12.rs"
        );
    }
}
