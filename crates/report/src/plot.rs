//! Figures for the report: time series and static curves drawn as SVG (for the HTML report, text stays
//! text) and PNG (for everything else), with the same layout in both.
//!
//! A [`Figure`] is a title over one or more [`Panel`]s stacked vertically, each a pair of axes with
//! labelled series. Paper's Fig. 2, for instance, is a figure with an input panel (`u`, PWM counts)
//! above an output panel (`y`, position in mm):
//!
//! ```
//! use report::plot::{render_svg, Figure, Panel, Series, SeriesStyle};
//!
//! let t_s: Vec<f64> = (0..200).map(|k| k as f64 * 0.01).collect();
//! let u: Vec<f64> = t_s.iter().map(|&t| if t < 1.0 { 255.0 } else { -255.0 }).collect();
//! let y_mm: Vec<f64> = t_s.iter().map(|&t| if t < 1.0 { 30.0 * t } else { 30.0 - 20.0 * (t - 1.0) }).collect();
//! let fig = Figure::new("Identification data")
//!     .size(900, 600)
//!     .panel(Panel::new("time t (s)", "input u (PWM counts)").series(Series::step("u", t_s.clone(), u)))
//!     .panel(Panel::new("time t (s)", "position y (mm)").series(Series::line("y", t_s, y_mm)));
//! let svg = render_svg(&fig).unwrap();
//! assert!(svg.contains("Identification data"));
//! ```
//!
//! Drawing rules, so that every figure of the report reads the same way:
//! - colours follow the Okabe–Ito palette (distinguishable with the common colour-vision deficiencies),
//!   by the series' position in its panel; dashed series also differ by their dash pattern, so that a
//!   grey-scale print still tells them apart;
//! - non-finite samples (NaN, ±inf) are skipped: a line breaks at them instead of plunging off the axes;
//! - the x axis spans the finite data exactly; the y axis adds 5 % above and below; a constant series
//!   gets a padded range around its value, a panel with no finite sample gets the range 0..1;
//! - the legend goes into a corner of the panel that no data cross; when data run through every corner,
//!   it goes below the plot, outside the axes (in as many columns as the width holds), so that it never
//!   hides a curve (before session 34 the top of the y axis was raised for a band, and a curve above a
//!   fixed range then ran under the legend: Fig. 5's ARX curve near 335 mm);
//! - a fixed y range ([`Panel::y_range`]) clips the data at the axes drawn, so a clipped curve sits on
//!   the frame; [`y_axes`] tells a caption the range drawn.
//!
//! Text is drawn with DejaVu Sans embedded in the binary (`assets/DejaVuSans.ttf`), so PNG rendering
//! needs no system font.

use std::path::Path;
use std::sync::OnceLock;

use plotters::coord::Shift;
use plotters::element::DashedPathElement;
use plotters::prelude::*;
use plotters::style::{register_font, FontStyle};

use crate::ReportError;

/// DejaVu Sans, the font used for all text of the figures (license in `assets/DejaVuSans-LICENSE.txt`).
static DEJAVU_SANS: &[u8] = include_bytes!("../../../assets/DejaVuSans.ttf");

/// The font family name under which DejaVu Sans is registered with plotters. SVG output carries it
/// verbatim as the `font-family` attribute, so a browser uses DejaVu Sans when installed (the metrics
/// the layout was computed with) and any sans-serif font otherwise.
const FONT_FAMILY: &str = "DejaVu Sans, sans-serif";

/// Default figure width in pixels (SVG user units).
pub const DEFAULT_WIDTH: u32 = 960;
/// Default figure height in pixels for a single panel; [`Figure::panel`] grows the default height
/// by [`DEFAULT_PANEL_HEIGHT`] for each further panel unless [`Figure::size`] was called.
pub const DEFAULT_HEIGHT: u32 = 480;
/// Height in pixels added to a default-sized figure for each panel after the first.
pub const DEFAULT_PANEL_HEIGHT: u32 = 320;

/// Largest accepted width or height in pixels (a 8192 x 8192 RGB buffer is 200 MB).
pub const MAX_SIDE: u32 = 8192;

/// The Okabe–Ito colour-blind-safe palette, reordered for print on white paper: black first (the
/// measured data or the reference in most figures), then vermillion, blue, bluish green, reddish
/// purple, orange and sky blue. Yellow is left out: it is unreadable on white.
pub const PALETTE: [(u8, u8, u8); 7] = [
    (0, 0, 0),
    (213, 94, 0),
    (0, 114, 178),
    (0, 158, 115),
    (204, 121, 167),
    (230, 159, 0),
    (86, 180, 233),
];

/// Dash patterns (dash length, gap length) in pixels, used in turn by the dashed series of a panel.
const DASHES: [(u32, u32); 4] = [(10, 5), (4, 4), (16, 5), (7, 3)];

/// How a series is drawn.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SeriesStyle {
    /// A solid line through the samples (measured or simulated signals).
    Line,
    /// A dashed line through the samples (references, set-points, a second model).
    Dashed,
    /// Unconnected markers (static characteristics, sparse estimates).
    Points,
    /// Zero-order hold: each sample's value is held until the next sample's `x`, as the PWM command
    /// `u(k)` is held for one sampling period `Ts`.
    Step,
}

/// One labelled curve: the pairs `(x[i], y[i])`, drawn in the given [`SeriesStyle`].
#[derive(Debug, Clone, PartialEq)]
pub struct Series {
    /// Legend text; an empty label leaves the series out of the legend.
    pub label: String,
    /// Abscissae (often time in s); must have the same length as `y`.
    pub x: Vec<f64>,
    /// Ordinates (in the unit named by the panel's `y_label`).
    pub y: Vec<f64>,
    /// How the series is drawn.
    pub style: SeriesStyle,
    /// Colour as `(r, g, b)`; `None` takes the [`PALETTE`] colour of the series' position in its panel.
    /// Give a colour when one curve (a model, the plant) must keep its colour across figures.
    pub colour: Option<(u8, u8, u8)>,
}

