//! Which parts of the deadzone a record can determine: the left branch (u <= b_l) is only seen when
//! the input goes below zero, the right branch (u >= b_r) only when it goes above.
//!
//! Real records are often one-sided (a pump voltage, a heater voltage never goes negative). Then the
//! unexcited branch is dropped from the structure: its slope is fixed at 0 and its breakpoint at 0, so
//! that the fitted model maps every u on that side to x = 0. When, in addition, every sample lies on the
//! remaining branch and the model has an offset c, the breakpoint of that branch and c are the same
//! regressor (−m_r b_r is a constant), so the breakpoint is fixed at 0 and c absorbs it.
//!
//! Entries of θ (key-term layout, [`Structure::theta_names`]) that are fixed are zero and not estimated.

use sysid_core::param::{Layout, Parameterisation};
use sysid_core::{Dataset, Deadzone, ModelKind, Structure, SysidError};

/// The deadzone branches a record excites, and which breakpoints are fixed.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Branches {
    /// The input goes below zero somewhere: the left branch (b_l, m_l) is estimated.
    pub left: bool,
    /// The input goes above zero somewhere: the right branch (b_r, m_r) is estimated.
    pub right: bool,
    /// b_l is fixed at 0 although m_l is estimated (every u < 0 and an offset c: not separable).
    pub b_l_fixed: bool,
    /// b_r is fixed at 0 although m_r is estimated (every u > 0 and an offset c: not separable).
    pub b_r_fixed: bool,
    /// The initial left breakpoint: the largest command below zero (see [`Branches::of`] for the case
    /// with an offset), 0 when none.
    pub max_neg: f64,
    /// The initial right breakpoint: the smallest command above zero, 0 when none.
    pub min_pos: f64,
    /// max |u|: bound for breakpoint estimates.
    pub limit: f64,
}

impl Branches {
    /// Both branches free (ARX, or a two-sided record).
    pub fn all(max_neg: f64, min_pos: f64, limit: f64) -> Self {
        Branches {
            left: true,
            right: true,
            b_l_fixed: false,
            b_r_fixed: false,
            max_neg,
            min_pos,
            limit,
        }
    }

    /// Looks at the input of `data`. With `allow_one_sided == false` a one-sided input is refused (as the
    /// paper's method would fail on it); otherwise the unexcited branch is dropped.
    pub fn of(data: &Dataset, offset: bool, allow_one_sided: bool) -> Result<Self, SysidError> {
        let (mut min_pos, mut max_pos, mut max_neg, mut min_neg) = (
            f64::INFINITY,
            f64::NEG_INFINITY,
            f64::NEG_INFINITY,
            f64::INFINITY,
        );
        let mut zero = false;
        for &v in &data.u {
            if v > 0.0 {
                min_pos = min_pos.min(v);
                max_pos = max_pos.max(v);
            } else if v < 0.0 {
                max_neg = max_neg.max(v);
                min_neg = min_neg.min(v);
            } else {
                zero = true;
            }
        }
        let right = min_pos.is_finite();
        let left = max_neg.is_finite();
        if !(allow_one_sided || left && right) {
            return Err(SysidError::Data(format!(
                "{}: the input is never {}: a Hammerstein deadzone needs commands on both sides of zero \
                 (not persistently exciting); use --model arx or richer data",
                data.name,
                if right { "negative" } else { "positive" }
            )));
        }
        if !left && !right {
            return Err(SysidError::Data(format!(
                "{}: the input is zero throughout: a Hammerstein model cannot be estimated (not persistently exciting)",
                data.name
            )));
        }
        let limit = max_pos.max(-min_neg).max(0.0);
        // Two-sided input without a zero command and with an offset: with the breakpoints at the smallest
        // commands h_r + h_l = 1 on every sample, which is the offset's column. Start instead with the
        // breakpoints at the 10 % quantiles of |u| on each side, so that some samples lie in the deadzone.
        let (mut start_neg, mut start_pos) = (max_neg, min_pos);
        if offset && left && right && !zero {
            let quantile = |mut v: Vec<f64>| {
                v.sort_by(f64::total_cmp);
                v[(v.len() - 1) / 10]
            };
            start_pos = quantile(data.u.iter().copied().filter(|&v| v > 0.0).collect());
            start_neg = -quantile(data.u.iter().filter(|&&v| v < 0.0).map(|v| -v).collect());
        }
        Ok(Branches {
            left,
            right,
            b_l_fixed: left && !right && !zero && offset,
            b_r_fixed: right && !left && !zero && offset,
            max_neg: if left { start_neg } else { 0.0 },
            min_pos: if right { start_pos } else { 0.0 },
            limit,
        })
    }

    /// True when nothing is fixed.
    pub fn is_full(&self) -> bool {
        self.left && self.right && !self.b_l_fixed && !self.b_r_fixed
    }

