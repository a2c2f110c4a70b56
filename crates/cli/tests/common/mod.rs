//! What the trust tests share: running the binary for its `--json` document and reading its
//! `warnings`. Each integration test that needs them declares `mod common;` (Cargo's convention: a
//! folder module is not compiled as a test of its own).

// Each test binary uses part of this module; the rest would be reported as dead code.
#![allow(dead_code, clippy::unwrap_used, clippy::expect_used)]

use std::path::Path;
use std::process::{Command, Output};

use serde_json::Value;

/// The binary under test.
pub fn bin() -> Command {
    Command::new(env!("CARGO_BIN_EXE_ipa-sysid"))
}

/// Runs `ipa-sysid ARGS` and returns what it did (exit status, standard output and error).
pub fn run(args: &[&str]) -> Output {
    bin().args(args).output().expect("run ipa-sysid")
}

/// A run's standard error as text.
pub fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

/// A run's standard output as text.
pub fn stdout(o: &Output) -> String {
    String::from_utf8_lossy(&o.stdout).into_owned()
}

/// A path as the `&str` an argument list takes (the tests' temporary paths are UTF-8).
pub fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

/// The JSON document a command wrote to `path` (`--json`, `--save-model`, `--out`).
pub fn json(path: &Path) -> Value {
    serde_json::from_str(&std::fs::read_to_string(path).unwrap()).unwrap()
}

/// Runs `ipa-sysid ARGS --json F` in `dir`; returns the exit code and the JSON document (the command
/// must have written one, whatever its exit code).
pub fn run_json_code(dir: &Path, args: &[&str]) -> (i32, Value) {
    let tmp = tempfile::tempdir().unwrap();
    let json = tmp.path().join("out.json");
    let out = bin()
        .current_dir(dir)
        .args(args)
        .arg("--json")
        .arg(&json)
        .output()
        .unwrap();
    let text = std::fs::read_to_string(&json).unwrap_or_else(|_| {
        panic!(
            "{args:?}: no JSON; {}",
            String::from_utf8_lossy(&out.stderr)
        )
    });
    (
        out.status.code().unwrap(),
        serde_json::from_str(&text).unwrap(),
    )
}

/// Runs `ipa-sysid ARGS --json F` in `dir` and returns the JSON document; the command must succeed.
pub fn run_json(dir: &Path, args: &[&str]) -> Value {
    let (code, doc) = run_json_code(dir, args);
    assert_eq!(code, 0, "{args:?} exited with {code}");
    doc
}

/// A CSV record `u,y` of `n` rows (n even) at `dir/long.csv` whose input is 0 and whose output moves
/// (0, 1, 0, 1, …): cheap to write and read, and no "the output never moves" refusal, so that a size
/// check is what a test of one meets.
pub fn moving_output_csv(dir: &Path, n: usize) -> std::path::PathBuf {
    let path = dir.join("long.csv");
    std::fs::write(&path, format!("u,y\n{}", "0,0\n0,1\n".repeat(n / 2))).unwrap();
    path
}

/// A control trace's columns (t, r, u, y): the CSV `control --out` and `reproduce` write.
pub type Trace = (Vec<f64>, Vec<f64>, Vec<f64>, Vec<f64>);

/// Reads a control trace (header `t,r,u,y`, four numbers a row) into its columns (t, r, u, y).
pub fn read_trace(path: &Path) -> Trace {
    let text = std::fs::read_to_string(path).unwrap();
    let mut lines = text.lines();
    assert_eq!(lines.next(), Some("t,r,u,y"), "{path:?}");
    let (mut t, mut r, mut u, mut y) = (vec![], vec![], vec![], vec![]);
    for line in lines {
        let v: Vec<f64> = line.split(',').map(|x| x.parse().unwrap()).collect();
        assert_eq!(v.len(), 4, "{path:?}: {line}");
        t.push(v[0]);
        r.push(v[1]);
        u.push(v[2]);
        y.push(v[3]);
    }
    (t, r, u, y)
}

/// What `tune` wrote ([`tune`]): the controller file, the report's JSON document, the text printed.
pub struct Tuned {
    /// The controller file (`--out`).
    pub controller: std::path::PathBuf,
    /// The report (`--json`).
    pub report: Value,
    /// Standard output (the table and the lines around it).
    pub text: String,
}

/// `ipa-sysid tune --model MODEL ARGS --out DIR/c.json --json DIR/t.json`, required to succeed: the
/// set-up of the tests that tune a model file and read what came out.
pub fn tune(dir: &Path, model: &Path, args: &[&str]) -> Tuned {
    let controller = dir.join("c.json");
    let json = dir.join("t.json");
    let o = bin()
        .args(["tune", "--model", model.to_str().unwrap()])
        .args(args)
        .args(["--out", controller.to_str().unwrap()])
        .args(["--json", json.to_str().unwrap()])
        .output()
        .expect("run ipa-sysid");
    assert!(o.status.success(), "{}", stderr(&o));
    Tuned {
        controller,
        report: serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap(),
        text: String::from_utf8_lossy(&o.stdout).into_owned(),
    }
}

