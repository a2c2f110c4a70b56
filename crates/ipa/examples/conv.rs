//! Scratch: convergence of the position versus the RK4 substep, and speed.
use ipa::{Ipa, PlantConfig};
use sysid::Plant;

fn run(h_ms: f64, u: &[f64]) -> (Vec<f64>, f64, u64) {
    let mut cfg = PlantConfig::default();
    cfg.integration.max_substep_ms = h_ms;
    let ratio: f64 = std::env::var("RATIO").map(|r| r.parse().unwrap()).unwrap_or(4.0);
    cfg.integration.slow_substep_ms = h_ms / ratio;
    if std::env::var("SAMEEXP").is_ok() {
        cfg.air.exponent_charging = 1.2;
        cfg.air.exponent_discharging = 1.2;
    }
    if std::env::var("NOSTRIB").is_ok() {
        cfg.friction.static_n = cfg.friction.coulomb_n;
    }
    if std::env::var("NOFRIC").is_ok() {
        cfg.friction.static_n = 0.0;
        cfg.friction.coulomb_n = 0.0;
    }
    if std::env::var("NODELAY").is_ok() {
        cfg.valve.opening_delay_ms = 0.0;
        cfg.valve.closing_delay_ms = 0.0;
    }
    if let Ok(r) = std::env::var("RLAM") {
        cfg.valve.laminar_pressure_ratio = r.parse().unwrap();
    }
    let mut p = Ipa::new(cfg).unwrap();
    p.reset(100.0);
    let t = std::time::Instant::now();
    let mut xs = vec![];
    for &uk in u {
        p.step(uk).unwrap();
        xs.push(p.position_mm());
    }
    (xs, t.elapsed().as_secs_f64(), p.event_count())
}

fn main() {
    let n: usize = std::env::args().nth(1).map(|s| s.parse().unwrap()).unwrap_or(500);
    let u = ipa::generate(&ipa::InputSpec::Staircase, n, 0.01, 255.0, 1).unwrap();
    let (r, _, _) = run(0.5 / 64.0, &u);
    if std::env::var("TRACE").is_ok() && false {
        let (x, _, _) = run(0.5, &u);
        for k in 0..n {
            let d = (x[k] - r[k]).abs();
            if d > 1e-8 {
                println!("k={k} u={} x={:.6} dx={:.3e}", u[k], x[k], d);
            }
        }
    }
    for h in [2.0, 1.0, 0.5, 0.25, 0.125] {
        let (x, el, ev) = run(h, &u);
        let err = x.iter().zip(&r).map(|(a, b)| (a - b).abs()).fold(0.0, f64::max);
        println!("h = {h} ms: max |dx| = {err:.3e} mm, {:.0}x real time, events {ev}", n as f64 * 0.01 / el);
    }
}

#[allow(dead_code)]
pub fn trace() {}
