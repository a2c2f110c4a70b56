//! Simulation speed of the physics plant: 200 000 samples (2000 s of plant time at Ts = 0.01 s) of the
//! staircase input, timed in the release build.
//!
//! `cargo run --release -p ipa --example speed [SAMPLES] [rk4|dp] [TOLERANCE]` (default 200 000 samples, the adaptive
//! Dormand–Prince integrator; `rk4` runs the classical RK4 reference instead).

#![allow(clippy::unwrap_used, clippy::expect_used, missing_docs)] // tests, benches and examples may panic

use sysid_core::Plant;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let mut args = std::env::args().skip(1);
    let n: usize = match args.next() {
        Some(a) => a.parse()?,
        None => 200_000,
    };
    let integrator = match args.next().as_deref() {
        Some("rk4") => ipa::plant::Integrator::Rk4,
        _ => ipa::plant::Integrator::DormandPrince,
    };
    let u = ipa::generate(&ipa::InputSpec::Staircase, n, 0.01, 255.0, 1)?;
    let mut cfg = ipa::PlantConfig::default();
    if let Some(t) = args.next() {
        cfg.integration.tolerance = t.parse()?;
    }
    let mut plant = ipa::Ipa::new(cfg)?;
    plant.set_integrator(integrator);
    plant.reset(100.0);
    let start = std::time::Instant::now();
    let y = sysid_core::run_open_loop(&mut plant, &u)?;
    let elapsed = start.elapsed().as_secs_f64();
    let plant_time = n as f64 * plant.ts();
    println!(
        "{n} samples ({plant_time} s of plant time) in {elapsed:.3} s: {:.0}x real time; {} events; final y {} mm",
        plant_time / elapsed,
        plant.event_count(),
        y[n - 1]
    );
    let st = plant.integration_stats();
    println!(
        "{:?}: {:.2} steps, {:.2} rejected, {:.1} derivative evaluations per sample",
        plant.integrator(),
        st.steps as f64 / n as f64,
        st.rejected_steps as f64 / n as f64,
        st.derivative_evaluations as f64 / n as f64
    );
    Ok(())
}
