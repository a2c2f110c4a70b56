//! `ipa-sysid control`: closed-loop PI position control on a plant, with step metrics (MATLAB `stepinfo`).
//!
//! Thin: flags -> `control` library -> summary, JSON and trace CSV. Definitions are in docs/control.md.

use std::path::{Path, PathBuf};

use anyhow::{bail, Context};
use control::{
    closed_loop, run_metrics, AntiWindup, AntiWindupScheme, DeadzoneCompensator, IntegralForm,
    PiSettings, Profile, RunMetrics, SlopeMode, StepMetrics, StepSegment, Trace, Units,
};
use serde::Serialize;

/// Default run length for a fixed set-point, in s.
const DEFAULT_FIXED_DURATION_S: f64 = 10.0;

/// Flags of `ipa-sysid control`. Exactly one of --setpoint and --profile (one group, so that a missing
/// one is named as "--setpoint or --profile": audit s22 L-N6).
#[derive(Debug, clap::Args)]
#[command(group(clap::ArgGroup::new("reference").args(["setpoint", "profile"]).required(true)))]
pub struct Args {
    /// Plant: `ipa` (physics simulator), `paper` (the paper's Table III model) or `model:FILE` (a saved model).
    #[arg(long, value_name = "SPEC", default_value = "ipa")]
    pub plant: String,
    /// TOML file of physics-plant parameters (see `ipa-sysid plant-config`); only with `--plant ipa`.
    #[arg(long, value_name = "FILE")]
    pub plant_config: Option<PathBuf>,
    /// Kp: proportional gain, counts/mm.
    #[arg(long, default_value_t = 14.0)]
    pub kp: f64,
    /// Ki: integral gain, counts/(mm·s) with --integral scaled, counts/(mm·sample) with per-sample.
    #[arg(long, default_value_t = 1.0)]
    pub ki: f64,
    /// Fixed set-point r in mm (the paper's fixed set-point test).
    #[arg(long, value_name = "MM")]
    pub setpoint: Option<f64>,
    /// Set-point profile: `fixed:MM`, `staircase:L1,L2,...@HOLD_S` (mm, s) or `file:PATH.csv` (columns t,r).
    #[arg(long, value_name = "SPEC")]
    pub profile: Option<String>,
    /// Run length in s [default: the profile's length; 10 s for a fixed set-point].
    #[arg(long, value_name = "S")]
    pub duration: Option<f64>,
    /// Initial position y0 in mm (the plant is reset there at rest; the paper's step test starts at 0;
    /// `simulate` starts mid-stroke at 100 mm so that its open-loop input can move both ways).
    #[arg(long, value_name = "MM", default_value_t = 0.0)]
    pub y0: f64,
    /// Form of the integral term.
    #[arg(long, value_enum, default_value_t = IntegralForm::Scaled)]
    pub integral: IntegralForm,
    /// Anti-windup scheme.
    #[arg(long, value_enum, default_value_t = AntiWindupScheme::None)]
    pub anti_windup: AntiWindupScheme,
    /// Tracking time constant Tt in s for --anti-windup back-calculation [default: Ti = Kp/Ki, scaled form].
    #[arg(long, value_name = "S")]
    pub tracking_time: Option<f64>,
    /// Saturation limit of the command in counts.
    #[arg(long, value_name = "COUNTS", default_value_t = 255.0)]
    pub u_max: f64,
    /// Add a deadzone-inverse compensator built from the deadzone of this saved Hammerstein model
    /// (`paper` = the paper's Table III deadzone; write `./paper` for a file of that name).
    #[arg(long, value_name = "MODEL.json")]
    pub compensate_deadzone: Option<PathBuf>,
    /// How the compensator treats the deadzone slopes.
    #[arg(long, value_enum, default_value_t = SlopeMode::Shift)]
    pub compensator_slopes: SlopeMode,
    /// |u| at or below this many counts gives no command (avoids chattering at the set-point).
    #[arg(long, value_name = "COUNTS", default_value_t = 0.0)]
    pub compensator_threshold: f64,
    /// Let the deadzone compensator follow the online recursive Hammerstein estimate during the run
    /// (needs --compensate-deadzone as its start; docs/online.md).
    #[arg(long, requires = "compensate_deadzone")]
    pub adaptive: bool,
    /// --adaptive: RLS forgetting factor ρ of the online estimate.
    #[arg(long, default_value_t = sysid_control::AdaptiveSettings::default().tracker.forgetting)]
    pub adaptive_forgetting: f64,
    /// --adaptive: estimator updates before its deadzone is used (again after a detected change).
    #[arg(long, value_name = "N", default_value_t = sysid_control::AdaptiveSettings::default().min_updates)]
    pub adaptive_min_updates: usize,
    /// --adaptive: a compensator breakpoint follows the estimate only when its standard deviation is at
    /// most this many counts (otherwise it is frozen).
    #[arg(long, value_name = "COUNTS", default_value_t = sysid_control::AdaptiveSettings::default().max_breakpoint_sd_counts)]
    pub adaptive_max_sd: f64,
    /// --adaptive: largest change of a compensator breakpoint, counts per second.
    #[arg(long, value_name = "COUNTS_PER_S", default_value_t = sysid_control::AdaptiveSettings::default().max_rate_counts_per_s)]
    pub adaptive_max_rate: f64,
    /// Make the plant's valve deadzone wider during the run: `AT_S:WIDEN_COUNTS` (e.g. 30:20: from
    /// t = 30 s every command loses 20 counts towards zero, i.e. b_r + 20 and b_l − 20).
    #[arg(long, value_name = "AT_S:COUNTS")]
    pub deadzone_change: Option<control::DeadzoneChange>,
    /// Run the controller of this file (written by `ipa-sysid tune --out`) instead of the PI of --kp/--ki
    /// (its gains, command limit, anti-windup, deadzone inverse and hold band are in the file, so the
    /// flags that set them are refused beside it).
    #[arg(long, value_name = "CONTROLLER.json", conflicts_with_all = ["compensate_deadzone", "adaptive", "anti_windup", "tracking_time", "integral", "kp", "ki", "u_max", "compensator_threshold", "compensator_slopes"])]
    pub controller: Option<PathBuf>,
    /// Exit with code 1 when the result carries warnings (they are printed either way), without writing
    /// the output files (an earlier file there is kept).
    #[arg(long)]
    pub strict: bool,
    /// Write the metrics and settings as JSON to this file (`-` = standard output).
    #[arg(long, value_name = "OUT")]
    pub json: Option<PathBuf>,
    /// Write the trace as CSV (columns t,r,u,y) to this file.
    #[arg(long, value_name = "CSV")]
    pub out: Option<PathBuf>,
}

