//! Time oracle (issue 25): what a plant allows in time for a set-point step from rest, whatever the
//! controller: a lower bound on the 2 % settling time and on the 10–90 % rise time, and the best
//! settling time of a family of open-loop command sequences. Not a controller: it knows the step and
//! runs the plant open loop (docs/control.md, "How fast can any command settle? (the time oracle)").
//!
//! For a step from rest at y0 to r (d = sign(r − y0), step |r − y0|, band b = 2 % of the step):
//! - **full command**: u(k) = d u_max at every sample. Its first entry into the band, t_b (the
//!   first time d (y − y0) reaches |r − y0| − b, interpolated as [`StepMetrics`] interpolates), and its
//!   rise time t_90 − t_10 (levels p |r − y0|) are the lower bounds: *argued*, not proved, that no
//!   command sequence within ±u_max enters the band earlier or rises faster (the valve flow into the
//!   driving chamber grows with |u| and the flow out of the other with it, so the full command raises
//!   the driving pressure difference fastest; friction opposes motion whatever the command). Any 2 %
//!   settling time is at least the first entry into the band.
//! - **bang-bang family**: u = d u_max for T1 samples (the last of them at a fraction a1 of u_max),
//!   −a2 d u_max for T2 samples, then 0 (valves closed) to the end of the run; T1 ≥ 1, T2 ≥ 0 on the
//!   sampling grid, a1 and a2 from [`FamilySearch`]. A sequence counts when the
//!   run ends within the band around r; its settling time is [`StepMetrics`]' (the same metric as the
//!   verification's). The best over the family is an *achievable* settling time (an upper bound on the
//!   best possible one), reported also under the overshoot limit and with a landing within e_max.
//!
//! Timing is the closed loop's ([`crate::closed_loop`]): y(k) is read, then u(k) applied for one Ts.

use sysid_core::Plant;

use crate::metrics::{first_reach, RISE_HIGH, RISE_LOW, SETTLING_BAND};
use crate::{ControlError, StepMetrics};

/// A step from rest: start y0 and set-point r (mm), command limit u_max (counts), run length in samples
/// (the first at t = 0, as the closed loop records them).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StepRun {
    /// y0: start (rest), mm.
    pub y0_mm: f64,
    /// r: set-point, mm.
    pub r_mm: f64,
    /// u_max: command limit, counts.
    pub u_max: f64,
    /// N: samples of the run (t = 0, Ts, …, (N − 1) Ts).
    pub samples: usize,
}

impl StepRun {
    fn direction(&self) -> f64 {
        (self.r_mm - self.y0_mm).signum()
    }
    fn step_mm(&self) -> f64 {
        (self.r_mm - self.y0_mm).abs()
    }
    /// b: the settling band's half width, 2 % of |r − y0|, mm.
    pub fn band_mm(&self) -> f64 {
        SETTLING_BAND * self.step_mm()
    }
}

/// Times of a response against a step (all measured from t = 0, interpolated between samples).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Reach {
    /// The first time y enters the band r ∓ b from the start's side, s.
    pub band_entry_s: Option<f64>,
    /// t_90 − t_10 with the levels y0 + p (r − y0), s.
    pub rise_s: Option<f64>,
}

/// [`Reach`] of the response `y` (one sample per Ts from t = 0) for the step `run`.
pub fn reach(ts_s: f64, y: &[f64], run: &StepRun) -> Reach {
    let t: Vec<f64> = (0..y.len()).map(|k| k as f64 * ts_s).collect();
    let d = run.direction();
    let z = |k: usize| d * (y[k] - run.y0_mm);
    let step = run.step_mm();
    let at = |level: f64| first_reach(&t, &z, level);
    Reach {
        band_entry_s: at(step - run.band_mm()),
        rise_s: at(RISE_HIGH * step)
            .zip(at(RISE_LOW * step))
            .map(|(hi, lo)| hi - lo),
    }
}

/// The measured outputs y(0..N) of `plant` reset to rest at y0 and driven by u(k) = `command(k)`.
pub fn response(
    plant: &mut dyn Plant,
    run: &StepRun,
    command: &dyn Fn(usize) -> f64,
) -> Result<Vec<f64>, ControlError> {
    plant.reset(run.y0_mm);
    let mut y = Vec::with_capacity(run.samples);
    for k in 0..run.samples {
        y.push(plant.output());
        step(plant, command(k), k)?;
    }
    Ok(y)
}

fn step(plant: &mut dyn Plant, u: f64, k: usize) -> Result<(), ControlError> {
    plant
        .step(u)
        .map_err(|e| ControlError::Numerical(format!("sample {k}: {e}")))?;
    let y = plant.output();
    if y.is_finite() {
        Ok(())
    } else {
        Err(ControlError::Numerical(format!(
            "the output of {} is {y} after sample {k}",
            plant.name()
        )))
    }
}