impl Series {
    /// A series drawn in `style`.
    pub fn new(label: impl Into<String>, x: Vec<f64>, y: Vec<f64>, style: SeriesStyle) -> Self {
        Series {
            label: label.into(),
            x,
            y,
            style,
            colour: None,
        }
    }

    /// Sets the colour `(r, g, b)` (builder style), overriding the palette colour of its position.
    pub fn colour(mut self, rgb: (u8, u8, u8)) -> Self {
        self.colour = Some(rgb);
        self
    }

    /// A solid line ([`SeriesStyle::Line`]).
    pub fn line(label: impl Into<String>, x: Vec<f64>, y: Vec<f64>) -> Self {
        Series::new(label, x, y, SeriesStyle::Line)
    }

    /// A dashed line ([`SeriesStyle::Dashed`]).
    pub fn dashed(label: impl Into<String>, x: Vec<f64>, y: Vec<f64>) -> Self {
        Series::new(label, x, y, SeriesStyle::Dashed)
    }

    /// Markers only ([`SeriesStyle::Points`]).
    pub fn points(label: impl Into<String>, x: Vec<f64>, y: Vec<f64>) -> Self {
        Series::new(label, x, y, SeriesStyle::Points)
    }

    /// A zero-order-hold staircase ([`SeriesStyle::Step`]), for PWM commands held over `Ts`.
    pub fn step(label: impl Into<String>, x: Vec<f64>, y: Vec<f64>) -> Self {
        Series::new(label, x, y, SeriesStyle::Step)
    }

    /// A series sampled every `ts_s` seconds from `t = 0`: `x[k] = k ts_s`.
    pub fn sampled(label: impl Into<String>, ts_s: f64, y: Vec<f64>, style: SeriesStyle) -> Self {
        let x = (0..y.len()).map(|k| k as f64 * ts_s).collect();
        Series::new(label, x, y, style)
    }
}

/// One pair of axes with its series. Axis labels should name the quantity, symbol and unit, e.g.
/// `"position y (mm)"`.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Panel {
    /// Label of the horizontal axis, with its unit.
    pub x_label: String,
    /// Label of the vertical axis, with its unit.
    pub y_label: String,
    /// The curves, drawn in order (later ones on top).
    pub series: Vec<Series>,
    /// Fixed y range `(lo, hi)`; `None` fits the data. The legend never changes it (without a free
    /// corner it goes below the plot; [`y_axes`] gives the range drawn); values outside it are clipped
    /// at the axes.
    pub y_range: Option<(f64, f64)>,
    /// The x values are log10 of the quantity (e.g. log10 of a frequency in Hz); tick labels show
    /// 10^x (`0.1`, `1`, `10`), so the axis reads as a logarithmic one.
    pub x_log10: bool,
}

impl Panel {
    /// An empty panel with the given axis labels.
    pub fn new(x_label: impl Into<String>, y_label: impl Into<String>) -> Self {
        Panel {
            x_label: x_label.into(),
            y_label: y_label.into(),
            ..Panel::default()
        }
    }

    /// Adds a series (builder style).
    pub fn series(mut self, series: Series) -> Self {
        self.series.push(series);
        self
    }

    /// Fixes the y range to `lo..hi` (builder style); ignored unless both are finite and `lo < hi`.
    pub fn y_range(mut self, lo: f64, hi: f64) -> Self {
        self.y_range = (lo.is_finite() && hi.is_finite() && lo < hi).then_some((lo, hi));
        self
    }

    /// Marks the x values as log10 of the quantity (builder style): tick labels show 10^x.
    pub fn x_log10(mut self) -> Self {
        self.x_log10 = true;
        self
    }
}

/// A titled figure: panels stacked vertically, sharing the figure's width, each getting an equal
/// share of its height.
#[derive(Debug, Clone, PartialEq)]
pub struct Figure {
    /// Title drawn above the panels (also the name used in error messages).
    pub title: String,
    /// The panels, top to bottom.
    pub panels: Vec<Panel>,
    /// Width in pixels (SVG user units), 1 to [`MAX_SIDE`].
    pub width: u32,
    /// Height in pixels (SVG user units), 1 to [`MAX_SIDE`].
    pub height: u32,
}

impl Figure {
    /// An empty figure of the default size ([`DEFAULT_WIDTH`] x [`DEFAULT_HEIGHT`]).
    pub fn new(title: impl Into<String>) -> Self {
        Figure {
            title: title.into(),
            panels: Vec::new(),
            width: DEFAULT_WIDTH,
            height: DEFAULT_HEIGHT,
        }
    }

    /// Adds a panel below the existing ones (builder style). While the figure still has its default
    /// width, each panel after the first adds [`DEFAULT_PANEL_HEIGHT`] to a default height.
    pub fn panel(mut self, panel: Panel) -> Self {
        let default_height =
            DEFAULT_HEIGHT + DEFAULT_PANEL_HEIGHT * (self.panels.len().saturating_sub(1) as u32);
        if !self.panels.is_empty() && self.width == DEFAULT_WIDTH && self.height == default_height {
            self.height = default_height + DEFAULT_PANEL_HEIGHT;
        }
        self.panels.push(panel);
        self
    }

    /// Sets the size in pixels (builder style).
    pub fn size(mut self, width: u32, height: u32) -> Self {
        self.width = width;
        self.height = height;
        self
    }
}

/// Renders `fig` as a standalone SVG document (text as `<text>` elements).
pub fn render_svg(fig: &Figure) -> Result<String, ReportError> {
    check(fig)?;
    let mut svg = String::new();
    {
        let root = SVGBackend::with_string(&mut svg, (fig.width, fig.height)).into_drawing_area();
        draw_figure(&root, fig)?;
        root.present()
            .map_err(|e| ReportError::render(&fig.title, e))?;
    }
    Ok(svg)
}

