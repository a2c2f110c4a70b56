//! Time oracle for issue 25's time targets (docs/control.md, "How fast can any command settle? (the
//! time oracle)"), on the verification's 168 runs of `ipa-sysid tune --check-physics` (the physics
//! plant nominal + variants ±30 %, seeds 1..=20; the default specification's 8 steps, 3 s runs):
//! per run the lower bounds of the 2 % settling time (first entry into the band under the full
//! command) and of the 10–90 % rise time, the best settling time of the bang-bang family (full
//! command T1 samples, full reverse T2 samples, valves closed), and the settling times of a
//! controller file and of the paper's PI on the same run ([`control::oracle`]). Then the counts, a
//! check of the bound against other command shapes and the closed loops, and Table V's nominal 50 mm
//! step (0 → 50 mm).
//!
//! `cargo run --release -p control --example time_oracle -- [CONTROLLER.json] [VARIANT...]`, or
//! `scripts/time_oracle.sh`. ROWS=1 prints a line per run; FULL_TAIL=1 simulates every tail to the end
//! of the run (default: a tail whose output has not changed for 30 samples is held there).
#![allow(clippy::unwrap_used, clippy::expect_used, missing_docs)] // tests, benches and examples may panic

use control::oracle::{self, FamilyBest, FamilySearch, Reach, StepRun};
use control::tune::Spec;
use control::{closed_loop, Controller, ControllerFile, PiSettings, Profile, StepMetrics};
use rayon::prelude::*;

const TS: f64 = 0.01;

fn plant(v: usize) -> ipa::Ipa {
    let base = ipa::PlantConfig::default();
    let cfg = if v == 0 {
        base
    } else {
        ipa::calibrate::study::perturbed_from(&base, v as u64, 0.3)
    };
    ipa::Ipa::with_ts(cfg, TS).unwrap()
}

/// A closed-loop run: its metrics (as the verification computes them) and its [`Reach`].
struct Loop {
    metrics: StepMetrics,
    reach: Reach,
    /// Samples at |u| = u_max before y first reaches 90 % of the step.
    saturated: usize,
}

fn closed(v: usize, c: &mut dyn Controller, run: &StepRun, duration_s: f64) -> Loop {
    let mut p = plant(v);
    let profile = Profile::Fixed {
        setpoint_mm: run.r_mm,
    };
    let tr = closed_loop::run(&mut p, c, None, &profile, duration_s, run.y0_mm).unwrap();
    let (metrics, _) = StepMetrics::assess(&tr.t, &tr.y, Some(&tr.u), run.y0_mm, run.r_mm).unwrap();
    let d = (run.r_mm - run.y0_mm).signum();
    let k90 =
        tr.y.iter()
            .position(|y| d * (y - run.y0_mm) >= 0.9 * (run.r_mm - run.y0_mm).abs())
            .unwrap_or(tr.len());
    Loop {
        metrics,
        reach: oracle::reach(TS, &tr.y, run),
        saturated: tr.u[..k90]
            .iter()
            .filter(|u| u.abs() >= run.u_max - 1e-9)
            .count(),
    }
}

/// Other command shapes towards r (none should enter the band earlier or rise faster than the full
/// command): constant fractions of u_max, ramps to u_max over a few samples, one sample of delay, one
/// sample of reverse first.
type Shape = (String, Box<dyn Fn(usize) -> f64 + Sync>);

fn shapes(u_max: f64) -> Vec<Shape> {
    let mut v: Vec<Shape> = Vec::new();
    for f in [0.5, 0.75, 0.9, 0.97] {
        v.push((format!("const {f}"), Box::new(move |_| f * u_max)));
    }
    for w in [2usize, 5, 10] {
        v.push((
            format!("ramp over {w}"),
            Box::new(move |k| u_max * ((k + 1) as f64 / w as f64).min(1.0)),
        ));
    }
    v.push((
        "delay 1".into(),
        Box::new(move |k| if k == 0 { 0.0 } else { u_max }),
    ));
    v.push((
        "reverse 1".into(),
        Box::new(move |k| if k == 0 { -u_max } else { u_max }),
    ));
    v
}

struct Row {
    v: usize,
    run: StepRun,
    bound: Reach,
    family: FamilyBest,
    tuned: Option<Loop>,
    pi: Loop,
    /// Shapes and loops that entered the band earlier than the full command (refutations).
    refuted: Vec<String>,
    /// The most by which a shape's rise time beat the full command's, s (0: none did).
    rise_beaten: f64,
}

fn tuned_of(r: &Row) -> Option<&Loop> {
    r.tuned.as_ref()
}