/// The lower bounds: [`reach`] of the full command d u_max from rest.
pub fn full_command_bound(plant: &mut dyn Plant, run: &StepRun) -> Result<Reach, ControlError> {
    let u = run.direction() * run.u_max;
    let y = response(plant, run, &|_| u)?;
    Ok(reach(plant.ts(), &y, run))
}

/// One sequence of the bang-bang family and what it gave.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BangBang {
    /// T1: samples of command towards r (full, the last at a1 u_max).
    pub t1: usize,
    /// a1: the fraction of u_max of the last of the T1 samples.
    pub a1: f64,
    /// T2: samples of reverse command after them.
    pub t2: usize,
    /// a2: the reverse command's fraction of u_max.
    pub a2: f64,
    /// Its metrics (the run ends within the band around r, so t_s is centred on r).
    pub metrics: StepMetrics,
}

/// The best sequences of the family (smallest settling time; ties: the first found, smallest T1 then T2).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct FamilyBest {
    /// Best of all sequences that end within the band.
    pub any: Option<BangBang>,
    /// Best of those whose overshoot ≤ the limit.
    pub overshoot_ok: Option<BangBang>,
    /// Best of those whose overshoot ≤ the limit and |e_ss| ≤ e_max.
    pub landed: Option<BangBang>,
    /// The shortest rise time of those whose overshoot ≤ the limit.
    pub fastest_rise: Option<BangBang>,
    /// Of the sequences ending in the band whose rise time is below [`FamilySearch::rise_below_s`],
    /// the one with the least overshoot.
    pub least_overshoot_faster: Option<BangBang>,
    /// Sequences simulated.
    pub sequences: usize,
    /// The earliest first entry into the band of any sequence simulated, s (a check of the bound).
    pub earliest_entry_s: Option<f64>,
}

/// How the family is searched.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FamilySearch {
    /// OS_max, % of the step (for [`FamilyBest::overshoot_ok`]).
    pub overshoot_percent: f64,
    /// e_max, mm (for [`FamilyBest::landed`]).
    pub ess_mm: f64,
    /// Stop simulating a tail (valves closed) once the output has not changed for this many samples
    /// and hold it there (None: simulate every tail to the end of the run). With the valves closed
    /// both chambers exhaust, so a piston at rest stays at rest: this only saves time.
    pub rest_samples: Option<usize>,
    /// a1: fractions of u_max tried for the last sample of the first phase (1 = full).
    pub last_fractions: &'static [f64],
    /// a2: fractions of u_max tried for the reverse phase.
    pub reverse_fractions: &'static [f64],
    /// A rise time, s: report the least overshoot of the sequences that rise faster than it
    /// ([`FamilyBest::least_overshoot_faster`]; e.g. the paper's PI's rise time).
    pub rise_below_s: Option<f64>,
}

/// Searches T1 = 1, 2, … and, for each, T2 = 0, 1, … exhaustively on the sampling grid, with two
/// cuts that cannot lose a better sequence of the ones reported: T2 stops growing once the reverse
/// command has the piston moving away from r outside the band on the start's side (more reverse
/// cannot bring it back; it ends outside the band), and T1 stops once the full command has passed
/// the far band edge by more than the overshoot limit allows (and than the least overshoot of the
/// sequences rising faster than [`FamilySearch::rise_below_s`], when given) and its time exceeds the
/// best settling time found (every later T1 is outside the band then).
pub fn bang_bang<P: Plant + Clone>(
    plant: &P,
    run: &StepRun,
    search: &FamilySearch,
) -> Result<FamilyBest, ControlError> {
    let ts = plant.ts();
    let n = run.samples;
    let d = run.direction();
    let (step_mm, band) = (run.step_mm(), run.band_mm());
    let t: Vec<f64> = (0..n).map(|k| k as f64 * ts).collect();
    let mut best = FamilyBest::default();
    let mut base = plant.clone();
    base.reset(run.y0_mm);
    let mut y_full: Vec<f64> = Vec::with_capacity(n);
    for t1 in 1..n {
        y_full.push(base.output());
        for &a1 in search.last_fractions {
            let mut last = base.clone();
            step(&mut last, d * a1 * run.u_max, t1 - 1)?;
            for &a2 in search.reverse_fractions {
                let seq = Sequence { t1, a1, t2: 0, a2 };
                reverse_then_rest(&mut best, &t, &last, &y_full, run, search, seq)?;
            }
        }
        step(&mut base, d * run.u_max, t1 - 1)?;
        let z = d * (base.output() - run.y0_mm);
        let far = step_mm + band;
        // Every later T1 ends (within the band) with at least this overshoot, %.
        let os_floor = 100.0 * (z - far) / far;
        let least_faster = match search.rise_below_s {
            None => Some(f64::NEG_INFINITY),
            Some(_) => best
                .least_overshoot_faster
                .and_then(|b| b.metrics.overshoot_percent),
        };
        let past =
            os_floor > search.overshoot_percent && least_faster.is_some_and(|o| os_floor > o);
        let late = best
            .any
            .and_then(|b| b.metrics.settling_time_s)
            .is_some_and(|s| t1 as f64 * ts >= s);
        if past && late {
            break;
        }
    }
    Ok(best)
}

