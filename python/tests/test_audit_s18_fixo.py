"""Audit s18 Python parity fixes (M-2, M-4, L-2, L-4, L-5, L-8): the package says what the command line
says (warnings compared line for line with the binary's), and every number is checked against numpy or
a hand derivation written here."""

import json
import subprocess
import warnings

import numpy as np
import pytest

import ipa_sysid
from binary import cli_path


def run(*args):
    return subprocess.run([cli_path(), *map(str, args)], capture_output=True, text=True)


def cli_warnings(stderr):
    return [l[len("warning: "):] for l in stderr.splitlines() if l.startswith("warning: ")]


def recorded(f, *args, **kwargs):
    with warnings.catch_warnings(record=True) as w:
        warnings.simplefilter("always")
        out = f(*args, **kwargs)
    return out, [str(x.message) for x in w if issubclass(x.category, ipa_sysid.IpaSysidWarning)]


# An ARX model with an offset (no operating point) whose estimation data had u in [3.41, 6.41] and y in
# [3.20, 6.19] (the hair dryer's, audit s18 M-2): y(k) = 0.9 y(k-1) + 0.1 u(k-1) + 0.05.
OFFSET_MODEL = {
    "format": "ipa-sysid-model", "version": 2,
    "model": {"kind": "arx", "ts": 0.08, "na": 1, "nb": 1, "nk": 1, "a": [-0.9], "b": [0.1],
              "offset": 0.05, "data_range": {"u": [[3.41, 6.41]], "y": [3.2, 6.19]}},
}


# M-2: simulate_plant("model:FILE") issues the warnings `simulate --plant model:FILE` prints, in its
# order; the designed staircase (±255 counts) leaves [3.41, 6.41] (numpy: u.min() < 3.41 - 0.3).
def test_simulate_plant_of_a_model_file_warns_as_the_command_line(tmp_path):
    path = tmp_path / "off.json"
    path.write_text(json.dumps(OFFSET_MODEL))
    (t, u, y, p), got = recorded(ipa_sysid.simulate_plant, f"model:{path}", samples=200)
    assert u.min() < 3.41 - 0.3 and y.max() > 6.19 + 0.3
    r = run("simulate", "--plant", f"model:{path}", "--samples", 200, "--out", tmp_path / "s.csv")
    assert r.returncode == 0, r.stderr
    expected = cli_warnings(r.stderr)
    assert got == expected
    assert any("the input spans" in w for w in got), got
    assert any("the simulated output spans" in w for w in got), got
    assert any("starts at its rest" in w for w in got), got
    # An input of 1e300: y(1) = 0.1·1e300 + ..., far outside; still the command line's words.
    (_, _, y, _), got = recorded(ipa_sysid.simulate_plant, f"model:{path}", input="step:1e300", samples=50)
    assert y.max() > 1e298
    r = run("simulate", "--plant", f"model:{path}", "--input", "step:1e300", "--samples", 50,
            "--out", tmp_path / "s2.csv")
    assert r.returncode == 0, r.stderr
    assert got == cli_warnings(r.stderr) and got


# M-4: a controller file whose provenance says it missed its specification: control(controller=...)
# warns as `control --controller` does, and tune()'s "controller_file" carries that provenance.
def test_control_with_a_controller_that_missed_its_spec_warns(tmp_path):
    model = tmp_path / "m.json"
    model.write_text(json.dumps({
        "format": "ipa-sysid-model", "version": 2,
        "model": {"kind": "hammerstein", "ts": 0.01, "na": 1, "nb": 1, "nk": 1, "a": [-1.0], "b": [1.0],
                  "offset": None, "deadzone": {"b_l": -20.0, "b_r": 20.0, "m_l": 0.005, "m_r": 0.005},
                  "noise_model": "output-error"},
    }))
    t, _ = recorded(ipa_sysid.tune, model=str(model), max_evaluations=10, variants=1)
    prov = json.loads(t["controller_file"])["provenance"]
    met = not any(w.startswith("not met") for w in t["warnings"])
    assert prov["meets_spec"] is met
    doc = json.loads(t["controller_file"])
    doc["provenance"]["meets_spec"] = False
    ctl = tmp_path / "c.json"
    ctl.write_text(json.dumps(doc))
    js = tmp_path / "cc.json"
    r = run("control", "--plant", f"model:{model}", "--controller", ctl, "--setpoint", 30,
            "--duration", 3, "--json", js)
    assert r.returncode == 0, r.stderr
    cli = json.loads(js.read_text())["warnings"]
    assert any("does not meet the specification" in w for w in cli), cli
    c, got = recorded(ipa_sysid.control, f"model:{model}", controller=str(ctl), setpoint=30, duration=3)
    assert c["warnings"] == cli and got == cli


