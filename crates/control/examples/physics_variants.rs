//! Runs a controller file (CONTROLLER.json) through the verification of `ipa-sysid tune
//! --check-physics`: the physics plant, nominal + 20 variants ±30 % (seeds 1..=20), the default
//! specification's 8 steps (168 runs), and prints the counts of runs meeting each criterion. For
//! trying a change of one setting of a tuned controller (not a tuning: it runs on the true plants).
//!
//! `cargo run --release -p control --example physics_variants -- CONTROLLER.json [REST_BAND_MM]`
//! REST_BAND_MM replaces the nudge's rest band e_r; the environment variables GAMMA, BAND, RHO, BETA
//! replace γ, e_n, ρ, β; SHOW=1 lists the runs whose |e_ss| > 0.02 mm; TRACE=V,Y0,R prints the run of
//! variant V from Y0 to R (samples within 3 mm of R). APPROACH=τ_b,e_sw[,Q[,R]] wraps the controller
//! in a prototype approach mode (issue 25, session 12; not in the controller): full command towards r
//! from the step's start until |e| ≤ e_sw + τ_b |dy/dt| (moving towards r; Q = 1: τ_b (dy/dt)², τ_b
//! in s²/mm), then the controller for the rest of the run (it runs through the approach, its command
//! unused; R = 1: it restarts at the switch instead). Braking after the switch (issue 25, session
//! 14; prototypes, not in the controller): BRAKE=a_b reverses the command to −a_b u_max while the
//! piston still moves towards r, or for BRAKE_N=T samples (timed, the time oracle's T2);
//! BRAKE_HOLD=N (1 = 3) then closes the valves (u = 0) until y has not changed for N samples and restarts
//! the controller; SLIDE=H replaces the switch by a switching line (full command while |e| > e_sw +
//! τ_b |dy/dt|, −a_b u_max below it) until |e| ≤ H mm (with BRAKE_HOLD: inside H only the brake, while
//! τ_b |dy/dt| > |e|, until rest); APPROACH_MIN=mm limits the approach to steps of at least that size,
//! APPROACH_DIR=1 (−1) to steps up (down). ROWS=1 prints a line per run (plant, y0, r, e_ss, OS %,
//! t_s, limit cycle); TRACE_MM=W widens TRACE's window to W mm. BRAKE_CTL=e_a,e_s,τ_b,a_b,T_b,N_b sets
//! the controller's own approach with braking (`brake` of CONTROLLER.json). TWIN=TWIN.toml runs on the twin and its tuning draws (seeds 1001..,
//! `tune --plant-config`'s plants: for choosing a setting without the true plants) instead;
//! SEED_OFFSET=K draws the variants with seeds K+1.. instead (e.g. TWIN=twin.toml SEED_OFFSET=2000: a
//! family of twins neither the search nor the verification uses); PLANTS=N runs N plants (default 21);
//! COST=1 also prints the tuning cost J of the runs (their mean run cost) and the largest run cost.
//! BRAKE_CTL=...,κ_b,τ_max[,T_r] adds the learnt lead (`brake.learn`, `brake.lead_max_s`) and the
//! release (`brake.release_samples`; issue 25, session 15); BRAKE_RAMP=N lowers the prototype's timed
//! brake (BRAKE_N) to 0 over N samples; LEADS=1 prints, per variant and 150 mm step, OS, t_s, e_ss and
//! the learnt τ_b after each of 3 repeated moves; WARMUP=N makes N runs of the same step before each measured one, the controller
//! keeping what it learnt (a machine that repeats its moves; `tune::evaluate_repeated`).
//! Session 16: NR=N replaces the nudge's rest count N_r; APPROACH_MAX=mm limits the prototype approach
//! to steps of at most that size, APPROACH_U=U drives it at U u_max instead of u_max, APPROACH_RAMP=c
//! raises that drive by c counts per sample until the piston first moves (the short-step approach of
//! docs/control.md, Results' session-16 block).
//! Session 17: SHORT_CTL=e_m,U,ρ_a,e_s',τ_s,a_s,T_s,N_s sets the controller's own short-step approach
//! (`short_approach` of CONTROLLER.json; e_m = 0 removes it).
//! Session 18: CREEP=e_v replaces ramp-and-cut's creep limit (`nudge.creep_step_mm`, mm per sample;
//! 0 = off: cut at the first count).
//! SHORT_EM=mm replaces the file's short-step range e_m (`max_step_mm`).
//! Session 19: PHASES=1 prints a line per run instead of the counts (the peak past r and its time,
//! the first rest after the piston moved and its distance short of r, the moves after it, the
//! largest speed towards r, the first sample within the 2 % band); REBRAKE=N_b turns the brake's
//! re-brake on with a hold of N_b samples at rest (`brake.rebrake`, `brake.rest_samples`; 0 = off);
//! BRAKE_CTL's tenth value 1 turns it on too.
//! Session 20: RELEARN=1 (0) turns the nudge's relearning of its breakaway on (off)
//! (`nudge.relearn`).
//! Session 23: CUT_LEARN=1 (0) turns the held nudge's learnt cut fraction on (off) (`nudge.cut_learn`).
//! Session 20: PREVIEW=S,B sets the short-step approach's (S) and the approach with braking's (B)
//! preview (`short_approach.preview`, `brake.preview`; 1 on, 0 off); BRAKE_CTL's eleventh value and
//! SHORT_CTL's ninth value 1 turn it on too.
#![allow(clippy::unwrap_used, clippy::expect_used, missing_docs)] // tests, benches and examples may panic
use control::tune::{self, Spec};
use control::ControllerFile;
use sysid_core::Plant;

