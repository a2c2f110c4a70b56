//! Criterion benchmark of one update of `ipa_embedded::Rls` (eq. 12: plain and with the trace guard;
//! UD form: plain and guarded) and of the Hammerstein RLS, in f32 and f64, beside the no_std peer
//! `oxictl` 0.1.1 (`sysid::arx::RecursiveArx`) measured in the same run on the same data.
//!
//! Data (`common`): 1e6 samples of the second-order ARX system
//! y(t) = 1.5 y(t−1) − 0.7 y(t−2) + u(t−1) + 0.5 u(t−2) + 0.1 e(t), with u, e white N(0, 1). Regressors
//! φ(t) = [−y(t−1), …, −y(t−na), u(t−1), …, u(t−nb)], the peer's own regressor for (NA, NB, NK = 1):
//! n = 4 is (na, nb) = (2, 2), n = 9 is (4, 5). λ = 0.98, P(0) = 1000 I for both. The peer builds φ
//! itself from its delay lines; ours gets it from the benchmark
//! loop, which builds it from the record (comparable work: n moves).
//!
//! Guard cases: `guard` and `ud-guard` have T = p0 · n (the `identify --windup trace` default; on this
//! data it is active only at the start), `guard-active` and `ud-guard-active` have T = ½ the trace the
//! unguarded estimator reaches, so that they keep P near the bound and rescale it on most updates (the
//! guard's worst case, which sets the update's worst-case time on a controller). On this record the UD
//! guard then acts on 84 % of updates at n = 4 and 77 % at n = 9, and its decision changes on 13–14 % of
//! them (issue 28, fifteenth round).
//!
//! Run: `cargo bench -p ipa-embedded --bench rls -- --warm-up-time 1 --measurement-time 3`, then
//! `python3 crates/embedded/benches/best_of.py` for the best and median sample of each benchmark.
//! Criterion runs one benchmark after another, seconds apart: on a shared host whose speed changes for
//! seconds at a time, compare two of them through `interleaved.rs` (ours and the peer in turns of 200
//! updates, the states moved through 64 offsets modulo 4096), or check `sample.json` for slow stretches.

#![allow(clippy::unwrap_used, clippy::expect_used, missing_docs)] // benches may panic

use std::hint::black_box;

use criterion::measurement::WallTime;
use criterion::{criterion_group, criterion_main, BenchmarkGroup, BenchmarkId, Criterion};
use ipa_embedded::hammerstein::{HammersteinRls, HammersteinSettings};
use ipa_embedded::{Float, Form};
use oxictl::sysid::arx::RecursiveArx;

mod common;
use common::{arx_record, hammerstein_record, new_rls, regressor, LAMBDA, P0, SAMPLES};