/// The `settings` object of the JSON output.
#[derive(Debug, Serialize)]
struct SettingsOut<'a> {
    controller: ControllerOut<'a>,
    ts_s: f64,
    duration_s: f64,
    y0_mm: f64,
    profile: &'a Profile,
    compensator: Option<&'a DeadzoneCompensator>,
}

/// The controller of the JSON output: the PI of the flags, or the tuned controller of --controller
/// (with the file it came from).
#[derive(Debug, Serialize)]
#[serde(untagged)]
enum ControllerOut<'a> {
    Pi(&'a PiSettings),
    Tuned {
        file: String,
        tuned: &'a control::ControllerSettings,
    },
}

/// The JSON output of `ipa-sysid control --json`.
#[derive(Debug, Serialize)]
struct ControlOut<'a> {
    /// The plant's name and the spec it was built from.
    plant: PlantOut<'a>,
    settings: SettingsOut<'a>,
    /// `fixed`: metrics of the single step; `worst-step`: field-wise worst over `steps` (unfixed set-point).
    metrics_kind: &'a str,
    /// The units of the command and of the output, set-point and metrics (whose keys say `_mm`): the
    /// IPA's counts and mm, or a model plant's "(u's units)" and "(y's units)" (audit s22 L-B8).
    units: control::trust::Units,
    metrics: StepMetrics,
    /// False when a step that moved has not settled: its `overshoot_mm`/`overshoot_percent` (beyond
    /// the last sample, `stepinfo(y, t)`) are then not final; `overshoot_past_setpoint_*` (beyond r)
    /// are (audit s17 M-b).
    overshoot_final: bool,
    steps: &'a [StepSegment],
    samples: usize,
    trace: Option<String>,
    /// Reasons not to trust the step metrics, in words (always present; empty when all is well):
    /// the model file's load warnings and `control::loop_warnings`.
    warnings: &'a [String],
    /// With --adaptive: what the adaptation did.
    #[serde(skip_serializing_if = "Option::is_none")]
    adaptive: Option<&'a AdaptiveOut>,
}

/// The `adaptive` object of the JSON output (`--adaptive`).
#[derive(Debug, Serialize)]
struct AdaptiveOut {
    /// The compensator's deadzone at the end of the run.
    final_deadzone: Option<sysid::Deadzone>,
    /// Times (s) at which the online estimator detected a change of the plant.
    change_points_s: Vec<f64>,
    /// The online estimate's deadzone at the end of the run (not necessarily the compensator's).
    final_estimate: Option<sysid::Deadzone>,
    /// Its standard deviations.
    final_estimate_sd: Option<sysid::online::DeadzoneSd>,
    /// Samples at which the right branch (b_r, m_r) waited, was frozen (implausible, undetermined) or
    /// followed the estimate.
    right: sysid_control::BranchCounts,
    /// The same for the left branch (b_l, m_l).
    left: sysid_control::BranchCounts,
    /// Reasons not to trust the adaptation, in words.
    warnings: Vec<String>,
    /// ρ of the online estimate.
    forgetting: f64,
    /// Updates before an estimate is used.
    min_updates: usize,
}

#[derive(Debug, Serialize)]
struct PlantOut<'a> {
    name: String,
    spec: &'a str,
}

/// Refuses a start outside the plant's stroke (the piston would start at the end stop under a report
/// that says y0) and a command limit above what the plant applies (the IPA's valves saturate at ±255
/// counts: a larger limit writes commands the plant never received and hides its saturation; audit s11).
fn check_plant_limits(limits: &ipa::PlantLimits, y0: f64, u_max: f64) -> anyhow::Result<()> {
    limits.check_start(y0)?;
    if let Some(limit) = limits.u_max.filter(|l| u_max > *l) {
        bail!(sysid::SysidError::setting(
            sysid::Setting::Other("--u-max (or the controller file's u_max)"),
            u_max,
            &format!(
                "at most {limit} counts: the IPA's valves saturate at ±{limit}, so a larger limit \
                 would write commands the plant never received"
            )
        ));
    }
    Ok(())
}

