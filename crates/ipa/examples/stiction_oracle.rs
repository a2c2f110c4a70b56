//! Feasibility oracle for issue 25's |e_ss| targets (docs/control.md, "Can any command land within
//! 0.02 mm?"): on the physics plant, nominal and the verification's variants (seeds 1..=20, ±30 %),
//! which displacements can ANY per-sample valve command sequence make from rest?
//!
//! From rest at 100 mm (or ORACLE_AT_MM) with both chambers at atmosphere, in each direction, open-loop command
//! sequences of three families, each followed by u = 0 until 1.5 s after the last non-zero command:
//! - pulses: u = ±A for W samples (A = 30..255 counts in steps of 15, W = 1..=20);
//! - ramp and cut: u rises from 0.8 u_b (u_b = the command at which a 20 counts/s ramp breaks the
//!   piston loose, found first) at ρ counts/s (ρ = 10, 20, 50, 100, 200, 500, 1000) and is cut
//!   j samples after the sample in which the piston first moved (true state, j = −1..=25: any cut
//!   time, as an open-loop sequence may choose it);
//! - ramp, cut and brake: as above, then a reverse command −B for Wb samples at the cut
//!   (B = 64, 128, 255; Wb = 1, 2, 3).
//!
//! Printed per variant and direction: F_s and F_c, the smallest move from rest (true displacement
//! ≥ 0.005 mm, i.e. one that shows on the 0.01 mm encoder) and the family that makes it, and the
//! smallest of each family, the smallest move of a ramp cut in the sample after the encoder first
//! counted (the best ρ; what a controller seeing only the encoder does), and the landing test: for every target distance d = 0.01..=2 mm (step
//! 0.01 mm) the move closest to d; how many of the 200 targets are reached within 0.02 mm and within
//! 0.05 mm, and the largest gap between consecutive achievable moves below 2 mm (a finer grid of
//! cut times or ramp rates can only fill gaps: these are lower bounds of what is achievable).
//!
//! `cargo run --release -p ipa --example stiction_oracle [-- VARIANT...]` (default: 0..=20; 0 =
//! nominal), or `scripts/stiction_oracle.sh`.
#![allow(clippy::unwrap_used, clippy::expect_used, missing_docs)] // tests, benches and examples may panic

use ipa::calibrate::study::perturbed_from;
use ipa::{Ipa, PlantConfig};
use rayon::prelude::*;
use sysid_core::Plant;

const TS: f64 = 0.01;
const REST_AFTER: usize = 150;

/// Runs `u` (then zeros for REST_AFTER samples) from rest at x0_mm(); returns the true displacement, mm.
fn run(cfg: &PlantConfig, u: &[f64]) -> f64 {
    let x0 = x0_mm();
    let mut p = Ipa::with_ts(cfg.clone(), TS).unwrap();
    p.reset(x0);
    for &uk in u {
        p.step(uk).unwrap();
    }
    for _ in 0..REST_AFTER {
        p.step(0.0).unwrap();
    }
    p.position_mm() - x0
}

/// The ramp from `u0` at `rho` counts/s in direction `side`; returns the commands up to and including
/// the sample in which the piston first leaves rest, or None if it never does within 6 s.
fn ramp_to_breakaway(cfg: &PlantConfig, side: f64, u0: f64, rho: f64) -> Option<Vec<f64>> {
    let x0 = x0_mm();
    let mut p = Ipa::with_ts(cfg.clone(), TS).unwrap();
    p.reset(x0);
    let mut u = Vec::new();
    let mut cmd = u0;
    for _ in 0..600 {
        u.push(side * cmd.min(255.0));
        p.step(side * cmd.min(255.0)).unwrap();
        if !p.is_stuck() || (p.position_mm() - x0).abs() > 1e-6 {
            return Some(u);
        }
        cmd += rho * TS;
    }
    None
}

/// The ramp from `u0` at `rho` counts/s in direction `side`, cut in the sample after the encoder
/// reading first changed (what a controller that sees only the encoder can do); the true move, mm.
fn ramp_cut_at_encoder(cfg: &PlantConfig, side: f64, u0: f64, rho: f64) -> Option<f64> {
    let x0 = x0_mm();
    let mut p = Ipa::with_ts(cfg.clone(), TS).unwrap();
    p.reset(x0);
    let y0 = p.output();
    let mut cmd = u0;
    for _ in 0..600 {
        if p.step(side * cmd.min(255.0)).unwrap() != y0 {
            for _ in 0..REST_AFTER {
                p.step(0.0).unwrap();
            }
            return Some(side * (p.position_mm() - x0));
        }
        cmd += rho * TS;
    }
    None
}

/// The start position, mm: the environment variable ORACLE_AT_MM, else 100 (mid-stroke).
fn x0_mm() -> f64 {
    std::env::var("ORACLE_AT_MM")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(100.0)
}

struct Move {
    d_mm: f64,
    how: String,
}

