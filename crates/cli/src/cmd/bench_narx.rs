//! `ipa-sysid bench narx`: seconds and test RMSE of polynomial NARX identification on real records
//! (`sysid_studies::narx_bench`), and on request SysIdentPy's FROLS on the same records, splits, lags and
//! degree in the same run (`scripts/bench_sysidentpy_narx.py`, with the Python given by `--peer`).

use std::path::{Path, PathBuf};

use anyhow::Context;
use serde::Serialize;
use sysid_studies::narx_bench::{bench_narx, NarxBench, NarxCase, NARX_CASES};

/// Flags of `bench narx`.
#[derive(Debug, clap::Args)]
pub struct NarxArgs {
    /// Folder holding the shared records (cascaded_tanks/, silverbox/, coupled_electric_drives_prbs/,
    /// hydraulic_actuator/); a case whose file is absent is skipped with a message.
    #[arg(long, value_name = "DIR")]
    pub data_dir: PathBuf,
    /// Timed repetitions per case (the best and the median are reported).
    #[arg(long, default_value_t = 3, value_parser = clap::value_parser!(u64).range(1..=1000))]
    pub repetitions: u64,
    /// Also run the peer, SysIdentPy's FROLS, with this Python interpreter (one with `sysidentpy`).
    #[arg(long, value_name = "PYTHON")]
    pub peer: Option<PathBuf>,
    /// The peer's script.
    #[arg(
        long,
        value_name = "FILE",
        default_value = "scripts/bench_sysidentpy_narx.py"
    )]
    pub peer_script: PathBuf,
    /// Write the result as JSON here (`-` for standard output).
    #[arg(long, value_name = "OUT")]
    pub json: Option<PathBuf>,
}

#[derive(Serialize)]
struct Case {
    #[serde(flatten)]
    case: NarxCase,
    command: String,
    #[serde(skip_serializing_if = "Option::is_none")]
    narx: Option<NarxBench>,
    #[serde(skip_serializing_if = "Option::is_none")]
    skipped: Option<String>,
    #[serde(skip_serializing_if = "Option::is_none")]
    peer: Option<serde_json::Value>,
}

fn rmse(v: Option<f64>) -> String {
    v.map_or_else(|| "blew up".into(), |r| format!("{r:.4e}"))
}

/// Runs `bench narx`.
pub fn run(a: NarxArgs) -> anyhow::Result<()> {
    super::bench::check_data_dir(&a.data_dir)?;
    if let Some(python) = &a.peer {
        super::bench_oe::check_peer(python, &a.peer_script, "sysidentpy")?;
    }
    let reps = a.repetitions as usize;
    let mut text = format!(
        "Polynomial NARX identification (FROLS, the stopping rule of each case, simulation-error refinement), best of {reps}:\n"
    );
    let mut cases = Vec::new();
    let mut inputs: Vec<PathBuf> = Vec::new();
    for case in &NARX_CASES {
        let [est_path, test_path] = case.paths(&a.data_dir);
        let mut out = Case {
            case: *case,
            command: case.command(&a.data_dir),
            narx: None,
            skipped: None,
            peer: None,
        };
        if !est_path.is_file() || !test_path.is_file() {
            let why = super::bench::absent(&est_path);
            text.push_str(&format!("  {:<16} skipped: {why}\n", case.name));
            out.skipped = Some(why);
            cases.push(out);
            continue;
        }
        let est = sysid::data::read_csv(&est_path, &case.estimation.csv_options(case.ts_s))?;
        let test = sysid::data::read_csv(&test_path, &case.test.csv_options(case.ts_s))?;
        let r = bench_narx(&est, &test, &case.settings(), reps)
            .with_context(|| format!("bench narx: case {}", case.name))?;
        text.push_str(&format!(
            "  {:<16} ({},{},{}) D={} --stop {}, {} samples: {:.3} s (median {:.3} s), {} terms, test RMSE (simulation) {}\n",
            case.name,
            case.na,
            case.nb,
            case.nk,
            case.degree,
            case.stop,
            r.samples,
            r.seconds,
            r.median_seconds,
            r.terms,
            rmse(r.test_rmse_sim)
        ));
        out.narx = Some(r);
        inputs.push(est_path);
        cases.push(out);
    }
    let (peer, peer_failure) = match &a.peer {
        Some(python) if !inputs.is_empty() => {
            let r = run_peer(python, &a, &mut cases, &mut text);
            super::bench_oe::peer_outcome(r, &mut text)
        }
        _ => (None, None),
    };
    let out = super::bench::RecordBench {
        benchmark: "narx",
        data_dir: a.data_dir.display().to_string(),
        repetitions: reps,
        cases,
        peer_versions: peer,
        peer_failure,
    };
    let ins: Vec<&Path> = inputs.iter().map(PathBuf::as_path).collect();
    super::bench::emit(&text, &out, &a.json, &ins)?;
    super::bench::peer_exit(&out)
}

/// Runs the peer script on the same cases (given on its standard input); adds its results.
fn run_peer(
    python: &Path,
    a: &NarxArgs,
    cases: &mut [Case],
    text: &mut String,
) -> anyhow::Result<serde_json::Value> {
    let spec: Vec<serde_json::Value> = cases
        .iter()
        .filter(|c| c.skipped.is_none())
        .map(|c| {
            let [e, t] = c.case.paths(&a.data_dir);
            let (er, tr) = (c.case.estimation.rows, c.case.test.rows);
            serde_json::json!({
                "name": c.case.name,
                "estimation": [e, c.case.estimation.u_col, c.case.estimation.y_col, er.0, er.1],
                "test": [t, c.case.test.u_col, c.case.test.y_col, tr.0, tr.1],
                "na": c.case.na, "nb": c.case.nb, "nk": c.case.nk, "degree": c.case.degree,
            })
        })
        .collect();
    let v = super::bench_oe::peer_json(
        python,
        &a.peer_script,
        &[
            "--cases".into(),
            "-".into(),
            "--repetitions".into(),
            a.repetitions.to_string(),
        ],
        Some(&serde_json::to_string(&spec)?),
    )?;
    let versions = super::bench::peer_versions(&v);
    text.push_str(&format!(
        "Peer in the same run: SysIdentPy FROLS, AIC, least squares ({versions}):\n"
    ));
    for case in cases.iter_mut() {
        let Some(p) = super::bench::peer_case(&v, case.case.name) else {
            continue;
        };
        let num = |k: &str| p.get(k).and_then(serde_json::Value::as_f64);
        text.push_str(&format!(
            "  {:<16} {} s (median {} s), {} terms, test RMSE (simulation) {}\n",
            case.case.name,
            num("seconds").map_or("?".into(), |s| format!("{s:.3}")),
            num("median_seconds").map_or("?".into(), |s| format!("{s:.3}")),
            num("terms").map_or("?".into(), |n| format!("{n:.0}")),
            rmse(num("test_rmse_sim")),
        ));
        case.peer = Some(p.clone());
    }
    Ok(versions)
}