/// Renders `fig` as PNG-encoded bytes (8-bit RGB, `fig.width` x `fig.height` pixels).
pub fn render_png(fig: &Figure) -> Result<Vec<u8>, ReportError> {
    check(fig)?;
    let (w, h) = (fig.width, fig.height);
    let mut rgb = vec![0u8; w as usize * h as usize * 3];
    {
        let font = ab_glyph::FontRef::try_from_slice(DEJAVU_SANS).map_err(|e| {
            ReportError::render(
                &fig.title,
                format!("embedded font assets/DejaVuSans.ttf: {e}"),
            )
        })?;
        let inner = BitMapBackend::with_buffer(&mut rgb, (w, h));
        let root = glyph_fix::GlyphFix { inner, font }.into_drawing_area();
        draw_figure(&root, fig)?;
        root.present()
            .map_err(|e| ReportError::render(&fig.title, e))?;
    }
    encode_png(&fig.title, &rgb, w, h)
}

/// Writes `dir/stem.svg` and `dir/stem.png`, each atomically (the folder must exist).
pub fn save_figure(fig: &Figure, dir: &Path, stem: &str) -> Result<(), ReportError> {
    if stem.is_empty() || stem.contains(['/', '\\']) || stem == "." || stem == ".." {
        return Err(ReportError::invalid(
            &fig.title,
            format!("file stem {stem:?} must be a plain, non-empty file name without a folder"),
        ));
    }
    let svg = render_svg(fig)?;
    let png = render_png(fig)?;
    sysid_io::write_atomic(&dir.join(format!("{stem}.svg")), svg.as_bytes())?;
    sysid_io::write_atomic(&dir.join(format!("{stem}.png")), &png)?;
    Ok(())
}

/// Validates what the drawing code relies on: a usable size and `x`, `y` of equal lengths.
fn check(fig: &Figure) -> Result<(), ReportError> {
    if fig.width == 0 || fig.height == 0 || fig.width > MAX_SIDE || fig.height > MAX_SIDE {
        return Err(ReportError::invalid(
            &fig.title,
            format!(
                "size {} x {} px: width and height must be 1 to {MAX_SIDE}",
                fig.width, fig.height
            ),
        ));
    }
    for (p, panel) in fig.panels.iter().enumerate() {
        for (s, series) in panel.series.iter().enumerate() {
            if series.x.len() != series.y.len() {
                return Err(ReportError::invalid(
                    &fig.title,
                    format!(
                        "panel {}, series {} (\"{}\"): x has {} samples but y has {}; they must match",
                        p + 1,
                        s + 1,
                        series.label,
                        series.x.len(),
                        series.y.len()
                    ),
                ));
            }
        }
    }
    Ok(())
}

/// Registers the embedded font with plotters, once per process.
fn ensure_font(figure: &str) -> Result<(), ReportError> {
    static REGISTERED: OnceLock<bool> = OnceLock::new();
    let ok = *REGISTERED.get_or_init(|| {
        [FontStyle::Normal, FontStyle::Bold]
            .into_iter()
            .all(|style| register_font(FONT_FAMILY, style, DEJAVU_SANS).is_ok())
    });
    if ok {
        Ok(())
    } else {
        Err(ReportError::render(
            figure,
            "the embedded font assets/DejaVuSans.ttf could not be loaded",
        ))
    }
}

/// Font sizes in plotters' units (pixels, 1.24 x the em size) derived from the figure's width.
struct Fonts {
    title: f64,
    label: f64,
    tick: f64,
    legend: f64,
}

impl Fonts {
    fn for_width(width: u32) -> Self {
        let base = (f64::from(width) / 48.0).clamp(12.0, 28.0);
        Fonts {
            title: base * 1.3,
            label: base * 1.05,
            tick: base * 0.95,
            legend: base * 0.95,
        }
    }
}

/// Draws the whole figure on `root`.
fn draw_figure<DB: DrawingBackend>(
    root: &DrawingArea<DB, Shift>,
    fig: &Figure,
) -> Result<(), ReportError> {
    let fonts = Fonts::for_width(fig.width);
    let areas = panel_areas(root, fig, &fonts)?;
    for (panel, area) in fig.panels.iter().zip(areas.iter()) {
        draw_panel(area, panel, &fonts, &fig.title)?;
    }
    Ok(())
}

/// Fills `root` white, draws the title and splits the rest into one area per panel (none for a figure
/// without panels).
fn panel_areas<DB: DrawingBackend>(
    root: &DrawingArea<DB, Shift>,
    fig: &Figure,
    fonts: &Fonts,
) -> Result<Vec<DrawingArea<DB, Shift>>, ReportError> {
    ensure_font(&fig.title)?;
    let err = |e: DrawingAreaErrorKind<DB::ErrorType>| ReportError::render(&fig.title, e);
    root.fill(&WHITE).map_err(err)?;
    let body = if fig.title.trim().is_empty() {
        root.clone()
    } else {
        root.titled(&fig.title, (FONT_FAMILY, fonts.title))
            .map_err(err)?
    };
    if fig.panels.is_empty() {
        return Ok(Vec::new());
    }
    Ok(body.split_evenly((fig.panels.len(), 1)))
}

/// The finite `(x, y)` runs of a series: a non-finite `x` or `y` ends a run.
fn finite_runs(series: &Series) -> Vec<Vec<(f64, f64)>> {
    let mut runs = Vec::new();
    let mut run = Vec::new();
    for (&x, &y) in series.x.iter().zip(series.y.iter()) {
        if x.is_finite() && y.is_finite() {
            run.push((x, y));
        } else if !run.is_empty() {
            runs.push(std::mem::take(&mut run));
        }
    }
    if !run.is_empty() {
        runs.push(run);
    }
    runs
}

/// The zero-order-hold staircase through `run`: `(x_i, y_i) -> (x_{i+1}, y_i) -> (x_{i+1}, y_{i+1})`.
fn staircase(run: &[(f64, f64)]) -> Vec<(f64, f64)> {
    let mut out = Vec::with_capacity(run.len() * 2);
    for (i, &(x, y)) in run.iter().enumerate() {
        if i > 0 {
            out.push((x, run[i - 1].1));
        }
        out.push((x, y));
    }
    out
}