fn moves(cfg: &PlantConfig, side: f64) -> (Vec<Move>, Option<f64>, (f64, f64)) {
    let mut out = Vec::new();
    for a in (30..=255).step_by(15) {
        for w in 1..=20 {
            let u = vec![side * a as f64; w];
            out.push(Move {
                d_mm: side * run(cfg, &u),
                how: format!("pulse {a} x {w}"),
            });
        }
    }
    let ub = ramp_to_breakaway(cfg, side, 0.0, 20.0).map(|u| u.last().unwrap().abs());
    if let Some(ub) = ub {
        for rho in [10.0, 20.0, 50.0, 100.0, 200.0, 500.0, 1000.0] {
            let Some(base) = ramp_to_breakaway(cfg, side, 0.8 * ub, rho) else {
                continue;
            };
            let last = base.last().unwrap().abs();
            for j in -1i32..=25 {
                let mut u = base.clone();
                if j < 0 {
                    u.pop();
                } else {
                    for i in 0..j {
                        u.push(side * (last + rho * TS * f64::from(i + 1)).min(255.0));
                    }
                }
                out.push(Move {
                    d_mm: side * run(cfg, &u),
                    how: format!("ramp {rho} cut {j}"),
                });
                for b in [64.0, 128.0, 255.0] {
                    for wb in 1..=3 {
                        let mut ub2 = u.clone();
                        ub2.extend(std::iter::repeat_n(-side * b, wb));
                        out.push(Move {
                            d_mm: side * run(cfg, &ub2),
                            how: format!("ramp {rho} cut {j} brake {b} x {wb}"),
                        });
                    }
                }
            }
        }
    }
    let encoder_cut = ub
        .and_then(|ub| {
            [10.0, 20.0, 50.0, 100.0, 200.0, 500.0, 1000.0]
                .into_iter()
                .filter_map(|rho| ramp_cut_at_encoder(cfg, side, 0.8 * ub, rho).map(|d| (d, rho)))
                .min_by(|a, b| a.0.total_cmp(&b.0))
        })
        .unwrap_or((f64::NAN, f64::NAN));
    (out, ub, encoder_cut)
}

/// The family of a sequence from its description.
fn family_of(how: &str) -> &'static str {
    if how.starts_with("pulse") {
        "pulse"
    } else if how.contains("brake") {
        "brake"
    } else {
        "ramp"
    }
}

fn main() {
    let args: Vec<usize> = std::env::args()
        .skip(1)
        .map(|a| a.parse().expect("variant numbers"))
        .collect();
    let variants: Vec<usize> = if args.is_empty() {
        (0..=20).collect()
    } else {
        args
    };
    let jobs: Vec<(usize, f64)> = variants
        .iter()
        .flat_map(|&v| [(v, 1.0), (v, -1.0)])
        .collect();
    let lines: Vec<String> = jobs
        .par_iter()
        .map(|&(v, side)| {
            let base = PlantConfig::default();
            let cfg = if v == 0 {
                base
            } else {
                perturbed_from(&base, v as u64, 0.3)
            };
            let (ms, ub, enc) = moves(&cfg, side);
            let smallest_of = |family: &str| {
                ms.iter()
                    .filter(|m| m.d_mm >= 0.005 && family_of(&m.how) == family)
                    .map(|m| m.d_mm)
                    .fold(f64::INFINITY, f64::min)
            };
            let smallest = ms
                .iter()
                .filter(|m| m.d_mm >= 0.005)
                .min_by(|a, b| a.d_mm.total_cmp(&b.d_mm))
                .unwrap();
            let mut ds: Vec<f64> = ms.iter().map(|m| m.d_mm).filter(|d| *d > 0.0).collect();
            ds.sort_by(f64::total_cmp);
            let best = |d: f64| ds.iter().map(|m| (m - d).abs()).fold(f64::INFINITY, f64::min);
            // Targets d = 0.01..=2 mm (step 0.01): how many are reached within 0.02 and 0.05 mm.
            let reached = |tol: f64| (1..=200).filter(|&i| best(f64::from(i) * 0.01) <= tol).count();
            let below: Vec<f64> = ds.iter().copied().filter(|d| *d <= 2.0).collect();
            let gap = below
                .windows(2)
                .map(|w| (w[1] - w[0], w[0]))
                .fold((0.0, 0.0), |a, b| if b.0 > a.0 { b } else { a });
            format!(
                "variant {v:2} {} F_s {:5.2} N F_c {:5.2} N (F_c/F_s {:.2}) u_b {:>5} | smallest move {:.3} mm ({}); pulse {:.3}, ramp+cut {:.3}, +brake {:.3}; cut at the first encoder count {:.3} (ρ {}) | d = 0.01..2 mm reached within 0.02: {}/200, within 0.05: {}/200 | largest gap below 2 mm {:.3} mm at {:.3} mm",
                if side > 0.0 { "+" } else { "-" },
                cfg.friction.static_n,
                cfg.friction.coulomb_n,
                cfg.friction.coulomb_n / cfg.friction.static_n,
                ub.map_or("none".into(), |u| format!("{u:.1}")),
                smallest.d_mm,
                smallest.how,
                smallest_of("pulse"),
                smallest_of("ramp"),
                smallest_of("brake"),
                enc.0,
                enc.1,
                reached(0.02),
                reached(0.05),
                gap.0,
                gap.1,
            )
        })
        .collect();
    for l in lines {
        println!("{l}");
    }
}
