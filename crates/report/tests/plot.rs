//! Figures: SVG structure, PNG encoding and size, robustness to NaN / empty / constant data.

#![allow(clippy::unwrap_used, clippy::expect_used, missing_docs)] // tests, benches and examples may panic

mod common;

use common::{check_well_formed, decode_rgb, png_size, PNG_SIGNATURE};
use report::plot::{
    render_png, render_svg, save_figure, y_axes, Figure, Panel, Series, SeriesStyle, PALETTE,
};
use report::ReportError;

/// Two panels like the paper's Fig. 2: a held PWM input over a position output, plus a dashed
/// reference and markers, with labels that need escaping.
fn two_panel_figure() -> Figure {
    let t: Vec<f64> = (0..300).map(|k| k as f64 * 0.01).collect();
    let u: Vec<f64> = t
        .iter()
        .map(|&t| {
            if (t * 2.0) as i64 % 2 == 0 {
                255.0
            } else {
                -255.0
            }
        })
        .collect();
    let y: Vec<f64> = t.iter().map(|&t| 20.0 + 10.0 * (3.0 * t).sin()).collect();
    let r: Vec<f64> = t.iter().map(|_| 25.0).collect();
    Figure::new("Data <input & output>")
        .size(800, 600)
        .panel(
            Panel::new("time t (s)", "input u (PWM counts)").series(Series::step(
                "u(k) held",
                t.clone(),
                u,
            )),
        )
        .panel(
            Panel::new("time t (s)", "position y (mm)")
                .series(Series::line("measured y", t.clone(), y.clone()))
                .series(Series::dashed("set-point r", t.clone(), r))
                .series(Series::points(
                    "samples \"ŷ\"",
                    t[..30].to_vec(),
                    y[..30].to_vec(),
                )),
        )
}

// The SVG is one well-formed <svg> element carrying the (escaped) title and every legend label.
#[test]
fn svg_is_well_formed_and_names_title_and_every_series() {
    let svg = render_svg(&two_panel_figure()).unwrap();
    let names = check_well_formed(&svg).unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(names.first().map(String::as_str), Some("svg"));
    assert!(
        svg.contains("Data &lt;input &amp; output&gt;"),
        "title missing"
    );
    for label in [
        "u(k) held",
        "measured y",
        "set-point r",
        "samples &quot;ŷ&quot;",
        "time t (s)",
        "position y (mm)",
    ] {
        assert!(svg.contains(label), "label {label} missing");
    }
    assert!(svg.contains("width=\"800\"") && svg.contains("height=\"600\""));
}

// A PNG begins with the 8-byte signature, its IHDR gives the requested size, and it decodes.
#[test]
fn png_has_signature_and_requested_size() {
    let fig = two_panel_figure();
    let png = render_png(&fig).unwrap();
    assert_eq!(png[..8], PNG_SIGNATURE);
    assert_eq!(png_size(&png).unwrap(), (800, 600));
    let (w, h, rgb) = decode_rgb(&png);
    assert_eq!((w, h), (800, 600));
    assert_eq!(rgb.len(), 800 * 600 * 3);
    // Background is white: the top-left pixel lies in the margin.
    assert_eq!(&rgb[..3], &[255, 255, 255]);
}

// The title is drawn with the embedded font: dark pixels appear in the title band (top 6 %) of an
// otherwise empty figure, which would be blank if no glyph were rasterised.
#[test]
fn png_title_text_is_rasterised_without_system_fonts() {
    let fig = Figure::new("Title only").size(600, 400);
    let (w, _, rgb) = decode_rgb(&render_png(&fig).unwrap());
    let band = &rgb[..(w as usize * 24 * 3)];
    let dark = band
        .chunks(3)
        .filter(|p| p.iter().all(|&c| c < 100))
        .count();
    assert!(dark > 50, "only {dark} dark pixels in the title band");
    let below = &rgb[(w as usize * 60 * 3)..];
    assert!(
        below.chunks(3).all(|p| p == [255, 255, 255]),
        "no panel, so nothing below the title"
    );
}

// Series take the palette colours in order: the second series of a panel is drawn in PALETTE[1].
#[test]
fn series_colours_follow_the_palette() {
    let x: Vec<f64> = (0..100).map(f64::from).collect();
    let fig = Figure::new("").size(400, 300).panel(
        Panel::new("x", "y")
            .series(Series::line("a", x.clone(), x.clone()))
            .series(Series::line(
                "b",
                x.clone(),
                x.iter().map(|v| 100.0 - v).collect(),
            )),
    );
    let (_, _, rgb) = decode_rgb(&render_png(&fig).unwrap());
    let (r, g, b) = PALETTE[1];
    let close = |p: &[u8]| {
        (i32::from(p[0]) - i32::from(r)).abs() < 8
            && (i32::from(p[1]) - i32::from(g)).abs() < 8
            && (i32::from(p[2]) - i32::from(b)).abs() < 8
    };
    assert!(
        rgb.chunks(3).filter(|p| close(p)).count() > 100,
        "second series colour not found"
    );
}

