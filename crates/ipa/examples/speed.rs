//! Simulation speed of the physics plant: 200 000 samples (2000 s of plant time at Ts = 0.01 s) of the
//! staircase input, timed in the release build.
//!
//! `cargo run --release -p ipa --example speed`

#![allow(clippy::unwrap_used, clippy::expect_used, missing_docs)] // tests, benches and examples may panic

use sysid_core::Plant;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let n = 200_000;
    let u = ipa::generate(&ipa::InputSpec::Staircase, n, 0.01, 255.0, 1)?;
    let mut plant = ipa::Ipa::new(ipa::PlantConfig::default())?;
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
    Ok(())
}
