//! MATLAB `.mat` records (`--data rec.mat`): Level 5 MAT-files, as written by MATLAB's `save` (default
//! `-v7`, compressed, and `-v6`) and by `scipy.io.savemat`.
//!
//! The reader is this module's own: the subset of the MAT-File Format (MathWorks, "MAT-File Format",
//! chapter 1, Level 5) that a record needs. It replaced the `matfile` crate (0.5, unmaintained), which
//! printed to standard output on an unsupported element (so `--json -` emitted invalid JSON), printed
//! raw debug lines on a damaged compressed element, inflated compressed elements without a bound (a 1 MB
//! file could inflate to 1 GiB) and refused some integer classes. What is read:
//! - a 128-byte header (text, version, the endian indicator `IM` or `MI`), then data elements, each an
//!   8-byte tag (type, byte count; or the 4-byte "small element" form) and its data, padded to 8 bytes
//!   except a compressed element;
//! - a variable is a `miMATRIX` element (array flags with the class, dimensions, name, real part,
//!   imaginary part when complex), or a zlib-compressed `miCOMPRESSED` element holding one;
//! - the numeric classes (double, single, int8..uint64, logical) whatever storage type holds the values
//!   (MATLAB stores doubles as small integers when they fit), converted to f64; other classes (char,
//!   cell, struct, sparse, objects) are listed by name and refused when chosen;
//! - only the variables asked for are inflated in full, after the size their element announces is
//!   checked against [`super::MAX_SAMPLES`]; the others are inflated only far enough (64 KiB) to learn
//!   their name;
//! - a file that ends inside an element is reported as truncated, naming the variable when it is known.
//!
//! `--u-col` / `--y-col` / `--t-col` name variables: real numeric vectors (row or column, any numeric
//! class, converted to f64). Ts comes from `--ts`, or from the time variable (uniform within 0.1 %, or
//! resampled with `--resample`); `--rows` and `--time-unit` apply as for CSV. MATLAB v7.3 files (HDF5)
//! and Level 4 files are refused with the way out: save with `-v7`.

use std::io::Read;

use super::{
    check_ts, increasing_time, resample, time_fault_message, time_goes_back, time_notes,
    uniform_time, CsvOptions, Record, Signals, TimeFacts, TimeFault,
};
use crate::error::Setting;
use crate::{Dataset, SysidError};

