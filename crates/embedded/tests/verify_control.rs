//! The embedded PI controller and deadzone compensator against the `control` crate's (the ones the
//! command line's `control` subcommand runs): bit-for-bit equal commands on random error sequences,
//! because the operations and their order are the same.

#![allow(clippy::unwrap_used, clippy::expect_used, missing_docs)] // tests may panic

use control::{AntiWindup as CAw, DeadzoneCompensator, PiSettings, SlopeMode as CMode};
use ipa_embedded::{AntiWindup, Compensator, Deadzone, Pi, SlopeMode};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

#[test]
fn pi_commands_equal_control_pi_bit_for_bit() {
    let schemes = [
        (AntiWindup::None, CAw::None),
        (AntiWindup::Clamping, CAw::Clamping),
        (
            AntiWindup::BackCalculation { tt_s: 0.05 },
            CAw::BackCalculation { tt_s: 0.05 },
        ),
    ];
    for (mine, theirs) in schemes {
        let mut rng = ChaCha8Rng::seed_from_u64(5);
        let mut a = Pi::new(14.0, 1.0, 0.01, 255.0, mine).unwrap();
        let mut b = PiSettings::new(14.0, 1.0)
            .with_anti_windup(theirs)
            .build(0.01)
            .unwrap();
        let mut saturated = 0;
        for _ in 0..5000 {
            // Set-points and positions in mm, errors up to ±60 mm so that the command saturates often.
            let (r, y) = (rng.gen_range(-60.0..60.0), rng.gen_range(-10.0..10.0));
            let (ua, ub) = (a.step(r, y).unwrap(), b.step(r, y));
            assert_eq!(ua.to_bits(), ub.to_bits(), "{mine:?}: {ua} vs {ub}");
            saturated += usize::from(ua.abs() == 255.0);
        }
        assert_eq!(a.integral().to_bits(), b.integral_counts().to_bits());
        assert!(saturated > 100 && saturated < 4900, "{saturated}");
    }
}

#[test]
fn compensator_equals_control_compensator_bit_for_bit() {
    let dz = Deadzone {
        b_l: -23.5,
        b_r: 31.25,
        m_l: 5.4e-3,
        m_r: 3.7e-3,
    };
    let sdz = sysid::Deadzone {
        b_l: dz.b_l,
        b_r: dz.b_r,
        m_l: dz.m_l,
        m_r: dz.m_r,
    };
    for (mine, theirs) in [
        (SlopeMode::Shift, CMode::Shift),
        (SlopeMode::Equalise, CMode::Equalise),
    ] {
        let a = Compensator::new(dz, mine, 2.0, 255.0).unwrap();
        let b = DeadzoneCompensator::new(sdz, theirs, 255.0)
            .unwrap()
            .with_threshold(2.0)
            .unwrap();
        let mut rng = ChaCha8Rng::seed_from_u64(6);
        for _ in 0..5000 {
            let u: f64 = rng.gen_range(-300.0..300.0);
            assert_eq!(
                a.apply(u).to_bits(),
                b.apply(u).to_bits(),
                "{mine:?} u = {u}"
            );
        }
    }
}
