//! `ipa-sysid response`: frequency response (Bode), DC gain, poles and zeros, impulse and step
//! response of an identified model's linear block, and the margins of a PI loop around it (MATLAB
//! `bode`, `dcgain`, `pole`, `zero`, `impulse`, `step`, `margin`); the logic is
//! `control::response::response`.

use std::path::{Path, PathBuf};

use anyhow::Context;
use control::response::{response, Response, ResponseSettings};
use report::format::num;

use super::common::{check_outputs, print_report, write_outputs};

/// Flags of `response`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Model file (`identify --save-model`): an ARX or Hammerstein model (one input).
    #[arg(long, value_name = "FILE")]
    pub model: PathBuf,
    /// Number of log-spaced frequencies of the Bode table, up to the Nyquist frequency 1/(2 Ts).
    #[arg(long, default_value_t = 20, value_name = "N", value_parser = clap::value_parser!(u32).range(2..=100_000))]
    pub points: u32,
    /// Lowest frequency of the Bode table, Hz (default: the Nyquist frequency / 1000).
    #[arg(long, value_name = "HZ")]
    pub f_min: Option<f64>,
    /// Samples of the impulse and step responses (k = 0 .. N-1).
    #[arg(long, default_value_t = 20, value_name = "N", value_parser = clap::value_parser!(u32).range(1..=1_000_000))]
    pub samples: u32,
    /// Proportional gain of a PI controller (counts per output unit): print the loop's gain and phase
    /// margins as `tune` computes them (MATLAB `margin(C*G)`).
    #[arg(long, value_name = "KP")]
    pub kp: Option<f64>,
    /// Integral gain of that PI controller (counts per output unit per s; default 0 with --kp).
    #[arg(long, value_name = "KI", requires = "kp")]
    pub ki: Option<f64>,
    /// A tuned controller file (`tune --out`, read as `control --controller` reads it): print the
    /// loop's margins with its Kp, Ki, Kd and Tf, as `tune` reported them. Not with --kp/--ki.
    #[arg(long, value_name = "CONTROLLER.json", conflicts_with_all = ["kp", "ki"])]
    pub controller: Option<PathBuf>,
    /// Write the Bode table as CSV here (f_hz, w_rad_s, mag_db, phase_deg; a Hammerstein model adds
    /// mag_db_right, mag_db_left: the gain from u on each side of the deadzone).
    #[arg(long, value_name = "FILE")]
    pub out: Option<PathBuf>,
    /// Write everything as JSON here (`-` for standard output).
    #[arg(long, value_name = "OUT")]
    pub json: Option<PathBuf>,
    /// Exit with code 1 when the result carries warnings (they are printed either way), without writing
    /// --out or the JSON (an earlier file there is kept), as `control` and `tune` do.
    #[arg(long)]
    pub strict: bool,
}

fn list(v: &[(f64, f64)]) -> String {
    if v.is_empty() {
        "none".into()
    } else {
        v.iter()
            .map(|p| crate::text::complex(p.0, p.1, 0.0, true))
            .collect::<Vec<_>>()
            .join(", ")
    }
}

fn opt(v: Option<f64>) -> String {
    v.map_or_else(|| "n/a".into(), num)
}

/// The DC gain G(1) in words: the number, or why there is none (an integrator, an unstable block;
/// audit s21 H-A1), or for a deadzone side whose slope identify fixed at 0 "not identified".
fn dc_words(r: &Response) -> String {
    let mut o = match (r.dc_gain, r.dc_gain_note) {
        (Some(g), _) => num(g),
        (None, Some(note)) => note.to_string(),
        (None, None) => "n/a".to_string(),
    };
    for s in &r.sides {
        let v = match (s.identified, s.dc_gain) {
            (false, _) => "not identified".to_string(),
            (true, Some(g)) => num(g),
            (true, None) => r.dc_gain_note.unwrap_or("n/a").to_string(),
        };
        o += &format!("; {}: {v}", s.side);
    }
    o
}

