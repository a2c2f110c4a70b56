//! A controller file written before the approach with braking existed runs as it did then.
#![allow(clippy::unwrap_used, clippy::expect_used, missing_docs)] // tests may panic
use control::Controller;

// data/s13_b_controller.json: session 13's (B) (`tune --plant-config twin.toml --check-physics` on
// main 264a133; no `brake` field). data/s13_b_run.csv: main 264a133's `ipa-sysid control --plant ipa
// --controller s13_b_controller.json --profile staircase:40,38,120,60@2 --out s13_b_run.csv` (t, r,
// u, y; round-trip decimals). Fed the recorded r and y, today's controller gives the recorded u
// bit for bit: the expectation is main's binary's output, not this code's.
#[test]
fn a_file_without_a_brake_commands_as_main_264a133_did_on_a_recorded_run() {
    let file = include_str!("data/s13_b_controller.json");
    let s = control::ControllerFile::parse(file, "s13_b_controller.json").unwrap();
    assert!(s.brake.is_none());
    let mut c = s.build().unwrap();
    let mut n = 0;
    for line in include_str!("data/s13_b_run.csv").lines().skip(1) {
        let v: Vec<f64> = line.split(',').map(|x| x.parse().unwrap()).collect();
        let u = c.step(v[1], v[3]);
        assert_eq!(
            u.to_bits(),
            v[2].to_bits(),
            "t = {} s: {u} vs {}",
            v[0],
            v[2]
        );
        n += 1;
    }
    assert_eq!(n, 801);
}
