//! `Scenario`: one resolved configuration with its radio world and RSRP source, the pairs its
//! episodes are drawn from, and the radio queries on NumPy arrays (spec/radio.md).

use crate::arrays::{Real, view2};
use crate::errors::{runtime_error, value_error};
use dupac_actor::pairs::Pair;
use dupac_common::config::{Association, Config};
use dupac_common::geometry::Point;
use dupac_common::ids::SiteId;
use dupac_learner::checkpoint::load_policy;
use dupac_radio::class::{RsrpClass, RsrpThresholds};
use dupac_radio::coverage::{Server, compute_slice};
use dupac_radio::world::RadioWorld;
use dupac_scenario::pairs::{guide_sets_cached, held_out_pairs, make_pool};
use dupac_scenario::planners::{Planners, unguided};
use dupac_scenario::world::{SharedRsrp, world_and_cache};
use numpy::ndarray::{Array1, Array2};
use numpy::{AllowTypeChange, IntoPyArray, PyArrayMethods};
use pyo3::prelude::*;
use pyo3::types::PyDict;
use rayon::prelude::*;
use std::path::PathBuf;
use std::sync::{Arc, OnceLock};

/// Which pairs an episode is drawn from.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Split {
    /// The training pool (`train.pool_size` pairs drawn with `train.seed`).
    Train,
    /// The held-out evaluation pairs (`pairs.eval_file`).
    Eval,
}

impl Split {
    pub(crate) fn parse(s: &str) -> PyResult<Split> {
        match s {
            "train" => Ok(Split::Train),
            "eval" => Ok(Split::Eval),
            other => Err(value_error(format!(
                "split {other:?}: expected \"train\" (the training pool) or \"eval\" (the held-out pairs)"
            ))),
        }
    }

    /// The shadow-fading realisations the split's episodes fly in: training's for the pool,
    /// the validation's for the held-out pairs (as `dupac fly` and `dupac eval` fly them).
    pub(crate) fn field(self) -> dupac_radio::channel::FieldSplit {
        match self {
            Split::Train => dupac_radio::channel::FieldSplit::Train,
            Split::Eval => dupac_radio::channel::FieldSplit::Eval,
        }
    }
}

/// The resolved configuration, the radio world and its RSRP source, and the pairs (planned on
/// first use, guided as the configuration's episodes are).
pub(crate) struct Shared {
    pub cfg: Config,
    pub world: Arc<RadioWorld>,
    pub rsrp: SharedRsrp,
    pool: OnceLock<Arc<Vec<Pair>>>,
    eval: OnceLock<Arc<Vec<Pair>>>,
}

impl Shared {
    /// The pairs of `split`, drawn (training pool) or read (held-out file, written when missing)
    /// and guided on first use.
    pub(crate) fn pairs(&self, split: Split) -> PyResult<Arc<Vec<Pair>>> {
        let cell = match split {
            Split::Train => &self.pool,
            Split::Eval => &self.eval,
        };
        if let Some(p) = cell.get() {
            return Ok(p.clone());
        }
        let un = unguided(&self.cfg);
        let planners = Planners::new(&un, &[], &self.world, &self.rsrp, false);
        let mut pairs = match split {
            Split::Train => make_pool(&un, &planners, true),
            Split::Eval => held_out_pairs(&un, &planners, true),
        }
        .map_err(runtime_error)?;
        drop(planners);
        guide_sets_cached(&self.cfg, &self.world, &self.rsrp, &mut [&mut pairs], true)
            .map_err(runtime_error)?;
        let _ = cell.set(Arc::new(pairs));
        Ok(cell.get().expect("set above").clone())
    }
}

/// A DUPAC scenario: the configuration (`dupac config` prints every key), the city and its
/// sites, the RSRP source (the cache of `cache.path`, built on first use, or the exact model with
/// `env.radio_mode = "exact"`) and the pairs. Built once; environments share it.
#[pyclass(module = "dupac._dupac", frozen)]
pub struct Scenario {
    pub(crate) shared: Arc<Shared>,
}

/// Parses a point array `(N, 3)` in metres, refusing non-finite values.
pub(crate) fn points(a: &Real<'_, f64>, what: &str) -> PyResult<Vec<Point>> {
    let v = view2(a, what, Some(3))?;
    v.rows()
        .into_iter()
        .enumerate()
        .map(|(i, r)| {
            let p = Point::new(r[0], r[1], r[2]);
            if p.iter().all(|x| x.is_finite()) {
                Ok(p)
            } else {
                Err(value_error(format!("points[{i}] = {r} is not finite")))
            }
        })
        .collect()
}

