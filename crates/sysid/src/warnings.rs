//! Warnings: when an estimate may not deserve trust, the tool says so in words (the `warnings` list of
//! `identify --json`, `warning: ...` lines in the text). Each [`Warning`] is typed; its `Display` is
//! the sentence users read. [`deadzone_warnings`] holds the checks of a deadzone against the data.

use serde::{Serialize, Serializer};
use sysid_core::{Deadzone, Model, ParamName};

/// Which record a warning is about.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Record {
    /// The estimation data.
    Estimation,
    /// The validation data.
    Validation,
}

impl std::fmt::Display for Record {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            Record::Estimation => "estimation",
            Record::Validation => "validation",
        })
    }
}

/// A deadzone branch.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Branch {
    /// u <= b_l.
    Left,
    /// u >= b_r.
    Right,
}

impl std::fmt::Display for Branch {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            Branch::Left => "left",
            Branch::Right => "right",
        })
    }
}

/// A reason not to trust an estimate blindly.
#[derive(Debug, Clone, PartialEq)]
pub enum Warning {
    /// A pole on or outside the unit circle.
    Unstable {
        /// Largest pole modulus.
        max_pole_modulus: f64,
    },
    /// The free-run simulation does worse than the mean of the record (fit < 0 %), or diverges.
    PoorSimulation {
        /// Which record.
        record: Record,
        /// The fit % (`None`: the simulation diverged).
        fit_percent: Option<f64>,
    },
    /// The estimator stopped before its convergence criterion.
    NotConverged {
        /// How it stopped, in words.
        how: String,
    },
    /// The method's own Hammerstein estimate diverged or trails the linear ARX start, which was not
    /// substituted (fallback off).
    LinearStartBetter {
        /// What is wrong with the estimate.
        why: String,
    },
    /// Another estimate than the method's own result was returned.
    Fallback {
        /// What was returned.
        used: String,
        /// Why.
        why: String,
    },
    /// A breakpoint sits on one of the input's levels, or within its standard deviation of one: the
    /// loss has a kink there, so the quadratic approximation behind the standard deviation fails.
    BreakpointOnInputLevel {
        /// b_l or b_r.
        name: ParamName,
        /// Its value.
        value: f64,
        /// The level (counts).
        level: f64,
    },
    /// A breakpoint outside the range of the input: no data on one side of it.
    BreakpointNotBracketed {
        /// b_l or b_r.
        name: ParamName,
        /// Its value.
        value: f64,
        /// Smallest input.
        u_min: f64,
        /// Largest input.
        u_max: f64,
    },
    /// b_l > b_r, or slopes of opposite sign.
    NonPhysicalDeadzone {
        /// What is wrong.
        why: String,
    },
    /// A warning about the deadzone of one input of a several-input model.
    ForInput {
        /// The input's name.
        input: String,
        /// The warning (one of the deadzone checks).
        warning: Box<Warning>,
    },
    /// A deadzone branch with fewer than two distinct input levels beyond its breakpoint: its slope and
    /// breakpoint are not separately determined.
    FewInputLevels {
        /// Which branch.
        branch: Branch,
        /// Distinct levels beyond the breakpoint.
        levels: usize,
    },
    /// A trust check of [`crate::trust`] (initial state, baseline, standard deviations).
    Trust(crate::trust::Concern),
}

impl std::fmt::Display for Warning {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Warning::Unstable { max_pole_modulus } => write!(
                f,
                "unstable model: a pole has modulus {max_pole_modulus:.6} >= 1; its simulation diverges \
                 (do not use it for simulation or control)"
            ),
            Warning::PoorSimulation {
                record,
                fit_percent: Some(fit),
            } => write!(
                f,
                "negative simulation fit on the {record} data ({fit:.2} %): the model simulates worse than \
                 the record's mean"
            ),
            Warning::PoorSimulation {
                record,
                fit_percent: None,
            } => write!(f, "the free-run simulation diverges on the {record} data"),
            Warning::NotConverged { how } => write!(f, "not converged: {how}"),
            Warning::Fallback { used, why } => write!(f, "fallback used: {used}, because {why}"),
            Warning::LinearStartBetter { why } => write!(
                f,
                "{why}; the linear ARX model of the same orders does better (the fallback option returns \
                 it as a Hammerstein model with b_l = b_r = 0)"
            ),
            Warning::BreakpointOnInputLevel { name, value, level } => write!(
                f,
                "{name} = {value:.6} lies on the input level {level} (within its standard deviation): the \
                 criterion has a kink there, so its standard deviation is not meaningful (not reported)"
            ),
            Warning::BreakpointNotBracketed {
                name,
                value,
                u_min,
                u_max,
            } => write!(
                f,
                "{name} = {value:.6} is not bracketed by the data (input range {u_min} .. {u_max}): no \
                 samples on one side of it, so it is not determined and its standard deviation is not \
                 meaningful (not reported)"
            ),
            Warning::NonPhysicalDeadzone { why } => write!(f, "deadzone not physical: {why}"),
            Warning::ForInput { input, warning } => write!(f, "input {input}: {warning}"),
            Warning::FewInputLevels { branch, levels } => write!(
                f,
                "too few distinct input levels on the {branch} deadzone branch ({levels} beyond its \
                 breakpoint; at least 2 are needed to separate slope and breakpoint)"
            ),
            Warning::Trust(c) => c.fmt(f),
        }
    }
}

