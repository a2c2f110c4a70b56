//! `ipa-sysid bench oe`: seconds, iterations and fit of output-error identification on the EMPS and
//! silverbox records (`sysid_studies::oe_bench`), and on request SysIdentPy's FROLS on the same records
//! in the same run (`scripts/bench_sysidentpy.py`, run with the Python given by `--peer`).

use std::path::{Path, PathBuf};
use std::process::Command;

use anyhow::Context;
use serde::Serialize;
use sysid_studies::oe_bench::{bench_oe, OeBench, OE_CASES};

/// Flags of `bench oe`.
#[derive(Debug, clap::Args)]
pub struct OeArgs {
    /// Folder holding the public benchmark records `emps/DATA_EMPS.csv` and `silverbox/SNLS80mV.csv`
    /// (nonlinearbenchmark.org; not part of the project); a case whose file is absent is skipped with a
    /// message.
    #[arg(long, value_name = "DIR")]
    pub data_dir: PathBuf,
    /// Timed repetitions per case (the best and the median are reported).
    #[arg(long, default_value_t = 3, value_parser = clap::value_parser!(u64).range(1..=1000))]
    pub repetitions: u64,
    /// Also run the peer, SysIdentPy's FROLS on the same records, with this Python interpreter (one that
    /// has `sysidentpy` installed), in the same run.
    #[arg(long, value_name = "PYTHON")]
    pub peer: Option<PathBuf>,
    /// The peer's script.
    #[arg(
        long,
        value_name = "FILE",
        default_value = "scripts/bench_sysidentpy.py"
    )]
    pub peer_script: PathBuf,
    /// Write the result as JSON here (`-` for standard output).
    #[arg(long, value_name = "OUT")]
    pub json: Option<PathBuf>,
}

/// One case of the JSON output.
#[derive(Serialize)]
struct Case {
    name: &'static str,
    file: String,
    command: String,
    #[serde(skip_serializing_if = "Option::is_none")]
    output_error: Option<OeBench>,
    /// Why the case was not run (its file is absent).
    #[serde(skip_serializing_if = "Option::is_none")]
    skipped: Option<String>,
    /// The peer's result on the same record (its script's JSON for this case).
    #[serde(skip_serializing_if = "Option::is_none")]
    peer: Option<serde_json::Value>,
}

