//! `ipa-sysid calibrate` end to end: simulate a plant with known parameters, calibrate, and use the
//! written plant-config with the other commands.

#![allow(clippy::unwrap_used, clippy::expect_used, missing_docs)] // tests, benches and examples may panic

use std::path::Path;

mod common;
use common::bin;

fn run(dir: &Path, args: &[&str]) -> std::process::Output {
    bin().current_dir(dir).args(args).output().unwrap()
}

// A plant with a 20 % larger moving mass and supply conductance than the defaults: calibrating
// those two from the defaults recovers them (within 2 %, the target), the twin's TOML is a
// plant-config that `simulate` takes, and the JSON report has the twin and the Hammerstein baseline
// on the validation record, the twin far better (the baseline cannot follow stick-slip motion).
#[test]
fn calibrate_recovers_a_known_plant_and_writes_a_usable_plant_config() {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path();
    std::fs::write(
        p.join("truth.toml"),
        "[load]\nmoving_mass_kg = 0.72\n[valve]\nsupply_conductance_dm3_s_bar = 0.12\n",
    )
    .unwrap();
    for (input, seed, out) in [
        ("calibration", "1", "est.csv"),
        ("staircase", "2", "val.csv"),
    ] {
        let o = run(
            p,
            &[
                "simulate",
                "--plant-config",
                "truth.toml",
                "--input",
                input,
                "--samples",
                "1000",
                "--seed",
                seed,
                "--out",
                out,
            ],
        );
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    }
    let o = run(
        p,
        &[
            "calibrate",
            "--data",
            "est.csv",
            "--validation",
            "val.csv",
            "--free",
            "moving_mass,supply_conductance",
            "--out",
            "twin.toml",
            "--json",
            "twin.json",
        ],
    );
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let text = String::from_utf8_lossy(&o.stdout);
    assert!(text.contains("best Hammerstein model"), "{text}");
    let cfg = ipa::PlantConfig::from_toml_file(&p.join("twin.toml")).unwrap();
    assert!(
        (cfg.load.moving_mass_kg / 0.72 - 1.0).abs() < 0.02,
        "{cfg:?}"
    );
    assert!((cfg.valve.supply_conductance_dm3_s_bar / 0.12 - 1.0).abs() < 0.02);
    let j: serde_json::Value =
        serde_json::from_slice(&std::fs::read(p.join("twin.json")).unwrap()).unwrap();
    let twin = j["metrics"]["validation"]["fit_sim_measured_percent"]
        .as_f64()
        .unwrap();
    let hammerstein = j["hammerstein"]["fit_sim_measured_percent"]
        .as_f64()
        .unwrap();
    assert!(twin > 98.0 && twin > hammerstein, "{twin} vs {hammerstein}");
    assert!(j["warnings"].is_array());
    same_names_as_identify(p, &j);
}

/// Audit s17 L-d: calibrate's fits carry identify's names for the same quantities. The twin's fit and
/// RMSE on the validation record agree with fit = 100 (1 − RMSE·√N / ‖y − ȳ‖) over val.csv's y
/// (computed here); the Hammerstein comparison's fit is what `identify` prints under
/// `metrics.validation.fit_sim_measured_percent` for the same structure and estimator.
fn same_names_as_identify(p: &Path, j: &serde_json::Value) {
    let text = std::fs::read_to_string(p.join("val.csv")).unwrap();
    let mut lines = text.lines();
    let header: Vec<&str> = lines.next().unwrap().split(',').collect();
    let iy = header.iter().position(|h| *h == "y").unwrap();
    let y: Vec<f64> = lines
        .map(|l| l.split(',').nth(iy).unwrap().parse().unwrap())
        .collect();
    let mean = y.iter().sum::<f64>() / y.len() as f64;
    let spread = y.iter().map(|v| (v - mean).powi(2)).sum::<f64>().sqrt();
    let v = &j["metrics"]["validation"];
    let rmse = v["rmse_sim_measured"].as_f64().unwrap();
    let fit = v["fit_sim_measured_percent"].as_f64().unwrap();
    let expect = 100.0 * (1.0 - rmse * (y.len() as f64).sqrt() / spread);
    assert!((fit - expect).abs() < 1e-9, "{fit} vs {expect}");
    // The start plant's fits sit beside, under the same keys.
    assert!(j["start_metrics"]["estimation"]["fit_sim_measured_percent"].is_f64());
    assert!(j.get("fit_validation_percent").is_none());
    let h = &j["hammerstein"];
    let orders: Vec<String> = ["na", "nb", "nk"]
        .iter()
        .map(|k| h[*k].as_u64().unwrap().to_string())
        .collect();
    let o = run(
        p,
        &[
            "identify",
            "--data",
            "est.csv",
            "--validation",
            "val.csv",
            "--structure",
            "hammerstein",
            "--na",
            &orders[0],
            "--nb",
            &orders[1],
            "--nk",
            &orders[2],
            "--method",
            "oe",
            "--json",
            "id.json",
        ],
    );
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let id: serde_json::Value =
        serde_json::from_slice(&std::fs::read(p.join("id.json")).unwrap()).unwrap();
    let theirs = id["metrics"]["validation"]["fit_sim_measured_percent"]
        .as_f64()
        .unwrap();
    let ours = h["fit_sim_measured_percent"].as_f64().unwrap();
    assert!(
        (theirs - ours).abs() < 1e-9 * ours.abs().max(1.0),
        "{ours} vs identify's {theirs}"
    );
    let o = run(
        p,
        &[
            "simulate",
            "--plant-config",
            "twin.toml",
            "--samples",
            "50",
            "--out",
            "s.csv",
        ],
    );
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
}

