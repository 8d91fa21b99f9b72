//! Array arguments as users pass them: any array-like of real numbers (lists, tuples, any integer
//! or float dtype), converted as `numpy.asarray` converts it ([`Real`]); the shape is then
//! checked here, with errors naming the argument and the expected shape.

use crate::errors::value_error;
use numpy::ndarray::{ArrayView1, ArrayView2, Ix1, Ix2};
use numpy::{AllowTypeChange, Element, PyArrayLikeDyn};
use pyo3::prelude::*;

/// An array argument of element type `T`, converted from any real dtype or array-like.
pub(crate) type Real<'py, T> = PyArrayLikeDyn<'py, T, AllowTypeChange>;

/// The shape of `a` as given.
fn v_shape<T: Element>(a: &Real<'_, T>) -> Vec<usize> {
    a.as_array().shape().to_vec()
}

fn shape_error(what: &str, want: &str, got: &[usize]) -> PyErr {
    let got = match got {
        [n] => format!("({n},)"),
        dims => format!(
            "({})",
            dims.iter()
                .map(usize::to_string)
                .collect::<Vec<_>>()
                .join(", ")
        ),
    };
    value_error(format!(
        "{what}: expected an array of shape {want}, got shape {got}"
    ))
}

/// `a` as a vector, of `len` values when given.
pub(crate) fn view1<'a, T: Element>(
    a: &'a Real<'_, T>,
    what: &str,
    len: Option<usize>,
) -> PyResult<ArrayView1<'a, T>> {
    let v = a.as_array();
    let want = || len.map_or("(N,)".to_string(), |n| format!("({n},)"));
    match v.into_dimensionality::<Ix1>() {
        Ok(v) if len.is_none_or(|n| v.len() == n) => Ok(v),
        _ => Err(shape_error(what, &want(), &v_shape(a))),
    }
}

/// `a` as a matrix, of `cols` columns when given.
pub(crate) fn view2<'a, T: Element>(
    a: &'a Real<'_, T>,
    what: &str,
    cols: Option<usize>,
) -> PyResult<ArrayView2<'a, T>> {
    let v = a.as_array();
    let want = || cols.map_or("(N, M)".to_string(), |m| format!("(N, {m})"));
    match v.into_dimensionality::<Ix2>() {
        Ok(v) if cols.is_none_or(|m| v.ncols() == m) => Ok(v),
        _ => Err(shape_error(what, &want(), &v_shape(a))),
    }
}