/// The `warning:` lines of the report (the JSON's `warnings`), each model-file string escaped.
fn warning_lines(r: &Response) -> String {
    r.warnings
        .iter()
        .map(|w| format!("warning: {w}\n"))
        .collect()
}

/// The printed report; `controller` names the controller of the margins.
fn text(name: &str, r: &Response, controller: Option<&str>) -> String {
    let b = &r.bode;
    let mut o = format!(
        "Response of {name} (Ts = {} s, nk = {}; MATLAB idpoly conventions)\n",
        num(r.ts_s),
        r.nk
    );
    o += &format!("gain:     {}\n", r.gain);
    o += &format!("DC gain:  G(1) = {}\n", dc_words(r));
    o += &format!("poles:    {}\n", list(&r.poles));
    o += &format!("zeros:    {}\n", list(&r.zeros));
    if let (Some(m), Some(c)) = (&r.margins, controller) {
        o += &format!(
            "margins:  {c}: gain {} dB at {} rad/s, phase {} deg at {} rad/s; closed-loop \
             poles |p| <= {}{}{}\n",
            opt(m.gain_margin_db),
            opt(m.phase_crossover_rad_s),
            opt(m.phase_margin_deg),
            opt(m.gain_crossover_rad_s),
            opt(m.closed_loop_max_pole_modulus),
            if m.closed_loop_unstable() {
                ": UNSTABLE"
            } else {
                ""
            },
            if r.sides.is_empty() {
                ""
            } else {
                " (as tune: the deadzone replaced by its mean slope (m_l + m_r)/2)"
            }
        );
    }
    o += &format!(
        "\nFrequency response G(e^jwTs), {} frequencies up to the Nyquist frequency {} Hz:\n",
        b.f_hz.len(),
        num(0.5 / r.ts_s)
    );
    o += &format!(
        "{:>12} {:>12} {:>10} {:>11}",
        "f (Hz)", "w (rad/s)", "|G| dB", "phase deg"
    );
    for s in &r.sides {
        o += &format!(" {:>13}", format!("|m_{} G| dB", &s.side[..1]));
    }
    o += "\n";
    for i in 0..b.f_hz.len() {
        o += &format!(
            "{:>12} {:>12} {:>10.3} {:>11.2}",
            num(b.f_hz[i]),
            num(2.0 * std::f64::consts::PI * b.f_hz[i]),
            b.mag_db[i],
            b.phase_deg[i]
        );
        for s in &r.sides {
            o += &match s.offset_db {
                Some(db) => format!(" {:>13.3}", b.mag_db[i] + db),
                None => format!(" {:>13}", "n/a"),
            };
        }
        o += "\n";
    }
    o += "\nImpulse and unit-step response of G (t = k Ts):\n";
    o += &format!(
        "{:>6} {:>10} {:>14} {:>14}\n",
        "k", "t (s)", "impulse", "step"
    );
    for (k, (h, s)) in r.impulse.iter().zip(&r.step).enumerate() {
        o += &format!(
            "{:>6} {:>10} {:>14} {:>14}\n",
            k,
            num(k as f64 * r.ts_s),
            num(*h),
            num(*s)
        );
    }
    o + &warning_lines(r)
}

/// The Bode table as CSV.
fn csv(r: &Response) -> String {
    let b = &r.bode;
    let mut o = String::from("f_hz,w_rad_s,mag_db,phase_deg");
    for s in &r.sides {
        o += &format!(",mag_db_{}", s.side);
    }
    o += "\n";
    for i in 0..b.f_hz.len() {
        o += &format!(
            "{},{},{},{}",
            b.f_hz[i],
            2.0 * std::f64::consts::PI * b.f_hz[i],
            b.mag_db[i],
            b.phase_deg[i]
        );
        for s in &r.sides {
            // An unidentified side (slope fixed at 0) has no gain to give: an empty field.
            if let Some(db) = s.offset_db {
                o += &format!(",{}", b.mag_db[i] + db);
            } else {
                o += ",";
            }
        }
        o += "\n";
    }
    o
}

