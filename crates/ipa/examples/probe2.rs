use ipa::plant::Integrator;
use sysid::Plant;
fn main() {
    let u = ipa::generate(&ipa::InputSpec::Staircase, 86300, 0.01, 255.0, 1).unwrap();
    let mut cfg = ipa::PlantConfig::default();
    cfg.integration.tolerance = 5e-9;
    let mut a = ipa::Ipa::new(cfg).unwrap();
    let mut b = ipa::Ipa::new(ipa::PlantConfig::default()).unwrap();
    b.set_integrator(Integrator::Rk4);
    a.reset(100.0); b.reset(100.0);
    for (k, &uk) in u.iter().enumerate() {
        let (ea, eb) = (a.event_count(), b.event_count());
        a.step(uk).unwrap(); b.step(uk).unwrap();
        if k > 86150 && k < 86200 {
            println!("k {k} u {uk} dp x {:.6} v {:.4} ev+{} stuck {} | rk4 x {:.6} v {:.4} ev+{} stuck {} | F {:.3} {:.3}", a.position_mm(), a.velocity_mm_s(), a.event_count()-ea, a.is_stuck(), b.position_mm(), b.velocity_mm_s(), b.event_count()-eb, b.is_stuck(), a.dynamics().drive_force_n(&a.state()), b.dynamics().drive_force_n(&b.state()));
        }
    }
}
