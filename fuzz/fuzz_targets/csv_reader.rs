//! Fuzz target: the CSV reader (`sysid::data`) on arbitrary bytes. It must never panic; an accepted
//! record must be finite, with equal lengths and a positive Ts.
#![no_main]

use libfuzzer_sys::fuzz_target;
use sysid::data::{read_csv_bytes, read_table, CsvOptions};

fuzz_target!(|bytes: &[u8]| {
    if let Ok(table) = read_table(bytes, "fuzz.csv") {
        for col in 0..table.headers.len() {
            if let Ok(v) = table.numbers(col) {
                assert!(v.iter().all(|x| x.is_finite()));
                assert_eq!(v.len(), table.len());
            }
        }
    }
    // With the time column, with --ts, and with a model's Ts as the fallback.
    for ts in [None, Some(0.01)] {
        for fallback_ts in [None, Some(0.02)] {
            let opts = CsvOptions {
                ts,
                fallback_ts,
                ..CsvOptions::default()
            };
            match read_csv_bytes(bytes, "fuzz.csv", &opts) {
                Ok(d) => {
                    assert_eq!(d.u.len(), d.y.len());
                    assert!(!d.is_empty());
                    assert!(d.u.iter().chain(&d.y).all(|x| x.is_finite()));
                    assert!(d.ts.is_finite() && d.ts > 0.0);
                }
                Err(e) => assert!(!e.to_string().is_empty()),
            }
        }
    }
});
