//! Property tests of the file readers: the CSV reader and the model-file reader never panic, whatever
//! the bytes, and what they accept round-trips exactly.
//!
//! Case counts are modest so that the debug-mode run stays within a few seconds.

#![allow(clippy::unwrap_used, clippy::expect_used, missing_docs)] // tests, benches and examples may panic

use proptest::prelude::*;
use sysid::data::{read_csv_bytes, read_table, CsvOptions};
use sysid::model_file::{parse_model, to_json};
use sysid::{Deadzone, Model, ModelKind};

fn opts() -> CsvOptions {
    CsvOptions::default()
}

/// Any finite f64: ordinary magnitudes, extremes, subnormals, signed zeros.
fn finite() -> impl Strategy<Value = f64> {
    prop_oneof![
        4 => -1e3..1e3f64,
        1 => any::<f64>().prop_filter("finite", |v| v.is_finite()),
        1 => Just(0.0),
        1 => Just(-0.0),
        1 => Just(f64::MAX),
        1 => Just(-f64::MIN_POSITIVE),
        1 => Just(5e-324),
    ]
}

/// One CSV cell: numbers, empty, non-finite, text, quotes and other troublemakers.
fn cell() -> impl Strategy<Value = String> {
    prop_oneof![
        4 => finite().prop_map(|v| format!("{v:?}")),
        1 => Just(String::new()),
        1 => Just("NaN".to_string()),
        1 => Just("-inf".to_string()),
        1 => Just("1,5".to_string()),
        1 => Just("\"2\"".to_string()),
        1 => Just("\"unterminated".to_string()),
        1 => Just("1e999".to_string()),
        1 => Just(" 3 ".to_string()),
        1 => "[a-z\"' ]{0,6}",
    ]
}

fn delimiter() -> impl Strategy<Value = char> {
    prop_oneof![Just(','), Just(';'), Just('\t')]
}

fn line_end() -> impl Strategy<Value = &'static str> {
    prop_oneof![Just("\n"), Just("\r\n"), Just("\r")]
}

/// Structured but possibly wrong CSV: a header of plausible and implausible names, rows of random
/// length and content.
fn messy_csv() -> impl Strategy<Value = String> {
    let name = prop_oneof![
        Just("t".to_string()),
        Just("u".to_string()),
        Just("y".to_string()),
        Just("U".to_string()),
        Just(String::new()),
        Just("\"y\"".to_string()),
        "[a-z]{1,3}",
    ];
    (
        prop::collection::vec(name, 0..6),
        prop::collection::vec(prop::collection::vec(cell(), 0..6), 0..20),
        delimiter(),
        line_end(),
        any::<bool>(),
    )
        .prop_map(|(header, rows, d, eol, bom)| {
            let mut s = String::new();
            if bom {
                s.push('\u{feff}');
            }
            s += &header.join(&d.to_string());
            s += eol;
            for r in rows {
                s += &r.join(&d.to_string());
                s += eol;
            }
            s
        })
}

