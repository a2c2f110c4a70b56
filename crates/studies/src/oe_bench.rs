//! Output-error identification on long real records (issue 16): the cases `ipa-sysid bench oe` times —
//! EMPS (`vir` → `qm`, ARX(6,5,0) with an offset) and the silverbox multisine block (`V1` → `V2`,
//! ARX(7,9,0)) — and the timing of one case. The records themselves are not part of the project: the
//! caller reads them from a data folder that holds the public EMPS and silverbox benchmark records
//! (nonlinearbenchmark.org) and skips a case whose file is absent.

use std::hint::black_box;
use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};

use crate::bench::time_it;
use sysid::data::{CsvOptions, RowRange};
use sysid::metrics::metrics;
use sysid::{identify, Identification, Method};
use sysid::{Dataset, ModelKind, SysidError};

/// One output-error benchmark case: a real record and the ARX structure identified on it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct OeCase {
    /// Short name (`emps`, `silverbox`).
    pub name: &'static str,
    /// The CSV file, relative to the data folder.
    pub file: &'static str,
    /// Input column u.
    pub u_col: &'static str,
    /// Output column y.
    pub y_col: &'static str,
    /// Sampling period Ts in s when the file has no time column.
    pub ts_s: Option<f64>,
    /// Data rows used (0-based, half-open), `None` for all.
    pub rows: Option<(usize, usize)>,
    /// na, nb, nk of the ARX model.
    pub orders: (usize, usize, usize),
    /// Estimate a constant offset c.
    pub offset: bool,
}

/// The two cases of issue 16's table, with the rows and columns of their SOURCE.md split conventions:
/// all of `DATA_EMPS.csv` (24 841 samples, Ts = 1 ms from its time column), and the silverbox
/// multisine train block [40650, 105712) (65 062 samples, Ts = 2^14 / 10^7 s = 1.6384 ms).
pub const OE_CASES: [OeCase; 2] = [
    OeCase {
        name: "emps",
        file: "emps/DATA_EMPS.csv",
        u_col: "vir",
        y_col: "qm",
        ts_s: None,
        rows: None,
        orders: (6, 5, 0),
        offset: true,
    },
    OeCase {
        name: "silverbox",
        file: "silverbox/SNLS80mV.csv",
        u_col: "V1",
        y_col: "V2",
        ts_s: Some(0.0016384),
        rows: Some((40650, 105712)),
        orders: (7, 9, 0),
        offset: false,
    },
];

impl OeCase {
    /// The record's path inside `data_dir`.
    pub fn path(&self, data_dir: &Path) -> PathBuf {
        data_dir.join(self.file)
    }

    /// How to read the record (the same options as the equivalent `ipa-sysid identify` flags).
    pub fn csv_options(&self) -> CsvOptions {
        CsvOptions {
            u_col: self.u_col.into(),
            y_col: self.y_col.into(),
            ts: self.ts_s,
            rows: self.rows.map(|(a, b)| RowRange {
                start: Some(a),
                end: Some(b),
            }),
            ..CsvOptions::default()
        }
    }

    /// Output-error identification of the case's ARX structure (default settings otherwise).
    pub fn settings(&self) -> Identification {
        let (na, nb, nk) = self.orders;
        Identification::default()
            .with_kind(ModelKind::Arx)
            .with_orders(na, nb, nk)
            .with_offset(self.offset)
            .with_method(Method::Oe)
    }

    /// The `ipa-sysid identify` command that runs the same identification (data folder `data_dir`).
    pub fn command(&self, data_dir: &Path) -> String {
        let (na, nb, nk) = self.orders;
        let mut c = format!(
            "ipa-sysid identify --data {} --u-col {} --y-col {}",
            self.path(data_dir).display(),
            self.u_col,
            self.y_col
        );
        if let Some(ts) = self.ts_s {
            c.push_str(&format!(" --ts {ts}"));
        }
        if let Some((a, b)) = self.rows {
            c.push_str(&format!(" --rows {a}..{b}"));
        }
        c.push_str(&format!(
            " --model arx --na {na} --nb {nb} --nk {nk} --method oe"
        ));
        if self.offset {
            c.push_str(" --offset");
        }
        c
    }
}

/// Result of [`bench_oe`].
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct OeBench {
    /// Samples in the record.
    pub samples: usize,
    /// Wall time of one output-error identification (settings check, least-squares start, search,
    /// standard deviations), best run, s.
    pub seconds: f64,
    /// The same, median run.
    pub median_seconds: f64,
    /// Levenberg–Marquardt iterations of the search.
    pub iterations: usize,
    /// Whether the search reported convergence (not the iteration cap).
    pub converged: bool,
    /// How it stopped (`Termination`'s debug form).
    pub termination: String,
    /// Fit % of the free-run simulation on the record, initial outputs estimated (what `identify`
    /// prints as `fit % (simulation)`).
    pub fit_sim_percent: Option<f64>,
    /// Fit % of the free-run simulation from the measured initial outputs (`fit % (sim., y0 meas.)`).
    pub fit_sim_measured_percent: Option<f64>,
    /// Timed runs.
    pub repetitions: usize,
}

/// Times the output-error identification of `data` with `settings` (one untimed run, then
/// `repetitions` timed runs) and reports the iterations and simulation fits of the result.
pub fn bench_oe(
    data: &Dataset,
    settings: &Identification,
    repetitions: usize,
) -> Result<OeBench, SysidError> {
    let fit = identify(data, settings)?;
    let m = metrics(&fit.model, data)?;
    let t = time_it(repetitions, 1, || {
        black_box(identify(black_box(data), settings)?);
        Ok::<(), SysidError>(())
    })?;
    Ok(OeBench {
        samples: data.len(),
        seconds: t.best_s,
        median_seconds: t.median_s,
        iterations: fit.iterations,
        converged: fit.converged(),
        termination: format!("{:?}", fit.termination),
        fit_sim_percent: m.fit_sim_percent,
        fit_sim_measured_percent: m.fit_sim_measured_percent,
        repetitions: t.repetitions,
    })
}
