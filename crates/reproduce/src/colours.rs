//! One colour per model and signal across every figure of the report: the legend key, kept in one
//! place. The colours are [`report::plot::PALETTE`]'s (Okabe–Ito, colour-blind safe).

use report::plot::PALETTE;

/// An `(r, g, b)` colour.
pub type Rgb = (u8, u8, u8);

/// The plant and its measured signals (position y, command u): black.
pub const PLANT: Rgb = PALETTE[0];
/// The set-point r: sky blue.
pub const SETPOINT: Rgb = PALETTE[6];
/// The paper's Table III model (its "actual" values): orange.
pub const PAPER: Rgb = PALETTE[5];
/// Confidence bounds and reference lines: grey.
pub const BOUND: Rgb = (136, 136, 136);

/// The colour of the model with key `key` (the keys of `summary.json` `models`); the plant's colour for
/// an unknown key.
pub fn model(key: &str) -> Rgb {
    match key {
        "arx" => PALETTE[1],
        "hammerstein" => PALETTE[2],
        "hammerstein_ls" => PALETTE[3],
        "hammerstein_oe" => PALETTE[4],
        "paper" => PAPER,
        _ => PLANT,
    }
}

/// The name of a colour of this key, for the report's legend key.
pub fn name(rgb: Rgb) -> &'static str {
    match rgb {
        c if c == PALETTE[0] => "black",
        c if c == PALETTE[1] => "vermillion",
        c if c == PALETTE[2] => "blue",
        c if c == PALETTE[3] => "bluish green",
        c if c == PALETTE[4] => "reddish purple",
        c if c == PALETTE[5] => "orange",
        c if c == PALETTE[6] => "sky blue",
        c if c == BOUND => "grey",
        _ => "other",
    }
}

/// `#rrggbb`, as the SVG figures write the colour.
pub fn hex(rgb: Rgb) -> String {
    format!("#{:02X}{:02X}{:02X}", rgb.0, rgb.1, rgb.2)
}