/// Runs `ipa-sysid control`.
pub fn run(args: Args) -> anyhow::Result<()> {
    let profile = profile_of(&args)?;
    if args.tracking_time.is_some() && args.anti_windup != AntiWindupScheme::BackCalculation {
        bail!(sysid::SysidError::setting(
            sysid::Setting::Other("--tracking-time"),
            args.tracking_time.unwrap_or_default(),
            "only together with --anti-windup back-calculation"
        ));
    }

    // Inputs (for refusing to overwrite them) and the plant.
    let mut inputs: Vec<PathBuf> = Vec::new();
    if let Some(p) = &args.plant_config {
        inputs.push(p.clone());
    }
    if let Some(f) = args.plant.trim().strip_prefix("model:") {
        inputs.push(PathBuf::from(f));
    }
    if let Profile::Samples { path, .. } = &profile {
        inputs.push(path.clone());
    }
    let mut plant = ipa::plant_from_spec(&args.plant, args.plant_config.as_deref())
        .with_context(|| format!("cannot build the plant for --plant {}", args.plant))?;
    if let Some(change) = args.deadzone_change {
        plant = Box::new(control::Widened::new(plant, change));
    }
    let ts = plant.ts();

    let settings = PiSettings::new(args.kp, args.ki)
        .with_integral(args.integral)
        .with_anti_windup(anti_windup(&args, ts)?)
        .with_u_max(args.u_max);
    let tuned_file = tuned_controller(&args, ts, &mut inputs)?;
    let tuned = tuned_file.as_ref().map(|f| f.controller);
    let limits = args
        .plant
        .parse::<ipa::PlantSpec>()
        .and_then(|spec| spec.limits(args.plant_config.as_deref()))
        .with_context(|| format!("cannot read the plant for --plant {}", args.plant))?;
    check_plant_limits(&limits, args.y0, tuned.map_or(args.u_max, |t| t.u_max))?;
    let mut pi = settings.build(ts)?;
    let mut position = tuned.map(|t| t.build()).transpose()?;
    let controller: &mut dyn control::Controller = match position.as_mut() {
        Some(p) => p,
        None => &mut pi,
    };
    let (compensator, compensator_warning) = compensator(&args, &mut inputs)?;

    // Without --duration the profile sets the run's length, and a length too long for a run is
    // blamed on the profile (its file's last row), not on a --duration nobody typed (audit s28 L-7).
    let duration_s = match args.duration {
        Some(d) => d,
        None => profile
            .natural_duration_checked(ts)?
            .unwrap_or(DEFAULT_FIXED_DURATION_S),
    };
    check_outputs(&args, &inputs)?;
    let to_stdout = |p: &Option<PathBuf>| p.as_ref().is_some_and(|p| p.as_os_str() == "-");
    if to_stdout(&args.out) && to_stdout(&args.json) {
        bail!("--out - and --json - would both write to standard output: give one of them a file");
    }

    let (trace, adaptive) = run_loop(
        &args,
        plant.as_mut(),
        controller,
        compensator.as_ref(),
        &profile,
        duration_s,
    )?;
    if trace.len() < 2 {
        // The run's length came from --duration, or from the profile's own hold times when none was
        // given: name what the user typed (audit s13 L14: a staircase held 1e-9 s blamed --duration).
        let flag = if args.duration.is_some() {
            "--duration"
        } else {
            "--profile (its hold times; or give --duration)"
        };
        bail!(sysid::SysidError::setting(
            sysid::Setting::Other(flag),
            duration_s,
            &format!("at least one sampling period ({ts} s) to measure a response")
        ));
    }
    let RunMetrics {
        kind,
        metrics,
        steps,
    } = run_metrics(&trace, &profile)?;
    let metrics_kind = kind.as_str();
    // The model file's own doubts (a crossed deadzone), then the loop's.
    let mut warnings = control::trust::setup_warnings(
        &limits.model_warnings,
        tuned_file.as_ref(),
        compensator_warning,
        &profile,
        duration_s,
    );
    // A controller file tuned for another plant, or whose compensator inverts another deadzone.
    if let (Some(f), Ok(spec)) = (&tuned_file, args.plant.parse::<ipa::PlantSpec>()) {
        warnings.extend(control::trust::controller_plant_warnings(
            f,
            &spec,
            args.plant_config.as_deref(),
        ));
    }
    if let Some(change) = args.deadzone_change.filter(|c| c.at_s >= duration_s) {
        warnings.push(format!(
            "--deadzone-change at {} s comes at or after the run's end ({duration_s} s): the plant never \
             changes in this run",
            change.at_s
        ));
    }
    // A widening of at least the command limit leaves no command outside the widened deadzone: from
    // the change on, no command moves the plant (audit s32 L-6). Said as the change after the run's end
    // is said: a warning, the run is what was asked.
    let u_max = tuned.map_or(args.u_max, |t| t.u_max);
    if let Some(change) = args
        .deadzone_change
        .filter(|c| c.at_s < duration_s && c.widen_counts >= u_max)
    {
        warnings.push(format!(
            "--deadzone-change widens the deadzone by {} counts on each side at {} s, at least the \
             command limit u_max = {} counts: from then on every command |u| <= u_max lies inside the \
             widened deadzone, so no command can move the plant (the run after {} s shows only the \
             plant coasting); a widening below u_max leaves some command that can",
            sysid_core::format::shortest(change.widen_counts),
            sysid_core::format::shortest(change.at_s),
            sysid_core::format::shortest(u_max),
            sysid_core::format::shortest(change.at_s),
        ));
    }
    warnings.extend(control::loop_warnings(
        &trace,
        &steps,
        &control::LoopFacts {
            u_max: tuned.map_or(args.u_max, |t| t.u_max),
            range_mm: limits.range_mm,
            plant_stability: limits.stability,
            judge_steps: profile.has_held_steps(),
            data_u_range: limits.data_u_range,
            data_y_range: limits.data_y_range,
            duration_setting: Some("--duration"),
            start_setting: Some("--y0"),
            units: Units::of(limits.model_units()),
        },
    ));
    // The run against the steady-state specification the controller file was tuned for.
    if let Some(f) = &tuned_file {
        warnings.extend(control::trust::spec_warnings(f, &steps));
    }
    // The adaptation's own doubts are the run's warnings too: in `warnings` (text, JSON, --strict) as
    // well as in `adaptive.warnings` (audit s34 L-11: 11 `warning:` lines, 5 JSON `warnings`, and
    // --strict counted only the 5).
    if let Some(a) = &adaptive {
        warnings.extend(a.warnings.iter().cloned());
    }

    // The trace and the JSON are written together, after both are made (a failure of either leaves
    // both files as they were; audit s14 M-f).
    let trace_csv = match &args.out {
        Some(out) => Some(sysid_io::columns_csv(
            out,
            &Trace::COLUMNS,
            &trace.columns(),
        )?),
        None => None,
    };
    let mut json_text = None;
    if args.json.is_some() {
        let doc = ControlOut {
            plant: PlantOut {
                name: plant.name(),
                spec: &args.plant,
            },
            settings: SettingsOut {
                controller: match (&tuned, &args.controller) {
                    (Some(t), Some(p)) => ControllerOut::Tuned {
                        file: p.display().to_string(),
                        tuned: t,
                    },
                    _ => ControllerOut::Pi(&settings),
                },
                ts_s: ts,
                duration_s,
                y0_mm: args.y0,
                profile: &profile,
                compensator: compensator.as_ref(),
            },
            metrics_kind,
            units: Units::of(limits.model_units()),
            metrics,
            overshoot_final: metrics.overshoot_mm.is_none() || metrics.settling_time_s.is_some(),
            steps: &steps,
            samples: trace.len(),
            trace: args.out.as_ref().map(|p| p.display().to_string()),
            warnings: &warnings,
            adaptive: adaptive.as_ref(),
        };
        json_text = Some(
            super::common::report_json(&doc, true).context("serialising the JSON output")? + "\n",
        );
    }
    let mut outputs: Vec<(&Path, &[u8], &str)> = Vec::new();
    if let (Some(out), Some(bytes)) = (&args.out, &trace_csv) {
        outputs.push((out, bytes, "--out"));
    }
    if let (Some(json), Some(text)) = (&args.json, &json_text) {
        outputs.push((json, text.as_bytes(), "--json"));
    }
    // With --strict and warnings, no file is written (an earlier one is kept) and the exit code is 1,
    // after the report (audit s17 L-d).
    let written = super::common::write_outputs(&outputs, &[], args.strict, warnings.len());
    if let Err(e) = &written {
        if e.downcast_ref::<crate::exit::StrictWarnings>().is_none() {
            return written;
        }
    }

    // A model plant's signals are in its record's units, not the IPA's (audit s14 L-p).
    let units = Units::of(limits.model_units());
    let mut summary = summary_text(
        &plant.name(),
        &match &tuned {
            Some(t) => tuned_line(t),
            None => pi_line(&settings, units),
        },
        units,
        ts,
        &profile,
        args.y0,
        compensator.as_ref(),
        &trace,
        metrics_kind,
        &metrics,
        &steps,
    );
    if let Some(a) = &adaptive {
        summary += &adaptive_text(a);
    }
    for w in &warnings {
        summary += &format!("warning: {w}\n");
    }
    // Keep standard output clean JSON (or CSV) when the JSON (or the trace) goes there.
    super::common::print_report(&summary, &[args.json.as_deref(), args.out.as_deref()])?;
    written
}

