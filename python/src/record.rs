//! The library's records (frame statistics, quality, RD points) as Python
//! dicts, field by field from their serde form: a field the library adds
//! reaches Python without a line here. A figure that was not measured
//! (NaN in the record) is left out of the dict.

use pyo3::prelude::*;
use pyo3::types::{PyDict, PyList};
use serde::Serialize;
use serde_json::Value;

use crate::arrays::value_error;

/// `record` as a dict.
pub fn to_dict<'py, T: Serialize>(py: Python<'py>, record: &T) -> PyResult<Bound<'py, PyDict>> {
    match serde_json::to_value(record).map_err(|e| value_error(e.to_string()))? {
        Value::Object(fields) => {
            let d = PyDict::new(py);
            for (k, v) in fields {
                if !v.is_null() {
                    d.set_item(k, to_py(py, v)?)?;
                }
            }
            Ok(d)
        }
        other => Err(value_error(format!("not a record: {other}"))),
    }
}

fn to_py(py: Python<'_>, v: Value) -> PyResult<Bound<'_, PyAny>> {
    Ok(match v {
        Value::Null => py.None().into_bound(py),
        Value::Bool(b) => b.into_pyobject(py)?.to_owned().into_any(),
        Value::Number(n) => match (n.as_u64(), n.as_i64()) {
            (Some(u), _) => u.into_pyobject(py)?.into_any(),
            (None, Some(i)) => i.into_pyobject(py)?.into_any(),
            _ => n.as_f64().unwrap_or(f64::NAN).into_pyobject(py)?.into_any(),
        },
        Value::String(s) => s.into_pyobject(py)?.into_any(),
        Value::Array(items) => {
            let list = PyList::empty(py);
            for item in items {
                list.append(to_py(py, item)?)?;
            }
            list.into_any()
        }
        Value::Object(_) => to_dict(py, &v)?.into_any(),
    })
}
