"""Audit s22 (fixac): array arguments are bounded before the core copies them (H-B1), and text cells
written with a decimal comma get a hint naming pandas' decimal=',' (L-N5). Expectations are the refusal
and its words; the bound is MAX_SAMPLES = 50 000 000 samples (docs/reliability.md, "Resource bounds")."""

import json

import numpy as np
import pytest

import ipa_sysid


def _arx(tmp_path):
    model = {"kind": "arx", "ts": 0.1, "na": 1, "nb": 1, "nk": 1, "a": [-0.5], "b": [1.0],
             "offset": None, "noise_model": "equation-error"}
    path = tmp_path / "m.json"
    path.write_text(json.dumps({"format": "ipa-sysid-model", "version": 2, "model": model}))
    return ipa_sysid.load_model(str(path))


def test_an_input_beyond_the_record_bound_is_a_memory_error(tmp_path):
    m = _arx(tmp_path)
    n = 50_000_001
    # np.broadcast_to holds one number: the array costs no memory until it is copied.
    u = np.broadcast_to(np.float64(0.0), (n,))
    with pytest.raises(MemoryError, match=f"u: {n} samples \\({8 * n} bytes as float64"):
        m.simulate(u, y0=0.0)
    with pytest.raises(MemoryError, match="more than the 50000000 samples a record may have"):
        m.predict(u, u)
    with pytest.raises(MemoryError, match=f"u: {n} samples"):
        m.metrics(u, u)


def test_decimal_comma_text_gets_a_pandas_hint():
    u = np.array(["0,01", "0,02", "0,03"], dtype=object)
    with pytest.raises(ValueError, match=r"text such as '0,01'.*decimal=','"):
        ipa_sysid.identify(u, u, 0.01)
    # Text that is no number gets no such hint.
    with pytest.raises(ValueError) as e:
        ipa_sysid.identify(np.array(["a", "b", "c"], dtype=object), u, 0.01)
    assert "decimal=" not in str(e.value)
