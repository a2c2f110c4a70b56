//! Session 25 (helper fixal, audit s23 L-B4's second half): when a physics run never moves although
//! its commands left the valves' deadzone, `simulate` names the static friction and the forces the
//! commands can give instead of blaming the command record's scale; commands inside the deadzone keep
//! the old words. The expectations: the deadzone U_MAX · t_open / T = 255 · 0.4 / 10 = 10.2 counts
//! (the valve model: a pulse shorter than the opening delay never opens it); the piston, held by a
//! static friction F_s, cannot have felt a force above F_s in a run where it never moved; and the
//! force figure must agree with the physics plant itself, which starts to move one count above it.

#![allow(clippy::unwrap_used, clippy::expect_used, missing_docs)] // tests may panic

use std::path::Path;

mod common;
use common::{run as ipa_sysid, s, stderr};

/// `simulate --plant ipa` with the step `amplitude` (counts) from t = 0 for 3 s, on the config
/// `config` (none: the defaults): its stderr.
fn simulate(dir: &Path, config: Option<&Path>, amplitude: i32) -> String {
    let input = format!("step:{amplitude}@0");
    let out = dir.join("o.csv");
    let mut args = vec![
        "simulate",
        "--plant",
        "ipa",
        "--input",
        &input,
        "--samples",
        "300",
        "--out",
        s(&out),
        "--force",
    ];
    if let Some(c) = config {
        args.extend(["--plant-config", s(c)]);
    }
    let o = ipa_sysid(&args);
    assert!(o.status.success(), "{}", stderr(&o));
    stderr(&o)
}

/// The force "… is X N extending" of a friction warning.
fn extend_force(e: &str) -> f64 {
    let at = e.find(" N extending").unwrap_or_else(|| panic!("{e}"));
    let head = &e[..at];
    head[head.rfind(' ').unwrap() + 1..].parse().unwrap()
}

#[test]
fn friction_just_below_the_refusal_limit_is_named_with_the_forces() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    // The supply gives 0.6 MPa · π/4 · (40² − 16²) mm² = 633.3 N retracting (the refusal limit, the
    // smaller side); 630 N of static friction is just below it.
    let limit = 0.6 * std::f64::consts::FRAC_PI_4 * (40.0 * 40.0 - 16.0 * 16.0);
    assert!(630.0 < limit);
    let cfg = d.join("sticky.toml");
    std::fs::write(&cfg, "[friction]\nstatic_n = 630.0\ncoulomb_n = 100.0\n").unwrap();
    let e = simulate(d, Some(&cfg), 40);
    assert!(e.contains("never moved"), "{e}");
    assert!(e.contains("static friction holds the piston"), "{e}");
    assert!(e.contains("friction.static_n = 630.0 N"), "{e}");
    assert!(
        e.contains("beyond the valves' deadzone (±10.2000 counts)"),
        "{e}"
    );
    assert!(!e.contains("inside the valves' deadzone"), "{e}");
    let f = extend_force(&e);
    assert!(f > 0.0 && f <= 630.0, "{f}: {e}");
}

#[test]
fn commands_inside_the_deadzone_keep_the_scale_words() {
    let dir = tempfile::tempdir().unwrap();
    // 8 counts < 10.2: the valve never opens, so the command record's scale is the doubt.
    let e = simulate(dir.path(), None, 8);
    assert!(
        e.contains("the commands stay within ±8.0000 counts, inside the valves' deadzone"),
        "{e}"
    );
    assert!(!e.contains("friction"), "{e}");
}

// The default plant (F_s = 8 N) holds at some amplitude A and moves at A + 1 (found by running the
// plant itself, not from the warning); the warning's force at A must not exceed F_s, and the force the
// library gives one count above must (the two are independent computations: the plant's event-located
// breakaway along its integrated trajectory, the warning's periodic steady state of a held chamber).
#[test]
fn the_force_figure_agrees_with_where_the_physics_plant_breaks_away() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let moves = |a: i32| !simulate(d, None, a).contains("never moved");
    assert!(!moves(11) && moves(255));
    let (mut lo, mut hi) = (11, 255); // lo holds, hi moves
    while hi - lo > 1 {
        let mid = (lo + hi) / 2;
        if moves(mid) {
            hi = mid;
        } else {
            lo = mid;
        }
    }
    let f_lo = extend_force(&simulate(d, None, lo));
    assert!(f_lo <= 8.0, "{lo} counts: {f_lo} N");
    let cfg = ipa::PlantConfig::default();
    let f_hi = cfg.held_drive_force_n(f64::from(hi), 100.0);
    assert!(f_hi > 8.0, "{hi} counts: {f_hi} N");
}
