#![allow(clippy::unwrap_used, missing_docs)]
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use sysid::data::Signals;
use sysid::*;
fn gauss(rng: &mut ChaCha8Rng) -> f64 {
    let u1: f64 = rng.gen_range(1e-12..1.0);
    let u2: f64 = rng.gen();
    (-2.0 * u1.ln()).sqrt() * (std::f64::consts::TAU * u2).cos()
}
fn main() {
    let mut rng = ChaCha8Rng::seed_from_u64(101);
    let mut u = Vec::new();
    while u.len() < 2000 {
        let level = rng.gen_range(-8i32..=8) as f64;
        let hold = rng.gen_range(10..50);
        for _ in 0..hold {
            if u.len() < 2000 {
                u.push(level);
            }
        }
    }
    let m = Model::paper();
    let y0 = m.simulate(&u, &vec![0.0; u.len()]).unwrap();
    let y: Vec<f64> = y0.iter().map(|v| v + 0.01 * gauss(&mut rng)).collect();
    let data = Dataset::new(Signals { u, y }, 0.01, "t").unwrap();
    for it in [100usize, 300, 1000] {
        let s = Identification::default().with_estimator(EstimatorSettings::Oe(OutputError {
            max_iterations: it,
            ..OutputError::default()
        }));
        let fit = identify(&data, &s).unwrap();
        println!("{it}: {:?} {:?}", fit.model.a(), fit.note());
    }
}
