//! How a Rust error reaches Python: an exception whose message is the error's own text,
//! `ValueError` for bad input and `RuntimeError` otherwise.

use pyo3::PyErr;

/// A `ValueError` carrying `e`'s message and the chain of its causes (bad input).
pub(crate) fn value_error(e: impl std::fmt::Display) -> PyErr {
    pyo3::exceptions::PyValueError::new_err(e.to_string())
}

/// A `RuntimeError` carrying `e`'s message (a failure that is not the caller's input).
pub(crate) fn runtime_error(e: impl std::fmt::Display) -> PyErr {
    pyo3::exceptions::PyRuntimeError::new_err(e.to_string())
}