/// The prototype approach mode (see the module documentation) around `inner`.
struct Approach {
    inner: control::PositionController,
    tau_s: f64,
    switch_mm: f64,
    u_max: f64,
    y_prev: Option<f64>,
    /// APPROACH_RAMP=c: the drive rises by c counts per sample until the piston first moves
    /// (its start position and the samples so far).
    drive_from: Option<(f64, u32)>,
    on: bool,
    /// The braking distance is τ_b v² (τ_b in s²/mm) instead of τ_b |v|.
    quadratic: bool,
    /// The controller restarts at the switch (else it runs through the approach, its command unused).
    reset_at_switch: bool,
    /// BRAKE=a_b: after the switch, −a_b u_max while the piston still moves towards r (0 = none).
    brake: f64,
    braking: bool,
    /// APPROACH_MIN=mm: the approach only for a step of at least this size.
    min_step_mm: f64,
    /// APPROACH_DIR=1 or −1: the approach only for steps up (r > y0) or down (0 = both).
    direction: f64,
    /// BRAKE_HOLD=1: after the brake, valves closed until y rests 3 samples, then the controller restarts.
    hold: bool,
    /// Samples of unchanged y that end the hold (BRAKE_HOLD=N, default 3).
    rest_n: u32,
    /// SLIDE=H: sliding approach: full command while |e| > e_sw + τ_b v, else −a_b u_max, until |e| ≤ H mm.
    slide: f64,
    /// BRAKE_N=T: the brake lasts T samples (timed, the time oracle's T2) instead of until the piston stops.
    brake_n: u32,
    brake_k: u32,
    side: f64,
    holding: bool,
    still: u32,
}

