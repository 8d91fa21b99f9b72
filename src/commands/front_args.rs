//! The options `dupac tune-a3` and `dupac eval` share: A3's grid of settings ([`A3GridArgs`]),
//! and `dupac eval`'s fronts on the same flights ([`FrontArgs`]).

use clap::Args;
use dupac_eval::a3_setting::A3Grid;

/// A3's settings tried: every offset × hysteresis × time-to-trigger × filter coefficient
/// (TS 36.331 values; a value it cannot signal is refused naming its flag).
#[derive(Args, Debug, Clone, Default)]
pub struct A3GridArgs {
    /// a3-Offset values (dB; TS 36.331: −15…15 in 0.5 dB steps; space- or comma-separated).
    /// Default 0, 1, …, 15 (with hysteresis 0: A3's entering margin, offset + hysteresis, from 0
    /// to 15 dB).
    #[arg(long, value_name = "DB", num_args = 1.., value_delimiter = ',', allow_negative_numbers = true)]
    pub offset_db: Vec<f64>,
    /// Hysteresis values (dB; TS 36.331: 0…15 in 0.5 dB steps). Default 0.
    #[arg(long, value_name = "DB", num_args = 1.., value_delimiter = ',', allow_negative_numbers = true)]
    pub hysteresis_db: Vec<f64>,
    /// timeToTrigger values (ms; TS 36.331: 0, 40, 64, 80, 100, 128, 160, 256, 320, 480, 512,
    /// 640, 1024, 1280, 2560, 5120). Default 0, 80, 160, 320, 640, 1280.
    #[arg(long, value_name = "MS", num_args = 1.., value_delimiter = ',', allow_negative_numbers = true)]
    pub ttt_ms: Vec<f64>,
    /// A3's own layer-3 filter coefficient k (`radio.a3.l3_filter_k`; TS 36.331: 0…9, 11, 13,
    /// 15, 17, 19), or `none`: A3 compares what the UAV holds. Default 0, 4, 8.
    #[arg(long, value_name = "K|none", num_args = 1.., value_delimiter = ',', value_parser = parse_filter_k)]
    pub l3_filter_k: Vec<FilterK>,
}

/// A `--l3-filter-k` value: a coefficient, or none (A3 compares what the UAV holds).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FilterK(pub Option<u32>);

fn parse_filter_k(s: &str) -> Result<FilterK, String> {
    match s {
        "none" => Ok(FilterK(None)),
        _ => s
            .parse()
            .map(|k| FilterK(Some(k)))
            .map_err(|_| format!("{s}: expected a filter coefficient k (0…19) or none")),
    }
}

impl A3GridArgs {
    /// The grid: each flag's values, or the default's ([`A3Grid::default`]).
    pub fn grid(&self) -> A3Grid {
        let d = A3Grid::default();
        let or = |v: &Vec<f64>, d: Vec<f64>| if v.is_empty() { d } else { v.clone() };
        A3Grid {
            offsets_db: or(&self.offset_db, d.offsets_db),
            hysteresis_db: or(&self.hysteresis_db, d.hysteresis_db),
            ttt_ms: or(&self.ttt_ms, d.ttt_ms),
            l3_filter_k: if self.l3_filter_k.is_empty() {
                d.l3_filter_k
            } else {
                self.l3_filter_k.iter().map(|k| k.0).collect()
            },
        }
    }
}

/// `dupac eval`'s fronts on the same flights (docs/results.md "How the fronts are measured").
#[derive(Args, Debug, Clone, Default)]
pub struct FrontArgs {
    /// A3's front on the same flights: re-fly every learned-site policy's moves and every
    /// planner's A3 path with each A3 setting of the grid (the flags below, by default the
    /// `dupac tune-a3` grid: 288 settings) into `OUT/records/front/` (each flight flown once and
    /// re-associated by every setting); the report adds `front.csv`, `fronts.png` and each policy
    /// against A3 at its own handover rate (`LABEL+a3_matched`, `matched.md`).
    #[arg(long)]
    pub a3_front: bool,
    #[command(flatten)]
    pub grid: A3GridArgs,
    /// The hindsight association's front: re-fly every learned-site policy's moves with the
    /// hindsight association (perfect foresight of the true field, a bound) at each of these
    /// costs (dB·steps per handover, no minimum stay; comma-separated).
    #[arg(long, value_name = "C,…", value_delimiter = ',')]
    pub hindsight_front: Vec<f64>,
    /// The predictive association's front: re-fly every learned-site policy's moves with the
    /// predictive association at each of these costs (`env.predictive.handover_cost_db_m`, dB·m
    /// per handover; comma-separated).
    #[arg(long, value_name = "C,…", value_delimiter = ',')]
    pub predictive_front: Vec<f64>,
}

impl FrontArgs {
    /// A3's grid of `--a3-front`; its flags without `--a3-front` are refused (they would set
    /// nothing).
    pub fn a3_grid(&self) -> anyhow::Result<A3Grid> {
        let g = &self.grid;
        let given = !(g.offset_db.is_empty()
            && g.hysteresis_db.is_empty()
            && g.ttt_ms.is_empty()
            && g.l3_filter_k.is_empty());
        if given && !self.a3_front {
            anyhow::bail!(
                "--offset-db, --hysteresis-db, --ttt-ms and --l3-filter-k set A3's front: give --a3-front"
            );
        }
        Ok(g.grid())
    }
}
