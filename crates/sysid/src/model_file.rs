//! Saved model files (`identify --save-model`), read back by `validate --model` and `--plant model:FILE`.
//!
//! A model file is a JSON object `{"format": "ipa-sysid-model", "version": 1, "model": {...}}` where
//! `model` has the keys of [`Model`]. The JSON written by `identify --json` is accepted too (it also has a
//! top-level `model` object).

use std::path::Path;

use serde::{Deserialize, Serialize};

use crate::{Model, SysidError};

/// Value of the `format` key of a model file.
pub const FORMAT: &str = "ipa-sysid-model";
/// Current version of the model file schema.
pub const VERSION: u32 = 1;

#[derive(Serialize)]
struct ModelFileOut<'a> {
    format: &'static str,
    version: u32,
    model: &'a Model,
}

#[derive(Deserialize)]
struct ModelFileIn {
    format: Option<String>,
    version: Option<u32>,
    model: Option<serde_json::Value>,
}

/// Serialises `model` as a model file (pretty JSON).
pub fn to_json(model: &Model) -> String {
    let out = ModelFileOut { format: FORMAT, version: VERSION, model };
    // Serialising plain structs of numbers and strings cannot fail.
    serde_json::to_string_pretty(&out).unwrap_or_default() + "\n"
}

/// Writes `model` to `path` atomically.
pub fn write_model(path: &Path, model: &Model) -> Result<(), SysidError> {
    crate::output::write_atomic(path, to_json(model).as_bytes())
}

/// Reads and checks a model file.
pub fn read_model(path: &Path) -> Result<Model, SysidError> {
    let text = std::fs::read(path).map_err(|source| SysidError::Io { path: path.to_path_buf(), source })?;
    parse_model(&text, &path.display().to_string())
}

/// Parses model-file bytes; `name` is used in messages.
pub fn parse_model(bytes: &[u8], name: &str) -> Result<Model, SysidError> {
    let file_err = |message: String| SysidError::File { file: name.to_string(), message };
    let json_err = |e: serde_json::Error, what: &str| SysidError::Parse {
        file: name.to_string(),
        line: e.line(),
        column: e.column(),
        message: format!("{what}: {e}"),
    };
    let raw: ModelFileIn =
        serde_json::from_slice(bytes).map_err(|e| json_err(e, "not a JSON model file"))?;
    if let Some(f) = &raw.format {
        if f != FORMAT {
            return Err(file_err(format!("format is '{f}', expected '{FORMAT}'")));
        }
    }
    if let Some(v) = raw.version {
        if v > VERSION {
            return Err(file_err(format!(
                "model file version {v} is newer than this program understands ({VERSION}); upgrade ipa-sysid"
            )));
        }
    }
    let value = raw.model.ok_or_else(|| {
        file_err("no \"model\" object; expected a file written by identify --save-model or --json".into())
    })?;
    let model: Model = serde_json::from_value(value).map_err(|e| {
        file_err(format!("the \"model\" object does not match the model schema: {e}"))
    })?;
    model.check().map_err(|e| file_err(e.to_string()))?;
    Ok(model)
}
