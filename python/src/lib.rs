//! `ipa_sysid._core`: the Python bindings of ipa-sysid (PyO3, numpy). Thin: every computation is a call
//! into the libraries `sysid-core`, `sysid`, `ipa`, `control` and `sysid-io`; this crate converts
//! arguments and results and maps errors to Python exceptions with the command line's messages
//! ([`sysid_core::SysidError::render_flags`]).
//!
//! The Python package `ipa_sysid` (python/ipa_sysid) re-exports everything defined here.

use std::path::PathBuf;

use clap::ValueEnum;
use numpy::{
    Complex64, IntoPyArray, PyArray1, PyArray2, PyReadonlyArray1, PyReadonlyArray2,
    PyUntypedArrayMethods,
};
use pyo3::exceptions::{
    PyArithmeticError, PyImportError, PyKeyboardInterrupt, PyMemoryError, PyOSError,
    PyRuntimeError, PyTypeError, PyValueError,
};
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyList};

use sysid::data::{Dataset, Signals};
use sysid::{IdentifyOptions, Model, Setting, SysidError};
use sysid_summary::IdentifyReport;

mod text;

/// Upper bound on the number of parameters of a stand-alone [`Rls`] (P has n² entries).
const MAX_RLS_PARAMS: usize = 1000;

/// Default run length of `control` with a fixed set-point, s (as `ipa-sysid control`).
const DEFAULT_FIXED_DURATION_S: f64 = 10.0;

// ---------------------------------------------------------------------------------------------------
// Errors: input errors are ValueError, numerical failures ArithmeticError, file-system errors OSError.

/// The Python keyword of a command-line flag: `--max-iterations` -> `max_iterations` (each part of
/// `--setpoint/--profile`); Python errors name the argument the caller wrote, not the flag.
fn keyword(flag: &str) -> String {
    flag.split('/')
        .map(|f| f.trim().trim_start_matches("--").replace('-', "_"))
        .collect::<Vec<_>>()
        .join("/")
}

/// The flags whose Python argument is the flag's [`keyword`] (`--rls-form` is `rls_form`): named in free
/// text (an `IpaError::Config`, an RLS failure's advice) by the command line's words, said here by the
/// Python argument's (fix34 leftover: `--input`, `--samples`, `--ts`, `--rls-form`, `--p0` reached
/// Python users).
const PYTHON_ARGUMENTS: [&str; 19] = [
    "--input",
    "--samples",
    "--ts",
    "--amplitude",
    "--plant",
    "--plant-config",
    "--seed",
    "--rls-form",
    "--p0",
    "--forgetting",
    "--windup",
    "--max-trace",
    "--method",
    "--na",
    "--nb",
    "--nk",
    "--passes",
    "--max-iterations",
    "--iv-stages",
];

/// `msg` with each flag of [`PYTHON_ARGUMENTS`] (a whole flag: `--plant` is not the start of
/// `--plant-config`) replaced by its Python argument ([`keyword`]); other text as it is.
fn python_words(msg: &str) -> String {
    let mut out = String::with_capacity(msg.len());
    let mut rest = msg;
    while let Some(at) = rest.find("--") {
        out.push_str(&rest[..at]);
        let tail = &rest[at..];
        let len = 2 + tail[2..]
            .find(|c: char| !(c.is_ascii_alphanumeric() || c == '-'))
            .unwrap_or(tail.len() - 2);
        let flag = &tail[..len];
        if PYTHON_ARGUMENTS.contains(&flag) {
            out.push_str(&keyword(flag));
        } else {
            out.push_str(flag);
        }
        rest = &tail[len..];
    }
    out.push_str(rest);
    out
}

/// A library error as the Python exception of its kind, with the command line's message naming the
/// Python keyword where the command line names its flag.
fn sysid_err(e: SysidError) -> PyErr {
    let msg = python_words(&e.render(&|s| keyword(s.flag())));
    match e {
        SysidError::Numerical(_) => PyArithmeticError::new_err(msg),
        SysidError::Io { .. } => PyOSError::new_err(msg),
        // Stopped by `compute`'s signal watch, which raises the handler's exception first; this is
        // only what a stop without one would say.
        SysidError::Cancelled => PyKeyboardInterrupt::new_err(msg),
        _ => PyValueError::new_err(msg),
    }
}

/// An error of the plant library.
fn ipa_err(e: ipa::IpaError) -> PyErr {
    match e {
        ipa::IpaError::Sysid(s) => sysid_err(s),
        ipa::IpaError::Numerical(_) => PyArithmeticError::new_err(e.to_string()),
        ipa::IpaError::Config(_) | ipa::IpaError::Setting { .. } => {
            PyValueError::new_err(python_words(&e.render(&|s| keyword(s.flag()))))
        }
    }
}

/// An error of the control library.
fn control_err(e: ::control::ControlError) -> PyErr {
    match e {
        ::control::ControlError::Numerical(_) => PyArithmeticError::new_err(e.to_string()),
        ::control::ControlError::Io { .. } => PyOSError::new_err(e.to_string()),
        // As `sysid_err`: only what a stop without a signal handler's exception would say.
        ::control::ControlError::Cancelled => PyKeyboardInterrupt::new_err(e.to_string()),
        _ => PyValueError::new_err(e.render(&|s| keyword(s.flag()))),
    }
}

/// The controller file of `control(..., controller=...)`: `controller` is the JSON text of one (a `str`
/// starting with `{`), or its path (a `str` or an `os.PathLike`), read as the command line reads
/// `--controller` (`ControllerFile::read_file`). A file that cannot be read is a `ValueError` naming
/// `controller` (a folder, a device, a FIFO, more than 1 MiB, not UTF-8), or an `OSError` (a missing file).
fn controller_file(controller: &Bound<'_, PyAny>) -> PyResult<::control::ControllerFile> {
    if let Ok(text) = controller.extract::<&str>() {
        if text.trim_start().starts_with('{') {
            return ::control::ControllerFile::parse_file(text, "controller").map_err(control_err);
        }
    }
    let path: PathBuf = controller.extract().map_err(|_| {
        PyTypeError::new_err(format!(
            "controller: expected tune()'s result, its \"controller\" dict, a controller file's JSON text \
             or its path, not {}",
            controller.get_type()
        ))
    })?;
    ::control::ControllerFile::read_file(&path).map_err(|e| match e {
        ::control::ControlError::Io { path, source } => io_err(&path, &source),
        other => PyValueError::new_err(format!("cannot read controller: {other}")),
    })
}

/// A tuned controller `t` refused (a `ValueError` naming `controller`) unless it was tuned for the
/// sampling period `ts` of the `what` (`plant`, `model`) it is to run with, as `--controller` is.
fn check_controller_ts(t: &::control::ControllerSettings, ts: f64, what: &str) -> PyResult<()> {
    if (t.ts_s - ts).abs() > 1e-9 * ts {
        return Err(setting_err(
            "--controller",
            t.ts_s,
            &format!(
                "a controller for the {what}'s Ts = {} s",
                sysid_core::format::Shortest(ts)
            ),
        ));
    }
    Ok(())
}

/// The operating system's refusal `source` of `path` as an `OSError` with its errno (so that Python
/// makes it a `FileNotFoundError`, `PermissionError`, ...) and the path. An error that `tempfile`
/// wrapped with the path of the temporary file beside an output (`... at path ".../.ipa-sysid-*.tmp"`,
/// its errno kept only as a kind) is reported against `path`, the one the caller gave (audit s19 H-4: a
/// missing folder named the temporary file).
fn io_err(path: &std::path::Path, source: &std::io::Error) -> PyErr {
    let errno = source
        .raw_os_error()
        .or_else(|| errno_of_kind(source.kind()));
    let text = source.to_string();
    let text = text.split(" at path \"").next().unwrap_or(&text);
    match errno {
        Some(n) => {
            let text = text
                .strip_suffix(&format!(" (os error {n})"))
                .unwrap_or(text)
                .to_string();
            PyOSError::new_err((n, text, path.display().to_string()))
        }
        None => PyOSError::new_err(format!("{}: {text}", path.display())),
    }
}

/// The errno of an error that carries only its kind (`tempfile` wraps the error of creating a temporary
/// file with that file's path and keeps only the kind), from Python's `errno` module.
fn errno_of_kind(kind: std::io::ErrorKind) -> Option<i32> {
    use std::io::ErrorKind as K;
    let name = match kind {
        K::NotFound => "ENOENT",
        K::PermissionDenied => "EACCES",
        K::AlreadyExists => "EEXIST",
        K::NotADirectory => "ENOTDIR",
        K::IsADirectory => "EISDIR",
        K::StorageFull => "ENOSPC",
        K::ReadOnlyFilesystem => "EROFS",
        _ => return None,
    };
    Python::attach(|py| py.import("errno").ok()?.getattr(name).ok()?.extract().ok())
}

/// An output error as the Python exception of its kind: a path refused for what it is (a folder, a
/// socket, a read-only file, a link to nothing) is a `ValueError` naming the argument in the command
/// line's words (`invalid setting path = out: a file name (this is a folder)`); a refusal of the
/// operating system is an `OSError` with its errno and the output's path (so `FileNotFoundError` for a
/// missing folder, naming the output, not the temporary file beside it).
fn output_err(e: sysid_io::OutputError) -> PyErr {
    match &e {
        sysid_io::OutputError::Io { path, source } => io_err(path, source),
        // The command line's `--force` is named `force=True` here (`sysid_io::set_force_word`, at
        // the module's import).
        sysid_io::OutputError::Refused { .. } | sysid_io::OutputError::Occupied { .. } => {
            PyValueError::new_err(e.to_string())
        }
    }
}

/// `resid_lags`: the lags M of the residual analysis, 1 to `sysid::residuals::MAX_LAG` (as
/// `--resid-lags`), of `identify` and `Model.metrics` alike.
fn check_resid_lags(resid_lags: usize) -> PyResult<()> {
    if (1..=sysid::residuals::MAX_LAG).contains(&resid_lags) {
        return Ok(());
    }
    Err(setting_err(
        "resid_lags",
        resid_lags,
        &format!(
            "a whole number of lags in 1..={}",
            sysid::residuals::MAX_LAG
        ),
    ))
}

/// A `ValueError` naming a setting, worded as the library's setting errors.
fn setting_err(name: &'static str, value: impl ToString, expected: &str) -> PyErr {
    sysid_err(SysidError::setting(Setting::Other(name), value, expected))
}

/// A bool given for a number (`y0=True`): Python counts it as 1, the core would run with it. A
/// `TypeError` naming `name`, in the words of the Python wrapper's `_refuse_bools` (audit s23 L-P7).
fn refuse_bool(name: &str, v: &Bound<'_, PyAny>) -> PyResult<()> {
    if v.is_instance_of::<pyo3::types::PyBool>() {
        return Err(PyTypeError::new_err(format!(
            "{name}: expected a number, not the bool {v}"
        )));
    }
    Ok(())
}

/// A real number argument of a method (a bool refused by [`refuse_bool`]; another type a `TypeError`
/// naming `name`, where pyo3 names it only in an exception note).
fn number(name: &str, v: &Bound<'_, PyAny>) -> PyResult<f64> {
    refuse_bool(name, v)?;
    // The conversion's words without its type's name (`y: only 0-dimensional arrays can be converted
    // to Python scalars`), as `whole`'s.
    v.extract::<f64>()
        .map_err(|e| PyTypeError::new_err(format!("{name}: {}", e.value(v.py()))))
}

/// A path argument of a method (`str`, `bytes` or `os.PathLike`, as `os.fsdecode` takes them; audit
/// s23 L-P6: a bytes path was refused while the error for an int said bytes were accepted); another
/// type a `TypeError` naming `name`.
fn path_arg(name: &str, v: &Bound<'_, PyAny>) -> PyResult<PathBuf> {
    let py = v.py();
    let text = py
        .import("os")?
        .getattr("fsdecode")?
        .call1((v,))
        .map_err(|e| {
            if e.is_instance_of::<pyo3::exceptions::PyTypeError>(py) {
                PyTypeError::new_err(format!("{name}: {}", e.value(py)))
            } else {
                e
            }
        })?;
    Ok(PathBuf::from(text.extract::<String>()?))
}

/// A whole number argument of a method (where the module's functions get this from the Python
/// wrapper `_named_ints`): a negative one is a `ValueError` naming `name`, as the functions' are.
fn whole(name: &'static str, v: &Bound<'_, PyAny>) -> PyResult<usize> {
    refuse_bool(name, v)?;
    match v.extract::<i64>() {
        // The words of the Python wrapper's refusal of the core functions' whole numbers
        // (`identify(na=-1)`: `_named_ints`), one wording for `Rls(n=-1)` and `identify(na=-1)`.
        Ok(n) => {
            usize::try_from(n).map_err(|_| setting_err(name, n, "expected a whole number >= 0"))
        }
        // A Python int beyond 64 bits (the conversion alone raises an OverflowError naming none).
        Err(_) if v.is_instance_of::<pyo3::types::PyInt>() => Err(setting_err(
            name,
            v,
            "expected a whole number that fits 64 bits",
        )),
        // The conversion's own words without its type's name (`n: 'float' object cannot be
        // interpreted as an integer`, as `identify(na=2.5)` says).
        Err(e) => Err(PyTypeError::new_err(format!("{name}: {}", e.value(v.py())))),
    }
}

/// Issues each message as an `ipa_sysid.IpaSysidWarning` (the command line's `warning:` lines).
fn warn_all(py: Python<'_>, messages: &[String]) -> PyResult<()> {
    if messages.is_empty() {
        return Ok(());
    }
    let category = py.import("ipa_sysid")?.getattr("IpaSysidWarning")?;
    for m in messages {
        PyErr::warn(
            py,
            &category,
            &std::ffi::CString::new(m.replace('\0', " "))?,
            1,
        )?;
    }
    Ok(())
}

/// One of the command line's value names (`--method rls`, ...) parsed into its enum.
fn choice<T: ValueEnum>(flag: &'static str, value: &str) -> PyResult<T> {
    T::from_str(value, false).map_err(|_| {
        let names: Vec<String> = T::value_variants()
            .iter()
            .filter_map(|v| v.to_possible_value().map(|p| p.get_name().to_string()))
            .collect();
        setting_err(flag, value, &format!("one of {}", names.join(", ")))
    })
}

// ---------------------------------------------------------------------------------------------------
// Conversions.

/// A 1-D float64 copy of `obj` (ndarray, list, pandas Series, anything `numpy.asarray` accepts).
fn floats(obj: &Bound<'_, PyAny>, what: &str) -> PyResult<Vec<f64>> {
    // A masked array's mask says which samples are invalid; its data would be read whole (audit s14
    // L-g): refused unless nothing is masked.
    if obj.hasattr("mask")? {
        let ma = obj.py().import("numpy")?.getattr("ma")?;
        if ma.call_method1("isMaskedArray", (obj,))?.is_truthy()? {
            let masked: usize = ma.call_method1("count_masked", (obj,))?.extract()?;
            if masked > 0 {
                return Err(PyValueError::new_err(format!(
                    "{what}: a masked array with {masked} masked samples; the mask would be ignored: \
                     drop those samples or fill them (numpy.ma.filled) first"
                )));
            }
        }
    }
    if let Ok(a) = obj.extract::<PyReadonlyArray1<'_, f64>>() {
        check_samples(a.len(), what)?;
        return Ok(match a.as_slice() {
            Ok(s) => s.to_vec(),
            Err(_) => a.as_array().to_vec(),
        });
    }
    let arr = as_float_array(obj, what)?;
    if arr.ndim() != 1 {
        return Err(PyValueError::new_err(format!(
            "{what}: expected a 1-D array of numbers, got an array of shape {:?}",
            arr.shape()
        )));
    }
    let a: PyReadonlyArray1<'_, f64> = arr.extract()?;
    check_samples(a.len(), what)?;
    Ok(a.as_array().to_vec())
}

/// Refuses an array of more than [`sysid_core::data::MAX_SAMPLES`] samples, the bound of a record on
/// every surface (the CSV and MAT readers, `simulate_plant`), before the core copies it (audit s22
/// H-B1: `Model.simulate(numpy.zeros(2 * 10**8))` aborted the interpreter on a failed allocation of the
/// core's further full-length copies, which no `except` can catch).
fn check_samples(n: usize, what: &str) -> PyResult<()> {
    let max = sysid_core::data::MAX_SAMPLES;
    if n > max {
        return Err(PyMemoryError::new_err(format!(
            "{what}: {n} samples ({} bytes as float64, and as much again for each copy the computation \
             makes) is more than the {max} samples a record may have (the command line's bound too); \
             pass a slice (u[a:b]) or decimate the record",
            n.saturating_mul(8)
        )));
    }
    Ok(())
}

/// A hint for an array of text `raw` (dtype object, str) whose first cell is a number written with a
/// decimal comma such as '0,01' (a semicolon CSV read by pandas with its defaults; audit s22 L-N5).
fn decimal_comma_hint(raw: &Bound<'_, PyAny>) -> String {
    let first = raw
        .getattr("size")
        .and_then(|n| n.extract::<usize>())
        .ok()
        .filter(|&n| n > 0)
        .and_then(|_| raw.call_method0("ravel").ok())
        .and_then(|flat| flat.get_item(0).ok())
        .and_then(|cell| cell.extract::<String>().ok());
    match first {
        Some(cell) if sysid_core::data::looks_like_decimal_comma(&cell) => format!(
            " (cells are text such as '{}', a number written with a decimal comma: read the file with \
             pandas.read_csv(path, sep=';', decimal=',') or convert the column with \
             .str.replace(',', '.').astype(float))",
            sysid_core::format::visible(&cell)
        ),
        _ => String::new(),
    }
}