# L-2: calibrate() has every key of `calibrate --no-baseline --json` (seconds aside, a wall time, and the
# report mark "format") with the same values.
def test_calibrate_has_the_keys_of_the_command_line(tmp_path):
    rec = tmp_path / "ipa3.csv"
    assert run("simulate", "--plant", "ipa", "--seed", 3, "--samples", 500, "--out", rec).returncode == 0
    js = tmp_path / "cal.json"
    r = run("calibrate", "--data", rec, "--max-iterations", 5, "--no-baseline", "--json", js,
            "--out", tmp_path / "cal.toml")
    assert r.returncode == 0, r.stderr
    doc = json.loads(js.read_text())
    # "format" is the file's mark as a report (audit s32 H-1), not part of the result.
    assert doc.pop("format") == "ipa-sysid-report"
    py, _ = recorded(ipa_sysid.calibrate, str(rec), max_iterations=5)
    assert set(doc) <= set(py), set(doc) - set(py)
    for k in ("ts", "used_pressures", "cost_floor", "segment_rmse_mm", "hammerstein", "cost", "segments"):
        assert py[k] == doc[k], k
    assert py["ts"] == 0.01 and py["hammerstein"] is None


# L-5: identify(detrend=...) is `identify --detrend`: the model stores (u0, y0) = the record's means
# (numpy), its parameters are those of the command line, and the JSON carries the "detrend" key.
@pytest.mark.parametrize("how", ["mean", "linear"])
def test_identify_detrends_as_the_command_line(tmp_path, how):
    rng = np.random.default_rng(5)
    n = 400
    u = 5.0 + np.repeat(rng.choice([-1.0, 1.0], n // 20), 20)
    y = np.zeros(n)
    for k in range(1, n):
        y[k] = 0.8 * y[k - 1] + 0.5 * u[k - 1] + 0.01 * rng.standard_normal()
    y += 3.0 + 0.001 * np.arange(n)
    csv = tmp_path / "d.csv"
    with open(csv, "w") as f:
        f.write("u,y\n")
        for a, b in zip(u, y):
            f.write(f"{float(a)!r},{float(b)!r}\n")
    js, mf = tmp_path / "i.json", tmp_path / "m.json"
    r = run("identify", "--data", csv, "--ts", 1, "--structure", "arx", "--method", "ls", "--na", 1,
            "--nb", 1, "--nk", 1, "--detrend", how, "--json", js, "--save-model", mf)
    assert r.returncode == 0, r.stderr
    doc = json.loads(js.read_text())
    fit, _ = recorded(ipa_sysid.identify, u, y, 1.0, structure="arx", method="ls", na=1, nb=1, nk=1,
                      detrend=how)
    d = fit.to_dict()
    assert d["detrend"] == how and doc["detrend"] == how
    for p, q in zip(d["parameters"], doc["parameters"]):
        assert p["name"] == q["name"] and abs(p["value"] - q["value"]) <= 1e-12 * max(1.0, abs(q["value"]))
    op = json.loads(fit.model.to_json())["model"]["operating_point"]
    assert op["u"][0] == pytest.approx(np.mean(u), rel=1e-12)
    assert op["y"] == pytest.approx(np.mean(y), rel=1e-12)
    assert op == json.loads(mf.read_text())["model"]["operating_point"]
    with pytest.raises(ValueError, match="detrend"):
        ipa_sysid.identify(u, y, 1.0, structure="arx", detrend="quadratic")


# L-8: str(model) of a detrended model prints u0 as a number, and the record's units (not counts/mm)
# for a model other than the paper's.
def test_str_of_a_detrended_model_prints_its_operating_point_as_numbers(tmp_path):
    rng = np.random.default_rng(2)
    u = 4.994 + rng.standard_normal(300) * 0.5
    u -= np.mean(u) - 4.994  # mean 4.994 exactly up to rounding
    y = np.convolve(u, [0.0, 0.5, 0.25])[:300] + 0.01 * rng.standard_normal(300)
    fit, _ = recorded(ipa_sysid.identify, u, y, 0.08, structure="arx", method="ls", na=1, nb=1, nk=1,
                      detrend="mean")
    text = str(fit.model)
    assert "u0 = 4.994," in text, text
    assert '["' not in text and "counts" not in text and " mm" not in text, text
    assert "estimation record's units" in text
    paper = str(ipa_sysid.paper_model())
    assert "u in PWM counts, y in mm" in paper and "counts" in paper


# L-4: the undershoot of control()'s step (hand-derived in crates/cli/tests/audit_s18_fixo_cli.rs:
# y(1) = -0.02 (5·10 + 20·0.01·10) = -1.04) and its warning, as the command line.
def test_control_reports_the_undershoot(tmp_path):
    m = tmp_path / "nmp.json"
    m.write_text(json.dumps({"format": "ipa-sysid-model", "version": 2,
                             "model": {"kind": "arx", "ts": 0.01, "na": 1, "nb": 2, "nk": 1,
                                       "a": [-0.95], "b": [-0.02, 0.05], "offset": None}}))
    c, got = recorded(ipa_sysid.control, f"model:{m}", kp=5, ki=20, setpoint=10, u_max=1e9, duration=10)
    assert c["y"][1] == pytest.approx(-1.04, abs=1e-12)
    assert c["metrics"]["undershoot_mm"] == pytest.approx(1.04, abs=1e-12)
    assert c["metrics"]["undershoot_percent"] == pytest.approx(104.0 / abs(c["y"][-1]), rel=1e-12)
    assert any("the wrong way" in w for w in got), got