/// The shape of one sequence (its T2 filled in as it grows).
#[derive(Clone, Copy)]
struct Sequence {
    t1: usize,
    a1: f64,
    t2: usize,
    a2: f64,
}

/// From `last` (the plant after the first phase, outputs `y_first`), T2 = 0, 1, … samples of reverse
/// command a2 u_max, each followed by a tail of u = 0 to the end of the run.
fn reverse_then_rest<P: Plant + Clone>(
    best: &mut FamilyBest,
    t: &[f64],
    last: &P,
    y_first: &[f64],
    run: &StepRun,
    search: &FamilySearch,
    seq: Sequence,
) -> Result<(), ControlError> {
    let n = run.samples;
    let d = run.direction();
    let (step_mm, band) = (run.step_mm(), run.band_mm());
    let mut rev = last.clone();
    let mut y_rev = y_first.to_vec();
    y_rev.push(last.output());
    for t2 in 0..=n.saturating_sub(seq.t1) {
        if t2 > 0 {
            step(&mut rev, -d * seq.a2 * run.u_max, seq.t1 + t2 - 1)?;
            y_rev.push(rev.output());
        }
        if y_rev.len() > n || (t2 > 0 && seq.a2 == 0.0) {
            break;
        }
        // y_rev holds y(0..=t1+t2): the last is the output the tail starts from.
        let mut tail = rev.clone();
        let mut y = y_rev.clone();
        let mut still = 0;
        while y.len() < n {
            step(&mut tail, 0.0, y.len() - 1)?;
            let yk = tail.output();
            still = if y.last() == Some(&yk) { still + 1 } else { 0 };
            y.push(yk);
            if search.rest_samples.is_some_and(|m| still >= m) {
                y.resize(n, yk);
            }
        }
        y.truncate(n);
        best.sequences += 1;
        consider(best, t, &y, run, search, Sequence { t2, ..seq })?;
        let z = d * (rev.output() - run.y0_mm);
        let moving_back =
            y_rev.len() >= 2 && d * (y_rev[y_rev.len() - 1] - y_rev[y_rev.len() - 2]) < 0.0;
        if t2 > 0 && z < step_mm - band && moving_back {
            break;
        }
    }
    Ok(())
}

fn consider(
    best: &mut FamilyBest,
    t: &[f64],
    y: &[f64],
    run: &StepRun,
    search: &FamilySearch,
    seq: Sequence,
) -> Result<(), ControlError> {
    let ts = t.get(1).copied().unwrap_or(0.0);
    if let Some(e) = reach(ts, y, run).band_entry_s {
        best.earliest_entry_s = Some(best.earliest_entry_s.map_or(e, |b: f64| b.min(e)));
    }
    let y_f = y[y.len() - 1];
    if (run.r_mm - y_f).abs() > run.band_mm() {
        return Ok(());
    }
    let metrics = StepMetrics::compute(t, y, run.y0_mm, run.r_mm)?;
    let Some(ts_new) = metrics.settling_time_s else {
        return Ok(());
    };
    let candidate = BangBang {
        t1: seq.t1,
        a1: seq.a1,
        t2: seq.t2,
        a2: seq.a2,
        metrics,
    };
    let better = |slot: &Option<BangBang>| {
        slot.and_then(|b| b.metrics.settling_time_s)
            .is_none_or(|s| ts_new < s)
    };
    if better(&best.any) {
        best.any = Some(candidate);
    }
    let os_ok = metrics
        .overshoot_percent
        .is_some_and(|os| os <= search.overshoot_percent);
    if os_ok && better(&best.overshoot_ok) {
        best.overshoot_ok = Some(candidate);
    }
    let lands = metrics
        .steady_state_error_mm
        .is_some_and(|e| e.abs() <= search.ess_mm + crate::tune::ROUNDING_MM);
    if os_ok && lands && better(&best.landed) {
        best.landed = Some(candidate);
    }
    let faster = best
        .fastest_rise
        .and_then(|b| b.metrics.rise_time_s)
        .is_none_or(|r| metrics.rise_time_s.is_some_and(|x| x < r));
    if os_ok && metrics.rise_time_s.is_some() && faster {
        best.fastest_rise = Some(candidate);
    }
    let rises_faster = metrics
        .rise_time_s
        .zip(search.rise_below_s)
        .is_some_and(|(r, below)| r < below);
    let less = |b: BangBang| b.metrics.overshoot_percent < metrics.overshoot_percent;
    if rises_faster && !best.least_overshoot_faster.is_some_and(less) {
        best.least_overshoot_faster = Some(candidate);
    }
    Ok(())
}
