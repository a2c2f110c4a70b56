//! `str(model)`: a model as the equations it stands for, with units (paper eqs. 1 and 5–7), for the
//! Python package's `Model.__str__`. Rendering only; the numbers are the model's.

use std::fmt::Write;

use sysid::{Model, StaticNonlinearity};

/// A number with 4 significant digits (scientific notation outside 1e-3..1e5).
fn num(v: f64) -> String {
    if v == 0.0 || !v.is_finite() {
        return format!("{v}");
    }
    let mag = v.abs().log10().floor();
    if !(-3.0..5.0).contains(&mag) {
        return format!("{v:.3e}");
    }
    let decimals = (3.0 - mag).max(0.0) as usize;
    let s = format!("{v:.decimals$}");
    if s.contains('.') {
        s.trim_end_matches('0').trim_end_matches('.').to_string()
    } else {
        s
    }
}

/// `s(k)` or `s(k−lag)`.
fn lagged(signal: &str, lag: usize) -> String {
    if lag == 0 {
        format!("{signal}(k)")
    } else {
        format!("{signal}(k−{lag})")
    }
}

/// `+ c·s` / `− c·s` for the next term of a sum.
fn term(out: &mut String, first: &mut bool, coefficient: f64, signal: &str) {
    let sign = if coefficient < 0.0 { "−" } else { "+" };
    if *first {
        let lead = if coefficient < 0.0 { "−" } else { "" };
        let _ = write!(out, "{lead}{} {signal}", num(coefficient.abs()));
        *first = false;
    } else {
        let _ = write!(out, " {sign} {} {signal}", num(coefficient.abs()));
    }
}

/// The model as equations: the static nonlinearity of each input, then the difference equation
/// y(k) = −a1 y(k−1) − … + Σ b_j x(k−nk−j+1) + c, with Ts and the units: u in PWM counts and y in mm
/// for the paper's IPA model, the estimation record's own units for any other (the rule of `control`'s
/// messages, `ipa::PlantLimits::model_units`; audit s18 L-8: IPA units were printed for a hair-dryer
/// model). The slopes carry the gain since b1 = 1 for a nonlinear input.
pub(crate) fn equations(m: &Model) -> String {
    let mut o = String::new();
    let several = m.inputs().len() > 1;
    let ipa_units = !ipa::PlantLimits::of_model(m).model_units();
    let (units, u_unit, y_unit) = if ipa_units {
        ("u in PWM counts, y in mm", " counts", " mm")
    } else {
        ("u and y in the estimation record's units", "", "")
    };
    let _ = writeln!(
        o,
        "{} model, Ts = {} s ({units}; {} parameters)",
        match (
            m.kind().to_string().as_str(),
            m.output_nonlinearity().is_some()
        ) {
            ("arx", false) => "ARX".to_string(),
            ("hammerstein", false) => "Hammerstein".to_string(),
            ("arx", true) => "Wiener (ARX and an output nonlinearity)".to_string(),
            (_, true) => "Hammerstein–Wiener".to_string(),
            (other, false) => other.to_string(),
        },
        num(m.ts()),
        m.parameter_count()
    );
    if let Some(op) = m.operating_point() {
        let u0: Vec<String> = op.u.iter().map(|v| num(*v)).collect();
        let u0 = if u0.len() == 1 {
            u0.concat()
        } else {
            format!("({})", u0.join(", "))
        };
        let _ = writeln!(
            o,
            "  signals are deviations from the operating point u0 = {u0}{u_unit}, y0 = {}{y_unit}",
            num(op.y)
        );
    }
    let mut rhs = String::new();
    let mut first = true;
    for (i, a) in m.a().iter().enumerate() {
        term(&mut rhs, &mut first, -a, &lagged("y", i + 1));
    }
    for ch in m.inputs() {
        let (u, x) = if several {
            (format!("{}(k)", ch.name()), format!("x_{}", ch.name()))
        } else {
            ("u(k)".to_string(), "x".to_string())
        };
        match ch.nonlinearity() {
            StaticNonlinearity::Linear => {
                let _ = writeln!(o, "  {x}(k) = {u}");
            }
            StaticNonlinearity::Deadzone(d) => {
                // u − b written as u + |b| for a negative breakpoint.
                let shifted = |b: f64| {
                    if b < 0.0 {
                        format!("{u} + {}", num(-b))
                    } else {
                        format!("{u} − {}", num(b))
                    }
                };
                let _ = writeln!(
                    o,
                    "  {x}(k) = {} ({})  if {u} ≥ b_r = {}{u_unit}\n  {x}(k) = 0  if b_l < {u} < b_r\n  {x}(k) = {} ({})  if {u} ≤ b_l = {}{u_unit}",
                    num(d.m_r),
                    shifted(d.b_r),
                    num(d.b_r),
                    num(d.m_l),
                    shifted(d.b_l),
                    num(d.b_l)
                );
            }
            other => {
                let _ = writeln!(o, "  {x}(k) = {}", map_text(other, &u, u_unit));
            }
        }
        for (j, b) in ch.b().iter().enumerate() {
            term(&mut rhs, &mut first, *b, &lagged(&x, ch.nk() + j));
        }
    }
    if let Some(c) = m.offset() {
        term(&mut rhs, &mut first, c, "");
    }
    if first {
        rhs.push('0');
    }
    // With an output nonlinearity (Wiener, Hammerstein–Wiener) the recursion is the linear block's
    // output v, and y = g(v) (audit s31 M-4: the recursion was printed as y(k)).
    match m.output_nonlinearity() {
        Some(g) => {
            let rhs = rhs.replace("y(k−", "v(k−");
            let _ = writeln!(o, "  v(k) = {}", rhs.trim_end());
            let _ = write!(o, "  y(k) = g(v(k)) = {}", map_text(g, "v(k)", y_unit));
        }
        None => {
            let _ = write!(o, "  y(k) = {}", rhs.trim_end());
        }
    }
    o
}