/// The invariants of an accepted record: equal lengths, finite values, a usable Ts.
fn check_dataset(d: &sysid::Dataset) {
    assert_eq!(d.u().len(), d.y().len());
    assert!(d.u().iter().chain(d.y()).all(|v| v.is_finite()));
    assert!(d.ts().is_finite() && d.ts() > 0.0);
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 256, ..ProptestConfig::default() })]

    // Arbitrary bytes: the reader returns Ok or Err, never panics; an error names the file.
    #[test]
    fn csv_reader_never_panics_on_arbitrary_bytes(bytes in prop::collection::vec(any::<u8>(), 0..400)) {
        let _ = read_table(&bytes, "fuzz.csv");
        match read_csv_bytes(&bytes, "fuzz.csv", &opts()) {
            Ok(d) => check_dataset(&d),
            Err(e) => prop_assert!(e.to_string().contains("fuzz.csv"), "{e}"),
        }
    }

    // Structured-but-wrong CSV (bad names, ragged rows, text, NaN, quotes, any delimiter and line end):
    // never panics; an accepted record is finite; an error names the file.
    #[test]
    fn csv_reader_never_panics_on_messy_csv(text in messy_csv(), ts in prop::option::of(-1.0..1.0f64)) {
        let o = CsvOptions { ts, ..opts() };
        match read_csv_bytes(text.as_bytes(), "messy.csv", &o) {
            Ok(d) => check_dataset(&d),
            Err(e) => {
                let m = e.to_string();
                // A bad file names the file; a bad setting (Ts ≤ 0 given with the record) names the setting.
                prop_assert!(
                    m.contains("messy.csv") || m.contains("setting ts =") || m.contains("--y-col"),
                    "{m}"
                );
            }
        }
    }

    // Valid CSV in every accepted dialect reads back bit for bit: u and y exactly, Ts from the time
    // column within rounding (t_k printed to 12 significant digits).
    #[test]
    fn valid_csv_round_trips_exactly(
        rows in prop::collection::vec((finite(), finite()), 2..60),
        ts in prop_oneof![Just(0.01), 1e-4..10.0f64],
        d in delimiter(),
        eol in prop_oneof![Just("\n"), Just("\r\n")],
        bom in any::<bool>(),
        quoted in any::<bool>(),
        spaces in any::<bool>(),
        decimal_comma in any::<bool>(),
        with_time in any::<bool>(),
    ) {
        let decimal_comma = decimal_comma && d != ',';
        let fmt = |v: f64| {
            let mut s = format!("{v:?}");
            if decimal_comma {
                s = s.replace('.', ",");
            }
            if quoted {
                s = format!("\"{s}\"");
            }
            if spaces {
                s = format!(" {s} ");
            }
            s
        };
        let mut text = String::new();
        if bom {
            text.push('\u{feff}');
        }
        let names: Vec<&str> = if with_time { vec!["t", "u", "y"] } else { vec!["u", "y"] };
        text += &names.join(&d.to_string());
        text += eol;
        for (k, (u, y)) in rows.iter().enumerate() {
            let mut cells = vec![fmt(*u), fmt(*y)];
            if with_time {
                let t: f64 = format!("{:.11e}", k as f64 * ts).parse().unwrap();
                cells.insert(0, fmt(t));
            }
            text += &cells.join(&d.to_string());
            text += eol;
        }
        let o = CsvOptions { ts: if with_time { None } else { Some(ts) }, ..opts() };
        let data = read_csv_bytes(text.as_bytes(), "gen.csv", &o).map_err(|e| TestCaseError::fail(format!("{e}\n{text}")))?;
        let (u, y): (Vec<f64>, Vec<f64>) = rows.iter().copied().unzip();
        prop_assert_eq!(data.u().iter().map(|v| v.to_bits()).collect::<Vec<_>>(), u.iter().map(|v| v.to_bits()).collect::<Vec<_>>());
        prop_assert_eq!(data.y().iter().map(|v| v.to_bits()).collect::<Vec<_>>(), y.iter().map(|v| v.to_bits()).collect::<Vec<_>>());
        prop_assert!((data.ts() - ts).abs() <= 1e-9 * ts, "{} vs {}", data.ts(), ts);
    }
}

/// Arbitrary JSON values, nested a few levels.
fn json_value() -> impl Strategy<Value = serde_json::Value> {
    let leaf = prop_oneof![
        Just(serde_json::Value::Null),
        any::<bool>().prop_map(serde_json::Value::Bool),
        any::<i64>().prop_map(|v| serde_json::json!(v)),
        finite().prop_map(|v| serde_json::json!(v)),
        prop_oneof![
            Just("ipa-sysid-model".to_string()),
            Just("hammerstein".to_string()),
            Just("arx".to_string()),
            "[a-z_]{0,8}"
        ]
        .prop_map(serde_json::Value::String),
    ];
    leaf.prop_recursive(4, 48, 8, |inner| {
        let key = prop_oneof![
            Just("format".to_string()),
            Just("version".to_string()),
            Just("model".to_string()),
            Just("kind".to_string()),
            Just("ts".to_string()),
            Just("na".to_string()),
            Just("nb".to_string()),
            Just("nk".to_string()),
            Just("a".to_string()),
            Just("b".to_string()),
            Just("offset".to_string()),
            Just("deadzone".to_string()),
            Just("b_l".to_string()),
            "[a-z]{1,4}",
        ];
        prop_oneof![
            prop::collection::vec(inner.clone(), 0..6).prop_map(serde_json::Value::Array),
            prop::collection::btree_map(key, inner, 0..8)
                .prop_map(|m| serde_json::Value::Object(m.into_iter().collect())),
        ]
    })
}