// Bad input: an unknown parameter name, a missing column and an output over the input are refused
// with a message naming the culprit, exit code 2, and no file written.
#[test]
fn bad_calibrate_input_is_refused_clearly() {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path();
    std::fs::write(p.join("r.csv"), "t,u,pos\n0,0,1\n").unwrap();
    let o = run(
        p,
        &[
            "calibrate",
            "--data",
            "r.csv",
            "--free",
            "mass",
            "--out",
            "o.toml",
        ],
    );
    assert_eq!(o.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&o.stderr).contains("moving_mass"));
    // A parameter named twice, or both free and fixed, is a contradiction, not a set (audit s13 L4).
    for (flags, said) in [
        (
            &["--free", "moving_mass,moving_mass"][..],
            "names moving_mass twice",
        ),
        (
            &[
                "--free",
                "moving_mass,static_friction",
                "--fixed",
                "static_friction",
            ][..],
            "static_friction is named both free and fixed",
        ),
    ] {
        let mut args = vec!["calibrate", "--data", "r.csv", "--out", "o.toml"];
        args.extend_from_slice(flags);
        let o = run(p, &args);
        let e = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(2), "{e}");
        assert!(e.contains(said), "{e}");
    }
    let o = run(p, &["calibrate", "--data", "r.csv", "--out", "o.toml"]);
    assert_eq!(o.status.code(), Some(2));
    let e = String::from_utf8_lossy(&o.stderr);
    assert!(e.contains("r.csv") && e.contains('y'), "{e}");
    let o = run(p, &["calibrate", "--data", "r.csv", "--out", "r.csv"]);
    assert_eq!(o.status.code(), Some(2));
    assert!(!p.join("o.toml").exists());
    assert_eq!(
        std::fs::read_to_string(p.join("r.csv")).unwrap(),
        "t,u,pos\n0,0,1\n"
    );
}