fn pi_of(r: &Row) -> Option<&Loop> {
    Some(&r.pi)
}

/// "T1 …, a1 …, T2 …, a2 …" of a family's sequence, or "none".
fn sequence(b: Option<oracle::BangBang>) -> String {
    b.map_or("none".into(), |b| {
        format!("T1 {}, a1 {}, T2 {}, a2 {}", b.t1, b.a1, b.t2, b.a2)
    })
}

fn fmt(x: Option<f64>) -> String {
    x.map_or("—".into(), |x| format!("{x:.3}"))
}

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let file = args
        .iter()
        .find(|a| a.ends_with(".json"))
        .map(|a| ControllerFile::parse(&std::fs::read_to_string(a).unwrap(), a).unwrap());
    let mut variants: Vec<usize> = args
        .iter()
        .filter(|a| !a.ends_with(".json"))
        .map(|a| a.parse().expect("variant numbers"))
        .collect();
    if variants.is_empty() {
        variants = (0..=20).collect();
    }
    let spec = Spec::default();
    let samples = (spec.run_s / TS + 1e-9).floor() as usize + 1;
    let search = FamilySearch {
        overshoot_percent: spec.overshoot_percent,
        ess_mm: spec.ess_mm,
        rest_samples: if std::env::var("FULL_TAIL").is_ok() {
            None
        } else {
            Some(30)
        },
        last_fractions: &[1.0, 0.9, 0.8, 0.7, 0.6, 0.5, 0.4, 0.3, 0.2, 0.1],
        reverse_fractions: &[1.0, 0.75, 0.5, 0.25],
        rise_below_s: None,
    };
    let jobs: Vec<(usize, StepRun)> = variants
        .iter()
        .flat_map(|&v| {
            spec.cases().into_iter().map(move |c| {
                (
                    v,
                    StepRun {
                        y0_mm: c.y0_mm,
                        r_mm: c.r_mm,
                        u_max: spec.u_max,
                        samples,
                    },
                )
            })
        })
        .collect();
    let shapes = shapes(spec.u_max);
    let rows: Vec<Row> = jobs
        .par_iter()
        .map(|&(v, run)| {
            let p = plant(v);
            let bound = oracle::full_command_bound(&mut p.clone(), &run).unwrap();
            let family = oracle::bang_bang(&p, &run, &search).unwrap();
            let tuned = file.map(|s| {
                let mut c = s.build().unwrap();
                closed(v, &mut c, &run, spec.run_s)
            });
            let mut pi = PiSettings::paper().build(TS).unwrap();
            let pi = closed(v, &mut pi, &run, spec.run_s);
            let d = (run.r_mm - run.y0_mm).signum();
            let below = |x: Option<f64>, lb: Option<f64>| match (x, lb) {
                (Some(x), Some(lb)) => x < lb - 1e-9,
                (Some(_), None) => true,
                _ => false,
            };
            let mut refuted = Vec::new();
            let mut rise_beaten = 0.0f64;
            for (name, u) in &shapes {
                let y = oracle::response(&mut p.clone(), &run, &|k| d * u(k)).unwrap();
                let r = oracle::reach(TS, &y, &run);
                if below(r.band_entry_s, bound.band_entry_s) {
                    refuted.push(format!("{name}: band entry {}", fmt(r.band_entry_s)));
                }
                if below(r.rise_s, bound.rise_s) {
                    rise_beaten =
                        rise_beaten.max(bound.rise_s.unwrap_or(f64::INFINITY) - r.rise_s.unwrap());
                }
            }
            for (name, l) in [("tuned", tuned.as_ref()), ("PI", Some(&pi))] {
                if let Some(l) = l {
                    if below(l.reach.band_entry_s, bound.band_entry_s) {
                        refuted.push(format!("{name}: band entry {}", fmt(l.reach.band_entry_s)));
                    }
                }
            }
            if below(family.earliest_entry_s, bound.band_entry_s) {
                refuted.push(format!(
                    "family: band entry {}",
                    fmt(family.earliest_entry_s)
                ));
            }
            Row {
                v,
                run,
                bound,
                family,
                tuned,
                pi,
                refuted,
                rise_beaten,
            }
        })
        .collect();

    let target = spec.settling_s;
    let ts_of = |b: Option<oracle::BangBang>| b.and_then(|b| b.metrics.settling_time_s);
    let within = |x: Option<f64>| x.is_some_and(|x| x <= target);
    if std::env::var("ROWS").is_ok() {
        println!(
            "variant y0 -> r | bound: band entry, rise | bang-bang t_s: any (T1,a1,T2,a2), OS ok, landed | tuned t_s (entry) | PI t_s (entry)"
        );
        for r in &rows {
            let b = |x: Option<oracle::BangBang>| {
                x.map_or("—".into(), |x| {
                    format!(
                        "{} ({},{},{},{})",
                        fmt(x.metrics.settling_time_s),
                        x.t1,
                        x.a1,
                        x.t2,
                        x.a2
                    )
                })
            };
            println!(
                "{:2} {:5.0} -> {:5.0} | {} {} | {} {} {} | {} ({}) | {} ({}) {}",
                r.v,
                r.run.y0_mm,
                r.run.r_mm,
                fmt(r.bound.band_entry_s),
                fmt(r.bound.rise_s),
                b(r.family.any),
                b(r.family.overshoot_ok),
                b(r.family.landed),
                fmt(r.tuned.as_ref().and_then(|l| l.metrics.settling_time_s)),
                fmt(r.tuned.as_ref().and_then(|l| l.reach.band_entry_s)),
                fmt(r.pi.metrics.settling_time_s),
                fmt(r.pi.reach.band_entry_s),
                r.refuted.join("; ")
            );
        }
    }
    let n = rows.len();
    let count = |f: &dyn Fn(&Row) -> bool| rows.iter().filter(|r| f(r)).count();
    let impossible = count(&|r| !within(r.bound.band_entry_s));
    let any = count(&|r| within(ts_of(r.family.any)));
    let os_ok = count(&|r| within(ts_of(r.family.overshoot_ok)));
    let landed = count(&|r| within(ts_of(r.family.landed)));
    println!(
        "runs {n}; settling target {target} s; sequences simulated {}",
        rows.iter().map(|r| r.family.sequences).sum::<usize>()
    );
    println!("t_s <= {target} s physically impossible (full command enters the band after {target} s): {impossible}");
    println!("t_s <= {target} s achieved by the bang-bang family: {any} (with OS <= {} %: {os_ok}; and |e_ss| <= {} mm too: {landed})", spec.overshoot_percent, spec.ess_mm);
    let loop_ok = |l: Option<&Loop>| {
        l.is_some_and(|l| {
            within(l.metrics.settling_time_s)
                && l.metrics
                    .overshoot_percent
                    .is_some_and(|os| os <= spec.overshoot_percent)
        })
    };
    let shown = count(&|r| {
        within(ts_of(r.family.overshoot_ok)) || loop_ok(r.tuned.as_ref()) || loop_ok(Some(&r.pi))
    });
    println!(
        "t_s <= {target} s with OS <= {} % shown achievable by the family, the tuned controller or the PI: {shown}; neither shown impossible nor achievable: {}",
        spec.overshoot_percent,
        n - impossible - shown
    );
    for (name, get) in [
        ("tuned", tuned_of as fn(&Row) -> Option<&Loop>),
        ("paper PI", pi_of),
    ] {
        if rows.iter().all(|r| get(r).is_none()) {
            continue;
        }
        let met = count(&|r| get(r).is_some_and(|l| within(l.metrics.settling_time_s)));
        let reachable = |r: &Row| within(ts_of(r.family.overshoot_ok));
        let missed =
            |r: &Row| reachable(r) && get(r).is_some_and(|l| !within(l.metrics.settling_time_s));
        let missed_n = count(&missed);
        let approach =
            count(&|r| missed(r) && get(r).is_some_and(|l| !within(l.reach.band_entry_s)));
        println!(
            "{name}: t_s <= {target} s in {met} runs; misses {missed_n} of the {os_ok} runs the family settles within {target} s (OS ok): {approach} in the approach (first band entry after {target} s), {} in the finish (entered by {target} s, settled later or not at all)",
            missed_n - approach
        );
    }
    let refuted: Vec<String> = rows
        .iter()
        .filter(|r| !r.refuted.is_empty())
        .map(|r| {
            format!(
                "variant {} {} -> {}: {}",
                r.v,
                r.run.y0_mm,
                r.run.r_mm,
                r.refuted.join("; ")
            )
        })
        .collect();
    println!(
        "band-entry bound checked against {} other shapes, the bang-bang sequences and the closed loops on every run: {} runs refute it",
        shapes.len(),
        refuted.len()
    );
    let beaten: Vec<&Row> = rows.iter().filter(|r| r.rise_beaten > 0.0).collect();
    println!(
        "full-command rise time beaten by another shape in {} runs, by at most {:.4} s (largest relative: {:.2} %)",
        beaten.len(),
        beaten.iter().map(|r| r.rise_beaten).fold(0.0, f64::max),
        beaten
            .iter()
            .map(|r| 100.0 * r.rise_beaten / r.bound.rise_s.unwrap())
            .fold(0.0, f64::max)
    );
    for l in refuted {
        println!("  {l}");
    }
    for step in spec.steps_mm.iter() {
        let sel: Vec<&Row> = rows
            .iter()
            .filter(|r| (r.run.r_mm - r.run.y0_mm).abs() == *step)
            .collect();
        let lo_hi = |f: &dyn Fn(&Row) -> Option<f64>| {
            let v: Vec<f64> = sel.iter().filter_map(|r| f(r)).collect();
            format!(
                "{:.3}–{:.3}",
                v.iter().copied().fold(f64::INFINITY, f64::min),
                v.iter().copied().fold(f64::NEG_INFINITY, f64::max)
            )
        };
        println!(
            "{step} mm steps ({} runs): band entry bound {} s, rise bound {} s, bang-bang t_s (OS ok) {} s, settled within {target} s: bang-bang {} / tuned {} / PI {}",
            sel.len(),
            lo_hi(&|r| r.bound.band_entry_s),
            lo_hi(&|r| r.bound.rise_s),
            lo_hi(&|r| ts_of(r.family.overshoot_ok)),
            sel.iter().filter(|r| within(ts_of(r.family.overshoot_ok))).count(),
            sel.iter().filter(|r| r.tuned.as_ref().is_some_and(|l| within(l.metrics.settling_time_s))).count(),
            sel.iter().filter(|r| within(r.pi.metrics.settling_time_s)).count(),
        );
    }

    // Table V: the nominal plant, 0 -> 50 mm (the paper's step test; the PI over 40 s as in Results).
    if variants.contains(&0) {
        let run = StepRun {
            y0_mm: 0.0,
            r_mm: 50.0,
            u_max: spec.u_max,
            samples,
        };
        let p = plant(0);
        let bound = oracle::full_command_bound(&mut p.clone(), &run).unwrap();
        let mut pi = PiSettings::paper().build(TS).unwrap();
        let pi = closed(0, &mut pi, &run, 40.0);
        let search = FamilySearch {
            rise_below_s: pi.metrics.rise_time_s,
            ..search
        };
        let family = oracle::bang_bang(&p, &run, &search).unwrap();
        let shape_rise = shapes
            .iter()
            .filter_map(|(_, u)| {
                let y = oracle::response(&mut p.clone(), &run, &|k| u(k)).unwrap();
                oracle::reach(TS, &y, &run).rise_s
            })
            .fold(f64::INFINITY, f64::min);
        let fr = family.fastest_rise;
        let lo = family.least_overshoot_faster;
        println!(
            "Table V: of the bang-bang sequences ending in the band that rise faster than the PI, the least overshoot is {} % ({}; rise {} s)",
            fmt(lo.and_then(|b| b.metrics.overshoot_percent)),
            sequence(lo),
            fmt(lo.and_then(|b| b.metrics.rise_time_s)),
        );
        println!(
            "Table V rise: full command {:.4} s, fastest other shape {shape_rise:.4} s, paper PI {:.4} s; fastest bang-bang with OS <= {} % ending in the band: {} s ({}; t_s {} s)",
            bound.rise_s.unwrap_or(f64::NAN),
            pi.metrics.rise_time_s.unwrap_or(f64::NAN),
            spec.overshoot_percent,
            fmt(fr.and_then(|b| b.metrics.rise_time_s)),
            sequence(fr),
            fmt(fr.and_then(|b| b.metrics.settling_time_s)),
        );
        println!(
            "Table V, nominal 0 -> 50 mm: bound: rise {} s, band entry {} s | paper PI (40 s): rise {} s, t_s {} s, OS {} %, at u_max in {} of the samples before 90 % | bang-bang: t_s {} s (OS ok {} s, landed {} s)",
            fmt(bound.rise_s),
            fmt(bound.band_entry_s),
            fmt(pi.metrics.rise_time_s),
            fmt(pi.metrics.settling_time_s),
            fmt(pi.metrics.overshoot_percent),
            pi.saturated,
            fmt(ts_of(family.any)),
            fmt(ts_of(family.overshoot_ok)),
            fmt(ts_of(family.landed)),
        );
        if let Some(s) = file {
            let mut c = s.build().unwrap();
            let l = closed(0, &mut c, &run, spec.run_s);
            println!(
                "  tuned (3 s): rise {} s, t_s {} s, OS {} %",
                fmt(l.metrics.rise_time_s),
                fmt(l.metrics.settling_time_s),
                fmt(l.metrics.overshoot_percent)
            );
        }
    }
}