/// The closed loop of `run`: with `--adaptive`, the compensator follows the online estimate and the run
/// reports what the adaptation did; otherwise the fixed loop.
fn run_loop(
    args: &Args,
    plant: &mut dyn sysid::Plant,
    controller: &mut dyn control::Controller,
    compensator: Option<&DeadzoneCompensator>,
    profile: &Profile,
    duration_s: f64,
) -> anyhow::Result<(Trace, Option<AdaptiveOut>)> {
    let ts = plant.ts();
    Ok(match (compensator, args.adaptive) {
        (Some(initial), true) => {
            let mut adaptive_settings = sysid_control::AdaptiveSettings {
                min_updates: args.adaptive_min_updates,
                max_breakpoint_sd_counts: args.adaptive_max_sd,
                max_rate_counts_per_s: args.adaptive_max_rate,
                ..sysid_control::AdaptiveSettings::default()
            };
            adaptive_settings.tracker.forgetting = args.adaptive_forgetting;
            let run = sysid_control::run_adaptive(
                plant,
                controller,
                *initial,
                &adaptive_settings,
                profile,
                duration_s,
                args.y0,
            )?;
            let summary = AdaptiveOut {
                final_deadzone: run.deadzones.last().copied(),
                change_points_s: run.change_points.iter().map(|&k| k as f64 * ts).collect(),
                final_estimate: run.final_estimate,
                final_estimate_sd: run.final_sd,
                right: run.right,
                left: run.left,
                warnings: run.warnings().to_vec(),
                forgetting: args.adaptive_forgetting,
                min_updates: args.adaptive_min_updates,
            };
            (run.trace, Some(summary))
        }
        _ => (
            closed_loop::run(plant, controller, compensator, profile, duration_s, args.y0)?,
            None,
        ),
    })
}

