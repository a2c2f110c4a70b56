//! Saved model files (`identify --save-model`), read back by `validate --model` and `--plant model:FILE`.
//!
//! A model file is a JSON object `{"format": "ipa-sysid-model", "version": 2, "model": {...}}` where
//! `model` has the keys of [`Model`]. The JSON written by `identify --json` is accepted too (it also has a
//! top-level `model` object).

use std::path::Path;

use serde::{Deserialize, Serialize};

use crate::format::visible;
use crate::model::ModelRepr;
use crate::narx::NarxModel;
use crate::{Model, SysidError};

/// Value of the `format` key of a model file.
pub const FORMAT: &str = "ipa-sysid-model";
/// Current version of the model file schema. Version 2 added the optional `operating_point` (`--detrend`);
/// version 3 the optional `identification` ([`crate::model::Provenance`]: the record, its column names
/// and identify's warnings). Version 1 and 2 files still load (they have neither).
pub const VERSION: u32 = 3;

#[derive(Serialize)]
struct ModelFileOut<'a> {
    format: &'static str,
    version: u32,
    model: &'a Model,
}

/// Upper bound on the size of a model file (a model has at most 3 * [`crate::model::MAX_ORDER`]
/// coefficients; the `identify --json` summary is larger but still a few kB).
pub const MAX_MODEL_FILE_BYTES: u64 = 16 * 1024 * 1024;

#[derive(Deserialize)]
struct ModelFileIn {
    model: ModelRepr,
}

/// Serialises `model` as a model file (pretty JSON, ending with a newline).
pub fn to_json(model: &Model) -> Result<String, SysidError> {
    // A file that would not load again is not written.
    if model.ts() < crate::model::MIN_TS_S {
        return Err(SysidError::Data(format!(
            "the model's Ts = {:e} s is below {:e} s, the shortest sampling period a model file may \
             hold: it is not saved",
            model.ts(),
            crate::model::MIN_TS_S
        )));
    }
    if model.ts() > crate::model::MAX_TS_S {
        return Err(SysidError::Data(format!(
            "the model's Ts = {:e} s is above {:e} s, the longest sampling period a model file may \
             hold: it is not saved",
            model.ts(),
            crate::model::MAX_TS_S
        )));
    }
    // Nor one whose identification record (column names, ...) load refuses (audit s22 M-B4: names with
    // control characters were written, then loaded without a word).
    if let Some(p) = model.provenance() {
        p.check_sizes().map_err(|m| {
            SysidError::Data(format!(
                "the model is not saved: {m} (the file would not load)"
            ))
        })?;
    }
    let out = ModelFileOut {
        format: FORMAT,
        version: VERSION,
        model,
    };
    serde_json::to_string_pretty(&out)
        .map(|s| s + "\n")
        .map_err(|e| SysidError::Numerical(format!("the model could not be serialised: {e}")))
}

/// Reads and checks a model file.
pub fn read_model(path: &Path) -> Result<Model, SysidError> {
    parse_model(&read_file(path)?, &path.display().to_string())
}

/// What a model file holds that a reader must be told about, in words: an input or output map that is
/// not the physical shape its kind names ([`crate::StaticNonlinearity::shape_problems`]: a deadzone
/// whose breakpoints cross or whose slopes are zero or of opposite signs, a saturation whose limits
/// cross, ...). `identify` saves such a model with its own warning; `validate`, `simulate`, `control`
/// and `tune` repeat these when they load the file (`control --compensate-deadzone` refuses a
/// non-physical deadzone, as it cannot invert it). Then the warnings of the identification that wrote
/// the file ([`provenance_warnings`]).
pub fn load_warnings(model: &Model) -> Vec<String> {
    let mut w = shape_warnings(model);
    w.extend(provenance_warnings(model.provenance()));
    w
}

/// [`load_warnings`] without the identification's warnings that `said` (the warnings a report of the same
/// model makes itself, such as `validate`'s deadzone warning) already holds word for word: each said
/// once (fix34 leftover: `validate` printed the deadzone warning and the identification's copy of it).
pub fn load_warnings_besides(model: &Model, said: &[String]) -> Vec<String> {
    let mut w = shape_warnings(model);
    if let Some(p) = model.provenance() {
        w.extend(
            provenance_warnings(Some(p))
                .into_iter()
                .zip(&p.warnings)
                .filter(|(_, own)| !said.contains(own))
                .map(|(words, _)| words),
        );
    }
    w
}

