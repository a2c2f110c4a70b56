//! Runs a controller file (CONTROLLER.json) through the verification of `ipa-sysid tune
//! --check-physics`: the physics plant, nominal + 20 variants ±30 % (seeds 1..=20), the default
//! specification's 8 steps (168 runs), and prints the counts of runs meeting each criterion. For
//! trying a change of one setting of a tuned controller (not a tuning: it runs on the true plants).
//!
//! `cargo run --release -p control --example physics_variants -- CONTROLLER.json [REST_BAND_MM]`
//! REST_BAND_MM replaces the nudge's rest band e_r; the environment variables GAMMA, BAND, RHO, BETA
//! replace γ, e_n, ρ, β; SHOW=1 lists the runs whose |e_ss| > 0.02 mm; TRACE=V,Y0,R prints the run of
//! variant V from Y0 to R (samples within 3 mm of R).
#![allow(clippy::unwrap_used, clippy::expect_used, missing_docs)] // tests, benches and examples may panic
use control::tune::{self, Spec};
use control::ControllerFile;
use sysid_core::Plant;
fn main() {
    let a: Vec<String> = std::env::args().collect();
    let mut s = ControllerFile::parse(&std::fs::read_to_string(&a[1]).unwrap(), "c").unwrap();
    if let (Some(n), Some(rb)) = (s.nudge.as_mut(), a.get(2)) {
        n.rest_band_mm = rb.parse().unwrap();
    }
    if let Some(n) = s.nudge.as_mut() {
        let env = |k: &str| std::env::var(k).ok().map(|v| v.parse::<f64>().unwrap());
        for (key, field) in [
            ("GAMMA", &mut n.cut_fraction),
            ("BAND", &mut n.band_mm),
            ("RHO", &mut n.ramp_counts_s),
            ("BETA", &mut n.start_fraction),
            ("MINRHO", &mut n.min_ramp_counts_s),
            ("CUTBAND", &mut n.cut_band_mm),
        ] {
            if let Some(v) = env(key) {
                *field = v;
            }
        }
    }
    let spec = Spec::default();
    if let Ok(t) = std::env::var("TRACE") {
        let v: Vec<f64> = t.split(',').map(|x| x.parse().unwrap()).collect();
        let base = ipa::PlantConfig::default();
        let cfg = if v[0] == 0.0 {
            base
        } else {
            ipa::calibrate::study::perturbed_from(&base, v[0] as u64, 0.3)
        };
        let mut p = ipa::Ipa::with_ts(cfg, 0.01).unwrap();
        let mut c = s.build().unwrap();
        let tr = control::closed_loop::run(
            &mut p,
            &mut c,
            None,
            &control::Profile::Fixed { setpoint_mm: v[2] },
            3.0,
            v[1],
        )
        .unwrap();
        for k in 0..tr.len() {
            if (v[2] - tr.y[k]).abs() < 3.0 {
                println!(
                    "{:.2} y {:.3} e {:.3} u {:.1}",
                    tr.t[k],
                    tr.y[k],
                    v[2] - tr.y[k],
                    tr.u[k]
                );
            }
        }
        return;
    }
    let make = |i: usize| -> Result<Box<dyn Plant + Send>, control::ControlError> {
        let base = ipa::PlantConfig::default();
        let cfg = if i == 0 {
            base
        } else {
            ipa::calibrate::study::perturbed_from(&base, i as u64, 0.3)
        };
        Ok(Box::new(ipa::Ipa::with_ts(cfg, 0.01).unwrap()))
    };
    let ev = tune::evaluate(21, &make, &move || Ok(Box::new(s.build()?)), &spec).unwrap();
    for r in &ev.runs {
        let e = r.metrics.steady_state_error_mm.unwrap_or(f64::NAN);
        if (e.is_nan() || e.abs() > 0.02) && std::env::var("SHOW").is_ok() {
            println!(
                "  plant {} {} -> {} e_ss {:.3} cycle {:.2} OS {:?} ts {:?}",
                r.plant,
                r.case.y0_mm,
                r.case.r_mm,
                e,
                r.limit_cycle_mm,
                r.metrics.overshoot_percent,
                r.metrics.settling_time_s
            );
        }
    }
    println!(
        "OS {} ts {} ess {} all {} worst ess {:.3} cycle {:.3}",
        ev.overshoot_met,
        ev.settling_met,
        ev.ess_met,
        ev.met,
        ev.max_abs_ess_mm,
        ev.worst_limit_cycle_mm
    );
}
