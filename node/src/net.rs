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
    #[error("cannot open the zenoh session: {0}")]
    Open(String),
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
                message: e.to_string(),
            })?,
            None => zenoh::Config::default(),
        };
        let mut set = |key: &str, value: String| {
            c.insert_json5(key, &value)
                .map_err(|e| NetError::ConfigKey {
                    key: key.to_string(),
                    message: e.to_string(),
                })
        };
        if let Some(m) = self.mode {
            set("mode", format!("\"{}\"", m.as_str()))?;
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
            .map_err(|e| NetError::Open(e.to_string()))
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
        assert!(e.to_string().contains("connect/endpoints"), "{e}");
        let o = ConnectOpts {
            config: Some("/nonexistent/zenoh.json5".into()),
            ..ConnectOpts::default()
        };
        let e = o.zenoh_config().expect_err("missing file");
        assert!(e.to_string().contains("/nonexistent/zenoh.json5"), "{e}");
    }
}