/// A static map other than the deadzone (which has its own three lines) applied to `arg`, in words
/// and 4 significant digits (audit s31 L-2: a polynomial printed as a Rust debug dump). `unit`: the
/// argument's unit for breakpoints and limits (" counts", " mm" or "").
fn map_text(f: &StaticNonlinearity, arg: &str, unit: &str) -> String {
    match f {
        StaticNonlinearity::Linear => arg.to_string(),
        StaticNonlinearity::Deadzone(d) => format!(
            "deadzone({arg}; b_l = {}{unit}, b_r = {}{unit}, m_l = {}, m_r = {})",
            num(d.b_l),
            num(d.b_r),
            num(d.m_l),
            num(d.m_r)
        ),
        StaticNonlinearity::Saturation(s) => format!(
            "{} clamp({arg}, {}{unit}, {}{unit})",
            num(s.m),
            num(s.s_l),
            num(s.s_r)
        ),
        StaticNonlinearity::DeadzoneSaturation(d) => format!(
            "{} (min({arg}, {}) − {}) if {arg} ≥ b_r = {}{unit}; 0 if b_l < {arg} < b_r; {} (max({arg}, {}) − {}) \
             if {arg} ≤ b_l = {}{unit} (saturating at s_l = {}{unit}, s_r = {}{unit})",
            num(d.m_r),
            num(d.s_r),
            num(d.b_r),
            num(d.b_r),
            num(d.m_l),
            num(d.s_l),
            num(d.b_l),
            num(d.b_l),
            num(d.s_l),
            num(d.s_r)
        ),
        StaticNonlinearity::PiecewiseLinear(p) => {
            let bps: Vec<String> = p.breakpoints().iter().map(|b| format!("{}{unit}", num(*b))).collect();
            let slopes: Vec<String> = p.slopes().iter().map(|s| num(*s)).collect();
            format!(
                "piecewise linear in {arg} through 0: slopes {} between the breakpoints {}",
                slopes.join(", "),
                bps.join(", ")
            )
        }
        StaticNonlinearity::Polynomial(poly) => {
            let mut t = String::new();
            let mut first = true;
            for (i, g) in poly.coefficients().iter().enumerate() {
                if *g == 0.0 {
                    continue;
                }
                let power = match i {
                    0 => arg.to_string(),
                    1 => format!("{arg}²"),
                    2 => format!("{arg}³"),
                    d => format!("{arg}^{}", d + 1),
                };
                term(&mut t, &mut first, *g, &power);
            }
            if first {
                t.push('0');
            }
            t
        }
    }
}
