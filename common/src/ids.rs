//! Typed ids used across crates, so a site index is never confused with any other index.

use serde::{Deserialize, Serialize};
use std::fmt;

/// Index of a ground base station (GBS, a 3-sector site) in the scenario's site list,
/// `0..M` (M = 30 by default, paper Sec. II).
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize, Deserialize)]
#[serde(transparent)]
pub struct SiteId(pub u16);

impl SiteId {
    /// The id as a `usize`, for indexing per-site arrays that are laid out by `SiteId`.
    #[inline]
    pub fn index(self) -> usize {
        usize::from(self.0)
    }

    /// Iterator over the ids `0..m`.
    pub fn all(m: usize) -> impl Iterator<Item = SiteId> {
        (0..m).map(|i| SiteId(i as u16))
    }
}

impl fmt::Display for SiteId {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "gbs{}", self.0)
    }
}

/// Identifies one actor process within a run (`--id`; the key `dupac/<run>/traj/<id>`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize, Deserialize)]
#[serde(transparent)]
pub struct ActorId(pub u32);

impl ActorId {
    /// The id the learner uses in the headers of its own messages.
    pub const LEARNER: ActorId = ActorId(u32::MAX);
}

impl fmt::Display for ActorId {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        if *self == ActorId::LEARNER {
            f.write_str("learner")
        } else {
            write!(f, "{}", self.0)
        }
    }
}