/// `numpy.ascontiguousarray(obj, dtype=float64)`, with a message naming the argument on failure.
/// Only real numbers are taken: `None`, a scalar, booleans, complex numbers, text and objects are
/// refused (numpy would make `None` a one-sample NaN array, `True` a 1.0 and drop an imaginary part
/// with only a ComplexWarning; audit s13 L7).
fn as_float_array<'py>(
    obj: &Bound<'py, PyAny>,
    what: &str,
) -> PyResult<Bound<'py, numpy::PyUntypedArray>> {
    let py = obj.py();
    let np = py.import("numpy")?;
    if obj.is_none() {
        return Err(PyValueError::new_err(format!(
            "{what}: expected an array of numbers, got None"
        )));
    }
    if let Ok(raw) = np.call_method1("asarray", (obj,)) {
        let kind: String = raw.getattr("dtype")?.getattr("kind")?.extract()?;
        if !matches!(kind.as_str(), "f" | "i" | "u") {
            let dtype = raw.getattr("dtype")?.str()?.to_string();
            return Err(PyValueError::new_err(format!(
                "{what}: expected an array of real numbers (integers or floats), got dtype {dtype}{}",
                decimal_comma_hint(&raw)
            )));
        }
        let ndim: usize = raw.getattr("ndim")?.extract()?;
        if ndim == 0 {
            return Err(PyValueError::new_err(format!(
                "{what}: expected an array of numbers, got a single number"
            )));
        }
    }
    let kwargs = PyDict::new(py);
    kwargs.set_item("dtype", "float64")?;
    let arr = np
        .call_method("ascontiguousarray", (obj,), Some(&kwargs))
        .map_err(|e| {
            PyValueError::new_err(format!("{what}: expected an array of numbers ({e})"))
        })?;
    Ok(arr.cast_into::<numpy::PyUntypedArray>()?)
}

/// Refuses two pandas objects (Series, DataFrame columns) `u` and `y` whose indexes differ (audit s16
/// L7): a sample is paired with the sample at the same position, never by label, so a reordered or
/// misaligned `y` would be identified against the wrong `u` without a word. Objects without a pandas
/// index (arrays, lists) are paired by position as always.
fn same_index<'py>(u: &Bound<'py, PyAny>, y: &Bound<'py, PyAny>) -> PyResult<()> {
    let index = |o: &Bound<'py, PyAny>| -> Option<Bound<'py, PyAny>> {
        let i = o.getattr("index").ok()?;
        i.hasattr("equals").ok()?.then_some(i)
    };
    let (Some(iu), Some(iy)) = (index(u), index(y)) else {
        return Ok(());
    };
    if iu.call_method1("equals", (&iy,))?.is_truthy()? {
        return Ok(());
    }
    // A label as a user wrote it: `1`, not numpy's `np.int64(1)` (audit s25 L-6); a string label
    // keeps its quotes, so that `'1'` and `1` differ in the message as they do in the index.
    let label = |v: &Bound<'py, PyAny>| -> PyResult<String> {
        if v.is_instance_of::<pyo3::types::PyString>() {
            return Ok(v.repr()?.to_string());
        }
        Ok(v.str()?.to_string())
    };
    let (nu, ny) = (iu.len()?, iy.len()?);
    let first = if nu != ny {
        format!("u's index has {nu} labels, y's {ny}")
    } else {
        let mut at = String::new();
        for k in 0..nu {
            let (a, b) = (iu.get_item(k)?, iy.get_item(k)?);
            if !a.eq(&b)? {
                at = format!(
                    "at position {k} u's index has {} where y's has {}",
                    label(&a)?,
                    label(&b)?
                );
                break;
            }
        }
        at
    };
    Err(PyValueError::new_err(format!(
        "u and y: pandas objects whose indexes differ ({first}); samples are paired by position, not \
         by index label, so they would be misaligned: align them first (y = y.reindex(u.index), or \
         pandas.concat([u, y], axis=1).dropna()) or pass u.to_numpy() and y.to_numpy()"
    )))
}

/// `validation=`: a pair (u_val, y_val) given as a tuple, a list or any other sequence of two arrays
/// (audit s25 L-4: a list was a raw "'list' object is not an instance of 'tuple'"). A 2-D array (a
/// (2, N) ndarray, a DataFrame) is refused in words: which of its rows or columns is u is a guess.
fn record_pair<'py>(
    v: &Bound<'py, PyAny>,
    what: &str,
) -> PyResult<(Bound<'py, PyAny>, Bound<'py, PyAny>)> {
    let expected = "a pair (u_val, y_val) of two arrays, as a tuple or a list";
    let kind = v.get_type().name()?.to_string();
    if v.hasattr("ndim")? && v.getattr("ndim")?.extract::<usize>().is_ok_and(|d| d != 1) {
        let shape = v.getattr("shape")?.str()?.to_string();
        return Err(PyValueError::new_err(format!(
            "{what}: expected {expected}, got a {kind} of shape {shape}: which of its rows or columns \
             is u is not guessed; pass (a[0], a[1]) for an array whose rows are u and y, or \
             (df['u'], df['y']) for a DataFrame"
        )));
    }
    let refused = v.is_instance_of::<pyo3::types::PyString>()
        || v.is_instance_of::<pyo3::types::PyBytes>()
        || v.is_instance_of::<PyDict>()
        || v.hasattr("ndim")?;
    let n = if refused { None } else { v.len().ok() };
    match n {
        Some(2) => Ok((v.get_item(0)?, v.get_item(1)?)),
        Some(n) => Err(PyValueError::new_err(format!(
            "{what}: expected {expected}, got a {kind} of {n} items"
        ))),
        None => Err(PyTypeError::new_err(format!(
            "{what}: expected {expected}, got a {kind}"
        ))),
    }
}

/// A record (u, y) checked by the library (equal lengths, finite values, Ts > 0); two pandas objects
/// must share their index ([`same_index`]), which is then dropped.
fn dataset(u: &Bound<'_, PyAny>, y: &Bound<'_, PyAny>, ts: f64, name: &str) -> PyResult<Dataset> {
    same_index(u, y)?;
    let u = floats(u, "u")?;
    let y = floats(y, "y")?;
    Dataset::new(Signals { u, y }, ts, name).map_err(sysid_err)
}

/// A JSON text as Python objects (`json.loads`).
fn json_loads<'py>(py: Python<'py>, text: &str) -> PyResult<Bound<'py, PyAny>> {
    py.import("json")?.call_method1("loads", (text,))
}

/// Rows of `Rls.update_many` between two runs of Python's signal handlers: 4 096 updates of n = 9
/// parameters take about 0.5 ms at the release build's 8 million updates per second (docs/benchmarks.md),
/// and a run of the handlers with no signal pending is one flag test.
const RLS_SIGNAL_ROWS: usize = 4096;

/// How often the calling thread runs Python's signal handlers while a computation runs ([`compute`]).
const SIGNAL_POLL: std::time::Duration = std::time::Duration::from_millis(50);

/// Stack of the thread a computation runs on ([`compute`]): the usual main thread's 8 MiB.
const WORKER_STACK_BYTES: usize = 8 << 20;

/// Runs the computation `f` with the GIL released (other Python threads run meanwhile) on a thread of
/// its own, while the calling thread runs Python's signal handlers every [`SIGNAL_POLL`]
/// (`py.check_signals()`). When a handler raises (Ctrl-C: `KeyboardInterrupt`; an alarm handler: its own
/// exception), the [`Stop`](sysid::Stop) handed to `f` is requested, `f` ends with
/// `SysidError::Cancelled` at its next poll (each iteration, term, window or evaluation), and that
/// exception is raised: never a result (audit s25 M-P1: the interrupt waited for the whole computation;
/// audit s23 H-P1: it surfaced inside numpy's first array conversion as a `PanicException`). Only the
/// main thread runs signal handlers, so a call from another thread runs to its end (docs/python.md
/// "Threads and Ctrl-C"). A panic in `f` is resumed here (pyo3 raises it as `PanicException`).
fn compute<T: Send>(py: Python<'_>, f: impl Send + FnOnce(&sysid::Stop) -> T) -> PyResult<T> {
    let stop = sysid::Stop::new();
    let mut raised: Option<PyErr> = None;
    let out = py.detach(|| {
        let job = std::sync::Mutex::new(Some(f));
        // Takes the computation out of `job` (once) and runs it.
        let run = || job.lock().ok().and_then(|mut j| j.take()).map(|f| f(&stop));
        let caller = std::thread::current();
        // Set by the worker when `f` has returned (before the thread itself has ended, which
        // `JoinHandle::is_finished` would wait for: a 50 ms park more on every call).
        let done = std::sync::atomic::AtomicBool::new(false);
        let finished = || done.load(std::sync::atomic::Ordering::Acquire);
        std::thread::scope(|s| {
            let spawned = std::thread::Builder::new()
                .name("ipa-sysid".into())
                .stack_size(WORKER_STACK_BYTES)
                .spawn_scoped(s, || {
                    let out = run();
                    done.store(true, std::sync::atomic::Ordering::Release);
                    caller.unpark();
                    out
                });
            let Ok(worker) = spawned else {
                // No thread to be had (a process limit): computed here, the signals taken at its end.
                return run();
            };
            // (`is_finished` too: a panic in `f` ends the thread without setting `done`.)
            while !finished() && !worker.is_finished() {
                std::thread::park_timeout(SIGNAL_POLL);
                if raised.is_none() && !finished() && !worker.is_finished() {
                    if let Err(e) = Python::attach(|py| py.check_signals()) {
                        raised = Some(e);
                        stop.request();
                    }
                }
            }
            match worker.join() {
                Ok(out) => out,
                Err(panic) => std::panic::resume_unwind(panic),
            }
        })
    });
    if let Some(e) = raised {
        return Err(e);
    }
    py.check_signals()?;
    out.ok_or_else(|| PyRuntimeError::new_err("the computation did not run (internal error)"))
}

/// A serialisable value as Python objects, through its JSON form.
fn to_py<'py, T: serde::Serialize>(py: Python<'py>, v: &T) -> PyResult<Bound<'py, PyAny>> {
    let text = serde_json::to_string(v)
        .map_err(|e| PyArithmeticError::new_err(format!("serialising a result: {e}")))?;
    json_loads(py, &text)
}

// ---------------------------------------------------------------------------------------------------
// Model.

/// An identified (or loaded) model: the ARX block A(q) y(k) = B(q) x(k − nk) + c, with x = u for ARX
/// and x = the deadzone f(u) (b_l, b_r in counts, m_l, m_r) for Hammerstein. Ts in s.
#[pyclass(name = "Model", module = "ipa_sysid", frozen)]
#[derive(Clone)]
struct PyModel {
    inner: Model,
}

#[pymethods]
impl PyModel {
    /// "hammerstein" or "arx".
    #[getter]
    fn kind(&self) -> String {
        self.inner.kind().to_string()
    }