// NaN, inf, empty, constant and all-NaN series, an empty panel and a figure with no panel all render.
#[test]
fn degenerate_data_renders_without_panic() {
    let nan = f64::NAN;
    let fig = Figure::new("degenerate")
        .panel(
            Panel::new("t (s)", "y (mm)")
                .series(Series::line(
                    "gappy",
                    vec![0.0, 1.0, 2.0, 3.0, 4.0],
                    vec![1.0, nan, 3.0, f64::INFINITY, 2.0],
                ))
                .series(Series::step("empty", vec![], vec![]))
                .series(Series::dashed("all NaN", vec![nan, nan], vec![nan, nan]))
                .series(Series::points("single", vec![2.0], vec![2.5])),
        )
        .panel(Panel::new("t (s)", "constant").series(Series::line(
            "c",
            vec![0.0, 1.0],
            vec![50.0, 50.0],
        )))
        .panel(Panel::new("t (s)", "zero").series(Series::step(
            "z",
            vec![3.0, 3.0],
            vec![0.0, 0.0],
        )))
        .panel(Panel::new("nothing", "at all"));
    let svg = render_svg(&fig).unwrap();
    check_well_formed(&svg).unwrap();
    assert!(
        svg.contains("all NaN") && svg.contains("empty"),
        "legend keeps series without data"
    );
    assert_eq!(
        png_size(&render_png(&fig).unwrap()).unwrap(),
        (fig.width, fig.height)
    );
    let bare = Figure::new("no panels");
    assert!(render_svg(&bare).is_ok() && render_png(&bare).is_ok());
    let blank =
        Figure::new("").panel(Panel::new("", "").series(Series::line("", vec![nan], vec![1.0])));
    assert!(render_png(&blank).is_ok());
}

// Values near ±f64::MAX make the axis span overflow: an error naming the panel, not a panic.
#[test]
fn overflowing_range_is_an_error() {
    let fig = Figure::new("huge").panel(Panel::new("t", "y (mm)").series(Series::line(
        "h",
        vec![0.0, 1.0],
        vec![-1e308, 1e308],
    )));
    let e = render_svg(&fig).unwrap_err();
    assert!(
        matches!(e, ReportError::InvalidFigure { .. }) && e.to_string().contains("y (mm)"),
        "{e}"
    );
}

// x and y of different lengths cannot be paired: the error names the panel, series and lengths.
#[test]
fn mismatched_lengths_are_reported() {
    let fig = Figure::new("bad").panel(Panel::new("t", "y").series(Series::new(
        "y meas",
        vec![0.0, 1.0, 2.0],
        vec![1.0],
        SeriesStyle::Line,
    )));
    let msg = render_png(&fig).unwrap_err().to_string();
    assert!(
        msg.contains("panel 1, series 1")
            && msg.contains("y meas")
            && msg.contains('3')
            && msg.contains('1'),
        "{msg}"
    );
    assert!(!render_svg(&fig).unwrap_err().is_numerical());
}

// A zero-sized or oversized canvas is rejected before any allocation.
#[test]
fn zero_or_huge_size_is_rejected() {
    for (w, h) in [(0, 100), (100, 0), (100_000, 100)] {
        let fig = Figure::new("size").size(w, h);
        assert!(
            matches!(render_png(&fig), Err(ReportError::InvalidFigure { .. })),
            "{w}x{h}"
        );
        assert!(render_svg(&fig).is_err());
    }
}

// Each extra panel of a default-sized figure adds DEFAULT_PANEL_HEIGHT; an explicit size is kept.
#[test]
fn default_height_grows_with_panels() {
    use report::plot::{DEFAULT_HEIGHT, DEFAULT_PANEL_HEIGHT};
    let p = || Panel::new("x", "y");
    assert_eq!(Figure::new("a").panel(p()).height, DEFAULT_HEIGHT);
    assert_eq!(
        Figure::new("a").panel(p()).panel(p()).panel(p()).height,
        DEFAULT_HEIGHT + 2 * DEFAULT_PANEL_HEIGHT
    );
    assert_eq!(
        Figure::new("a").size(500, 300).panel(p()).panel(p()).height,
        300
    );
}