    /// The parameterisation of `s` in `layout` with the entries this record determines marked free.
    pub fn parameterisation(&self, s: &Structure, layout: Layout) -> Parameterisation {
        let free = match layout {
            Layout::KeyTerm => self.free_theta(s),
            Layout::Physical => self.free_physical(s),
        };
        let p = Parameterisation::new(*s, layout);
        // The masks have one entry per parameter of `s` by construction.
        p.clone().with_free(free).unwrap_or(p)
    }

    /// Which entries of θ (key-term layout [m_r, m_r b_r, m_l, m_l b_l, ...]) are estimated.
    pub fn free_theta(&self, s: &Structure) -> Vec<bool> {
        let mut free = vec![true; s.n_params()];
        if s.kind == ModelKind::Hammerstein {
            free[0] = self.right;
            free[1] = self.right && !self.b_r_fixed;
            free[2] = self.left;
            free[3] = self.left && !self.b_l_fixed;
        }
        free
    }

    /// Which entries of the physical parameter vector [b_l, b_r, m_l, m_r, a.., b2.., c] are estimated.
    pub fn free_physical(&self, s: &Structure) -> Vec<bool> {
        let mut free = vec![true; s.n_params()];
        if s.kind == ModelKind::Hammerstein {
            free[0] = self.left && !self.b_l_fixed;
            free[1] = self.right && !self.b_r_fixed;
            free[2] = self.left;
            free[3] = self.right;
        }
        free
    }

    /// The deadzone the key-term iteration starts from: breakpoints at the smallest commands on each
    /// side (every nonzero command switches its branch on), unit slopes; a dropped branch has slope 0 and
    /// breakpoint 0, a fixed breakpoint is 0.
    pub fn initial_deadzone(&self) -> Deadzone {
        Deadzone {
            b_l: if self.left && !self.b_l_fixed {
                self.max_neg
            } else {
                0.0
            },
            b_r: if self.right && !self.b_r_fixed {
                self.min_pos
            } else {
                0.0
            },
            m_l: if self.left { 1.0 } else { 0.0 },
            m_r: if self.right { 1.0 } else { 0.0 },
        }
    }

    /// Sets the fixed parts of a deadzone estimate.
    pub fn impose(&self, d: &mut Deadzone) {
        if !self.left {
            d.m_l = 0.0;
            d.b_l = 0.0;
        }
        if !self.right {
            d.m_r = 0.0;
            d.b_r = 0.0;
        }
        if self.b_l_fixed {
            d.b_l = 0.0;
        }
        if self.b_r_fixed {
            d.b_r = 0.0;
        }
    }

    /// The remarks for the report, one per fixed part (empty when nothing is fixed).
    pub fn notes(&self) -> Vec<String> {
        let mut parts = Vec::new();
        if !self.left {
            parts.push("the input is never negative: the left deadzone branch is not excited and was dropped (m_l = 0, b_l = 0 fixed)".to_string());
        }
        if !self.right {
            parts.push("the input is never positive: the right deadzone branch is not excited and was dropped (m_r = 0, b_r = 0 fixed)".to_string());
        }
        if self.b_r_fixed {
            parts.push("every input sample is on the right branch, so b_r cannot be separated from the offset c: b_r = 0 fixed (c absorbs -m_r b_r)".to_string());
        }
        if self.b_l_fixed {
            parts.push("every input sample is on the left branch, so b_l cannot be separated from the offset c: b_l = 0 fixed (c absorbs -m_l b_l)".to_string());
        }
        parts
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::Orders;
    use sysid_core::data::Signals;

    fn data(u: Vec<f64>) -> Dataset {
        let y = vec![0.0; u.len()];
        Dataset::new(Signals { u, y }, 1.0, "t").unwrap()
    }

    // u in {1, 2, 3}: no negative command, so m_l and m_l b_l (θ entries 2, 3) are not estimated.
    #[test]
    fn a_positive_input_drops_the_left_branch() {
        let b = Branches::of(&data(vec![1.0, 2.0, 3.0]), false, true).unwrap();
        assert!(!b.left && b.right && !b.b_r_fixed);
        let s = Structure {
            kind: ModelKind::Hammerstein,
            orders: Orders::PAPER,
            offset: false,
        };
        assert_eq!(&b.free_theta(&s)[..4], &[true, true, false, false]);
    }

    // Every u > 0 with an offset: the column −h_r is the constant −1, the offset column's negative.
    #[test]
    fn with_an_offset_a_breakpoint_below_all_samples_is_fixed() {
        let b = Branches::of(&data(vec![1.0, 2.0, 3.0]), true, true).unwrap();
        assert!(b.b_r_fixed);
        let b0 = Branches::of(&data(vec![0.0, 2.0, 3.0]), true, true).unwrap();
        assert!(!b0.b_r_fixed, "a zero command leaves h_r non-constant");
    }

    #[test]
    fn one_sided_input_is_refused_unless_allowed() {
        let e = Branches::of(&data(vec![-1.0, -2.0]), false, false).unwrap_err();
        assert!(e.to_string().contains("never positive"), "{e}");
    }
}