    /// A(q) coefficients [a1, ..., a_na] (the leading 1 omitted), as a float64 array.
    #[getter]
    fn a<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        PyArray1::from_slice(py, self.inner.a())
    }

    /// B(q) coefficients [b1, ..., b_nb] of the input (b1 = 1 by normalisation for Hammerstein).
    #[getter]
    fn b<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        PyArray1::from_slice(py, self.inner.b())
    }

    /// na: number of poles.
    #[getter]
    fn na(&self) -> usize {
        self.inner.na()
    }

    /// nb: number of B coefficients.
    #[getter]
    fn nb(&self) -> usize {
        self.inner.nb()
    }

    /// nk: input delay in samples.
    #[getter]
    fn nk(&self) -> usize {
        self.inner.nk()
    }

    /// k0 = max(na, nk + nb − 1): the number of initial outputs a simulation takes as given.
    #[getter]
    fn k0(&self) -> usize {
        self.inner.k0()
    }

    /// Ts: sampling period in s.
    #[getter]
    fn ts(&self) -> f64 {
        self.inner.ts()
    }

    /// c: the constant term of the linear block, or None when the model has none.
    #[getter]
    fn offset(&self) -> Option<f64> {
        self.inner.offset()
    }

    /// The deadzone as a dict {"b_l", "b_r" (counts), "m_l", "m_r"}, or None for an ARX model.
    #[getter]
    fn deadzone<'py>(&self, py: Python<'py>) -> PyResult<Option<Bound<'py, PyAny>>> {
        self.inner.deadzone().map(|d| to_py(py, d)).transpose()
    }

    /// Poles of the linear block (roots of z^na + a1 z^(na−1) + ... + a_na), complex array.
    #[getter]
    fn poles<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<Complex64>> {
        poles_array(py, &self.inner)
    }

    /// True when the model settles: its stability verdict (`stability`) is "settles", every pole
    /// inside the unit circle by more than 1e-5 (an integrator, a pole on the circle and an unstable
    /// model are not stable; the `stable` of `identify --json`).
    #[getter]
    fn stable(&self) -> bool {
        self.inner.stability().settles()
    }

    /// The stability verdict, the one every command reports: "settles" (every pole inside the unit
    /// circle by more than 1e-5), "integrator" (a pole within 1e-5 of z = 1), "on_circle" (a pole
    /// within 1e-5 of the unit circle away from 1) or "unstable" (a pole beyond 1 + 1e-5, or not a
    /// number); the `stability` of `identify --json` and `validate --json`.
    #[getter]
    fn stability(&self) -> &'static str {
        self.inner.stability().name()
    }

    /// The range of the estimation data, in the data's units: {"u": [[min, max] of each input], "y":
    /// [min, max]}, or None for a model saved without one. Outside it the model extrapolates:
    /// `simulate`, `predict` and `metrics` warn (an `IpaSysidWarning`) when an input leaves it by more
    /// than a tenth of its span (the command line's rule). Read-only.
    #[getter]
    fn data_range<'py>(&self, py: Python<'py>) -> PyResult<Option<Bound<'py, PyAny>>> {
        self.inner.data_range().map(|r| to_py(py, r)).transpose()
    }

    /// p: the number of estimated parameters (as in FPE and AIC).
    #[getter]
    fn parameter_count(&self) -> usize {
        self.inner.parameter_count()
    }

    /// Free-run simulation (MATLAB `sim`) of the model driven by `u`: an array of len(u). The first k0
    /// outputs are the initial conditions, taken from `y0`: an array of at least k0 values (only the
    /// first k0 are used, so a measured output record can be passed, exactly as `validate` does), or one
    /// number (the output at rest before the record, e.g. 100.0 mm), or None: zeros, with an
    /// `IpaSysidWarning` saying so.
    #[pyo3(signature = (u, y0=None))]
    fn simulate<'py>(
        &self,
        py: Python<'py>,
        u: &Bound<'py, PyAny>,
        y0: Option<&Bound<'py, PyAny>>,
    ) -> PyResult<Bound<'py, PyArray1<f64>>> {
        let u = floats(u, "u")?;
        // What `simulate --plant model:FILE` warns of, less the model file's doubts (said once, by
        // `load_model`): an unstable model, an integrator, a pole on the unit circle.
        let doubts: Vec<String> = sysid_summary::simulation::stability_words(&self.inner)
            .into_iter()
            .collect();
        warn_all(py, &doubts)?;
        let k0 = self.inner.k0();
        let mut y = vec![0.0; u.len()];
        let y0 = match y0 {
            None => {
                if k0 > 0 {
                    warn_all(
                        py,
                        &[format!(
                            "Model.simulate without y0 starts from y = 0 for the first k0 = {k0} samples; \
                             a record that starts elsewhere (e.g. at 100 mm) then fits badly: pass y0 = the \
                             record's output (its first k0 values are used) or its start position"
                        )],
                    )?;
                }
                None
            }
            Some(obj) => match obj.extract::<f64>() {
                // One number: the output at rest there before the record (each of the first k0 samples).
                Ok(_) => Some(vec![number("y0", obj)?; k0]),
                Err(_) => Some(floats(obj, "y0")?),
            },
        };
        if let Some(y0) = y0 {
            if y0.len() < k0.min(u.len()) {
                return Err(setting_err(
                    "y0",
                    format!("{} value(s)", y0.len()),
                    &format!("at least k0 = {k0} initial output(s), one number, or None for zeros"),
                ));
            }
            let k = k0.min(u.len());
            y[..k].copy_from_slice(&y0[..k]);
        }
        let data =
            Dataset::new(Signals { u, y }, self.inner.ts(), "simulate").map_err(sysid_err)?;
        let out = self
            .inner
            .simulate(&data.input_signals(), data.y())
            .map_err(sysid_err)?;
        warn_all(py, &extrapolation_warnings(&self.inner, data.u(), &out))?;
        Ok(out.into_pyarray(py))
    }

    /// k-step-ahead prediction (MATLAB `predict(m, data, k)`) from measured `u` and `y` (equal lengths):
    /// ŷ(k) uses measured outputs up to k − horizon. horizon = 1 is the one-step prediction; entries
    /// k < k0 are copies of `y`, except for a model that predicts by simulation (output error,
    /// Wiener): its initial outputs estimated to fit the record, as `validate`'s `y_pred`.
    /// (`horizon` None: 1; taken as any object so that a bool, a negative or a too-large number is
    /// refused naming it.)
    #[pyo3(signature = (u, y, horizon=None))]
    fn predict<'py>(
        &self,
        py: Python<'py>,
        u: &Bound<'py, PyAny>,
        y: &Bound<'py, PyAny>,
        horizon: Option<&Bound<'py, PyAny>>,
    ) -> PyResult<Bound<'py, PyArray1<f64>>> {
        let horizon = horizon.map_or(Ok(1), |h| whole("horizon", h))?;
        let data = dataset(u, y, self.inner.ts(), "predict")?;
        let k0 = self.inner.k0();
        if data.len() <= k0 {
            // Nothing would be predicted: the first k0 outputs are the measured initial ones (audit s31
            // L-3: the data came back unchanged, without a word).
            return Err(PyValueError::new_err(format!(
                "predict: {} samples are not enough to predict with a model with k0 = {k0} (the first \
                 k0 outputs are its measured initial ones)",
                data.len()
            )));
        }
        // validate's y_pred, one definition (audit s31 M-3: for an output-error or Wiener model this
        // returned the simulation from the measured initial outputs while validate's y_pred and this
        // model's metrics()["fit_pred_percent"] start from the estimated ones).
        let out = sysid_core::metrics::model_output(&self.inner, &[data.u()], data.y(), horizon)
            .map_err(sysid_err)?
            .y_pred;
        warn_all(py, &extrapolation_warnings(&self.inner, data.u(), &out))?;
        Ok(out.into_pyarray(py))
    }

    /// Validation metrics on a record (the `validate` command): fit % (simulation and 1-step), RMSE,
    /// loss V (paper eq. 14), FPE (eq. 15), AIC (equation error), MATLAB's LossFcn, FPE and normalised
    /// AIC of the model's own prediction errors (`loss_fcn`, `fpe_matlab`, `aic_matlab`), N, p, as a
    /// dict like the CLI JSON's. `score_from` = K (`validate --score-from K`): every figure over the
    /// samples k >= max(K, k0) only (0-based; e.g. 50 for a benchmark's state-initialisation window;
    /// the simulations are the same, only the rows scored change); the dict's "score_from" is that
    /// first scored sample. A K that reaches the record's end, or leaves no more samples than the
    /// model's parameters, raises a ValueError naming score_from. The dict's "warnings" are those of
    /// `validate` (one assembly, `sysid_summary::ValidationReport`: the model's own doubts, an unstable
    /// model, a negative or flattered fit, a fit far below the estimation fit, the residuals correlated
    /// with past inputs, the record beyond the model's data) and "residuals" its residual analysis with
    /// `resid_lags` lags (`validate --resid-lags`; audit s33 M-2: the input–residual warning was missing).
    #[pyo3(signature = (u, y, name="data", score_from=None, resid_lags=25))]
    fn metrics<'py>(
        &self,
        py: Python<'py>,
        u: &Bound<'py, PyAny>,
        y: &Bound<'py, PyAny>,
        name: &str,
        score_from: Option<&Bound<'py, PyAny>>,
        resid_lags: usize,
    ) -> PyResult<Bound<'py, PyAny>> {
        let score_from = score_from.map_or(Ok(0), |k| whole("score_from", k))?;
        check_resid_lags(resid_lags)?;
        let data = dataset(u, y, self.inner.ts(), name)?;
        let report = sysid_summary::ValidationReport::assemble_scored_from(
            &self.inner,
            &data,
            resid_lags,
            score_from,
        )
        .map_err(sysid_err)?;
        // The model file's own doubts first (said by `load_model` already), then validate's; all in the
        // dict's "warnings" (audit s13 M4), each of this result's own an IpaSysidWarning.
        let warnings: Vec<String> =
            sysid::model_file::load_warnings_besides(&self.inner, &report.warnings)
                .into_iter()
                .map(|w| format!("model: {w}"))
                .chain(report.warnings.iter().cloned())
                .collect();
        warn_all(py, &result_warnings(&self.inner, &warnings))?;
        let out = to_py(py, &report.metrics.validation)?;
        out.set_item("warnings", warnings)?;
        out.set_item("residuals", to_py(py, &report.residuals.validation)?)?;
        out.set_item(
            "score_from",
            sysid::metrics::first_scored(self.inner.k0(), score_from),
        )?;
        Ok(out)
    }

    /// The model file text (the command line's `--save-model` format, JSON).
    fn to_json(&self) -> PyResult<String> {
        sysid::model_file::to_json(&self.inner).map_err(sysid_err)
    }

    /// A model from its model-file text (what `to_json()` returns and `identify --save-model` writes),
    /// without a file: `Model.from_json(m.to_json())` is `m`, bit for bit. Checked as `load_model`
    /// checks a file, and warns of the file's own doubts as `load_model` does. A NARX model file is
    /// refused (it is `identify(..., structure="narx")`'s `NarxFit.model_file()`).
    /// `text` may be `bytes` (a file's content read in binary), decoded as UTF-8.
    #[staticmethod]
    fn from_json(py: Python<'_>, text: &Bound<'_, PyAny>) -> PyResult<PyModel> {
        let text: String = if let Ok(b) = text.cast::<pyo3::types::PyBytes>() {
            String::from_utf8(b.as_bytes().to_vec()).map_err(|e| {
                PyValueError::new_err(format!("text: the model text is not UTF-8 ({e})"))
            })?
        } else {
            text.extract::<String>().map_err(|_| {
                PyTypeError::new_err(format!(
                    "text: expected the model file's text (a str, or bytes in UTF-8), got a {}",
                    text.get_type()
                        .name()
                        .map_or("?".to_string(), |n| n.to_string())
                ))
            })?
        };
        let inner = parse_model_text(&text)?;
        warn_all(py, &sysid::model_file::load_warnings(&inner))?;
        Ok(PyModel { inner })
    }

    /// Pickling, `copy.copy` and `copy.deepcopy` (a model sent to a multiprocessing or Dask worker):
    /// the model-file text, read back without warning again (audit s23 L-P5).
    fn __reduce__<'py>(&self, py: Python<'py>) -> PyResult<(Bound<'py, PyAny>, (String,))> {
        let restore = py.import("ipa_sysid._core")?.getattr("_model_from_json")?;
        Ok((restore, (self.to_json()?,)))
    }

    /// Writes the model file (as `identify --save-model`), atomically; readable by `load_model` and by
    /// `ipa-sysid validate --model` / `--plant model:FILE`. An existing file is replaced only when it is a
    /// model file (or empty), and a symbolic link is refused, unless `force=True` (the command line's
    /// `--force`).
    #[pyo3(signature = (path, force = false))]
    fn save(&self, py: Python<'_>, path: &Bound<'_, PyAny>, force: bool) -> PyResult<()> {
        let path = path_arg("path", path)?;
        let text = self.to_json()?;
        write_output(py, path, text.as_bytes(), "path", force)
    }

    /// The linear block as a python-control `TransferFunction` in z (discrete, dt = Ts):
    /// G(z) = (b1 z^-nk + ... + b_nb z^-(nk+nb-1)) / (1 + a1 z^-1 + ... + a_na z^-na). The constant term
    /// is not part of it. For a Hammerstein model (b1 = 1, the gain in the deadzone's slopes) `side` =
    /// "right" or "left" multiplies G by m_r or m_l: the gain from u beyond b_r or below b_l; without
    /// `side` such a model's G is returned with an `IpaSysidWarning` saying so (audit s20 M-2: a Bode
    /// plot of G alone is 20 log10(1/m) dB off the gain from u). Raises ImportError when python-control
    /// is not installed.
    #[pyo3(signature = (side=None))]
    fn to_control<'py>(&self, py: Python<'py>, side: Option<&str>) -> PyResult<Bound<'py, PyAny>> {
        // A bad `side` is refused before python-control is looked for: the caller's mistake is said
        // whether or not the package is installed (and G's warning only with a G to go with it).
        let mut warning = None;
        let slope = match (self.inner.deadzone(), side) {
            (_, Some(s)) if s != "right" && s != "left" => {
                return Err(PyValueError::new_err(format!(
                    "invalid setting side = {s:?}: expected \"right\", \"left\" or None"
                )))
            }
            (None, Some(s)) => {
                return Err(PyValueError::new_err(format!(
                    "invalid setting side = {s:?}: the model has no deadzone (side is for a Hammerstein model)"
                )))
            }
            (Some(d), Some("right")) => d.m_r,
            (Some(d), Some(_)) => d.m_l,
            (Some(d), None) => {
                warning = Some(format!(
                    "Model.to_control(): the linear block G = B/A with b1 = 1, from the deadzone's output; \
                     the gain from u is m_r G (m_r = {}, {:+.2} dB) beyond b_r and m_l G (m_l = {}, {:+.2} dB) \
                     below b_l: pass side=\"right\" or side=\"left\" for it",
                    d.m_r,
                    20.0 * d.m_r.abs().log10(),
                    d.m_l,
                    20.0 * d.m_l.abs().log10()
                ));
                1.0
            }
            (None, None) => 1.0,
        };
        let ct = py.import("control").map_err(|e| {
            PyImportError::new_err(format!(
                "Model.to_control needs python-control: pip install control ({e})"
            ))
        })?;
        warn_all(py, warning.as_slice())?;
        let (mut num, den) = self.transfer_polynomials();
        for v in &mut num {
            *v *= slope;
        }
        ct.getattr("TransferFunction")?
            .call1((num, den, self.inner.ts()))
    }

    /// Frequency response (gain dB, phase deg on a log grid up to the Nyquist frequency), DC gain,
    /// poles, zeros, impulse and step response of the linear block, and with `kp` (and `ki`) the gain
    /// and phase margins of that PI loop, or with `controller` (what `control(controller=...)` takes:
    /// tune()'s result, its "controller" dict, a controller file's JSON text or path) those of the
    /// tuned controller (Kp, Ki, Kd, Tf) as tune reported them, as a dict: the same function and keys
    /// as `ipa-sysid response --json` (`control::response::response`). For a Hammerstein model
    /// `"gain"` says in words which gain the figures use and `"sides"` gives m_r, m_l with their dB
    /// offsets. `"dc_gain"` is None when the step settles at no level, `"dc_gain_note"` saying why
    /// ("infinite (integrator)", "not defined (unstable)"); `"warnings"` (each also an
    /// `IpaSysidWarning`) gives the stability verdict in identify's words, the model file's doubts and
    /// figures that are not finite.
    #[pyo3(signature = (points=None, f_min_hz=None, samples=None, kp=None, ki=None, controller=None),
        text_signature = "($self, points=20, f_min_hz=None, samples=20, kp=None, ki=None, controller=None)")]
    #[allow(clippy::too_many_arguments)] // Python keyword arguments
    fn frequency_response<'py>(
        &self,
        py: Python<'py>,
        points: Option<&Bound<'py, PyAny>>,
        f_min_hz: Option<&Bound<'py, PyAny>>,
        samples: Option<&Bound<'py, PyAny>>,
        kp: Option<&Bound<'py, PyAny>>,
        ki: Option<&Bound<'py, PyAny>>,
        controller: Option<&Bound<'py, PyAny>>,
    ) -> PyResult<Bound<'py, PyAny>> {
        // Taken as any object so that a bool is refused by name (audit s23 L-P7: points=True ran as 1).
        let points = points.map_or(Ok(20), |v| whole("points", v))?;
        let samples = samples.map_or(Ok(20), |v| whole("samples", v))?;
        let f_min_hz = f_min_hz.map(|v| number("f_min_hz", v)).transpose()?;
        let kp = kp.map(|v| number("kp", v)).transpose()?;
        let ki = ki.map(|v| number("ki", v)).transpose()?;
        if !(2..=100_000).contains(&points) {
            return Err(PyValueError::new_err(format!(
                "invalid setting points = {points}: expected 2..=100000"
            )));
        }
        if !(1..=1_000_000).contains(&samples) {
            return Err(PyValueError::new_err(format!(
                "invalid setting samples = {samples}: expected 1..=1000000"
            )));
        }
        for (name, v) in [("f_min_hz", f_min_hz), ("kp", kp), ("ki", ki)] {
            if v.is_some_and(|v| !v.is_finite()) {
                return Err(PyValueError::new_err(format!(
                    "invalid setting {name} = {}: expected a finite number",
                    v.unwrap_or(f64::NAN)
                )));
            }
        }
        if ki.is_some() && kp.is_none() && controller.is_none() {
            return Err(PyValueError::new_err(
                "invalid setting ki: give kp as well (the PI controller of the margins)",
            ));
        }
        let ts = self.inner.ts();
        let tuned = match (controller, kp.is_some() || ki.is_some()) {
            (Some(_), true) => {
                return Err(PyValueError::new_err(
                    "invalid setting controller: not together with kp/ki (the tuned controller has its own gains)",
                ))
            }
            (Some(c), false) => {
                // tune()'s result and its "controller" dict become a file's text as for control().
                let text = py
                    .import("ipa_sysid")?
                    .getattr("_controller_text")?
                    .call1((c,))?;
                let file = controller_file(&text)?;
                check_controller_ts(&file.controller, ts, "model")?;
                Some(file)
            }
            (None, _) => None,
        };
        // A tuned controller that did not meet its specification says so, as `control` does.
        let not_met = tuned.as_ref().and_then(|f| f.provenance_warning());
        // The controller's file when it was given by its path (for the "controller" entry).
        let controller_path = controller.and_then(|c| c.extract::<String>().ok());
        let tuned_for_model = tuned.clone();
        let controller = match tuned {
            Some(f) => Some(f.controller),
            None => kp.map(|kp| ::control::ControllerSettings::pi(ts, kp, ki.unwrap_or(0.0))),
        };
        let settings = ::control::response::ResponseSettings {
            points,
            f_min_hz,
            samples,
            controller,
        };
        let mut r = ::control::response::response(&self.inner, &settings).map_err(control_err)?;
        r.warnings
            .extend(not_met.map(|w| format!("controller: {w}")));
        if let Some(f) = &tuned_for_model {
            r.warnings.extend(
                ::control::trust::controller_model_warnings(f, &self.inner, None)
                    .into_iter()
                    .map(|w| format!("controller: {w}")),
            );
        }
        // The dict's "warnings" (what `response` prints as `warning:` lines), each of this result's
        // own an IpaSysidWarning (the model file's were said by `load_model`).
        warn_all(py, &result_warnings(&self.inner, &r.warnings))?;
        let out = to_py(py, &r)?;
        // The controller of the margins as numbers, as `response --json` gives it (audit s22 L-B7).
        if let Some(c) = &controller {
            out.set_item(
                "controller",
                to_py(
                    py,
                    &::control::response::controller_json(c, controller_path.as_deref()),
                )?,
            )?;
        }
        Ok(out)
    }

    /// Numerator and denominator of the linear block in descending powers of z (equal lengths n + 1,
    /// n = max(na, nk + nb − 1)), as `to_control` uses them.
    fn transfer_polynomials(&self) -> (Vec<f64>, Vec<f64>) {
        let m = &self.inner;
        let n = m.k0().max(1);
        let mut den = vec![0.0; n + 1];
        den[0] = 1.0;
        den[1..=m.na()].copy_from_slice(m.a());
        let mut num = vec![0.0; n + 1];
        for (j, bj) in m.b().iter().enumerate() {
            num[m.nk() + j] = *bj;
        }
        (num, den)
    }

    fn __repr__(&self) -> String {
        let m = &self.inner;
        format!(
            "Model(kind={:?}, na={}, nb={}, nk={}, ts={}, a={:?}, b={:?}, deadzone={})",
            m.kind().to_string(),
            m.na(),
            m.nb(),
            m.nk(),
            m.ts(),
            m.a(),
            m.b(),
            m.deadzone().map_or("None".to_string(), |d| format!(
                "{{b_l={}, b_r={}, m_l={}, m_r={}}}",
                d.b_l, d.b_r, d.m_l, d.m_r
            ))
        )
    }

    /// The model as equations with units (`print(model)`); `repr(model)` gives the numbers in full.
    fn __str__(&self) -> String {
        text::equations(&self.inner)
    }

    fn __eq__(&self, other: &Self) -> bool {
        self.inner == other.inner
    }
}

/// The poles of a model as a complex array, in the order of the `identify --json` `poles`.
/// What `simulate --plant model:` warns of after a run (audit s16 M5): the input `u` or the
/// simulated / predicted output `y` beyond the model's estimation data by more than a tenth of its
/// span (`sysid_summary::input_outside_data`, `output_outside_data`).
fn extrapolation_warnings(model: &Model, u: &[f64], y: &[f64]) -> Vec<String> {
    sysid_summary::input_outside_data(model, u)
        .into_iter()
        .chain(sysid_summary::output_outside_data(model, y))
        .collect()
}

fn poles_array<'py>(py: Python<'py>, m: &Model) -> Bound<'py, PyArray1<Complex64>> {
    let p: Vec<Complex64> = m
        .poles()
        .iter()
        .map(|z| Complex64::new(z.re, z.im))
        .collect();
    p.into_pyarray(py)
}

