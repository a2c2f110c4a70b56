//! One plant of the calibration study, printed (estimates against the truth, time, fits):
//! `cargo run --release -p ipa --example calibrate_one -- SEED [SEGMENT_S [MAX_ITERATIONS [SAMPLES]]]`.
use ipa::calibrate::study::Study;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let seed: u64 = std::env::args().nth(1).map_or(Ok(1), |s| s.parse())?;
    let mut study = Study {
        seed,
        ..Study::default()
    };
    if let Some(seg) = std::env::args().nth(2) {
        study.calibration.segment_s = seg.parse()?;
    }
    if let Some(it) = std::env::args().nth(3) {
        study.calibration.max_iterations = it.parse()?;
    }
    if let Some(n) = std::env::args().nth(4) {
        study.estimation_samples = n.parse()?;
    }
    let t = std::time::Instant::now();
    let c = study.case(0)?;
    let cal = &c.calibrated;
    println!(
        "seed {} segments {} iterations {} evaluations {} {:?} cost {:.3e} -> {:.3e} in {:.2} s",
        c.seed,
        cal.segments,
        cal.iterations,
        cal.evaluations,
        cal.termination,
        cal.cost_start,
        cal.cost,
        t.elapsed().as_secs_f64()
    );
    for (i, e) in cal.estimates.iter().enumerate() {
        println!(
            "{:22} truth {:10.4} start {:10.4} est {:10.4} std {:9.2e} err {:7.3} % det {}",
            e.parameter.name(),
            e.parameter.get(&c.truth),
            e.start,
            e.value,
            e.std.unwrap_or(f64::NAN),
            100.0 * c.relative_errors[i],
            c.determined[i]
        );
    }
    let f = |r: &Option<ipa::calibrate::FreeRun>| {
        r.as_ref().and_then(|r| r.fit_percent).unwrap_or(f64::NAN)
    };
    println!(
        "fit est start {:.2} twin {:.2}; val start {:.2} twin {:.2}",
        f(&cal.estimation_start),
        f(&cal.estimation),
        f(&cal.validation_start),
        f(&cal.validation)
    );
    for w in &cal.warnings {
        println!("warning: {w}");
    }
    Ok(())
}
