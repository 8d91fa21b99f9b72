//! The RSRP sources (spec/radio.md): what tells the RSRP of every site at a point
//! ([`RsrpSource`]) — the radio world by a ray cast per query (exact), the cache
//! ([`crate::cache::RsrpCache`]) by interpolation — and a source with an episode's shadow-fading
//! realisation on top ([`ShadowedSource`], the true RSRP under `radio.channel.model = "real"`).
//! Beside the world and the shadow model, holding neither: a source is given what it reads.

use crate::shadow::ShadowField;
use crate::world::RadioWorld;
use dupac_common::geometry::Point;
use dupac_common::ids::SiteId;
use std::sync::Arc;

/// Anything that can tell the RSRP of every site at a point: exact ray casting or the cache.
pub trait RsrpSource: Sync {
    /// M, the number of sites.
    fn num_sites(&self) -> usize;
    /// RSRP (dBm) of every site at `p_m`, into `out[0..M]`.
    fn rsrp_all_dbm(&self, p_m: Point, out: &mut [f64]);
    /// Line of sight of every site at `p_m` as this source knows it, into `out[0..M]`: 1 (LoS)
    /// or 0 (NLoS) where it is decided at `p_m`, a value between where the source interpolates
    /// (the cache: between grid points, as its RSRP). Returns false, leaving `out` alone, when
    /// the source does not know it (the caller casts the rays).
    fn los_all(&self, _p_m: Point, _out: &mut [f64]) -> bool {
        false
    }
}

impl RsrpSource for RadioWorld {
    fn num_sites(&self) -> usize {
        RadioWorld::num_sites(self)
    }
    fn rsrp_all_dbm(&self, p_m: Point, out: &mut [f64]) {
        RadioWorld::rsrp_all_dbm(self, p_m, out)
    }
    /// A ray per site (exact).
    fn los_all(&self, p_m: Point, out: &mut [f64]) -> bool {
        for (i, o) in out.iter_mut().enumerate().take(self.sites.len()) {
            *o = f64::from(u8::from(self.los(SiteId(i as u16), p_m)));
        }
        true
    }
}

/// An RSRP source with a shadow-fading realisation on top: the true RSRP of an episode's field,
/// for the metrics (SINR, hindsight) and for planners that know the true field
/// (`radio.channel.knowledge = "true_field"`).
pub struct ShadowedSource {
    pub base: Arc<dyn RsrpSource + Send + Sync>,
    pub field: Arc<ShadowField>,
    /// Where the base source does not know the line of sight, a source that does (the radio
    /// world: a ray per site).
    pub los: Arc<dyn RsrpSource + Send + Sync>,
}

impl RsrpSource for ShadowedSource {
    fn num_sites(&self) -> usize {
        self.base.num_sites()
    }

    fn rsrp_all_dbm(&self, p_m: Point, out: &mut [f64]) {
        let m = self.base.num_sites();
        self.base.rsrp_all_dbm(p_m, out);
        let mut los = vec![0.0; m];
        if !self.base.los_all(p_m, &mut los) {
            self.los.los_all(p_m, &mut los);
        }
        let mut sf = vec![0.0; m];
        self.field.apply(p_m, &los, out, &mut sf);
    }

    fn los_all(&self, p_m: Point, out: &mut [f64]) -> bool {
        self.base.los_all(p_m, out)
    }
}
