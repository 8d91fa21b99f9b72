//! The held-out splits (docs/env.md "Held-out pairs: validation and test"): validation and
//! test, the same bins and count, each with its seed, ChaCha domain and file.

use super::{EVAL_DOMAIN, TEST_DOMAIN};
use dupac_common::config::PairsConfig;
use dupac_radio::city::City;
use std::path::PathBuf;

/// A held-out split (docs/env.md "Held-out pairs: validation and test"): both have
/// `pairs.eval_bins_m` × `pairs.eval_per_bin` pairs and differ in seed, ChaCha domain and file.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
pub enum Split {
    /// `pairs.eval_seed`, [`EVAL_DOMAIN`], `pairs.eval_file`: the set training evaluates on and
    /// the design was chosen on (the default).
    #[default]
    Validation,
    /// `pairs.test_seed`, [`TEST_DOMAIN`], `pairs.test_file`: for the final report only.
    Test,
}

/// What `pairs.eval_file` and `pairs.test_file` write for the city's fingerprint.
pub const CITY_PLACEHOLDER: &str = "{city}";

impl Split {
    /// Both splits, validation first.
    pub const ALL: [Split; 2] = [Split::Validation, Split::Test];

    /// `validation` or `test`.
    pub fn name(self) -> &'static str {
        match self {
            Split::Validation => "validation",
            Split::Test => "test",
        }
    }

    /// The split of `name` (`validation` or `test`).
    pub fn from_name(name: &str) -> Option<Split> {
        Split::ALL.into_iter().find(|s| s.name() == name)
    }

    /// The split's seed (`pairs.eval_seed` or `pairs.test_seed`).
    pub fn seed(self, cfg: &PairsConfig) -> u64 {
        match self {
            Split::Validation => cfg.eval_seed,
            Split::Test => cfg.test_seed,
        }
    }

    /// The configuration key of [`Split::seed`].
    pub fn seed_key(self) -> &'static str {
        match self {
            Split::Validation => "pairs.eval_seed",
            Split::Test => "pairs.test_seed",
        }
    }

    /// The split's file in `city` (`pairs.eval_file` or `pairs.test_file`, with `{city}`
    /// replaced by the city's fingerprint: [`CITY_PLACEHOLDER`]).
    pub fn file(self, cfg: &PairsConfig, city: &City) -> PathBuf {
        let configured = match self {
            Split::Validation => &cfg.eval_file,
            Split::Test => &cfg.test_file,
        };
        match configured.to_str() {
            Some(s) if s.contains(CITY_PLACEHOLDER) => {
                PathBuf::from(s.replace(CITY_PLACEHOLDER, &format!("{:016x}", city.fingerprint())))
            }
            _ => configured.clone(),
        }
    }

    /// The split's file as configured (`{city}` not replaced): what can be checked before the
    /// city is built (a path with the placeholder does not exist).
    pub fn configured_file(self, cfg: &PairsConfig) -> &std::path::Path {
        match self {
            Split::Validation => &cfg.eval_file,
            Split::Test => &cfg.test_file,
        }
    }

    /// The configuration key of [`Split::file`].
    pub fn file_key(self) -> &'static str {
        match self {
            Split::Validation => "pairs.eval_file",
            Split::Test => "pairs.test_file",
        }
    }

    /// The ChaCha domain tag of the split's streams.
    pub fn domain(self) -> u64 {
        match self {
            Split::Validation => EVAL_DOMAIN,
            Split::Test => TEST_DOMAIN,
        }
    }

    /// `split: NAME (KEY = SEED)`, the line a report names its pairs with.
    pub fn describe(self, cfg: &PairsConfig) -> String {
        format!(
            "split: {} ({} = {})",
            self.name(),
            self.seed_key(),
            self.seed(cfg)
        )
    }
}
