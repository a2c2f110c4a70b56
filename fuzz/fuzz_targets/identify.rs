//! Fuzz target: the identification pipeline on records and settings decoded from arbitrary bytes.
//! It must never panic or hang; Ok results must hold finite parameters.
#![no_main]

use libfuzzer_sys::fuzz_target;
use sysid::estimate::{identify, IdentifySettings, Method};
use sysid::{Dataset, ModelKind, Orders};

fuzz_target!(|bytes: &[u8]| {
    if bytes.len() < 4 {
        return;
    }
    let (head, rest) = bytes.split_at(4);
    let kind = if head[0] & 1 == 0 {
        ModelKind::Arx
    } else {
        ModelKind::Hammerstein
    };
    let method = match (head[0] >> 1) & 3 {
        0 => Method::Ls,
        1 => Method::Rls,
        2 => Method::Iv,
        _ => Method::Oe,
    };
    let orders = Orders {
        na: usize::from(head[1] % 6),
        nb: usize::from(head[2] % 4),
        nk: usize::from(head[3] % 4),
    };
    // u and y from pairs of little-endian f32 (finite ones only), at most 200 samples.
    let mut u = Vec::new();
    let mut y = Vec::new();
    for ch in rest.chunks_exact(8).take(200) {
        let a = f32::from_le_bytes([ch[0], ch[1], ch[2], ch[3]]) as f64;
        let b = f32::from_le_bytes([ch[4], ch[5], ch[6], ch[7]]) as f64;
        if a.is_finite() && b.is_finite() {
            u.push(a);
            y.push(b);
        }
    }
    let Ok(data) = Dataset::new(u, y, 0.01, "fuzz") else {
        return;
    };
    let settings = IdentifySettings {
        kind,
        orders,
        method,
        offset: head[0] & 8 != 0,
        drop_unexcited_branch: head[0] & 16 != 0,
        max_iterations: 20,
        iv_stages: 2,
        ..IdentifySettings::default()
    };
    if let Ok(fit) = identify(&data, &settings) {
        assert!(
            fit.params.iter().all(|p| p.value.is_finite()),
            "{:?}",
            fit.params
        );
        let _ = sysid::validation::metrics(&fit.model, &data);
    }
});