/// The document's `warnings` list.
pub fn warnings(doc: &Value) -> Vec<String> {
    doc["warnings"]
        .as_array()
        .unwrap()
        .iter()
        .map(|w| w.as_str().unwrap().to_string())
        .collect()
}

/// A linear congruential generator (Knuth's MMIX constants): state ← 6364136223846793005 · state +
/// 1442695040888963407 (mod 2^64), starting from `seed`. Deterministic test data written here, so
/// independent of the library; the one generator of the CLI tests.
pub fn lcg(seed: u64) -> Lcg {
    Lcg(seed)
}

/// The state of [`lcg`].
#[derive(Debug, Clone)]
pub struct Lcg(u64);

impl Lcg {
    /// Steps the generator and returns its new state.
    pub fn next_u64(&mut self) -> u64 {
        self.0 = self
            .0
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        self.0
    }

    /// Steps the generator and returns its top 53 bits as a number in [0, 1).
    pub fn unit(&mut self) -> f64 {
        (self.next_u64() >> 11) as f64 / (1u64 << 53) as f64
    }
}

/// The noise-free ARX record y(k) = Σ_i a_i y(k−i) + Σ_j b_j u(k−j) (i = 1 … na, j = 1 … nb: nk = 1;
/// a and b as in the difference equation, A(q) = 1 − Σ a_i q⁻ⁱ) from rest, k = 0 … n − 1, with
/// u(k) = `input(k)`: test data computed here, independent of the library. Returns (u, y).
pub fn arx_signals(
    n: usize,
    a: &[f64],
    b: &[f64],
    mut input: impl FnMut(usize) -> f64,
) -> (Vec<f64>, Vec<f64>) {
    let (mut u, mut y) = (Vec::with_capacity(n), Vec::<f64>::with_capacity(n));
    for k in 0..n {
        u.push(input(k));
        let mut v = 0.0;
        for (i, ai) in a.iter().enumerate() {
            if let Some(j) = k.checked_sub(i + 1) {
                v += ai * y[j];
            }
        }
        for (i, bi) in b.iter().enumerate() {
            if let Some(j) = k.checked_sub(i + 1) {
                v += bi * u[j];
            }
        }
        y.push(v);
    }
    (u, y)
}

/// The paper's model (b1 = 1; deadzone b_l = −1.5, b_r = 1.41, m_l = 3.46·15.67e−4, m_r =
/// 2.38·15.67e−4) driven by a deterministic staircase (twelve levels in counts, 17 samples each, started
/// `phase` levels in), by a plain loop from rest, k = 0 … n − 1:
/// y(k) = 1.869 y(k−1) − 0.9976 y(k−2) + 0.1284 y(k−3) + x(k−1), x the deadzone's output.
/// Test data computed here, independent of the library. Returns (u, y).
pub fn paper_record(n: usize, phase: usize) -> (Vec<f64>, Vec<f64>) {
    let levels = [
        200.0, -120.0, 0.5, 255.0, -255.0, 60.0, -30.0, 1.0, -90.0, 140.0, -4.0, 25.0,
    ];
    let u: Vec<f64> = (0..n)
        .map(|k| levels[((k / 17) + phase) % levels.len()])
        .collect();
    let (bl, br, ml, mr) = (-1.5, 1.41, 3.46 * 15.67e-4, 2.38 * 15.67e-4);
    let dz = |v: f64| {
        if v >= br {
            mr * (v - br)
        } else if v <= bl {
            ml * (v - bl)
        } else {
            0.0
        }
    };
    let mut y = vec![0.0; n];
    for k in 1..n {
        let mut v = dz(u[k - 1]) + 1.869 * y[k - 1];
        if k >= 2 {
            v -= 0.9976 * y[k - 2];
        }
        if k >= 3 {
            v += 0.1284 * y[k - 3];
        }
        y[k] = v;
    }
    (u, y)
}

/// Writes the record `t,u,y` (t = k·`ts_s`) to `dir/name` ([`write_csv`]) and returns its path.
pub fn write_tuy(dir: &Path, name: &str, ts_s: f64, u: &[f64], y: &[f64]) -> std::path::PathBuf {
    let path = dir.join(name);
    write_csv(&path, "t,u,y", Some(ts_s), &[u, y]);
    path
}

/// Writes `columns` (equal lengths) to `path` as CSV under `header`; with `ts_s` each row starts with
/// its time t = k·Ts (the header names it). The one writer of the tests' generated records.
pub fn write_csv(path: &Path, header: &str, ts_s: Option<f64>, columns: &[&[f64]]) {
    use std::fmt::Write;
    let mut text = format!("{header}\n");
    for k in 0..columns.first().map_or(0, |c| c.len()) {
        let mut row: Vec<String> = ts_s
            .map(|ts| (k as f64 * ts).to_string())
            .into_iter()
            .collect();
        row.extend(columns.iter().map(|c| c[k].to_string()));
        let _ = writeln!(text, "{}", row.join(","));
    }
    std::fs::write(path, text).unwrap();
}

