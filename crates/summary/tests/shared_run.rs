//! `shared_run` (audit s17 M-e: a record cut from another) against an independent, start-by-start
//! scan written here: the longest run, bit for bit, beginning at the head of one record and found in
//! the other, whose output moves.

#![allow(clippy::unwrap_used, missing_docs)] // tests may panic

use sysid::data::Signals;
use sysid::Dataset;
use sysid_summary::{shared_run, MIN_SHARED_SAMPLES};

/// A record's columns (u, y).
type Columns = (Vec<f64>, Vec<f64>);

fn record(u: Vec<f64>, y: Vec<f64>) -> Dataset {
    Dataset::new(Signals { u, y }, 0.01, "r").unwrap()
}

/// The plain scan: every start in each record, extended sample by sample.
fn naive(a: (&[f64], &[f64]), b: (&[f64], &[f64])) -> Option<(usize, usize, usize)> {
    let min = MIN_SHARED_SAMPLES.min(a.1.len()).min(b.1.len());
    if min < 10 {
        return None;
    }
    let eq = |i: usize, j: usize| {
        a.0[i].to_bits() == b.0[j].to_bits() && a.1[i].to_bits() == b.1[j].to_bits()
    };
    let mut best: Option<(usize, usize, usize)> = None;
    for head_of_b in [true, false] {
        let hay = if head_of_b { a.1.len() } else { b.1.len() };
        for s in 0..hay {
            let (i0, j0) = if head_of_b { (s, 0) } else { (0, s) };
            let mut n = 0;
            while i0 + n < a.1.len() && j0 + n < b.1.len() && eq(i0 + n, j0 + n) {
                n += 1;
            }
            let moves = (i0..i0 + n).any(|k| a.1[k] != a.1[i0]);
            if n >= min && moves && best.is_none_or(|(_, _, m)| n > m) {
                best = Some((i0, j0, n));
            }
        }
    }
    best
}

#[test]
fn cuts_splices_rests_and_strangers_agree_with_the_plain_scan() {
    // A record with a long rest (0, 0), a moving part, a rest again; values chosen to repeat.
    let mut u = vec![0.0; 120];
    let mut y = vec![0.0; 120];
    for k in 0..300 {
        u.push(((k * 7) % 5) as f64 - 2.0);
        y.push(((k * 3) % 11) as f64);
    }
    u.extend(vec![0.0; 80]);
    y.extend(vec![4.0; 80]);
    let n = u.len();
    let cut = |lo: usize, hi: usize| (u[lo..hi].to_vec(), y[lo..hi].to_vec());
    let other: Columns = (
        (0..200).map(|k| (k % 3) as f64).collect(),
        (0..200).map(|k| (k % 7) as f64 * 0.5).collect(),
    );
    let mut spliced = other.clone();
    spliced.0.extend_from_slice(&u[..250]);
    spliced.1.extend_from_slice(&y[..250]);
    let cases: Vec<(Columns, Columns)> = vec![
        ((u.clone(), y.clone()), cut(200, n)), // the later part cut out
        ((u.clone(), y.clone()), cut(0, 150)), // the head, mostly rest
        (cut(0, 130), cut(0, 125)),            // two rests: no run that moves
        (cut(100, 400), (u.clone(), y.clone())), // contained the other way
        ((u.clone(), y.clone()), spliced.clone()), // spliced after another record
        ((u.clone(), y.clone()), other.clone()), // a stranger
        (cut(0, 9), cut(0, 9)),                // too short to judge
    ];
    for (k, (a, b)) in cases.iter().enumerate() {
        let got = shared_run(
            &record(a.0.clone(), a.1.clone()),
            &record(b.0.clone(), b.1.clone()),
        );
        let want = naive((&a.0, &a.1), (&b.0, &b.1));
        assert_eq!(got, want, "case {k}");
    }
    // The cut from sample 200 is found whole: it starts at 200 in the record, at 0 in the cut.
    let a = &cases[0];
    let got = shared_run(
        &record(a.0 .0.clone(), a.0 .1.clone()),
        &record(a.1 .0.clone(), a.1 .1.clone()),
    );
    assert_eq!(got, Some((200, 0, n - 200)));
}
