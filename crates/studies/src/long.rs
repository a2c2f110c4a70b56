//! `ipa-sysid bench long`: rows per second and peak memory of the streaming identification on long
//! records, beside the in-memory path and a numpy least-squares peer measured in the same run.
//!
//! Every measured program runs as a **child process** (the `ipa-sysid` binary itself, or Python), timed
//! by the wall clock from spawn to exit, and its peak resident memory is the child's own `ru_maxrss`
//! from `wait4` (Linux: KiB): the benchmark process's own allocations do not count. The records are
//! made by `ipa-sysid simulate --plant paper` into a folder chosen by the caller (a temporary one by
//! default) and are not kept.

use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::Instant;

use serde::Serialize;

/// One run of a child process.
#[derive(Debug, Clone, Serialize)]
pub struct ChildRun {
    /// Wall-clock seconds from spawn to exit.
    pub wall_s: f64,
    /// Peak resident set size of the child in bytes (`ru_maxrss`; `None` where `wait4` is missing).
    pub peak_rss_bytes: Option<u64>,
}

/// Runs `cmd` with its standard output and error written to `log`, waits for it, and measures it; a
/// failure (non-zero exit) is an error quoting the end of `log`.
pub fn run_measured(cmd: &mut Command, log: &Path) -> Result<ChildRun, String> {
    let file = std::fs::File::create(log).map_err(|e| format!("{}: {e}", log.display()))?;
    let err = file
        .try_clone()
        .map_err(|e| format!("{}: {e}", log.display()))?;
    let start = Instant::now();
    // Listed so that a signal ending the benchmark ends and waits for the child first (audit s36
    // M-4: a SIGTERM left `simulate` running, orphaned).
    let (child, listed) = sysid_io::spawn_listed(cmd.stdin(Stdio::null()).stdout(file).stderr(err))
        .map_err(|e| format!("cannot start {:?}: {e}", cmd.get_program()))?;
    let (ok, peak) = wait(child)?;
    drop(listed);
    let wall_s = start.elapsed().as_secs_f64();
    if !ok {
        let text = std::fs::read_to_string(log).unwrap_or_default();
        let tail: String = text
            .lines()
            .rev()
            .take(5)
            .collect::<Vec<_>>()
            .into_iter()
            .rev()
            .collect::<Vec<_>>()
            .join("\n");
        return Err(format!("{:?} failed:\n{tail}", cmd.get_program()));
    }
    Ok(ChildRun {
        wall_s,
        peak_rss_bytes: peak,
    })
}

/// Waits for `child`; (exited with 0, peak RSS in bytes).
#[cfg(unix)]
fn wait(child: std::process::Child) -> Result<(bool, Option<u64>), String> {
    let pid = child.id() as libc::pid_t;
    let mut status: libc::c_int = 0;
    // SAFETY: rusage is plain data that wait4 fills in; pid is our own child, not yet waited for.
    let mut usage: libc::rusage = unsafe { std::mem::zeroed() };
    let r = unsafe { libc::wait4(pid, &mut status, 0, &mut usage) };
    if r != pid {
        return Err(format!(
            "waiting for child {pid}: {}",
            std::io::Error::last_os_error()
        ));
    }
    let ok = libc::WIFEXITED(status) && libc::WEXITSTATUS(status) == 0;
    // ru_maxrss is in KiB on Linux.
    Ok((ok, u64::try_from(usage.ru_maxrss).ok().map(|k| k * 1024)))
}

/// Waits for `child`; (exited with 0, no peak memory measurement).
#[cfg(not(unix))]
fn wait(mut child: std::process::Child) -> Result<(bool, Option<u64>), String> {
    let status = child.wait().map_err(|e| e.to_string())?;
    Ok((status.success(), None))
}

/// What `bench long` runs.
#[derive(Debug, Clone)]
pub struct LongConfig {
    /// The `ipa-sysid` binary (the benchmark runs itself as a child).
    pub exe: PathBuf,
    /// Where the records and logs are written.
    pub dir: PathBuf,
    /// Record lengths N.
    pub rows: Vec<usize>,
    /// Also run the in-memory path (`--stream off`) on records of at most this many rows.
    pub in_memory_max: usize,
    /// The numpy peer: the Python interpreter and `scripts/bench_numpy_long.py`.
    pub numpy: Option<(PathBuf, PathBuf)>,
}