/// Axis range `[lo, hi]` of finite values, with `margin` (fraction of the span) added on both sides.
/// No value gives `0..1`; a constant (or nearly constant) value `v` gives `v ± max(|v|/10, 1)`-ish
/// padding. Returns `None` if the span overflows `f64`.
pub(crate) fn axis_range(values: impl Iterator<Item = f64>, margin: f64) -> Option<(f64, f64)> {
    let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
    for v in values.filter(|v| v.is_finite()) {
        lo = lo.min(v);
        hi = hi.max(v);
    }
    if lo > hi {
        return Some((0.0, 1.0));
    }
    let scale = lo.abs().max(hi.abs());
    let span = hi - lo;
    if !span.is_finite() {
        return None;
    }
    if span <= scale * 1e-9 {
        let mid = 0.5 * (lo + hi);
        let pad = if scale == 0.0 { 1.0 } else { 0.1 * scale };
        return Some((mid - pad, mid + pad));
    }
    let pad = span * margin;
    let (a, b) = (lo - pad, hi + pad);
    if a.is_finite() && b.is_finite() {
        Some((a, b))
    } else {
        Some((lo, hi))
    }
}

/// A tick label for value `v` on an axis spanning `span`: as many decimals as a tick step of about
/// `span / 10` needs (one more than its leading digit), trailing zeros trimmed; scientific notation
/// for spans below 1e-4 or values from 1e6 up.
pub(crate) fn tick_label(v: f64, span: f64) -> String {
    let span = if span.is_finite() && span > 0.0 {
        span
    } else {
        1.0
    };
    if span < 1e-4 || v.abs() >= 1e6 {
        let step = span / 10.0;
        let digits = ((v.abs().max(step) / step).log10().ceil().max(0.0) as usize).min(12);
        let s = format!("{:.*e}", digits, v);
        let (mantissa, exponent) = s.split_once('e').unwrap_or((&s, "0"));
        let mantissa = trim_zeros(mantissa);
        return if mantissa == "0" {
            "0".to_string()
        } else {
            format!("{mantissa}e{exponent}")
        };
    }
    let decimals = (1.0 - (span / 10.0).log10().floor()).clamp(0.0, 12.0) as usize;
    let s = trim_zeros(&format!("{:.*}", decimals, v));
    if s == "-0" {
        "0".to_string()
    } else {
        s
    }
}

/// `2.500` -> `2.5`, `3.000` -> `3`; integers are left alone.
fn trim_zeros(s: &str) -> String {
    if s.contains('.') {
        s.trim_end_matches('0').trim_end_matches('.').to_string()
    } else {
        s.to_string()
    }
}

/// Position of a series in its panel, turned into its colour and (for dashed series) dash pattern.
fn colour(index: usize) -> RGBColor {
    let (r, g, b) = PALETTE[index % PALETTE.len()];
    RGBColor(r, g, b)
}

/// Which corner of the plotting area the legend goes to: the one where the fewest data points (and
/// points interpolated along the segments between them) fall inside a box of the legend's estimated
/// size `(w_frac, h_frac)` of the plotting area. Ties prefer upper right, then upper left, lower
/// right, lower left. Also returns how many points fall under the chosen corner (0: the legend hides
/// nothing).
fn legend_corner(
    runs: &[Vec<(f64, f64)>],
    x_range: (f64, f64),
    y_range: (f64, f64),
    w_frac: f64,
    h_frac: f64,
) -> (SeriesLabelPosition, usize) {
    // (left?, top?) for each candidate, in order of preference.
    let corners = [(false, true), (true, true), (false, false), (true, false)];
    let mut counts = [0usize; 4];
    let norm = |v: f64, (lo, hi): (f64, f64)| (v - lo) / (hi - lo);
    let mut tally = |u: f64, v: f64| {
        for (c, &(left, top)) in corners.iter().enumerate() {
            let in_x = if left { u <= w_frac } else { u >= 1.0 - w_frac };
            let in_y = if top { v >= 1.0 - h_frac } else { v <= h_frac };
            if in_x && in_y {
                counts[c] += 1;
            }
        }
    };
    for run in runs {
        for (i, &(x, y)) in run.iter().enumerate() {
            let (u, v) = (norm(x, x_range), norm(y, y_range));
            tally(u, v);
            if let Some(&(x1, y1)) = run.get(i + 1) {
                let (u1, v1) = (norm(x1, x_range), norm(y1, y_range));
                for j in 1..8 {
                    let f = f64::from(j) / 8.0;
                    tally(u + f * (u1 - u), v + f * (v1 - v));
                }
            }
        }
    }
    let best = (0..4).min_by_key(|&c| counts[c]).unwrap_or(0);
    let position = match corners[best] {
        (false, true) => SeriesLabelPosition::UpperRight,
        (true, true) => SeriesLabelPosition::UpperLeft,
        (false, false) => SeriesLabelPosition::LowerRight,
        (true, false) => SeriesLabelPosition::LowerLeft,
    };
    (position, counts[best])
}

/// Where a panel's parts go, computed from its series and the pixel size of its area: one layout for
/// drawing ([`draw_panel`]) and for telling a caller which range was drawn ([`y_axes`]).
struct PanelLayout {
    /// The finite runs of each series, their y clamped to the drawn `y_range` when the panel has a fixed
    /// range (clipped curves sit on the frame).
    runs: Vec<Vec<Vec<(f64, f64)>>>,
    /// The drawn x range.
    x_range: (f64, f64),
    /// The drawn y range: the fixed or fitted range.
    y_range: (f64, f64),
    /// Where the legend goes; `None` when no series has a label.
    legend: Option<LegendPlace>,
    /// Gap between the legend and the plotting area's edge, px.
    legend_margin: u32,
    /// Width of the y tick-label area, px.
    y_label_area: u32,
    /// Height of the x tick-label area, px.
    x_label_area: u32,
}