/// The set-point profile of `--setpoint` or `--profile` (exactly one).
fn profile_of(args: &Args) -> anyhow::Result<Profile> {
    Ok(match (&args.setpoint, &args.profile) {
        (Some(r), None) => {
            if !r.is_finite() {
                bail!(sysid::SysidError::setting(
                    sysid::Setting::Other("--setpoint"),
                    r,
                    "a finite position in mm"
                ));
            }
            Profile::Fixed { setpoint_mm: *r }
        }
        (None, Some(spec)) => Profile::parse(spec).context("invalid --profile")?,
        _ => bail!(sysid::SysidError::setting(
            sysid::Setting::Other("--setpoint/--profile"),
            "",
            "exactly one of --setpoint MM or --profile SPEC"
        )),
    })
}

/// The anti-windup of `--anti-windup` (and `--tracking-time`, default Ti = Kp/Ki) at sampling period `ts`.
fn anti_windup(args: &Args, ts: f64) -> anyhow::Result<AntiWindup> {
    Ok(match args.anti_windup {
        AntiWindupScheme::None => AntiWindup::None,
        AntiWindupScheme::Clamping => AntiWindup::Clamping,
        AntiWindupScheme::BackCalculation => {
            let default_tt = || {
                PiSettings::new(args.kp, args.ki)
                    .with_integral(args.integral)
                    .integral_time_s(ts)
            };
            if let Some(tt_s) = args.tracking_time {
                return Ok(AntiWindup::BackCalculation { tt_s });
            }
            // The default Ti = Kp/Ki is checked here, where it is known to be the default: the
            // controller's own check would blame `--tracking-time`, which the user did not pass
            // (audit s19 L-4: `--ki 1e-320` gave "invalid setting --tracking-time = inf").
            let usable = default_tt().filter(|&ti| ti.is_finite() && ti > ts / 2.0);
            let Some(tt_s) = usable else {
                bail!(sysid::SysidError::setting(
                    sysid::Setting::Other("--anti-windup"),
                    "back-calculation",
                    &format!(
                        "a tracking time: the default Ti = Kp/Ki = {} s (Kp = {}, Ki = {}) is not a finite \
                         number of seconds above half the sampling period ({} s); give --tracking-time \
                         SECONDS",
                        default_tt().map_or("(none: Kp or Ki is 0)".to_string(), |ti| {
                            sysid_core::format::Shortest(ti).to_string()
                        }),
                        sysid_core::format::Shortest(args.kp),
                        sysid_core::format::Shortest(args.ki),
                        sysid_core::format::Shortest(ts / 2.0)
                    )
                ));
            };
            AntiWindup::BackCalculation { tt_s }
        }
    })
}

/// The deadzone-inverse compensator of `--compensate-deadzone`, if any; a model file read is added to
/// `inputs` (so that no output replaces it).
/// The deadzone compensator of `--compensate-deadzone`, with a warning when its model's data never
/// came near the loop's command limit ([`control::compensator::compensator_scale_warning`]).
fn compensator(
    args: &Args,
    inputs: &mut Vec<PathBuf>,
) -> anyhow::Result<(Option<DeadzoneCompensator>, Option<String>)> {
    let Some(path) = &args.compensate_deadzone else {
        return Ok((None, None));
    };
    let (deadzone, warning) = if path.as_os_str() == "paper" {
        let d = sysid::Model::paper()
            .deadzone()
            .copied()
            .context("the paper's model has a deadzone")?;
        (d, None)
    } else {
        inputs.push(path.clone());
        let m = sysid::model_file::read_model(path).context("cannot read --compensate-deadzone")?;
        (
            command_deadzone(&m, path, "--compensate-deadzone")?,
            control::compensator::compensator_scale_warning(&m, args.u_max),
        )
    };
    Ok((
        Some(
            DeadzoneCompensator::new(deadzone, args.compensator_slopes, args.u_max)?
                .with_threshold(args.compensator_threshold)?,
        ),
        warning,
    ))
}

/// The deadzone of a single-input Hammerstein model `m` (read from `path`, given with `flag`) in the
/// command's units (`control::compensator::command_deadzone`); errors name the file and the flag.
pub fn command_deadzone(
    m: &sysid::Model,
    path: &Path,
    flag: &'static str,
) -> anyhow::Result<sysid::Deadzone> {
    control::compensator::command_deadzone(m).map_err(|problem| {
        anyhow::Error::new(sysid::SysidError::setting(
            sysid::Setting::Other(flag),
            path.display(),
            &problem.to_string(),
        ))
    })
}