/// Reads a model file written by `ipa-sysid identify --save-model` (or an `identify --json` summary, or
/// `Model.save`). What the file holds that a reader must be told about is said here, once per load,
/// as `IpaSysidWarning`s (`sysid::model_file::load_warnings`, what the command line's `validate`,
/// `simulate`, `response` say prefixed `model: `): an input or output map that is not physical, and the
/// warnings of the identification that wrote the file (model file version 3: "this model's
/// identification on X warned: …", audit s20 M-3). The model's methods keep them in their results'
/// `warnings` but do not warn of them again (session 22: `Model.frequency_response` and
/// `Model.metrics` repeated them on every call).
#[pyfunction]
fn load_model(py: Python<'_>, path: &Bound<'_, PyAny>) -> PyResult<PyModel> {
    let path = path_arg("path", path)?;
    let inner = sysid::model_file::read_model(&path).map_err(sysid_err)?;
    warn_all(py, &sysid::model_file::load_warnings(&inner))?;
    Ok(PyModel { inner })
}

/// The model file's own doubts as a result lists them (`model: ` and the words of
/// `sysid::model_file::load_warnings`, which `load_model` warns of).
fn file_warnings(model: &Model) -> Vec<String> {
    sysid::model_file::load_warnings(model)
        .into_iter()
        .map(|w| format!("model: {w}"))
        .collect()
}

/// The warnings of a result on `model` to warn of on each call: `warnings` less the model file's own
/// ([`file_warnings`], said once by `load_model`).
fn result_warnings(model: &Model, warnings: &[String]) -> Vec<String> {
    let file = file_warnings(model);
    warnings
        .iter()
        .filter(|w| !file.contains(w))
        .cloned()
        .collect()
}

/// Model-file text to a model; errors name "the model text" as a file would be named.
fn parse_model_text(text: &str) -> PyResult<Model> {
    sysid::model_file::parse_model(text.as_bytes(), "the model text").map_err(sysid_err)
}

/// Unpickling a `Model` (its `__reduce__`): `Model.from_json` without its warnings, which were given
/// when the pickled model was made or loaded.
#[pyfunction]
fn _model_from_json(text: &str) -> PyResult<PyModel> {
    Ok(PyModel {
        inner: parse_model_text(text)?,
    })
}

/// The paper's "actual" Hammerstein model (Table III): the `paper` plant.
#[pyfunction]
fn paper_model() -> PyModel {
    PyModel {
        inner: Model::paper(),
    }
}

// ---------------------------------------------------------------------------------------------------
// identify.

/// The result of `identify`: the model, its poles and stability, the metrics, the estimator's remarks,
/// and `to_dict()`, the document `ipa-sysid identify --json` writes.
#[pyclass(name = "Fit", module = "ipa_sysid", frozen)]
struct PyFit {
    report: IdentifyReport,
    json: String,
}

#[pymethods]
impl PyFit {
    /// The fitted model.
    #[getter]
    fn model(&self) -> PyModel {
        PyModel {
            inner: self.report.model.clone(),
        }
    }

    /// Poles of the linear block (largest modulus first), complex array.
    #[getter]
    fn poles<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<Complex64>> {
        let p: Vec<Complex64> = self
            .report
            .poles
            .iter()
            .map(|z| Complex64::new(z.re, z.im))
            .collect();
        p.into_pyarray(py)
    }

    /// True when every pole lies strictly inside the unit circle.
    #[getter]
    fn stable(&self) -> bool {
        self.report.stable
    }

    /// {"estimation": {...}, "validation": {...}} (validation only when given): the `metrics` of
    /// `identify --json` (fit_sim_percent, fit_pred_percent, rmse_sim, rmse_pred, loss, fpe, aic,
    /// loss_fcn, fpe_matlab, aic_matlab, n, p).
    #[getter]
    fn metrics<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        to_py(py, &self.report.metrics)
    }

    /// Parameters with standard deviations: a list of {"name", "value", "std"} (std None when fixed or
    /// not computable), with "fixed" naming why when the tool held the parameter at its value instead of
    /// estimating it ("normalisation": b1 = 1; "one-sided input": a dropped deadzone branch).
    #[getter]
    fn parameters<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        to_py(py, &self.report.parameters)
    }

    /// The estimates by name, `{"b_r": 30.97, ...}` (`"u2.b_r"` when the model has several inputs): a
    /// mapping for `fit.params["b_r"]`; the standard deviations are in `parameters` and
    /// `parameters_frame()`.
    #[getter]
    fn params<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let out = PyDict::new(py);
        for p in &self.report.parameters {
            out.set_item(param_key(p), p.value)?;
        }
        Ok(out)
    }

    /// The parameters as a pandas DataFrame indexed by name (columns `value`, `std`, `fixed` (why the
    /// tool held it, or None), and `input` when the model has several inputs); needs pandas.
    fn parameters_frame<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        let pd = py.import("pandas").map_err(|e| {
            PyImportError::new_err(format!(
                "Fit.parameters_frame needs pandas: pip install pandas ({e})"
            ))
        })?;
        let several = self.report.parameters.iter().any(|p| p.input.is_some());
        let cols = PyDict::new(py);
        let names: Vec<String> = self.report.parameters.iter().map(param_key).collect();
        cols.set_item(
            "value",
            self.report
                .parameters
                .iter()
                .map(|p| p.value)
                .collect::<Vec<_>>(),
        )?;
        cols.set_item(
            "std",
            self.report
                .parameters
                .iter()
                .map(|p| p.std.unwrap_or(f64::NAN))
                .collect::<Vec<_>>(),
        )?;
        cols.set_item(
            "fixed",
            self.report
                .parameters
                .iter()
                .map(|p| p.fixed.clone())
                .collect::<Vec<_>>(),
        )?;
        if several {
            cols.set_item(
                "input",
                self.report
                    .parameters
                    .iter()
                    .map(|p| p.input.clone().unwrap_or_default())
                    .collect::<Vec<_>>(),
            )?;
        }
        let kwargs = PyDict::new(py);
        kwargs.set_item("index", pd.getattr("Index")?.call1((names,))?)?;
        let frame = pd.getattr("DataFrame")?.call((cols,), Some(&kwargs))?;
        frame.getattr("index")?.setattr("name", "name")?;
        Ok(frame)
    }

    /// How the model was estimated: the `estimation` object of `identify --json` (method, iterations,
    /// converged, noise_variance, note, ...).
    #[getter]
    fn estimation<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        to_py(py, &self.report.estimation)
    }

    /// Reasons not to trust the estimate, in words: the `warnings` of `identify --json` when the
    /// library reports them, otherwise the estimator's note (if any) as a one-element list.
    #[getter]
    fn warnings<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        let d = self.to_dict(py)?;
        if let Some(w) = d.cast::<PyDict>()?.get_item("warnings")? {
            return Ok(w);
        }
        let notes: Vec<String> = self.report.estimation.note.iter().cloned().collect();
        Ok(PyList::new(py, notes)?.into_any())
    }

    /// The residual analysis of `identify --json` (`residuals`), or None when the library does not
    /// report one.
    #[getter]
    fn residuals<'py>(&self, py: Python<'py>) -> PyResult<Option<Bound<'py, PyAny>>> {
        let d = self.to_dict(py)?;
        d.cast::<PyDict>()?.get_item("residuals")
    }

    /// The whole `ipa-sysid identify --json` document as Python objects (dicts, lists, floats).
    fn to_dict<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        json_loads(py, &self.json)
    }

    /// The `ipa-sysid identify --json` document as text.
    fn to_json(&self) -> String {
        self.json.clone()
    }

    /// Pickling and copying: the report (read back bit for bit) and the JSON document. A report that
    /// would not read back equal (a NaN figure, written as JSON null) is refused in words, naming what
    /// does pickle (audit s23 L-P5).
    fn __reduce__<'py>(&self, py: Python<'py>) -> PyResult<(Bound<'py, PyAny>, (String, String))> {
        let report = serde_json::to_string(&self.report)
            .map_err(|e| PyTypeError::new_err(format!("cannot pickle this Fit: {e}")))?;
        if serde_json::from_str::<IdentifyReport>(&report)
            .ok()
            .as_ref()
            != Some(&self.report)
        {
            return Err(PyTypeError::new_err(
                "cannot pickle this Fit: its report holds a figure (NaN or infinite) that JSON \
                 cannot carry; pickle fit.model and fit.to_json() instead",
            ));
        }
        let restore = py.import("ipa_sysid._core")?.getattr("_fit_restore")?;
        Ok((restore, (report, self.json.clone())))
    }

    /// The simulation fit % on the estimation record (`metrics["estimation"]["fit_sim_percent"]`;
    /// the name the repr shows, audit s14 L-f).
    #[getter]
    fn fit_sim_percent(&self) -> Option<f64> {
        self.report.metrics.estimation.fit_sim_percent
    }

    /// The one-step prediction fit % on the estimation record
    /// (`metrics["estimation"]["fit_pred_percent"]`).
    #[getter]
    fn fit_pred_percent(&self) -> Option<f64> {
        self.report.metrics.estimation.fit_pred_percent
    }

    /// The fit % named by their record (audit s25 L-2: the estimation record's figures were shown
    /// unlabelled also when a validation record was given, whose figure is the one to read).
    fn __repr__(&self) -> String {
        let m = &self.report.metrics;
        fit_repr(
            &format!(
                "Fit(method={:?}, model={:?}, stable={}",
                self.report.estimation.method.to_string(),
                self.report.model.kind().to_string(),
                if self.report.stable { "True" } else { "False" },
            ),
            (m.estimation.fit_sim_percent, m.estimation.fit_pred_percent),
            m.validation
                .as_ref()
                .map(|v| (v.fit_sim_percent, v.fit_pred_percent)),
        )
    }
}

/// The key of a parameter in `Fit.params`: its name, prefixed by its input with several inputs.
fn param_key(p: &sysid::Param) -> String {
    match &p.input {
        Some(input) => format!("{input}.{}", p.name),
        None => p.name.to_string(),
    }
}

/// The command line's `--max-memory GIB`, by the same function, named by its keyword
/// `max_memory_gb` here.
fn memory_budget(max_memory_gb: f64) -> PyResult<sysid::ls::MemoryBudget> {
    sysid::ls::MemoryBudget::from_gib(max_memory_gb).map_err(|e| match e {
        SysidError::Setting { expected, .. } => {
            setting_err("max_memory_gb", max_memory_gb, &expected)
        }
        e => sysid_err(e),
    })
}

/// `control(profile=...)`: the command line's text (`"fixed:MM"`, `"staircase:L1,L2,...@HOLD_S"`,
/// `"file:PATH.csv"`), or an array of (t, r) rows (t in s, strictly increasing; r in mm), which is
/// the `file:` profile's table without the file (audit s25 L-4: a list of rows was a raw "'list'
/// object is not an instance of 'str'").
fn profile_arg(spec: &Bound<'_, PyAny>) -> PyResult<::control::Profile> {
    if let Ok(text) = spec.extract::<String>() {
        return ::control::Profile::parse(&text).map_err(control_err);
    }
    let forms =
        "a string such as \"fixed:50\", \"staircase:20,40@5\" or \"file:PATH.csv\", or an array \
                 of (t, r) rows (t in s, increasing; r in mm)";
    let refused =
        |got: String| PyTypeError::new_err(format!("profile: expected {forms}, got {got}"));
    if spec.is_instance_of::<pyo3::types::PyBytes>() || spec.is_instance_of::<PyDict>() {
        return Err(refused(format!("a {}", spec.get_type().name()?)));
    }
    let np = spec.py().import("numpy")?;
    let rows = np.call_method1("asarray", (spec,)).map_err(|_| {
        refused(format!(
            "a {}",
            spec.get_type().name().map_or("?".into(), |n| n.to_string())
        ))
    })?;
    let kind: String = rows.getattr("dtype")?.getattr("kind")?.extract()?;
    let shape: Vec<usize> = rows.getattr("shape")?.extract()?;
    if !matches!(kind.as_str(), "f" | "i" | "u") || shape.len() != 2 || shape[1] != 2 {
        let dtype = rows.getattr("dtype")?.str()?.to_string();
        return Err(refused(format!(
            "an array of shape {shape:?} and dtype {dtype}"
        )));
    }
    let column = |c: usize| -> PyResult<Vec<f64>> {
        floats(
            &rows.get_item((pyo3::types::PySlice::full(spec.py()), c))?,
            "profile",
        )
    };
    let profile = ::control::Profile::Samples {
        path: PathBuf::from("the profile array"),
        t_s: column(0)?,
        r_mm: column(1)?,
        last_t_at: None,
    };
    profile.validate().map_err(control_err)?;
    Ok(profile)
}

/// The end of `Fit`'s and `NarxFit`'s repr after `head`: the simulation and one-step prediction fit %
/// of the estimation record and, when one was given, of the validation record, each named.
fn fit_repr(
    head: &str,
    estimation: (Option<f64>, Option<f64>),
    validation: Option<(Option<f64>, Option<f64>)>,
) -> String {
    let pair = |(sim, pred): (Option<f64>, Option<f64>)| {
        format!(
            "fit_sim_percent={}, fit_pred_percent={}",
            py_float(sim),
            py_float(pred)
        )
    };
    let validation = validation.map_or(" (no validation record)".to_string(), |v| {
        format!("; validation: {}", pair(v))
    });
    format!("{head}; estimation: {}{validation})", pair(estimation))
}

/// An optional number as Python prints it (`None` when absent).
fn py_float(v: Option<f64>) -> String {
    v.map_or("None".to_string(), |x| format!("{x:?}"))
}

/// Identifies a Hammerstein (deadzone + ARX) or ARX model from the input `u` (counts) and output `y`
/// (mm) sampled every `ts` s, as `ipa-sysid identify` does with the same options; `validation` =
/// (u_val, y_val) adds validation metrics. `name` and `validation_name` name the records in messages
/// (the command line uses the file names). `nonlinearity` ("deadzone" or "linear", the command line's
/// `--nonlinearity`: "linear", "deadzone", "saturation", "deadzone-saturation", "piecewise-linear" with
/// `breakpoints` K, "polynomial" with `degree` D) chooses the input's static nonlinearity instead of
/// `model`; `output_nonlinearity` ("saturation", "piecewise-linear", "polynomial", the command line's
/// `--output-nonlinearity`) adds y = g(v) after the linear block, fitted by output error.
/// `detrend` ("none", "mean", "linear", the command line's `--detrend`) removes the record's operating
/// point before the estimation; the model stores (u0, y0) and puts it back in its simulations.
/// `max_memory_gb` (the command line's `--max-memory`, 4 GiB by default) is the most memory the
/// estimation's matrices may take: more is refused before anything is allocated.
#[pyfunction]
#[pyo3(signature = (u, y, ts, model="hammerstein", method=None, na=3, nb=1, nk=1, forgetting=1.0,
    p0=1e6, offset=false, validation=None, passes=None, max_iterations=100, rls_form="standard",
    windup="none", max_trace=None, iv_stages=10, name="data", validation_name="validation",
    resid_lags=25, fallback=false, nonlinearity=None, breakpoints=None, degree=None,
    output_nonlinearity=None, structure=None, stop="sim", max_terms=30, refine=true, detrend="none",
    max_memory_gb=4.0))]