/// A program run on one record.
#[derive(Debug, Clone, Serialize)]
pub struct Measured {
    /// The child run.
    #[serde(flatten)]
    pub run: ChildRun,
    /// N / wall time.
    pub rows_per_s: f64,
    /// Largest |θ_i − θ_stream,i| / max(|θ_stream,i|, 1e-300) against the streamed parameters.
    pub max_rel_diff_to_stream: Option<f64>,
}

/// The numpy peer's own account of its run.
#[derive(Debug, Clone, Serialize)]
pub struct NumpyDetail {
    /// numpy version.
    pub numpy: String,
    /// Python version.
    pub python: String,
    /// Seconds reading the CSV (numpy.loadtxt).
    pub read_s: f64,
    /// Seconds in numpy.linalg.lstsq.
    pub solve_s: f64,
}

/// The results on one record length.
#[derive(Debug, Clone, Serialize)]
pub struct LongRow {
    /// N.
    pub rows: usize,
    /// Size of the CSV file in bytes.
    pub file_bytes: u64,
    /// `identify --structure arx --method ls --stream on` (ARX(3,1,1): θ, standard deviations, fit,
    /// loss, FPE, AIC, residual tests; three passes).
    pub stream: Measured,
    /// The same with `--stream off` (records of at most `in_memory_max` rows).
    pub in_memory: Option<Measured>,
    /// numpy.loadtxt + numpy.linalg.lstsq of the same regression (θ only).
    pub numpy: Option<Measured>,
    /// Versions and the split of the numpy time.
    pub numpy_detail: Option<NumpyDetail>,
    /// Why the numpy peer gave no result (numpy missing...), when it failed.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub numpy_error: Option<String>,
}

/// Runs the benchmark (see the module documentation); `progress` is told what runs.
pub fn bench_long(
    cfg: &LongConfig,
    mut progress: impl FnMut(&str),
) -> Result<Vec<LongRow>, String> {
    let mut out = Vec::new();
    for &n in &cfg.rows {
        let csv = cfg.dir.join(format!("long_{n}.csv"));
        let log = |what: &str| cfg.dir.join(format!("{what}_{n}.log"));
        progress(&format!("making a record of {n} rows"));
        run_measured(
            Command::new(&cfg.exe)
                .args([
                    "simulate",
                    "--plant",
                    "paper",
                    "--samples",
                    &n.to_string(),
                    "--seed",
                    "1",
                    "--noise-std",
                    "0.01",
                    "--out",
                ])
                .arg(&csv),
            &log("simulate"),
        )?;
        let file_bytes = std::fs::metadata(&csv).map_err(|e| e.to_string())?.len();
        let identify = |mode: &str| -> Result<(ChildRun, Vec<f64>), String> {
            let json = cfg.dir.join(format!("identify_{mode}_{n}.json"));
            let run = run_measured(
                Command::new(&cfg.exe)
                    .args(["identify", "--data"])
                    .arg(&csv)
                    .args([
                        "--structure",
                        "arx",
                        "--method",
                        "ls",
                        "--stream",
                        mode,
                        "--json",
                    ])
                    .arg(&json),
                &log(&format!("identify_{mode}")),
            )?;
            Ok((run, identify_theta(&json)?))
        };
        progress(&format!("streaming identification of {n} rows"));
        let (stream_run, theta) = identify("on")?;
        let measured = |run: ChildRun, other: Option<&[f64]>| Measured {
            rows_per_s: n as f64 / run.wall_s,
            run,
            max_rel_diff_to_stream: other.map(|o| max_rel_diff(o, &theta)),
        };
        let in_memory = if n <= cfg.in_memory_max {
            progress(&format!("in-memory identification of {n} rows"));
            let (run, t) = identify("off")?;
            Some(measured(run, Some(&t)))
        } else {
            None
        };
        let (mut numpy, mut numpy_detail, mut numpy_error) = (None, None, None);
        if let Some((python, script)) = &cfg.numpy {
            progress(&format!("numpy peer on {n} rows"));
            let json = cfg.dir.join(format!("numpy_{n}.json"));
            // A failing peer (no numpy) is reported, not fatal: the measurements above stand.
            let result = run_measured(
                Command::new(python)
                    .arg(script)
                    .arg("--data")
                    .arg(&csv)
                    .arg("--json")
                    .arg(&json),
                &log("numpy"),
            )
            .and_then(|run| numpy_result(&json).map(|r| (run, r)));
            match result {
                Ok((run, (t, detail))) => {
                    numpy = Some(measured(run, Some(&t)));
                    numpy_detail = Some(detail);
                }
                Err(e) => numpy_error = Some(e),
            }
        }
        // The record is not kept (up to gigabytes).
        let _ = std::fs::remove_file(&csv);
        out.push(LongRow {
            rows: n,
            file_bytes,
            stream: measured(stream_run, None),
            in_memory,
            numpy,
            numpy_detail,
            numpy_error,
        });
    }
    Ok(out)
}

