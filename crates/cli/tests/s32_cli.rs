//! Audit s32 (coordinator's fixes). H-1: any JSON file without a "format" key was taken for an earlier `--json` report and
//! replaced without `--force` (`delay --json package.json` printed "replaced package.json"). Every
//! `--json` report now carries `"format": "ipa-sysid-report"` as its first key; a report replaces an
//! earlier report (or an empty file), any other JSON document is refused (exit 2, untouched) unless
//! `--force`. M-1: a constant input is refused in every structure (ARX with nb = 1 and no offset
//! printed a "gain" with exit 0).

#![allow(clippy::unwrap_used, clippy::expect_used, missing_docs)] // tests may panic

mod common;
use common::{arx_signals, bin, s, stderr, write_tuy};

#[test]
fn a_json_report_replaces_only_an_earlier_report() {
    let dir = tempfile::tempdir().unwrap();
    let (u, y) = arx_signals(400, &[0.5], &[1.0], |k| {
        if (k / 7) % 2 == 0 {
            1.0
        } else {
            -1.0
        }
    });
    let data = write_tuy(dir.path(), "a.csv", 0.1, &u, &y);
    let delay = |json: &std::path::Path, extra: &[&str]| {
        bin()
            .args(["delay", "--data", s(&data), "--json", s(json)])
            .args(extra)
            .output()
            .unwrap()
    };
    // A fresh report: its first key is the mark (the text, not only the parsed object).
    let report = dir.path().join("r.json");
    let o = delay(&report, &[]);
    assert!(o.status.success(), "{}", stderr(&o));
    let text = std::fs::read_to_string(&report).unwrap();
    assert!(
        text.starts_with("{\n  \"format\": \"ipa-sysid-report\",\n"),
        "{text}"
    );
    let v: serde_json::Value = serde_json::from_str(&text).unwrap();
    assert!(v["nk"].is_u64(), "{text}");
    // An earlier report is replaced, by the same command or another.
    assert!(delay(&report, &[]).status.success());
    let o = bin()
        .args([
            "identify",
            "--data",
            s(&data),
            "--structure",
            "arx",
            "--method",
            "ls",
        ])
        .args(["--json", s(&report)])
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", stderr(&o));
    // Other JSON documents: a package.json, an array, an object with other keys, a report of a version
    // before the mark. Each refused and left as it was; --force replaces it.
    let others = [
        "{\n \"name\": \"my-app\",\n \"version\": \"1.0.0\"\n}\n",
        "[1, 2, 3]\n",
        "{\"keep\": 1}\n",
        "{\n  \"data\": \"a.csv\",\n  \"nk\": 1\n}\n",
    ];
    for (i, content) in others.iter().enumerate() {
        let f = dir.path().join(format!("other{i}.json"));
        std::fs::write(&f, content).unwrap();
        let o = delay(&f, &[]);
        let err = stderr(&o);
        assert_eq!(o.status.code(), Some(2), "{content}: {err}");
        assert!(err.contains("not an ipa-sysid output"), "{content}: {err}");
        assert_eq!(std::fs::read_to_string(&f).unwrap(), *content);
        let o = delay(&f, &["--force"]);
        assert!(o.status.success(), "{}", stderr(&o));
        assert!(std::fs::read_to_string(&f)
            .unwrap()
            .contains("ipa-sysid-report"));
    }
    // A report on standard output carries the mark too (one document, parseable).
    let o = bin()
        .args(["delay", "--data", s(&data), "--json", "-"])
        .output()
        .unwrap();
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert_eq!(v["format"], "ipa-sysid-report");
}

#[test]
fn a_constant_input_is_refused_in_every_structure() {
    let dir = tempfile::tempdir().unwrap();
    // u = 1 at every sample, y(k) = 0.9 y(k−1) + 0.5 + a deterministic wobble (the level is not the
    // input's effect: nothing tells them apart).
    let n = 500;
    let u = vec![1.0; n];
    let mut y = vec![0.0; n];
    for k in 1..n {
        y[k] = 0.9 * y[k - 1] + 0.5 + 0.1 * ((k * 7919) % 13) as f64 / 13.0;
    }
    let data = write_tuy(dir.path(), "constu.csv", 0.1, &u, &y);
    let says = "the input u is 1 at every sample: a constant input is not persistently exciting";
    for extra in [
        &[
            "--structure",
            "arx",
            "--method",
            "ls",
            "--na",
            "1",
            "--nb",
            "1",
            "--nk",
            "1",
        ][..],
        &[
            "--structure",
            "arx",
            "--method",
            "ls",
            "--na",
            "1",
            "--nb",
            "1",
            "--nk",
            "1",
            "--stream",
            "on",
        ],
        &[
            "--structure",
            "arx",
            "--method",
            "oe",
            "--na",
            "1",
            "--nb",
            "1",
            "--nk",
            "1",
        ],
        &["--structure", "arx", "--method", "ls", "--offset"],
        &["--method", "ls"],
    ] {
        let o = bin()
            .args(["identify", "--data", s(&data)])
            .args(extra)
            .output()
            .unwrap();
        let err = stderr(&o);
        assert_eq!(o.status.code(), Some(2), "{extra:?}: {err}");
        assert!(err.contains(says), "{extra:?}: {err}");
    }
    // One changing sample is enough to be let through (that the estimate is poorly determined is the
    // rest of the tool's business).
    let mut u2 = u.clone();
    u2[250] = 2.0;
    let data2 = write_tuy(dir.path(), "oneblip.csv", 0.1, &u2, &y);
    let o = bin()
        .args([
            "identify",
            "--data",
            s(&data2),
            "--structure",
            "arx",
            "--method",
            "ls",
        ])
        .args(["--na", "1", "--nb", "1", "--nk", "1"])
        .output()
        .unwrap();
    assert!(!stderr(&o).contains("constant input"), "{}", stderr(&o));
}
