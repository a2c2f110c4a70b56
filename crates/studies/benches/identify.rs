//! Criterion benchmark of a full Hammerstein identification (na = 3, nb = 1, nk = 1) of 2000 samples of
//! the paper's model driven by a staircase, with 0.01 mm measurement noise: key-term LS and RLS.
//! Run with `cargo bench -p sysid --bench identify` (not part of the tests).

#![allow(clippy::unwrap_used, clippy::expect_used, missing_docs)] // tests, benches and examples may panic

use std::hint::black_box;

use criterion::{criterion_group, criterion_main, Criterion};
use sysid::{identify, Method};
use sysid_studies::bench::{paper_experiment, paper_settings, staircase};

fn hammerstein_2000(c: &mut Criterion) {
    let u = staircase(2000, 255.0, 1);
    let data = paper_experiment(&u, 0.01, 1).expect("the paper model runs");
    let mut g = c.benchmark_group("hammerstein_2000");
    for method in [Method::Ls, Method::Rls] {
        let settings = paper_settings(method);
        g.bench_function(method.to_string(), |b| {
            b.iter(|| black_box(identify(black_box(&data), &settings).expect("identifiable data")))
        });
    }
    g.finish();
}

criterion_group!(benches, hammerstein_2000);
criterion_main!(benches);