#[allow(clippy::too_many_arguments)]
fn identify<'py>(
    py: Python<'py>,
    u: &Bound<'_, PyAny>,
    y: &Bound<'_, PyAny>,
    ts: f64,
    model: &str,
    method: Option<&str>,
    na: usize,
    nb: usize,
    nk: usize,
    forgetting: f64,
    p0: f64,
    offset: bool,
    validation: Option<Bound<'_, PyAny>>,
    passes: Option<usize>,
    max_iterations: usize,
    rls_form: &str,
    windup: &str,
    max_trace: Option<f64>,
    iv_stages: usize,
    name: &str,
    validation_name: &str,
    resid_lags: usize,
    fallback: bool,
    nonlinearity: Option<&str>,
    breakpoints: Option<Bound<'_, PyAny>>,
    degree: Option<usize>,
    output_nonlinearity: Option<&str>,
    structure: Option<&str>,
    stop: &str,
    max_terms: usize,
    refine: bool,
    detrend: &str,
    max_memory_gb: f64,
) -> PyResult<Bound<'py, PyAny>> {
    let max_memory = memory_budget(max_memory_gb)?;
    // `structure` is the command line's --structure (`model` its older spelling).
    let model = structure.unwrap_or(model);
    // The command line's --detrend none|mean|linear (audit s18 L-5).
    let detrend: sysid::detrend::Detrend = choice("--detrend", detrend)?;
    // The settings one kind of model uses and the other ignores are refused where they would be
    // ignored, as the command line refuses their flags (`identify::Args::check_flags`): a value other
    // than the default (or, for `method`, any value) counts as given.
    let narx = model == "narx";
    // The defaults of the signature above are the library's (`IdentifyOptions::default`,
    // `NarxSettings::default`): compared with those, not with repeated literals.
    let (d, dn) = (
        IdentifyOptions::default(),
        sysid::narx::NarxSettings::default(),
    );
    let given_estimator = [
        ("method", method.is_some()),
        ("forgetting", forgetting != d.forgetting),
        ("p0", p0 != d.p0),
        ("passes", passes.is_some()),
        ("rls_form", rls_form != "standard"),
        ("windup", windup != "none"),
        ("max_trace", max_trace.is_some()),
        ("iv_stages", iv_stages != d.iv_stages),
        (
            "resid_lags",
            resid_lags != sysid::residuals::DEFAULT_MAX_LAG,
        ),
        ("fallback", fallback),
        ("nonlinearity", nonlinearity.is_some()),
        ("breakpoints", breakpoints.is_some()),
        ("output_nonlinearity", output_nonlinearity.is_some()),
    ];
    let given_narx = [
        ("stop", stop != "sim"),
        ("max_terms", max_terms != dn.max_terms),
        ("refine", refine != dn.refine),
    ];
    let ignored: Vec<&str> = if narx {
        given_estimator.iter()
    } else {
        given_narx.iter()
    }
    .filter(|(_, given)| *given)
    .map(|(name, _)| *name)
    .collect();
    if !ignored.is_empty() {
        let one = ignored.len() == 1;
        let (whose, why) = if narx {
            (
                "the ARX, Hammerstein and Wiener estimators",
                "its terms are chosen by orthogonal least squares (FROLS) and refined on the simulation \
                 error by its own search; refine=False keeps the least-squares ones",
            )
        } else {
            (
                "the polynomial NARX search",
                "they apply only with structure=\"narx\"",
            )
        };
        return Err(PyValueError::new_err(format!(
            "{}: {} of {whose}, which structure=\"{model}\" does not use ({why}); leave {} out",
            ignored.join(", "),
            if one { "a setting" } else { "settings" },
            if one { "it" } else { "them" },
        )));
    }
    check_resid_lags(resid_lags)?;
    let method = method.unwrap_or("rls");
    if narx && detrend != sysid::detrend::Detrend::None {
        return Err(setting_err(
            "detrend",
            detrend,
            "none with structure=\"narx\" (it takes no detrend: offer the constant term with offset=True instead)",
        ));
    }
    if narx {
        let settings = sysid::narx::NarxSettings {
            na,
            nb,
            nk,
            degree: degree.unwrap_or(2),
            constant: offset,
            max_terms,
            stop: choice("--stop", stop)?,
            refine,
            max_iterations: max_iterations.min(200),
            max_memory,
            ..sysid::narx::NarxSettings::default()
        };
        settings.check().map_err(sysid_err)?;
        let data = dataset(u, y, ts, name)?;
        let val = validation
            .map(|v| {
                let (uv, yv) = record_pair(&v, "validation")?;
                dataset(&uv, &yv, ts, validation_name)
            })
            .transpose()?;
        let mut report = compute(
            py,
            |stop| -> Result<sysid_summary::narx::NarxReport, SysidError> {
                let settings = sysid::narx::NarxSettings {
                    cancel: stop.clone(),
                    ..settings.clone()
                };
                let fit = sysid::narx::identify_narx(&data, &settings)?;
                sysid_summary::narx::NarxReport::assemble(fit, &settings, &data, val.as_ref())
            },
        )?
        .map_err(sysid_err)?;
        report.warnings.extend(in_sample(&data, val.as_ref()));
        let json = serde_json::to_string_pretty(&report)
            .map_err(|e| PyValueError::new_err(e.to_string()))?
            + "\n";
        let model_file = sysid::model_file::narx_to_json(&report.model).map_err(sysid_err)?;
        return Ok(Bound::new(py, PyNarxFit { json, model_file })?.into_any());
    }
    // K >= 1, or "auto" (the command line's --breakpoints auto).
    let breakpoints = breakpoints
        .map(|b| match b.extract::<String>() {
            Ok(t) if t == "auto" => Ok(sysid::blocks::AUTO_BREAKPOINTS),
            _ => match b.extract::<usize>() {
                Ok(k) if k >= 1 => Ok(k),
                _ => Err(PyValueError::new_err(
                    "breakpoints: expected a whole number of breakpoints from 1, or \"auto\"",
                )),
            },
        })
        .transpose()?;
    let sized = |k: sysid::NonlinearityKind| {
        let k = breakpoints.map_or(k, |n| k.with_breakpoints(n));
        degree.map_or(k, |d| k.with_degree(d))
    };
    let output = output_nonlinearity
        .map(str::parse::<sysid::NonlinearityKind>)
        .transpose()
        .map_err(|e| PyValueError::new_err(format!("output_nonlinearity: {e}")))?
        .map(sized);
    let nonlinearity = nonlinearity
        .map(str::parse::<sysid::NonlinearityKind>)
        .transpose()
        .map_err(|e| PyValueError::new_err(format!("nonlinearity: {e}")))?
        .map(sized);
    let piecewise = |k: &Option<sysid::NonlinearityKind>| {
        matches!(k, Some(sysid::NonlinearityKind::PiecewiseLinear { .. }))
    };
    if breakpoints.is_some() && !piecewise(&nonlinearity) && !piecewise(&output) {
        return Err(PyValueError::new_err(
            "breakpoints: is for nonlinearity= or output_nonlinearity=\"piecewise-linear\" (it sets its number of breakpoints)",
        ));
    }
    let options = IdentifyOptions {
        model: if structure.is_some() {
            // `structure=` is the command line's --structure, which also offers narx (handled above).
            choice("--structure", model)
                .map_err(|_| setting_err("structure", model, "one of arx, hammerstein, narx"))?
        } else {
            choice("--model", model)?
        },
        na,
        nb,
        nk,
        method: choice("--method", method)?,
        forgetting,
        p0,
        // None: passes until the estimate settles (the command line's `--passes auto`).
        passes: passes.map_or(sysid::Passes::AUTO, sysid::Passes::Fixed),
        max_iterations,
        rls_form: choice("--rls-form", rls_form)?,
        windup: choice("--windup", windup)?,
        max_trace,
        iv_stages,
        offset,
        fallback,
        max_memory,
    };
    // A setting of another method's estimator, given (a value other than the default, NaN included),
    // is refused as the command line refuses its flag (one table: `sysid::EstimatorSetting`; audit s19
    // L-5: `method="ls", forgetting=nan` was accepted and ignored).
    let given = |s: sysid::EstimatorSetting| match s {
        sysid::EstimatorSetting::Passes => passes.is_some(),
        sysid::EstimatorSetting::RlsForm => rls_form != "standard",
        sysid::EstimatorSetting::Windup => windup != "none",
        sysid::EstimatorSetting::MaxTrace => max_trace.is_some(),
        sysid::EstimatorSetting::Forgetting => forgetting.to_bits() != d.forgetting.to_bits(),
        sysid::EstimatorSetting::P0 => p0.to_bits() != d.p0.to_bits(),
        sysid::EstimatorSetting::IvStages => iv_stages != d.iv_stages,
    };
    if let Some(s) = sysid::EstimatorSetting::unused_by(options.method, given) {
        let methods = s
            .methods()
            .iter()
            .map(|m| format!("\"{m}\""))
            .collect::<Vec<_>>()
            .join(" or ");
        return Err(PyValueError::new_err(format!(
            "{} is a setting of {} (method={methods}); method=\"{}\" does not use it; leave it out",
            s.id(),
            s.whose(),
            options.method
        )));
    }
    let mut settings = options.settings();
    if let Some(nonlinearity) = nonlinearity {
        settings = settings.with_inputs(vec![sysid::InputSpec {
            nb,
            nk,
            nonlinearity,
        }]);
    }
    settings = settings.with_output_nonlinearity(output);
    settings.check().map_err(sysid_err)?;
    let data = dataset(u, y, ts, name)?;
    let val = validation
        .map(|v| {
            let (uv, yv) = record_pair(&v, "validation")?;
            dataset(&uv, &yv, ts, validation_name)
        })
        .transpose()?;
    let mut report = compute(py, |stop| -> Result<IdentifyReport, SysidError> {
        let settings = sysid::Identification {
            cancel: stop.clone(),
            ..settings.clone()
        };
        // As `identify --detrend`: estimated on the deviations from the operating point, which
        // the model stores (with its data range in the record's units) and puts back; metrics,
        // residuals and warnings on the record as given.
        let (estimation, op) = sysid::detrend::detrend(&data, detrend);
        let mut fit = sysid::identify(&estimation, &settings)?;
        if op.is_some() {
            fit.model = fit
                .model
                .with_operating_point(op)?
                .with_data_range(sysid::DataRange::of(std::slice::from_ref(&data)))?;
        }
        IdentifyReport::assemble(
            &fit,
            &settings,
            std::slice::from_ref(&data),
            val.as_ref(),
            resid_lags,
        )
    })?
    .map_err(sysid_err)?;
    report.warnings.extend(in_sample(&data, val.as_ref()));
    let mut json = report.to_json().map_err(sysid_err)?;
    if detrend != sysid::detrend::Detrend::None {
        // The keys `identify --detrend --json` adds (the reader's notes: none for arrays).
        let mut value: serde_json::Value =
            serde_json::from_str(&json).map_err(|e| PyValueError::new_err(e.to_string()))?;
        if let Some(obj) = value.as_object_mut() {
            obj.insert("detrend".into(), serde_json::json!(detrend));
            obj.insert("data_notes".into(), serde_json::json!(Vec::<String>::new()));
        }
        json = serde_json::to_string_pretty(&value)
            .map_err(|e| PyValueError::new_err(e.to_string()))?
            + "\n";
    }
    Ok(Bound::new(py, PyFit { report, json })?.into_any())
}

/// The command line's warning (`identify --validation` of the estimation data, audit s16 M12) when
/// the validation record holds exactly the estimation record's samples: its fit is in-sample.
fn in_sample(data: &Dataset, val: Option<&Dataset>) -> Option<String> {
    val.and_then(|v| sysid_summary::same_samples_warning("validation", v, data))
}

/// The result of `identify(..., structure="narx")`: a polynomial NARX model, its terms and metrics
/// (the `identify --structure narx --json` document).
#[pyclass(name = "NarxFit", module = "ipa_sysid")]
struct PyNarxFit {
    json: String,
    model_file: String,
}

#[pymethods]
impl PyNarxFit {
    /// The selected terms: [{"term", "coefficient", "std", "err"}] in FROLS order.
    #[getter]
    fn terms<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        self.to_dict(py)?.get_item("terms")
    }

    /// {"estimation": {...}, "validation": {...}} as in identify --json.
    #[getter]
    fn metrics<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        self.to_dict(py)?.get_item("metrics")
    }

    /// Reasons not to trust the model, in words (a blow-up of its simulation, weak terms, ...).
    #[getter]
    fn warnings<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        self.to_dict(py)?.get_item("warnings")
    }

    /// The whole `identify --structure narx --json` document as Python objects.
    fn to_dict<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        json_loads(py, &self.json)
    }

    /// The `identify --json` document as text.
    fn to_json(&self) -> String {
        self.json.clone()
    }

    /// The model file text (`identify --save-model`), readable by `validate --model` and
    /// `--plant model:FILE`.
    fn model_file(&self) -> String {
        self.model_file.clone()
    }

    /// What a user needs (audit s25 L-3: it was "NarxFit(2295 bytes of JSON)"): the number of terms
    /// of the candidates, the stopping rule, whether the simulation blew up, and the fit % named by
    /// their record as `Fit`'s repr.
    fn __repr__(&self) -> String {
        let doc: serde_json::Value = serde_json::from_str(&self.json).unwrap_or_default();
        let num = |v: &serde_json::Value| v.as_f64();
        let fits =
            |m: &serde_json::Value| (num(&m["fit_sim_percent"]), num(&m["fit_pred_percent"]));
        let metrics = &doc["metrics"];
        let blew = metrics["estimation"]["blew_up_at"]
            .as_u64()
            .map_or(String::new(), |k| format!(", simulation blew up at k={k}"));
        fit_repr(
            &format!(
                "NarxFit(terms={} of {} candidates, degree={}, stop={:?}{blew}",
                doc["terms"].as_array().map_or(0, Vec::len),
                doc["selection"]["candidates"].as_u64().unwrap_or(0),
                doc["model"]["degree"].as_u64().unwrap_or(0),
                doc["selection"]["stop"]["rule"].as_str().unwrap_or("?"),
            ),
            fits(&metrics["estimation"]),
            (!metrics["validation"].is_null()).then(|| fits(&metrics["validation"])),
        )
    }

    /// Pickling and copying: the JSON document and the model file (audit s23 L-P5).
    fn __reduce__<'py>(&self, py: Python<'py>) -> PyResult<(Bound<'py, PyAny>, (String, String))> {
        let restore = py.import("ipa_sysid._core")?.getattr("_narx_fit_restore")?;
        Ok((restore, (self.json.clone(), self.model_file.clone())))
    }
}

/// Unpickling a `Fit` (its `__reduce__`).
#[pyfunction]
fn _fit_restore(report: &str, json: String) -> PyResult<PyFit> {
    let report = serde_json::from_str(report)
        .map_err(|e| PyValueError::new_err(format!("not a pickled Fit: {e}")))?;
    Ok(PyFit { report, json })
}

/// Unpickling a `NarxFit` (its `__reduce__`).
#[pyfunction]
fn _narx_fit_restore(json: String, model_file: String) -> PyNarxFit {
    PyNarxFit { json, model_file }
}

// ---------------------------------------------------------------------------------------------------
// fleet.

/// Identification and tracking of every window of a partition of many actuators' records
/// (`sysid_summary::monitor::partition`: the windows cut by `monitor::windows`, each identified by
/// `monitor::window`): `u`, `y` hold the actuators one after the other, actuator g in rows offsets[g] ..
/// offsets[g + 1]; each actuator's rows are cut into consecutive windows of `window` samples (an
/// incomplete last window is left out). Returns a dict of columns, one entry per window: `group`,
/// `window`, `start` (its first row), `names` (the parameters), `values` and `sds` (windows × parameters;
/// NaN where a window has no such parameter or no standard deviation), `fit_sim_percent`,
/// `fit_pred_percent` (NaN when not computed), `stable`, `warnings` (one string, lines joined by "\n"),
/// `change_points` (lists of samples within the window), and for a window not identified (a fleet goes
/// on past one bad record) the facts, for the caller to word: `error` ("" or the core's message, the
/// window's record not named), and for a sample that is not finite `error_signal` ("u" or "y"; "" for
/// other failures), `error_sample` (the sample within the window; -1 when none) and `error_value`
/// (its value; NaN when none). The GIL is released while computing.
#[pyfunction]
#[pyo3(signature = (u, y, offsets, ts, window, method="ls", na=3, nb=1, nk=1, detect_warmup=200,
    detect_calibration=800))]
#[allow(clippy::too_many_arguments)]
fn fleet_windows<'py>(
    py: Python<'py>,
    u: &Bound<'py, PyAny>,
    y: &Bound<'py, PyAny>,
    offsets: Vec<usize>,
    ts: f64,
    window: usize,
    method: &str,
    na: usize,
    nb: usize,
    nk: usize,
    detect_warmup: usize,
    detect_calibration: usize,
) -> PyResult<Bound<'py, PyDict>> {
    use sysid_summary::monitor::{self, WindowFault};
    let u = floats(u, "u")?;
    let y = floats(y, "y")?;
    if u.len() != y.len() {
        return Err(PyValueError::new_err(format!(
            "u has {} samples but y has {}",
            u.len(),
            y.len()
        )));
    }
    sysid_core::data::check_ts(ts).map_err(sysid_err)?;
    if !(2..=sysid_core::data::MAX_SAMPLES).contains(&window) {
        return Err(setting_err(
            "window",
            window,
            &format!("2..={} samples", sysid_core::data::MAX_SAMPLES),
        ));
    }
    let spans = monitor::windows(&offsets, u.len(), window).map_err(sysid_err)?;
    let options = IdentifyOptions {
        method: choice("--method", method)?,
        na,
        nb,
        nk,
        ..IdentifyOptions::default()
    };
    let identification = options.settings();
    identification.check().map_err(sysid_err)?;
    let track = sysid::online::TrackSettings {
        orders: sysid::Orders { na, nb, nk },
        detector: Some(sysid::online::DetectorSettings {
            warmup: detect_warmup,
            calibration: detect_calibration,
            ..sysid::online::DetectorSettings::default()
        }),
        ..sysid::online::TrackSettings::default()
    };
    sysid::online::Tracker::new(track).map_err(sysid_err)?;
    let settings = monitor::WindowSettings {
        identification,
        track,
    };
    let results = compute(py, |stop| {
        let mut settings = settings.clone();
        settings.identification.cancel = stop.clone();
        monitor::partition(&u, &y, &spans, ts, &settings)
    })?
    .map_err(sysid_err)?;
    let mut names: Vec<String> = Vec::new();
    for r in results.iter().flatten() {
        for p in &r.report.parameters {
            let n = p.name.to_string();
            if !names.contains(&n) {
                names.push(n);
            }
        }
    }
    let rows = results.len();
    let mut values = numpy::ndarray::Array2::<f64>::from_elem((rows, names.len()), f64::NAN);
    let mut sds = values.clone();
    let (mut fit_sim, mut fit_pred) = (vec![f64::NAN; rows], vec![f64::NAN; rows]);
    let mut stable = vec![false; rows];
    let (mut warnings, mut errors) = (vec![String::new(); rows], vec![String::new(); rows]);
    let mut signal = vec![String::new(); rows];
    let (mut sample, mut value) = (vec![-1i64; rows], vec![f64::NAN; rows]);
    let mut changes: Vec<Vec<usize>> = vec![Vec::new(); rows];
    for (i, r) in results.into_iter().enumerate() {
        match r {
            Ok(r) => {
                for p in &r.report.parameters {
                    if let Some(c) = names.iter().position(|n| *n == p.name.to_string()) {
                        values[(i, c)] = p.value;
                        sds[(i, c)] = p.std.unwrap_or(f64::NAN);
                    }
                }
                let m = &r.report.metrics.estimation;
                fit_sim[i] = m.fit_sim_percent.unwrap_or(f64::NAN);
                fit_pred[i] = m.fit_pred_percent.unwrap_or(f64::NAN);
                stable[i] = r.report.stable;
                warnings[i] = r.report.warnings.join("\n");
                changes[i] = r.change_points;
            }
            Err(WindowFault::NonFinite(f)) => {
                errors[i] = f.to_string();
                sample[i] = i64::try_from(f.sample).unwrap_or(i64::MAX);
                value[i] = f.value;
                signal[i] = f.signal;
            }
            Err(WindowFault::Failed(e)) => {
                errors[i] = e.render_within(monitor::WINDOW_RECORD, &|s| keyword(s.flag()));
            }
        }
    }
    let out = PyDict::new(py);
    out.set_item("group", spans.iter().map(|s| s.group).collect::<Vec<_>>())?;
    out.set_item("window", spans.iter().map(|s| s.window).collect::<Vec<_>>())?;
    out.set_item("start", spans.iter().map(|s| s.first).collect::<Vec<_>>())?;
    out.set_item("names", names)?;
    out.set_item("values", values.into_pyarray(py))?;
    out.set_item("sds", sds.into_pyarray(py))?;
    out.set_item("fit_sim_percent", fit_sim.into_pyarray(py))?;
    out.set_item("fit_pred_percent", fit_pred.into_pyarray(py))?;
    out.set_item("stable", stable)?;
    out.set_item("warnings", warnings)?;
    out.set_item("change_points", changes)?;
    out.set_item("error", errors)?;
    out.set_item("error_signal", signal)?;
    out.set_item("error_sample", sample.into_pyarray(py))?;
    out.set_item("error_value", value.into_pyarray(py))?;
    Ok(out)
}

