//! Criterion benchmark of one RLS update (paper eqs. 9–12) for n = 4, 9 and 16 parameters: the fast
//! heap estimator `Rls::update`, the array-backed `RlsN<N>` and the plain reference loop `ReferenceRls`.
//! Run with `cargo bench -p sysid --bench rls` (not part of the tests).

#![allow(clippy::unwrap_used, clippy::expect_used, missing_docs)] // tests, benches and examples may panic

use std::hint::black_box;

use criterion::{criterion_group, criterion_main, BenchmarkId, Criterion, Throughput};
use rand::Rng;
use sysid::rls::{ReferenceRls, Rls, RlsN};
use sysid_studies::rng::SplitMix64;

const RING: usize = 1024;

/// `RING` regressors uniform in [−1, 1] and outputs y = φᵀθ* + 0.01 e.
fn data(n: usize) -> (Vec<f64>, Vec<f64>) {
    let mut rng = SplitMix64::new(n as u64);
    let truth: Vec<f64> = (0..n).map(|_| rng.range(-1.0, 1.0)).collect();
    let phi: Vec<f64> = (0..RING * n).map(|_| rng.range(-1.0, 1.0)).collect();
    let y = phi
        .chunks_exact(n)
        .map(|r| {
            r.iter().zip(&truth).map(|(a, b)| a * b).sum::<f64>()
                + 0.01 * rng.sample::<f64, _>(rand_distr::StandardNormal)
        })
        .collect();
    (phi, y)
}

fn fixed<const N: usize>(
    c: &mut criterion::BenchmarkGroup<'_, criterion::measurement::WallTime>,
    phi: &[f64],
    y: &[f64],
) {
    let rows: Vec<[f64; N]> = phi
        .chunks_exact(N)
        .map(|r| std::array::from_fn(|i| r[i]))
        .collect();
    c.bench_function(BenchmarkId::new("RlsN", N), |b| {
        let mut est = RlsN::<N>::new(0.99, 1e3).expect("valid settings");
        let mut k = 0;
        b.iter(|| {
            let i = k % RING;
            k += 1;
            black_box(
                est.update(black_box(&rows[i]), y[i], k)
                    .expect("well-posed data"),
            )
        })
    });
}

fn rls_update(c: &mut Criterion) {
    let mut g = c.benchmark_group("rls_update");
    g.throughput(Throughput::Elements(1));
    for n in [4usize, 9, 16] {
        let (phi, y) = data(n);
        g.bench_function(BenchmarkId::new("Rls", n), |b| {
            let mut est = Rls::new(n, 0.99, 1e3).expect("valid settings");
            let mut k = 0;
            b.iter(|| {
                let i = k % RING;
                k += 1;
                black_box(
                    est.update(black_box(&phi[i * n..i * n + n]), y[i], k)
                        .expect("well-posed data"),
                )
            })
        });
        g.bench_function(BenchmarkId::new("reference", n), |b| {
            let mut est = ReferenceRls::new(n, 0.99, 1e3).expect("valid settings");
            let mut k = 0;
            b.iter(|| {
                let i = k % RING;
                k += 1;
                black_box(
                    est.update(black_box(&phi[i * n..i * n + n]), y[i], k)
                        .expect("well-posed data"),
                )
            })
        });
        match n {
            4 => fixed::<4>(&mut g, &phi, &y),
            9 => fixed::<9>(&mut g, &phi, &y),
            16 => fixed::<16>(&mut g, &phi, &y),
            _ => {}
        }
    }
    g.finish();
}

criterion_group!(benches, rls_update);
criterion_main!(benches);