impl Warning {
    /// Whether this warning already says why the parameter named `param` (as in a several-input
    /// parameter list: `b_l (u1)`) has no standard deviation: a breakpoint warning naming it, or the
    /// linear start returned by the fallback (its breakpoints are fixed at 0 and its B/b1 not estimated
    /// as such).
    pub fn explains_missing_std(&self, param: &str) -> bool {
        match self {
            Warning::Fallback { used, .. } => used.starts_with(crate::estimate::LINEAR_START_USED),
            Warning::ForInput { input, warning } => match warning.as_ref() {
                Warning::BreakpointOnInputLevel { name, .. }
                | Warning::BreakpointNotBracketed { name, .. } => {
                    param == format!("{name} ({input})")
                }
                _ => false,
            },
            _ => false,
        }
    }

    /// [`Warning::Unstable`] when a pole of `model` has modulus >= 1.
    pub fn if_unstable(model: &Model) -> Option<Warning> {
        let max_pole_modulus = model.poles().iter().map(|z| z.norm()).fold(0.0, f64::max);
        (max_pole_modulus >= 1.0).then_some(Warning::Unstable { max_pole_modulus })
    }

    /// [`Warning::PoorSimulation`] when the simulation fit % on `record` is negative or missing (the
    /// simulation diverged).
    pub fn if_poor_simulation(record: Record, fit_percent: Option<f64>) -> Option<Warning> {
        match fit_percent {
            Some(f) if f >= 0.0 => None,
            other => Some(Warning::PoorSimulation {
                record,
                fit_percent: other,
            }),
        }
    }
}

impl Serialize for Warning {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        s.collect_str(self)
    }
}

/// Checks a deadzone estimate against the input it was estimated from: a physical shape, breakpoints
/// bracketed by the data and not on an input level (nor within their standard deviation `std_l`,
/// `std_r` of one), at least two distinct levels on each estimated branch. `left`/`right`: whether that
/// branch was estimated (not dropped for a one-sided input). Returns the warnings and the names of the
/// breakpoints whose standard deviation is not meaningful.
pub fn deadzone_warnings(
    d: &Deadzone,
    u: &[f64],
    (left, right): (bool, bool),
    (std_l, std_r): (Option<f64>, Option<f64>),
) -> (Vec<Warning>, Vec<ParamName>) {
    let mut w = Vec::new();
    let mut no_std = Vec::new();
    let mut levels: Vec<f64> = u.to_vec();
    levels.sort_by(f64::total_cmp);
    levels.dedup();
    let (u_min, u_max) = match (levels.first(), levels.last()) {
        (Some(a), Some(b)) => (*a, *b),
        _ => return (w, no_std),
    };
    if left && right && d.b_l > d.b_r {
        w.push(Warning::NonPhysicalDeadzone {
            why: format!("b_l = {} > b_r = {}", d.b_l, d.b_r),
        });
    }
    if left && right && d.m_l * d.m_r < 0.0 {
        w.push(Warning::NonPhysicalDeadzone {
            why: format!(
                "the slopes have opposite signs (m_l = {}, m_r = {})",
                d.m_l, d.m_r
            ),
        });
    }
    let checks = [
        (left, ParamName::BL, d.b_l, std_l, Branch::Left),
        (right, ParamName::BR, d.b_r, std_r, Branch::Right),
    ];
    for (estimated, name, b, std, branch) in checks {
        if !estimated {
            continue;
        }
        let reach = |l: f64| (1e-9 * l.abs().max(1.0)).max(std.unwrap_or(0.0));
        if let Some(level) = levels.iter().find(|l| (b - **l).abs() <= reach(**l)) {
            w.push(Warning::BreakpointOnInputLevel {
                name,
                value: b,
                level: *level,
            });
            no_std.push(name);
        } else if b <= u_min || b >= u_max {
            w.push(Warning::BreakpointNotBracketed {
                name,
                value: b,
                u_min,
                u_max,
            });
            no_std.push(name);
        }
        let beyond = levels
            .iter()
            .filter(|l| match branch {
                Branch::Left => **l < b,
                Branch::Right => **l > b,
            })
            .count();
        if beyond < 2 {
            w.push(Warning::FewInputLevels {
                branch,
                levels: beyond,
            });
        }
    }
    (w, no_std)
}