/// The time column of each actuator of a fleet partition checked as the command line's reader checks
/// one (`sysid_core::data::uniform_time`, `ts_contradicts`; audit s16 H1): `t` (s) holds the actuators
/// one after the other, actuator g in rows offsets[g] .. offsets[g + 1], each sorted by time. Returns
/// one (error, step) pair per actuator: error "" or why its time column cannot date a uniformly sampled
/// record (a NaN time, a time that does not increase — duplicated rows —, a gap or other non-uniform
/// step; the sample and its time named); step the column's typical (median) step, s, when `ts`
/// contradicts it by more than 0.1 % (`ts_contradicts`' rule), NaN when they agree or the column has
/// an error (the caller words the contradiction from `ts` and the step). An actuator of one sample has
/// neither (it is too short for a window anyway).
#[pyfunction]
fn fleet_times(t: &Bound<'_, PyAny>, offsets: Vec<usize>, ts: f64) -> PyResult<Vec<(String, f64)>> {
    let t = floats(t, "t")?;
    if offsets.first() != Some(&0)
        || offsets.last() != Some(&t.len())
        || offsets.windows(2).any(|w| w[1] < w[0])
    {
        return Err(PyValueError::new_err(format!(
            "offsets: expected non-decreasing row offsets from 0 to {} (the number of samples)",
            t.len()
        )));
    }
    sysid_core::data::check_ts(ts).map_err(sysid_err)?;
    use sysid_core::data::TimeFault;
    Ok(offsets
        .windows(2)
        .map(|w| {
            let t = &t[w[0]..w[1]];
            let error = match sysid_core::data::uniform_time(t) {
                Ok(_) | Err(TimeFault::TooShort) => String::new(),
                Err(fault) => {
                    let at = fault
                        .sample()
                        .map(|k| format!(" (sample {k} of the actuator's rows sorted by t)"))
                        .unwrap_or_default();
                    let advice = match fault {
                        TimeFault::NotFinite { .. } => "drop or fill the rows without a time",
                        TimeFault::NotIncreasing { .. } => {
                            "drop the duplicated rows (a record appended twice, a logger that \
                             repeated samples)"
                        }
                        _ => "resample the actuator's record onto a uniform grid of ts, or split it at \
                              the gap",
                    };
                    format!("time column t: {fault}{at}; not identified: {advice}")
                }
            };
            let step = sysid_core::data::ts_contradicts(t, ts)
                .filter(|_| error.is_empty())
                .unwrap_or(f64::NAN);
            (error, step)
        })
        .collect())
}

// ---------------------------------------------------------------------------------------------------
// Rls.

/// Recursive least squares (paper eqs. 9–12) on n parameters: θ̂(0) = 0, P(0) = p0 · I, forgetting
/// factor ρ in (0, 1]. Each update takes a regressor φ(k) (n values) and a measurement y(k).
#[pyclass(name = "Rls", module = "ipa_sysid")]
struct PyRls {
    inner: sysid::rls::Rls,
    samples: usize,
}

#[pymethods]
impl PyRls {
    #[new]
    // Taken as any object so that a bool is refused by name (audit s23 L-P7); None is the default.
    #[pyo3(signature = (n, forgetting=None, p0=None), text_signature = "(n, forgetting=1.0, p0=1e6)")]
    fn new(
        n: &Bound<'_, PyAny>,
        forgetting: Option<&Bound<'_, PyAny>>,
        p0: Option<&Bound<'_, PyAny>>,
    ) -> PyResult<Self> {
        let forgetting = forgetting.map_or(Ok(1.0), |v| number("forgetting", v))?;
        let p0 = p0.map_or(Ok(1e6), |v| number("p0", v))?;
        let n = whole("n", n)?;
        if n == 0 || n > MAX_RLS_PARAMS {
            return Err(setting_err(
                "n",
                n,
                &format!("a number of parameters from 1 to {MAX_RLS_PARAMS}"),
            ));
        }
        Ok(PyRls {
            inner: sysid::rls::Rls::new(n, forgetting, p0).map_err(sysid_err)?,
            samples: 0,
        })
    }

    /// n: number of parameters.
    #[getter]
    fn n(&self) -> usize {
        self.inner.n_params()
    }

    /// ρ: the forgetting factor.
    #[getter]
    fn forgetting(&self) -> f64 {
        self.inner.forgetting()
    }

    /// Number of updates applied so far.
    #[getter]
    fn samples(&self) -> usize {
        self.samples
    }

    /// θ̂: the current estimate (a copy, float64 array of n).
    #[getter]
    fn theta<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        PyArray1::from_slice(py, self.inner.theta())
    }

    /// P: the n × n matrix proportional to the covariance of θ̂ (a copy).
    #[getter(P)]
    fn p<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray2<f64>> {
        let p = self.inner.p();
        let n = p.nrows();
        let mut out = numpy::ndarray::Array2::<f64>::zeros((n, n));
        for ((i, j), v) in out.indexed_iter_mut() {
            *v = p[(i, j)];
        }
        out.into_pyarray(py)
    }

    /// One update with regressor φ (n values) and measurement y; returns the a-priori error
    /// ε = y − φᵀθ̂. Raises ValueError naming the entry when φ or y is not finite, ArithmeticError
    /// when P loses positive definiteness; the state is unchanged in both cases.
    fn update(&mut self, phi: &Bound<'_, PyAny>, y: &Bound<'_, PyAny>) -> PyResult<f64> {
        // y by its name (audit s35 L-7: an array for y was numpy's "only 0-dimensional arrays can be
        // converted to Python scalars", naming nothing).
        let y = number("y", y)?;
        let phi = floats(phi, "phi")?;
        self.check_columns(phi.len(), "phi has")?;
        // A non-finite input is the caller's, named as such (audit s19 L-5: y = NaN raised the
        // estimator's ArithmeticError "RLS lost positive definiteness or met a non-finite value").
        check_finite_sample(&phi, y, None)?;
        let e = self
            .inner
            .try_update(&phi, y, self.samples)
            .map_err(rls_update_err)?;
        self.samples += 1;
        Ok(e)
    }

    /// Updates with each row of `Phi` (N × n float64) and each entry of `y` (N), in Rust without a
    /// Python loop; returns the a-priori errors ε (N). Every row is checked before any is applied: a
    /// non-finite φ_k or y_k is a ValueError naming the argument and the row k, the estimate unchanged
    /// (as `update`'s). On a numerical failure at row k (P losing positive definiteness), rows before
    /// k are applied, the state is that after row k − 1, and ArithmeticError names the sample.
    /// Python's signal handlers run every [`RLS_SIGNAL_ROWS`] rows and once more after the last: when
    /// one raises (Ctrl-C's KeyboardInterrupt), the state from before the call is put back and that
    /// exception is raised, so that "interrupted" means "nothing was applied" (audit s36 L-9: the
    /// interrupt came after every row, with the state advanced and the errors lost).
    #[allow(non_snake_case)]
    fn update_many<'py>(
        &mut self,
        py: Python<'py>,
        Phi: &Bound<'py, PyAny>,
        y: &Bound<'py, PyAny>,
    ) -> PyResult<Bound<'py, PyArray1<f64>>> {
        let y = floats(y, "y")?;
        let owned;
        let phi: PyReadonlyArray2<'py, f64> = match Phi.extract::<PyReadonlyArray2<'py, f64>>() {
            Ok(a) if a.is_c_contiguous() => a,
            _ => {
                owned = as_float_array(Phi, "Phi")?;
                if owned.ndim() != 2 {
                    return Err(PyValueError::new_err(format!(
                        "Phi: expected an N × n array, got an array of shape {:?}",
                        owned.shape()
                    )));
                }
                owned.extract()?
            }
        };
        let [rows, cols] = [phi.shape()[0], phi.shape()[1]];
        self.check_columns(cols, "Phi has")?;
        if rows != y.len() {
            return Err(PyValueError::new_err(format!(
                "Phi has {rows} rows but y has {} samples",
                y.len()
            )));
        }
        let data = phi
            .as_slice()
            .map_err(|e| PyValueError::new_err(format!("Phi: {e}")))?;
        // All rows before any update (audit s19 leftover: a NaN y at row k raised ArithmeticError
        // after rows 0..k had been applied).
        for (k, (row, yk)) in data.chunks_exact(cols).zip(&y).enumerate() {
            check_finite_sample(row, *yk, Some(k))?;
        }
        let mut errors = Vec::with_capacity(rows);
        let mut failure = None;
        // The state before the call (θ̂, P and the count: n + n² numbers), put back on an interrupt.
        let before = (self.inner.clone(), self.samples);
        for (k, (row, yk)) in data.chunks_exact(cols).zip(&y).enumerate() {
            if k % RLS_SIGNAL_ROWS == 0 && k > 0 {
                if let Err(e) = py.check_signals() {
                    (self.inner, self.samples) = before;
                    return Err(e);
                }
            }
            match self.inner.try_update(row, *yk, self.samples) {
                Ok(e) => {
                    errors.push(e);
                    self.samples += 1;
                }
                Err(e) => {
                    failure = Some(e);
                    break;
                }
            }
        }
        if let Err(e) = py.check_signals() {
            (self.inner, self.samples) = before;
            return Err(e);
        }
        match failure {
            Some(e) => Err(rls_update_err(e)),
            None => Ok(errors.into_pyarray(py)),
        }
    }

    /// Restarts P at p0 · I, keeping θ̂ (a new pass over the data).
    fn restart_covariance(&mut self, p0: f64) -> PyResult<()> {
        sysid::rls::check_settings(self.inner.forgetting(), p0).map_err(sysid_err)?;
        self.inner.restart_covariance(p0);
        Ok(())
    }

    fn __repr__(&self) -> String {
        format!(
            "Rls(n={}, forgetting={}, samples={})",
            self.inner.n_params(),
            self.inner.forgetting(),
            self.samples
        )
    }
}

/// A refused `Rls` update as the Python exception, its advice in `Rls`'s own terms (its arguments
/// `forgetting`, `p0` and its method `restart_covariance`; audit s33 L-6: it quoted the command line's
/// `--rls-form`, `--p0`, which `Rls` does not have): under forgetting ρ < 1 covariance windup first (P
/// grows by 1/ρ per update while φ does not excite; the estimator then refuses every later update until
/// its covariance is restarted), else P(0) too large for the signals.
fn rls_update_err(e: sysid::rls::UpdateError) -> PyErr {
    let f = match e {
        sysid::rls::UpdateError::Shape(e) => return sysid_err(e),
        sysid::rls::UpdateError::Failure(f) => f,
    };
    let advice = if f.windup_likely() {
        format!(
            "with forgetting ρ = {} < 1 the likely cause is covariance windup: while the regressor φ \
             does not excite a direction (a rest, a constant command) P grows by 1/ρ per update in it \
             until it overflows, whatever p0 (a smaller p0 only delays it), and every later update is \
             refused as well; call restart_covariance(p0) to go on (and after each unexciting \
             stretch, before it overflows), leave such stretches out of the updates, or use \
             forgetting=1; if φ kept exciting, p0 may be too large for the signals' magnitude \
             instead: a smaller p0 or rescaled signals",
            f.forgetting
        )
    } else {
        "this usually means p0 is too large for the signals' magnitude (large numbers, e.g. µm or \
         Pa: the rounding of P − Pφφᵀ P/δ then exceeds its smallest entries): try a smaller p0 or \
         rescaled signals (identify(..., method=\"rls\", rls_form=\"ud\") runs the factorised \
         update, which stays positive definite)"
            .to_string()
    };
    PyArithmeticError::new_err(format!("{}; {advice}", f.what()))
}

/// Refuses a non-finite regressor entry φ_i or measurement y before an RLS update, naming the
/// argument: `phi(i)` / `y` for `Rls.update`, `Phi(k, i)` / `y(k)` with the row k for
/// `Rls.update_many` (`row` = Some(k)). The one check of both, so that the estimate is unchanged.
fn check_finite_sample(phi: &[f64], y: f64, row: Option<usize>) -> PyResult<()> {
    let unchanged = |what: String, v: f64, expected: &str| {
        let at = row.map_or(String::new(), |k| format!(" (row {k})"));
        PyValueError::new_err(format!(
            "{what} = {}: expected {expected}{at}; the estimate is unchanged",
            py_float(Some(v))
        ))
    };
    if let Some((i, v)) = phi.iter().enumerate().find(|(_, v)| !v.is_finite()) {
        let what = row.map_or(format!("phi({i})"), |k| format!("Phi({k}, {i})"));
        return Err(unchanged(what, *v, "finite numbers"));
    }
    if !y.is_finite() {
        let what = row.map_or("y".to_string(), |k| format!("y({k})"));
        return Err(unchanged(what, y, "a finite number"));
    }
    Ok(())
}

impl PyRls {
    fn check_columns(&self, got: usize, what: &str) -> PyResult<()> {
        let n = self.inner.n_params();
        if got == n {
            Ok(())
        } else {
            Err(PyValueError::new_err(format!(
                "{what} {got} entries per regressor but the estimator has n = {n} parameters"
            )))
        }
    }
}

// ---------------------------------------------------------------------------------------------------
// Plants and control.

/// A plant spec as the command line's `--plant`: "ipa", "paper", "model:FILE", or a model file path.
fn plant_spec(plant: &str) -> PyResult<ipa::PlantSpec> {
    let t = plant.trim();
    let spec = if t == "ipa" || t == "paper" || t.starts_with("model:") {
        t.to_string()
    } else if std::path::Path::new(t).exists() {
        format!("model:{t}")
    } else {
        // Neither a plant's name nor a file: a misspelt name as often as a missing file (audit s13 L9).
        return Err(setting_err(
            "plant",
            t,
            "one of ipa, paper, model:FILE or the path of an existing model file",
        ));
    };
    spec.parse::<ipa::PlantSpec>().map_err(ipa_err)
}

/// Runs one open-loop experiment, as `ipa-sysid simulate` (same options, same numbers): returns
/// (t, u, y, pressures) — t in s, u in counts, y in mm (noise included), pressures an N × 2 array of
/// the chamber pressures p_a, p_b in Pa (physics plant `ipa` only; None otherwise; the CSV of the
/// command line rounds them to 0.1 Pa). `plant`: "ipa", "paper", or a model file ("model:FILE" or its path).
/// The command line's warnings (a model file's doubts, a start outside its data, an input or output
/// beyond its estimation data, a flat physics record, the paper model beyond the stroke) are each
/// issued as an `IpaSysidWarning` (`sysid_summary::simulation`, the list `simulate` prints).
/// `max_memory_gb` (the command line's `--max-memory`, 4 GiB by default) bounds the run's buffers:
/// more samples than fit are refused before the run.
#[pyfunction]
#[pyo3(signature = (plant=None, input="staircase", samples=None, seed=0, amplitude=255.0, ts=None,
    x0=None, noise_std=0.0, plant_config=None, max_memory_gb=4.0),
    text_signature = "(plant='ipa', input='staircase', samples=None, seed=0, amplitude=255.0, ts=None, \
    x0=None, noise_std=0.0, plant_config=None, max_memory_gb=4.0)")]
