//! Real measured data from `../shared/data` (read at run time, never copied into the repository). Each test
//! skips, saying so, when the folder is absent.

#![allow(clippy::unwrap_used, clippy::expect_used, missing_docs)] // tests, benches and examples may panic

use sysid::data::{read_csv, CsvOptions};
use sysid::metrics::metrics;
use sysid::{identify, Identification, Method};
use sysid::{Dataset, ModelKind};

fn tanks(dir: &std::path::Path, u: &str, y: &str) -> Dataset {
    let opts = CsvOptions {
        u_col: u.into(),
        y_col: y.into(),
        t_col: "t".into(),
        ts: Some(4.0),
        ..CsvOptions::default()
    };
    read_csv(&dir.join("cascaded_tanks/dataBenchmark.csv"), &opts).unwrap()
}

// Cascaded tanks (SOURCE.md): a linear ARX(2, 2, 1) with offset refined by output error simulates the test
// record with an RMSE below the published best linear approximation (0.75 V); LS ARX is above OE.
#[test]
fn cascaded_tanks_output_error_arx_beats_the_published_bla() {
    let Some(dir) = ipa_testdata::shared_data() else {
        return;
    };
    let (est, val) = (tanks(&dir, "uEst", "yEst"), tanks(&dir, "uVal", "yVal"));
    let s = Identification::default()
        .with_kind(ModelKind::Arx)
        .with_orders(2, 2, 1)
        .with_offset(true);
    let ls = identify(&est, &s.clone().with_method(Method::Ls)).unwrap();
    let oe = identify(&est, &s.with_method(Method::Oe)).unwrap();
    let rmse_ls = metrics(&ls.model, &val).unwrap().rmse_sim.unwrap();
    let rmse_oe = metrics(&oe.model, &val).unwrap().rmse_sim.unwrap();
    assert!(rmse_oe < 0.75, "OE test RMSE {rmse_oe}");
    assert!(rmse_oe < rmse_ls, "OE {rmse_oe} vs LS {rmse_ls}");
}

// The pump voltage is never negative: a Hammerstein model is estimated (not refused) with the left branch
// dropped and the fixed parameters reported without a standard deviation.
#[test]
fn cascaded_tanks_one_sided_hammerstein_is_estimated_with_a_note() {
    let Some(dir) = ipa_testdata::shared_data() else {
        return;
    };
    let est = tanks(&dir, "uEst", "yEst");
    let mut s = Identification::default()
        .with_orders(2, 2, 1)
        .with_method(Method::Ls)
        .with_offset(true);
    s.drop_unexcited_branch = true;
    let fit = identify(&est, &s).unwrap();
    assert!(fit.note().unwrap().contains("never negative"));
    let d = fit.model.deadzone().copied().unwrap();
    assert_eq!((d.m_l, d.b_l), (0.0, 0.0));
}

// Cascaded tanks, issue 23: the polynomial NARX structure that `order --classes` picks on the estimation
// record (degree 3, (2, 2, 0), docs/real-data.md) simulates the test record below the target of
// 0.40 V (the published polynomial NARX: 0.413 V), its terms and their number chosen without the test record.
#[test]
fn cascaded_tanks_polynomial_narx_reaches_the_target() {
    let Some(dir) = ipa_testdata::shared_data() else {
        return;
    };
    let (est, val) = (tanks(&dir, "uEst", "yEst"), tanks(&dir, "uVal", "yVal"));
    let s = sysid::narx::NarxSettings {
        na: 2,
        nb: 2,
        nk: 0,
        degree: 3,
        constant: true,
        ..sysid::narx::NarxSettings::default()
    };
    let fit = sysid::narx::identify_narx(&est, &s).unwrap();
    let m = sysid::narx::narx_metrics(&fit.model, &val).unwrap();
    let rmse = m.rmse_sim.expect("the test simulation must not blow up");
    assert!(rmse <= 0.40, "NARX test RMSE {rmse} V");
}