/// A valid model: consistent orders and lengths, finite coefficients, Ts > 0.
fn valid_model() -> impl Strategy<Value = Model> {
    (
        any::<bool>(),
        0usize..6,
        0usize..4,
        0usize..4,
        prop_oneof![Just(0.01), 1e-6..100.0f64],
        prop::option::of(-1e3..1e3f64),
        prop::collection::vec(finite(), 10),
        prop::collection::vec(-1e3..1e3f64, 4),
    )
        .prop_map(|(hammerstein, na, nb, nk, ts, offset, coef, dz)| {
            let nb = if hammerstein { nb.max(1) } else { nb };
            let mut b: Vec<f64> = coef[5..5 + nb].to_vec();
            if hammerstein {
                b[0] = 1.0;
            }
            let kind = if hammerstein {
                ModelKind::Hammerstein
            } else {
                ModelKind::Arx
            };
            let deadzone = hammerstein.then_some(Deadzone {
                b_l: dz[0],
                b_r: dz[1],
                m_l: dz[2],
                m_r: dz[3],
            });
            Model::siso(kind, ts, coef[..na].to_vec(), b, nk, deadzone, offset).unwrap()
        })
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 256, ..ProptestConfig::default() })]

    // Arbitrary bytes: the model reader never panics, and an error names the file.
    #[test]
    fn model_reader_never_panics_on_arbitrary_bytes(bytes in prop::collection::vec(any::<u8>(), 0..300)) {
        if let Err(e) = parse_model(&bytes, "fuzz.json") {
            prop_assert!(e.to_string().contains("fuzz.json"), "{e}");
        }
    }

    // Arbitrary JSON (objects with the model file's keys at any place and of any type): never panics;
    // what is accepted is a consistent, finite model.
    #[test]
    fn model_reader_never_panics_on_arbitrary_json(v in json_value(), wrap in any::<bool>()) {
        let v = if wrap {
            serde_json::json!({"format": "ipa-sysid-model", "version": 1, "model": v})
        } else {
            v
        };
        let text = serde_json::to_string(&v).unwrap();
        match parse_model(text.as_bytes(), "any.json") {
            // Accepted models are consistent by construction (private fields, validating
            // constructors); check the invariants the constructors promise.
            Ok(m) => prop_assert!(
                m.a().iter().chain(m.b()).all(|v| v.is_finite()) && m.ts() > 0.0 && m.ts().is_finite()
            ),
            Err(e) => prop_assert!(e.to_string().contains("any.json"), "{e}"),
        }
    }

    // A valid model survives to_json -> parse_model unchanged (every f64 bit for bit), and every
    // truncation of the file is refused, never accepted as a different model and never a panic.
    #[test]
    fn valid_models_round_trip_and_truncations_are_refused(m in valid_model(), cut in 0.0..1.0f64) {
        let text = to_json(&m).unwrap();
        let back = parse_model(text.as_bytes(), "m.json").map_err(|e| TestCaseError::fail(format!("{e}\n{text}")))?;
        prop_assert_eq!(&back, &m);
        let trimmed = text.trim_end();
        let at = ((trimmed.len() as f64) * cut) as usize;
        if at < trimmed.len() {
            let e = parse_model(&trimmed.as_bytes()[..at], "m.json");
            prop_assert!(e.is_err(), "truncated at {} of {} accepted", at, trimmed.len());
        }
    }
}