// A record without motion (u = 1 count, y = 2 mm throughout) carries no information on any parameter
// (the Jacobian is 0): no standard deviation is reported as 0 (each is withheld and said, and every
// parameter is "not determined"); a record of 1e300 values makes the cost overflow: an error (exit 1)
// and no twin written (audit s10 F4).
#[test]
fn a_still_record_has_no_zero_standard_deviations_and_an_overflowing_one_fails() {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path();
    let still: String = std::iter::once("u,y\n".to_string())
        .chain((0..300).map(|_| "1,2\n".to_string()))
        .collect();
    std::fs::write(p.join("still.csv"), still).unwrap();
    let o = run(
        p,
        &[
            "calibrate",
            "--data",
            "still.csv",
            "--ts",
            "0.08",
            "--no-baseline",
            "--out",
            "s.toml",
            "--json",
            "s.json",
        ],
    );
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let doc: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(p.join("s.json")).unwrap()).unwrap();
    let text = doc.to_string();
    assert!(!text.contains("\"std\":0.0"), "{text}");
    let warnings = doc["warnings"].as_array().unwrap();
    assert!(
        warnings
            .iter()
            .any(|w| w.as_str().unwrap().contains("came out exactly 0")),
        "{warnings:?}"
    );
    let not_determined = warnings
        .iter()
        .filter(|w| w.as_str().unwrap().contains("is not determined"))
        .count();
    assert_eq!(not_determined, 12, "{warnings:?}");
    // With the comparison model asked for: a constant command cannot give one; the twin is still
    // written and the report says why there is no comparison (it was an error naming no file, audit
    // s13 L5).
    let o = run(
        p,
        &[
            "calibrate",
            "--data",
            "still.csv",
            "--ts",
            "0.08",
            "--out",
            "b.toml",
        ],
    );
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success(), "{err}");
    assert!(p.join("b.toml").exists());
    let report = String::from_utf8_lossy(&o.stdout);
    assert!(
        report.contains(
            "warning: no Hammerstein model could be identified for the comparison (still.csv"
        ),
        "{report}"
    );

    let huge: String = std::iter::once("u,y\n".to_string())
        .chain((0..300).map(|k| format!("{}e300,{}e300\n", 1 + k % 7, 4 + k % 3)))
        .collect();
    std::fs::write(p.join("huge.csv"), huge).unwrap();
    let o = run(
        p,
        &[
            "calibrate",
            "--data",
            "huge.csv",
            "--ts",
            "0.08",
            "--no-baseline",
            "--out",
            "h.toml",
            "--json",
            "h.json",
        ],
    );
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(1), "{err}");
    assert!(err.contains("cost is inf"), "{err}");
    assert!(!p.join("h.toml").exists() && !p.join("h.json").exists());
}

// A record the twin cannot follow (commands of a few counts, inside the valves' deadzone, and an output
// that swings anyway: another plant, or other units): the twin's free-run fit is below zero and the
// report says so, with the likely cause (audit s14 M-b: a −1.5 % twin was written without a word).
#[test]
fn a_twin_that_does_not_follow_its_record_is_said() {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path();
    let mut csv = String::from("t,u,y\n");
    for k in 0..400 {
        let x = k as f64 * 0.05;
        csv.push_str(&format!(
            "{:.2},{:.4},{:.4}\n",
            k as f64 * 0.01,
            3.4 + 3.0 * x.sin(),
            5.0 + 4.0 * (x - 0.6).sin()
        ));
    }
    std::fs::write(p.join("slow.csv"), csv).unwrap();
    let o = run(
        p,
        &[
            "calibrate",
            "--data",
            "slow.csv",
            "--no-baseline",
            "--out",
            "s.toml",
            "--json",
            "s.json",
        ],
    );
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let doc: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(p.join("s.json")).unwrap()).unwrap();
    let fit = doc["metrics"]["estimation"]["fit_sim_measured_percent"]
        .as_f64()
        .unwrap();
    assert!(fit <= 0.0, "{fit}");
    let warned = doc["warnings"].as_array().unwrap().iter().any(|w| {
        let w = w.as_str().unwrap();
        w.contains("the twin simulates the estimation record worse than its mean")
            && w.contains("inside the valves' deadzone")
    });
    assert!(warned, "{}", doc["warnings"]);

    // Audit s16 M8: the twin carries the verdict (a `[calibration]` table with the fit and every
    // warning of the report), and tune and control, run on it, repeat each warning.
    let toml = std::fs::read_to_string(p.join("s.toml")).unwrap();
    assert!(toml.contains("\n[calibration]\n"), "{toml}");
    let warnings: Vec<String> = doc["warnings"]
        .as_array()
        .unwrap()
        .iter()
        .map(|w| w.as_str().unwrap().to_string())
        .collect();
    let tune = run(
        p,
        &[
            "tune",
            "--plant-config",
            "s.toml",
            "--out",
            "c.json",
            "--variants",
            "1",
            "--max-evaluations",
            "8",
            "--physics-variants",
            "0",
        ],
    );
    let control = run(
        p,
        &[
            "control",
            "--plant",
            "ipa",
            "--plant-config",
            "s.toml",
            "--setpoint",
            "60",
            "--duration",
            "0.3",
        ],
    );
    for (name, o) in [("tune", &tune), ("control", &control)] {
        let text =
            String::from_utf8_lossy(&o.stdout).into_owned() + &String::from_utf8_lossy(&o.stderr);
        assert!(o.status.success(), "{name}: {text}");
        for w in &warnings {
            let repeated = format!(
                "this twin's calibration on slow.csv (free-run fit {fit:.2} % on it) warned: {w}"
            );
            assert!(
                text.contains(&repeated),
                "{name}: no '{repeated}' in {text}"
            );
        }
    }
    // A plant config without the table (plant-config's output, a twin written before it): no such
    // warning.
    let o = run(p, &["plant-config"]);
    std::fs::write(p.join("plain.toml"), &o.stdout).unwrap();
    let o = run(
        p,
        &[
            "control",
            "--plant",
            "ipa",
            "--plant-config",
            "plain.toml",
            "--setpoint",
            "60",
            "--duration",
            "0.3",
        ],
    );
    let text =
        String::from_utf8_lossy(&o.stdout).into_owned() + &String::from_utf8_lossy(&o.stderr);
    assert!(
        o.status.success() && !text.contains("calibration"),
        "{text}"
    );
}