fn read_json(path: &Path) -> Result<serde_json::Value, String> {
    let text = std::fs::read_to_string(path).map_err(|e| format!("{}: {e}", path.display()))?;
    serde_json::from_str(&text).map_err(|e| format!("{}: {e}", path.display()))
}

/// θ = [a1.., b1..] from an `identify --json` document.
fn identify_theta(path: &Path) -> Result<Vec<f64>, String> {
    let v = read_json(path)?;
    v["parameters"]
        .as_array()
        .map(|ps| ps.iter().filter_map(|p| p["value"].as_f64()).collect())
        .ok_or_else(|| format!("{}: no parameters", path.display()))
}

/// θ and the details from the numpy script's JSON.
fn numpy_result(path: &Path) -> Result<(Vec<f64>, NumpyDetail), String> {
    let v = read_json(path)?;
    let theta = v["theta"]
        .as_array()
        .map(|t| t.iter().filter_map(serde_json::Value::as_f64).collect())
        .ok_or_else(|| format!("{}: no theta", path.display()))?;
    let text = |k: &str| v[k].as_str().unwrap_or("?").to_string();
    let num = |k: &str| v[k].as_f64().unwrap_or(f64::NAN);
    Ok((
        theta,
        NumpyDetail {
            numpy: text("numpy"),
            python: text("python"),
            read_s: num("read_s"),
            solve_s: num("solve_s"),
        },
    ))
}

/// max_i |a_i − b_i| / max(|b_i|, 1e-300); infinite when the lengths differ.
pub fn max_rel_diff(a: &[f64], b: &[f64]) -> f64 {
    if a.len() != b.len() {
        return f64::INFINITY;
    }
    a.iter()
        .zip(b)
        .map(|(x, y)| (x - y).abs() / y.abs().max(1e-300))
        .fold(0.0, f64::max)
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used, clippy::expect_used)]
    use super::*;

    // A shell that holds 100 MB in a variable has a peak RSS of at least that, `true` far less: the
    // measurement is the child's, not this process's (which holds neither).
    #[cfg(target_os = "linux")]
    #[test]
    fn peak_memory_is_the_childs_own() {
        let dir = std::env::temp_dir();
        let log = dir.join(format!("ipa-sysid-long-{}.log", std::process::id()));
        let big = run_measured(
            Command::new("sh").args([
                "-c",
                "x=$(head -c 100000000 /dev/zero | tr '\\0' a); echo ${#x}",
            ]),
            &log,
        )
        .unwrap();
        let small = run_measured(&mut Command::new("true"), &log).unwrap();
        let _ = std::fs::remove_file(&log);
        assert!(small.peak_rss_bytes.unwrap() < 50_000_000, "{small:?}");
        assert!(big.peak_rss_bytes.unwrap() >= 100_000_000, "{big:?}");
        let e = run_measured(&mut Command::new("false"), &dir.join("x.log")).unwrap_err();
        assert!(e.contains("failed"), "{e}");
    }

    #[test]
    fn relative_difference_of_parameter_vectors() {
        assert_eq!(max_rel_diff(&[1.0, 2.0], &[1.0, 4.0]), 0.5);
        assert!(max_rel_diff(&[1.0], &[1.0, 2.0]).is_infinite());
    }
}
