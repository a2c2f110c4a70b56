//! Batch least squares by Householder QR (never the normal equations).

use nalgebra::{DMatrix, DVector};

use crate::SysidError;

/// Result of a least-squares solve of y ≈ Φ θ.
#[derive(Debug, Clone)]
pub struct LsSolution {
    /// θ̂, the minimiser of ‖y − Φθ‖².
    pub theta: DVector<f64>,
    /// (ΦᵀΦ)⁻¹, from the triangular factor (multiply by σ² for the covariance of θ̂).
    pub inv_gram: DMatrix<f64>,
    /// Residual sum of squares ‖y − Φθ̂‖².
    pub rss: f64,
}

/// Relative size below which a diagonal entry of R (of the column-normalised Φ) counts as zero.
pub const RANK_TOLERANCE: f64 = 1e-10;

/// Solves min ‖y − Φθ‖ by QR of the column-normalised Φ. `names` label the columns in errors.
///
/// Fails with [`SysidError::Data`] when Φ is rank deficient (a column is zero or a combination of the
/// others — the input is not persistently exciting for this structure) and with
/// [`SysidError::Numerical`] on non-finite data.
pub fn solve(
    phi: &DMatrix<f64>,
    y: &DVector<f64>,
    names: &[String],
) -> Result<LsSolution, SysidError> {
    let (n, p) = phi.shape();
    if n < p {
        return Err(SysidError::Data(format!(
            "{n} regression rows for {p} parameters: too few samples for these orders"
        )));
    }
    if phi.iter().chain(y.iter()).any(|v| !v.is_finite()) {
        return Err(SysidError::Numerical(
            "non-finite value in the regression data".into(),
        ));
    }
    let name = |j: usize| {
        names
            .get(j)
            .cloned()
            .unwrap_or_else(|| format!("column {}", j + 1))
    };
    // Column scaling makes the rank test independent of units (counts vs mm vs 0/1 switches).
    let mut scale = DVector::<f64>::zeros(p);
    let mut a = phi.clone();
    for j in 0..p {
        let norm = crate::fast_ls::scaled_norm(a.column(j).as_slice());
        if norm == 0.0 {
            return Err(SysidError::Data(format!(
                "regressor {} is zero over the whole record: the input does not excite it (not persistently exciting)",
                name(j)
            )));
        }
        scale[j] = norm;
        a.column_mut(j).unscale_mut(norm);
    }
    let qr = a.qr();
    let r = qr.r();
    for j in 0..p {
        if r[(j, j)].abs() < RANK_TOLERANCE {
            return Err(SysidError::Data(format!(
                "the regressors are linearly dependent (at {}): the input is not persistently exciting for \
                 this model structure (constant input, too few distinct levels, or orders too high)",
                name(j)
            )));
        }
    }
    let qty = qr.q().transpose() * y;
    let z = r.solve_upper_triangular(&qty).ok_or_else(|| {
        SysidError::Numerical("singular triangular factor in least squares".into())
    })?;
    let theta = z.component_div(&scale);
    let resid = y - phi * &theta;
    let rss = resid.norm_squared();
    let rinv = r
        .solve_upper_triangular(&DMatrix::identity(p, p))
        .ok_or_else(|| {
            SysidError::Numerical("singular triangular factor in least squares".into())
        })?;
    let mut inv_gram = &rinv * rinv.transpose();
    for i in 0..p {
        for j in 0..p {
            inv_gram[(i, j)] /= scale[i] * scale[j];
        }
    }
    if !rss.is_finite() || theta.iter().any(|v| !v.is_finite()) {
        return Err(SysidError::Numerical(
            "least squares produced a non-finite estimate".into(),
        ));
    }
    Ok(LsSolution {
        theta,
        inv_gram,
        rss,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    // Line through (0,1), (1,3), (2,5): y = 1 + 2t exactly, so θ = [1, 2] and RSS = 0.
    #[test]
    fn fits_a_line_through_three_collinear_points() {
        let phi = DMatrix::from_row_slice(3, 2, &[1.0, 0.0, 1.0, 1.0, 1.0, 2.0]);
        let y = DVector::from_vec(vec![1.0, 3.0, 5.0]);
        let s = solve(&phi, &y, &[]).unwrap();
        assert!((s.theta[0] - 1.0).abs() < 1e-12 && (s.theta[1] - 2.0).abs() < 1e-12);
        assert!(s.rss < 1e-24);
    }

    // Mean of (1, 2, 6) is 3; RSS = 4 + 1 + 9 = 14; (ΦᵀΦ)⁻¹ = 1/3 for a column of ones.
    #[test]
    fn constant_regressor_gives_the_mean_and_its_variance_factor() {
        let phi = DMatrix::from_element(3, 1, 1.0);
        let y = DVector::from_vec(vec![1.0, 2.0, 6.0]);
        let s = solve(&phi, &y, &[]).unwrap();
        assert!((s.theta[0] - 3.0).abs() < 1e-12);
        assert!((s.rss - 14.0).abs() < 1e-12);
        assert!((s.inv_gram[(0, 0)] - 1.0 / 3.0).abs() < 1e-12);
    }

    #[test]
    fn dependent_columns_are_refused_as_not_exciting() {
        let phi = DMatrix::from_row_slice(3, 2, &[1.0, 2.0, 1.0, 2.0, 1.0, 2.0]);
        let y = DVector::from_vec(vec![1.0, 1.0, 1.0]);
        let e = solve(&phi, &y, &["a".into(), "b".into()]).unwrap_err();
        assert!(e.to_string().contains("persistently exciting"), "{e}");
    }
}
