//! Characterises the physics plant (default, or the TOML file given as argument): full-command speeds,
//! the command-to-velocity curve (deadzone), the paper's PI loop on 50 mm steps, the default staircase
//! experiment for a few seeds, and the simulation speed.
//!
//! `cargo run --release -p ipa --example characterise [-- plant.toml]`
#![allow(clippy::unwrap_used, clippy::expect_used, missing_docs)] // tests, benches and examples may panic

use ipa::{Ipa, PlantConfig};
use sysid_core::Plant;

fn speed(cfg: &PlantConfig, u: f64, dur_s: f64) -> f64 {
    let mut p = Ipa::new(cfg.clone()).unwrap();
    let start = if u > 0.0 { 20.0 } else { 180.0 };
    p.reset(start);
    let n = (dur_s / 0.01) as usize;
    let mut xs = vec![];
    for _ in 0..n {
        p.step(u).unwrap();
        xs.push(p.position_mm());
        if (p.position_mm() - start).abs() > 120.0 {
            break;
        }
    }
    // mean velocity over the second half of the record
    let m = xs.len();
    let h = m / 2;
    (xs[m - 1] - xs[h]) / ((m - 1 - h) as f64 * 0.01)
}

fn pi_step(cfg: &PlantConfig, from: f64, to: f64, secs: f64) -> (f64, f64, Vec<f64>) {
    let mut p = Ipa::new(cfg.clone()).unwrap();
    p.reset(from);
    let (kp, ki, ts) = (14.0, 1.0, 0.01);
    let mut sum = 0.0;
    let mut ys = vec![];
    for _ in 0..(secs / ts) as usize {
        let y = p.output();
        ys.push(y);
        let e = to - y;
        sum += e;
        let u = (kp * e + ki * ts * sum).clamp(-255.0, 255.0);
        p.step(u).unwrap();
    }
    let dir = (to - from).signum();
    let peak = ys.iter().map(|y| (y - from) * dir).fold(f64::MIN, f64::max);
    let os = 100.0 * (peak - (to - from).abs()) / (to - from).abs();
    let sse = to - ys[ys.len() - 1];
    (os, sse, ys)
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let cfg = match args.get(1) {
        Some(f) => PlantConfig::from_toml_file(std::path::Path::new(f)).unwrap(),
        None => PlantConfig::default(),
    };
    println!(
        "full speed +255: {:.1} mm/s, -255: {:.1} mm/s",
        speed(&cfg, 255.0, 0.6),
        speed(&cfg, -255.0, 0.6)
    );
    let mut line = String::new();
    for u in [5, 10, 15, 20, 25, 30, 35, 40, 50, 60, 80, 100, 150, 200] {
        let up = speed(&cfg, u as f64, 1.0);
        let dn = speed(&cfg, -u as f64, 1.0);
        line += &format!("u={u}: {up:.1}/{dn:.1}  ");
    }
    println!("{line}");
    for (a, b) in [(50.0, 100.0), (100.0, 50.0), (20.0, 70.0), (150.0, 100.0)] {
        let (os, sse, ys) = pi_step(&cfg, a, b, 8.0);
        println!(
            "PI {a}->{b}: overshoot {os:.2} %, sse(8s) {sse:.3} mm, y(1s) {:.2}, y(3s) {:.2}",
            ys[100], ys[300]
        );
    }
    for seed in 0..6 {
        let u = ipa::generate(&ipa::InputSpec::Staircase, 2000, 0.01, 255.0, seed).unwrap();
        let mut p = Ipa::new(cfg.clone()).unwrap();
        p.reset(100.0);
        let y = sysid_core::run_open_loop(&mut p, &u).unwrap();
        let ends = y.iter().filter(|&&v| v <= 0.0 || v >= 200.0).count();
        let (lo, hi) = y
            .iter()
            .fold((f64::MAX, f64::MIN), |(a, b), &v| (a.min(v), b.max(v)));
        println!(
            "staircase seed {seed}: at end stops {ends}/2000, range {lo:.1}..{hi:.1}, events {}",
            p.event_count()
        );
    }
    let u = ipa::generate(&ipa::InputSpec::Staircase, 200_000, 0.01, 255.0, 1).unwrap();
    let mut p = Ipa::new(cfg.clone()).unwrap();
    let t = std::time::Instant::now();
    let y = sysid_core::run_open_loop(&mut p, &u).unwrap();
    let el = t.elapsed().as_secs_f64();
    println!(
        "200000 steps (2000 s): {el:.3} s -> {:.0}x real time; last y {}",
        2000.0 / el,
        y[y.len() - 1]
    );
}