fn class_code(c: RsrpClass) -> i8 {
    c.index() as i8
}

#[pymethods]
impl Scenario {
    /// Resolves the configuration (`config`: a TOML file, else the defaults; each of `set` an
    /// `a.b=v` override as `dupac --set` takes it), applies `association` (`"learned"` or
    /// `"a3"`) and, with `policy`, the observation that policy was trained with (its file
    /// records it), then builds the world and opens (or builds) the RSRP cache. The GIL is
    /// released while it works.
    #[new]
    #[pyo3(signature = (config=None, set=Vec::new(), association=None, policy=None))]
    fn new(
        py: Python<'_>,
        config: Option<PathBuf>,
        set: Vec<String>,
        association: Option<String>,
        policy: Option<PathBuf>,
    ) -> PyResult<Scenario> {
        let mut cfg = Config::load(config.as_deref(), &set).map_err(value_error)?;
        if let Some(a) = association {
            cfg.env.association = match a.as_str() {
                "learned" => Association::Learned,
                "a3" => Association::A3,
                other => {
                    return Err(value_error(format!(
                        "association {other:?}: expected \"learned\" (DUPAC) or \"a3\" (the base method)"
                    )));
                }
            };
        }
        if let Some(path) = policy {
            let p = load_policy(&path).map_err(value_error)?;
            cfg.env.association = if p.n_sites > 0 {
                Association::Learned
            } else {
                Association::A3
            };
            cfg = p
                .configure(&cfg)
                .map_err(|e| value_error(format!("{}: {e}", path.display())))?;
        }
        let (world, rsrp) = py
            .detach(|| world_and_cache(&cfg, true))
            .map_err(runtime_error)?;
        Ok(Scenario {
            shared: Arc::new(Shared {
                cfg,
                world,
                rsrp,
                pool: OnceLock::new(),
                eval: OnceLock::new(),
            }),
        })
    }

    /// The resolved configuration as TOML (every key, as `dupac config` prints it).
    fn config_toml(&self) -> String {
        self.shared.cfg.to_toml_string()
    }

    /// The city's name.
    #[getter]
    fn city(&self) -> String {
        self.shared.world.city.name.clone()
    }

    /// M, the number of sites.
    #[getter]
    fn num_sites(&self) -> usize {
        self.shared.world.num_sites()
    }