/// Where a panel's legend goes.
#[derive(Debug, Clone)]
enum LegendPlace {
    /// Inside the plotting area, in a corner no data cross.
    Corner(SeriesLabelPosition),
    /// Below the plot, outside the axes: a band of `height` px at the panel's bottom holding the
    /// entries in `columns` columns of `column_w` px, `row_h` px per row.
    Below {
        height: u32,
        columns: usize,
        column_w: u32,
        row_h: u32,
    },
}

/// Lays out one panel in an area of `area_w` x `area_h` pixels.
fn layout_panel(
    panel: &Panel,
    (area_w, area_h): (u32, u32),
    fonts: &Fonts,
    figure: &str,
) -> Result<PanelLayout, ReportError> {
    let mut runs: Vec<Vec<Vec<(f64, f64)>>> = panel.series.iter().map(finite_runs).collect();
    // A fixed range clips at the axes drawn: the legend never moves them.
    if let Some((lo, hi)) = panel.y_range {
        for p in runs.iter_mut().flatten().flatten() {
            p.1 = p.1.clamp(lo, hi);
        }
    }
    let all = || runs.iter().flatten().flatten();
    let overflow = || {
        ReportError::invalid(
            figure,
            format!(
                "panel \"{}\": values too large to plot (the axis span overflows f64)",
                panel.y_label
            ),
        )
    };
    let x_range = axis_range(all().map(|p| p.0), 0.0).ok_or_else(overflow)?;
    let y_range = match panel.y_range {
        Some(r) => r,
        None => axis_range(all().map(|p| p.1), 0.05).ok_or_else(overflow)?,
    };

    let tick_px = fonts.tick / 1.24;
    let y_label_area = (tick_px * 5.5 + fonts.label) as u32;
    let x_label_area = (tick_px * 1.6 + fonts.label * 1.3) as u32;

    // Legend placement: a corner no data cross; when every corner has data under the legend, below
    // the plot, outside the axes (a curve never runs under it, whatever the range).
    let labelled: Vec<&Series> = panel
        .series
        .iter()
        .filter(|s| !s.label.is_empty())
        .collect();
    let legend_margin = (fonts.tick * 0.5) as u32;
    let legend = if labelled.is_empty() {
        None
    } else {
        let plot_w = f64::from(area_w.saturating_sub(y_label_area).max(1));
        let plot_h = f64::from(area_h.saturating_sub(x_label_area).max(1));
        let legend_px = fonts.legend / 1.24;
        let chars = labelled
            .iter()
            .map(|s| s.label.chars().count())
            .max()
            .unwrap_or(0) as f64;
        let rows = labelled.len() as f64;
        let margin = f64::from(legend_margin);
        let entry_w = (chars * 0.62 + 4.5) * legend_px;
        let w_frac = ((entry_w + margin) / plot_w).min(0.9);
        let h_frac = (((rows * 1.55 + 0.8) * legend_px + margin) / plot_h).min(0.6);
        let flat: Vec<Vec<(f64, f64)>> = runs.iter().flatten().cloned().collect();
        let (position, hidden) = legend_corner(&flat, x_range, y_range, w_frac, h_frac);
        if hidden == 0 {
            Some(LegendPlace::Corner(position))
        } else {
            let columns = ((plot_w / (entry_w + margin)).floor() as usize).clamp(1, labelled.len());
            let rows = labelled.len().div_ceil(columns);
            let row_h = (1.55 * legend_px).ceil() as u32;
            Some(LegendPlace::Below {
                height: row_h * rows as u32 + 2 * legend_margin + (0.8 * legend_px) as u32,
                columns,
                column_w: (entry_w + margin) as u32,
                row_h,
            })
        }
    };
    Ok(PanelLayout {
        runs,
        x_range,
        y_range,
        legend,
        legend_margin,
        y_label_area,
        x_label_area,
    })
}

/// The y range each panel of `fig` is drawn with, top to bottom, as [`render_svg`] and [`render_png`]
/// lay them out: the panel's fixed range ([`Panel::y_range`]) or the range fitted to its data (the
/// legend never changes it). Values outside it are clipped at these edges, so a caption can state the
/// range a reader sees.
pub fn y_axes(fig: &Figure) -> Result<Vec<(f64, f64)>, ReportError> {
    check(fig)?;
    let fonts = Fonts::for_width(fig.width);
    let mut svg = String::new();
    let root = SVGBackend::with_string(&mut svg, (fig.width, fig.height)).into_drawing_area();
    let areas = panel_areas(&root, fig, &fonts)?;
    fig.panels
        .iter()
        .zip(areas.iter())
        .map(|(panel, area)| {
            layout_panel(panel, area.dim_in_pixel(), &fonts, &fig.title).map(|l| l.y_range)
        })
        .collect()
}

