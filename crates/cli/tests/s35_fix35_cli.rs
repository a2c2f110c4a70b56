//! Session 35, helper fix35: audit s34 L-4 (common logger layouts), L-8 (a validation record in ms
//! for `identify` / `order`; a MAT-file matrix variable), through the command line.

#![allow(clippy::unwrap_used, clippy::expect_used, missing_docs)] // tests may panic

mod common;
use common::{arx_signals, bin, json, mat_tag, s, stderr, write_csv};

/// A record of y(k) = 0.9 y(k−1) + 0.5 u(k−1) driven by u = ±1 (a pseudo-random sign from the tests'
/// generator), 600 samples.
fn signals() -> (Vec<f64>, Vec<f64>) {
    let mut g = common::lcg(35);
    arx_signals(
        600,
        &[0.9],
        &[0.5],
        |_| {
            if g.unit() < 0.5 {
                -1.0
            } else {
                1.0
            }
        },
    )
}

fn fails(args: &[&str]) -> String {
    let o = bin().args(args).output().unwrap();
    assert_eq!(o.status.code(), Some(2), "{args:?}: {}", stderr(&o));
    stderr(&o)
}

// L-8: a validation record whose time column counts milliseconds (0, 10, 20, ...) against a 0.01 s
// estimation record: identify (in memory, merged records and in passes) and order name --time-unit ms and the Ts it
// gives, 10 ms = 0.01 s, as validate does.
#[test]
fn a_validation_record_in_milliseconds_gets_the_time_unit_hint_everywhere() {
    let dir = tempfile::tempdir().unwrap();
    let (u, y) = signals();
    let base = dir.path().join("base.csv");
    write_csv(&base, "t,u,y", Some(0.01), &[&u, &y]);
    let ms = dir.path().join("ms.csv");
    let t: Vec<f64> = (0..u.len()).map(|k| 10.0 * k as f64).collect();
    write_csv(&ms, "t,u,y", None, &[&t, &u, &y]);
    let arx = [
        "--structure",
        "arx",
        "--na",
        "1",
        "--nb",
        "1",
        "--nk",
        "1",
        "--method",
        "ls",
    ];
    let runs: [Vec<&str>; 4] = [
        [
            &["identify", "--data", s(&base), "--validation", s(&ms)][..],
            &arx[..],
        ]
        .concat(),
        [
            &[
                "identify",
                "--data",
                s(&base),
                s(&base),
                "--merge",
                "--validation",
                s(&ms),
            ][..],
            &arx[..],
        ]
        .concat(),
        [
            &[
                "identify",
                "--data",
                s(&base),
                "--validation",
                s(&ms),
                "--stream",
                "on",
            ][..],
            &arx[..],
        ]
        .concat(),
        vec!["order", "--data", s(&base), "--validation", s(&ms)],
    ];
    for args in runs {
        let e = fails(&args);
        assert!(
            e.contains("sampled at Ts = 10 s but the model was identified at Ts = 0.01 s"),
            "{args:?}: {e}"
        );
        assert!(
            e.contains("pass --time-unit ms: Ts = 0.01 s"),
            "{args:?}: {e}"
        );
    }
}

/// A MAT-file (Level 5, uncompressed) holding one double matrix `name` of `rows` x `cols`, column-major.
fn write_matrix(path: &std::path::Path, name: &str, rows: usize, cols: usize, values: &[f64]) {
    let mut bytes = b"MATLAB 5.0 MAT-file, ipa-sysid tests".to_vec();
    bytes.resize(124, b' ');
    bytes.extend_from_slice(&0x0100u16.to_le_bytes());
    bytes.extend_from_slice(b"IM");
    let mut body = Vec::new();
    mat_tag(&mut body, 6, &[6, 0, 0, 0, 0, 0, 0, 0]); // array flags: class 6 (double)
    let dims: Vec<u8> = [rows as i32, cols as i32]
        .iter()
        .flat_map(|d| d.to_le_bytes())
        .collect();
    mat_tag(&mut body, 5, &dims);
    mat_tag(&mut body, 1, name.as_bytes());
    let data: Vec<u8> = values.iter().flat_map(|v| v.to_le_bytes()).collect();
    mat_tag(&mut body, 9, &data);
    mat_tag(&mut bytes, 14, &body);
    std::fs::write(path, bytes).unwrap();
}

// L-8: MATLAB's z = [u y] saved whole (600 x 2) is refused with the MATLAB lines that save its columns
// as the vectors the reader reads, whether z is asked for or u and y are.
#[test]
fn a_mat_matrix_is_refused_with_the_lines_that_save_its_columns() {
    let dir = tempfile::tempdir().unwrap();
    let (u, y) = signals();
    let f = dir.path().join("z.mat");
    write_matrix(&f, "z", u.len(), 2, &[u, y].concat());
    let e = fails(&["identify", "--data", s(&f), "--ts", "0.01"]);
    assert!(
        e.contains("no variable named 'u'; the file holds 'z', a 600x2 matrix"),
        "{e}"
    );
    assert!(
        e.contains("u = z(:,1); y = z(:,2); save('record.mat', 'u', 'y')"),
        "{e}"
    );
    let e = fails(&["identify", "--data", s(&f), "--ts", "0.01", "--u-col", "z"]);
    assert!(e.contains("variable 'z' is a 600x2 array"), "{e}");
    assert!(e.contains("u = z(:,1); y = z(:,2)"), "{e}");
}