#[allow(clippy::too_many_arguments, clippy::type_complexity)]
fn simulate_plant<'py>(
    py: Python<'py>,
    plant: Option<&Bound<'py, PyAny>>,
    input: &str,
    samples: Option<usize>,
    seed: u64,
    amplitude: f64,
    ts: Option<f64>,
    x0: Option<f64>,
    noise_std: f64,
    plant_config: Option<&Bound<'py, PyAny>>,
    max_memory_gb: f64,
) -> PyResult<(
    Bound<'py, PyArray1<f64>>,
    Bound<'py, PyArray1<f64>>,
    Bound<'py, PyArray1<f64>>,
    Option<Bound<'py, PyArray2<f64>>>,
)> {
    // Every path argument by the one conversion (`str`, `bytes` or `os.PathLike`; audit s35 L-8).
    let plant_config = plant_config
        .map(|v| path_arg("plant_config", v))
        .transpose()?;
    // `plant`: a name or `model:FILE` as text, or a model file's path in any path form.
    let plant = match plant {
        Some(p) => path_arg("plant", p)?.to_string_lossy().into_owned(),
        None => "ipa".to_string(),
    };
    // The initial position by its Python keyword (audit s35 L-7: the core's check named `y0`, the
    // command line's `--y0`).
    if let Some(v) = x0.filter(|v| !v.is_finite()) {
        return Err(setting_err(
            "x0",
            sysid_core::format::Shortest(v),
            "a finite position in mm",
        ));
    }
    let plant = plant_spec(&plant)?;
    // The model a `model:FILE` plant names, for its warnings (those of `simulate --plant model:FILE`,
    // audit s18 M-2): its file's doubts first, said with the file's name.
    let (mut warnings, model, narx_range) = match &plant {
        ipa::PlantSpec::ModelFile(path) => {
            match sysid::model_file::read_any_model(path).map_err(sysid_err)? {
                sysid::model_file::AnyModel::Linear(m) => {
                    let w = sysid_summary::simulation::model_file_warnings(&m)
                        .into_iter()
                        .map(|w| format!("{}: {w}", path.display()))
                        .collect();
                    (w, Some(m), None)
                }
                sysid::model_file::AnyModel::Narx(m) => (Vec::new(), None, m.data_range().cloned()),
            }
        }
        _ => (Vec::new(), None, None),
    };
    // A file input is read once; its time column's Ts is the physics plant's unless ts= says
    // otherwise, as on the command line.
    let input = input
        .parse::<ipa::InputSpec>()
        .map_err(ipa_err)?
        .load()
        .map_err(ipa_err)?;
    let file_ts = input.file_ts();
    let run_ts = match (ts, file_ts, &plant) {
        (None, Some(f), ipa::PlantSpec::Ipa) => Some(f),
        _ => ts,
    };
    let (physics, paper) = (
        matches!(plant, ipa::PlantSpec::Ipa),
        matches!(plant, ipa::PlantSpec::Paper),
    );
    let exp = ipa::Experiment {
        plant,
        plant_config,
        input,
        amplitude,
        samples,
        ts: run_ts,
        x0,
        seed,
        noise_std,
        cancel: sysid::Stop::never(),
    };
    exp.check().map_err(ipa_err)?;
    // The run's buffers, bounded before they are made (audit s36 H-1: 5 × 10^7 samples, accepted,
    // aborted the interpreter on a failed allocation under a 1.5 GB memory limit).
    let budget = memory_budget(max_memory_gb)?;
    let n = exp.sample_count().map_err(ipa_err)?;
    if let Err((need, fit)) = sysid::ls::record_budget(n, 1, budget) {
        return Err(setting_err(
            "samples",
            n,
            &format!(
                "at most {} samples within max_memory_gb = {} (a run holds about {} numbers of 8 \
                 bytes per sample: {} GB here); fewer samples, or a larger max_memory_gb if this \
                 machine has the memory",
                fit,
                budget,
                sysid::ls::RECORD_NUMBERS_PER_SAMPLE,
                sysid::ls::format_gb(need)
            ),
        ));
    }
    let y0 = match exp.x0 {
        Some(v) => v,
        None => exp.plant.default_y0().map_err(ipa_err)?,
    };
    let mut exp = ipa::Experiment {
        x0: Some(y0),
        ..exp
    };
    // The plant polls `compute`'s stop: Ctrl-C ends the run within a few thousand samples.
    let rec = compute(py, |stop| {
        exp.cancel = stop.clone();
        exp.run()
    })?
    .map_err(ipa_err)?;
    // What holds the physics plant's piston, as `simulate` computes it (its config's deadzone,
    // friction and the forces the run's commands build up).
    let hold = if physics {
        let cfg = match exp.plant_config.as_deref() {
            Some(path) => ipa::PlantConfig::from_toml_file(path).map_err(ipa_err)?,
            None => ipa::PlantConfig::default(),
        };
        sysid_summary::simulation::PhysicsHold::of_run(&cfg, &rec.u, &rec.y, y0)
    } else {
        None
    };
    let run = sysid_summary::simulation::OpenLoopRun {
        model: model.as_ref(),
        narx_range: narx_range.as_ref(),
        physics,
        hold,
        paper_stroke_mm: paper.then(|| ipa::PlantConfig::default().cylinder.stroke_mm),
        y0,
        y0_default: x0.is_none(),
        input_file: exp.input.file().map(|p| (p, file_ts)),
        ts_setting: ts,
    };
    warnings.extend(sysid_summary::simulation::record_warnings(
        &run, &rec.u, &rec.y, rec.ts,
    ));
    warn_all(py, &warnings)?;
    let t = sysid::data::sample_times(rec.u.len(), rec.ts);
    let pressures = rec.pressures.map(|p| {
        let flat: Vec<f64> = p.iter().flatten().copied().collect();
        numpy::ndarray::Array2::from_shape_vec((p.len(), 2), flat).map(|a| a.into_pyarray(py))
    });
    let pressures = pressures
        .transpose()
        .map_err(|e| PyArithmeticError::new_err(format!("pressures: {e}")))?;
    Ok((
        t.into_pyarray(py),
        rec.u.into_pyarray(py),
        rec.y.into_pyarray(py),
        pressures,
    ))
}

/// Closed-loop PI position control, as `ipa-sysid control`: returns a dict with the trace ("t" s,
/// "r" mm, "u" counts, "y" mm as arrays), "metrics" (overshoot, rise and settling time, steady-state
/// error: MATLAB `stepinfo`), "metrics_kind" ("fixed" or "worst-step"), "steps", "ts" and "warnings"
/// (not settled, saturated, unreachable set-point, unstable model, the paper's acceptance missed:
/// `control::loop_warnings`; the package's `control` issues each as an `IpaSysidWarning`). Give exactly
/// one of `setpoint` (mm) or `profile` ("fixed:MM", "staircase:L1,L2,...@HOLD_S", "file:PATH.csv").
/// `anti_windup`: "none" or "clamping" ("back-calculation" needs `tracking_time` in s).
/// `compensate_deadzone`: a Hammerstein `Model` or "paper" adds a deadzone-inverse compensator.
/// A plant of `control`, boxed.
type BoxedPlant = Box<dyn sysid::Plant + Send>;

/// The plant of `control`: a spec string (`"ipa"`, the default, `"paper"`, `"model:FILE"`) or a `Model`
/// object, with the limits its loop is checked against.
fn plant_and_limits(
    plant: Option<&Bound<'_, PyAny>>,
    config: Option<&std::path::Path>,
) -> PyResult<(ipa::PlantLimits, BoxedPlant)> {
    let Some(plant) = plant else {
        let spec = ipa::PlantSpec::Ipa;
        return Ok((
            spec.limits(config).map_err(ipa_err)?,
            spec.build(config, None).map_err(ipa_err)?,
        ));
    };
    if let Ok(m) = plant.cast::<PyModel>() {
        if let Some(path) = config {
            return Err(setting_err(
                "plant_config",
                path.display(),
                "a physics plant configuration, which applies to the plant ipa only, not to a Model",
            ));
        }
        let model = m.get().inner.clone();
        // The paper's model (`paper_model()`) is the paper plant, in the IPA's counts and mm
        // (`PlantLimits::of_model`); any other Model speaks its record's units.
        let limits = ipa::PlantLimits::of_model(&model);
        let plant = sysid::ModelPlant::new(model, "model").map_err(sysid_err)?;
        return Ok((limits, Box::new(plant)));
    }
    let Ok(text) = plant.extract::<&str>() else {
        return Err(setting_err(
            "plant",
            plant.to_string(),
            "\"ipa\", \"paper\", \"model:FILE\" or a Model",
        ));
    };
    let spec = plant_spec(text)?;
    let limits = spec.limits(config).map_err(ipa_err)?;
    let plant = spec.build(config, None).map_err(ipa_err)?;
    Ok((limits, plant))
}

/// Runs the PI position loop on a plant, as `ipa-sysid control --json` (same options, same numbers).
/// `plant`: "ipa" (the physics simulator, the default), "paper", "model:FILE", a model file's path or
/// a `Model` (e.g. `fit.model`). Give exactly one of `setpoint` (r in mm, held) and `profile` (text:
/// "fixed:50" or "50", "staircase:20,60,100,40@3" — each level in mm held 3 s —, or "file:PATH.csv"
/// with columns t (s) and r (mm); or an array of (t, r) rows, the same table without a file). `kp` in counts/mm (default 14), `ki` in
/// counts/(mm·s) with `integral="scaled"` (default) or counts/(mm·sample) with "per-sample" (default
/// 1); `duration` in s (default: the profile's own length, else 10 s); `y0` the start position in mm
/// (default 0); `anti_windup`: "none" (default), "clamping" or "back-calculation" (needs
/// `tracking_time` Tt in s); `u_max` the command limit in counts (default 255);
/// `compensate_deadzone`: a `Model` or "paper" whose deadzone is cancelled before the valve
/// (`compensator_slopes` "shift" or "equalise", `compensator_threshold` in mm); `plant_config`: a
/// plant TOML for "ipa"; `controller`: a tuned controller (`tune()`'s result, its "controller" dict, a
/// controller file's JSON text or path) instead of `kp`/`ki`.
/// Returns a dict: "t" (s), "r" and "y" (mm), "u" (counts) numpy arrays, "ts" (s), "units",
/// "metrics_kind", "metrics" (overshoot, undershoot, rise and settling times, steady-state error),
/// "steps" (a staircase's steps) and "warnings" (each also issued as an `IpaSysidWarning`).
/// Raises ValueError for a bad setting (named by its keyword), ArithmeticError when the simulation
/// fails numerically. The GIL is released while the loop runs; Ctrl-C raises `KeyboardInterrupt`
/// within a few thousand samples (the plant polls the stop of docs/python.md "Threads and Ctrl-C").
#[pyfunction]
#[pyo3(signature = (plant=None, setpoint=None, profile=None, kp=14.0, ki=1.0, duration=None, y0=0.0,
    integral="scaled", anti_windup="none", tracking_time=None, u_max=255.0, compensate_deadzone=None,
    compensator_slopes="shift", compensator_threshold=0.0, plant_config=None, controller=None))]
#[pyo3(name = "control")]
#[allow(clippy::too_many_arguments)]
fn control_loop<'py>(
    py: Python<'py>,
    plant: Option<&Bound<'py, PyAny>>,
    setpoint: Option<f64>,
    profile: Option<Bound<'_, PyAny>>,
    kp: f64,
    ki: f64,
    duration: Option<f64>,
    y0: f64,
    integral: &str,
    anti_windup: &str,
    tracking_time: Option<f64>,
    u_max: f64,
    compensate_deadzone: Option<&Bound<'py, PyAny>>,
    compensator_slopes: &str,
    compensator_threshold: f64,
    plant_config: Option<&Bound<'py, PyAny>>,
    controller: Option<&Bound<'py, PyAny>>,
) -> PyResult<Bound<'py, PyDict>> {
    // Every path argument by the one conversion (`str`, `bytes` or `os.PathLike`; audit s35 L-8).
    let plant_config = plant_config
        .map(|v| path_arg("plant_config", v))
        .transpose()?;
    use ::control::{AntiWindup, IntegralForm, Profile, SlopeMode};
    // A tuned controller: the JSON of a controller file (the Python wrapper turns tune()'s result and
    // its "controller" dict into it), or a controller file's path, read as `control --controller` reads
    // it (`ControllerFile::read_file`: a regular file only, at most 1 MiB counted as it is read; audit
    // s19 H-2: the wrapper's `f.read()` read /dev/zero until memory ran out and waited forever on a FIFO).
    let tuned_file = controller.map(controller_file).transpose()?;
    let tuned = tuned_file.as_ref().map(|f| f.controller);
    if tuned.is_some() && compensate_deadzone.is_some() {
        return Err(setting_err(
            "--controller",
            "(given)",
            "not together with compensate_deadzone (the tuned controller has its own)",
        ));
    }
    let profile = match (setpoint, profile) {
        (Some(r), None) if r.is_finite() => Profile::Fixed { setpoint_mm: r },
        (Some(r), None) => return Err(setting_err("--setpoint", r, "a finite position in mm")),
        (None, Some(spec)) => profile_arg(&spec)?,
        (given_setpoint, given_profile) => {
            // What was given, not an empty value (audit s33 L-3).
            let given = match (given_setpoint, given_profile) {
                (Some(r), Some(p)) => format!("{} and {p:?}", sysid_core::format::Shortest(r)),
                _ => "(neither given)".to_string(),
            };
            return Err(setting_err(
                "--setpoint/--profile",
                given,
                "exactly one of setpoint=MM or profile=SPEC",
            ));
        }
    };
    let integral = match integral {
        "scaled" => IntegralForm::Scaled,
        "per-sample" => IntegralForm::PerSample,
        other => {
            return Err(setting_err(
                "--integral",
                other,
                "one of scaled, per-sample",
            ))
        }
    };
    let anti_windup = match (anti_windup, tracking_time) {
        ("none", None) => AntiWindup::None,
        ("clamping", None) => AntiWindup::Clamping,
        ("back-calculation", Some(tt_s)) => AntiWindup::BackCalculation { tt_s },
        ("back-calculation", None) => {
            return Err(setting_err(
                "--tracking-time",
                "(none)",
                "a tracking time in s with anti_windup=\"back-calculation\"",
            ))
        }
        ("none" | "clamping", Some(t)) => {
            return Err(setting_err(
                "--tracking-time",
                t,
                "only together with anti_windup=\"back-calculation\"",
            ))
        }
        (other, _) => {
            return Err(setting_err(
                "--anti-windup",
                other,
                "one of none, clamping, back-calculation",
            ))
        }
    };
    // The plant as given, for the controller file's check against a model plant (M-B6).
    let plant_arg = plant;
    let (limits, mut plant) = plant_and_limits(plant, plant_config.as_deref())?;
    // A start the plant cannot hold (beyond the IPA's stroke, or ±1e6 of a model), as the command line.
    limits.check_start(y0).map_err(sysid_err)?;
    let ts = plant.ts();
    let settings = ::control::PiSettings::new(kp, ki)
        .with_integral(integral)
        .with_anti_windup(anti_windup)
        .with_u_max(u_max);
    if let Some(t) = &tuned {
        check_controller_ts(t, ts, "plant")?;
    }
    let mut pi = settings.build(ts).map_err(control_err)?;
    let mut position = tuned.map(|t| t.build()).transpose().map_err(control_err)?;
    let u_max = tuned.map_or(u_max, |t| t.u_max);
    let mut compensator_warning = None;
    let compensator = match compensate_deadzone {
        None => None,
        Some(obj) => {
            let deadzone = if obj.extract::<&str>().ok() == Some("paper") {
                Model::paper().deadzone().copied()
            } else {
                let m = &obj
                    .cast::<PyModel>()
                    .map_err(|_| {
                        setting_err(
                            "--compensate-deadzone",
                            obj.to_string(),
                            "a Hammerstein Model or \"paper\"",
                        )
                    })?
                    .get()
                    .inner;
                compensator_warning = ::control::compensator::compensator_scale_warning(m, u_max);
                m.deadzone().copied()
            };
            let Some(deadzone) = deadzone else {
                return Err(setting_err(
                    "--compensate-deadzone",
                    "Model(kind=\"arx\")",
                    "a Hammerstein model (this model is ARX and has no deadzone)",
                ));
            };
            let mode = match compensator_slopes {
                "shift" => SlopeMode::Shift,
                "equalise" => SlopeMode::Equalise,
                other => {
                    return Err(setting_err(
                        "--compensator-slopes",
                        other,
                        "one of shift, equalise",
                    ))
                }
            };
            Some(
                ::control::DeadzoneCompensator::new(deadzone, mode, u_max)
                    .and_then(|c| c.with_threshold(compensator_threshold))
                    .map_err(control_err)?,
            )
        }
    };
    let duration_s = duration
        .or(profile.natural_duration_s())
        .unwrap_or(DEFAULT_FIXED_DURATION_S);
    let (trace, run) = compute(py, |stop| -> Result<_, ::control::ControlError> {
        let controller: &mut dyn ::control::Controller = match position.as_mut() {
            Some(p) => p,
            None => &mut pi,
        };
        // The plant polls `compute`'s stop: Ctrl-C ends the loop within a few thousand samples.
        let trace = ::control::closed_loop::run(
            &mut sysid::plant::Stoppable::new(plant.as_mut(), stop),
            controller,
            compensator.as_ref(),
            &profile,
            duration_s,
            y0,
        )?;
        if trace.len() < 2 {
            return Err(::control::ControlError::setting(
                ::control::ControlSetting::Duration,
                duration_s,
                &format!("at least one sampling period ({ts} s) to measure a response"),
            ));
        }
        let run = ::control::run_metrics(&trace, &profile)?;
        Ok((trace, run))
    })?
    .map_err(control_err)?;
    // The model file's own doubts (a crossed deadzone), the controller file's, then the loop's.
    let mut warnings = ::control::trust::setup_warnings(
        &limits.model_warnings,
        tuned_file.as_ref(),
        compensator_warning,
        &profile,
        duration_s,
    );
    // A controller file tuned for another model, or whose compensator inverts another deadzone
    // (`control`'s check of the command line).
    if let (Some(f), Some(p)) = (&tuned_file, plant_arg) {
        if let Ok(m) = p.cast::<PyModel>() {
            // A model given in memory names no file: its deadzone only.
            warnings.extend(::control::trust::controller_model_warnings(
                f,
                &m.get().inner,
                None,
            ));
        } else if let Some(Ok(spec)) = p.extract::<&str>().ok().map(str::parse::<ipa::PlantSpec>) {
            warnings.extend(::control::trust::controller_plant_warnings(
                f,
                &spec,
                plant_config.as_deref(),
            ));
        }
    }
    warnings.extend(::control::loop_warnings(
        &trace,
        &run.steps,
        &::control::LoopFacts {
            u_max,
            range_mm: limits.range_mm,
            plant_stability: limits.stability,
            judge_steps: profile.has_held_steps(),
            data_u_range: limits.data_u_range,
            data_y_range: limits.data_y_range,
            duration_setting: Some("duration="),
            start_setting: Some("y0="),
            units: ::control::Units::of(limits.model_units()),
        },
    ));
    // The run against the controller file's own steady-state specification, as `control`.
    if let Some(f) = &tuned_file {
        warnings.extend(::control::trust::spec_warnings(f, &run.steps));
    }
    let out = PyDict::new(py);
    out.set_item("t", trace.t.into_pyarray(py))?;
    out.set_item("r", trace.r.into_pyarray(py))?;
    out.set_item("u", trace.u.into_pyarray(py))?;
    out.set_item("y", trace.y.into_pyarray(py))?;
    out.set_item("ts", ts)?;
    out.set_item("metrics_kind", run.kind.as_str())?;
    // The units of u and of y and the metrics (keys named _mm), as `control --json` (audit s22 L-B8).
    out.set_item(
        "units",
        to_py(py, &::control::Units::of(limits.model_units()))?,
    )?;
    out.set_item("metrics", to_py(py, &run.metrics)?)?;
    out.set_item("steps", to_py(py, &run.steps)?)?;
    out.set_item("warnings", warnings)?;
    Ok(out)
}