/// Output paths: never over an input, and not both to the same file (in any spelling: `x` and `./x`,
/// an absolute path, `sub/..`; audit s16 H2): the one check of `identify`, `validate` and `calibrate`.
fn check_outputs(args: &Args, inputs: &[PathBuf]) -> anyhow::Result<()> {
    let input_refs: Vec<&Path> = inputs.iter().map(PathBuf::as_path).collect();
    super::common::check_outputs(&[(&args.out, "--out"), (&args.json, "--json")], &input_refs)
}

/// The lines `--adaptive` adds to the text summary: the final compensator, the detected changes and what
/// each branch did (its warnings are among the run's).
fn adaptive_text(a: &AdaptiveOut) -> String {
    let dz = a.final_deadzone.map_or("n/a".to_string(), |d| {
        format!(
            "b_l = {}, b_r = {}, m_l = {}, m_r = {}",
            d.b_l, d.b_r, d.m_l, d.m_r
        )
    });
    let counts = |c: &sysid_control::BranchCounts| {
        format!(
            "followed {} / frozen {} (implausible {}, undetermined {}, settling {}) / waiting {}",
            c.following,
            c.implausible + c.undetermined + c.settling,
            c.implausible,
            c.undetermined,
            c.settling,
            c.waiting
        )
    };
    let text = format!(
        "adaptive:     final compensator deadzone {dz}; changes detected at t = {:?} s\n\
         adaptive:     samples: right branch {}; left branch {}\n",
        a.change_points_s,
        counts(&a.right),
        counts(&a.left)
    );
    // Its warnings are printed with the run's (`warnings`), once.
    text
}

fn fmt_opt(v: Option<f64>, unit: &str, m: &StepMetrics) -> String {
    match v {
        Some(x) => format!("{} {unit}", control::trust::fmt_value(x)),
        None => no_metric(m).to_string(),
    }
}

/// Why a step metric is missing: no step at all (the set-point was where the output rested), or a
/// step the warnings describe (too short to judge, moved away, no response).
fn no_metric(m: &StepMetrics) -> &'static str {
    if m.steady_state_error_mm.is_some_and(|e| e != 0.0) {
        "n/a (see the warnings)"
    } else {
        "n/a (no step towards the set-point)"
    }
}

/// The settling time, or why there is none: no step, or not settled within the run.
fn fmt_settling(m: &StepMetrics, run_s: f64) -> String {
    match (m.settling_time_s, m.overshoot_mm) {
        (Some(x), _) => format!("{x:.4} s"),
        (None, Some(_)) => format!("not settled within {run_s} s (see the warnings)"),
        (None, None) => no_metric(m).to_string(),
    }
}

/// The `controller:` line of the summary for the PI of the flags.
fn pi_line(s: &PiSettings, units: Units) -> String {
    let form = match s.integral {
        IntegralForm::Scaled => "u = Kp e + Ki Ts Σe",
        IntegralForm::PerSample => "u = Kp e + Ki Σe",
    };
    format!(
        "PI Kp = {}, Ki = {} ({form}), anti-windup {}, |u| <= {} {}",
        report::format::sig(s.kp, 6),
        report::format::sig(s.ki, 6),
        s.anti_windup,
        report::format::sig(s.u_max, 6),
        units.u
    )
}

