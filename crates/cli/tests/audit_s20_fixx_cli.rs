//! Audit s20 through the binary: `response` (M-2: a model's frequency response, impulse and step, DC
//! gain and a PI loop's margins), decimal-comma and date-time CSV errors that name the cause (L-1,
//! L-5), and the `--samples` refusal in the "invalid setting X = V" form (L-3). Each expectation is
//! computed here from the model's coefficients or from what the user passed, never copied from output.

#![allow(clippy::unwrap_used, clippy::expect_used, missing_docs)] // tests may panic

use std::path::Path;

mod common;
use common::{run as ipa_sysid, stderr};

fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

// L-3: the --samples refusal in the form of every other refusal of docs/reliability.md's table.
#[test]
fn samples_out_of_range_is_an_invalid_setting() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("x.csv");
    let o = ipa_sysid(&["simulate", "--samples", "10000000000", "--out", s(&out)]);
    assert_eq!(o.status.code(), Some(2));
    assert!(
        stderr(&o).contains("invalid setting --samples = 10000000000: expected 1..=50000000"),
        "{}",
        stderr(&o)
    );
}
