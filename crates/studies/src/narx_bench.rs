//! Polynomial NARX identification on real records (issue 23): the cases `ipa-sysid bench narx` times —
//! the cascaded tanks and the silverbox multisine block at the structures `order --classes` chooses on
//! their estimation records, and the coupled drives and hydraulic actuator records — with the test
//! record's free-run RMSE of each. The records are not part of the project: the caller reads them from
//! the shared data folder and skips a case whose file is absent.

use std::hint::black_box;
use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};

use crate::bench::time_it;
use sysid::data::{CsvOptions, RowRange};
use sysid::narx::{identify_narx, narx_metrics, NarxSettings, StopRule};
use sysid::{Dataset, SysidError};

/// One record part: file (relative to the data folder), input and output columns, data rows.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Part {
    /// The CSV file, relative to the data folder.
    pub file: &'static str,
    /// Input column u.
    pub u_col: &'static str,
    /// Output column y.
    pub y_col: &'static str,
    /// Data rows (0-based, half-open).
    pub rows: (usize, usize),
}

impl Part {
    /// How to read this part (Ts `ts_s`).
    pub fn csv_options(&self, ts_s: f64) -> CsvOptions {
        CsvOptions {
            u_col: self.u_col.into(),
            y_col: self.y_col.into(),
            ts: Some(ts_s),
            rows: Some(RowRange {
                start: Some(self.rows.0),
                end: Some(self.rows.1),
            }),
            ..CsvOptions::default()
        }
    }
}

/// One NARX benchmark case: estimation and test parts (the SOURCE.md splits) and the structure.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct NarxCase {
    /// Short name.
    pub name: &'static str,
    /// Estimation part.
    pub estimation: Part,
    /// Test part (never used by the identification).
    pub test: Part,
    /// Ts in s.
    pub ts_s: f64,
    /// na, nb, nk.
    pub na: usize,
    /// nb.
    pub nb: usize,
    /// nk.
    pub nk: usize,
    /// Degree D.
    pub degree: usize,
    /// The stopping rule.
    pub stop: StopRule,
}

/// The cases, each at the structure `order --classes` chose on its estimation record only
/// (docs/real-data.md): cascaded tanks (Est → Val columns, 1024 rows each), silverbox (multisine block,
/// [40650, 105712) → [105712, 127400); its number of terms by BIC, which takes a fifth of the time of the
/// sim rule for the same test RMSE), coupled drives (u1/z1, 250/250, the PR-SSM split) and the hydraulic
/// actuator (512/512).
pub const NARX_CASES: [NarxCase; 4] = [
    NarxCase {
        name: "cascaded_tanks",
        estimation: Part {
            file: "cascaded_tanks/dataBenchmark.csv",
            u_col: "uEst",
            y_col: "yEst",
            rows: (0, 1024),
        },
        test: Part {
            file: "cascaded_tanks/dataBenchmark.csv",
            u_col: "uVal",
            y_col: "yVal",
            rows: (0, 1024),
        },
        ts_s: 4.0,
        na: 2,
        nb: 2,
        nk: 0,
        degree: 3,
        stop: StopRule::Sim,
    },
    NarxCase {
        name: "silverbox",
        estimation: Part {
            file: "silverbox/SNLS80mV.csv",
            u_col: "V1",
            y_col: "V2",
            rows: (40650, 105712),
        },
        test: Part {
            file: "silverbox/SNLS80mV.csv",
            u_col: "V1",
            y_col: "V2",
            rows: (105712, 127400),
        },
        ts_s: 0.0016384,
        na: 3,
        nb: 3,
        nk: 0,
        degree: 3,
        stop: StopRule::Bic,
    },
    NarxCase {
        name: "coupled_drives",
        estimation: Part {
            file: "coupled_electric_drives_prbs/DATAPRBS.csv",
            u_col: "u1",
            y_col: "z1",
            rows: (0, 250),
        },
        test: Part {
            file: "coupled_electric_drives_prbs/DATAPRBS.csv",
            u_col: "u1",
            y_col: "z1",
            rows: (250, 500),
        },
        ts_s: 0.02,
        na: 3,
        nb: 4,
        nk: 2,
        degree: 3,
        stop: StopRule::Sim,
    },
    NarxCase {
        name: "hydraulic",
        estimation: Part {
            file: "hydraulic_actuator/actuator.csv",
            u_col: "u",
            y_col: "p",
            rows: (0, 512),
        },
        test: Part {
            file: "hydraulic_actuator/actuator.csv",
            u_col: "u",
            y_col: "p",
            rows: (512, 1024),
        },
        ts_s: 1.0,
        na: 4,
        nb: 2,
        nk: 0,
        degree: 3,
        stop: StopRule::Sim,
    },
];

impl NarxCase {
    /// The files of the case inside `data_dir`.
    pub fn paths(&self, data_dir: &Path) -> [PathBuf; 2] {
        [
            data_dir.join(self.estimation.file),
            data_dir.join(self.test.file),
        ]
    }

    /// The identification: the defaults of `identify --structure narx` (sim rule, refined), with the
    /// constant offered.
    pub fn settings(&self) -> NarxSettings {
        NarxSettings {
            na: self.na,
            nb: self.nb,
            nk: self.nk,
            degree: self.degree,
            constant: true,
            stop: self.stop,
            ..NarxSettings::default()
        }
    }

    /// The `ipa-sysid identify` command that runs the same identification.
    pub fn command(&self, data_dir: &Path) -> String {
        let [e, t] = self.paths(data_dir);
        let (er, tr) = (self.estimation.rows, self.test.rows);
        format!(
            "ipa-sysid identify --data {} --u-col {} --y-col {} --rows {}..{} --validation {} --val-u-col {} \
             --val-y-col {} --val-rows {}..{} --ts {} --offset --structure narx --na {} --nb {} --nk {} --degree {} \
             --stop {}",
            e.display(),
            self.estimation.u_col,
            self.estimation.y_col,
            er.0,
            er.1,
            t.display(),
            self.test.u_col,
            self.test.y_col,
            tr.0,
            tr.1,
            self.ts_s,
            self.na,
            self.nb,
            self.nk,
            self.degree,
            self.stop
        )
    }
}

/// Result of [`bench_narx`].
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct NarxBench {
    /// Samples of the estimation record.
    pub samples: usize,
    /// Wall time of one identification (selection, coefficients, refinement), best run, s.
    pub seconds: f64,
    /// The same, median run.
    pub median_seconds: f64,
    /// Selected terms.
    pub terms: usize,
    /// Free-run RMSE on the test record (measured initial outputs); `None`: the simulation blew up.
    pub test_rmse_sim: Option<f64>,
    /// Timed runs.
    pub repetitions: usize,
}

/// Times the NARX identification of `est` with `settings` and reports the test RMSE on `test`.
pub fn bench_narx(
    est: &Dataset,
    test: &Dataset,
    settings: &NarxSettings,
    repetitions: usize,
) -> Result<NarxBench, SysidError> {
    let fit = identify_narx(est, settings)?;
    let m = narx_metrics(&fit.model, test)?;
    let t = time_it(repetitions, 1, || {
        black_box(identify_narx(black_box(est), settings)?);
        Ok::<(), SysidError>(())
    })?;
    Ok(NarxBench {
        samples: est.len(),
        seconds: t.best_s,
        median_seconds: t.median_s,
        terms: fit.model.terms().len(),
        test_rmse_sim: m.rmse_sim,
        repetitions: t.repetitions,
    })
}