/// Runs `bench oe`.
pub fn run(a: OeArgs) -> anyhow::Result<()> {
    super::bench::check_data_dir(&a.data_dir)?;
    if let Some(python) = &a.peer {
        check_peer(python, &a.peer_script, "sysidentpy")?;
    }
    let reps = a.repetitions as usize;
    let mut text = format!(
        "Output-error identification (ARX, Levenberg-Marquardt on the simulation error), best of {reps}:\n"
    );
    let mut cases = Vec::new();
    let mut inputs: Vec<PathBuf> = Vec::new();
    for case in &OE_CASES {
        let path = case.path(&a.data_dir);
        let mut out = Case {
            name: case.name,
            file: path.display().to_string(),
            command: case.command(&a.data_dir),
            output_error: None,
            skipped: None,
            peer: None,
        };
        if !path.is_file() {
            let why = super::bench::absent(&path);
            text.push_str(&format!("  {:<10} skipped: {why}\n", case.name));
            out.skipped = Some(why);
            cases.push(out);
            continue;
        }
        let data = sysid::data::read_csv(&path, &case.csv_options())?;
        let r = bench_oe(&data, &case.settings(), reps)
            .with_context(|| format!("bench oe: case {}", case.name))?;
        let (na, nb, nk) = case.orders;
        text.push_str(&format!(
            "  {:<10} ({na},{nb},{nk}), {} samples: {:.3} s (median {:.3} s), {} iterations ({}), fit {} % (simulation), {} % (y0 measured)\n",
            case.name,
            r.samples,
            r.seconds,
            r.median_seconds,
            r.iterations,
            if r.converged { "converged" } else { "NOT converged" },
            percent(r.fit_sim_percent),
            percent(r.fit_sim_measured_percent),
        ));
        out.output_error = Some(r);
        inputs.push(path);
        cases.push(out);
    }
    let (peer, peer_failure) = match &a.peer {
        Some(python) if !inputs.is_empty() => {
            let r = run_peer(python, &a, &mut cases, &mut text);
            peer_outcome(r, &mut text)
        }
        Some(_) => {
            text.push_str("peer not run: no record was found\n");
            (None, None)
        }
        None => (None, None),
    };
    let out = super::bench::RecordBench {
        benchmark: "oe",
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

fn percent(v: Option<f64>) -> String {
    v.map_or_else(|| "n/a".into(), |f| format!("{f:.2}"))
}

/// Runs the peer script; adds its per-case results to `cases` and its lines to `text`; returns the
/// versions it reports.
fn run_peer(
    python: &Path,
    a: &OeArgs,
    cases: &mut [Case],
    text: &mut String,
) -> anyhow::Result<serde_json::Value> {
    let v = peer_json(
        python,
        &a.peer_script,
        &[
            "--data-dir".into(),
            a.data_dir.display().to_string(),
            "--repetitions".into(),
            a.repetitions.to_string(),
        ],
        None,
    )?;
    let versions = super::bench::peer_versions(&v);
    text.push_str(&format!(
        "Peer in the same run: SysIdentPy FROLS ({versions}):\n"
    ));
    for case in cases.iter_mut() {
        let Some(p) = super::bench::peer_case(&v, case.name) else {
            continue;
        };
        let num = |k: &str| p.get(k).and_then(serde_json::Value::as_f64);
        text.push_str(&format!(
            "  {:<10} {} samples: {} s (median {} s), {} terms, fit {} % (free-run simulation)\n",
            case.name,
            num("samples").map_or("?".into(), |n| format!("{n:.0}")),
            num("seconds").map_or("?".into(), |s| format!("{s:.3}")),
            num("median_seconds").map_or("?".into(), |s| format!("{s:.3}")),
            num("terms").map_or("?".into(), |n| format!("{n:.0}")),
            percent(num("fit_sim_percent")),
        ));
        if let (Some(ours), Some(theirs)) = (&case.output_error, num("seconds")) {
            text.push_str(&format!(
                "  {:<10} time ratio (SysIdentPy / ipa-sysid): {:.1}\n",
                "",
                theirs / ours.seconds.max(1e-12)
            ));
        }
        case.peer = Some(p.clone());
    }
    Ok(versions)
}

/// Checks, before any work, that the peer can run (audit s32 L-2): the interpreter `python` starts,
/// the script `script` is there, and `module` imports — in one short subprocess
/// (`python -c "import MODULE"`); the error names which of the three failed.
pub(super) fn check_peer(python: &Path, script: &Path, module: &str) -> anyhow::Result<()> {
    // The interpreter first (a missing one is not the script's fault), then the script, then the
    // module the interpreter already tried to import.
    let out = sysid_io::spawn_listed(
        Command::new(python)
            .args(["-c", &format!("import {module}")])
            .stdin(std::process::Stdio::null())
            .stdout(std::process::Stdio::piped())
            .stderr(std::process::Stdio::piped()),
    )
    .and_then(|(child, listed)| {
        let out = child.wait_with_output();
        drop(listed);
        out
    })
    .map_err(|e| {
        anyhow::anyhow!(
            "--peer {}: the interpreter cannot be run ({e}); give a Python interpreter that has \
                 {module}",
            python.display()
        )
    })?;
    if !script.is_file() {
        anyhow::bail!(
            "--peer-script {} is not there: run from the repository's root or pass --peer-script FILE",
            script.display()
        );
    }
    if !out.status.success() {
        let err = String::from_utf8_lossy(&out.stderr);
        let last = err
            .lines()
            .rev()
            .find(|l| !l.trim().is_empty())
            .unwrap_or("");
        anyhow::bail!(
            "--peer {}: this Python cannot import {module} ({}); install it there (pip install \
             {module}) or give a Python that has it",
            python.display(),
            sysid_core::format::visible(last.trim())
        );
    }
    Ok(())
}

/// The peer's result, or its failure as a warning line after ipa-sysid's own results (audit s32 L-2:
/// a failing peer left our results unprinted): `(versions, failure)`.
pub(super) fn peer_outcome(
    result: anyhow::Result<serde_json::Value>,
    text: &mut String,
) -> (Option<serde_json::Value>, Option<String>) {
    match result {
        Ok(v) => (Some(v), None),
        Err(e) => {
            let why = format!("{e:#}");
            text.push_str(&format!(
                "warning: the peer failed after ipa-sysid's own results above: {why}\n"
            ));
            (None, Some(why))
        }
    }
}

/// Runs a peer benchmark script (`python script ARGS --json -`, with `stdin` on its standard input if
/// given) and returns the JSON it prints; its failure is an error naming it.
pub(super) fn peer_json(
    python: &Path,
    script: &Path,
    args: &[String],
    stdin: Option<&str>,
) -> anyhow::Result<serde_json::Value> {
    use std::io::Write;
    use std::process::Stdio;
    // Listed: a signal that ends the benchmark ends and waits for the peer first (audit s36 M-4).
    let (mut child, listed) = sysid_io::spawn_listed(
        Command::new(python)
            .arg(script)
            .args(args)
            .args(["--json", "-"])
            .stdin(if stdin.is_some() {
                Stdio::piped()
            } else {
                Stdio::null()
            })
            .stdout(Stdio::piped())
            .stderr(Stdio::piped()),
    )
    .with_context(|| {
        format!(
            "--peer {}: cannot run {}",
            python.display(),
            script.display()
        )
    })?;
    if let (Some(text), Some(mut pipe)) = (stdin, child.stdin.take()) {
        pipe.write_all(text.as_bytes())?;
    }
    let output = child.wait_with_output();
    drop(listed);
    let output = output?;
    if !output.status.success() {
        anyhow::bail!(
            "--peer: {} {} failed ({}): {}",
            python.display(),
            script.display(),
            output.status,
            String::from_utf8_lossy(&output.stderr).trim()
        );
    }
    serde_json::from_slice(&output.stdout)
        .with_context(|| format!("--peer: {} did not print JSON", script.display()))
}