/// The warnings `identify` gave when it wrote the model file ([`crate::model::Provenance`]), each
/// prefixed by the record and the model's free-run fit on it, the file's strings made printable
/// ([`visible`]) — the words `tune --plant-config` uses for
/// a twin's calibration warnings (audit s20 M-3): "this model's identification on rec.csv (free-run fit
/// −38.27 % on it) warned: …". Empty for a file without an `identification` record or whose
/// identification gave none. A linear model's ([`Model::provenance`]) and a NARX model's
/// ([`NarxModel::provenance`]) alike.
pub fn provenance_warnings(provenance: Option<&crate::model::Provenance>) -> Vec<String> {
    let Some(p) = provenance else {
        return Vec::new();
    };
    // A missing fit in words, not a bare dash (audit s33 L-4: "(free-run fit - on it)").
    let fit = p.fit_estimation_percent.map_or(
        "free-run fit not available on it: the simulation diverged or the output is constant"
            .to_string(),
        |f| format!("free-run fit {f:.2} % on it"),
    );
    p.warnings
        .iter()
        .map(|w| {
            format!(
                "this model's identification on {} ({fit}) warned: {}",
                visible(&p.record),
                visible(w)
            )
        })
        .collect()
}

/// The shape problems of a model's input and output maps, in words ([`load_warnings`]).
fn shape_warnings(model: &Model) -> Vec<String> {
    let several = model.inputs().len() > 1;
    let inputs = model.inputs().iter().map(|input| {
        let of = if several {
            format!(" (input {})", visible(input.name()))
        } else {
            String::new()
        };
        (input.nonlinearity(), of)
    });
    let output = model
        .output_nonlinearity()
        .map(|g| (g, " (the output nonlinearity)".to_string()));
    inputs
        .chain(output)
        .flat_map(|(f, of)| {
            let kind = f.kind_name();
            f.shape_problems().into_iter().map(move |why| {
                format!(
                    "non-physical {kind}{of}: {why}; the model's map is not a {kind}, use its results \
                     with care"
                )
            })
        })
        .collect()
}

/// What a model file holds: a linear or Hammerstein [`Model`], or a polynomial [`NarxModel`].
#[derive(Debug, Clone, PartialEq)]
pub enum AnyModel {
    /// ARX or Hammerstein (`kind` `arx` or `hammerstein`).
    Linear(Model),
    /// Polynomial NARX (`kind` `narx`).
    Narx(NarxModel),
}

/// Parses model-file bytes; `name` is used in messages. A NARX model is refused, naming the commands
/// that take one ([`parse_any_model`]).
///
/// Errors name the file, and the line and column for malformed JSON or a value of the wrong type, and
/// say what was expected. A UTF-8 byte-order mark is skipped. Never panics, whatever the bytes.
pub fn parse_model(bytes: &[u8], name: &str) -> Result<Model, SysidError> {
    match parse_any_model(bytes, name)? {
        AnyModel::Linear(m) => Ok(m),
        AnyModel::Narx(_) => Err(SysidError::File {
            file: name.to_string(),
            message: "the file holds a polynomial NARX model; this use needs an ARX or Hammerstein \
                      model (validate, simulate --plant model:FILE and control --plant model:FILE take \
                      NARX models)"
                .into(),
        }),
    }
}

/// Reads and checks a model file of any kind.
pub fn read_any_model(path: &Path) -> Result<AnyModel, SysidError> {
    parse_any_model(&read_file(path)?, &path.display().to_string())
}

/// The bytes of a model file, its size bounded by [`MAX_MODEL_FILE_BYTES`].
fn read_file(path: &Path) -> Result<Vec<u8>, SysidError> {
    crate::data::bounded::read_bounded(
        path,
        MAX_MODEL_FILE_BYTES,
        "a model file",
        "expected a file written by identify --save-model",
    )
}

/// Writes a NARX model as a model file (pretty JSON, ending with a newline).
pub fn narx_to_json(model: &NarxModel) -> Result<String, SysidError> {
    #[derive(Serialize)]
    struct Out<'a> {
        format: &'static str,
        version: u32,
        model: &'a NarxModel,
    }
    serde_json::to_string_pretty(&Out {
        format: FORMAT,
        version: VERSION,
        model,
    })
    .map(|s| s + "\n")
    .map_err(|e| SysidError::Numerical(format!("the model could not be serialised: {e}")))
}

