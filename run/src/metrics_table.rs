//! Every metrics row of a run, held compactly for the CSV and the learning curves: one column
//! index shared by all rows and `f64` values (NaN where a row lacks a column). A row costs
//! 8 bytes per column (≈ 0.5 KB at ~65 columns) instead of a map of owned strings (≈ 5 KB):
//! the learner's memory over a long run stays flat to within megabytes (the soak test of
//! docs/reliability.md checks it).

use dupac_learner::learner::MetricsRow;
use std::collections::HashMap;

#[derive(Debug, Default)]
pub struct MetricsTable {
    columns: Vec<String>,
    index: HashMap<String, usize>,
    rows: Vec<Vec<f64>>,
}

impl MetricsTable {
    pub fn from_rows(rows: &[MetricsRow]) -> MetricsTable {
        let mut t = MetricsTable::default();
        for r in rows {
            t.push(r);
        }
        t
    }

    pub fn push(&mut self, row: &MetricsRow) {
        let mut values = vec![f64::NAN; self.columns.len()];
        for (k, &v) in row {
            let i = match self.index.get(k) {
                Some(&i) => i,
                None => {
                    self.columns.push(k.clone());
                    self.index.insert(k.clone(), self.columns.len() - 1);
                    values.push(f64::NAN);
                    self.columns.len() - 1
                }
            };
            values[i] = v;
        }
        self.rows.push(values);
    }

    #[allow(clippy::len_without_is_empty)]
    pub fn len(&self) -> usize {
        self.rows.len()
    }

    /// Column names, sorted.
    pub fn columns_sorted(&self) -> Vec<&str> {
        let mut c: Vec<&str> = self.columns.iter().map(String::as_str).collect();
        c.sort_unstable();
        c
    }

    /// The value of `key` in row `i` (NaN when absent).
    pub fn get(&self, i: usize, key: &str) -> f64 {
        match (self.rows.get(i), self.index.get(key)) {
            (Some(r), Some(&c)) => r.get(c).copied().unwrap_or(f64::NAN),
            _ => f64::NAN,
        }
    }

    /// (x, y) of every row where both columns are finite.
    pub fn points(&self, x: &str, y: &str) -> Vec<(f64, f64)> {
        let (Some(&cx), Some(&cy)) = (self.index.get(x), self.index.get(y)) else {
            return Vec::new();
        };
        self.rows
            .iter()
            .filter_map(|r| Some((*r.get(cx)?, *r.get(cy)?)))
            .filter(|(a, b)| a.is_finite() && b.is_finite())
            .collect()
    }

    /// The last row as a map (absent columns left out).
    pub fn last(&self) -> MetricsRow {
        let Some(r) = self.rows.last() else {
            return MetricsRow::new();
        };
        self.columns
            .iter()
            .zip(r)
            .filter(|(_, v)| !v.is_nan())
            .map(|(k, v)| (k.clone(), *v))
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn row(kv: &[(&str, f64)]) -> MetricsRow {
        kv.iter().map(|(k, v)| (k.to_string(), *v)).collect()
    }

    #[test]
    fn rows_with_different_columns_round_trip() {
        let mut t = MetricsTable::default();
        t.push(&row(&[("update", 1.0), ("global_step", 10.0)]));
        t.push(&row(&[
            ("update", 2.0),
            ("global_step", 20.0),
            ("eval/x", 0.5),
        ]));
        t.push(&row(&[("global_step", 30.0), ("update", 3.0)]));
        assert_eq!(t.len(), 3);
        assert_eq!(t.columns_sorted(), vec!["eval/x", "global_step", "update"]);
        assert!(t.get(0, "eval/x").is_nan());
        assert_eq!(t.get(1, "eval/x"), 0.5);
        assert_eq!(t.points("global_step", "eval/x"), vec![(20.0, 0.5)]);
        assert_eq!(t.last(), row(&[("update", 3.0), ("global_step", 30.0)]));
        assert!(t.get(9, "update").is_nan() && t.get(0, "nope").is_nan());
    }
}