// Audit s16 M6: a record without a time column and without --ts is refused with identify's message
// (it was calibrated at an assumed 0.01 s without a word); with --ts, the report says the Ts used, in
// the text and the JSON.
#[test]
fn calibrate_without_a_time_column_needs_ts_as_identify_does() {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path();
    let o = run(
        p,
        &[
            "simulate",
            "--input",
            "calibration",
            "--samples",
            "300",
            "--seed",
            "2",
            "--out",
            "est.csv",
        ],
    );
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    // The record without its t column (the first).
    let text = std::fs::read_to_string(p.join("est.csv")).unwrap();
    let bare: String = text
        .lines()
        .map(|l| format!("{}\n", l.split_once(',').unwrap().1))
        .collect();
    std::fs::write(p.join("not.csv"), bare).unwrap();
    let identify = run(p, &["identify", "--data", "not.csv"]);
    let calibrate = run(
        p,
        &[
            "calibrate",
            "--data",
            "not.csv",
            "--out",
            "t.toml",
            "--no-baseline",
            "--max-iterations",
            "1",
        ],
    );
    let (ie, ce) = (
        String::from_utf8_lossy(&identify.stderr),
        String::from_utf8_lossy(&calibrate.stderr),
    );
    assert_eq!(identify.status.code(), Some(2), "{ie}");
    assert_eq!(calibrate.status.code(), Some(2), "{ce}");
    assert!(ie.contains("no time column 't' and no --ts"), "{ie}");
    assert_eq!(ie, ce);
    assert!(!p.join("t.toml").exists());

    let o = run(
        p,
        &[
            "calibrate",
            "--data",
            "not.csv",
            "--ts",
            "0.01",
            "--out",
            "t.toml",
            "--no-baseline",
            "--max-iterations",
            "1",
            "--json",
            "t.json",
        ],
    );
    let out = String::from_utf8_lossy(&o.stdout);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert!(
        out.starts_with("Calibrated twin of the physics IPA (Ts = 0.01 s;"),
        "{out}"
    );
    let doc: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(p.join("t.json")).unwrap()).unwrap();
    assert_eq!(doc["ts"].as_f64(), Some(0.01));
    let toml = std::fs::read_to_string(p.join("t.toml")).unwrap();
    assert!(toml.contains("\nts_s = 0.01\n"), "{toml}");
}

