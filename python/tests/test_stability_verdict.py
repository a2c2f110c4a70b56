"""One stability verdict (session 23, brief stab): Python's Model.stable, Model.stability,
Model.simulate's warning and Model.frequency_response's DC-gain note give the verdict of the poles
placed in a hand-built model, the same one as `validate --json` on the same file. The expected
verdict is named from where the poles were put, never from the program's output."""

import json
import math
import os
import subprocess
import warnings

import numpy as np
import pytest

import ipa_sysid

# (what, alpha of y(k) = sum alpha_i y(k-i) + u(k-1), the verdict those poles call for)
_C = 2.0 * math.cos(math.pi / 3.0)
CASES = [
    ("0.5", [0.5], "settles"),
    ("0.9995", [0.9995], "settles"),
    ("1 - 1e-12", [1.0 - 1e-12], "integrator"),
    ("1", [1.0], "integrator"),
    ("1 + 1e-12", [1.0 + 1e-12], "integrator"),
    ("1 + 1e-3", [1.0 + 1e-3], "unstable"),
    ("-1", [-1.0], "on_circle"),
    ("e^{+-i pi/3}", [_C, -1.0], "on_circle"),
]

DC_NOTE = {
    "settles": None,
    "integrator": "infinite (integrator)",
    "unstable": "not defined (unstable)",
    "on_circle": "not defined (a pole on the stability boundary)",
}

SIMULATE_WORDS = {
    "integrator": "a pole at 1 (an integrator)",
    "unstable": "unstable model",
    "on_circle": "a pole on the unit circle away from 1",
}


def _model_file(tmp_path, alpha):
    model = {"kind": "arx", "ts": 0.1, "na": len(alpha), "nb": 1, "nk": 1,
             "a": [-x for x in alpha], "b": [1.0], "offset": None, "noise_model": "equation-error"}
    path = tmp_path / "m.json"
    path.write_text(json.dumps({"format": "ipa-sysid-model", "version": 2, "model": model}))
    return path


def _caught(f):
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        out = f()
    return out, [str(w.message) for w in caught if issubclass(w.category, ipa_sysid.IpaSysidWarning)]


@pytest.mark.parametrize("what,alpha,verdict", CASES)
def test_python_gives_the_verdict_of_the_poles_placed(tmp_path, what, alpha, verdict):
    path = _model_file(tmp_path, alpha)
    m = ipa_sysid.load_model(str(path))
    assert m.stability == verdict, what
    assert m.stable == (verdict == "settles"), what
    _, said = _caught(lambda: m.simulate(np.zeros(12), 0.0))
    for v, words in SIMULATE_WORDS.items():
        assert any(words in w for w in said) == (v == verdict), (what, said)
    r, _ = _caught(lambda: m.frequency_response())
    assert r["dc_gain_note"] == DC_NOTE[verdict], what


@pytest.mark.parametrize("what,alpha,verdict", CASES)
def test_validate_names_the_same_verdict(tmp_path, what, alpha, verdict):
    binary = os.environ.get("IPA_SYSID_BIN")
    if not binary:
        pytest.skip("IPA_SYSID_BIN not set (scripts/test sets it)")
    path = _model_file(tmp_path, alpha)
    rec = tmp_path / "val.csv"
    rng = np.random.default_rng(3)
    rec.write_text("u,y\n" + "".join(f"{float(u)!r},{math.sin(0.1 * k)!r}\n"
                                     for k, u in enumerate(rng.uniform(-1, 1, 100))))
    out = subprocess.run([binary, "validate", "--model", str(path), "--data", str(rec), "--json", "-"],
                         capture_output=True, text=True, check=False)
    assert out.returncode == 0, (what, out.stderr)
    doc = json.loads(out.stdout)
    assert doc["stability"] == verdict, (what, doc)
    assert doc["stable"] == (verdict == "settles"), what


# control()'s plant check: what an actuator does not do is warned of (an undamped oscillation, a
# diverging model); an integrator is a position actuator's normal dynamics and is not.
CONTROL_WORDS = {
    "unstable": "the plant model is unstable",
    "on_circle": "the plant model has a pole on the unit circle away from z = 1",
}


@pytest.mark.parametrize("what,alpha,verdict", CASES)
def test_control_warns_of_an_on_circle_or_unstable_plant_model(tmp_path, what, alpha, verdict):
    path = _model_file(tmp_path, alpha)
    c, said = _caught(lambda: ipa_sysid.control(f"model:{path}", setpoint=3, duration=0.5))
    for v, words in CONTROL_WORDS.items():
        assert any(words in w for w in c["warnings"]) == (v == verdict), (what, c["warnings"])
        assert any(words in w for w in said) == (v == verdict), (what, said)
