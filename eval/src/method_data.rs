//! A method's flights as the report's tables read them: every flight's metrics with its distance
//! bin, all training seeds together ([`MethodData`], [`gather`]), with the rates and intervals
//! of the main table.

use crate::interval::{MeanCi, Rate, mean_ci95, wilson95};
use crate::metrics::{FlightMetrics, flight_metrics};
use crate::records::RecordsFile;
use dupac_common::msg::Outcome;
use std::collections::BTreeMap;

/// The metrics of every flight of a method, all seeds together.
#[derive(Clone)]
pub struct MethodData {
    pub label: String,
    pub seeds: u32,
    /// (bin_m, metrics) of every flight.
    pub flights: Vec<(f64, FlightMetrics)>,
}

impl MethodData {
    pub fn successes(&self) -> impl Iterator<Item = &(f64, FlightMetrics)> {
        self.flights
            .iter()
            .filter(|(_, m)| m.outcome == Outcome::Goal)
    }
    /// Handovers and ping-pongs per km flown, over all flights.
    pub fn per_km(&self) -> (f64, f64) {
        let km: f64 = self
            .flights
            .iter()
            .map(|(_, m)| m.distance_m / 1000.0)
            .sum();
        let ho: f64 = self
            .flights
            .iter()
            .map(|(_, m)| f64::from(m.handovers))
            .sum();
        let pp: f64 = self
            .flights
            .iter()
            .map(|(_, m)| f64::from(m.ping_pongs))
            .sum();
        (ho / km.max(1e-9), pp / km.max(1e-9))
    }
    pub fn rate(&self, o: Outcome) -> Rate {
        let k = self.flights.iter().filter(|(_, m)| m.outcome == o).count();
        wilson95(k, self.flights.len())
    }
    pub fn ci(&self, bin: Option<f64>, f: impl Fn(&FlightMetrics) -> f64) -> MeanCi {
        let v: Vec<f64> = self
            .successes()
            .filter(|(b, _)| bin.is_none_or(|x| (x - b).abs() < 1e-6))
            .map(|(_, m)| f(m))
            .collect();
        mean_ci95(&v)
    }
    pub fn all_ci(&self, f: impl Fn(&FlightMetrics) -> f64) -> MeanCi {
        mean_ci95(&self.flights.iter().map(|(_, m)| f(m)).collect::<Vec<_>>())
    }
}

/// Each method's data from its records files (any number of seeds each).
pub fn gather<'a>(files: impl IntoIterator<Item = &'a RecordsFile>) -> Vec<MethodData> {
    let mut by: BTreeMap<String, MethodData> = BTreeMap::new();
    for f in files {
        let d = by.entry(f.method.clone()).or_insert_with(|| MethodData {
            label: f.method.clone(),
            seeds: 0,
            flights: Vec::new(),
        });
        d.seeds += 1;
        for r in &f.flights {
            d.flights.push((r.bin_m, flight_metrics(r, &f.rules)));
        }
    }
    // Policies first (as given), planners after.
    let mut v: Vec<MethodData> = by.into_values().collect();
    v.sort_by_key(|d| (is_planner(&d.label), d.label.clone()));
    v
}

pub fn is_planner(label: &str) -> bool {
    label.starts_with("shortest_") || label.starts_with("coverage_l")
}

pub fn bins_of(data: &[MethodData]) -> Vec<f64> {
    let mut b: Vec<f64> = data
        .iter()
        .flat_map(|d| d.flights.iter().map(|f| f.0))
        .collect();
    b.sort_by(f64::total_cmp);
    b.dedup_by(|a, b| (*a - *b).abs() < 1e-6);
    b
}
