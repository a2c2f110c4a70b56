//! MATLAB `.mat` records (`--data rec.mat`): Level 5 MAT-files, as written by MATLAB's `save` (default
//! `-v7`, compressed, and `-v6`) and by `scipy.io.savemat`, read with the `matfile` crate.
//!
//! `--u-col` / `--y-col` / `--t-col` name variables: real numeric vectors (row or column, any numeric
//! class, converted to f64). Ts comes from `--ts`, or from the time variable (uniform within 0.1 %, or
//! resampled with `--resample`); `--rows` and `--time-unit` apply as for CSV. MATLAB v7.3 files (HDF5)
//! and Level 4 files are refused with the way out: save with `-v7`.

use matfile::{MatFile, NumericData};

use super::{check_ts, resample, CsvOptions, Record, Signals};
use crate::error::Setting;
use crate::{Dataset, SysidError};

/// True when `bytes` look like a MAT-file (Level 5 or v7.3 header text).
pub fn is_mat(bytes: &[u8]) -> bool {
    bytes.starts_with(b"MATLAB 5.0 MAT-file") || bytes.starts_with(b"MATLAB 7.3 MAT-file")
}

fn file_err(name: &str, message: String) -> SysidError {
    SysidError::File {
        file: name.to_string(),
        message,
    }
}

/// Reads a record from the bytes of a `.mat` file; `name` is used in messages.
pub fn read_mat_bytes(bytes: &[u8], name: &str, opts: &CsvOptions) -> Result<Record, SysidError> {
    if bytes.starts_with(b"MATLAB 7.3 MAT-file")
        || bytes.get(512..520) == Some(b"\x89HDF\r\n\x1a\n")
    {
        return Err(file_err(
            name,
            "a MATLAB v7.3 (HDF5) MAT-file, which is not supported; save it in MATLAB with \
             save('file.mat', 'u', 'y', '-v7') (or -v6), or export to CSV"
                .into(),
        ));
    }
    if !bytes.starts_with(b"MATLAB 5.0 MAT-file") {
        return Err(file_err(
            name,
            "not a Level 5 MAT-file (no 'MATLAB 5.0 MAT-file' header; a Level 4 file?); save it in \
             MATLAB with save('file.mat', 'u', 'y', '-v7'), or export to CSV"
                .into(),
        ));
    }
    let mat = MatFile::parse(bytes).map_err(|e| {
        file_err(
            name,
            format!("the MAT-file could not be read ({e}); truncated or damaged? expected a file saved with -v7"),
        )
    })?;
    let names = || {
        let v: Vec<&str> = mat.arrays().iter().map(|a| a.name()).collect();
        if v.is_empty() {
            "none readable".to_string()
        } else {
            v.join(", ")
        }
    };
    let vector = |var: &str, setting: Setting| -> Result<Vec<f64>, SysidError> {
        let Some(a) = mat.find_by_name(var) else {
            return Err(SysidError::MissingColumn {
                file: name.to_string(),
                column: var.to_string(),
                setting,
                header: mat.arrays().iter().map(|a| a.name().to_string()).collect(),
                hint: None,
            });
        };
        let size = a.size();
        let long = size.iter().filter(|&&d| d > 1).count();
        if long > 1 {
            return Err(file_err(
                name,
                format!(
                    "variable '{var}' is a {} array; expected a vector (one row or one column)",
                    size.iter()
                        .map(usize::to_string)
                        .collect::<Vec<_>>()
                        .join("x")
                ),
            ));
        }
        let v = real_f64(a.data()).ok_or_else(|| {
            file_err(
                name,
                format!("variable '{var}' is complex; expected a real vector"),
            )
        })?;
        if let Some(k) = v.iter().position(|x| !x.is_finite()) {
            return Err(file_err(
                name,
                format!(
                    "variable '{var}' element {} (1-based) is {}; expected finite numbers (remove or fill \
                     missing samples)",
                    k + 1,
                    v[k]
                ),
            ));
        }
        Ok(v)
    };
    let mut u = vector(&opts.u_col, Setting::UCol)?;
    let mut y = vector(&opts.y_col, Setting::YCol)?;
    if u.len() != y.len() {
        return Err(file_err(
            name,
            format!(
                "'{}' has {} samples but '{}' has {}; expected vectors of the same length",
                opts.u_col,
                u.len(),
                opts.y_col,
                y.len()
            ),
        ));
    }
    let has_t = mat.find_by_name(&opts.t_col).is_some();
    let mut t = if has_t && opts.ts.is_none() {
        let t = vector(&opts.t_col, Setting::TCol)?;
        if t.len() != u.len() {
            return Err(file_err(
                name,
                format!(
                    "time variable '{}' has {} samples but '{}' has {}",
                    opts.t_col,
                    t.len(),
                    opts.u_col,
                    u.len()
                ),
            ));
        }
        Some(
            t.iter()
                .map(|v| v * opts.time_unit.seconds())
                .collect::<Vec<f64>>(),
        )
    } else {
        None
    };
    let mut name = name.to_string();
    if let Some(r) = &opts.rows {
        let range = r.resolve(u.len(), opts.rows_flag, &name)?;
        u = u[range.clone()].to_vec();
        y = y[range.clone()].to_vec();
        t = t.map(|t| t[range.clone()].to_vec());
        name = format!("{name}[{}..{}]", range.start, range.end);
    }
    let mut notes = Vec::new();
    let ts = match (opts.resample, &t, opts.ts.or(if has_t { None } else { opts.fallback_ts })) {
        (Some(ts), Some(t), _) => {
            increasing(t, &name, &opts.t_col)?;
            let r = resample::resample_record(t, &u, &y, ts, &name)?;
            (u, y) = (r.u, r.y);
            notes.push(r.note);
            ts
        }
        (_, _, Some(ts)) => {
            check_ts(ts)?;
            ts
        }
        (_, Some(t), None) => {
            increasing(t, &name, &opts.t_col)?;
            let sp = resample::spacing(t);
            if sp.irregular > 0.0 {
                return Err(file_err(
                    &name,
                    format!(
                        "non-uniform sampling in '{}': steps from {} to {} s (median {} s); pass \
                         --resample TS to interpolate onto a uniform grid, or --ts",
                        opts.t_col, sp.min, sp.max, sp.median
                    ),
                ));
            }
            (t[t.len() - 1] - t[0]) / (t.len() - 1) as f64
        }
        (_, None, None) => {
            return Err(file_err(
                &name,
                format!(
                    "no time variable '{}' and no --ts: pass --ts SECONDS or name the time variable with \
                     --t-col (variables are: {})",
                    opts.t_col,
                    names()
                ),
            ))
        }
    };
    Ok(Record {
        data: Dataset::new(Signals { u, y }, ts, name)?,
        notes,
    })
}