impl control::Controller for Approach {
    fn ts_s(&self) -> f64 {
        self.inner.ts_s()
    }
    fn reset(&mut self) {
        self.inner.reset();
        self.y_prev = None;
        self.drive_from = None;
        self.on = true;
        self.braking = false;
        self.holding = false;
        self.still = 0;
    }
    fn step(&mut self, r_mm: f64, y_mm: f64) -> f64 {
        let e = r_mm - y_mm;
        let v = self.y_prev.map_or(0.0, |p| (y_mm - p) / self.ts_s());
        let max_step: f64 =
            std::env::var("APPROACH_MAX").map_or(f64::INFINITY, |b| b.parse().unwrap());
        if self.y_prev.is_none()
            && (e.abs() < self.min_step_mm || e.abs() > max_step || e * self.direction < 0.0)
        {
            self.on = false;
        }
        self.y_prev = Some(y_mm);
        if self.on {
            let towards = (e.signum() * v).max(0.0);
            let braking = if self.quadratic {
                self.tau_s * towards * towards
            } else {
                self.tau_s * towards
            };
            if self.slide > 0.0 && e.abs() > self.slide {
                if !self.reset_at_switch {
                    self.inner.step(r_mm, y_mm);
                }
                return if e.abs() > self.switch_mm + braking {
                    e.signum() * self.u_max
                } else {
                    -e.signum() * self.brake * self.u_max
                };
            }
            if self.slide > 0.0 && self.hold {
                // inside H: brake only (while the predicted stop is past r), else valves closed, until rest
                self.still = if v == 0.0 { self.still + 1 } else { 0 };
                if self.still < self.rest_n {
                    if !self.reset_at_switch {
                        self.inner.step(r_mm, y_mm);
                    }
                    return if braking > e.abs() {
                        -e.signum() * self.brake * self.u_max
                    } else {
                        0.0
                    };
                }
                self.on = false;
                self.inner.reset();
            } else if self.slide > 0.0 {
                self.on = false;
                self.holding = self.hold;
                self.still = 0;
                if self.reset_at_switch {
                    self.inner.reset();
                }
            } else if e.abs() > self.switch_mm + braking {
                if !self.reset_at_switch {
                    self.inner.step(r_mm, y_mm);
                }
                let a1: f64 = std::env::var("APPROACH_U").map_or(1.0, |b| b.parse().unwrap());
                let ramp: f64 = std::env::var("APPROACH_RAMP").map_or(0.0, |b| b.parse().unwrap());
                let (y_start, k) = *self.drive_from.get_or_insert((y_mm, 0));
                if y_mm == y_start {
                    self.drive_from = Some((y_start, k + 1));
                }
                let k = self.drive_from.map_or(0, |d| d.1);
                let u = (a1 * self.u_max + ramp * f64::from(k.saturating_sub(1))).min(self.u_max);
                return e.signum() * u;
            }
            if self.slide <= 0.0 {
                self.on = false;
                self.braking = self.brake > 0.0;
                self.side = e.signum();
                self.brake_k = 0;
                if self.reset_at_switch {
                    self.inner.reset();
                }
            }
        }
        if self.braking && self.brake_n > 0 {
            self.brake_k += 1;
            if self.brake_k <= self.brake_n {
                self.inner.step(r_mm, y_mm);
                return -self.side * self.brake * self.u_max;
            }
            // BRAKE_RAMP=N: the reverse command falls to 0 over N samples after the timed brake.
            let ramp: u32 = std::env::var("BRAKE_RAMP").map_or(0, |n| n.parse().unwrap());
            if self.brake_k <= self.brake_n + ramp {
                self.inner.step(r_mm, y_mm);
                let left = (self.brake_n + ramp + 1 - self.brake_k) as f64 / (ramp + 1) as f64;
                return -self.side * self.brake * self.u_max * left;
            }
            self.braking = false;
            self.holding = self.hold;
            self.still = 0;
        }
        if self.braking {
            if e.signum() * v > 0.0 {
                self.inner.step(r_mm, y_mm);
                return -e.signum() * self.brake * self.u_max;
            }
            self.braking = false;
            self.holding = self.hold;
            self.still = 0;
        }
        if self.holding {
            self.still = if v == 0.0 { self.still + 1 } else { 0 };
            if self.still < self.rest_n {
                self.inner.step(r_mm, y_mm);
                return 0.0;
            }
            self.holding = false;
            self.inner.reset();
        }
        self.inner.step(r_mm, y_mm)
    }
}