// calibrate reads its records with the reader every command uses (audit s13 M6/H3, L): a --ts that
// contradicts the record's time column is said (it sent the search into minutes of a plant twice too
// slow, without a word), a non-uniform time column is refused at its line, and the column flags are
// named as the command spells them (--u-col, not --u-column).
#[test]
fn calibrate_reads_records_like_every_command() {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path();
    let o = run(
        p,
        &[
            "simulate",
            "--input",
            "calibration",
            "--samples",
            "300",
            "--seed",
            "1",
            "--out",
            "est.csv",
        ],
    );
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let calibrate = |data: &str, extra: &[&str]| {
        let mut args = vec![
            "calibrate",
            "--data",
            data,
            "--out",
            "twin.toml",
            "--no-baseline",
            "--max-iterations",
            "1",
        ];
        args.extend(extra);
        run(p, &args)
    };
    let o = calibrate("est.csv", &["--ts", "0.02"]);
    let err = String::from_utf8_lossy(&o.stderr).into_owned();
    let out = String::from_utf8_lossy(&o.stdout).into_owned();
    assert!(o.status.success(), "{err}");
    assert!(
        (out + &err)
            .contains("--ts 0.02 s contradicts the time column t (its typical step is 0.01 s)"),
        "{err}"
    );
    // Audit s16 M9: said on standard error before the search, with a start line naming the work
    // (the report on standard output repeats the warning with the others).
    let contradiction = err
        .find("warning: --ts 0.02 s contradicts the time column t")
        .expect(&err);
    let start = err
        .find("calibrating 12 parameters on est.csv (300 samples, Ts = 0.02 s): up to 9 Levenberg-Marquardt")
        .expect(&err);
    assert!(contradiction < start, "{err}");

    // Row 100's time moved by half a step: refused at its line (data row 100 is line 102 with the header).
    let text = std::fs::read_to_string(p.join("est.csv")).unwrap();
    let mut lines: Vec<String> = text.lines().map(str::to_string).collect();
    let mut cells: Vec<String> = lines[101].split(',').map(str::to_string).collect();
    cells[0] = format!("{}", cells[0].parse::<f64>().unwrap() + 0.005);
    lines[101] = cells.join(",");
    std::fs::write(p.join("jitter.csv"), lines.join("\n") + "\n").unwrap();
    let o = calibrate("jitter.csv", &[]);
    let err = String::from_utf8_lossy(&o.stderr).into_owned();
    assert_eq!(o.status.code(), Some(2), "{err}");
    assert!(
        err.contains("jitter.csv:102:1: non-uniform sampling"),
        "{err}"
    );

    // The shared reader's flags: a file without a header, columns by position (1-based).
    std::fs::write(
        p.join("bare.csv"),
        text.lines()
            .skip(1)
            .map(|l| format!("{l}\n"))
            .collect::<String>(),
    )
    .unwrap();
    let o = calibrate(
        "bare.csv",
        &[
            "--no-header",
            "--t-col",
            "1",
            "--u-col",
            "2",
            "--y-col",
            "3",
        ],
    );
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));

    let o = calibrate("est.csv", &["--u-col", "command"]);
    let err = String::from_utf8_lossy(&o.stderr).into_owned();
    assert_eq!(o.status.code(), Some(2), "{err}");
    assert!(
        err.contains("--u-col") && !err.contains("--u-column"),
        "{err}"
    );
}

// Audit s14 L-e: the validation record's columns named apart (`--val-u-col`/`--val-y-col`, as identify
// and order have them: the cascaded-tanks file holds both records). A file with the validation record
// in columns uv, yv gives the twin's validation fit of the same record written alone as u, y; the flags
// without --validation are refused.
#[test]
fn calibrate_takes_the_validation_records_own_columns() {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path();
    for (seed, out) in [("1", "est.csv"), ("2", "val.csv")] {
        let o = run(
            p,
            &[
                "simulate",
                "--input",
                "calibration",
                "--samples",
                "300",
                "--seed",
                seed,
                "--out",
                out,
            ],
        );
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    }
    // Every column of est.csv (t, u, y and the pressures) beside val.csv's u, y as uv, yv; val.csv
    // without its pressures (the twin is judged on the position).
    let est = std::fs::read_to_string(p.join("est.csv")).unwrap();
    let val = std::fs::read_to_string(p.join("val.csv")).unwrap();
    let col = |l: &str, i: usize| l.split(',').nth(i).unwrap().to_string();
    assert!(est.lines().next().unwrap().starts_with("t,u,y"));
    let both: String = est
        .lines()
        .zip(val.lines())
        .enumerate()
        .map(|(k, (e, v))| {
            if k == 0 {
                format!("{e},uv,yv\n")
            } else {
                format!("{e},{},{}\n", col(v, 1), col(v, 2))
            }
        })
        .collect();
    std::fs::write(
        p.join("val.csv"),
        val.lines()
            .map(|v| format!("{},{},{}\n", col(v, 0), col(v, 1), col(v, 2)))
            .collect::<String>(),
    )
    .unwrap();
    std::fs::write(p.join("both.csv"), both).unwrap();
    let fit = |args: &[&str], json: &str| {
        let mut a = vec![
            "calibrate",
            "--out",
            "twin.toml",
            "--no-baseline",
            "--max-iterations",
            "1",
            "--json",
            json,
        ];
        a.extend(args);
        let o = run(p, &a);
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        let v: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(p.join(json)).unwrap()).unwrap();
        v["metrics"]["validation"]["fit_sim_measured_percent"]
            .as_f64()
            .unwrap()
    };
    let alone = fit(&["--data", "est.csv", "--validation", "val.csv"], "a.json");
    let apart = fit(
        &[
            "--data",
            "both.csv",
            "--validation",
            "both.csv",
            "--val-u-col",
            "uv",
            "--val-y-col",
            "yv",
        ],
        "b.json",
    );
    assert_eq!(alone, apart);
    let o = run(
        p,
        &[
            "calibrate",
            "--data",
            "est.csv",
            "--out",
            "t2.toml",
            "--val-u-col",
            "uv",
        ],
    );
    assert_eq!(o.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&o.stderr).contains("--validation"));
}