// L-4 (a): the record written with quoted decimal commas (pandas.to_csv(decimal=',')) gives the
// plain record's estimates, in memory and read in passes.
#[test]
fn quoted_decimal_commas_give_the_plain_records_estimates_in_memory_and_in_passes() {
    let dir = tempfile::tempdir().unwrap();
    let (u, y) = signals();
    let plain = dir.path().join("plain.csv");
    write_csv(&plain, "t,u,y", Some(0.01), &[&u, &y]);
    let quoted = dir.path().join("quoted.csv");
    let mut text = String::from("\"t\",\"u\",\"y\"\n");
    for k in 0..u.len() {
        let c = |v: f64| format!("\"{}\"", format!("{v:?}").replace('.', ","));
        text.push_str(&format!("{},{},{}\n", c(0.01 * k as f64), c(u[k]), c(y[k])));
    }
    std::fs::write(&quoted, text).unwrap();
    let theta = |data: &std::path::Path, stream: &str| {
        let out = dir.path().join(format!(
            "{}-{stream}.json",
            data.file_stem().unwrap().to_str().unwrap()
        ));
        let o = bin()
            .args([
                "identify",
                "--data",
                s(data),
                "--structure",
                "arx",
                "--na",
                "1",
                "--nb",
                "1",
                "--nk",
                "1",
                "--method",
                "ls",
                "--stream",
                stream,
                "--json",
                s(&out),
            ])
            .output()
            .unwrap();
        assert!(o.status.success(), "{}", stderr(&o));
        json(&out)["parameters"].clone()
    };
    let want = theta(&plain, "off");
    // The record is noise-free: A(q) = 1 − 0.9 q⁻¹ (a1 = −0.9 in MATLAB's sign), b1 = 0.5.
    assert!(
        (want[0]["value"].as_f64().unwrap() + 0.9).abs() < 1e-9,
        "{want}"
    );
    assert!(
        (want[1]["value"].as_f64().unwrap() - 0.5).abs() < 1e-9,
        "{want}"
    );
    for stream in ["off", "on"] {
        let got = theta(&quoted, stream);
        for i in 0..2 {
            let (a, b) = (
                got[i]["value"].as_f64().unwrap(),
                want[i]["value"].as_f64().unwrap(),
            );
            assert!((a - b).abs() < 1e-12, "{stream}: {got} vs {want}");
        }
    }
}

/// A one-sided Hammerstein record computed here by a plain loop: a staircase of 10 levels in 0..200
/// counts (never negative; 25 samples each), a deadzone b_r = 20, m_r = 0.01 and
/// y(k) = 0.8 y(k−1) + x(k−1), from rest; 2000 samples.
fn one_sided(dir: &std::path::Path) -> std::path::PathBuf {
    let levels = [
        0.0, 150.0, 40.0, 200.0, 10.0, 120.0, 60.0, 180.0, 90.0, 30.0,
    ];
    let n = 2000;
    let u: Vec<f64> = (0..n).map(|k| levels[(k / 25) % levels.len()]).collect();
    let x = |v: f64| if v >= 20.0 { 0.01 * (v - 20.0) } else { 0.0 };
    let mut y = vec![0.0; n];
    for k in 1..n {
        y[k] = 0.8 * y[k - 1] + x(u[k - 1]);
    }
    let path = dir.join("one_sided.csv");
    write_csv(&path, "t,u,y", Some(0.01), &[&u, &y]);
    path
}

// fix34 leftover (a): a record that never drives u < 0 holds the left slope at 0 (not estimated); the
// warning says that, not "m_l = 0 (that branch does not respond)". (b): validate says it once, not
// again as the identification's warning the model file repeats.
#[test]
fn a_one_sided_record_is_said_to_leave_a_branch_unestimated_once() {
    let dir = tempfile::tempdir().unwrap();
    let data = one_sided(dir.path());
    let model = dir.path().join("m.json");
    let report = dir.path().join("r.json");
    let o = bin()
        .args([
            "identify",
            "--data",
            s(&data),
            "--structure",
            "hammerstein",
            "--na",
            "1",
            "--nb",
            "1",
            "--nk",
            "1",
            "--method",
            "ls",
            "--save-model",
            s(&model),
            "--json",
            s(&report),
        ])
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", stderr(&o));
    let never = "the record never drives the left side of the deadzone (u < 0)";
    let w = common::warnings(&json(&report));
    let hits: Vec<&String> = w.iter().filter(|w| w.contains(never)).collect();
    assert_eq!(hits.len(), 1, "{w:?}");
    assert!(
        hits[0].contains("m_l = 0 is held, not measured"),
        "{}",
        hits[0]
    );
    assert!(!w.iter().any(|w| w.contains("does not respond")), "{w:?}");
    for stream in ["off", "on"] {
        let out = dir.path().join(format!("v-{stream}.json"));
        let o = bin()
            .args([
                "validate",
                "--model",
                s(&model),
                "--data",
                s(&data),
                "--stream",
                stream,
            ])
            .args(["--json", s(&out)])
            .output()
            .unwrap();
        assert!(o.status.success(), "{}", stderr(&o));
        let w = common::warnings(&json(&out));
        assert_eq!(
            w.iter().filter(|w| w.contains(never)).count(),
            1,
            "{stream}: {w:?}"
        );
        let text = format!("{}{}", common::stdout(&o), stderr(&o));
        assert_eq!(text.matches(never).count(), 1, "{stream}: {text}");
    }
}
