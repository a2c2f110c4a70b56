//! The paper's numbers (Tables III–V), for the "paper" columns.

use sysid::ParamName;

/// Table III, estimated values as printed (b1 not normalised): b_r, b_l, m_r, m_l, a1, a2, a3, b1.
pub const ESTIMATED: [(&str, f64); 8] = [
    ("b_r", 1.4120),
    ("b_l", -1.5010),
    ("m_r", 2.3810),
    ("m_l", 3.4710),
    ("a1", -1.8200),
    ("a2", 1.0010),
    ("a3", -0.1808),
    ("b1", 7.4980e-4),
];
/// Table III, actual values as printed.
pub const ACTUAL: [(&str, f64); 8] = [
    ("b_r", 1.4100),
    ("b_l", -1.5000),
    ("m_r", 2.3800),
    ("m_l", 3.4600),
    ("a1", -1.8690),
    ("a2", 0.9976),
    ("a3", -0.1284),
    ("b1", 15.67e-4),
];
/// Table IV: (ARX, Hammerstein) best fit %, loss, FPE.
pub const FIT: (f64, f64) = (87.3102, 92.9665);
/// Table IV loss function.
pub const LOSS: (f64, f64) = (4.4000e-3, 0.8510e-3);
/// Table IV final prediction error.
pub const FPE: (f64, f64) = (4.4000e-3, 0.8561e-3);
/// Table V: (simulation, experiment) overshoot mm, e_ss mm, rise s, settling s.
pub const CLOSED_LOOP: [(&str, f64, f64); 4] = [
    ("overshoot (mm)", 0.1173, 2.1849),
    ("steady-state error (mm)", 0.0037, 0.6800),
    ("rise time (s)", 0.2231, 0.6780),
    ("settling time (s)", 0.4194, 36.5939),
];

/// The paper's Table III value of `name`, normalised to b1 = 1 (slopes times b1).
pub(crate) fn paper_normalised(table: &[(&str, f64); 8], name: ParamName) -> Option<f64> {
    let b1 = table[7].1;
    let v = table.iter().find(|(n, _)| name == *n)?.1;
    Some(match name {
        ParamName::MR | ParamName::ML => v * b1,
        ParamName::B(1) => 1.0,
        _ => v,
    })
}