/// The controller restarted, not reset, at each run (what it learnt kept).
struct Restart<'a>(&'a mut control::PositionController);

impl control::Controller for Restart<'_> {
    fn ts_s(&self) -> f64 {
        self.0.ts_s()
    }
    fn reset(&mut self) {
        control::Controller::restart(self.0);
    }
    fn step(&mut self, r_mm: f64, y_mm: f64) -> f64 {
        self.0.step(r_mm, y_mm)
    }
}

fn main() {
    let a: Vec<String> = std::env::args().collect();
    let mut s = ControllerFile::parse(&std::fs::read_to_string(&a[1]).unwrap(), "c").unwrap();
    if let (Some(n), Some(rb)) = (s.nudge.as_mut(), a.get(2)) {
        n.rest_band_mm = rb.parse().unwrap();
    }
    if let Some(n) = s.nudge.as_mut() {
        let env = |k: &str| std::env::var(k).ok().map(|v| v.parse::<f64>().unwrap());
        for (key, field) in [
            ("GAMMA", &mut n.cut_fraction),
            ("BAND", &mut n.band_mm),
            ("RHO", &mut n.ramp_counts_s),
            ("BETA", &mut n.start_fraction),
            ("MINRHO", &mut n.min_ramp_counts_s),
            ("CUTBAND", &mut n.cut_band_mm),
            ("CREEP", &mut n.creep_step_mm),
        ] {
            if let Some(v) = env(key) {
                *field = v;
            }
        }
        if let Some(v) = env("NR") {
            n.rest_samples = v as u32;
        }
        if let Some(v) = env("SLIP") {
            n.slip_brake_fraction = v;
        }
        if let Some(v) = env("SLIP_N") {
            n.slip_brake_samples = v as u32;
        }
        if let Some(v) = env("RELEARN") {
            n.relearn = v != 0.0;
        }
        if let Some(v) = env("CUT_LEARN") {
            n.cut_learn = v != 0.0;
        }
    }
    if let Ok(b) = std::env::var("BRAKE_CTL") {
        let v: Vec<f64> = b.split(',').map(|x| x.parse().unwrap()).collect();
        s.brake = Some(control::position::Brake {
            min_step_mm: v[0],
            switch_mm: v[1],
            lead_s: v[2],
            strength: v[3],
            samples: v[4] as u32,
            rest_samples: v[5] as u32,
            learn: v.get(6).copied().unwrap_or(0.0),
            lead_max_s: v.get(7).copied().unwrap_or(0.0),
            release_samples: v.get(8).copied().unwrap_or(0.0) as u32,
            rebrake: v.get(9) == Some(&1.0),
            preview: v.get(10) == Some(&1.0),
        });
    }
    if let Ok(b) = std::env::var("SHORT_CTL") {
        let v: Vec<f64> = b.split(',').map(|x| x.parse().unwrap()).collect();
        s.short_approach = (v[0] > 0.0).then(|| control::position::ShortApproach {
            max_step_mm: v[0],
            drive_fraction: v[1],
            ramp_counts_s: v[2],
            switch_mm: v[3],
            lead_s: v[4],
            brake_strength: v[5],
            brake_samples: v[6] as u32,
            rest_samples: v[7] as u32,
            preview: v.get(8) == Some(&1.0),
            breakaway_seed: v.get(9).copied().unwrap_or(0.0),
            seed_speed_mm_s: v.get(10).copied().unwrap_or(0.0),
        });
    }
    if let (Ok(v), Some(a)) = (std::env::var("SHORT_SEED"), s.short_approach.as_mut()) {
        // SHORT_SEED=κ_s (session 23): the nudge's breakaway seeded at κ_s × the drive's command
        // at its first motion.
        let w: Vec<f64> = v.split(',').map(|x| x.parse().unwrap()).collect();
        a.breakaway_seed = w[0];
        a.seed_speed_mm_s = w.get(1).copied().unwrap_or(0.0);
    }
    if let (Ok(v), Some(a)) = (std::env::var("SHORT_LEAD"), s.short_approach.as_mut()) {
        // SHORT_LEAD=e_s',τ_s (session 23): the short-step switch and lead.
        let w: Vec<f64> = v.split(',').map(|x| x.parse().unwrap()).collect();
        a.switch_mm = w[0];
        a.lead_s = w[1];
    }
    if let (Ok(v), Some(a)) = (std::env::var("SHORT_EM"), s.short_approach.as_mut()) {
        a.max_step_mm = v.parse().unwrap();
    }
    if let (Ok(v), Some(b)) = (std::env::var("REBRAKE"), s.brake.as_mut()) {
        // REBRAKE=N_b: the brake re-brakes (rebrake on) and its hold ends after N_b samples at rest;
        // REBRAKE=0: rebrake off, N_b as in the file.
        let n: u32 = v.parse().unwrap();
        b.rebrake = n > 0;
        if n > 0 {
            b.rest_samples = n;
        }
    }
    if let Ok(v) = std::env::var("PREVIEW") {
        // PREVIEW=S,B (session 20): the short-step approach's (S = 1) and the approach with
        // braking's (B = 1) preview on, 0 off.
        let v: Vec<f64> = v.split(',').map(|x| x.parse().unwrap()).collect();
        if let Some(a) = s.short_approach.as_mut() {
            a.preview = v.first() == Some(&1.0);
        }
        if let Some(b) = s.brake.as_mut() {
            b.preview = v.get(1) == Some(&1.0);
        }
    }
    let spec = Spec::default();
    let approach: Option<Vec<f64>> = std::env::var("APPROACH")
        .ok()
        .map(|a| a.split(',').map(|x| x.parse().unwrap()).collect());
    let s2 = s;
    let build = move || -> Result<Box<dyn control::Controller + Send>, control::ControlError> {
        let inner = s.build()?;
        Ok(match &approach {
            Some(a) => Box::new(Approach {
                u_max: spec.u_max,
                inner,
                tau_s: a[0],
                switch_mm: a[1],
                y_prev: None,
                drive_from: None,
                on: true,
                quadratic: a.get(2) == Some(&1.0),
                reset_at_switch: a.get(3) == Some(&1.0),
                brake: std::env::var("BRAKE").map_or(0.0, |b| b.parse().unwrap()),
                braking: false,
                hold: std::env::var("BRAKE_HOLD").is_ok(),
                rest_n: std::env::var("BRAKE_HOLD").map_or(3, |n| n.parse().unwrap_or(3)),
                holding: false,
                brake_n: std::env::var("BRAKE_N").map_or(0, |b| b.parse().unwrap()),
                brake_k: 0,
                side: 0.0,
                slide: std::env::var("SLIDE").map_or(0.0, |b| b.parse().unwrap()),
                still: 0,
                direction: std::env::var("APPROACH_DIR").map_or(0.0, |b| b.parse().unwrap()),
                min_step_mm: std::env::var("APPROACH_MIN").map_or(0.0, |b| b.parse().unwrap()),
            }),
            None => Box::new(inner),
        })
    };
    if std::env::var("LEADS").is_ok() {
        // Per plant and 150 mm step: the learnt lead τ_b after each of 3 moves, and the run's OS and
        // e_ss (a move repeated with what the controller learnt kept).
        for i in 0..21u64 {
            let base = ipa::PlantConfig::default();
            let cfg = if i == 0 {
                base
            } else {
                ipa::calibrate::study::perturbed_from(&base, i, 0.3)
            };
            let mut p = ipa::Ipa::with_ts(cfg, 0.01).unwrap();
            for (y0, r) in [(25.0, 175.0), (175.0, 25.0)] {
                let mut c = s2.build().unwrap();
                let mut line = format!("plant {i} {y0}->{r}:");
                for _ in 0..3 {
                    let tr = control::closed_loop::run(
                        &mut p,
                        &mut Restart(&mut c),
                        None,
                        &control::Profile::Fixed { setpoint_mm: r },
                        3.0,
                        y0,
                    )
                    .unwrap();
                    let m = control::StepMetrics::assess(&tr.t, &tr.y, Some(&tr.u), y0, r)
                        .unwrap()
                        .0;
                    let side = if r > y0 { 1 } else { 0 };
                    line += &format!(
                        " [OS {:.2} ts {:.3} ess {:.3} tau {:.4}]",
                        m.overshoot_percent.unwrap_or(f64::NAN),
                        m.settling_time_s.unwrap_or(f64::NAN),
                        m.steady_state_error_mm.unwrap_or(f64::NAN),
                        c.brake_lead_s()[side]
                    );
                }
                println!("{line}");
            }
        }
        return;
    }
    if let Ok(t) = std::env::var("TRACE") {
        let v: Vec<f64> = t.split(',').map(|x| x.parse().unwrap()).collect();
        let base = ipa::PlantConfig::default();
        let cfg = if v[0] == 0.0 {
            base
        } else {
            ipa::calibrate::study::perturbed_from(&base, v[0] as u64, 0.3)
        };
        let mut p = ipa::Ipa::with_ts(cfg, 0.01).unwrap();
        let mut c = build().unwrap();
        let tr = control::closed_loop::run(
            &mut p,
            c.as_mut(),
            None,
            &control::Profile::Fixed { setpoint_mm: v[2] },
            3.0,
            v[1],
        )
        .unwrap();
        let width = std::env::var("TRACE_MM").map_or(3.0, |w| w.parse().unwrap());
        for k in 0..tr.len() {
            if (v[2] - tr.y[k]).abs() < width {
                println!(
                    "{:.2} y {:.3} e {:.3} u {:.1}",
                    tr.t[k],
                    tr.y[k],
                    v[2] - tr.y[k],
                    tr.u[k]
                );
            }
        }
        return;
    }
    let twin = std::env::var("TWIN")
        .ok()
        .map(|p| ipa::PlantConfig::from_toml_file(std::path::Path::new(&p)).unwrap());
    let make = |i: usize| -> Result<Box<dyn Plant + Send>, control::ControlError> {
        let (base, offset) = match &twin {
            Some(t) => (t.clone(), control::tune::TUNING_SEED_OFFSET),
            None => (ipa::PlantConfig::default(), 0),
        };
        let offset = std::env::var("SEED_OFFSET").map_or(offset, |o| o.parse().unwrap());
        let cfg = if i == 0 {
            base
        } else {
            ipa::calibrate::study::perturbed_from(&base, offset + i as u64, 0.3)
        };
        Ok(Box::new(ipa::Ipa::with_ts(cfg, 0.01).unwrap()))
    };
    let plants = std::env::var("PLANTS").map_or(21, |n| n.parse().unwrap());
    if std::env::var("PHASES").is_ok() {
        // Session 19: a line per run with what its trace says of the approach and the finish.
        for i in 0..plants {
            for case in spec.cases() {
                let mut p = make(i).unwrap();
                let mut c = build().unwrap();
                let profile = control::Profile::Fixed {
                    setpoint_mm: case.r_mm,
                };
                let tr = control::closed_loop::run(
                    p.as_mut(),
                    c.as_mut(),
                    None,
                    &profile,
                    3.0,
                    case.y0_mm,
                )
                .unwrap();
                phases(i, case.y0_mm, case.r_mm, &tr.t, &tr.y, &tr.u);
            }
        }
        return;
    }
    let warmups = std::env::var("WARMUP").map_or(0, |n| n.parse().unwrap());
    let ev = tune::evaluate_repeated(plants, &make, &build, &spec, warmups).unwrap();
    for r in &ev.runs {
        let e = r.metrics.steady_state_error_mm.unwrap_or(f64::NAN);
        if std::env::var("ROWS").is_ok() {
            println!(
                "row {} {} {} ess {:.3} os {:.3} ts {:.3} cycle {:.3}",
                r.plant,
                r.case.y0_mm,
                r.case.r_mm,
                e,
                r.metrics.overshoot_percent.unwrap_or(f64::NAN),
                r.metrics.settling_time_s.unwrap_or(f64::NAN),
                r.limit_cycle_mm
            );
        }
        if (e.is_nan() || e.abs() > 0.02) && std::env::var("SHOW").is_ok() {
            println!(
                "  plant {} {} -> {} e_ss {:.3} cycle {:.2} OS {:?} ts {:?}",
                r.plant,
                r.case.y0_mm,
                r.case.r_mm,
                e,
                r.limit_cycle_mm,
                r.metrics.overshoot_percent,
                r.metrics.settling_time_s
            );
        }
    }
    println!(
        "OS {} ts {} ess {} all {} worst ess {:.3} cycle {:.3}{}",
        ev.overshoot_met,
        ev.settling_met,
        ev.ess_met,
        ev.met,
        ev.max_abs_ess_mm,
        ev.worst_limit_cycle_mm,
        if std::env::var("COST").is_ok() {
            let c: Vec<f64> = ev.runs.iter().map(|r| r.cost(&spec)).collect();
            format!(
                " J (mean run cost) {:.3} largest run cost {:.2}",
                ev.cost,
                c.iter().copied().fold(0.0, f64::max)
            )
        } else {
            String::new()
        }
    );
}