/// The `controller:` line of the summary for a tuned controller (--controller).
pub fn tuned_line(s: &control::ControllerSettings) -> String {
    let comp = s
        .compensator
        .map_or("no deadzone inverse".to_string(), |c| {
            format!(
                "deadzone inverse b_l = {:.3}, b_r = {:.3} (fine band {:.3} mm)",
                c.deadzone.b_l, c.deadzone.b_r, s.fine_band_mm
            )
        });
    let nudge = s.nudge.map_or(String::new(), |n| {
        format!(
            ", nudge band {:.3} mm (ramp {:.1} counts/s from {} of the learnt breakaway, cut at {:.3} of the error{}, rest {} samples{}{})",
            n.band_mm,
            n.ramp_counts_s,
            n.start_fraction,
            n.cut_fraction,
            if n.cut_learn {
                " (a held nudge's, raised per side after one that stopped short)"
            } else {
                ""
            },
            n.rest_samples,
            if n.rest_band_mm > n.band_mm {
                format!(", also after a rest within {:.3} mm", n.rest_band_mm)
            } else {
                String::new()
            },
            if n.cut_band_mm > 0.0 && n.creep_step_mm > 0.0 {
                format!(
                    "; ramp-and-cut within {:.3} mm: a learnt ramp of at least {:.1} counts/s, held while the piston creeps at most {} mm per sample, cut when it moves faster",
                    n.cut_band_mm,
                    n.min_ramp_counts_s,
                    report::format::sig(n.creep_step_mm, 6)
                )
            } else if n.cut_band_mm > 0.0 {
                format!(
                    "; ramp-and-cut within {:.3} mm: a learnt ramp of at least {:.1} counts/s, cut at the first count",
                    n.cut_band_mm, n.min_ramp_counts_s
                )
            } else {
                String::new()
            }
        )
    });
    let brake = s.brake.map_or(String::new(), |b| {
        format!(
            ", approach with braking for steps of {} mm or more (full command until the error is {} mm + {} s × the speed, then {} u_max reversed for {} samples, valves closed until {} samples at rest)",
            report::format::sig(b.min_step_mm, 6),
            report::format::sig(b.switch_mm, 6),
            report::format::sig(b.lead_s, 6),
            report::format::sig(b.strength, 6),
            b.samples,
            b.rest_samples
        ) + &if b.release_samples > 0 {
            format!(
                ", released over {} samples",
                b.release_samples
            )
        } else {
            String::new()
        } + &if b.rebrake {
            ", braked again at each count towards the set-point while released and held".to_string()
        } else {
            String::new()
        } + &if b.preview {
            ", the full command's last sample a fraction that reaches the switch".to_string()
        } else {
            String::new()
        } + &if b.learn > 0.0 {
            format!(
                "; the lead learnt per direction at {} per braked move, at most {} s",
                report::format::sig(b.learn, 6),
                report::format::sig(b.lead_max_s, 6)
            )
        } else {
            String::new()
        }
    });
    let short = s.short_approach.map_or(String::new(), |a| {
        format!(
            ", short-step approach for steps of at most {} mm ({} u_max, raised by {} counts/s until the piston moves, until the error is {} mm + {} s × the speed, then {} u_max reversed for {} samples, valves closed until {} samples at rest)",
            report::format::sig(a.max_step_mm, 6),
            report::format::sig(a.drive_fraction, 6),
            report::format::sig(a.ramp_counts_s, 6),
            report::format::sig(a.switch_mm, 6),
            report::format::sig(a.lead_s, 6),
            report::format::sig(a.brake_strength, 6),
            a.brake_samples,
            a.rest_samples
        ) + &if a.preview {
            ", the drive's last sample a fraction that reaches the switch".to_string()
        } else {
            String::new()
        }
    });
    format!(
        "tuned PID Kp = {:.4}, Ki = {:.4}, Kd = {:.4} (Tf = {} s), clamping anti-windup, {comp}, hold band {} mm{nudge}{brake}{short}, |u| <= {} counts",
        s.kp,
        s.ki,
        s.kd,
        report::format::sig(s.derivative_filter_s, 6),
        report::format::sig(s.hold_band_mm, 6),
        report::format::sig(s.u_max, 6)
    )
}

