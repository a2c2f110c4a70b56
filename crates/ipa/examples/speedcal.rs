use ipa::{Ipa, PlantConfig};
use sysid::Plant;
const P_ATM: f64 = 101_325.0;
const R: f64 = 287.0;
const T: f64 = 294.5;
const RHO0: f64 = 1.185;
const T0: f64 = 293.15;

/// ISO 6358 flow factor (choked = 1, subsonic ellipse), written out independently of the crate.
fn iso_factor(r: f64, b: f64) -> f64 {
    if r <= b {
        1.0
    } else {
        let z = ((r - b) / (1.0 - b)).min(1.0);
        (1.0 - z * z).sqrt()
    }
}

/// C in dm^3/(s bar) -> choked mass flow per Pa of upstream pressure, kg/(s Pa).
fn k_per_pa(c_dm3_s_bar: f64) -> f64 {
    c_dm3_s_bar * 1e-3 / 1e5 * RHO0 * (T0 / T).sqrt()
}

fn bisect(mut lo: f64, mut hi: f64, f: impl Fn(f64) -> f64) -> f64 {
    // f(lo) and f(hi) of opposite signs.
    let s_lo = f(lo).signum();
    for _ in 0..200 {
        let mid = 0.5 * (lo + hi);
        if f(mid).signum() == s_lo {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    0.5 * (lo + hi)
}

/// Steady full-command speed from the steady-state chamber and force balances (Stribeck part
/// negligible at speed). Returns (v m/s, filling-chamber pressure Pa).
fn steady_speed(cfg: &PlantConfig, extend: bool) -> (f64, f64) {
    let d = cfg.cylinder.bore_mm * 1e-3;
    let r = cfg.cylinder.rod_mm * 1e-3;
    let a_cap = std::f64::consts::PI * d * d / 4.0;
    let a_rod = std::f64::consts::PI * (d * d - r * r) / 4.0;
    let (a_fill, a_exh) = if extend { (a_cap, a_rod) } else { (a_rod, a_cap) };
    let p_s = P_ATM + cfg.air.supply_gauge_mpa * 1e6;
    let b = cfg.valve.critical_pressure_ratio;
    let k_s = k_per_pa(cfg.valve.supply_conductance_dm3_s_bar);
    let k_e = k_per_pa(cfg.valve.exhaust_conductance_dm3_s_bar);
    let (a_in, a_out, alpha) = (cfg.air.exponent_charging, cfg.air.exponent_discharging, cfg.air.exponent_volume);
    let rt = R * T;
    let fric = |v: f64| cfg.friction.coulomb_n + cfg.friction.viscous_n_s_m * v;
    // Given v: exhaust chamber pressure from alpha_out K_e p f(p_atm/p) RT = alpha p A_exh v.
    let p_exh = |v: f64| {
        let target = alpha * a_exh * v / (a_out * k_e * rt);
        let r_exh = bisect(b, 1.0, |r| iso_factor(r, b) - target);
        P_ATM / r_exh
    };
    // Force balance: p_fill A_fill = p_exh A_exh + p_atm (A_fill - A_exh) + friction (no external force).
    let p_fill = |v: f64| (p_exh(v) * a_exh + P_ATM * (a_fill - a_exh) + fric(v)) / a_fill;
    // Filling chamber: alpha_in K_s p_s f(p_fill/p_s) RT = alpha p_fill A_fill v.
    let v = bisect(1e-4, 3.0, |v| {
        let pf = p_fill(v);
        a_in * k_s * p_s * iso_factor(pf / p_s, b) * rt - alpha * pf * a_fill * v
    });
    (v, p_fill(v))
}

/// Simulated speed (m/s) between 80 and 150 mm of travel at full command from an end.
#[allow(dead_code)]
fn simulated_full_speed(extend: bool) -> f64 {
    let cfg = &PlantConfig::default();
    let mut p = Ipa::new(PlantConfig::default()).unwrap();
    let (start, u) = if extend { (10.0, 255.0) } else { (190.0, -255.0) };
    p.reset(start);
    let mut samples = vec![];
    for k in 0..60 {
        samples.push((k as f64 * 0.01, (p.position_mm() - start).abs()));
        p.step(u).unwrap();
    }
    let mut pf = vec![];
    {
        let mut q = Ipa::new(cfg.clone()).unwrap();
        q.reset(start);
        for _ in 0..100 {
            let tr = (q.position_mm() - start).abs();
            if (80.0..=150.0).contains(&tr) {
                pf.push(q.pressures_pa()[if extend { 0 } else { 1 }]);
            }
            q.step(u).unwrap();
        }
    }
    let pm = pf.iter().sum::<f64>() / pf.len() as f64;
    let d = 0.04f64; let r = 0.016f64;
    let a = if extend { std::f64::consts::PI * d * d / 4.0 } else { std::f64::consts::PI * (d * d - r * r) / 4.0 };
    let ps = P_ATM + 0.6e6;
    let vest = 1.4 / 1.2 * k_per_pa(cfg.valve.supply_conductance_dm3_s_bar) * ps * R * T / (pm * a);
    println!("  extend {extend}: mean p_fill {pm:.0} Pa (ratio {:.2}), choked est {vest:.3}", pm / ps);
    let first = samples.iter().find(|s| s.1 >= 80.0).unwrap();
    let last = samples.iter().rev().find(|s| s.1 <= 150.0).unwrap();
    (last.1 - first.1) * 1e-3 / (last.0 - first.0)
}


fn main() {
    for (cs, ce) in [(0.2, 0.3), (0.15, 0.5), (0.12, 0.5), (0.15, 0.6), (0.12, 0.6), (0.1, 0.5)] {
        let mut cfg = PlantConfig::default();
        cfg.valve.supply_conductance_dm3_s_bar = cs;
        cfg.valve.exhaust_conductance_dm3_s_bar = ce;
        let e = steady_speed(&cfg, true);
        let r = steady_speed(&cfg, false);
        let ps = P_ATM + 0.6e6;
        let se = sim(&cfg, true);
        let sr = sim(&cfg, false);
        println!("cs {cs} ce {ce}: ext est {:.3} (pfill/ps {:.2}) sim {:.3} | ret est {:.3} (pfill/ps {:.2}) sim {:.3}", e.0, e.1/ps, se, r.0, r.1/ps, sr);
    }
}
fn sim(cfg: &PlantConfig, extend: bool) -> f64 {
    let mut p = Ipa::new(cfg.clone()).unwrap();
    let (start, u) = if extend { (10.0, 255.0) } else { (190.0, -255.0) };
    p.reset(start);
    let mut samples = vec![];
    for k in 0..100 {
        samples.push((k as f64 * 0.01, (p.position_mm() - start).abs()));
        p.step(u).unwrap();
    }
    let mut pf = vec![];
    {
        let mut q = Ipa::new(cfg.clone()).unwrap();
        q.reset(start);
        for _ in 0..100 {
            let tr = (q.position_mm() - start).abs();
            if (80.0..=150.0).contains(&tr) {
                pf.push(q.pressures_pa()[if extend { 0 } else { 1 }]);
            }
            q.step(u).unwrap();
        }
    }
    let pm = pf.iter().sum::<f64>() / pf.len() as f64;
    let d = 0.04f64; let r = 0.016f64;
    let a = if extend { std::f64::consts::PI * d * d / 4.0 } else { std::f64::consts::PI * (d * d - r * r) / 4.0 };
    let ps = P_ATM + 0.6e6;
    let vest = 1.4 / 1.2 * k_per_pa(cfg.valve.supply_conductance_dm3_s_bar) * ps * R * T / (pm * a);
    println!("  extend {extend}: mean p_fill {pm:.0} Pa (ratio {:.2}), choked est {vest:.3}", pm / ps);
    let first = samples.iter().find(|s| s.1 >= 80.0).unwrap();
    let last = samples.iter().rev().find(|s| s.1 <= 150.0).unwrap();
    (last.1 - first.1) * 1e-3 / (last.0 - first.0)
}
