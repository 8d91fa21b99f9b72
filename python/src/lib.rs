//! `dupac._dupac`: the Rust core of the `dupac` Python package (python/dupac/): a scenario (the
//! configuration, the radio world and its RSRP source, the pairs), the UAV environment one at a
//! time and N at a time, the planners, and trained policies. The Python modules add Gymnasium's spaces and
//! conventions on top (python/dupac/gym.py).
//!
//! Every Rust error reaches Python as an exception whose message is the error's own text
//! (`ValueError` for bad input, `RuntimeError` otherwise); nothing here panics on user input.

mod arrays;
mod env;
mod env_core;
mod errors;
mod planner;
mod policy;
mod scenario;
mod threads;
mod vec_env;

use pyo3::prelude::*;

/// The Python module `dupac._dupac`.
#[pymodule]
fn _dupac(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    m.add_class::<scenario::Scenario>()?;
    m.add_class::<env::Env>()?;
    m.add_class::<vec_env::VecEnv>()?;
    m.add_class::<policy::Policy>()?;
    m.add_class::<planner::Planner>()?;
    m.add_function(wrap_pyfunction!(planner::fly_path, m)?)?;
    m.add_function(wrap_pyfunction!(policy::fly, m)?)?;
    m.add_function(wrap_pyfunction!(scenario::default_config_toml, m)?)?;
    Ok(())
}
