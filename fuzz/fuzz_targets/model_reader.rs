//! Fuzz target: the model-file reader (`sysid::model_file`) on arbitrary bytes. It must never panic; an
//! accepted model must be consistent and finite, and must survive to_json -> parse_model unchanged.
#![no_main]

use libfuzzer_sys::fuzz_target;
use sysid::model_file::{parse_model, to_json};

fuzz_target!(|bytes: &[u8]| {
    if let Ok(model) = parse_model(bytes, "fuzz.json") {
        assert!(model.check().is_ok());
        let text = to_json(&model);
        let back = parse_model(text.as_bytes(), "again.json").expect("a written model reads back");
        assert_eq!(back, model);
        // Poles and a short simulation of any accepted model terminate without panicking.
        let _ = model.poles();
        let u = [1.0, -1.0, 2.0, 0.0, 5.0, -3.0, 1.0, 1.0];
        let _ = model.simulate(&u, &u);
    }
});
