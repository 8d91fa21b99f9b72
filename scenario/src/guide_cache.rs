//! The episodes' guide paths of a set of pairs, planned once and kept on disk beside the RSRP
//! cache (`guides-<key>.bin` in the folder of `cache.path`), so that the processes of a run (the
//! orchestrator, every actor, the learner's held-out set) and later runs on the same host load
//! them instead of planning them again: planning 2 000 pairs' coverage-aware paths with their
//! coverage classes takes about a minute of every process that needs them.
//!
//! The key hashes everything that decides the paths: the environment fingerprint
//! ([`Config::env_fingerprint`]: the city, the sites, the radio, the environment, the planner),
//! the guide's λ and clearance, and every pair's id and endpoints. A file whose key, pair count
//! or ids do not match, or that cannot be read, is a miss: the paths are planned and the file
//! written anew (atomically; a failed write is logged, never fatal).

use dupac_actor::env::PathGuide;
use dupac_actor::pairs::Pair;
use dupac_common::codec;
use dupac_common::config::Config;
use dupac_common::fingerprint::Fnv64;
use serde::{Deserialize, Serialize};
use std::path::PathBuf;
use std::sync::Arc;

const MAGIC: &[u8; 8] = b"DUPACGDE";
/// Format version, raised whenever the planner's paths for the same inputs change, so that an
/// older file is rebuilt rather than reused.
const VERSION: u32 = 2;

/// The clearance (m) of the path `cfg`'s episodes are guided along:
/// `env.observation.path_guide_clearance_m`, or `planner.clearance_m` where that is 0.
/// Never below `env.uav_radius_m`, as the planner itself
/// ([`dupac_actor::planner::Planner::new`]) would raise it.
pub fn guide_clearance_m(cfg: &Config) -> f64 {
    let c = match cfg.env.observation.path_guide_clearance_m {
        c if c > 0.0 => c,
        _ => cfg.planner.clearance_m,
    };
    c.max(cfg.env.uav_radius_m)
}

/// Most bytes a guide file may have, and may allocate when decoded.
const MAX_BYTES: usize = 256 << 20;

/// One pair's guide path.
#[derive(Debug, Serialize, Deserialize)]
struct Entry {
    id: u64,
    #[serde(deserialize_with = "dupac_common::budget::vec")]
    points_m: Vec<[f64; 3]>,
}

/// What a guide file holds.
#[derive(Debug, Serialize, Deserialize)]
struct GuideFile {
    key: u64,
    /// Pairs the guide's clearance could not join, guided along the pairs' planner's path.
    fell_back: usize,
    #[serde(deserialize_with = "dupac_common::budget::vec")]
    entries: Vec<Entry>,
}

/// The cache entry of one set of pairs under one configuration.
#[derive(Debug, Clone)]
pub struct GuideCache {
    key: u64,
    path: PathBuf,
    lambda: f64,
    clearance_m: f64,
}

impl GuideCache {
    /// The entry of `pairs` guided as `cfg`'s episodes are, in a world of fingerprint
    /// `world_fingerprint` ([`dupac_radio::world::RadioWorld::fingerprint`]).
    pub fn new(cfg: &Config, world_fingerprint: u64, pairs: &[Pair]) -> GuideCache {
        let lambda = cfg.env.observation.path_guide_lambda;
        let clearance_m = guide_clearance_m(cfg);
        let mut h = Fnv64::new();
        h.write_u64(cfg.env_fingerprint(world_fingerprint));
        h.write_f64(lambda);
        h.write_f64(clearance_m);
        h.write_u64(pairs.len() as u64);
        // Endpoints to the millimetre: a pairs file read back (JSON) may differ in the last bit.
        for p in pairs {
            h.write_u64(p.id);
            for v in p.source_m.iter().chain(p.destination_m.iter()) {
                h.write_u64((v * 1e3).round() as i64 as u64);
            }
        }
        let key = h.finish();
        let dir = cfg
            .cache
            .path
            .parent()
            .map(PathBuf::from)
            .unwrap_or_default();
        GuideCache {
            key,
            path: dir.join(format!("guides-{key:016x}.bin")),
            lambda,
            clearance_m,
        }
    }

    /// The file of this entry.
    pub fn path(&self) -> &std::path::Path {
        &self.path
    }

    /// Gives `pairs` their cached paths: `Some(pairs that fell back)` on a hit, `None` on a
    /// miss (no file, another key, other pairs, a file that cannot be read: logged).
    pub fn load(&self, pairs: &mut [Pair]) -> Option<usize> {
        if !self.path.exists() {
            return None;
        }
        let what = self.path.display().to_string();
        let file: GuideFile = match codec::read_limited(&self.path, MAX_BYTES)
            .and_then(|b| codec::decode_budgeted(MAGIC, VERSION, &b, MAX_BYTES, MAX_BYTES, &what))
        {
            Ok(f) => f,
            Err(e) => {
                tracing::warn!("guide cache not used, planning again: {e}");
                return None;
            }
        };
        let fits = file.key == self.key
            && file.entries.len() == pairs.len()
            && file
                .entries
                .iter()
                .zip(pairs.iter())
                .all(|(e, p)| e.id == p.id);
        if !fits {
            tracing::warn!(file = %what, "guide cache of other pairs: planning again");
            return None;
        }
        let mut guides = Vec::with_capacity(pairs.len());
        for e in &file.entries {
            let points: Vec<dupac_common::geometry::Point> = e
                .points_m
                .iter()
                .map(|&[x, y, z]| dupac_common::geometry::Point::new(x, y, z))
                .collect();
            match PathGuide::new(&points) {
                Some(g) => guides.push(Arc::new(g)),
                None => {
                    tracing::warn!(file = %what, pair = e.id, "guide cache holds a bad path: planning again");
                    return None;
                }
            }
        }
        for (p, g) in pairs.iter_mut().zip(guides) {
            p.path = Some(g);
            p.path_lambda = self.lambda;
            p.path_clearance_m = self.clearance_m;
        }
        Some(file.fell_back)
    }

    /// Writes the paths of `pairs` (every pair has one) with the count that fell back; a
    /// failure is logged and otherwise ignored (the next process plans again).
    pub fn save(&self, pairs: &[Pair], fell_back: usize) {
        let entries: Option<Vec<Entry>> = pairs
            .iter()
            .map(|p| {
                p.path.as_ref().map(|g| Entry {
                    id: p.id,
                    points_m: g.points_m().iter().map(|q| [q.x, q.y, q.z]).collect(),
                })
            })
            .collect();
        let Some(entries) = entries else {
            tracing::warn!("a pair without a guide path: guide cache not written");
            return;
        };
        let file = GuideFile {
            key: self.key,
            fell_back,
            entries,
        };
        let written = codec::encode(MAGIC, VERSION, &file, "guide cache").and_then(|bytes| {
            if let Some(dir) = self.path.parent()
                && !dir.as_os_str().is_empty()
            {
                std::fs::create_dir_all(dir).map_err(|cause| codec::CodecError::Io {
                    path: dir.display().to_string(),
                    cause,
                })?;
            }
            codec::write_atomic(&self.path, &bytes)
        });
        if let Err(e) = written {
            tracing::warn!("guide cache not written: {e}");
        }
    }
}