#[allow(clippy::too_many_arguments)]
fn summary_text(
    plant: &str,
    controller_line: &str,
    units: Units,
    ts: f64,
    profile: &Profile,
    y0: f64,
    compensator: Option<&DeadzoneCompensator>,
    trace: &Trace,
    metrics_kind: &str,
    m: &StepMetrics,
    steps: &[StepSegment],
) -> String {
    let mut o = String::new();
    let duration = trace.t.last().copied().unwrap_or(0.0);
    o += &format!(
        "plant:        {plant} (Ts = {} s), {} samples over {} s\n",
        sysid_core::format::Shortest(ts),
        trace.len(),
        sysid_core::format::Shortest(duration)
    );
    o += &format!("controller:   {controller_line}\n");
    o += &format!(
        "set-point:    {} from y0 = {y0} {}\n",
        profile.describe_in(units.y),
        units.y
    );
    match compensator {
        None if controller_line.starts_with("tuned") => {
            o += "compensator:  the tuned controller's own (above)\n"
        }
        None => o += "compensator:  none\n",
        Some(c) => {
            let d = c.deadzone;
            o += &format!(
                "compensator:  deadzone inverse ({:?}), b_l = {}, b_r = {}, m_l = {}, m_r = {}, threshold {} {}\n",
                c.slope_mode,
                ::report::format::num(d.b_l),
                ::report::format::num(d.b_r),
                ::report::format::num(d.m_l),
                ::report::format::num(d.m_r),
                ::report::format::num(c.threshold_counts),
                units.u
            );
        }
    }
    let heading = if metrics_kind == "fixed" {
        "step metrics (stepinfo)"
    } else {
        "worst step (field-wise)"
    };
    o += &format!("{heading}:\n");
    // Beyond the last sample (stepinfo(y, t)): final only once the step has settled (audit s17 M-b).
    let not_final = if m.settling_time_s.is_none() {
        "; not final: not settled"
    } else {
        ""
    };
    o += &match (m.overshoot_mm, m.overshoot_percent) {
        (Some(_), Some(_)) => format!(
            "  overshoot            {} ({} of the step{not_final})\n",
            fmt_opt(m.overshoot_mm, units.y, m),
            fmt_opt(m.overshoot_percent, "%", m)
        ),
        _ => format!(
            "  overshoot            {}\n",
            fmt_opt(m.overshoot_mm, units.y, m)
        ),
    };
    if let (Some(us), Some(pc)) = (m.undershoot_mm, m.undershoot_percent) {
        // The wrong-way excursion from y0 (stepinfo's Undershoot; audit s18 L-4).
        o += &format!(
            "  undershoot           {} {} ({} % of the step)\n",
            control::trust::fmt_value(us),
            units.y,
            control::trust::fmt_value(pc)
        );
    }
    if let (Some(p), Some(pc)) = (
        m.overshoot_past_setpoint_mm,
        m.overshoot_past_setpoint_percent,
    ) {
        // How far the output went beyond r (stepinfo(y, t, r)), whatever the run's length.
        o += &format!(
            "  peak past r          {} {} ({} % of the set-point step)\n",
            control::trust::fmt_value(p),
            units.y,
            control::trust::fmt_value(pc)
        );
    }
    // The error at the last sample is final only once the step has settled, as the overshoot above
    // (audit s24 L-6; reproduce marks it "(n.f.)").
    // With r = y0 there is no step to settle (audit s30 L-6: "not final: not settled" without a
    // reason): e_ss is then only where the output ended.
    let no_step =
        metrics_kind == "fixed" && steps.first().is_some_and(|st| st.setpoint_mm == st.y0_mm);
    let ess_not_final = if no_step && m.steady_state_error_mm.is_some() {
        " (no step to settle: the set-point is y0; e_ss = r − y at the last sample)"
    } else if m.settling_time_s.is_none() && m.steady_state_error_mm.is_some() {
        " (not final: not settled)"
    } else {
        ""
    };
    o += &format!(
        "  steady-state error   {}{ess_not_final}\n",
        fmt_opt(m.steady_state_error_mm, units.y, m)
    );
    o += &format!(
        "  rise time 10-90 %    {}\n",
        fmt_opt(m.rise_time_s, "s", m)
    );
    o += &format!("  settling time 2 %    {}\n", fmt_settling(m, duration));
    if steps.len() > 1 {
        o += "steps:\n    start_s   r_mm      y0_mm     OS_%      e_ss_mm   t_r_s     t_s_s\n";
        for st in steps {
            let f = |v: Option<f64>| v.map_or("n/a".to_string(), control::trust::fmt_value);
            let row = format!(
                "  {:<9} {:<9} {:<9} {:<9} {:<9} {:<9} {:<9}",
                format!("{:.2}", st.start_s),
                st.setpoint_mm,
                format!("{:.3}", st.y0_mm),
                f(st.metrics.overshoot_percent),
                f(st.metrics.steady_state_error_mm),
                f(st.metrics.rise_time_s),
                f(st.metrics.settling_time_s),
            );
            o += row.trim_end();
            o += "\n";
        }
    }
    // The paper's acceptance: overshoot < 10 %, |e_ss| < 2 % of the step. The overshoot is the peak
    // past r (OS_r, `StepMetrics::overshoot_judged_percent`, as `tune` judges it): the overshoot beyond
    // the last sample is not final while the step has not settled (audit s17 M-b, L-d).
    if let (Some(os), Some(_), Some(first)) = (
        m.overshoot_judged_percent(),
        m.steady_state_error_mm,
        steps.first(),
    ) {
        if metrics_kind == "fixed" {
            let yes = |b: bool| if b { "yes" } else { "NO" };
            // An error measured on a loop that has not settled is not final: a miss is a miss at the
            // run's end, a pass is no verdict; a step too short to settle is not judged.
            let size = (first.setpoint_mm - first.y0_mm).abs();
            let too_short = first.too_short();
            let ess_verdict =
                control::EssVerdict::of_metrics(m, size, too_short, 0.02).words(too_short);
            // The paper judges overshoot and e_ss only; a large wrong-way dip is named beside its
            // verdict (and in a warning), not added to it (docs/control.md, "Step metrics").
            let dip = m
                .undershoot_percent
                .filter(|us| *us >= control::trust::UNDERSHOOT_WARN_PERCENT)
                .map_or(String::new(), |us| {
                    format!(
                        " (undershoot {} %: not one of the paper's criteria, see the warning)",
                        control::trust::fmt_value(us)
                    )
                });
            o += &format!(
                "paper's acceptance: overshoot past r < 10 %: {}; |e_ss| < 2 % of the step: {ess_verdict}{dip}\n",
                yes(os < 10.0),
            );
        }
    }
    o
}

/// The tuned controller file of `--controller FILE` (read, and its Ts checked against the plant's
/// `ts`; its provenance is said by [`control::trust::setup_warnings`]), its file added to `inputs`;
/// `None` without the flag (the PI of --kp/--ki).
fn tuned_controller(
    args: &Args,
    ts: f64,
    inputs: &mut Vec<PathBuf>,
) -> anyhow::Result<Option<control::ControllerFile>> {
    Ok(match &args.controller {
        Some(path) => {
            inputs.push(path.clone());
            Some(read_controller(path, ts, "plant")?)
        }
        None => None,
    })
}

/// The controller file of `--controller FILE` (as `tune --out` writes it), read by
/// [`control::ControllerFile::read_file`] and refused, naming the flag, when it was tuned for another
/// sampling period than the `what` (`plant`, `model`) it is to run with at `ts` s: the one reader of
/// `control --controller` and `response --controller`.
pub fn read_controller(
    path: &Path,
    ts: f64,
    what: &str,
) -> anyhow::Result<control::ControllerFile> {
    let file = control::ControllerFile::read_file(path).context("cannot read --controller")?;
    let t = file.controller;
    if (t.ts_s - ts).abs() > 1e-9 * ts {
        bail!(sysid::SysidError::setting(
            sysid::Setting::Other("--controller"),
            path.display(),
            &format!(
                "a controller for the {what}'s Ts = {} s (this one was tuned for Ts = {} s)",
                sysid_core::format::Shortest(ts),
                sysid_core::format::Shortest(t.ts_s)
            )
        ));
    }
    Ok(file)
}