// save_figure writes stem.svg and stem.png (no temporary file left) and refuses a stem with a folder.
#[test]
fn save_figure_writes_both_formats() {
    let dir = tempfile::tempdir().unwrap();
    let fig = two_panel_figure();
    save_figure(&fig, dir.path(), "fig2_data").unwrap();
    let svg = std::fs::read_to_string(dir.path().join("fig2_data.svg")).unwrap();
    assert_eq!(svg, render_svg(&fig).unwrap());
    let png = std::fs::read(dir.path().join("fig2_data.png")).unwrap();
    assert_eq!(png_size(&png).unwrap(), (800, 600));
    let mut names: Vec<String> = std::fs::read_dir(dir.path())
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    names.sort();
    assert_eq!(names, ["fig2_data.png", "fig2_data.svg"]);
    for stem in ["", "a/b", ".."] {
        assert!(save_figure(&fig, dir.path(), stem).is_err(), "{stem:?}");
    }
    // A missing folder is an I/O error naming the path.
    let missing = dir.path().join("no_such_dir");
    let e = save_figure(&fig, &missing, "x").unwrap_err();
    assert!(e.to_string().contains("no_such_dir"), "{e}");
}

// A series' own colour overrides the palette colour of its position; without one the palette applies.
#[test]
fn a_series_colour_overrides_its_position_in_the_palette() {
    let x = vec![0.0, 1.0, 2.0];
    let fig = Figure::new("c").panel(
        Panel::new("x", "y")
            .series(Series::line("first", x.clone(), vec![0.0, 1.0, 0.0]).colour((204, 121, 167)))
            .series(Series::line("second", x, vec![1.0, 0.0, 1.0])),
    );
    let svg = render_svg(&fig).unwrap();
    // Position 0 would be black; it is reddish purple. Position 1 keeps vermillion.
    assert!(svg.contains("stroke=\"#CC79A7\""));
    assert!(svg.contains(&format!(
        "stroke=\"#{:02X}{:02X}{:02X}\"",
        PALETTE[1].0, PALETTE[1].1, PALETTE[1].2
    )));
    assert!(!svg.contains("stroke=\"#000000\" stroke-width=\"2\""));
}

// A fixed y range is used as given (tick labels inside it only) and values beyond it are clipped
// to the axes instead of leaving the panel.
#[test]
fn a_fixed_y_range_clips_the_data() {
    let x: Vec<f64> = (0..50).map(f64::from).collect();
    let mut y = vec![1.0; 50];
    y[0] = 1000.0; // a start-up transient
    let fig = Figure::new("r").size(400, 300).panel(
        Panel::new("x", "y")
            .y_range(0.5, 1.5)
            .series(Series::line("", x, y)),
    );
    let svg = render_svg(&fig).unwrap();
    assert!(
        svg.contains(">\n1.2\n<") || svg.contains(">1.2<"),
        "tick 1.2 expected"
    );
    assert!(!svg.contains(">\n1000\n<") && !svg.contains(">\n500\n<"));
    // Every drawn point of the series lies inside the SVG canvas.
    for poly in svg.split("<polyline").skip(1) {
        let pts = poly
            .split("points=\"")
            .nth(1)
            .unwrap()
            .split('"')
            .next()
            .unwrap();
        for p in pts.split_whitespace() {
            let (px, py) = p.split_once(',').unwrap();
            let (px, py): (f64, f64) = (px.parse().unwrap(), py.parse().unwrap());
            assert!(
                (0.0..=400.0).contains(&px) && (0.0..=300.0).contains(&py),
                "{p}"
            );
        }
    }
    // An empty or reversed range is ignored.
    assert_eq!(Panel::new("x", "y").y_range(2.0, 1.0).y_range, None);
    assert_eq!(Panel::new("x", "y").y_range(f64::NAN, 1.0).y_range, None);
}

