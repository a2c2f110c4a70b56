//! This run beside the paper: the quantities, the values on both sides and why they differ.

use report::format::{estimate, opt};
use sysid::Fitted as FittedModel;
use sysid::ParamName;

use crate::paper::{self, paper_normalised};
use crate::study::{Fitted, Study};
use crate::ReproduceSettings;

/// A row of the "differences from the paper" table.
pub(crate) struct Difference {
    pub(crate) id: &'static str,
    /// Quantity and unit.
    pub(crate) quantity: &'static str,
    /// This run's values: (model label or "plant", value).
    pub(crate) plant: Vec<(String, Option<f64>)>,
    /// The paper's values: (which, value).
    pub(crate) paper: Vec<(&'static str, f64)>,
    /// Why they differ, where it is known.
    pub(crate) reason: &'static str,
}

pub(crate) fn param_value(fit: &FittedModel, name: ParamName) -> Option<f64> {
    fit.params.iter().find(|p| p.name == name).map(|p| p.value)
}

/// The side-by-side comparison of this run with the paper: deadzone, gains, dominant pole, fit, loss,
/// FPE, settling time.
pub(crate) fn differences(s: &ReproduceSettings, st: &Study) -> Vec<Difference> {
    let shown: Vec<&Fitted> = ["hammerstein", "hammerstein_oe"]
        .iter()
        .filter_map(|k| st.model(k))
        .collect();
    let per_model = |f: &dyn Fn(&Fitted) -> Option<f64>| -> Vec<(String, Option<f64>)> {
        shown.iter().map(|m| (m.short.to_string(), f(m))).collect()
    };
    let est = |name: ParamName| paper_normalised(&paper::ESTIMATED, name).unwrap_or(f64::NAN);
    let val = |m: &Fitted, f: &dyn Fn(&sysid_core::metrics::Metrics) -> Option<f64>| {
        m.rep.metrics.validation.as_ref().and_then(f)
    };
    let physics = s.plant == "ipa";
    let deadzone_reason = if physics {
        "the simulator's on/off valves open 0.4 ms after they are energised (no valve opens below 10.2 counts at a \
         10 ms PWM period) and the seals' static friction (stiction) holds the piston until the average chamber \
         pressure beats it: no motion for |u| ≤ 35 counts (docs/plant.md). 1.41 counts at the paper's 10 ms period \
         is a 0.055 ms pulse, far shorter than a solenoid valve opens, so the paper's deadzone leaves no room for \
         valve delay or stiction (docs/paper.md)"
    } else {
        "the plant is not the physics simulator: differences are estimation error"
    };
    vec![
        Difference {
            id: "b_r",
            quantity: "right breakpoint b_r (counts)",
            plant: per_model(&|m| param_value(&m.fit, ParamName::BR)),
            paper: vec![("estimated", est(ParamName::BR))],
            reason: deadzone_reason,
        },
        Difference {
            id: "b_l",
            quantity: "left breakpoint b_l (counts)",
            plant: per_model(&|m| param_value(&m.fit, ParamName::BL)),
            paper: vec![("estimated", est(ParamName::BL))],
            reason: if physics {
                "as for b_r"
            } else {
                deadzone_reason
            },
        },
        Difference {
            id: "m_r",
            quantity: "right gain m_r·b1 (mm per count and sample, b1 = 1)",
            plant: per_model(&|m| param_value(&m.fit, ParamName::MR)),
            paper: vec![("estimated", est(ParamName::MR))],
            reason: if physics {
                "beyond the deadzone the simulator's command-to-velocity curve is not a straight line (it bends up \
                 from creep at 40 counts to full speed), so one slope averages it; the paper's own estimated and \
                 actual gains differ by a factor 2.1 (docs/paper.md)"
            } else {
                "estimation error"
            },
        },
        Difference {
            id: "m_l",
            quantity: "left gain m_l·b1 (mm per count and sample, b1 = 1)",
            plant: per_model(&|m| param_value(&m.fit, ParamName::ML)),
            paper: vec![("estimated", est(ParamName::ML))],
            reason: if physics {
                "as for m_r; retracting is slower than extending (smaller rod-side area)"
            } else {
                "estimation error"
            },
        },
        Difference {
            id: "dominant_pole",
            quantity: "dominant pole, largest |p|",
            plant: per_model(&|m| m.rep.poles.iter().map(|p| p.abs).reduce(f64::max)),
            paper: vec![("estimated A(z)", 0.999445)],
            reason: "both plants integrate (position is the integral of velocity), so one pole belongs at 1; the \
                     equation-error estimates (RLS) of this integrating plant land just outside the unit circle, \
                     output error just inside. The paper's printed poles are those of its estimated A(z), not of \
                     its actual one (docs/paper.md)",
        },
        Difference {
            id: "fit",
            quantity: "validation fit (%), free-run, the worse of estimated and measured initial outputs",
            // The figure of Table IV and the verdict (audit s31 M-5: the fit from estimated initial outputs,
            // 61.96 %, stood here for an unstable model whose Table IV fit is −7.5 %).
            plant: per_model(&|m| crate::study::validation_fit(&m.rep)),
            paper: vec![("Hammerstein", paper::FIT.1)],
            reason: "a free-run fit of an integrating plant accumulates every gain error into a drift of the \
                     position; the paper does not say whether its fit is free-run or one-step ahead, nor how long its \
                     validation record is. The paper's experiment was a \"continuous step signal with amplitude \
                     ±255\", i.e. mostly full-speed motion; the staircase here visits every level in ±255 counts, \
                     inside the deadzone too, where the piston sticks",
        },
        Difference {
            id: "loss",
            quantity: "loss V = (1/N) Σ ½ ε² (mm²)",
            plant: per_model(&|m| val(m, &|v| v.loss)),
            paper: vec![("Hammerstein", paper::LOSS.1)],
            reason: "one-step errors grow with unmodelled dynamics: the simulator's pressure dynamics, friction and \
                     stick–slip are outside a 3rd-order Hammerstein model; the paper's V means a one-step RMS error of \
                     0.041 mm",
        },
        Difference {
            id: "fpe",
            quantity: "FPE (mm²)",
            plant: per_model(&|m| val(m, &|v| v.fpe)),
            paper: vec![("Hammerstein", paper::FPE.1)],
            reason: "as for the loss (FPE = V (1 + d/N)/(1 − d/N))",
        },
        Difference {
            id: "settling_time",
            quantity: "PI settling time into 2 %, fixed set-point (s)",
            plant: vec![
                ("plant".to_string(), st.fixed.m_plant.settling_time_s),
                (
                    st.cl().map_or("model".to_string(), |m| format!("{} (simulation)", m.short)),
                    st.fixed.m_model.as_ref().and_then(|m| m.settling_time_s),
                ),
            ],
            paper: vec![("simulation", paper::CLOSED_LOOP[3].1), ("experiment", paper::CLOSED_LOOP[3].2)],
            reason: if physics {
                "the piston stops where |Kp e + integral| falls inside the deadzone and the slow integral (Ki Ts = \
                 0.01 count per mm and sample) takes seconds to push it out; the paper's own experiment took 36.6 s, \
                 its 0.42 s is a simulation of its model"
            } else {
                "the paper does not state its step size or integral form (docs/paper.md)"
            },
        },
    ]
}

pub(crate) fn difference_cells(d: &Difference) -> [String; 4] {
    let join = |v: Vec<String>| v.join("; ");
    [
        d.quantity.to_string(),
        join(
            d.plant
                .iter()
                .map(|(l, v)| format!("{l}: {}", opt(*v)))
                .collect(),
        ),
        join(
            d.paper
                .iter()
                .map(|(l, v)| format!("{l}: {}", estimate(*v)))
                .collect(),
        ),
        d.reason.to_string(),
    ]
}