/// Draws one panel (axes, grid, series, legend) into `area`.
fn draw_panel<DB: DrawingBackend>(
    area: &DrawingArea<DB, Shift>,
    panel: &Panel,
    fonts: &Fonts,
    figure: &str,
) -> Result<(), ReportError> {
    let err = |e: DrawingAreaErrorKind<DB::ErrorType>| ReportError::render(figure, e);
    let (area_w, area_h) = area.dim_in_pixel();
    let PanelLayout {
        runs,
        x_range,
        y_range,
        legend,
        legend_margin,
        y_label_area,
        x_label_area,
    } = layout_panel(panel, (area_w, area_h), fonts, figure)?;
    // A legend below the plot takes a band at the panel's bottom, outside the axes.
    let (plot_area, legend_band) = match legend {
        Some(LegendPlace::Below { height, .. }) if height < area_h => {
            let (a, b) = area.split_vertically(area_h - height);
            (a, Some(b))
        }
        _ => (area.clone(), None),
    };
    let y_span = y_range.1 - y_range.0;
    let x_span = x_range.1 - x_range.0;
    let x_log10 = panel.x_log10;
    let x_fmt = move |v: &f64| {
        if x_log10 {
            crate::format::sig(10f64.powf(*v), 2)
        } else {
            tick_label(*v, x_span)
        }
    };
    let y_fmt = move |v: &f64| tick_label(*v, y_span);
    let mut chart = ChartBuilder::on(&plot_area)
        .margin_top((fonts.tick * 0.6) as u32)
        .margin_bottom((fonts.tick * 0.3) as u32)
        .margin_left((fonts.tick * 0.4) as u32)
        .margin_right((fonts.tick * 1.6) as u32)
        .x_label_area_size(x_label_area)
        .y_label_area_size(y_label_area)
        .build_cartesian_2d(x_range.0..x_range.1, y_range.0..y_range.1)
        .map_err(err)?;
    chart
        .configure_mesh()
        .x_desc(panel.x_label.as_str())
        .y_desc(panel.y_label.as_str())
        .axis_desc_style((FONT_FAMILY, fonts.label))
        .label_style((FONT_FAMILY, fonts.tick))
        .bold_line_style(RGBColor(205, 205, 205).stroke_width(1))
        .light_line_style(RGBColor(238, 238, 238).stroke_width(1))
        .max_light_lines(2)
        .axis_style(BLACK.stroke_width(1))
        .x_labels(8)
        .y_labels(8)
        .x_label_formatter(&x_fmt)
        .y_label_formatter(&y_fmt)
        .draw()
        .map_err(err)?;

    let stroke = ((f64::from(area_w.min(area_h * 3)) / 480.0).round() as u32).clamp(1, 4);
    let mut dashed_seen = 0usize;
    // The labelled series' legend entries, for a legend drawn below the plot.
    let mut entries: Vec<(&str, Glyph)> = Vec::new();
    for (index, (series, runs)) in panel.series.iter().zip(runs.iter()).enumerate() {
        let color = match series.colour {
            Some((r, g, b)) => RGBColor(r, g, b),
            None => colour(index),
        };
        let style = color.stroke_width(stroke);
        let (dash, gap) = DASHES[dashed_seen % DASHES.len()];
        if series.style == SeriesStyle::Dashed {
            dashed_seen += 1;
        }
        let (dash, gap) = (dash * stroke.max(2) / 2, gap * stroke.max(2) / 2);
        let marker = stroke + 2;
        // Each run is drawn as its own element so that lines break at non-finite samples; only the
        // first carries the legend entry. A series with no finite sample still gets its entry.
        let mut first = true;
        let empty = vec![Vec::new()];
        let runs: &[Vec<(f64, f64)>] = if runs.is_empty() { &empty } else { runs };
        for run in runs {
            let anno = match series.style {
                SeriesStyle::Line => chart.draw_series(LineSeries::new(run.iter().copied(), style)),
                SeriesStyle::Step => chart.draw_series(LineSeries::new(staircase(run), style)),
                SeriesStyle::Dashed => {
                    chart.draw_series(DashedLineSeries::new(run.iter().copied(), dash, gap, style))
                }
                SeriesStyle::Points => {
                    chart.draw_series(run.iter().map(|&p| Circle::new(p, marker, color.filled())))
                }
            }
            .map_err(err)?;
            if first && !series.label.is_empty() {
                let glyph = Glyph {
                    kind: series.style,
                    style,
                    color,
                    dash,
                    gap,
                    marker,
                };
                entries.push((series.label.as_str(), glyph));
                anno.label(series.label.as_str())
                    .legend(move |at| glyph.element::<DB>(at));
            }
            first = false;
        }
    }

    match (legend, legend_band) {
        (Some(LegendPlace::Corner(position)), _) => {
            chart
                .configure_series_labels()
                .position(position)
                .margin(legend_margin)
                .label_font((FONT_FAMILY, fonts.legend))
                .background_style(WHITE.mix(0.85))
                .border_style(LEGEND_BORDER)
                .draw()
                .map_err(err)?;
        }
        (
            Some(LegendPlace::Below {
                columns,
                column_w,
                row_h,
                ..
            }),
            Some(band),
        ) => {
            // The box starts at the plotting area's left edge (after the y labels), below the x
            // axis's labels; each entry is its glyph (24 px) then its label, as in a corner legend.
            let m = legend_margin as i32;
            let left = y_label_area as i32 + (fonts.tick * 0.4) as i32;
            let rows = entries.len().div_ceil(columns.max(1));
            let (w, h) = (
                (column_w as usize * columns.min(entries.len())) as i32 + m,
                (row_h as usize * rows) as i32 + m,
            );
            band.draw(&Rectangle::new(
                [(left, m), (left + w, m + h)],
                WHITE.filled(),
            ))
            .map_err(err)?;
            band.draw(&Rectangle::new(
                [(left, m), (left + w, m + h)],
                LEGEND_BORDER.stroke_width(1),
            ))
            .map_err(err)?;
            let font = (FONT_FAMILY, fonts.legend).into_font();
            let text_h = (fonts.legend / 1.24) as i32;
            for (i, (label, glyph)) in entries.iter().enumerate() {
                let (row, col) = ((i / columns) as i32, (i % columns) as i32);
                let x = left + m + col * column_w as i32;
                let y = m + m / 2 + row * row_h as i32 + row_h as i32 / 2;
                band.draw(&glyph.element::<DB>((x, y))).map_err(err)?;
                band.draw(&Text::new(
                    (*label).to_string(),
                    (x + 32, y - text_h / 2 - 1),
                    font.clone(),
                ))
                .map_err(err)?;
            }
        }
        _ => {}
    }
    Ok(())
}

/// The legend box's border colour.
const LEGEND_BORDER: RGBColor = RGBColor(120, 120, 120);

/// How a series is drawn in its legend entry: a 24 px sample of its line, step or marker.
#[derive(Debug, Clone, Copy)]
struct Glyph {
    kind: SeriesStyle,
    style: ShapeStyle,
    color: RGBColor,
    dash: u32,
    gap: u32,
    marker: u32,
}

