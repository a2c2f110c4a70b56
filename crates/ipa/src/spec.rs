//! Choosing a plant by name: `ipa` (physics), `paper` (the paper's model) or `model:FILE`, parsed once
//! into a [`PlantSpec`].

use std::path::{Path, PathBuf};
use std::str::FromStr;

use crate::{Ipa, IpaError, IpaSetting, PlantConfig};
use sysid_core::{Setting, SysidError};

/// Default sampling period Ts of the IPA experiments, s (paper: 0.01 s).
pub const DEFAULT_TS_S: f64 = 0.01;

/// Which plant to run (`--plant`).
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum PlantSpec {
    /// `ipa`: the physics simulator.
    Ipa,
    /// `paper`: the paper's "actual" Hammerstein model ([`sysid_core::Model::paper`]).
    Paper,
    /// `model:FILE`: a model saved by `identify --save-model`.
    ModelFile(PathBuf),
}

impl FromStr for PlantSpec {
    type Err = IpaError;
    fn from_str(text: &str) -> Result<Self, IpaError> {
        let spec = text.trim();
        match spec {
            "ipa" => Ok(PlantSpec::Ipa),
            "paper" => Ok(PlantSpec::Paper),
            _ => match spec.strip_prefix("model:") {
                Some("") => Err(IpaError::setting(
                    IpaSetting::Plant,
                    "'model:'",
                    "no file name after 'model:'",
                )),
                Some(file) => Ok(PlantSpec::ModelFile(PathBuf::from(file))),
                None => Err(IpaError::setting(
                    IpaSetting::Plant,
                    format!("'{spec}'"),
                    "expected ipa, paper or model:FILE",
                )),
            },
        }
    }
}

impl std::fmt::Display for PlantSpec {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            PlantSpec::Ipa => f.write_str("ipa"),
            PlantSpec::Paper => f.write_str("paper"),
            PlantSpec::ModelFile(p) => write!(f, "model:{}", p.display()),
        }
    }
}

impl PlantSpec {
    /// The model file this spec reads, if any (so that outputs never overwrite it).
    pub fn model_file(&self) -> Option<&Path> {
        match self {
            PlantSpec::ModelFile(p) => Some(p),
            _ => None,
        }
    }

    /// Builds the plant: `ipa` with the defaults or the TOML file `config`, sampled every `ts_s`
    /// (default [`DEFAULT_TS_S`]); a model with its own Ts. `config` is only accepted with `ipa`;
    /// `ts_s` must match a model's own Ts.
    pub fn build(
        &self,
        config: Option<&Path>,
        ts_s: Option<f64>,
    ) -> Result<Box<dyn sysid_core::Plant + Send>, IpaError> {
        if *self == PlantSpec::Ipa {
            let cfg = match config {
                Some(path) => PlantConfig::from_toml_file(path)?,
                None => PlantConfig::default(),
            };
            return Ok(Box::new(Ipa::with_ts(cfg, ts_s.unwrap_or(DEFAULT_TS_S))?));
        }
        if let Some(path) = config {
            // A typed setting, so that each surface names it (`--plant-config`, Python's
            // `plant_config`; audit s33 L-3).
            return Err(IpaError::setting(
                IpaSetting::PlantConfig,
                path.display(),
                format!(
                    "a physics plant configuration, which applies to the plant ipa only, not to \
                     the plant {self}"
                ),
            ));
        }
        use sysid_core::model_file::AnyModel;
        let (model, label) = match self {
            PlantSpec::ModelFile(path) => (
                sysid_core::model_file::read_any_model(path)?,
                format!("model {}", path.display()),
            ),
            _ => (
                AnyModel::Linear(sysid_core::Model::paper()),
                "paper model".to_string(),
            ),
        };
        let model_ts = match &model {
            AnyModel::Linear(m) => m.ts(),
            AnyModel::Narx(m) => m.ts(),
        };
        if let Some(ts) = ts_s {
            // A NaN --ts compares false with everything: refused by name (audit s19 L-3: `--ts nan`
            // ran at the model's Ts without a word).
            if ts.is_nan() || (ts - model_ts).abs() > 1e-9 * model_ts {
                // A setting error, so that each front end names it (`--ts`, Python's `ts`; audit s23
                // L-P2: the flag was in the text and reached Python unchanged).
                return Err(IpaError::setting(
                    IpaSetting::Ts,
                    sysid_core::format::Shortest(ts),
                    format!(
                        "the {label} is sampled at Ts = {} s; leave it out or pass that value",
                        sysid_core::format::Shortest(model_ts)
                    ),
                ));
            }
        }
        Ok(match model {
            AnyModel::Linear(m) => Box::new(sysid_core::ModelPlant::new(m, label)?),
            AnyModel::Narx(m) => Box::new(sysid_core::narx::NarxPlant::new(m, label)?),
        })
    }
}

