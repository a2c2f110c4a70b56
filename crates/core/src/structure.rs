//! The model structures as regressors: each structure turns data (and, for the Hammerstein model, the
//! current deadzone estimate) into rows φ(k) of a linear regression y(k) = φᵀ(k) θ + ε(k). Every estimator
//! works on every structure through this.

use crate::model::MAX_ORDER;
use crate::param::{Layout, Parameterisation};
use crate::{Deadzone, ModelKind, Orders, Setting, SysidError};

/// A linear-in-parameters structure: ARX, or Hammerstein by key-term separation (docs/paper.md, eq. 8).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Structure {
    /// ARX or Hammerstein.
    pub kind: ModelKind,
    /// na, nb, nk.
    pub orders: Orders,
    /// Whether a constant term c is estimated.
    pub offset: bool,
}

impl Structure {
    /// The structure every estimator accepts (`identify`, `order`, `track`): orders at most
    /// [`MAX_ORDER`], nb ≥ 1 for a Hammerstein model (b1 = 1 is its key term), at least one parameter; or
    /// the error naming the setting.
    pub fn check(&self) -> Result<(), SysidError> {
        let o = self.orders;
        for (setting, v) in [
            (Setting::Na, o.na),
            (Setting::Nb, o.nb),
            (Setting::Nk, o.nk),
        ] {
            if v > MAX_ORDER {
                return Err(SysidError::setting(
                    setting,
                    v,
                    &format!("an order of at most {MAX_ORDER}"),
                ));
            }
        }
        if self.kind == ModelKind::Hammerstein && o.nb == 0 {
            return Err(SysidError::setting(
                Setting::Nb,
                0,
                "nb >= 1 for a Hammerstein model (b1 = 1 is the key term)",
            ));
        }
        if self.n_params() == 0 {
            return Err(SysidError::Data(
                "the model has no parameter to estimate (na = nb = 0)".into(),
            ));
        }
        Ok(())
    }

    /// Number of entries of θ.
    ///
    /// ARX: θ = [a1..a_na, b1..b_nb, (c)].
    /// Hammerstein: θ = [m_r, m_r b_r, m_l, m_l b_l, a1..a_na, b2..b_nb, (c)] (b1 = 1).
    pub fn n_params(&self) -> usize {
        let o = self.orders;
        let c = usize::from(self.offset);
        match self.kind {
            ModelKind::Arx => o.na + o.nb + c,
            ModelKind::Hammerstein => 4 + o.na + o.nb.saturating_sub(1) + c,
        }
    }

    /// Names of the entries of θ (key-term layout), for messages and reports.
    pub fn theta_names(&self) -> Vec<String> {
        Parameterisation::new(*self, Layout::KeyTerm).name_strings()
    }

    /// Fills `row` with φ(k). For Hammerstein, `dz` gives the switching functions h_r, h_l at
    /// u(k−nk) and the internal x̂(k−nk−j) = dz(u(k−nk−j)) for j ≥ 1. Requires k ≥ k0.
    #[inline]
    pub fn fill_row(&self, u: &[f64], y: &[f64], k: usize, dz: &Deadzone, row: &mut [f64]) {
        let o = self.orders;
        let mut i = 0;
        let nk = o.nk;
        if self.kind == ModelKind::Hammerstein {
            let uk = u[k - nk];
            let hr = dz.h_r(uk);
            let hl = dz.h_l(uk);
            row[0] = hr * uk;
            row[1] = -hr;
            row[2] = hl * uk;
            row[3] = -hl;
            i = 4;
        }
        for a in 1..=o.na {
            row[i] = -y[k - a];
            i += 1;
        }
        match self.kind {
            ModelKind::Arx => {
                for j in 0..o.nb {
                    row[i] = u[k - nk - j];
                    i += 1;
                }
            }
            ModelKind::Hammerstein => {
                for j in 1..o.nb {
                    row[i] = dz.apply(u[k - nk - j]);
                    i += 1;
                }
            }
        }
        if self.offset {
            row[i] = 1.0;
        }
    }

    /// Left-hand side of the regression at sample k: y(k) for ARX; for Hammerstein also y(k) (the key
    /// term x(k−nk) with b1 = 1 is inside φᵀθ).
    #[inline]
    pub fn target(&self, y: &[f64], k: usize) -> f64 {
        y[k]
    }
}