impl Glyph {
    /// The entry's sample with its left end at `(x, y)` (pixels; y the entry's centre line).
    fn element<DB: DrawingBackend>(
        &self,
        (x, y): (i32, i32),
    ) -> DynElement<'static, DB, (i32, i32)> {
        let style = self.style;
        match self.kind {
            SeriesStyle::Line => PathElement::new(vec![(x, y), (x + 24, y)], style).into_dyn(),
            SeriesStyle::Step => PathElement::new(
                vec![
                    (x, y + 5),
                    (x + 12, y + 5),
                    (x + 12, y - 5),
                    (x + 24, y - 5),
                ],
                style,
            )
            .into_dyn(),
            SeriesStyle::Dashed => DashedPathElement::new(
                vec![(x, y), (x + 24, y)],
                self.dash.min(10),
                self.gap.min(5),
                style,
            )
            .into_dyn(),
            SeriesStyle::Points => {
                Circle::new((x + 12, y), self.marker, self.color.filled()).into_dyn()
            }
        }
    }
}

/// Encodes an 8-bit RGB buffer as PNG.
fn encode_png(figure: &str, rgb: &[u8], width: u32, height: u32) -> Result<Vec<u8>, ReportError> {
    let fail = |e: png::EncodingError| ReportError::Encode {
        figure: figure.to_string(),
        message: e.to_string(),
    };
    let mut out = Vec::new();
    {
        let mut encoder = png::Encoder::new(&mut out, width, height);
        encoder.set_color(png::ColorType::Rgb);
        encoder.set_depth(png::BitDepth::Eight);
        // Default rather than Best: for a 960 x 800 two-panel figure of 2000 samples (release build)
        // Default took 11 ms for 34 kB, Best 57 ms for 35 kB.
        encoder.set_compression(png::Compression::Default);
        let mut writer = encoder.write_header().map_err(fail)?;
        writer.write_image_data(rgb).map_err(fail)?;
        writer.finish().map_err(fail)?;
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    // The hold keeps y_i until x_{i+1}: two points per step after the first.
    #[test]
    fn staircase_holds_each_value_until_the_next_sample() {
        let s = staircase(&[(0.0, 1.0), (1.0, 3.0), (2.0, -1.0)]);
        assert_eq!(
            s,
            vec![(0.0, 1.0), (1.0, 1.0), (1.0, 3.0), (2.0, 3.0), (2.0, -1.0)]
        );
    }

    // NaN or inf in x or y splits the series into the finite runs around it.
    #[test]
    fn finite_runs_split_at_non_finite_samples() {
        let s = Series::line(
            "s",
            vec![0.0, 1.0, 2.0, 3.0, f64::INFINITY, 5.0],
            vec![1.0, f64::NAN, 2.0, 3.0, 4.0, 5.0],
        );
        assert_eq!(
            finite_runs(&s),
            vec![
                vec![(0.0, 1.0)],
                vec![(2.0, 2.0), (3.0, 3.0)],
                vec![(5.0, 5.0)]
            ]
        );
    }

    // Range of {-1, 3} with 5 % margin: span 4, pad 0.2 -> [-1.2, 3.2]; NaN ignored.
    #[test]
    fn axis_range_pads_the_span_and_ignores_nan() {
        let (lo, hi) = axis_range([-1.0, f64::NAN, 3.0].into_iter(), 0.05).unwrap();
        assert!(
            (lo + 1.2).abs() < 1e-12 && (hi - 3.2).abs() < 1e-12,
            "{lo} {hi}"
        );
    }

    // A constant 50 has zero span: padded by 10 % of |50| = 5 on each side; 0 is padded by 1.
    #[test]
    fn axis_range_of_a_constant_is_padded() {
        assert_eq!(
            axis_range([50.0, 50.0].into_iter(), 0.05),
            Some((45.0, 55.0))
        );
        assert_eq!(axis_range([0.0].into_iter(), 0.05), Some((-1.0, 1.0)));
        assert_eq!(axis_range(std::iter::empty(), 0.05), Some((0.0, 1.0)));
    }

    // max - min of ±1e308 overflows to inf: no range can be drawn.
    #[test]
    fn axis_range_reports_an_overflowing_span() {
        assert_eq!(axis_range([-1e308, 1e308].into_iter(), 0.05), None);
    }

    // Data along the top edge leaves the lower corners free; the lower right is preferred on a tie.
    #[test]
    fn legend_avoids_the_corner_the_data_crosses() {
        let run: Vec<(f64, f64)> = (0..=100).map(|i| (f64::from(i), 10.0)).collect();
        let (pos, hidden) = legend_corner(&[run], (0.0, 100.0), (0.0, 10.0), 0.3, 0.2);
        assert!(matches!(pos, SeriesLabelPosition::LowerRight) && hidden == 0);
        // A rising line from lower left to upper right leaves the upper left free.
        let run: Vec<(f64, f64)> = (0..=100).map(|i| (f64::from(i), f64::from(i))).collect();
        let (pos, hidden) = legend_corner(&[run], (0.0, 100.0), (0.0, 100.0), 0.3, 0.2);
        assert!(matches!(pos, SeriesLabelPosition::UpperLeft) && hidden == 0);
        // A full-width line through the middle (v = 0.5) misses all four 0.3 x 0.2 corner boxes, but
        // lines along the top and the bottom fill them all.
        let top: Vec<(f64, f64)> = (0..=100).map(|i| (f64::from(i), 1.0)).collect();
        let bottom: Vec<(f64, f64)> = (0..=100).map(|i| (f64::from(i), 0.0)).collect();
        let (_, hidden) = legend_corner(&[top, bottom], (0.0, 100.0), (0.0, 1.0), 0.3, 0.2);
        assert!(hidden > 0);
    }

    // Ticks 0, 2.5, 5 on a span of 20: one decimal at most, trailing zeros trimmed.
    #[test]
    fn tick_labels_are_short_and_exact() {
        assert_eq!(tick_label(200.0, 510.0), "200");
        assert_eq!(tick_label(2.5, 20.0), "2.5");
        assert_eq!(tick_label(5.0, 20.0), "5");
        assert_eq!(tick_label(-0.0, 20.0), "0");
        assert_eq!(tick_label(0.1 + 0.2, 1.0), "0.3");
        assert_eq!(tick_label(7.5e-4, 1e-3), "0.00075");
        assert_eq!(tick_label(1.5e-7, 1e-6), "1.5e-7");
        assert_eq!(tick_label(2.0e6, 4.0e6), "2e6");
    }
}

/// Text rasterisation for the PNG backend.
///
/// plotters 0.3.7 (`style/font/ab_glyph.rs`) places each glyph at the pen position without its left
/// side bearing and truncates the pen position per glyph, so PNG text comes out with uneven gaps
/// ("set-poin t r"). [`GlyphFix`] wraps the bitmap backend, delegates every drawing primitive and
/// draws text itself: glyphs positioned by ab_glyph at the fractional pen position (kerning
/// included), the same advance widths as plotters' layout estimate (so label areas and legend boxes
/// still fit), and the baseline at 0.76 em below the top of the text box, as the SVG backend does
/// (`dy="0.76em"`), so PNG and SVG figures look alike.
mod glyph_fix {
    use ab_glyph::{point, Font, FontRef, ScaleFont};
    use plotters::backend::BitMapBackend;
    use plotters_backend::text_anchor::{HPos, VPos};
    use plotters_backend::{
        BackendColor, BackendCoord, BackendStyle, BackendTextStyle, DrawingBackend,
        DrawingErrorKind,
    };

    /// A [`BitMapBackend`] whose text is drawn with correct glyph placement.
    pub(super) struct GlyphFix<'a> {
        pub(super) inner: BitMapBackend<'a>,
        pub(super) font: FontRef<'static>,
    }

    type Error<'a> = DrawingErrorKind<<BitMapBackend<'a> as DrawingBackend>::ErrorType>;

    impl<'a> DrawingBackend for GlyphFix<'a> {
        type ErrorType = <BitMapBackend<'a> as DrawingBackend>::ErrorType;

        fn get_size(&self) -> (u32, u32) {
            self.inner.get_size()
        }
        fn ensure_prepared(&mut self) -> Result<(), Error<'a>> {
            self.inner.ensure_prepared()
        }
        fn present(&mut self) -> Result<(), Error<'a>> {
            self.inner.present()
        }
        fn draw_pixel(
            &mut self,
            point: BackendCoord,
            color: BackendColor,
        ) -> Result<(), Error<'a>> {
            self.inner.draw_pixel(point, color)
        }
        fn draw_line<S: BackendStyle>(
            &mut self,
            from: BackendCoord,
            to: BackendCoord,
            style: &S,
        ) -> Result<(), Error<'a>> {
            self.inner.draw_line(from, to, style)
        }
        fn draw_rect<S: BackendStyle>(
            &mut self,
            upper_left: BackendCoord,
            bottom_right: BackendCoord,
            style: &S,
            fill: bool,
        ) -> Result<(), Error<'a>> {
            self.inner.draw_rect(upper_left, bottom_right, style, fill)
        }
        fn draw_path<S: BackendStyle, I: IntoIterator<Item = BackendCoord>>(
            &mut self,
            path: I,
            style: &S,
        ) -> Result<(), Error<'a>> {
            self.inner.draw_path(path, style)
        }
        fn draw_circle<S: BackendStyle>(
            &mut self,
            center: BackendCoord,
            radius: u32,
            style: &S,
            fill: bool,
        ) -> Result<(), Error<'a>> {
            self.inner.draw_circle(center, radius, style, fill)
        }
        fn fill_polygon<S: BackendStyle, I: IntoIterator<Item = BackendCoord>>(
            &mut self,
            vert: I,
            style: &S,
        ) -> Result<(), Error<'a>> {
            self.inner.fill_polygon(vert, style)
        }
        fn blit_bitmap(
            &mut self,
            pos: BackendCoord,
            size: (u32, u32),
            src: &[u8],
        ) -> Result<(), Error<'a>> {
            self.inner.blit_bitmap(pos, size, src)
        }

        fn draw_text<TStyle: BackendTextStyle>(
            &mut self,
            text: &str,
            style: &TStyle,
            pos: BackendCoord,
        ) -> Result<(), Error<'a>> {
            let color = style.color();
            if color.alpha == 0.0 {
                return Ok(());
            }
            let size = style.size() as f32;
            let scaled = self.font.as_scaled(size);
            // The text box as plotters estimates it: advances plus kerning wide, size/1.24 tall.
            let mut width = 0f32;
            let mut prev = None;
            for c in text.chars() {
                let id = scaled.glyph_id(c);
                if let Some(p) = prev {
                    width += scaled.kern(p, id);
                }
                width += scaled.h_advance(id);
                prev = Some(id);
            }
            let height = size / 1.24;
            let dx = match style.anchor().h_pos {
                HPos::Left => 0.0,
                HPos::Right => -width,
                HPos::Center => -width / 2.0,
            };
            let dy = match style.anchor().v_pos {
                VPos::Top => 0.0,
                VPos::Center => -height / 2.0,
                VPos::Bottom => -height,
            };
            let baseline = 0.76 * height;
            let trans = style.transform();
            let mut caret = 0f32;
            let mut prev = None;
            let mut pixels = Vec::new();
            for c in text.chars() {
                let id = scaled.glyph_id(c);
                if let Some(p) = prev {
                    caret += scaled.kern(p, id);
                }
                prev = Some(id);
                let glyph = id.with_scale_and_position(size, point(caret + dx, baseline + dy));
                if let Some(outline) = self.font.outline_glyph(glyph) {
                    let b = outline.px_bounds();
                    outline.draw(|gx, gy, coverage| {
                        let x = b.min.x as i32 + gx as i32;
                        let y = b.min.y as i32 + gy as i32;
                        pixels.push((trans.transform(x, y), coverage));
                    });
                }
                caret += scaled.h_advance(id);
            }
            for ((x, y), coverage) in pixels {
                if coverage > 0.0 {
                    let c = BackendColor {
                        alpha: color.alpha * f64::from(coverage.min(1.0)),
                        rgb: color.rgb,
                    };
                    self.inner.draw_pixel((pos.0 + x, pos.1 + y), c)?;
                }
            }
            Ok(())
        }
    }
}