/// The default initial output of an open-loop experiment on the IPA or the paper's model, mm:
/// mid-stroke, so that the input can move the piston both ways.
pub const MID_STROKE_Y0_MM: f64 = 100.0;

impl PlantSpec {
    /// Where an open-loop experiment starts when no y0 is given (`simulate` without `--y0`), mm: a
    /// stable linear model at its own resting level with the inputs at the operating point
    /// ([`sysid_core::Model::rest_output`]), so that its record shows the input's response and not a
    /// decay from an arbitrary start; a NARX model at the middle of the outputs it was estimated on
    /// (its `data_range`); the IPA, the paper's model and models without a resting level (an
    /// integrator such as the IPA's position, an unstable model, an output nonlinearity, a NARX model
    /// without a data range) at [`MID_STROKE_Y0_MM`].
    pub fn default_y0(&self) -> Result<f64, IpaError> {
        let rest = match self {
            PlantSpec::Ipa | PlantSpec::Paper => None,
            PlantSpec::ModelFile(path) => match sysid_core::model_file::read_any_model(path)? {
                sysid_core::model_file::AnyModel::Linear(m) => return Ok(model_default_y0(&m)),
                // A NARX model has no rest state to compute; the middle of the outputs it was
                // estimated on is inside its data (audit s30 L-14: the default 100 mm was outside a
                // hair dryer's [3.2, 6.2] V and the run failed for every such model).
                sysid_core::model_file::AnyModel::Narx(m) => {
                    m.data_range().map(|r| 0.5 * (r.y[0] + r.y[1]))
                }
            },
        };
        Ok(rest.unwrap_or(MID_STROKE_Y0_MM))
    }
}

/// [`PlantSpec::default_y0`] of a linear or Hammerstein model already read (any number of inputs):
/// the level at which it rests ([`sysid_core::Model::rest_state`]: its resting output, or the resting
/// level of the linear part of a model with an output nonlinearity), else [`MID_STROKE_Y0_MM`].
pub fn model_default_y0(model: &sysid_core::Model) -> f64 {
    model.rest_state().unwrap_or(MID_STROKE_Y0_MM)
}

/// The largest |y0| a plant without a stroke starts from: 1e6, the output beyond which `control`
/// reports a closed loop as diverging (`control::trust::DIVERGED_MM`, a kilometre in mm).
pub const MAX_START_ABS: f64 = 1e6;

/// What a closed loop around a plant can be checked against ([`PlantSpec::limits`]).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct PlantLimits {
    /// The outputs the plant can reach, in mm: the IPA's stroke 0..L (its end stops); `None` for a
    /// model, which has no stroke.
    pub range_mm: Option<(f64, f64)>,
    /// The largest command magnitude the plant applies, counts: the IPA's valves saturate at ±255 (a
    /// larger command is clipped; the physics plant and the paper's); `None` for a model file, which
    /// applies any command.
    pub u_max: Option<f64>,
    /// The stability verdict of a linear model plant's poles ([`sysid_core::Model::stability`]:
    /// settles, an integrator, on the unit circle away from z = 1, or unstable; `control` words the
    /// last two, `control::trust::plant_stability_warning`); `None` for the physics IPA and a NARX
    /// model, which have no poles.
    pub stability: Option<sysid_core::Stability>,
    /// What the model file holds that the user must be told (an input or output map that breaks its
    /// kind's shape: [`sysid_core::model_file::load_warnings`]), or what the calibration of a twin
    /// config warned ([`PlantConfig::calibration_warnings`]); empty for `paper` and the defaults.
    pub model_warnings: Vec<String>,
    /// The commands of a model plant's estimation data, [min, max] of its first input (its
    /// `data_range`): outside them the model extrapolates; `None` without one.
    pub data_u_range: Option<(f64, f64)>,
    /// The outputs of a model plant's estimation data, [min, max] (its `data_range`): a set-point
    /// outside them asks the model to extrapolate; `None` without one.
    pub data_y_range: Option<(f64, f64)>,
}

impl PlantSpec {
    /// The limits of this plant: the stroke and command range of `ipa` (from `config` or the
    /// defaults), the stability of a model.
    pub fn limits(&self, config: Option<&Path>) -> Result<PlantLimits, IpaError> {
        let model = match self {
            PlantSpec::Ipa => {
                let cfg = match config {
                    Some(path) => PlantConfig::from_toml_file(path)?,
                    None => PlantConfig::default(),
                };
                // A calibrated twin's own doubts (its `[calibration]` table), as a model file's.
                return Ok(PlantLimits {
                    model_warnings: cfg.calibration_warnings(),
                    ..PlantLimits::of_ipa(&cfg)
                });
            }
            // The paper's IPA: its model, with the ±255 PWM commands of its valves.
            PlantSpec::Paper => {
                return Ok(PlantLimits {
                    u_max: Some(crate::plant::U_MAX),
                    ..PlantLimits::of_model(&sysid_core::Model::paper())
                })
            }
            PlantSpec::ModelFile(path) => match sysid_core::model_file::read_any_model(path)? {
                sysid_core::model_file::AnyModel::Linear(m) => m,
                // A NARX model has no poles; its blow-up is caught as the closed loop runs. Its data
                // range (audit s17 M-d) says when the loop's commands leave what it was fitted on.
                sysid_core::model_file::AnyModel::Narx(n) => {
                    return Ok(PlantLimits {
                        data_u_range: n
                            .data_range()
                            .and_then(|r| r.u.first())
                            .map(|[lo, hi]| (*lo, *hi)),
                        data_y_range: n.data_range().map(|r| (r.y[0], r.y[1])),
                        ..PlantLimits::default()
                    })
                }
            },
        };
        Ok(PlantLimits::of_model(&model))
    }
}