// Audit s28 M-3: an --out that holds a user's text is refused before the record is read or the
// search starts (no start line on standard error, no "wrote" line), and the file is kept; an --out that
// cannot be written (/dev/full) gives no "wrote" line, which is printed only after the twin is written.
#[test]
fn calibrate_refuses_a_users_file_before_the_search_and_says_wrote_only_after_writing() {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path();
    let o = run(
        p,
        &[
            "simulate",
            "--input",
            "calibration",
            "--samples",
            "400",
            "--seed",
            "1",
            "--out",
            "est.csv",
        ],
    );
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    std::fs::write(p.join("user.txt"), "precious user text\n").unwrap();
    let o = run(
        p,
        &[
            "calibrate",
            "--data",
            "est.csv",
            "--out",
            "user.txt",
            "--max-iterations",
            "2",
        ],
    );
    let (out, err) = (
        String::from_utf8_lossy(&o.stdout),
        String::from_utf8_lossy(&o.stderr),
    );
    assert_eq!(o.status.code(), Some(2), "{out}{err}");
    assert!(err.contains("refusing to replace it"), "{err}");
    assert!(!err.contains("calibrating "), "the search ran first: {err}");
    assert!(!out.contains("wrote"), "{out}");
    assert_eq!(
        std::fs::read_to_string(p.join("user.txt")).unwrap(),
        "precious user text\n"
    );
    if Path::new("/dev/full").exists() {
        let o = run(
            p,
            &[
                "calibrate",
                "--data",
                "est.csv",
                "--out",
                "/dev/full",
                "--max-iterations",
                "2",
            ],
        );
        let out = String::from_utf8_lossy(&o.stdout);
        assert_ne!(o.status.code(), Some(0));
        assert!(!out.contains("wrote"), "{out}");
    } else {
        eprintln!("SKIPPED: /dev/full is absent here; the device case was not run");
    }
    let o = run(
        p,
        &[
            "calibrate",
            "--data",
            "est.csv",
            "--out",
            "twin.toml",
            "--max-iterations",
            "2",
        ],
    );
    let out = String::from_utf8_lossy(&o.stdout);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert!(
        out.trim_end()
            .ends_with("wrote twin.toml (use: --plant ipa --plant-config twin.toml)"),
        "{out}"
    );
    assert!(p.join("twin.toml").exists());
}

