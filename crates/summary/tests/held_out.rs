//! A held-out record judged against the model's own estimation record (audit s21 M-A1, M-A2): which
//! rows a record's name holds ([`record_rows`]), the in-sample word of `validate`
//! ([`estimation_rows_warning`]) and the drop from the recorded estimation fit
//! ([`ValidationReport::warnings_of`]). Expectations are row counts worked out by hand here.

#![allow(clippy::unwrap_used, missing_docs)] // tests may panic

use sysid::metrics::Metrics;
use sysid::model::Provenance;
use sysid::Model;
use sysid_summary::{estimation_rows_warning, record_rows, ValidationReport};

fn model_from(record: &str, fit: Option<f64>) -> Model {
    Model::arx(1.0, vec![-0.5], vec![1.0], 1, None)
        .unwrap()
        .with_provenance(Some(Provenance {
            record: record.to_string(),
            u_columns: Vec::new(),
            y_column: None,
            fit_estimation_percent: fit,
            warnings: Vec::new(),
        }))
}

// `--rows 100..600` then `--split 0.5`: rows 100 + 0 .. 100 + 250 of the file.
#[test]
fn a_cut_of_a_cut_names_rows_of_the_file() {
    assert_eq!(record_rows("d/f.csv"), ("d/f.csv", None));
    assert_eq!(
        record_rows("d/f.csv[100..600]"),
        ("d/f.csv", Some(100..600))
    );
    assert_eq!(
        record_rows("d/f.csv[100..600][0..250]"),
        ("d/f.csv", Some(100..350))
    );
    assert_eq!(
        record_rows("d/f.csv[100..600][250..500]"),
        ("d/f.csv", Some(350..600))
    );
    // Not a row suffix: the name is the file's.
    assert_eq!(record_rows("d/f[x].csv"), ("d/f[x].csv", None));
    assert_eq!(record_rows("d/f.csv[a..3]"), ("d/f.csv[a..3]", None));
}

// Estimated on rows 0..148: the same rows are wholly in-sample; rows 100..200 share 148 − 100 = 48 of
// their 100; rows 148..296 none; another file none; a model estimated on the whole file makes any cut
// of it in-sample.
#[test]
fn validating_on_the_estimation_rows_is_called_in_sample() {
    let m = model_from("d/f.csv[0..148]", Some(92.0));
    let w = estimation_rows_warning(m.provenance(), "d/f.csv[0..148]", 148, None).unwrap();
    assert!(
        w.starts_with("this is the data the model was estimated on"),
        "{w}"
    );
    let w = estimation_rows_warning(m.provenance(), "d/f.csv[100..200]", 100, None).unwrap();
    assert!(
        w.starts_with("48 of the 100 rows of d/f.csv[100..200] (48 %)"),
        "{w}"
    );
    assert!(estimation_rows_warning(m.provenance(), "d/f.csv[148..296]", 148, None).is_none());
    assert!(estimation_rows_warning(m.provenance(), "d/g.csv[0..148]", 148, None).is_none());
    // The whole file (296 rows) holds the 148 estimation rows: half of it.
    let w = estimation_rows_warning(m.provenance(), "d/f.csv", 296, None).unwrap();
    assert!(
        w.starts_with("148 of the 296 rows of d/f.csv (50 %)"),
        "{w}"
    );
    let whole = model_from("d/f.csv", None);
    let w = estimation_rows_warning(whole.provenance(), "d/f.csv[600..1000]", 400, None).unwrap();
    assert!(
        w.starts_with("this is the data the model was estimated on"),
        "{w}"
    );
    let plain = Model::arx(1.0, vec![-0.5], vec![1.0], 1, None).unwrap();
    assert!(estimation_rows_warning(plain.provenance(), "d/f.csv", 10, None).is_none());
}

fn fits(est: f64, meas: f64) -> Metrics {
    Metrics {
        fit_sim_percent: Some(est),
        fit_pred_percent: None,
        rmse_sim: None,
        fit_sim_measured_percent: Some(meas),
        rmse_sim_measured: None,
        rmse_pred: 0.0,
        loss: Some(0.0),
        loss_sim: None,
        fpe: None,
        aic: None,
        loss_fcn: Some(0.0),
        fpe_matlab: None,
        aic_matlab: None,
        n: 100,
        p: 2,
        note: None,
    }
}

// The model file records 92.12 % on its estimation rows; this record: 53.53 (estimated) and 53.50
// (measured initial outputs), the worse 53.50, 38.62 points below: said with both figures. 80 % is
// 12.12 points below: not said. Without a recorded fit there is nothing to compare.
#[test]
fn a_validation_fit_far_below_the_recorded_estimation_fit_is_said() {
    let m = model_from("d/f.csv[0..148]", Some(92.12));
    let said = |w: &[String]| {
        w.iter()
            .any(|w| w.contains("the simulation fit falls from"))
    };
    let w = ValidationReport::warnings_of(&m, &fits(53.53, 53.50));
    assert!(said(&w), "{w:?}");
    assert!(
        w.iter().any(|w| w.contains(
            "92.12 % on the estimation data to 53.50 % on the validation data (38.6 points"
        )),
        "{w:?}"
    );
    assert!(!said(&ValidationReport::warnings_of(&m, &fits(80.0, 80.0))));
    let none = model_from("d/f.csv[0..148]", None);
    assert!(!said(&ValidationReport::warnings_of(
        &none,
        &fits(10.0, 10.0)
    )));
}

// Audit s22 M-R2: one file holds two experiments side by side (the cascaded tanks: uEst/yEst,
// uVal/yVal). A model estimated on uEst/yEst judged on uVal/yVal of the same rows is held out; on
// uEst/yEst it is in-sample; a record read without a header (no names) keeps the rows rule.
#[test]
fn other_columns_of_the_estimation_file_are_held_out() {
    let m = Model::arx(1.0, vec![-0.5], vec![1.0], 1, None)
        .unwrap()
        .with_provenance(Some(Provenance {
            record: "d/f.csv".to_string(),
            u_columns: vec!["uEst".to_string()],
            y_column: Some("yEst".to_string()),
            fit_estimation_percent: None,
            warnings: Vec::new(),
        }));
    let est = ["uEst".to_string()];
    let val = ["uVal".to_string()];
    assert!(
        estimation_rows_warning(m.provenance(), "d/f.csv", 1024, Some((&val, "yVal"))).is_none()
    );
    // Only the output differs: still another record.
    assert!(
        estimation_rows_warning(m.provenance(), "d/f.csv", 1024, Some((&est, "yVal"))).is_none()
    );
    let w = estimation_rows_warning(m.provenance(), "d/f.csv", 1024, Some((&est, "yEst"))).unwrap();
    assert!(
        w.starts_with("this is the data the model was estimated on"),
        "{w}"
    );
    assert!(estimation_rows_warning(m.provenance(), "d/f.csv", 1024, None).is_some());
}