/// True when `path` is named `*.mat` (any case): the readers take such a file for a MAT-file whatever
/// its bytes, and the streaming reader, which reads CSV text, refuses it.
pub fn has_mat_name(path: &std::path::Path) -> bool {
    path.extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("mat"))
}

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
    // Several inputs (`--u-col u1,u2`) are several variables, as several columns of a CSV (audit s31
    // L-1: the list was looked up as one name, and refused while the file held u1 and u2).
    let inputs = opts.input_names();
    let mut wanted: Vec<&str> = inputs.iter().map(String::as_str).collect();
    wanted.extend([opts.y_col.as_str(), opts.t_col.as_str()]);
    let vars = parse(bytes, name, &wanted, opts.max_read_bytes)?;
    if vars.is_empty() {
        // A header and nothing else (audit s13 L8: "no column named 'u'; the header has: ").
        return Err(file_err(
            name,
            "the MAT-file holds no variables; expected the vectors u and y (save('file.mat', 'u', 'y', \
             '-v7'))"
                .into(),
        ));
    }
    // Two variables of one name (a file MATLAB's `save` cannot write): which one `load` would give is
    // not something to guess for a record, so a chosen name that appears twice is refused with both
    // places (audit s16 L2); a duplicated name that is not chosen is not read and does no harm.
    let find = |var: &str| -> Result<Option<&Variable>, SysidError> {
        let mut same = vars.iter().filter(|v| v.name == var);
        match (same.next(), same.next()) {
            (Some(a), Some(b)) => Err(file_err(
                name,
                format!(
                    "two variables are named '{var}' (data element {} at byte {} and data element {} at \
                     byte {}); expected one variable of each name: save the record again, or choose \
                     another variable",
                    a.element, a.offset, b.element, b.offset
                ),
            )),
            (a, _) => Ok(a),
        }
    };
    let names = || {
        let v: Vec<&str> = vars.iter().map(|a| a.name.as_str()).collect();
        if v.is_empty() {
            "none readable".to_string()
        } else {
            v.join(", ")
        }
    };
    let vector = |var: &str, setting: Setting| -> Result<Vec<f64>, SysidError> {
        let Some(a) = find(var)? else {
            // A MATLAB object (an iddata saved whole: class object, or opaque for MCOS classes)
            // holds its vectors inside, where this reader does not go (audit s23 L-N2).
            if let Some(o) = vars
                .iter()
                .find(|a| matches!(a.values, Values::Class("object" | "non-numeric")))
            {
                let z = if o.name == "MCOS" || o.name.is_empty() {
                    "z".to_string()
                } else {
                    o.name.clone()
                };
                return Err(file_err(
                    name,
                    format!(
                        "no variable named '{var}'; the file holds a MATLAB object ('{}'), which this \
                         reader cannot open (an iddata saved whole); save its vectors instead: u = \
                         {z}.InputData; y = {z}.OutputData; save('{z}.mat', 'u', 'y')",
                        o.name
                    ),
                ));
            }
            // A matrix of signals side by side (MATLAB's z = [u y]) in a file with no vector to
            // choose instead: said with the way to save its columns as the vectors this reader reads
            // (audit s34 L-8).
            let long = |a: &&Variable| a.dims.iter().filter(|&&d| d > 1).count();
            let matrix = vars.iter().find(|a| long(a) > 1);
            if let Some(m) = matrix.filter(|_| !vars.iter().any(|a| long(&a) == 1)) {
                return Err(file_err(
                    name,
                    format!(
                        "no variable named '{var}'; the file holds '{}', a {} matrix, and this reader \
                         reads vectors only{}",
                        m.name,
                        dims_text(&m.dims),
                        matrix_way_out(&m.name, &m.dims)
                    ),
                ));
            }
            return Err(SysidError::MissingVariable {
                file: name.to_string(),
                variable: var.to_string(),
                setting,
                variables: vars.iter().map(|a| a.name.clone()).collect(),
            });
        };
        let v = match &a.values {
            Values::Real(v) => {
                // Copied fallibly: a record near the limit is hundreds of MB (audit s23 H-B1).
                let mut copy = Vec::new();
                copy.try_reserve_exact(v.len()).map_err(|_| {
                    file_err(
                        name,
                        format!(
                            "not enough memory to read variable '{var}': {} bytes ({} GB) could not \
                             be allocated; save a part of the record, or run where more memory is free",
                            8 * v.len() as u64,
                            crate::ls::format_gb(8 * v.len() as u64)
                        ),
                    )
                })?;
                copy.extend_from_slice(v);
                copy
            }
            Values::Complex => {
                return Err(file_err(
                    name,
                    format!("variable '{var}' is complex; expected a real vector"),
                ))
            }
            Values::Class(class) => {
                return Err(file_err(
                    name,
                    format!(
                        "variable '{var}' is a {class} array; expected a numeric vector (double, single or \
                         an integer class)"
                    ),
                ))
            }
            Values::NotRead => {
                return Err(file_err(
                    name,
                    format!("variable '{var}' was not read (internal: not asked for)"),
                ))
            }
        };
        let long = a.dims.iter().filter(|&&d| d > 1).count();
        if long > 1 {
            return Err(file_err(
                name,
                format!(
                    "variable '{var}' is a {} array; expected a vector (one row or one column){}",
                    dims_text(&a.dims),
                    matrix_way_out(var, &a.dims)
                ),
            ));
        }
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
    let mut us = inputs
        .iter()
        .map(|var| vector(var, Setting::UCol))
        .collect::<Result<Vec<_>, _>>()?;
    let mut y = vector(&opts.y_col, Setting::YCol)?;
    for (var, u) in inputs.iter().zip(&us) {
        if u.len() != y.len() {
            return Err(file_err(
                name,
                format!(
                    "'{var}' has {} samples but '{}' has {}; expected vectors of the same length",
                    u.len(),
                    opts.y_col,
                    y.len()
                ),
            ));
        }
    }
    let n = y.len();
    // The time variable is read when there is one, also under --ts (its notes: audit s27 M-2).
    let t_exists = find(&opts.t_col)?.is_some();
    let has_t = opts.ts.is_none() && t_exists;
    let t_read = match (has_t, t_exists) {
        (true, _) => Some(vector(&opts.t_col, Setting::TCol)?),
        // Under --ts a time variable that is not a vector of the record's length is not checked.
        (false, true) => vector(&opts.t_col, Setting::TCol)
            .ok()
            .filter(|t| t.len() == n),
        (false, false) => None,
    };
    let mut t = if let Some(t) = t_read {
        if t.len() != n {
            return Err(file_err(
                name,
                format!(
                    "time variable '{}' has {} samples but '{}' has {n}",
                    opts.t_col,
                    t.len(),
                    opts.y_col,
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
    let mut first = 0;
    if let Some(r) = &opts.rows {
        let range = r.resolve(n, opts.rows_flag, &name)?;
        first = range.start;
        for u in &mut us {
            *u = u[range.clone()].to_vec();
        }
        y = y[range.clone()].to_vec();
        t = t.map(|t| t[range.clone()].to_vec());
        name = format!("{name}[{}..{}]", range.start, range.end);
    }
    let mut notes = Vec::new();
    // The CSV readers' outlier note (`super::lone_outlier`), at the element's place in its variable.
    for (var, values) in inputs.iter().zip(&us).chain([(&opts.y_col, &y)]) {
        let mut l = crate::ls::Largest::default();
        for (k, &v) in values.iter().enumerate() {
            l.push(k, v);
        }
        let place = || {
            format!(
                "{name}: variable '{var}' element {} (1-based)",
                first + l.at + 1
            )
        };
        notes.extend(super::outlier_note(&l, place, var));
    }
    let time_err = |fault: TimeFault| time_error(fault, &name, &opts.t_col);
    let ts = match (opts.resample, &t, opts.ts.or(if has_t { None } else { opts.fallback_ts })) {
        (Some(ts), Some(t), _) => {
            increasing_time(t).map_err(time_err)?;
            let mut ry = Vec::new();
            for u in &mut us {
                let r = resample::resample_record(t, u, &y, ts, &name)?;
                if ry.is_empty() {
                    notes.push(r.note);
                }
                *u = r.u;
                ry = r.y;
            }
            y = ry;
            ts
        }
        (_, t, Some(ts)) => {
            check_ts(ts)?;
            if let (Some(t), Some(given)) = (t, opts.ts) {
                if let Some(fault) = time_goes_back(t) {
                    return Err(time_err(fault));
                }
                notes.extend(time_notes(&TimeFacts::of(t), Some(given), ts, opts.time_unit, &opts.t_col));
            }
            ts
        }
        (_, Some(t), None) => {
            let ts = uniform_time(t).map_err(time_err)?;
            notes.extend(time_notes(&TimeFacts::of(t), None, ts, opts.time_unit, &opts.t_col));
            ts
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
    let t0 = t.as_ref().and_then(|t| t.first().copied());
    let data = if inputs.len() == 1 {
        let u = us.into_iter().next().unwrap_or_default();
        Dataset::new(Signals { u, y }, ts, name)?
    } else {
        Dataset::with_inputs(inputs.into_iter().zip(us).collect(), y, ts, name)?
    };
    Ok(Record { data, notes, t0 })
}

/// A fault of the time variable `var` as the reader's error, at its element (1-based) when it has one:
/// the words and advice of every reader ([`time_fault_message`]).
fn time_error(fault: TimeFault, name: &str, var: &str) -> SysidError {
    let message = time_fault_message(&fault);
    match fault.sample() {
        Some(k) => file_err(
            name,
            format!(
                "time variable '{var}' element {} (1-based): {message}",
                k + 1
            ),
        ),
        None => file_err(name, format!("time variable '{var}': {message}")),
    }
}

/// A variable of a MAT-file: its name, dimensions and (when asked for and numeric) its values, and
/// where it is (for messages).
#[derive(Debug)]
struct Variable {
    /// The top-level data element that holds it, 1-based.
    element: usize,
    /// The byte of the file its element starts at.
    offset: usize,
    name: String,
    dims: Vec<usize>,
    values: Values,
}

/// A variable's dimensions as MATLAB prints them (`600x2`).
fn dims_text(dims: &[usize]) -> String {
    dims.iter()
        .map(usize::to_string)
        .collect::<Vec<_>>()
        .join("x")
}

/// The way out of a matrix variable `var` of `dims` (signals side by side, MATLAB's `z = [u y]`):
/// the MATLAB lines that save its first two columns (or rows, for a 2xN matrix) as the vectors u and y
/// this reader reads.
fn matrix_way_out(var: &str, dims: &[usize]) -> String {
    let (first, second) = if dims.first() == Some(&2) && dims.get(1).is_some_and(|&n| n > 2) {
        (format!("{var}(1,:)"), format!("{var}(2,:)"))
    } else {
        (format!("{var}(:,1)"), format!("{var}(:,2)"))
    };
    format!(
        " (signals side by side, as in z = [u y]?): save them as vectors, e.g. in MATLAB u = {first}; \
         y = {second}; save('record.mat', 'u', 'y') (choose the columns that hold the input and the output)"
    )
}

/// What was read of a variable's values.
#[derive(Debug)]
enum Values {
    /// The real values, column-major, as f64.
    Real(Vec<f64>),
    /// A complex numeric array (refused when chosen).
    Complex,
    /// A class that is not numeric (named for the message).
    Class(&'static str),
    /// A numeric variable that was not asked for: its data were not read (nor inflated).
    NotRead,
}

/// A byte order.
#[derive(Debug, Clone, Copy)]
enum Endian {
    Little,
    Big,
}

/// A cursor over the bytes of one element, with the file name and the variable for messages.
struct Cursor<'a> {
    bytes: &'a [u8],
    at: usize,
    endian: Endian,
}

/// Why a parse stopped: the data end too early, or they are not what the format says.
enum Stop {
    Truncated,
    Damaged(String),
    /// A fallible allocation of this many bytes failed (the memory left is too small for the record).
    Memory(u64),
    /// Inflating the variable would bring the reader's inflated bytes to `need`, more than `budget`
    /// ([`CsvOptions::max_read_bytes`], `--max-memory`).
    Budget {
        need: u64,
        budget: u64,
    },
}

const MI_INT8: u32 = 1;
const MI_UINT8: u32 = 2;
const MI_INT16: u32 = 3;
const MI_UINT16: u32 = 4;
const MI_INT32: u32 = 5;
const MI_UINT32: u32 = 6;
const MI_SINGLE: u32 = 7;
const MI_DOUBLE: u32 = 9;
const MI_INT64: u32 = 12;
const MI_UINT64: u32 = 13;
const MI_MATRIX: u32 = 14;
const MI_COMPRESSED: u32 = 15;
const MI_UTF8: u32 = 16;

/// Inflated bytes looked at to learn a compressed variable's name and size before it is inflated whole.
const PEEK_BYTES: u64 = 1 << 16;

impl<'a> Cursor<'a> {
    fn u32(&mut self) -> Result<u32, Stop> {
        let b: [u8; 4] = self
            .bytes
            .get(self.at..self.at + 4)
            .and_then(|s| s.try_into().ok())
            .ok_or(Stop::Truncated)?;
        self.at += 4;
        Ok(match self.endian {
            Endian::Little => u32::from_le_bytes(b),
            Endian::Big => u32::from_be_bytes(b),
        })
    }

    /// A tag and its data: (type, data); moves past the padding to 8 bytes unless `packed`.
    fn element(&mut self, packed: bool) -> Result<(u32, &'a [u8]), Stop> {
        let first = self.u32()?;
        if first >> 16 != 0 {
            // The small data element: byte count in the upper half, data in the next 4 bytes.
            let (ty, n) = (first & 0xffff, (first >> 16) as usize);
            if n > 4 {
                return Err(Stop::Damaged(format!(
                    "a small data element of {n} bytes (at most 4)"
                )));
            }
            let data = self
                .bytes
                .get(self.at..self.at + n)
                .ok_or(Stop::Truncated)?;
            self.at += 4;
            return Ok((ty, data));
        }
        let n = self.u32()? as usize;
        let end = self.at.checked_add(n).ok_or(Stop::Truncated)?;
        let data = self.bytes.get(self.at..end).ok_or(Stop::Truncated)?;
        self.at = if packed { end } else { end.div_ceil(8) * 8 };
        Ok((first, data))
    }
}

/// The variables of a Level 5 MAT-file (`bytes`, named `name` in messages); the values of those named
/// in `wanted` are read (see the module documentation).
/// `budget`: the most bytes the wanted variables' compressed elements may inflate to, together.
fn parse(
    bytes: &[u8],
    name: &str,
    wanted: &[&str],
    budget: Option<u64>,
) -> Result<Vec<Variable>, SysidError> {
    // Inflated bytes of the wanted variables read so far (counted against `budget`).
    let mut inflated: u64 = 0;
    let endian = match bytes.get(126..128) {
        Some(b"IM") => Endian::Little,
        Some(b"MI") => Endian::Big,
        Some(_) => {
            return Err(file_err(
                name,
                "the MAT-file header has no endian indicator (IM or MI at byte 126); damaged? expected \
                 a file saved with -v7"
                    .into(),
            ))
        }
        None => {
            return Err(file_err(
                name,
                format!(
                    "the file ends within the 128-byte MAT-file header ({} bytes; truncated?)",
                    bytes.len()
                ),
            ))
        }
    };
    let mut top = Cursor {
        bytes,
        at: 128,
        endian,
    };
    let mut vars: Vec<Variable> = Vec::new();
    // The data elements met so far (the one being read is element `element`, 1-based).
    let mut element = 0;
    while top.at < bytes.len() {
        let start = top.at;
        let at_var = |vars: &Vec<Variable>| match vars.last() {
            Some(v) => format!("after variable '{}'", v.name),
            None => "in the first variable".to_string(),
        };
        // Only whole 8-byte tags start an element; a few trailing bytes are padding.
        if bytes.len() - start < 8 && bytes[start..].iter().all(|&b| b == 0) {
            break;
        }
        element += 1;
        let (ty, data) = match top.element(true) {
            Ok(e) => e,
            Err(Stop::Truncated) => {
                return Err(file_err(
                    name,
                    format!(
                        "the file ends in the middle of a data element at byte {start}, {} (truncated?)",
                        at_var(&vars)
                    ),
                ))
            }
            Err(Stop::Damaged(m)) => {
                return Err(file_err(
                    name,
                    format!("data element {element} at byte {start} is damaged: {m}"),
                ))
            }
            // Not made by reading a tag.
            Err(Stop::Memory(_) | Stop::Budget { .. }) => {
                unreachable!("a tag is read without allocating")
            }
        };
        let var = match ty {
            MI_MATRIX => {
                let end = top.at;
                // Uncompressed elements are padded to 8 bytes.
                top.at = top.at.div_ceil(8) * 8;
                matrix(&bytes[start..end], endian, wanted)
            }
            MI_COMPRESSED => compressed(data, endian, wanted, budget, &mut inflated),
            // A type that is no MAT data type (0, or above 18, miUTF32) is damage, not content (audit
            // s35 L-11: a first element whose type word was 0 was skipped, and the variable it held,
            // `t`, with it, without a word).
            0 | 19.. => {
                return Err(file_err(
                    name,
                    format!(
                        "data element {element} at byte {start} has type {ty}, not a MAT data type \
                         (1 to 18): the file is damaged; save the record again"
                    ),
                ))
            }
            // Other top-level elements (e.g. subsystem data) hold no variable.
            _ => continue,
        };
        let which = |var: Option<String>| match var {
            Some(v) => format!("variable '{v}' (data element {element} at byte {start})"),
            None => format!("data element {element} at byte {start}"),
        };
        match var {
            // A variable without a name is no variable MATLAB writes: damage (audit s16 L2: a damaged
            // compressed element of zeros was listed as a nameless "column").
            Ok(v) if v.name.is_empty() => {
                return Err(file_err(
                    name,
                    format!(
                    "{} is damaged: its variable has no name; expected a named variable (save the \
                         record again with save('file.mat', 'u', 'y', '-v7'))",
                    which(None)
                ),
                ))
            }
            Ok(v) => vars.push(Variable {
                element,
                offset: start,
                ..v
            }),
            Err((var, Stop::Truncated)) => {
                return Err(file_err(
                    name,
                    format!("the file ends in the middle of {} (truncated?)", which(var)),
                ))
            }
            Err((var, Stop::Damaged(m))) => {
                return Err(file_err(name, format!("{} is damaged: {m}", which(var))))
            }
            Err((var, Stop::Budget { need, budget })) => {
                return Err(file_err(
                    name,
                    format!(
                        "reading {} would inflate the record's compressed variables to {need} bytes \
                         ({} GB, as their elements declare), more than the budget of {budget} bytes \
                         ({} GB, --max-memory); save a part of the record, or raise --max-memory \
                         (max_memory_gb in Python) if this machine has the memory",
                        which(var),
                        crate::ls::format_gb(need),
                        crate::ls::format_gb(budget)
                    ),
                ))
            }
            Err((var, Stop::Memory(bytes))) => {
                return Err(file_err(
                    name,
                    format!(
                    "not enough memory to read {}: {bytes} bytes ({} GB) could not be allocated; \
                         save a part of the record, or run where more memory is free",
                    which(var),
                    crate::ls::format_gb(bytes)
                ),
                ))
            }
        }
    }
    Ok(vars)
}

/// A compressed variable: its name and size from the first inflated bytes, its values (inflated in
/// full, within the bound) only when it is wanted.
/// `budget` bounds `inflated`, the bytes inflated for the wanted variables so far, which this one's
/// declared size is added to before it is inflated.
fn compressed(
    zipped: &[u8],
    endian: Endian,
    wanted: &[&str],
    budget: Option<u64>,
    inflated: &mut u64,
) -> Result<Variable, (Option<String>, Stop)> {
    let inflate = |limit: u64| -> Result<Vec<u8>, (Option<String>, Stop)> {
        // The bytes are reserved fallibly before inflating (a 622 KB file announcing 640 MB aborted the
        // process on a failed allocation under a memory limit; audit s23 H-B1).
        let mut out = Vec::new();
        out.try_reserve_exact(usize::try_from(limit).unwrap_or(usize::MAX))
            .map_err(|_| (None, Stop::Memory(limit)))?;
        let mut z = flate2::read::ZlibDecoder::new(zipped);
        (&mut z).take(limit).read_to_end(&mut out).map_err(|e| {
            (
                None,
                Stop::Damaged(format!("its compressed data cannot be inflated ({e})")),
            )
        })?;
        // The stream ended before the bound: it must fill its element (bytes after the end of the
        // compressed data are damage; scipy refuses them too).
        let used = z.total_in();
        if (out.len() as u64) < limit && used < zipped.len() as u64 {
            return Err((
                None,
                Stop::Damaged(format!(
                    "{} bytes follow the end of its compressed data inside the element",
                    zipped.len() as u64 - used
                )),
            ));
        }
        Ok(out)
    };
    let peek = inflate(PEEK_BYTES)?;
    if (peek.len() as u64) < PEEK_BYTES {
        // The whole variable was inflated.
        return matrix(&peek, endian, wanted);
    }
    let head = matrix(&peek, endian, &[])?;
    if !wanted.contains(&head.name.as_str()) || !matches!(head.values, Values::NotRead) {
        return Ok(head);
    }
    let mut c = Cursor {
        bytes: &peek,
        at: 4,
        endian,
    };
    let declared = u64::from(c.u32().map_err(|s| (Some(head.name.clone()), s))?);
    // A vector of MAX_SAMPLES values of 8 bytes, a second part of as many, and its headers.
    let limit = 16 * super::MAX_SAMPLES as u64 + PEEK_BYTES;
    if declared > limit {
        return Err((
            Some(head.name),
            Stop::Damaged(format!(
                "it inflates to {declared} bytes, more than the {limit} a vector of at most {} samples \
                 needs",
                super::MAX_SAMPLES
            )),
        ));
    }
    // The reader's own bytes against the budget, before they are allocated: this element's tag and
    // declared data with those of the variables inflated before it.
    let need = inflated.saturating_add(declared + 8);
    if let Some(budget) = budget.filter(|&b| need > b) {
        return Err((Some(head.name), Stop::Budget { need, budget }));
    }
    *inflated = need;
    // One byte more than the element: a stream that goes on past it is damage, and one that ends
    // there is checked for bytes after it (in `inflate`).
    let whole = inflate(declared + 9)?;
    if whole.len() as u64 > declared + 8 {
        return Err((
            Some(head.name),
            Stop::Damaged(format!(
                "its compressed data inflate to more than the {} bytes its element declares",
                declared + 8
            )),
        ));
    }
    matrix(&whole, endian, wanted)
}

/// A miMATRIX element (its tag included in `bytes`, which may end early): the array flags, dimensions
/// and name, and the values when the name is in `wanted`. The error carries the name when it was read.
fn matrix(
    bytes: &[u8],
    endian: Endian,
    wanted: &[&str],
) -> Result<Variable, (Option<String>, Stop)> {
    let mut outer = Cursor {
        bytes,
        at: 0,
        endian,
    };
    let ty = outer.u32().map_err(|s| (None, s))?;
    let n = outer.u32().map_err(|s| (None, s))? as usize;
    if ty != MI_MATRIX {
        return Err((
            None,
            Stop::Damaged(format!(
                "an element of type {ty} where a matrix (14) was expected"
            )),
        ));
    }
    let body = &bytes[8..bytes.len().min(8usize.saturating_add(n))];
    let mut c = Cursor {
        bytes: body,
        at: 0,
        endian,
    };
    let (_, flags) = c.element(false).map_err(|s| (None, s))?;
    let word = |b: &[u8]| -> u32 {
        let a: [u8; 4] = b.get(..4).and_then(|s| s.try_into().ok()).unwrap_or([0; 4]);
        match endian {
            Endian::Little => u32::from_le_bytes(a),
            Endian::Big => u32::from_be_bytes(a),
        }
    };
    let flags = word(flags);
    let class = flags & 0xff;
    let complex = flags & 0x0800 != 0;
    let (_, dims_raw) = c.element(false).map_err(|s| (None, s))?;
    let raw_dims: Vec<i32> = dims_raw.chunks_exact(4).map(|d| word(d) as i32).collect();
    let (_, name_raw) = c.element(false).map_err(|s| (None, s))?;
    let name = String::from_utf8_lossy(name_raw).into_owned();
    // A negative size is damage; it is printed as read, not as 0.
    if raw_dims.iter().any(|&d| d < 0) {
        return Err((
            Some(name),
            Stop::Damaged(format!(
                "its dimensions {raw_dims:?} include a negative size"
            )),
        ));
    }
    let dims: Vec<usize> = raw_dims
        .iter()
        .map(|&d| usize::try_from(d).unwrap_or(0))
        .collect();
    let class_name = match class {
        1 => Some("cell"),
        2 => Some("struct"),
        3 => Some("object"),
        4 => Some("char"),
        5 => Some("sparse"),
        6..=15 => None,
        _ => Some("non-numeric"),
    };
    let values = if let Some(cn) = class_name {
        Values::Class(cn)
    } else if complex {
        Values::Complex
    } else if !wanted.contains(&name.as_str()) {
        Values::NotRead
    } else {
        let count = dims.iter().try_fold(1usize, |a, &d| a.checked_mul(d));
        let count = match count {
            Some(n) if n <= super::MAX_SAMPLES => n,
            _ => {
                return Err((
                    Some(name),
                    Stop::Damaged(format!(
                        "dimensions {dims:?} give more than the {} samples a record may have",
                        super::MAX_SAMPLES
                    )),
                ))
            }
        };
        let (ty, data) = c.element(false).map_err(|s| (Some(name.clone()), s))?;
        let v = numbers(ty, data, endian)
            .ok_or_else(|| {
                (
                    Some(name.clone()),
                    Stop::Damaged(format!("its values have the unknown storage type {ty}")),
                )
            })?
            .ok_or_else(|| (Some(name.clone()), Stop::Memory(8 * count as u64)))?;
        if v.len() != count {
            return Err((
                Some(name),
                Stop::Damaged(format!(
                    "{} values where its dimensions {dims:?} need {count}",
                    v.len()
                )),
            ));
        }
        Values::Real(v)
    };
    Ok(Variable {
        element: 0,
        offset: 0,
        name,
        dims,
        values,
    })
}

/// The values of a numeric data element of storage type `ty` as f64 (`None`: not a numeric type;
/// `Some(None)`: their vector could not be allocated, reserved fallibly).
fn numbers(ty: u32, data: &[u8], endian: Endian) -> Option<Option<Vec<f64>>> {
    fn conv<const N: usize>(
        data: &[u8],
        endian: Endian,
        f: impl Fn([u8; N], Endian) -> f64,
    ) -> Option<Vec<f64>> {
        let mut v = Vec::new();
        v.try_reserve_exact(data.len() / N).ok()?;
        v.extend(data.chunks_exact(N).map(|c| {
            let mut a = [0u8; N];
            a.copy_from_slice(c);
            f(a, endian)
        }));
        Some(v)
    }
    macro_rules! num {
        ($t:ty) => {
            conv(data, endian, |a, e| match e {
                Endian::Little => <$t>::from_le_bytes(a) as f64,
                Endian::Big => <$t>::from_be_bytes(a) as f64,
            })
        };
    }
    Some(match ty {
        MI_INT8 => num!(i8),
        MI_UINT8 | MI_UTF8 => num!(u8),
        MI_INT16 => num!(i16),
        MI_UINT16 => num!(u16),
        MI_INT32 => num!(i32),
        MI_UINT32 => num!(u32),
        MI_SINGLE => num!(f32),
        MI_DOUBLE => num!(f64),
        // 64-bit integers have no lossless f64 conversion; sample values fit in 2^53.
        MI_INT64 => num!(i64),
        MI_UINT64 => num!(u64),
        _ => return None,
    })
}
