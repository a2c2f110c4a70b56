//! Figures of `docs/plant.md`: step responses of the physics IPA plant and its measured
//! command-to-velocity curve (showing the deadzone).
//!
//! `cargo run --release -p report --example plant_figures` (writes docs/figures/plant_*.{svg,png}).

#![allow(clippy::unwrap_used, clippy::expect_used, missing_docs)] // tests, benches and examples may panic

use std::path::Path;

use ipa::{Ipa, PlantConfig};
use report::plot::{save_figure, Figure, Panel, Series};
use sysid::Plant;

/// Mean velocity (mm/s) at constant command u from the end stop it moves away from, measured over
/// 0.3..1.3 s (or until 150 mm of travel).
fn velocity_mm_s(u: f64) -> Result<f64, Box<dyn std::error::Error>> {
    let mut p = Ipa::new(PlantConfig::default())?;
    let start = if u >= 0.0 { 10.0 } else { 190.0 };
    p.reset(start);
    let mut pts = vec![];
    for k in 0..130 {
        let travel = (p.position_mm() - start).abs();
        if k >= 30 && travel <= 150.0 {
            pts.push((k as f64 * 0.01, p.position_mm()));
        }
        p.step(u)?;
    }
    Ok(match (pts.first(), pts.last()) {
        (Some(a), Some(b)) if b.0 > a.0 => (b.1 - a.1) / (b.0 - a.0),
        _ => 0.0,
    })
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../docs/figures");
    std::fs::create_dir_all(&dir)?;
    let ts = 0.01;

    // Open-loop command steps from 20 mm, u applied from t = 0.1 s.
    let mut pos = Panel::new("time (s)", "position y (mm)");
    let mut prs = Panel::new("time (s)", "chamber pressure (kPa abs), u = 120");
    for u in [60.0, 120.0, 255.0, -120.0] {
        let mut p = Ipa::new(PlantConfig::default())?;
        let start = if u > 0.0 { 20.0 } else { 180.0 };
        p.reset(start);
        let (mut t, mut y, mut pa, mut pb) = (vec![], vec![], vec![], vec![]);
        for k in 0..70 {
            t.push(k as f64 * ts);
            y.push(p.output());
            let pr = p.pressures_pa();
            pa.push(pr[0] / 1e3);
            pb.push(pr[1] / 1e3);
            p.step(if k >= 10 { u } else { 0.0 })?;
        }
        if u == 120.0 {
            prs = prs
                .series(Series::line("p_a (cap side)", t.clone(), pa))
                .series(Series::dashed("p_b (rod side)", t.clone(), pb));
        }
        pos = pos.series(Series::line(format!("u = {u}"), t, y));
    }
    // The paper's PI loop on a 50 mm step.
    let mut p = Ipa::new(PlantConfig::default())?;
    p.reset(50.0);
    let (mut t, mut y, mut r) = (vec![], vec![], vec![]);
    let mut sum = 0.0;
    for k in 0..300 {
        let yk = p.output();
        t.push(k as f64 * ts);
        y.push(yk);
        r.push(100.0);
        let e = 100.0 - yk;
        sum += e;
        p.step((14.0 * e + ts * sum).clamp(-255.0, 255.0))?;
    }
    let pi = Panel::new("time (s)", "position y (mm), PI Kp = 14, Ki = 1")
        .series(Series::dashed("set-point", t.clone(), r))
        .series(Series::line("y", t, y));
    let fig =
        Figure::new("Physics IPA: open-loop command steps (u from t = 0.1 s), pressures, PI step")
            .panel(pos)
            .panel(prs)
            .panel(pi)
            .size(900, 1000);
    save_figure(&fig, &dir, "plant_step")?;

    // Command-to-velocity curve.
    let (mut us, mut vs) = (vec![], vec![]);
    let mut u = -255.0;
    while u <= 255.0 {
        us.push(u);
        vs.push(velocity_mm_s(u)?);
        u += 5.0;
    }
    let zoom: Vec<usize> = (0..us.len()).filter(|&i| us[i].abs() <= 80.0).collect();
    let fig = Figure::new("Physics IPA: steady velocity versus command (deadzone)")
        .panel(
            Panel::new("command u (counts)", "velocity (mm/s)").series(Series::points(
                "measured",
                us.clone(),
                vs.clone(),
            )),
        )
        .panel(
            Panel::new("command u (counts), |u| <= 80", "velocity (mm/s)").series(Series::points(
                "measured",
                zoom.iter().map(|&i| us[i]).collect(),
                zoom.iter().map(|&i| vs[i]).collect(),
            )),
        )
        .size(900, 800);
    save_figure(&fig, &dir, "plant_deadzone")?;
    for (u, v) in us.iter().zip(&vs) {
        if u.abs() <= 60.0 || u.abs() == 255.0 {
            println!("u = {u:6.0}: v = {v:8.1} mm/s");
        }
    }
    Ok(())
}