/// `identify --data DATA --structure arx --na NA --nb NB --method METHOD`: the argument list the tests
/// of an ARX identification start from (extend it with their own flags).
pub fn identify_arx<'a>(data: &'a Path, na: &'a str, nb: &'a str, method: &'a str) -> Vec<&'a str> {
    identify_arx_named(data.to_str().unwrap(), na, nb, method)
}

/// [`identify_arx`] of a record named by a string (a path relative to the test's folder).
pub fn identify_arx_named<'a>(
    data: &'a str,
    na: &'a str,
    nb: &'a str,
    method: &'a str,
) -> Vec<&'a str> {
    vec![
        "identify",
        "--data",
        data,
        "--structure",
        "arx",
        "--na",
        na,
        "--nb",
        nb,
        "--method",
        method,
    ]
}

/// Writes `columns` as double 1 x n variables named by `names` into a little-endian MATLAB Level 5
/// `.mat` file at `path` (uncompressed miMATRIX elements; MAT-File Format, MathWorks, ch. 1): test data
/// in the format `--data FILE.mat` reads, written here independently of the library's reader.
pub fn write_mat(path: &Path, names: &[&str], columns: &[&[f64]]) {
    let mut bytes = b"MATLAB 5.0 MAT-file, ipa-sysid tests".to_vec();
    bytes.resize(124, b' ');
    bytes.extend_from_slice(&0x0100u16.to_le_bytes());
    bytes.extend_from_slice(b"IM");
    let tag = |out: &mut Vec<u8>, ty: u32, len: usize| {
        out.extend_from_slice(&ty.to_le_bytes());
        out.extend_from_slice(&(len as u32).to_le_bytes());
    };
    let pad = |out: &mut Vec<u8>| out.resize(out.len().div_ceil(8) * 8, 0);
    for (name, values) in names.iter().zip(columns) {
        let mut body = Vec::new();
        tag(&mut body, 6, 8); // array flags: class 6 (double)
        body.extend_from_slice(&6u32.to_le_bytes());
        body.extend_from_slice(&0u32.to_le_bytes());
        tag(&mut body, 5, 8); // dimensions 1 x n
        body.extend_from_slice(&1i32.to_le_bytes());
        body.extend_from_slice(&(values.len() as i32).to_le_bytes());
        tag(&mut body, 1, name.len());
        body.extend_from_slice(name.as_bytes());
        pad(&mut body);
        tag(&mut body, 9, 8 * values.len()); // miDOUBLE
        for v in values.iter() {
            body.extend_from_slice(&v.to_le_bytes());
        }
        pad(&mut body);
        tag(&mut bytes, 14, body.len());
        bytes.extend_from_slice(&body);
    }
    std::fs::write(path, bytes).unwrap();
}

/// Appends a MAT-file (Level 5) data element: its 8-byte tag (type `ty`, byte count) and `data`,
/// padded with zeros to a multiple of 8 bytes. The tests' one writer of hand-built `.mat` elements.
pub fn mat_tag(out: &mut Vec<u8>, ty: u32, data: &[u8]) {
    out.extend_from_slice(&ty.to_le_bytes());
    out.extend_from_slice(&(data.len() as u32).to_le_bytes());
    out.extend_from_slice(data);
    out.resize(out.len().div_ceil(8) * 8, 0);
}

/// Every number of `a` within 1e-9 (relative, floor 1) of the same entry of `b`; same keys and shape.
pub fn assert_same(a: &serde_json::Value, b: &serde_json::Value, at: &str) {
    match (a, b) {
        (Value::Object(x), Value::Object(y)) => {
            let (kx, ky): (Vec<_>, Vec<_>) = (x.keys().collect(), y.keys().collect());
            assert_eq!(kx, ky, "{at}");
            for (k, v) in x {
                assert_same(v, &y[k], &format!("{at}.{k}"));
            }
        }
        (Value::Array(x), Value::Array(y)) => {
            assert_eq!(x.len(), y.len(), "{at}");
            for (i, (v, w)) in x.iter().zip(y).enumerate() {
                assert_same(v, w, &format!("{at}[{i}]"));
            }
        }
        (Value::Number(x), Value::Number(y)) => {
            let (x, y) = (x.as_f64().unwrap(), y.as_f64().unwrap());
            assert!(
                (x - y).abs() <= 1e-9 * x.abs().max(y.abs()).max(1.0),
                "{at}: {x} vs {y}"
            );
        }
        _ => assert_eq!(a, b, "{at}"),
    }
}