/// [`parse_model`] for a file of any kind (`kind: "narx"` gives a [`NarxModel`]).
pub fn parse_any_model(bytes: &[u8], name: &str) -> Result<AnyModel, SysidError> {
    let file_err = |message: String| SysidError::File {
        file: name.to_string(),
        message,
    };
    let bytes = bytes.strip_prefix(b"\xef\xbb\xbf").unwrap_or(bytes);
    if bytes.iter().all(|b| b.is_ascii_whitespace()) {
        return Err(file_err(
            "the file is empty; expected a JSON model file written by identify --save-model".into(),
        ));
    }
    let raw: serde_json::Value = serde_json::from_slice(bytes).map_err(|e| {
        // A file of another kind (a CSV record, a Parquet file) is said as such, not as a JSON
        // parser's "expected ident" (audit s26 L-1).
        match crate::data::Sniffed::of(&bytes[..bytes.len().min(4096)]) {
            Some(
                k @ (crate::data::Sniffed::Csv
                | crate::data::Sniffed::Toml
                | crate::data::Sniffed::Parquet
                | crate::data::Sniffed::Mat
                | crate::data::Sniffed::Utf16),
            ) => file_err(format!(
                "this is {}, not a model file (the JSON that identify --save-model writes)",
                k.describe()
            )),
            _ => json_err(bytes, name, &e, "not valid JSON"),
        }
    })?;
    let Some(obj) = raw.as_object() else {
        return Err(file_err(format!(
            "the file holds a JSON {}; expected an object {{\"format\": \"{FORMAT}\", \"version\": \
             {VERSION}, \"model\": {{...}}}}",
            kind_of(&raw)
        )));
    };
    match obj.get("format") {
        None => {}
        // An `identify --json` report holds the model too.
        Some(serde_json::Value::String(f)) if f == FORMAT || f == crate::data::REPORT_FORMAT => {}
        Some(other) => {
            return Err(file_err(format!(
                "\"format\" is {other}, expected \"{FORMAT}\" (is this a model file?)"
            )))
        }
    }
    match obj.get("version") {
        None => {}
        Some(v) => match v.as_u64() {
            Some(v) if v <= u64::from(VERSION) => {}
            Some(v) => {
                return Err(file_err(format!(
                    "model file version {v} is newer than this program understands ({VERSION}); \
                     upgrade ipa-sysid"
                )))
            }
            None => {
                return Err(file_err(format!(
                    "\"version\" is {v}; expected a whole number such as {VERSION}"
                )))
            }
        },
    }
    if !obj.get("model").is_some_and(|m| m.is_object()) {
        return Err(file_err(
            "no \"model\" object; expected a file written by identify --save-model or --json"
                .into(),
        ));
    }
    // A model file holds exactly these keys (an `identify --json` report, format REPORT_FORMAT, holds
    // more): a key beside them was ignored before, so a value put at the wrong level (`"ts"` beside
    // `"model"` instead of in it) loaded without a word (session 36, docs as written).
    // An unmarked file holding a report's keys is an `identify --json` report written before reports
    // were marked (session 32): it is read as a report, as it was then (audit s37 L-1: its metrics
    // were called a misplaced model setting).
    let old_report = obj.get("format").is_none()
        && ["estimation", "metrics", "residuals", "parameters", "poles"]
            .iter()
            .any(|k| obj.contains_key(*k));
    if obj.get("format").is_none_or(|f| f == FORMAT) && !old_report {
        if let Some(key) = obj
            .keys()
            .find(|k| !["format", "version", "model"].contains(&k.as_str()))
        {
            let in_model = obj
                .get("model")
                .and_then(|m| m.as_object())
                .is_some_and(|m| m.contains_key(key.as_str()));
            return Err(file_err(format!(
                "unknown key \"{}\" at the top level of a model file; expected only \"format\", \
                 \"version\" and \"model\" ({})",
                crate::format::visible(key),
                if in_model {
                    "the \"model\" object has its own, which is the one read: remove this one"
                } else {
                    "a setting of the model belongs inside the \"model\" object"
                }
            )));
        }
    }
    if obj
        .get("model")
        .and_then(|m| m.get("kind"))
        .is_some_and(|k| k == "narx")
    {
        #[derive(Deserialize)]
        struct NarxIn {
            model: NarxModel,
        }
        let typed: NarxIn = serde_json::from_slice(bytes).map_err(|e| {
            json_err(
                bytes,
                name,
                &e,
                "the \"model\" object does not match the NARX model schema",
            )
        })?;
        return Ok(AnyModel::Narx(typed.model));
    }
    // Parse again, typed, so that a value of the wrong type is reported with its line and column.
    let typed: ModelFileIn = serde_json::from_slice(bytes).map_err(|e| {
        json_err(
            bytes,
            name,
            &e,
            "the \"model\" object does not match the model schema",
        )
    })?;
    Model::try_from(typed.model)
        .map(AnyModel::Linear)
        .map_err(|e| file_err(e.to_string()))
}