/// Tunes the position controller as `ipa-sysid tune`: on `model` (a Hammerstein Model, or the path
/// of a model file) or on `plant_config` (the path of a physics-plant TOML, a twin); `spec` as
/// `--spec`. Returns a dict: the `ipa-sysid tune --json` document ("controller", "margins",
/// "on_model", "on_physics", "warnings", ...) and "controller_file" (the text `--out` writes), whose
/// "controller" control() accepts as `controller=`.
#[pyfunction]
#[pyo3(signature = (model=None, plant_config=None, spec="", variants=5, max_evaluations=150,
    check_physics=false, physics_variants=20))]
#[allow(clippy::too_many_arguments)]
fn tune<'py>(
    py: Python<'py>,
    model: Option<&Bound<'py, PyAny>>,
    plant_config: Option<&Bound<'py, PyAny>>,
    spec: &str,
    variants: usize,
    max_evaluations: usize,
    check_physics: bool,
    physics_variants: usize,
) -> PyResult<Bound<'py, PyAny>> {
    // Every path argument by the one conversion (`str`, `bytes` or `os.PathLike`; audit s35 L-8).
    let plant_config = plant_config
        .map(|v| path_arg("plant_config", v))
        .transpose()?;
    use ::sysid_control::tuning::{self, Request, Source};
    let spec = ::control::tune::Spec::parse(spec).map_err(control_err)?;
    if variants == 0 {
        return Err(setting_err(
            "--variants",
            0,
            "at least 1 (the nominal plant)",
        ));
    }
    let source = match (model, plant_config) {
        (Some(obj), None) => {
            let (m, label) = match obj.cast::<PyModel>() {
                Ok(pm) => (pm.get().inner.clone(), "model (Python)".to_string()),
                Err(_) => {
                    // A path in any of its forms (`str`, `bytes`, `os.PathLike`: audit s35 L-8,
                    // a bytes path was refused as "a Model or the path of a model file").
                    let path: PathBuf = path_arg("model", obj).map_err(|_| {
                        setting_err(
                            "--model",
                            obj.to_string(),
                            "a Model or the path of a model file",
                        )
                    })?;
                    let m = sysid::model_file::read_model(&path)
                        .map_err(|e| PyValueError::new_err(format!("cannot read --model: {e}")))?;
                    (m, format!("model {}", path.display()))
                }
            };
            let deadzone = ::control::compensator::command_deadzone(&m)
                .map_err(|p| setting_err("--model", &label, &p.to_string()))?;
            Source::Model {
                model: m,
                deadzone,
                label,
            }
        }
        (None, Some(path)) => Source::Twin {
            config: ipa::PlantConfig::from_toml_file(&path).map_err(ipa_err)?,
            label: format!("twin {}", path.display()),
        },
        _ => {
            return Err(setting_err(
                "--model/--plant-config",
                "",
                "exactly one of model or plant_config",
            ))
        }
    };
    let req = Request {
        source,
        spec,
        search: ::control::tune::TuneSettings {
            plants: variants,
            max_evaluations,
        },
        check_physics,
        physics_variants,
        cancel: sysid::Stop::never(),
    };
    let report = compute(py, |stop| {
        tuning::run(&Request {
            cancel: stop.clone(),
            ..req.clone()
        })
    })?
    .map_err(control_err)?;
    // With its provenance, as `tune --out` writes it: control() repeats a missed spec (audit s18 M-4).
    let file = report.controller_file();
    let text = serde_json::to_string_pretty(&file)
        .map_err(|e| PyArithmeticError::new_err(format!("serialising the controller: {e}")))?;
    let out = to_py(py, &report)?;
    out.set_item("controller_file", text + "\n")?;
    Ok(out)
}

/// Calibrates the physics plant to a record, as `ipa-sysid calibrate --no-baseline` (without the
/// Hammerstein comparison, which `identify` gives): `data` and `validation` are CSV paths (columns u,
/// y and, when present, p_a_pa, p_b_pa; the validation record's own columns `val_u_col`/`val_y_col`,
/// default `u_col`/`y_col`); returns a dict with the keys of `calibrate --no-baseline --json`:
/// "estimates" (parameter, key, unit, start, value, std, at_bound), "correlation", "ts", "segments",
/// "used_pressures", "iterations", "simulations", "termination", "cost_start", "cost", "cost_floor",
/// "segment_rmse_mm", the free-run fits from the measured initial state keyed as `identify`'s metrics —
/// "metrics" (the twin) and "start_metrics" (the start plant), each {"estimation": {...},
/// "validation": {...}} with "fit_sim_measured_percent" and "rmse_sim_measured" — "hammerstein"
/// (None), "seconds", "warnings"; and "toml" (the plant-config of the twin, as `--out` writes it, with
/// its `[calibration]` table of fits and warnings). `max_memory_gb` bounds, as `calibrate
/// --max-memory`, the bytes the reader may inflate from a compressed `.mat` record (a file declaring
/// more is a `ValueError` naming it, before they are allocated).
#[pyfunction]
#[pyo3(signature = (data, validation=None, free=None, fixed=None, plant_config=None, segment=0.5,
    max_iterations=40, ts=None, u_col="u", y_col="y", t_col="t", no_header=false, val_u_col=None,
    val_y_col=None, max_memory_gb=4.0))]
#[allow(clippy::too_many_arguments)]
fn calibrate<'py>(
    py: Python<'py>,
    data: &Bound<'py, PyAny>,
    validation: Option<&Bound<'py, PyAny>>,
    free: Option<&str>,
    fixed: Option<&str>,
    plant_config: Option<&Bound<'py, PyAny>>,
    segment: f64,
    max_iterations: usize,
    ts: Option<f64>,
    u_col: &str,
    y_col: &str,
    t_col: &str,
    no_header: bool,
    val_u_col: Option<&str>,
    val_y_col: Option<&str>,
    max_memory_gb: f64,
) -> PyResult<Bound<'py, PyDict>> {
    use ipa::calibrate::Calibration;
    let data = path_arg("data", data)?;
    let validation = validation.map(|v| path_arg("validation", v)).transpose()?;
    // Every path argument by the one conversion (`str`, `bytes` or `os.PathLike`; audit s35 L-8).
    let plant_config = plant_config
        .map(|v| path_arg("plant_config", v))
        .transpose()?;
    let max_memory = memory_budget(max_memory_gb)?;
    if validation.is_none() && (val_u_col.is_some() || val_y_col.is_some()) {
        return Err(PyValueError::new_err(
            "val_u_col/val_y_col name columns of the validation record: give validation=PATH",
        ));
    }
    let start = match &plant_config {
        Some(p) => ipa::PlantConfig::from_toml_file(p).map_err(ipa_err)?,
        None => ipa::PlantConfig::default(),
    };
    let free_set = ipa::calibrate::free_parameters(free, fixed).map_err(ipa_err)?;
    let cal = Calibration {
        start,
        free: free_set,
        segment_s: segment,
        max_iterations,
        ..Calibration::default()
    };
    // The columns as the command line's --u-col/--y-col/--t-col/--no-header (audit s14 L-k: the
    // error named a u_col the function did not have).
    let opts = sysid::data::CsvOptions {
        ts,
        u_col: u_col.to_string(),
        y_col: y_col.to_string(),
        t_col: t_col.to_string(),
        no_header,
        // The reader's own bytes (a `.mat` record's inflated variables) within `max_memory_gb`, as
        // `calibrate --max-memory` bounds them.
        max_read_bytes: Some(max_memory.bytes()),
        ..sysid::data::CsvOptions::default()
    };
    // The validation record's own columns, as --val-u-col/--val-y-col (audit s14 L-e).
    let val_opts = sysid::data::CsvOptions {
        u_col: val_u_col.unwrap_or(u_col).to_string(),
        y_col: val_y_col.unwrap_or(y_col).to_string(),
        ..opts.clone()
    };
    let (est, val, notes) = ipa::calibrate::read_records(
        &data,
        validation.as_deref().map(|v| (v, &val_opts)),
        &opts,
        None,
    )
    .map_err(ipa_err)?;
    let started = std::time::Instant::now();
    let mut twin = compute(py, |stop| {
        let cal = Calibration {
            cancel: stop.clone(),
            ..cal.clone()
        };
        cal.fit(&est, val.as_ref())
    })?
    .map_err(ipa_err)?;
    let seconds = started.elapsed().as_secs_f64();
    twin.warnings.splice(0..0, notes);
    let out = PyDict::new(py);
    let estimates = PyList::empty(py);
    for e in &twin.estimates {
        let d = PyDict::new(py);
        d.set_item("parameter", e.parameter.name())?;
        d.set_item("key", e.parameter.key())?;
        d.set_item("unit", e.parameter.unit())?;
        d.set_item("start", e.start)?;
        d.set_item("value", e.value)?;
        d.set_item("std", e.std)?;
        d.set_item("at_bound", e.at_bound)?;
        estimates.append(d)?;
    }
    out.set_item("estimates", estimates)?;
    out.set_item("correlation", twin.correlation.clone())?;
    // The keys of `calibrate --json` (audit s18 L-2), NaN as None as it writes null.
    let finite = |v: f64| v.is_finite().then_some(v);
    out.set_item("ts", est.ts)?;
    out.set_item("used_pressures", twin.used_pressures)?;
    out.set_item("segments", twin.segments)?;
    out.set_item("iterations", twin.iterations)?;
    out.set_item("simulations", twin.evaluations)?;
    out.set_item("termination", twin.termination.to_string())?;
    out.set_item("cost_start", twin.cost_start)?;
    out.set_item("cost", twin.cost)?;
    out.set_item("cost_floor", twin.cost_floor)?;
    out.set_item("segment_rmse_mm", finite(twin.segment_rmse_mm))?;
    // Keyed as identify's metrics and `calibrate --json` (audit s17 L-d).
    out.set_item("metrics", to_py(py, &twin.metrics())?)?;
    out.set_item("start_metrics", to_py(py, &twin.start_metrics())?)?;
    // No Hammerstein comparison (`identify` gives one): None, as `calibrate --no-baseline --json`.
    out.set_item("hammerstein", py.None())?;
    out.set_item("seconds", seconds)?;
    out.set_item(
        "warnings",
        twin.warnings
            .iter()
            .map(ToString::to_string)
            .collect::<Vec<_>>(),
    )?;
    out.set_item("toml", twin.twin_toml(&data.display().to_string(), est.ts))?;
    Ok(out)
}

/// Looks at the output path `path` (the argument `argument`) as the command line looks at an output
/// flag before any work (`sysid_io::resolve_output`): a folder, a socket, a link to nothing and a
/// read-only file are refused (`ValueError` naming `argument`, the command line's words); a new name, a
/// regular file, a device, a FIFO and a link to a device or FIFO pass; a link to a regular file passes
/// only with `force` (the command line's `--force`).
#[pyfunction]
#[pyo3(signature = (path, argument, force = false))]
fn check_output(path: PathBuf, argument: &str, force: bool) -> PyResult<()> {
    sysid_io::resolve_output_as(&path, argument, force)
        .map(drop)
        .map_err(output_err)
}

/// Writes `data` to the output path `path` (the argument `argument`) as the command line writes every
/// output and `Model.save` its file (`sysid_io::write_atomic`, after [`check_output`]): a regular file
/// or a new name atomically (a temporary file beside it, renamed over it; the permissions and owner of
/// the file it replaces, or 0o666 less the umask), a device or a FIFO written into directly and never
/// replaced (`/dev/full` raises `OSError` "No space left on device"), `-` to standard output. An
/// existing regular file is replaced only by the same kind of file (`sysid_io::FileKind`: a model file
/// by a model file, a CSV by a CSV with the same header row) and a symbolic link to a file is refused,
/// unless `force` (then the link is followed: the file it names is replaced, the link stays). The GIL
/// is released while it writes (a FIFO waits for its reader, which may be another Python thread; Ctrl-C
/// and signal handlers' exceptions end that wait).
#[pyfunction]
#[pyo3(signature = (path, data, argument, force = false))]
fn write_output(
    py: Python<'_>,
    path: PathBuf,
    data: &[u8],
    argument: &str,
    force: bool,
) -> PyResult<()> {
    check_output(path.clone(), argument, force)?;
    // A FIFO waits for its reader (and a full pipe for it to read) in pieces of 10 ms, with Python's
    // signal check between them: Ctrl-C or an alarm handler's exception ends the wait (audit s25: a
    // blocking open is restarted after every signal, so `Model.save` into a FIFO nobody reads hung
    // for good and no handler ran). The exception raised is the handler's own.
    let mut raised: Option<PyErr> = None;
    let written = py.detach(|| {
        let mut check = || {
            Python::attach(|py| py.check_signals()).map_err(|e| {
                raised = Some(e);
                std::io::Error::new(
                    std::io::ErrorKind::Interrupted,
                    "interrupted while waiting for the FIFO's reader",
                )
            })
        };
        sysid_io::write_all_atomic_waiting(&[(&path, data)], force, Some(&mut check))
    });
    if let Some(e) = raised {
        return Err(e);
    }
    written.map(drop).map_err(output_err)
}

/// ipa-sysid from Python: identification (Hammerstein/ARX by LS, RLS, OE, IV), recursive least
/// squares, the physics IPA simulator and PI control, computed in Rust. The package `ipa_sysid` wraps
/// this module; see its docstring and docs/python.md.
#[pymodule]
fn _core(m: &Bound<'_, PyModule>) -> PyResult<()> {
    // numpy's C API (its capsule, the borrow checker's) is loaded now, where a failure is an
    // ImportError, and not by the first array a long call returns: loading it runs Python code, where
    // a Ctrl-C pressed during the call was raised and the numpy crate panicked on it (audit s23 H-P1:
    // `PanicException` "Failed to access NumPy array API capsule" instead of `KeyboardInterrupt`).
    let py = m.py();
    // The output messages name the override by its keyword (`force=True`), not `--force`.
    sysid_io::set_force_word("force=True");
    py.import("numpy")?;
    py.import("numpy.lib")?;
    let warm = PyArray1::<f64>::zeros(py, 0, false);
    drop(numpy::PyArrayMethods::readonly(&warm));
    drop(PyArray1::<Complex64>::zeros(py, 0, false));
    m.add_class::<PyModel>()?;
    m.add_class::<PyFit>()?;
    m.add_class::<PyNarxFit>()?;
    m.add_class::<PyRls>()?;
    m.add_function(wrap_pyfunction!(identify, m)?)?;
    m.add_function(wrap_pyfunction!(load_model, m)?)?;
    m.add_function(wrap_pyfunction!(_model_from_json, m)?)?;
    m.add_function(wrap_pyfunction!(_fit_restore, m)?)?;
    m.add_function(wrap_pyfunction!(_narx_fit_restore, m)?)?;
    m.add_function(wrap_pyfunction!(paper_model, m)?)?;
    m.add_function(wrap_pyfunction!(simulate_plant, m)?)?;
    m.add_function(wrap_pyfunction!(calibrate, m)?)?;
    m.add_function(wrap_pyfunction!(control_loop, m)?)?;
    m.add_function(wrap_pyfunction!(tune, m)?)?;
    m.add_function(wrap_pyfunction!(fleet_windows, m)?)?;
    m.add_function(wrap_pyfunction!(fleet_times, m)?)?;
    m.add_function(wrap_pyfunction!(check_output, m)?)?;
    m.add_function(wrap_pyfunction!(write_output, m)?)?;
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    Ok(())
}
