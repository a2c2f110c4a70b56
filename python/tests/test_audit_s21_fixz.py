"""Audit s21 (fixz): Model.frequency_response says when the linear block is unstable or an integrator
(H-A1, M-B4) and refuses coefficients beyond f64 (M-B3); model-file strings are escaped (M-B1).
Expectations are computed here from the model's coefficients."""

import json
import warnings

import pytest

import ipa_sysid


def _arx(tmp_path, a, b, name="m.json"):
    model = {"kind": "arx", "ts": 0.1, "na": len(a), "nb": len(b), "nk": 1, "a": a, "b": b,
             "offset": None, "noise_model": "equation-error"}
    path = tmp_path / name
    path.write_text(json.dumps({"format": "ipa-sysid-model", "version": 2, "model": model}))
    return ipa_sysid.load_model(str(path))


def test_integrator_has_no_finite_dc_gain_and_warns(tmp_path):
    # y(k) = y(k-1) + u(k-1): pole z = 1, G(1) = 1/0.
    m = _arx(tmp_path, [-1.0], [1.0])
    with pytest.warns(ipa_sysid.IpaSysidWarning, match="integrator"):
        r = m.frequency_response()
    assert r["dc_gain"] is None and r["dc_gain_note"] == "infinite (integrator)"
    assert any("integrator" in w for w in r["warnings"])


def test_unstable_block_has_no_dc_gain(tmp_path):
    # y(k) = 1.5 y(k-1) + u(k-1): 1/(1 - 1.5) = -2 would be a wrong-signed "gain" of a diverging step.
    m = _arx(tmp_path, [-1.5], [1.0])
    with pytest.warns(ipa_sysid.IpaSysidWarning, match="unstable"):
        r = m.frequency_response()
    assert r["dc_gain"] is None and r["dc_gain_note"] == "not defined (unstable)"


def test_stable_block_is_unchanged_and_silent(tmp_path):
    # y(k) = 0.5 y(k-1) + u(k-1): G(1) = 2; the step is within 2 % of it after 20 samples.
    m = _arx(tmp_path, [-0.5], [1.0])
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        r = m.frequency_response()
    assert r["dc_gain"] == pytest.approx(2.0, rel=1e-12) and r["warnings"] == []


def test_overflowing_coefficients_are_an_arithmetic_error(tmp_path):
    m = _arx(tmp_path, [1e308, 1e308], [1.0])
    with pytest.raises(ArithmeticError, match='"a" coefficients'):
        m.frequency_response()


def test_load_model_escapes_control_characters(tmp_path):
    model = {"kind": "arx", "ts": 0.1, "na": 1, "nb": 1, "nk": 1, "a": [-0.5], "b": [1.0],
             "offset": None, "noise_model": "equation-error",
             "identification": {"record": "rec.csv", "fit_estimation_percent": 90.0,
                                "warnings": ["\x1b[2J\x1b]0;pwned\x07\r\x00\x08do not use"]}}
    path = tmp_path / "esc.json"
    path.write_text(json.dumps({"format": "ipa-sysid-model", "version": 3, "model": model}))
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        ipa_sysid.load_model(str(path))
    texts = [str(w.message) for w in caught]
    assert any(t.endswith("\\u{1b}[2J\\u{1b}]0;pwned\\u{7}\\r\\u{0}\\u{8}do not use") for t in texts), texts
    assert not any(c in t for t in texts for c in "\x1b\x07\r\x00\x08")
    model["identification"]["warnings"] = ["w"] * 101
    path.write_text(json.dumps({"format": "ipa-sysid-model", "version": 3, "model": model}))
    with pytest.raises(ValueError, match="identification.warnings has 101 items, at most 100"):
        ipa_sysid.load_model(str(path))