/// A positioned error for malformed JSON, with a hint for the usual causes.
fn json_err(bytes: &[u8], name: &str, e: &serde_json::Error, what: &str) -> SysidError {
    let (line, column) = (e.line().max(1), e.column().max(1));
    let full = e.to_string();
    let bare = full
        .rsplit_once(" at line ")
        .map_or(full.as_str(), |(head, _)| head);
    let message = match e.classify() {
        serde_json::error::Category::Eof => {
            format!("{what}: the file ends in the middle of the JSON (truncated?): {bare}")
        }
        serde_json::error::Category::Syntax if non_finite_literal_at(bytes, line, column) => format!(
            "{what}: NaN and Infinity are not JSON numbers; every coefficient must be a finite number"
        ),
        _ => format!("{what}: {bare}"),
    };
    SysidError::Parse {
        file: name.to_string(),
        line,
        column,
        message,
    }
}

/// True when the text at (1-based) `line`, `column` starts with NaN or Infinity (as written by
/// Python's `json` or JavaScript), possibly signed.
fn non_finite_literal_at(bytes: &[u8], line: usize, column: usize) -> bool {
    let Some(text) = bytes.split(|&b| b == b'\n').nth(line - 1) else {
        return false;
    };
    let start = column.saturating_sub(1).min(text.len());
    // serde_json points at the offending character or just after it; look a few bytes around.
    let from = start.saturating_sub(2);
    let window = String::from_utf8_lossy(&text[from..text.len().min(start + 10)]).to_lowercase();
    window.contains("nan") || window.contains("inf")
}

fn kind_of(v: &serde_json::Value) -> &'static str {
    match v {
        serde_json::Value::Null => "null",
        serde_json::Value::Bool(_) => "boolean",
        serde_json::Value::Number(_) => "number",
        serde_json::Value::String(_) => "string",
        serde_json::Value::Array(_) => "array",
        serde_json::Value::Object(_) => "object",
    }
}

#[cfg(test)]
mod provenance_tests {
    use super::provenance_warnings;
    use crate::model::Provenance;

    // A diverged identification has no fit: the warning says so in words (audit s33 L-4), and a fit of
    // 50 is printed as "50.00 %".
    #[test]
    fn a_missing_estimation_fit_is_said_in_words() {
        let mut p = Provenance {
            record: "rec.csv".into(),
            u_columns: Vec::new(),
            y_column: None,
            fit_estimation_percent: None,
            warnings: vec!["unstable".into()],
        };
        assert_eq!(
            provenance_warnings(Some(&p)),
            vec![
                "this model's identification on rec.csv (free-run fit not available on it: the simulation \
                 diverged or the output is constant) warned: unstable"
                    .to_string()
            ]
        );
        p.fit_estimation_percent = Some(50.0);
        assert_eq!(
            provenance_warnings(Some(&p)),
            vec!["this model's identification on rec.csv (free-run fit 50.00 % on it) warned: unstable".to_string()]
        );
    }
}

#[cfg(test)]
mod top_level_tests {
    use super::{parse_any_model, to_json};
    use crate::Model;

    // A model file holds "format", "version" and "model"; a key beside them (a setting put at the
    // wrong level) is refused naming it, where it used to be ignored. A report (its own format) may
    // hold more keys.
    #[test]
    fn an_unknown_top_level_key_is_refused_and_a_report_keeps_its_keys() {
        let json = to_json(&Model::paper()).unwrap();
        assert!(parse_any_model(json.as_bytes(), "m.json").is_ok());
        let extra = json.replacen('{', "{\n  \"ts\": 0.02,", 1);
        let e = parse_any_model(extra.as_bytes(), "m.json")
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("m.json") && e.contains("unknown key \"ts\""),
            "{e}"
        );
        assert!(e.contains("has its own"), "the model has a ts: {e}");
        let stray = json.replacen('{', "{\n  \"nb_typo\": 2,", 1);
        let e = parse_any_model(stray.as_bytes(), "m.json")
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("\"nb_typo\"") && e.contains("belongs inside"),
            "{e}"
        );
        let report = json.replacen(
            &format!("\"format\": \"{}\"", super::FORMAT),
            &format!(
                "\"format\": \"{}\",\n  \"fit_percent\": 87.0",
                crate::data::REPORT_FORMAT
            ),
            1,
        );
        assert!(report.contains("fit_percent"));
        assert!(parse_any_model(report.as_bytes(), "r.json").is_ok());
    }
}