// A fixed range 0..10 whose data fill every corner keeps its range (the legend never raises the top:
// a curve above a raised top ran under the legend, session 33's Fig. 5); the legend goes below the
// plot, outside the axes: its box (border #787878) lies wholly below the frame's bottom row, so no
// drawn point of any curve is under it; a curve rising to 100 is clipped at the frame's top row (10).
#[test]
fn a_legend_that_fits_no_corner_goes_below_the_plot() {
    let x: Vec<f64> = (0..=100).map(f64::from).collect();
    // Zig-zags between 0 and 10 that fill all four corners, and a ramp from 5 to 100.
    let zig: Vec<f64> = (0..=100)
        .map(|i| if i % 2 == 0 { 0.0 } else { 10.0 })
        .collect();
    let ramp: Vec<f64> = (0..=100).map(|i| 5.0 + 0.95 * f64::from(i)).collect();
    let fig = Figure::new("below").size(600, 400).panel(
        Panel::new("x", "y")
            .y_range(0.0, 10.0)
            .series(Series::line("zig-zag", x.clone(), zig).colour((0, 0, 0)))
            .series(Series::line("ramp", x, ramp).colour((213, 94, 0))),
    );
    let axes = y_axes(&fig).unwrap();
    assert_eq!(axes, vec![(0.0, 10.0)], "the legend does not move the axes");
    let (lo, hi) = axes[0];
    let svg = render_svg(&fig).unwrap();
    // The y axis line: the plotting area's top and bottom pixel rows.
    let axis = svg
        .split("<polyline")
        .skip(1)
        .map(|p| {
            p.split("points=\"")
                .nth(1)
                .unwrap()
                .split('"')
                .next()
                .unwrap()
        })
        .find(|pts| {
            let v: Vec<&str> = pts.split_whitespace().collect();
            v.len() == 2 && v[0].split(',').next() == v[1].split(',').next()
        })
        .unwrap()
        .to_string();
    let rows: Vec<f64> = axis
        .split_whitespace()
        .map(|p| p.split_once(',').unwrap().1.parse().unwrap())
        .collect();
    let (top, bottom) = (rows[0].min(rows[1]), rows[0].max(rows[1]));
    let ramp_rows: Vec<f64> = svg
        .split("<polyline")
        .skip(1)
        .filter(|p| {
            p.contains("stroke=\"#D55E00\"")
                && p.split("points=\"")
                    .nth(1)
                    .unwrap()
                    .split_whitespace()
                    .count()
                    > 10
        })
        .flat_map(|p| {
            p.split("points=\"")
                .nth(1)
                .unwrap()
                .split('"')
                .next()
                .unwrap()
                .split_whitespace()
                .map(|q| q.split_once(',').unwrap().1.parse::<f64>().unwrap())
                .collect::<Vec<_>>()
        })
        .collect();
    let highest = ramp_rows.iter().copied().fold(f64::INFINITY, f64::min);
    assert!(
        (highest - top).abs() <= 1.0,
        "ramp drawn up to row {highest}, frame top {top}"
    );
    // The row of y = 10 (the fixed range's top) is the frame's top.
    let row10 = bottom - (bottom - top) * (10.0 - lo) / (hi - lo);
    assert!(
        (row10 - top).abs() <= 0.5,
        "row of 10: {row10}, frame top {top}"
    );
    // The legend box: below the frame, and both entries' labels in it.
    let legend = svg
        .split('<')
        .find(|e| e.starts_with("rect") && e.contains("stroke=\"#787878\""))
        .expect("a legend box");
    let attr = |name: &str| -> f64 {
        let key = format!(" {name}=\"");
        let at = legend.find(&key).unwrap() + key.len();
        legend[at..].split('"').next().unwrap().parse().unwrap()
    };
    assert!(
        attr("y") > bottom,
        "legend box top {} above the frame's bottom {bottom}",
        attr("y")
    );
    assert!(attr("y") + attr("height") <= 400.0);
    assert!(
        svg.contains(">\nzig-zag\n<") || svg.contains(">zig-zag<"),
        "the label is drawn"
    );
    // Without a legend no band is needed: the drawn range is the fixed one.
    let plain =
        Figure::new("plain")
            .size(600, 400)
            .panel(Panel::new("x", "y").y_range(0.0, 10.0).series(Series::line(
                "",
                (0..3).map(f64::from).collect(),
                vec![0.0, 50.0, 5.0],
            )));
    assert_eq!(y_axes(&plain).unwrap(), vec![(0.0, 10.0)]);
}

// On a log10 axis the tick labels show 10^x: x = -1, 0, 1 read 0.1, 1, 10.
#[test]
fn log10_x_axis_labels_show_the_frequency() {
    let lf: Vec<f64> = (0..=40).map(|i| -2.0 + f64::from(i) * 0.1).collect();
    let mag: Vec<f64> = lf.iter().map(|v| -20.0 * v).collect();
    let fig = Figure::new("b").panel(
        Panel::new("f (Hz)", "dB")
            .x_log10()
            .series(Series::line("", lf, mag)),
    );
    let svg = render_svg(&fig).unwrap();
    for label in ["0.01", "0.1", "1", "10", "100"] {
        assert!(
            svg.contains(&format!(">\n{label}\n<")),
            "tick {label} missing"
        );
    }
    assert!(
        !svg.contains(">\n-1\n<"),
        "raw log10 values must not be shown"
    );
}