// Audit s28 L-5: a record whose positions are in metres (the physics plant's own record divided by
// 1000 here) is said to be perhaps in metres; the same record in mm is not. The banner's bound on the
// iterations is the one the report counts against: M = 2 per search, four plans of at most
// ⌈M/2⌉ + M, M, 2⌈M/2⌉ + M and ⌈M/2⌉ + 2M iterations: 4 + 10 = 14 in all.
#[test]
fn a_record_in_metres_is_questioned_and_the_iterations_are_counted_one_way() {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path();
    let o = run(
        p,
        &[
            "simulate",
            "--input",
            "calibration",
            "--samples",
            "1500",
            "--seed",
            "3",
            "--out",
            "mm.csv",
        ],
    );
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let text = std::fs::read_to_string(p.join("mm.csv")).unwrap();
    let mut lines = text.lines();
    let header = lines.next().unwrap();
    let yi = header.split(',').position(|c| c == "y").unwrap();
    let mut metres = format!("{header}\n");
    for line in lines {
        let cells: Vec<String> = line
            .split(',')
            .enumerate()
            .map(|(i, c)| {
                if i == yi {
                    format!("{}", c.parse::<f64>().unwrap() / 1000.0)
                } else {
                    c.to_string()
                }
            })
            .collect();
        metres.push_str(&cells.join(","));
        metres.push('\n');
    }
    std::fs::write(p.join("m.csv"), metres).unwrap();
    let calibrate = |data: &str| {
        let o = run(
            p,
            &[
                "calibrate",
                "--data",
                data,
                "--max-iterations",
                "2",
                "--no-baseline",
                "--out",
                "twin.toml",
                "--json",
                "twin.json",
            ],
        );
        let err = String::from_utf8_lossy(&o.stderr).into_owned();
        assert!(o.status.success(), "{err}");
        let doc: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(p.join("twin.json")).unwrap()).unwrap();
        (String::from_utf8_lossy(&o.stdout).into_owned() + &err, doc)
    };
    let (err, doc) = calibrate("m.csv");
    assert!(
        err.contains("up to 14 Levenberg-Marquardt iterations in all"),
        "{err}"
    );
    let iterations = doc["iterations"].as_u64().unwrap();
    assert!(iterations <= 14, "{iterations}");
    let hinted = |doc: &serde_json::Value| {
        doc["warnings"]
            .as_array()
            .unwrap()
            .iter()
            .any(|w| w.as_str().unwrap().contains("is y in metres?"))
    };
    assert!(hinted(&doc), "{}", doc["warnings"]);
    assert!(err.contains("is y in metres?"), "{err}");
    // A twin that does not follow its record is not offered for use (audit s30 L-12).
    assert!(
        err.contains("it does not follow the record") && !err.contains("(use: --plant"),
        "{err}"
    );
    let (err, doc) = calibrate("mm.csv");
    assert!(!hinted(&doc) && !err.contains("metres"), "{err}");
    assert!(
        err.contains("(use: --plant ipa --plant-config twin.toml)"),
        "{err}"
    );
}

// Audit s37 M-4: a MAT-file holding the plant's pressure vectors p_a_pa and p_b_pa beside t, u, y was
// calibrated without them, without a word (a CSV's header gives them by default). The same record as a
// CSV and as a MAT-file's vectors gives the same twin, "with pressures", but for the record's name.
#[test]
fn calibrate_reads_the_pressures_of_a_mat_file_as_of_a_csv() {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path();
    let o = run(
        p,
        &[
            "simulate",
            "--input",
            "calibration",
            "--samples",
            "600",
            "--seed",
            "1",
            "--out",
            "rec.csv",
        ],
    );
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let text = std::fs::read_to_string(p.join("rec.csv")).unwrap();
    let mut lines = text.lines();
    let header: Vec<&str> = lines.next().unwrap().split(',').collect();
    assert!(
        header.contains(&"p_a_pa") && header.contains(&"p_b_pa"),
        "{header:?}"
    );
    let mut columns = vec![Vec::new(); header.len()];
    for line in lines {
        for (c, v) in columns.iter_mut().zip(line.split(',')) {
            c.push(v.parse::<f64>().unwrap());
        }
    }
    let refs: Vec<&[f64]> = columns.iter().map(Vec::as_slice).collect();
    common::write_mat(&p.join("rec.mat"), &header, &refs);
    let mut twins = Vec::new();
    for (data, out) in [("rec.csv", "twin_csv.toml"), ("rec.mat", "twin_mat.toml")] {
        let o = run(
            p,
            &[
                "calibrate",
                "--data",
                data,
                "--out",
                out,
                "--no-baseline",
                "--max-iterations",
                "2",
            ],
        );
        let said = String::from_utf8_lossy(&o.stdout).into_owned();
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        assert!(said.contains("with pressures"), "{data}: {said}");
        let twin = std::fs::read_to_string(p.join(out)).unwrap();
        twins.push(twin.replace(data, "RECORD"));
    }
    assert_eq!(twins[0], twins[1]);
}
