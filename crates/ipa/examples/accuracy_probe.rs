use ipa::plant::Integrator;
use sysid::Plant;
fn run(cfg: ipa::PlantConfig, integ: Integrator, u: &[f64]) -> (Vec<f64>, f64, u64) {
    let mut p = ipa::Ipa::new(cfg).unwrap();
    p.set_integrator(integ);
    p.reset(100.0);
    let t = std::time::Instant::now();
    let x: Vec<f64> = u.iter().map(|&uk| { p.step(uk).unwrap(); p.position_mm() }).collect();
    (x, t.elapsed().as_secs_f64(), p.event_count())
}
fn main() {
    let n: usize = std::env::args().nth(1).map(|a| a.parse().unwrap()).unwrap_or(3000);
    let tol: f64 = std::env::args().nth(2).map(|a| a.parse().unwrap()).unwrap_or(1e-8);
    let seed: u64 = std::env::var("SEED").ok().and_then(|v| v.parse().ok()).unwrap_or(1);
    let spec = match std::env::var("INPUT").as_deref() { Ok("prbs") => ipa::InputSpec::Prbs, Ok("aprbs") => ipa::InputSpec::Aprbs, _ => ipa::InputSpec::Staircase };
    let amp: f64 = std::env::var("AMP").ok().and_then(|v| v.parse().ok()).unwrap_or(255.0);
    let u = ipa::generate(&spec, n, 0.01, amp, seed).unwrap();
    let mut rcfg = ipa::PlantConfig::default();
    rcfg.integration.max_substep_ms /= 16.0;
    rcfg.integration.slow_substep_ms /= 16.0;
    let (r, tr, er) = run(rcfg, Integrator::Rk4, &u);
    let (o, to, eo) = run(ipa::PlantConfig::default(), Integrator::Rk4, &u);
    let mut cfg = ipa::PlantConfig::default();
    cfg.integration.tolerance = tol;
    let (d, td, ed) = run(cfg.clone(), Integrator::DormandPrince, &u);

    let err = |a: &[f64]| a.iter().zip(&r).map(|(a, b)| (a - b).abs()).fold(0.0, f64::max);
    let pos = |a: &[f64]| a.iter().zip(&r).position(|(a, b)| (a - b).abs() > 1e-3);
    let mut last = 0.0;
    for k in 0..n { let e = (d[k]-r[k]).abs(); if (e - last).abs() > 2e-5 { println!("  k {k} u {} x {:.4} err {:.3e} (was {:.3e})", u[k], r[k], e, last); } last = e; }
    println!("ref rk4/16: {tr:.3}s ev {er}; rk4: {to:.3}s ev {eo} err {:.3e}; dp tol {tol:e}: {td:.3}s ({:.0}x) ev {ed} err {:.3e} first>1e-3 {:?}", err(&o), n as f64*0.01/td, err(&d), pos(&d));
}
#[allow(dead_code)]
fn counts() {}