/// Our estimator's variants: (label, form, trace bound).
fn variants(n: usize, active_trace: f64) -> [(&'static str, Form, Option<f64>); 6] {
    let t = P0 * n as f64;
    [
        ("plain", Form::Standard, None),
        ("guard", Form::Standard, Some(t)),
        ("guard-active", Form::Standard, Some(active_trace)),
        ("ud", Form::Ud, None),
        ("ud-guard", Form::Ud, Some(t)),
        ("ud-guard-active", Form::Ud, Some(active_trace)),
    ]
}

/// `v` as F (only `Float` in scope: `oxictl`'s scalar trait has methods of the same names).
fn cv<F: Float>(v: f64) -> F {
    F::from_f64(v)
}

/// `v` as f64.
fn back<F: Float>(v: F) -> f64 {
    v.to_f64()
}

/// One group per (type, n): ours in every variant and the peer, on the same record.
fn arx_case<F, const NA: usize, const NB: usize, const P: usize, const UBN: usize>(
    c: &mut Criterion,
    name: &str,
    u64_: &[f64],
    y64: &[f64],
) where
    F: Float + oxictl::core::scalar::ControlScalar,
{
    let u: Vec<F> = u64_.iter().map(|v| cv::<F>(*v)).collect();
    let y: Vec<F> = y64.iter().map(|v| cv::<F>(*v)).collect();
    let start = NA.max(NB);
    // The trace the unguarded estimator settles at, and agreement with the peer over 1e5 samples.
    let mut ours = new_rls::<F, P>(Form::Standard, None);
    let mut peer = RecursiveArx::<F, NA, NB, P, 1, UBN>::new(cv::<F>(LAMBDA), cv::<F>(P0));
    for t in 0..100_000 {
        if t >= start {
            ours.update(&regressor::<F, NA, NB, P>(&u, &y, t), y[t])
                .unwrap();
        }
        peer.update(y[t], u[t]).unwrap();
    }
    let m = peer.model();
    let theirs: Vec<f64> = m.a.iter().chain(m.b.iter()).map(|v| back(*v)).collect();
    let diff = ours
        .theta()
        .iter()
        .zip(&theirs)
        .map(|(a, b)| (back(*a) - b).abs())
        .fold(0.0, f64::max);
    let active = 0.5 * back(ours.trace());
    eprintln!(
        "{name}: after 1e5 samples max |θ_ours − θ_oxictl| = {diff:.1e}, θ = {:?}; tr P = {:.3e}",
        &theirs,
        back(ours.trace())
    );
    // Subnormal operands slow floating point down on many cores: the smallest nonzero magnitude in
    // θ̂ and P over the rest of the record, against the type's smallest normal number.
    let mut smallest = f64::INFINITY;
    for t in 100_000..SAMPLES {
        ours.update(&regressor::<F, NA, NB, P>(&u, &y, t), y[t])
            .unwrap();
        let p_entries = (0..P * P).map(|k| ours.p(k / P, k % P));
        smallest = ours
            .theta()
            .iter()
            .copied()
            .chain(p_entries)
            .map(|v| back(v).abs())
            .filter(|v| *v > 0.0)
            .fold(smallest, f64::min);
    }
    let min_normal = if core::mem::size_of::<F>() == 4 {
        f64::from(f32::MIN_POSITIVE)
    } else {
        f64::MIN_POSITIVE
    };
    eprintln!(
        "{name}: smallest nonzero |θ̂_i|, |P_ij| over the record {smallest:.2e} (smallest normal {min_normal:.2e}): {}",
        if smallest < min_normal { "SUBNORMAL" } else { "no subnormals" }
    );

    let mut g = c.benchmark_group(name);
    for (label, form, trace) in variants(P, active) {
        g.bench_function(BenchmarkId::new("ipa-embedded", label), |b| {
            let mut est = new_rls::<F, P>(form, trace);
            let mut t = start;
            b.iter(|| {
                let phi = regressor::<F, NA, NB, P>(&u, &y, t);
                let r = est.update(black_box(&phi), y[t]);
                t += 1;
                if t == SAMPLES {
                    t = start;
                }
                black_box(r.unwrap())
            })
        });
    }
    g.bench_function(BenchmarkId::new("oxictl", "plain"), |b| {
        let mut est = RecursiveArx::<F, NA, NB, P, 1, UBN>::new(cv::<F>(LAMBDA), cv::<F>(P0));
        let mut t = 0;
        b.iter(|| {
            let r = est.update(black_box(y[t]), u[t]);
            t += 1;
            if t == SAMPLES {
                t = 0;
            }
            r.unwrap();
        })
    });
    g.finish();
}

fn hammerstein_case<F: Float>(g: &mut BenchmarkGroup<'_, WallTime>, u64_: &[f64], y64: &[f64]) {
    let u: Vec<F> = u64_.iter().map(|v| F::from_f64(*v)).collect();
    let y: Vec<F> = y64.iter().map(|v| F::from_f64(*v)).collect();
    for (label, form) in [("standard", Form::Standard), ("ud", Form::Ud)] {
        let mut s = HammersteinSettings::<F>::paper().from_record(&u);
        s.forgetting = F::from_f64(LAMBDA);
        s.p0 = F::from_f64(P0);
        s.form = form;
        // Every sample of the record must be a real update (an error would leave the state as it was
        // and time a shorter path).
        let mut check = HammersteinRls::<F, 7, 3>::new(s).unwrap();
        let errors = u
            .iter()
            .zip(&y)
            .filter(|(uk, yk)| check.update(**uk, **yk).is_err())
            .count();
        let ty = core::any::type_name::<F>();
        eprintln!(
            "hammerstein {ty} {label}: {errors} failed updates in 1e6 samples; deadzone {:?}",
            check.deadzone()
        );
        g.bench_function(BenchmarkId::new(format!("{ty}-n7"), label), |b| {
            let mut est = HammersteinRls::<F, 7, 3>::new(s).unwrap();
            let mut t = 0;
            b.iter(|| {
                let r = est.update(black_box(u[t]), y[t]);
                t += 1;
                if t == SAMPLES {
                    t = 0;
                }
                black_box(r)
            })
        });
    }
}

fn benches(c: &mut Criterion) {
    let (u, y) = arx_record();
    arx_case::<f64, 2, 2, 4, 3>(c, "f64-n4", &u, &y);
    arx_case::<f64, 4, 5, 9, 6>(c, "f64-n9", &u, &y);
    arx_case::<f32, 2, 2, 4, 3>(c, "f32-n4", &u, &y);
    arx_case::<f32, 4, 5, 9, 6>(c, "f32-n9", &u, &y);
    let (u, y) = hammerstein_record();
    let mut g = c.benchmark_group("hammerstein");
    hammerstein_case::<f64>(&mut g, &u, &y);
    hammerstein_case::<f32>(&mut g, &u, &y);
    g.finish();
}

criterion_group!(rls, benches);
criterion_main!(rls);