impl PlantLimits {
    /// True for a model used as the plant (a model file, a Python `Model`): it applies any command
    /// (`u_max` is `None`), and its signals are in its estimation record's units, not the IPA's mm and
    /// counts (what `control` prints and warns in).
    pub fn model_units(&self) -> bool {
        self.u_max.is_none()
    }

    /// The limits of the physics IPA of `cfg`: its stroke 0..L and its valves' ±[`crate::plant::U_MAX`].
    pub fn of_ipa(cfg: &PlantConfig) -> PlantLimits {
        PlantLimits {
            range_mm: Some((0.0, cfg.cylinder.stroke_mm)),
            u_max: Some(crate::plant::U_MAX),
            stability: None,
            model_warnings: Vec::new(),
            data_u_range: None,
            data_y_range: None,
        }
    }

    /// Refuses a start `y0_mm` the plant cannot hold (outside its stroke: it would start at the end stop
    /// under a record or report that says y0; audit s11).
    /// A plant without a stroke (a model) takes a start within ±[`MAX_START_ABS`] (audit s14 L-l: a
    /// start of 1e300 ran, and its metrics read as a diverging loop).
    pub fn check_start(&self, y0_mm: f64) -> Result<(), SysidError> {
        match self.range_mm {
            Some((lo, hi)) if !(lo..=hi).contains(&y0_mm) => Err(SysidError::setting(
                Setting::Other("--y0"),
                y0_mm,
                &format!("a start within the plant's stroke, {lo}..{hi} mm"),
            )),
            None if !(y0_mm.is_finite() && y0_mm.abs() <= MAX_START_ABS) => {
                Err(SysidError::setting(
                    Setting::Other("--y0"),
                    y0_mm,
                    &format!(
                        "a finite start within ±{MAX_START_ABS} (in the model's output units): beyond it a \
                         loop is reported as diverging"
                    ),
                ))
            }
            _ => Ok(()),
        }
    }

    /// The limits of a model used as the plant: no stroke, its stability verdict
    /// ([`sysid_core::Model::stability`]), and the doubts
    /// its parameters raise ([`sysid_core::model_file::load_warnings`]).
    pub fn of_model(model: &sysid_core::Model) -> PlantLimits {
        // The paper's model (Table III), however it came (`--plant paper`, its model file, Python's
        // `paper_model()`), is the paper's IPA: PWM counts within its valves' ±255 and mm, so a run on
        // it speaks the IPA's units; any other model its estimation record's (`model_units`).
        let paper = *model == sysid_core::Model::paper();
        PlantLimits {
            range_mm: None,
            u_max: paper.then_some(crate::plant::U_MAX),
            stability: Some(model.stability()),
            model_warnings: sysid_core::model_file::load_warnings(model),
            data_u_range: model
                .data_range()
                .and_then(|r| r.u.first())
                .map(|[lo, hi]| (*lo, *hi)),
            data_y_range: model.data_range().map(|r| (r.y[0], r.y[1])),
        }
    }
}

/// The plant named by `spec` with the default sampling period (see [`plant_from_spec_with_ts`]).
pub fn plant_from_spec(
    spec: &str,
    config: Option<&Path>,
) -> Result<Box<dyn sysid_core::Plant + Send>, IpaError> {
    plant_from_spec_with_ts(spec, config, None)
}

/// The plant named by `spec` (parsed as a [`PlantSpec`]), built by [`PlantSpec::build`].
pub fn plant_from_spec_with_ts(
    spec: &str,
    config: Option<&Path>,
    ts_s: Option<f64>,
) -> Result<Box<dyn sysid_core::Plant + Send>, IpaError> {
    spec.parse::<PlantSpec>()?.build(config, ts_s)
}

/// The input files a plant spec reads (so that outputs never overwrite them).
pub fn spec_input_files<'a>(spec: &'a str, config: Option<&'a Path>) -> Vec<&'a Path> {
    let mut v: Vec<&Path> = config.into_iter().collect();
    if let Some(file) = spec.trim().strip_prefix("model:").filter(|f| !f.is_empty()) {
        v.push(Path::new(file));
    }
    v
}
