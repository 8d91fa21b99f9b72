//! The radio world: city + sites + radio model, answering "what RSRP does site s give at p" in
//! exact mode (a line-of-sight ray cast per query; spec/radio.md D9).

use crate::antenna::AntennaPattern;
use crate::channel::Channel;
use crate::city::City;
use crate::error::RadioError;
use crate::link::{LinkBudget, LinkModel, Transmitter};
use crate::sites::{Site, place_sites};
use dupac_common::config::{Config, RadioConfig};
use dupac_common::geometry::Point;
use dupac_common::ids::SiteId;
use std::sync::Arc;

/// City, sites and radio model, ready for link queries.
#[derive(Debug, Clone)]
pub struct RadioWorld {
    pub city: City,
    pub sites: Vec<Site>,
    /// Antenna pattern per site (tilt and array may differ per site), indexed by [`SiteId`].
    antennas: Vec<AntennaPattern>,
    pub link: LinkModel,
    pub radio: RadioConfig,
    /// The shadow-fading realisations (`radio.channel.model = "real"`; `None`: deterministic).
    pub channel: Option<Arc<Channel>>,
}

impl RadioWorld {
    /// Loads the scenario's city, places its sites and sets up the radio model.
    pub fn build(cfg: &Config) -> Result<RadioWorld, RadioError> {
        let city = City::load(&cfg.scenario)?;
        let sites = place_sites(&cfg.scenario, &cfg.radio, &city)?;
        Ok(RadioWorld::from_parts(city, sites, &cfg.radio))
    }

    /// A world from an already built city and site list.
    pub fn from_parts(city: City, sites: Vec<Site>, radio: &RadioConfig) -> RadioWorld {
        let antennas = sites
            .iter()
            .map(|s| {
                AntennaPattern::with_array(
                    &radio.antenna,
                    radio.antenna.n_elements,
                    radio.antenna.spacing_wavelengths,
                    s.electrical_tilt_deg,
                )
            })
            .collect();
        let channel = Channel::new(
            &radio.channel,
            city.area_m,
            sites.iter().map(|s| s.kind.scenario()).collect(),
        )
        .map(Arc::new);
        RadioWorld {
            city,
            sites,
            antennas,
            link: LinkModel::from_config(radio),
            radio: radio.clone(),
            channel,
        }
    }

    /// M, the number of sites.
    pub fn num_sites(&self) -> usize {
        self.sites.len()
    }

    fn transmitter(&self, i: usize) -> Transmitter<'_> {
        let s = &self.sites[i];
        Transmitter {
            position_m: s.position_m,
            antenna: &self.antennas[i],
            boresights_deg: &s.boresights_deg,
            scenario: s.kind.scenario(),
            tx_power_dbm: s.tx_power_dbm,
        }
    }

    /// Checks that a UAV position is finite and inside the flight area.
    pub fn check_uav(&self, uav_m: Point) -> Result<(), RadioError> {
        if uav_m.iter().any(|v| !v.is_finite()) {
            return Err(RadioError::Position {
                what: "uav_xyz",
                value: uav_m,
                message: "not finite".into(),
            });
        }
        if !self.city.in_area(uav_m[0], uav_m[1]) {
            let a = self.city.area_m;
            return Err(RadioError::Position {
                what: "uav_xyz",
                value: uav_m,
                message: format!("outside the map ({a})"),
            });
        }
        Ok(())
    }

    /// Whether site `id` sees the UAV (no building on the antenna → UAV segment).
    #[inline]
    pub fn los(&self, id: SiteId, uav_m: Point) -> bool {
        !self
            .city
            .segment_blocked(self.sites[id.index()].position_m, uav_m)
    }

    /// Full link budget of site `id` at `uav_m`, LoS decided geometrically.
    pub fn link_budget(&self, id: SiteId, uav_m: Point) -> LinkBudget {
        let los = self.los(id, uav_m);
        self.link
            .evaluate(&self.transmitter(id.index()), uav_m, los)
    }

    /// Exact RSRP (dBm) of site `id` at `uav_m` and whether the site sees it (one ray cast).
    #[inline]
    pub fn rsrp_los(&self, id: SiteId, uav_m: Point) -> (f64, bool) {
        let los = self.los(id, uav_m);
        let rsrp_dbm = self
            .link
            .rsrp_dbm(&self.transmitter(id.index()), uav_m, los);
        (rsrp_dbm, los)
    }

    /// Exact RSRP (dBm) of site `id` at `uav_m`.
    #[inline]
    pub fn rsrp_dbm(&self, id: SiteId, uav_m: Point) -> f64 {
        self.rsrp_los(id, uav_m).0
    }

    /// Exact RSRP (dBm) of every site at `uav_m`, written into `out[site]` (`out.len()` ≥ M).
    pub fn rsrp_all_dbm(&self, uav_m: Point, out: &mut [f64]) {
        for (i, o) in out.iter_mut().enumerate().take(self.sites.len()) {
            *o = self.rsrp_dbm(SiteId(i as u16), uav_m);
        }
    }

    /// The strongest site at `uav_m`: `(site, RSRP dBm, LoS)`; lowest id on ties.
    pub fn best_server(&self, uav_m: Point) -> (SiteId, f64, bool) {
        let mut best = (SiteId(0), f64::NEG_INFINITY, false);
        for i in 0..self.sites.len() {
            let id = SiteId(i as u16);
            let los = self.los(id, uav_m);
            let r = self.link.rsrp_dbm(&self.transmitter(i), uav_m, los);
            if r > best.1 {
                best = (id, r, los);
            }
        }
        best
    }

    /// Every site's RSRP at `uav_m` (dBm, exact) less its shadow fading in `field` (dB), and each
    /// link's line of sight, into `rsrp_dbm` and `los`.
    pub fn rsrp_all_shadowed(
        &self,
        uav_m: Point,
        field: &crate::shadow::ShadowField,
        rsrp_dbm: &mut [f64],
        los: &mut [bool],
    ) {
        let m = self.sites.len();
        let mut los_frac = vec![0.0; m];
        for i in 0..m {
            los[i] = self.los(SiteId(i as u16), uav_m);
            los_frac[i] = f64::from(u8::from(los[i]));
            rsrp_dbm[i] = self.link.rsrp_dbm(&self.transmitter(i), uav_m, los[i]);
        }
        let mut sf = vec![0.0; m];
        field.apply(uav_m, &los_frac, rsrp_dbm, &mut sf);
    }

    /// Identifies city, sites and radio parameters: a cache built for another world is stale.
    pub fn fingerprint(&self) -> u64 {
        let mut h = dupac_common::fingerprint::Fnv64::new();
        h.write_u64(self.city.fingerprint());
        h.write_str(&serde_json::to_string(&self.sites).unwrap_or_default());
        // Only what changes RSRP: the A3 rule, the class thresholds and the handover
        // interruption do not.
        let mut rsrp_params = self.radio.clone();
        rsrp_params.a3 = Default::default();
        rsrp_params.handover_interruption_ms = 0.0;
        rsrp_params.rsrp_excellent_dbm = 0.0;
        rsrp_params.rsrp_poor_dbm = 0.0;
        // The channel's fading is applied on top of the cache, never stored in it: its section is
        // left out, so one cache (and the fingerprint it had before the section) serves every
        // channel.
        let text = toml::to_string(&rsrp_params).unwrap_or_default();
        h.write_str(text.split("\n[channel]\n").next().unwrap_or_default());
        h.finish()
    }
}