/// PHASES=1: one line per run. side e = side (r − y) (> 0: short of r). The first rest: the first
/// sample after the piston first moved with y unchanged for 2 samples (where the approach stopped);
/// moves: the rests left afterwards (nudges and slips); the peak past r and its time; the speed
/// towards r at its largest; t_s, the judged OS and e_ss.
fn phases(plant: usize, y0: f64, r: f64, t: &[f64], y: &[f64], u: &[f64]) {
    let side = (r - y0).signum();
    let m = control::StepMetrics::assess(t, y, Some(u), y0, r)
        .unwrap()
        .0;
    let band = 0.02 * (r - y0).abs();
    let mut moved = false;
    let mut rest1: Option<usize> = None;
    let mut moves = 0;
    let mut resting = false;
    let mut vmax = 0.0f64;
    for k in 1..y.len() {
        let v = side * (y[k] - y[k - 1]) / (t[k] - t[k - 1]);
        vmax = vmax.max(v);
        if y[k] != y0 {
            moved = true;
        }
        let still = k >= 2 && y[k] == y[k - 1] && y[k - 1] == y[k - 2];
        if moved && rest1.is_none() && still {
            rest1 = Some(k);
            resting = true;
        } else if rest1.is_some() {
            if resting && !still && y[k] != y[k - 1] {
                moves += 1;
                resting = false;
            } else if still {
                resting = true;
            }
        }
    }
    let (kp, past) = y
        .iter()
        .enumerate()
        .map(|(k, &yk)| (k, side * (yk - r)))
        .fold((0, f64::NEG_INFINITY), |a, b| if b.1 > a.1 { b } else { a });
    let (tr1, er1) = rest1.map_or((f64::NAN, f64::NAN), |k| (t[k], side * (r - y[k])));
    // The first sample within the 2 % band.
    let tin = y
        .iter()
        .position(|&yk| (yk - r).abs() <= band)
        .map_or(f64::NAN, |k| t[k]);
    println!(
        "ph {plant} {y0} {r} os {:.3} ts {:.3} ess {:.3} peak {:.3} tpeak {:.2} rest1 {:.2} erest1 {:.3} moves {moves} vmax {:.0} tin {:.2}",
        m.overshoot_judged_percent().unwrap_or(f64::NAN),
        m.settling_time_s.unwrap_or(f64::NAN),
        m.steady_state_error_mm.unwrap_or(f64::NAN),
        past.max(0.0),
        t[kp],
        tr1,
        er1,
        vmax,
        tin
    );
}