/// Runs `response`.
pub fn run(args: Args) -> anyhow::Result<()> {
    let mut inputs: Vec<&Path> = vec![&args.model];
    inputs.extend(args.controller.as_deref());
    check_outputs(&[(&args.out, "--out"), (&args.json, "--json")], &inputs)?;
    let model = sysid::model_file::read_model(&args.model).context("cannot read --model")?;
    let tuned = args
        .controller
        .as_deref()
        .map(|p| super::control::read_controller(p, model.ts(), "model").map(|f| (p, f)))
        .transpose()?;
    for (flag, v) in [
        ("--kp", args.kp),
        ("--ki", args.ki),
        ("--f-min", args.f_min),
    ] {
        if let Some(v) = v {
            if !v.is_finite() {
                anyhow::bail!("invalid setting {flag} = {v}: expected a finite number");
            }
        }
    }
    let (controller, words) = match (&tuned, args.kp) {
        (Some((path, f)), _) => {
            let c = f.controller;
            (
                Some(c),
                Some(format!(
                    "{} Kp = {}, Ki = {}, Kd = {}, Tf = {} s",
                    path.display(),
                    num(c.kp),
                    num(c.ki),
                    num(c.kd),
                    num(c.derivative_filter_s)
                )),
            )
        }
        (None, Some(kp)) => {
            let ki = args.ki.unwrap_or(0.0);
            (
                Some(control::ControllerSettings::pi(model.ts(), kp, ki)),
                Some(format!("PI Kp = {}, Ki = {}", num(kp), num(ki))),
            )
        }
        (None, None) => (None, None),
    };
    // The controller of the margins as numbers (its file, or null for --kp/--ki).
    let controller_value = controller.map(|c| {
        let file = tuned.as_ref().map(|(p, _)| p.display().to_string());
        control::response::controller_json(&c, file.as_deref())
    });
    let settings = ResponseSettings {
        points: args.points as usize,
        f_min_hz: args.f_min,
        samples: args.samples as usize,
        controller,
    };
    // The library's error kept as the cause, so that a numerical one (coefficients beyond f64) exits 1.
    // A setting's error names the flag, not the model (audit s28 L-7: `--f-min 0` blamed the model).
    let mut r = response(&model, &settings).map_err(|e| match e {
        control::ControlError::Setting { .. } => anyhow::Error::new(e),
        e => anyhow::Error::new(e).context(args.model.display().to_string()),
    })?;
    // A tuned controller that did not meet its specification says so here too, as in `control`.
    if let Some((_, f)) = &tuned {
        r.warnings
            .extend(f.provenance_warning().map(|w| format!("controller: {w}")));
        let name = args.model.display().to_string();
        r.warnings.extend(
            control::trust::controller_model_warnings(f, &model, Some(&name))
                .into_iter()
                .map(|w| format!("controller: {w}")),
        );
    }
    print_report(
        &text(&args.model.display().to_string(), &r, words.as_deref()),
        &[args.out.as_deref(), args.json.as_deref()],
    )?;
    let json = args
        .json
        .as_ref()
        .map(|_| {
            // The controller of the margins, as numbers (its file and gains, or the PI's).
            let mut v = serde_json::to_value(&r)?;
            if let (Some(o), Some(c)) = (v.as_object_mut(), &controller_value) {
                o.insert("controller".into(), c.clone());
            }
            super::common::report_json(&v, true).map(|s| s + "\n")
        })
        .transpose()?;
    let table = args.out.as_ref().map(|_| csv(&r));
    let mut outputs: Vec<(&Path, &[u8], &str)> = Vec::new();
    if let (Some(p), Some(t)) = (&args.out, &table) {
        outputs.push((p, t.as_bytes(), "--out"));
    }
    if let (Some(p), Some(t)) = (&args.json, &json) {
        outputs.push((p, t.as_bytes(), "--json"));
    }
    write_outputs(&outputs, &inputs, args.strict, r.warnings.len())
}
