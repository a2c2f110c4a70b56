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
    let path = format!("/tmp/ref_{n}_{}.bin", std::env::var("INPUT").unwrap_or_default() + &seed.to_string() + &amp.to_string());
    let (r, tr, er) = match std::fs::read(&path) {
        Ok(b) => (b.chunks(8).map(|c| f64::from_le_bytes(c.try_into().unwrap())).collect::<Vec<f64>>(), 0.0, 0),
        Err(_) => { let x = run(rcfg, Integrator::Rk4, &u); std::fs::write(&path, x.0.iter().flat_map(|v| v.to_le_bytes()).collect::<Vec<u8>>()).unwrap(); x }
    };
    let (o, to, eo) = if std::env::var("NORK4").is_ok() { (r.clone(), 0.0, 0) } else { run(ipa::PlantConfig::default(), Integrator::Rk4, &u) };
    let mut cfg = ipa::PlantConfig::default();
    cfg.integration.tolerance = tol;
    let (d, td, ed) = run(cfg.clone(), Integrator::DormandPrince, &u);

    let err = |a: &[f64]| a.iter().zip(&r).map(|(a, b)| (a - b).abs()).fold(0.0, f64::max);
    let pos = |a: &[f64]| a.iter().zip(&r).position(|(a, b)| (a - b).abs() > 1e-3);
    let mut last = 0.0;
    if std::env::var("QUIET").is_err() { for k in 0..n { let e = (d[k]-r[k]).abs(); if (e - last).abs() > 2e-5 { println!("  k {k} u {} x {:.4} err {:.3e} (was {:.3e})", u[k], r[k], e, last); } last = e; } }
    println!("ref rk4/16: {tr:.3}s ev {er}; rk4: {to:.3}s ev {eo} err {:.3e}; dp tol {tol:e}: {td:.3}s ({:.0}x) ev {ed} err {:.3e} first>1e-3 {:?}", err(&o), n as f64*0.01/td, err(&d), pos(&d));
}
#[allow(dead_code)]
fn counts() {}
