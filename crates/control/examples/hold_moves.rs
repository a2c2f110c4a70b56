//! How far a nudge moves the physics plant (nominal + the verification's 20 variants, from rest at
//! 100 mm, both directions) when its ramp is held k samples after the first encoder count instead of
//! cut at it (issue 25, session 18: the evidence for ramp-and-cut's creep limit, docs/control.md).
//! u_b: the command at which a 20 counts/s ramp from 0 first moves the encoder; then, per ramp rate
//! ρ = 20, 50, 100, 210 counts/s from 0.8 u_b, the final move (mm, after 1.5 s with the valves
//! closed) for k = 0, 1, 2, 3, 4, 6.
//!
//! `cargo run --release -p control --example hold_moves`
#![allow(clippy::unwrap_used, clippy::expect_used, missing_docs)] // tests, benches and examples may panic
use sysid_core::Plant;
fn main() {
    let rates = [20.0, 50.0, 100.0, 210.0];
    let holds = [0u32, 1, 2, 3, 4, 6];
    for v in 0..=20u64 {
        let base = ipa::PlantConfig::default();
        let cfg = if v == 0 {
            base
        } else {
            ipa::calibrate::study::perturbed_from(&base, v, 0.3)
        };
        let mut p = ipa::Ipa::with_ts(cfg, 0.01).unwrap();
        for side in [1.0f64, -1.0] {
            // u_b: a 20 counts/s ramp from 0, first count.
            p.reset(100.0);
            let mut u = 0.0;
            let ub = loop {
                u += 0.2;
                let y = p.step(side * u).unwrap();
                if (y - 100.0).abs() > 0.005 || u > 255.0 {
                    break u;
                }
            };
            let mut line = format!("v{v:2} {:+} ub {ub:5.1}:", side as i32);
            for &rho in &rates {
                line += &format!(" r{rho}[");
                for &k in &holds {
                    p.reset(100.0);
                    let mut u = 0.8 * ub;
                    let mut held: Option<u32> = None;
                    for _ in 0..400 {
                        let cmd = match held {
                            Some(h) if h >= k => 0.0,
                            _ => u,
                        };
                        let y = p.step(side * cmd).unwrap();
                        if let Some(h) = held.as_mut() {
                            *h += 1;
                        } else if (y - 100.0).abs() > 0.005 {
                            held = Some(0);
                        } else {
                            u += rho * 0.01;
                        }
                    }
                    for _ in 0..150 {
                        p.step(0.0).unwrap();
                    }
                    line += &format!("{:.2} ", side * (p.output() - 100.0));
                }
                line += "]";
            }
            println!("{line}");
        }
    }
}