#[cfg(test)]
mod tests {
    use super::*;
    use sysid_core::data::Signals;

    use sysid_core::Dataset;

    fn data(u: Vec<f64>) -> Dataset {
        let y = vec![0.0; u.len()];
        Dataset::new(Signals { u, y }, 1.0, "t").unwrap()
    }

    // A staircase of levels −60, −56, −48, −33, 20, 40, 60: a deadzone with b_l = −48 (on a level, two
    // levels below it) and b_r = 25 (between levels) warns about b_l only; b_r keeps its standard
    // deviation.
    #[test]
    fn a_breakpoint_on_an_input_level_is_flagged() {
        let d = data(vec![-60.0, -56.0, -48.0, -33.0, 20.0, 40.0, 60.0, -56.0]);
        let dz = Deadzone {
            b_l: -48.0,
            b_r: 25.0,
            m_l: 0.005,
            m_r: 0.005,
        };
        let (w, no_std) = deadzone_warnings(&dz, &d.u, (true, true), (None, None));
        assert_eq!(no_std, vec![ParamName::BL]);
        assert!(matches!(
            w[..],
            [Warning::BreakpointOnInputLevel { level, .. }] if level == -48.0
        ));
        assert!(w[0].to_string().contains("lies on the input level -48"));
        // A breakpoint 4e-5 from the level, with a standard deviation of 0.5: the kink is within one
        // standard deviation, so the same warning; 0.4 away with σ 0.1 is not.
        let near = Deadzone {
            b_l: -47.99996,
            ..dz
        };
        let (w, _) = deadzone_warnings(&near, &d.u, (true, true), (Some(0.5), Some(0.1)));
        assert!(
            matches!(w[..], [Warning::BreakpointOnInputLevel { .. }]),
            "{w:?}"
        );
        let apart = Deadzone { b_l: -47.6, ..dz };
        let (w, no_std) = deadzone_warnings(&apart, &d.u, (true, true), (Some(0.1), Some(0.1)));
        assert!(w.is_empty() && no_std.is_empty(), "{w:?}");
    }

    // b_r above every command: not bracketed; the right branch has no level beyond it.
    #[test]
    fn a_breakpoint_outside_the_input_range_is_not_bracketed() {
        let d = data(vec![-30.0, -20.0, -10.0, 5.0, 10.0]);
        let dz = Deadzone {
            b_l: -15.0,
            b_r: 12.0,
            m_l: 1.0,
            m_r: 1.0,
        };
        let (w, no_std) = deadzone_warnings(&dz, &d.u, (true, true), (None, None));
        assert_eq!(no_std, vec![ParamName::BR]);
        assert!(w.contains(&Warning::BreakpointNotBracketed {
            name: ParamName::BR,
            value: 12.0,
            u_min: -30.0,
            u_max: 10.0
        }));
        assert!(w.contains(&Warning::FewInputLevels {
            branch: Branch::Right,
            levels: 0
        }));
        // Left: levels below −15 are −30 and −20: two, enough.
        assert!(!w.contains(&Warning::FewInputLevels {
            branch: Branch::Left,
            levels: 2
        }));
    }

    // b_l > b_r and slopes of opposite sign are not a valve deadzone.
    #[test]
    fn crossed_breakpoints_and_opposite_slopes_are_not_physical() {
        let d = data(vec![-30.0, -20.0, -10.0, 10.0, 20.0, 30.0]);
        let dz = Deadzone {
            b_l: 5.0,
            b_r: -5.0,
            m_l: -1.0,
            m_r: 1.0,
        };
        let (w, _) = deadzone_warnings(&dz, &d.u, (true, true), (None, None));
        let n = w
            .iter()
            .filter(|w| matches!(w, Warning::NonPhysicalDeadzone { .. }))
            .count();
        assert_eq!(n, 2, "{w:?}");
    }

    // A dropped branch is not checked.
    #[test]
    fn dropped_branches_are_not_checked() {
        let d = data(vec![1.0, 2.0, 3.0, 4.0]);
        let dz = Deadzone {
            b_l: 0.0,
            b_r: 1.5,
            m_l: 0.0,
            m_r: 1.0,
        };
        let (w, _) = deadzone_warnings(&dz, &d.u, (false, true), (None, None));
        assert!(w.is_empty(), "{w:?}");
    }
}
