//! The tuner's model of a twin (`sysid_control::tuning::twin_model`): output error from the LS start alone
//! (`sysid::OutputError::second_start = false`), the model issue 25's figures were measured with
//! (docs/control.md, "The twin's model and the second start").

#![allow(clippy::unwrap_used, clippy::expect_used, missing_docs)] // tests may panic

use sysid::fitted::Note;

/// The default plant's staircase record, as `twin_model` simulates it, identified by output error
/// with the given second-start setting.
fn fitted(second_start: bool) -> sysid::Fitted {
    let cfg = ipa::PlantConfig::default();
    let rec = ipa::calibrate::study::record(&cfg, ipa::InputSpec::Staircase, 3000, 1).unwrap();
    let data = sysid_core::Dataset::new(
        sysid_core::data::Signals { u: rec.u, y: rec.y },
        rec.ts,
        "twin record",
    )
    .unwrap();
    let settings = sysid::Identification::default()
        .with_kind(sysid::ModelKind::Hammerstein)
        .with_orders(3, 1, 1)
        .with_estimator(sysid::EstimatorSettings::Oe(sysid::OutputError {
            second_start,
            ..sysid::OutputError::default()
        }));
    sysid::identify(&data, &settings).unwrap()
}

#[test]
fn the_twin_model_is_the_search_from_the_ls_start_alone() {
    let one = fitted(false);
    let two = fitted(true);
    // Without the second start there is no note of it; with it, the note gives both ends.
    assert!(!one
        .notes
        .iter()
        .any(|n| matches!(n, Note::SecondStart { .. })));
    let Some(Note::SecondStart {
        rss_ls, kept_iv, ..
    }) = two
        .notes
        .iter()
        .find(|n| matches!(n, Note::SecondStart { .. }))
    else {
        panic!("no second-start note: {:?}", two.notes)
    };
    // The LS start's end of the two-start search is the one-start search's model: its simulation
    // RSS (from the measured initial outputs, over the record) is the note's rss_ls (to 2 %: rows
    // k < k0 and the search's own start are counted a little differently).
    let cfg = ipa::PlantConfig::default();
    let rec = ipa::calibrate::study::record(&cfg, ipa::InputSpec::Staircase, 3000, 1).unwrap();
    let data = sysid_core::Dataset::new(
        sysid_core::data::Signals {
            u: rec.u.clone(),
            y: rec.y.clone(),
        },
        rec.ts,
        "twin record",
    )
    .unwrap();
    let m = sysid_core::metrics::metrics(&one.model, &data).unwrap();
    let rows = rec.y.len() as f64;
    let rss = m.rmse_sim_measured.unwrap().powi(2) * rows;
    assert!(
        (rss - rss_ls).abs() <= 0.02 * rss_ls,
        "one-start RSS {rss} against the note's LS end {rss_ls}"
    );
    // The tuner takes the one-start model, parameter for parameter (on this plant the two differ:
    // the IV end is kept, so the test tells the two settings apart).
    assert!(*kept_iv, "the IV end was not kept here: {:?}", two.notes);
    let twin = sysid_control::tuning::twin_model(&cfg).unwrap();
    assert_eq!(twin, one.model);
    assert_ne!(twin, two.model);
}