fn increasing(t: &[f64], name: &str, var: &str) -> Result<(), SysidError> {
    if t.len() < 2 {
        return Err(file_err(
            name,
            "one sample is not enough to find Ts; pass --ts".into(),
        ));
    }
    match t.windows(2).position(|w| w[1] <= w[0]) {
        Some(k) => Err(file_err(
            name,
            format!(
                "time variable '{var}' does not increase at element {} (1-based): {} after {}; expected \
                 strictly increasing time",
                k + 2,
                t[k + 1],
                t[k]
            ),
        )),
        None => Ok(()),
    }
}

/// The real part of a numeric array as f64, `None` when it has an imaginary part.
fn real_f64(d: &NumericData) -> Option<Vec<f64>> {
    fn conv<T: Copy + Into<f64>, I>(real: &[T], imag: &Option<I>) -> Option<Vec<f64>> {
        imag.is_none()
            .then(|| real.iter().map(|&v| v.into()).collect())
    }
    match d {
        NumericData::Double { real, imag } => conv(real, imag),
        NumericData::Single { real, imag } => conv(real, imag),
        NumericData::Int8 { real, imag } => conv(real, imag),
        NumericData::UInt8 { real, imag } => conv(real, imag),
        NumericData::Int16 { real, imag } => conv(real, imag),
        NumericData::UInt16 { real, imag } => conv(real, imag),
        NumericData::Int32 { real, imag } => conv(real, imag),
        NumericData::UInt32 { real, imag } => conv(real, imag),
        // 64-bit integers have no lossless f64 conversion; sample values fit in 2^53.
        NumericData::Int64 { real, imag } => imag
            .is_none()
            .then(|| real.iter().map(|&v| v as f64).collect()),
        NumericData::UInt64 { real, imag } => imag
            .is_none()
            .then(|| real.iter().map(|&v| v as f64).collect()),
    }
}
