//! Choosing a plant by name: `ipa` (physics), `paper` (the paper's model) or `model:FILE`.

use std::path::Path;

use crate::{Ipa, IpaError, PlantConfig};

/// Default sampling period Ts of the IPA experiments, s (paper: 0.01 s).
pub const DEFAULT_TS_S: f64 = 0.01;

/// The plant named by `spec` with the default sampling period (see [`plant_from_spec_with_ts`]).
pub fn plant_from_spec(
    spec: &str,
    config: Option<&Path>,
) -> Result<Box<dyn sysid::Plant + Send>, IpaError> {
    plant_from_spec_with_ts(spec, config, None)
}

/// The plant named by `spec`:
/// - `ipa`: the physics simulator, with the defaults or the TOML file `config`, sampled every `ts_s`
///   (default [`DEFAULT_TS_S`]);
/// - `paper`: the paper's "actual" Hammerstein model ([`sysid::Model::paper`]);
/// - `model:FILE`: a model saved by `identify --save-model`.
///
/// `config` is only accepted with `ipa`; `ts_s` must match a model's own Ts.
pub fn plant_from_spec_with_ts(
    spec: &str,
    config: Option<&Path>,
    ts_s: Option<f64>,
) -> Result<Box<dyn sysid::Plant + Send>, IpaError> {
    let spec = spec.trim();
    if spec == "ipa" {
        let cfg = match config {
            Some(path) => PlantConfig::from_toml_file(path)?,
            None => PlantConfig::default(),
        };
        return Ok(Box::new(Ipa::with_ts(cfg, ts_s.unwrap_or(DEFAULT_TS_S))?));
    }
    if let Some(path) = config {
        return Err(IpaError::Config(format!(
            "--plant-config {} applies to --plant ipa only, not to --plant {spec}",
            path.display()
        )));
    }
    let (model, label) = if spec == "paper" {
        (sysid::Model::paper(), "paper model".to_string())
    } else if let Some(file) = spec.strip_prefix("model:") {
        if file.is_empty() {
            return Err(IpaError::Config(
                "invalid --plant 'model:': no file name after 'model:'".into(),
            ));
        }
        let path = Path::new(file);
        (
            sysid::model_file::read_model(path)?,
            format!("model {}", path.display()),
        )
    } else {
        return Err(IpaError::Config(format!(
            "invalid --plant '{spec}': expected ipa, paper or model:FILE"
        )));
    };
    if let Some(ts) = ts_s {
        if (ts - model.ts).abs() > 1e-9 * model.ts {
            return Err(IpaError::Config(format!(
                "invalid --ts {ts}: the {label} is sampled at Ts = {} s; leave --ts out or pass that value",
                model.ts
            )));
        }
    }
    Ok(Box::new(sysid::ModelPlant::new(model, label)?))
}

/// The input files a plant spec reads (so that outputs never overwrite them).
pub fn spec_input_files<'a>(spec: &'a str, config: Option<&'a Path>) -> Vec<&'a Path> {
    let mut v: Vec<&Path> = config.into_iter().collect();
    if let Some(file) = spec.trim().strip_prefix("model:") {
        v.push(Path::new(file));
    }
    v
}