    /// `"learned"` (DUPAC: the policy chooses the site) or `"a3"` (the base method).
    #[getter]
    fn association(&self) -> &'static str {
        match self.shared.cfg.env.association {
            Association::Learned => "learned",
            Association::A3 => "a3",
            Association::BestRsrp => "best_rsrp",
            Association::Predictive => "predictive",
        }
    }

    /// The flight area `(x_min, y_min, x_max, y_max)` in metres (local ENU) and the altitude band
    /// `(z_min, z_max)` in metres above ground.
    fn bounds_m(&self) -> ((f64, f64, f64, f64), (f64, f64)) {
        let a = self.shared.world.city.area_m;
        let env = &self.shared.cfg.env;
        (
            (a.min_m[0], a.min_m[1], a.max_m[0], a.max_m[1]),
            (env.z_min_m, env.z_max_m),
        )
    }

    /// The sites: `name` (list), `position_m` (M, 3; z = antenna height above ground),
    /// `tx_power_dbm` (M,), `electrical_tilt_deg` (M,), `boresights_deg` (list of lists, CCW
    /// from east), `kind` (list: the TR 36.777 scenario, `"uma"` or `"umi"`, as `dupac radio link`
    /// takes it).
    fn sites<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let sites = &self.shared.world.sites;
        let d = PyDict::new(py);
        let pos = Array2::from_shape_fn((sites.len(), 3), |(i, k)| sites[i].position_m[k]);
        d.set_item(
            "name",
            sites.iter().map(|s| s.name.clone()).collect::<Vec<_>>(),
        )?;
        d.set_item("position_m", pos.into_pyarray(py))?;
        d.set_item(
            "tx_power_dbm",
            Array1::from_iter(sites.iter().map(|s| s.tx_power_dbm)).into_pyarray(py),
        )?;
        d.set_item(
            "electrical_tilt_deg",
            Array1::from_iter(sites.iter().map(|s| s.electrical_tilt_deg)).into_pyarray(py),
        )?;
        d.set_item(
            "boresights_deg",
            sites
                .iter()
                .map(|s| s.boresights_deg.clone())
                .collect::<Vec<_>>(),
        )?;
        d.set_item(
            "kind",
            sites
                .iter()
                .map(|s| format!("{:?}", s.kind.scenario()).to_lowercase())
                .collect::<Vec<_>>(),
        )?;
        Ok(d)
    }

    /// RSRP (dBm) of every site at each point: `points` (N, 3) in metres → (N, M). From the
    /// scenario's RSRP source (the cache, interpolated), or with `exact=True` from the 3GPP model
    /// itself (a ray per site for line of sight). Runs on every core, the GIL released.
    #[pyo3(signature = (points, exact=false))]
    fn rsrp_dbm<'py>(
        &self,
        py: Python<'py>,
        points: Real<'py, f64>,
        exact: bool,
    ) -> PyResult<Bound<'py, numpy::PyArray2<f64>>> {
        let pts = self::points(&points, "points")?;
        let rows = pts.len();
        let m = self.shared.world.num_sites();
        let sh = self.shared.clone();
        let out = py.detach(move || {
            let mut out = vec![0.0; pts.len() * m];
            out.par_chunks_mut(m.max(1))
                .zip(pts.par_iter())
                .for_each(|(row, p)| {
                    if exact {
                        sh.world.rsrp_all_dbm(*p, row)
                    } else {
                        sh.rsrp.rsrp_all_dbm(*p, row)
                    }
                });
            out
        });
        let a = Array2::from_shape_vec((rows, m), out).map_err(value_error)?;
        Ok(a.into_pyarray(py))
    }

    /// Geometric line of sight (a ray against the building mesh) from every site to each point:
    /// `points` (N, 3) in metres → (N, M) bool.
    fn los<'py>(
        &self,
        py: Python<'py>,
        points: Real<'py, f64>,
    ) -> PyResult<Bound<'py, numpy::PyArray2<bool>>> {
        let pts = self::points(&points, "points")?;
        let rows = pts.len();
        let m = self.shared.world.num_sites();
        let sh = self.shared.clone();
        let out = py.detach(move || {
            let mut out = vec![false; pts.len() * m];
            out.par_chunks_mut(m.max(1))
                .zip(pts.par_iter())
                .for_each(|(row, p)| {
                    for (j, o) in row.iter_mut().enumerate() {
                        *o = sh.world.los(SiteId(j as u16), *p);
                    }
                });
            out
        });
        let a = Array2::from_shape_vec((rows, m), out).map_err(value_error)?;
        Ok(a.into_pyarray(py))
    }

    /// The best (strongest) site at each point and its RSRP: `points` (N, 3) in metres →
    /// (`site` (N,) int64, `rsrp_dbm` (N,) float64), from the RSRP source or, `exact=True`, the
    /// model.
    #[pyo3(signature = (points, exact=false))]
    #[allow(clippy::type_complexity)]
    fn best_site<'py>(
        &self,
        py: Python<'py>,
        points: Real<'py, f64>,
        exact: bool,
    ) -> PyResult<(
        Bound<'py, numpy::PyArray1<i64>>,
        Bound<'py, numpy::PyArray1<f64>>,
    )> {
        let all = self.rsrp_dbm(py, points, exact)?;
        let all = all.readonly();
        let v = all.as_array();
        let mut site = Array1::<i64>::zeros(v.nrows());
        let mut best = Array1::<f64>::from_elem(v.nrows(), f64::NEG_INFINITY);
        for (i, row) in v.rows().into_iter().enumerate() {
            for (j, &r) in row.iter().enumerate() {
                if r > best[i] {
                    best[i] = r;
                    site[i] = j as i64;
                }
            }
        }
        Ok((site.into_pyarray(py), best.into_pyarray(py)))
    }

    /// The RSRP class of each value (spec/radio.md §3, `radio.excellent_dbm` and
    /// `radio.poor_dbm`): 0 excellent, 1 mediocre, 2 poor (NaN is poor); any shape, int8.
    fn rsrp_class<'py>(
        &self,
        py: Python<'py>,
        rsrp_dbm: numpy::PyArrayLikeDyn<'py, f64, AllowTypeChange>,
    ) -> Bound<'py, numpy::PyArrayDyn<i8>> {
        let t = RsrpThresholds::from_config(&self.shared.cfg.radio);
        rsrp_dbm
            .as_array()
            .map(|&r| class_code(t.classify(r)))
            .into_pyarray(py)
    }

    /// The best-server coverage map at `altitude_m` above ground over the flight area, square
    /// cells of `resolution_m` (paper Fig. 2(b)): a dict of `rsrp_dbm` (ny, nx) float32 (NaN inside
    /// buildings), `serving` (ny, nx) int32 (−1 inside buildings), `los` (ny, nx) bool, and the
    /// grid's `x0_m`, `y0_m` (south-west corner), `resolution_m`; row 0 is the southmost.
    #[pyo3(signature = (altitude_m, resolution_m=5.0))]
    fn coverage<'py>(
        &self,
        py: Python<'py>,
        altitude_m: f64,
        resolution_m: f64,
    ) -> PyResult<Bound<'py, PyDict>> {
        if !(resolution_m.is_finite() && resolution_m >= 0.5) {
            return Err(value_error(format!(
                "resolution_m = {resolution_m}: expected a finite cell size of at least 0.5 m"
            )));
        }
        if !altitude_m.is_finite() {
            return Err(value_error(format!(
                "altitude_m = {altitude_m} is not finite"
            )));
        }
        let sh = self.shared.clone();
        let s = py.detach(move || {
            compute_slice(
                &sh.world,
                Server::Best,
                None,
                sh.world.city.area_m,
                altitude_m,
                resolution_m,
                &|_| {},
            )
        });
        let d = PyDict::new(py);
        let shape = (s.ny, s.nx);
        d.set_item(
            "rsrp_dbm",
            Array2::from_shape_vec(shape, s.rsrp_dbm)
                .map_err(value_error)?
                .into_pyarray(py),
        )?;
        d.set_item(
            "serving",
            Array2::from_shape_vec(
                shape,
                s.serving
                    .iter()
                    .map(|x| x.map_or(-1, |id| i32::from(id.0)))
                    .collect(),
            )
            .map_err(value_error)?
            .into_pyarray(py),
        )?;
        d.set_item(
            "los",
            Array2::from_shape_vec(shape, s.los)
                .map_err(value_error)?
                .into_pyarray(py),
        )?;
        d.set_item("x0_m", s.x0_m)?;
        d.set_item("y0_m", s.y0_m)?;
        d.set_item("resolution_m", s.resolution_m)?;
        d.set_item("altitude_m", s.altitude_m)?;
        Ok(d)
    }

    /// The pairs of `split` (`"train"`: the training pool; `"eval"`: the held-out pairs of
    /// `pairs.eval_file`, written when missing) as a dict of arrays: `id` (N,) uint64,
    /// `source_m` and `destination_m` (N, 3), `shortest_m` and `straight_m` (N,) (the shortest
    /// flyable path and the straight line, m), `bin_m` (N,) (the evaluation bin, NaN for training
    /// pairs). Planned on first use (the guide paths through the host's guide cache).
    #[pyo3(signature = (split="eval"))]
    fn pairs<'py>(&self, py: Python<'py>, split: &str) -> PyResult<Bound<'py, PyDict>> {
        let split = Split::parse(split)?;
        let sh = self.shared.clone();
        let pairs = py.detach(move || sh.pairs(split))?;
        let d = PyDict::new(py);
        let n = pairs.len();
        d.set_item(
            "id",
            Array1::from_iter(pairs.iter().map(|p| p.id)).into_pyarray(py),
        )?;
        d.set_item(
            "source_m",
            Array2::from_shape_fn((n, 3), |(i, k)| pairs[i].source_m[k]).into_pyarray(py),
        )?;
        d.set_item(
            "destination_m",
            Array2::from_shape_fn((n, 3), |(i, k)| pairs[i].destination_m[k]).into_pyarray(py),
        )?;
        d.set_item(
            "shortest_m",
            Array1::from_iter(pairs.iter().map(|p| p.shortest_m)).into_pyarray(py),
        )?;
        d.set_item(
            "straight_m",
            Array1::from_iter(pairs.iter().map(|p| p.straight_m)).into_pyarray(py),
        )?;
        d.set_item(
            "bin_m",
            Array1::from_iter(pairs.iter().map(|p| p.bin_m.unwrap_or(f64::NAN))).into_pyarray(py),
        )?;
        Ok(d)
    }

    /// A scenario is immutable: a copy is the scenario itself (Gymnasium copies the keyword
    /// arguments of a registered environment).
    fn __copy__(slf: Py<Self>) -> Py<Self> {
        slf
    }

    fn __deepcopy__(slf: Py<Self>, _memo: &Bound<'_, PyAny>) -> Py<Self> {
        slf
    }

    fn __repr__(&self) -> String {
        format!(
            "Scenario(city={:?}, sites={}, association={:?})",
            self.city(),
            self.num_sites(),
            self.association()
        )
    }
}

/// The default configuration as TOML: every key with its default value (`dupac config`).
#[pyfunction]
pub fn default_config_toml() -> String {
    Config::default().to_toml_string()
}
