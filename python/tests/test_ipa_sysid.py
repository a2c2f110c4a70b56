import tempfile
"""Tests of the Python package against the command line (same data, same options) and against
independent implementations written here (closed-form least squares, a plain Python simulation loop).

The command line is found through IPA_SYSID_BIN (set by scripts/test) or in target/{debug,release};
the tests that need it fail when IPA_SYSID_BIN names a missing file, and skip with a message when no
binary was built."""

import csv
import json
import math
import os
import pathlib
import subprocess
import sys
import warnings

import numpy as np
import pytest

import ipa_sysid

from binary import cli_path

REPO = pathlib.Path(__file__).resolve().parents[2]
TOL = 1e-12



def cli(*args, check=True):
    r = subprocess.run([cli_path(), *map(str, args)], capture_output=True, text=True)
    if check and r.returncode != 0:
        raise AssertionError(f"ipa-sysid {' '.join(map(str, args))} failed: {r.stderr}")
    return r


def read_csv(path):
    """Columns of a CSV as float64 arrays, parsed by Python's float (correctly rounded)."""
    with open(path, newline="") as f:
        rows = list(csv.reader(f))
    header, body = rows[0], rows[1:]
    return {name: np.array([float(r[i]) for r in body]) for i, name in enumerate(header)}


@pytest.fixture(scope="module")
def records(tmp_path_factory):
    d = tmp_path_factory.mktemp("data")
    est, val = d / "est.csv", d / "val.csv"
    cli("simulate", "--plant", "ipa", "--seed", 1, "--out", est)
    cli("simulate", "--plant", "ipa", "--seed", 2, "--out", val)
    return est, val


def assert_same(a, b, path="$"):
    """Equal structures; numbers equal to 1e-12 (relative to their size, absolute below 1)."""
    if isinstance(b, dict):
        assert isinstance(a, dict), path
        assert sorted(a) == sorted(b), f"{path}: keys {sorted(a)} != {sorted(b)}"
        for k in b:
            assert_same(a[k], b[k], f"{path}.{k}")
    elif isinstance(b, list):
        assert isinstance(a, list) and len(a) == len(b), path
        for i, (x, y) in enumerate(zip(a, b)):
            assert_same(x, y, f"{path}[{i}]")
    elif isinstance(b, float) or isinstance(a, float):
        assert a is not None and b is not None, f"{path}: {a} != {b}"
        assert abs(a - b) <= TOL * max(1.0, abs(b)), f"{path}: {a} != {b}"
    else:
        assert a == b, f"{path}: {a!r} != {b!r}"


# --- identify: the same document as identify --json ----------------------------------------------


@pytest.mark.parametrize(
    "model,method",
    [("hammerstein", "rls"), ("hammerstein", "ls"), ("hammerstein", "oe"), ("hammerstein", "iv"),
     ("arx", "rls"), ("arx", "ls")],
)
def test_identify_matches_cli_json(records, tmp_path, model, method):
    est, val = records
    out = tmp_path / "fit.json"
    cli("identify", "--data", est, "--validation", val, "--ts", 0.01, "--model", model,
        "--method", method, "--json", out)
    expected = json.loads(out.read_text())
    e, v = read_csv(est), read_csv(val)
    fit = ipa_sysid.identify(e["u"], e["y"], 0.01, model=model, method=method,
                             validation=(v["u"], v["y"]), name=str(est), validation_name=str(val))
    got = fit.to_dict()
    # Every key the command line writes, with the same values.
    assert_same({k: got[k] for k in expected}, expected)
    assert_same(fit.metrics, expected["metrics"])
    assert fit.stable == expected["stable"]
    poles = sorted(expected["poles"], key=lambda p: (-p["abs"], p["re"], p["im"]))
    got_poles = sorted(fit.poles, key=lambda z: (-abs(z), z.real, z.imag))
    for z, p in zip(got_poles, poles):
        assert abs(z.real - p["re"]) <= TOL and abs(z.imag - p["im"]) <= TOL
    assert isinstance(fit.warnings, list)


def test_identify_options_reach_the_estimator(records, tmp_path):
    est, _ = records
    out = tmp_path / "fit.json"
    cli("identify", "--data", est, "--ts", 0.01, "--na", 2, "--nb", 2, "--nk", 2, "--forgetting",
        0.999, "--p0", 100, "--offset", "--model", "arx", "--json", out)
    e = read_csv(est)
    fit = ipa_sysid.identify(e["u"], e["y"], 0.01, model="arx", na=2, nb=2, nk=2, forgetting=0.999,
                             p0=100, offset=True, name=str(est))
    expected = json.loads(out.read_text())
    assert_same({k: fit.to_dict()[k] for k in expected}, expected)
    assert fit.model.na == 2 and fit.model.nb == 2 and fit.model.nk == 2
    assert fit.model.offset is not None


@pytest.mark.parametrize("nonlinearity,model", [("deadzone", "hammerstein"), ("linear", "arx")])
def test_nonlinearity_keyword_matches_cli(records, tmp_path, nonlinearity, model):
    # nonlinearity= is --nonlinearity: the input's static nonlinearity, the same fit as model=.
    est, _ = records
    out = tmp_path / "fit.json"
    cli("identify", "--data", est, "--ts", 0.01, "--method", "ls", "--nonlinearity", nonlinearity,
        "--json", out)
    expected = json.loads(out.read_text())
    e = read_csv(est)
    fit = ipa_sysid.identify(e["u"], e["y"], 0.01, method="ls", nonlinearity=nonlinearity,
                             name=str(est))
    assert_same({k: fit.to_dict()[k] for k in expected}, expected)
    assert fit.model.kind == model
    with pytest.raises(ValueError, match="nonlinearity"):
        ipa_sysid.identify(e["u"], e["y"], 0.01, nonlinearity="sigmoid")


@pytest.mark.parametrize("words,flags", [
    ({"nonlinearity": "saturation"}, ["--nonlinearity", "saturation"]),
    ({"nonlinearity": "deadzone-saturation"}, ["--nonlinearity", "deadzone-saturation"]),
    ({"nonlinearity": "piecewise-linear", "breakpoints": 3},
     ["--nonlinearity", "piecewise-linear", "--breakpoints", 3]),
    ({"nonlinearity": "polynomial", "degree": 2}, ["--nonlinearity", "polynomial", "--degree", 2]),
])
def test_input_nonlinearity_words_match_cli(records, tmp_path, words, flags):
    # The same words as keyword arguments: nonlinearity=, breakpoints=, degree= give the CLI's fit.
    est, _ = records
    out = tmp_path / "fit.json"
    cli("identify", "--data", est, "--ts", 0.01, "--method", "ls", *flags, "--json", out)
    expected = json.loads(out.read_text())
    e = read_csv(est)
    fit = ipa_sysid.identify(e["u"], e["y"], 0.01, method="ls", name=str(est), **words)
    assert_same({k: fit.to_dict()[k] for k in expected}, expected)
    assert expected["model"]["nonlinearity"]["kind"] == words["nonlinearity"]


def test_output_nonlinearity_keyword_matches_cli(records, tmp_path):
    # output_nonlinearity= is --output-nonlinearity: y = g(v) after the linear block, fitted by output error.
    est, _ = records
    out = tmp_path / "fit.json"
    cli("identify", "--data", est, "--ts", 0.01, "--method", "ls", "--output-nonlinearity", "polynomial",
        "--degree", 2, "--json", out)
    expected = json.loads(out.read_text())
    e = read_csv(est)
    fit = ipa_sysid.identify(e["u"], e["y"], 0.01, method="ls", output_nonlinearity="polynomial", degree=2,
                             name=str(est))
    assert_same({k: fit.to_dict()[k] for k in expected}, expected)
    assert expected["model"]["output_nonlinearity"]["kind"] == "polynomial"
    with pytest.raises(ValueError, match="output_nonlinearity"):
        ipa_sysid.identify(e["u"], e["y"], 0.01, output_nonlinearity="deadzone")


def test_breakpoints_keyword_needs_a_piecewise_input(records):
    est, _ = records
    e = read_csv(est)
    with pytest.raises(ValueError, match="breakpoints"):
        ipa_sysid.identify(e["u"], e["y"], 0.01, nonlinearity="saturation", breakpoints=2)


def test_inputs_lists_and_pandas_give_the_same_fit(records):
    est, _ = records
    e = read_csv(est)
    a = ipa_sysid.identify(e["u"], e["y"], 0.01).to_dict()
    b = ipa_sysid.identify(list(e["u"]), list(e["y"]), 0.01).to_dict()
    assert_same(b, a)
    pd = pytest.importorskip("pandas")
    df = pd.DataFrame({"u": e["u"], "y": e["y"]})
    c = ipa_sysid.identify(df["u"], df["y"], 0.01).to_dict()
    assert_same(c, a)
    # A strided view and integer input are converted too.
    u2 = np.repeat(e["u"], 2)[::2]
    assert_same(ipa_sysid.identify(u2, e["y"], 0.01).to_dict(), a)


# --- model files ---------------------------------------------------------------------------------


def test_model_file_round_trip_and_cli_reads_it(records, tmp_path):
    est, val = records
    e = read_csv(est)
    fit = ipa_sysid.identify(e["u"], e["y"], 0.01, method="ls")
    path = tmp_path / "m.json"
    fit.model.save(path)
    back = ipa_sysid.load_model(path)
    assert back == fit.model
    assert np.array_equal(back.a, fit.model.a) and back.deadzone == fit.model.deadzone
    # The command line validates the saved model with the same metrics as Model.metrics.
    out = tmp_path / "v.json"
    cli("validate", "--model", path, "--data", val, "--ts", 0.01, "--json", out)
    doc = json.loads(out.read_text())
    v = read_csv(val)
    m = back.metrics(v["u"], v["y"])
    # ... and the same warnings (validate's also carry the reader's notes on the file, "data: ...").
    assert sorted(m.pop("warnings")) == sorted(w for w in doc["warnings"] if not w.startswith("data:"))
    # The residual analysis and the first scored sample sit beside the metrics in validate's JSON.
    assert_same(m.pop("residuals"), doc["residuals"]["validation"])
    assert m.pop("score_from") == doc["score_from"]
    assert_same(m, doc["metrics"]["validation"])


def test_load_model_reads_the_cli_model_file(records, tmp_path):
    est, _ = records
    path, out = tmp_path / "cli-model.json", tmp_path / "fit.json"
    cli("identify", "--data", est, "--ts", 0.01, "--save-model", path, "--json", out)
    m = ipa_sysid.load_model(path)
    doc = json.loads(out.read_text())
    saved = json.loads(m.to_json())["model"]
    # The file also records its identification (model file version 3, audit s20 M-3): the record, the
    # columns and the warnings --json lists.
    ident = saved.pop("identification")
    assert ident["record"] == str(est) and ident["u_columns"] == ["u"] and ident["y_column"] == "y"
    assert ident["warnings"] == doc["warnings"]
    assert_same(saved, doc["model"])
    assert path.read_text() == m.to_json()  # the same bytes as the command line writes


def test_load_model_errors_name_the_file(tmp_path):
    bad = tmp_path / "bad.json"
    bad.write_text('{"format": "ipa-sysid-model", "version": 1, "model": {"ts": "x"}}')
    with pytest.raises(ValueError, match="bad.json"):
        ipa_sysid.load_model(bad)
    with pytest.raises(OSError):
        ipa_sysid.load_model(tmp_path / "missing.json")


# --- simulation and prediction against a plain Python loop ---------------------------------------


def python_simulate(a, b, nk, dz, u, y0, one_step_y=None):
    """y(k) = -sum a_i y(k-i) + sum b_j x(k-nk-j+1), x = f(u) the deadzone (paper eq. 1)."""

    def f(v):
        if dz is None:
            return v
        if v >= dz["b_r"]:
            return dz["m_r"] * (v - dz["b_r"])
        if v <= dz["b_l"]:
            return dz["m_l"] * (v - dz["b_l"])
        return 0.0

    x = [f(v) for v in u]
    k0 = max(len(a), nk + len(b) - 1)
    out = list(y0[:k0])
    for k in range(k0, len(u)):
        past = one_step_y if one_step_y is not None else out
        v = -sum(a[i] * past[k - 1 - i] for i in range(len(a)))
        v += sum(b[j] * x[k - nk - j] for j in range(len(b)))
        out.append(v)
    return np.array(out)


def test_simulate_and_predict_match_a_python_loop():
    m = ipa_sysid.paper_model()
    rng = np.random.default_rng(3)
    u = rng.uniform(-255, 255, 400)
    y0 = [1.0, 2.0, 3.0, 4.0][: m.k0]
    expected = python_simulate(list(m.a), list(m.b), m.nk, m.deadzone, u, y0)
    got = m.simulate(u, y0)
    assert got.shape == (400,)
    assert np.allclose(got, expected, rtol=1e-12, atol=1e-9)
    zeros = python_simulate(list(m.a), list(m.b), m.nk, m.deadzone, u, [0.0] * m.k0)
    assert np.allclose(m.simulate(u), zeros, rtol=1e-12, atol=1e-9)
    y = expected + rng.normal(0, 0.1, 400)
    pred = python_simulate(list(m.a), list(m.b), m.nk, m.deadzone, u, list(y), one_step_y=list(y))
    assert np.allclose(m.predict(u, y), pred, rtol=1e-12, atol=1e-9)
    # An infinite horizon is the simulation from the measured initial outputs.
    assert np.allclose(m.predict(u, y, horizon=10_000), m.simulate(u, y), rtol=1e-12, atol=1e-9)
    with pytest.raises(ValueError, match="k0"):
        m.simulate(u, y0=[])


# --- Rls against closed-form regularised least squares -------------------------------------------


def test_rls_update_many_equals_closed_form():
    rng = np.random.default_rng(7)
    n, N, p0 = 9, 500, 1e3
    Phi = rng.normal(size=(N, n))
    theta = rng.normal(size=n)
    y = Phi @ theta + rng.normal(0, 0.01, N)
    r = ipa_sysid.Rls(n, forgetting=1.0, p0=p0)
    eps = r.update_many(Phi, y)
    # With rho = 1, RLS from theta(0) = 0, P(0) = p0 I is exactly ridge regression:
    # P = (I/p0 + Phi'Phi)^-1, theta = P Phi' y.
    P = np.linalg.inv(np.eye(n) / p0 + Phi.T @ Phi)
    assert np.allclose(r.P, P, rtol=1e-8, atol=1e-14)
    assert np.allclose(r.theta, P @ Phi.T @ y, rtol=1e-8, atol=1e-10)
    assert eps.shape == (N,) and abs(eps[0] - y[0]) < 1e-15  # a-priori error with theta(0) = 0
    assert r.samples == N
    # One update at a time gives the same state.
    s = ipa_sysid.Rls(n, forgetting=1.0, p0=p0)
    for k in range(N):
        s.update(Phi[k], y[k])
    assert np.array_equal(s.theta, r.theta) and np.array_equal(s.P, r.P)
    # Fortran order and lists are accepted.
    t = ipa_sysid.Rls(n, p0=p0)
    t.update_many(np.asfortranarray(Phi), list(y))
    assert np.array_equal(t.theta, r.theta)


def test_rls_errors():
    with pytest.raises(ValueError, match=r"\bforgetting\b"):
        ipa_sysid.Rls(3, forgetting=1.5)
    with pytest.raises(ValueError, match="n = 0"):
        ipa_sysid.Rls(0)
    # A wrong type is named in the message (the core named it only in an exception note).
    u = np.zeros(100)
    with pytest.raises(TypeError, match=r"^ts: must be real number, not str"):
        ipa_sysid.identify(u, u, "a")
    with pytest.raises(TypeError, match=r"^samples: "):
        ipa_sysid.simulate_plant(samples=1.5)
    # A negative count is named (the conversion alone raised an OverflowError naming nothing).
    with pytest.raises(ValueError, match=r"invalid setting n = -1: .*whole number >= 0"):
        ipa_sysid.Rls(-1)
    with pytest.raises(ValueError, match=r"invalid setting horizon = -2"):
        ipa_sysid.paper_model().predict(np.zeros(10), np.zeros(10), horizon=-2)
    # Beyond 64 bits, or a bool, also named (audit s13 M2).
    with pytest.raises(ValueError, match=r"invalid setting n = 1180591620717411303424: .*fits 64 bits"):
        ipa_sysid.Rls(2**70)
    with pytest.raises(ValueError, match=r"invalid setting horizon = 1180591620717411303424"):
        ipa_sysid.paper_model().predict(np.zeros(10), np.zeros(10), horizon=2**70)
    with pytest.raises(TypeError, match=r"^n: expected a number, not the bool True"):
        ipa_sysid.Rls(True)
    with pytest.raises(TypeError, match=r"^horizon: "):
        ipa_sysid.paper_model().predict(np.zeros(10), np.zeros(10), horizon="2")
    p1 = ipa_sysid.paper_model().predict(np.full(10, 100.0), np.zeros(10))
    assert np.array_equal(p1, ipa_sysid.paper_model().predict(np.full(10, 100.0), np.zeros(10), horizon=1))
    r = ipa_sysid.Rls(3)
    with pytest.raises(ValueError, match="n = 3"):
        r.update_many(np.zeros((4, 2)), np.zeros(4))
    with pytest.raises(ValueError, match="4 rows"):
        r.update_many(np.zeros((4, 3)), np.zeros(5))
    # A non-finite measurement is the caller's, named as such (audit s19 L-5: an ArithmeticError).
    with pytest.raises(ValueError, match=r"^y = inf: "):
        r.update([1.0, 0.0, 0.0], math.inf)
    assert r.samples == 0 and np.array_equal(r.theta, np.zeros(3))


# --- errors: the command line's messages ---------------------------------------------------------


def cli_error(*args):
    r = cli(*args, check=False)
    assert r.returncode == 2, r.stderr
    first = r.stderr.splitlines()[0]
    assert first.startswith("error: ")
    return first[len("error: "):]


def test_setting_errors_have_the_cli_message_with_the_keyword(records):
    # The command line's message, naming the Python keyword where the command line names its flag.
    est, _ = records
    e = read_csv(est)
    for flag, kw in [("--na", dict(na=200)), ("--forgetting", dict(forgetting=0.0)),
                     ("--p0", dict(p0=-1.0)), ("--nb", dict(nb=0))]:
        msg = cli_error("identify", "--data", est, "--ts", 0.01, flag, list(kw.values())[0])
        assert flag in msg
        keyword = next(iter(kw))
        with pytest.raises(ValueError) as info:
            ipa_sysid.identify(e["u"], e["y"], 0.01, **kw)
        assert str(info.value) == msg.replace(flag, keyword)
        assert "--" not in str(info.value)


def test_bad_data_raises_value_error(records):
    est, _ = records
    e = read_csv(est)
    y = e["y"].copy()
    y[5] = np.nan
    with pytest.raises(ValueError, match=r"y\(5\) = NaN is not a finite number"):
        ipa_sysid.identify(e["u"], y, 0.01)
    with pytest.raises(ValueError, match="u has 2000 samples but y has 10"):
        ipa_sysid.identify(e["u"], e["y"][:10], 0.01)
    with pytest.raises(ValueError, match="1-D"):
        ipa_sysid.identify(np.zeros((3, 3)), np.zeros(3), 0.01)
    with pytest.raises(ValueError, match="invalid method 'magic'|method"):
        ipa_sysid.identify(e["u"], e["y"], 0.01, method="magic")
    with pytest.raises(ValueError, match=r"\bts\b") as info:
        ipa_sysid.identify(e["u"], e["y"], -1.0)
    assert "--ts" not in str(info.value)
    with pytest.raises(ValueError):
        ipa_sysid.identify(["a", "b"], [1.0, 2.0], 0.01)
    # Not arrays of real numbers: refused by name, where numpy would make None a one-sample NaN, True
    # a 1.0 and drop an imaginary part (audit s13 L7).
    with pytest.raises(ValueError, match=r"^u: expected an array of numbers, got None"):
        ipa_sysid.identify(None, e["y"], 0.01)
    with pytest.raises(ValueError, match=r"^u: expected an array of real numbers .*complex128"):
        ipa_sysid.identify(e["u"] + 1j, e["y"], 0.01)
    with pytest.raises(ValueError, match=r"^y: expected an array of real numbers .*bool"):
        ipa_sysid.identify(e["u"], e["y"] > 100, 0.01)
    with pytest.raises(ValueError, match=r"^y: expected an array of numbers, got a single number"):
        ipa_sysid.identify(e["u"], 3.0, 0.01)
    with pytest.raises(TypeError, match=r"^na: expected a number, not the bool True"):
        ipa_sysid.identify(e["u"], e["y"], 0.01, na=True)
    # A masked array's masked samples would be read as data (audit s14 L-g); without a mask it is data.
    masked = np.ma.masked_array(e["u"], mask=np.arange(len(e["u"])) > 1000)
    with pytest.raises(ValueError, match=r"^u: a masked array with 999 masked samples"):
        ipa_sysid.identify(masked, e["y"], 0.01)
    ipa_sysid.identify(np.ma.masked_array(e["u"]), e["y"], 0.01, model="arx", method="ls")
    # A maximum lag near the integer limit panicked (audit s14 H-c).
    with pytest.raises(ValueError, match=r"invalid setting resid_lags = 18446744073709551615: .*1\.\.=1000\b"):
        ipa_sysid.identify(e["u"], e["y"], 0.01, resid_lags=2**64 - 1)
    # Above 1000 lags the independence test's (2M+1)² matrix took seconds to minutes and GB (audit s27 M-4).
    with pytest.raises(ValueError, match=r"invalid setting resid_lags = 1001: .*1\.\.=1000\b"):
        ipa_sysid.identify(e["u"], e["y"], 0.01, resid_lags=1001)


def test_numerical_failure_raises_arithmetic_error(tmp_path):
    # An unstable model (poles 2, 2, 2: A = (z - 2)^3) overflows f64 in a free run: the library's
    # numerical failure, not a ValueError.
    doc = json.loads(ipa_sysid.paper_model().to_json())
    doc["model"]["a"] = [-6.0, 12.0, -8.0]
    path = tmp_path / "unstable.json"
    path.write_text(json.dumps(doc))
    m = ipa_sysid.load_model(path)
    assert not m.stable
    with pytest.raises(ArithmeticError, match="non-finite"):
        m.simulate(np.full(5000, 255.0), [1.0, 1.0, 1.0])


# --- plant and control against the command line --------------------------------------------------


def test_simulate_plant_matches_cli(records, tmp_path):
    est, _ = records
    t, u, y, p = ipa_sysid.simulate_plant("ipa", seed=1)
    e = read_csv(est)
    assert np.array_equal(u, e["u"]) and np.array_equal(y, e["y"])
    assert np.allclose(t, e["t"], rtol=0, atol=1e-12)
    assert p.shape == (2000, 2)
    assert np.all(np.abs(p[:, 0] - e["p_a_pa"]) <= 0.05 + 1e-6)  # the CSV rounds to 0.1 Pa
    out = tmp_path / "paper.csv"
    cli("simulate", "--plant", "paper", "--input", "prbs", "--samples", 300, "--seed", 4,
        "--noise-std", 0.1, "--out", out)
    t, u, y, p = ipa_sysid.simulate_plant("paper", input="prbs", samples=300, seed=4, noise_std=0.1)
    c = read_csv(out)
    assert p is None and np.array_equal(u, c["u"]) and np.array_equal(y, c["y"])
    with pytest.raises(ValueError, match=r"\bplant\b"):
        ipa_sysid.simulate_plant("model:")


def test_control_matches_cli(tmp_path):
    js, tr = tmp_path / "c.json", tmp_path / "trace.csv"
    cli("control", "--plant", "paper", "--setpoint", 50, "--duration", 5, "--json", js, "--out", tr)
    doc = json.loads(js.read_text())
    c = ipa_sysid.control("paper", setpoint=50, duration=5)
    trace = read_csv(tr)
    for k in ("t", "r", "u", "y"):
        assert np.array_equal(c[k], trace[k]), k
    assert_same(c["metrics"], doc["metrics"])
    assert c["metrics_kind"] == doc["metrics_kind"]
    assert_same(c["steps"], doc["steps"])
    assert c["warnings"] == doc["warnings"]
    with pytest.raises(ValueError, match="exactly one of"):
        ipa_sysid.control("paper")


TUNE_MODEL = {
    "format": "ipa-sysid-model",
    "version": 2,
    "model": {
        "kind": "hammerstein", "ts": 0.01, "na": 1, "nb": 1, "nk": 1, "a": [-1.0], "b": [1.0],
        "offset": None, "deadzone": {"b_l": -20.0, "b_r": 20.0, "m_l": 0.005, "m_r": 0.005},
        "noise_model": "output-error",
    },
}


def test_tune_matches_cli_and_control_takes_its_controller(tmp_path):
    # The same model, spec and search give the same controller and verification as the command
    # line; control() runs it (given as tune()'s result, its "controller" dict or the file's path)
    # exactly as `control --controller` does.
    m = tmp_path / "m.json"
    m.write_text(json.dumps(TUNE_MODEL))
    out, js, tr = tmp_path / "c.json", tmp_path / "t.json", tmp_path / "trace.csv"
    cli("tune", "--model", m, "--out", out, "--json", js, "--max-evaluations", 30)
    doc = json.loads(js.read_text())
    with pytest.warns(ipa_sysid.IpaSysidWarning, match="verified on the model only"):
        t = ipa_sysid.tune(model=str(m), max_evaluations=30)
    assert_same(t["controller"], doc["controller"])
    assert_same(t["on_model"]["tuned"]["runs"], doc["on_model"]["tuned"]["runs"])
    assert t["warnings"] == doc["warnings"]
    cli("control", "--plant", f"model:{m}", "--controller", out, "--setpoint", 60, "--duration", 2,
        "--out", tr)
    trace = read_csv(tr)
    for given in (t, t["controller"], str(out)):
        c = ipa_sysid.control(f"model:{m}", setpoint=60, duration=2, controller=given)
        assert np.array_equal(c["u"], trace["u"])
        assert np.array_equal(c["y"], trace["y"])
    # Errors name the Python keyword where the command line names its flag (--spec).
    with pytest.raises(ValueError, match="invalid setting spec = overshoot=fast"):
        ipa_sysid.tune(model=str(m), spec="overshoot=fast")
    with pytest.raises(ValueError, match="exactly one of"):
        ipa_sysid.tune()
    # Search sizes are checked by the library for both, named as the keyword (audit s13 L11).
    with pytest.raises(ValueError, match=r"^invalid setting max_evaluations = 0: a whole number in 8\.\.=10000"):
        ipa_sysid.tune(model=str(m), max_evaluations=0)
    with pytest.raises(ValueError, match=r"^invalid setting variants = 0: "):
        ipa_sysid.tune(model=str(m), variants=0)


def test_plants_that_are_neither_a_name_nor_a_file_and_missing_files(tmp_path):
    # A misspelt plant is a ValueError saying what is expected; a missing plant configuration is an
    # OSError as every missing file (audit s13 L9); a huge duration is shown as a number, not 301
    # digits (L11); calibrate's settings are checked as the command line checks them (L4).
    with pytest.raises(ValueError, match=r"invalid setting plant = foo: one of ipa, paper, model:FILE"):
        ipa_sysid.simulate_plant("foo")
    with pytest.raises(ValueError, match=r"invalid setting plant = foo: "):
        ipa_sysid.control("foo", setpoint=50)
    missing = tmp_path / "none.toml"
    with pytest.raises(OSError, match="none.toml"):
        ipa_sysid.simulate_plant(plant_config=str(missing))
    with pytest.raises(ValueError, match=r"^invalid setting duration = 1e300: at most 10000000 samples"):
        ipa_sysid.control("ipa", setpoint=50, duration=1e300)
    rec = tmp_path / "r.csv"
    t, u, y, _ = ipa_sysid.simulate_plant("ipa", input="calibration", samples=300)
    rec.write_text("t,u,y\n" + "".join(f"{a},{b},{c}\n" for a, b, c in zip(t, u, y)))
    with pytest.raises(ValueError, match=r"max_iterations = 0: expected 1\.\.=10000"):
        ipa_sysid.calibrate(str(rec), max_iterations=0)
    with pytest.raises(ValueError, match="names moving_mass twice"):
        ipa_sysid.calibrate(str(rec), free="moving_mass,moving_mass")
    # The columns by name, as the command line's --u-col/--y-col (audit s14 L-k).
    renamed = tmp_path / "renamed.csv"
    renamed.write_text(rec.read_text().replace("t,u,y", "time,cmd,pos", 1))
    a = ipa_sysid.calibrate(str(rec), max_iterations=2, free="moving_mass")
    b = ipa_sysid.calibrate(str(renamed), max_iterations=2, free="moving_mass", u_col="cmd",
                            y_col="pos", t_col="time")
    # The same twin; its `[calibration]` table names each record by its own path.
    assert a["toml"].replace(str(rec), "REC") == b["toml"].replace(str(renamed), "REC")
    assert "\n[calibration]\n" in a["toml"]
    with pytest.raises(ValueError, match=r"no column named 'u' \(the default of u_col; name yours with u_col NAME\)"):
        ipa_sysid.calibrate(str(renamed))
    # The validation record's own columns (audit s14 L-e): the record with u, y renamed (its time
    # column kept: a record without one and without ts is refused, audit s16 M6) as the validation
    # record of the first gives the fit of the first as its own validation record (the same samples).
    renamed_v = tmp_path / "renamed_v.csv"
    renamed_v.write_text(rec.read_text().replace("t,u,y", "t,cmd,pos", 1))
    c = ipa_sysid.calibrate(str(rec), validation=str(rec), max_iterations=2, free="moving_mass")
    d = ipa_sysid.calibrate(str(rec), validation=str(renamed_v), max_iterations=2, free="moving_mass",
                            val_u_col="cmd", val_y_col="pos")
    assert c["metrics"]["validation"] == d["metrics"]["validation"]
    with pytest.raises(ValueError, match="give validation=PATH"):
        ipa_sysid.calibrate(str(rec), val_u_col="cmd")


def test_control_warns_about_an_unreachable_set_point():
    # The physics plant's stroke is 0..200 mm (Table II): 300 mm cannot be reached; said in the
    # result and as a Python warning.
    with pytest.warns(ipa_sysid.IpaSysidWarning, match="outside the reachable range"):
        c = ipa_sysid.control("ipa", setpoint=300, duration=1)
    assert any("outside the reachable range" in w for w in c["warnings"])


def test_to_control_transfer_function():
    m = ipa_sysid.paper_model()
    num, den = m.transfer_polynomials()
    # G(z) = b1 z^-1 / (1 + a1 z^-1 + a2 z^-2 + a3 z^-3) = b1 z^2 / (z^3 + a1 z^2 + a2 z + a3).
    assert den == [1.0, *m.a] and num == [0.0, m.b[0], 0.0, 0.0]
    try:
        import control  # noqa: F401
    except ImportError:
        with pytest.raises(ImportError, match="pip install control"):
            m.to_control()
        return
    tf = m.to_control()
    assert tf.dt == m.ts
    assert np.allclose(np.sort_complex(tf.poles()), np.sort_complex(m.poles), atol=1e-9)


def test_example_script_runs(tmp_path):
    script = REPO / "python" / "examples" / "quickstart.py"
    r = subprocess.run([sys.executable, str(script)], capture_output=True, text=True, cwd=tmp_path)
    assert r.returncode == 0, r.stderr
    assert "fit % (simulation, validation)" in r.stdout


def test_calibrate_matches_cli(tmp_path):
    truth = tmp_path / "truth.toml"
    truth.write_text("[load]\nmoving_mass_kg = 0.7\n")
    est, val = tmp_path / "est.csv", tmp_path / "val.csv"
    cli("simulate", "--plant-config", truth, "--input", "calibration", "--samples", 600, "--seed", 3,
        "--out", est)
    cli("simulate", "--plant-config", truth, "--samples", 600, "--seed", 4, "--out", val)
    js, out = tmp_path / "c.json", tmp_path / "twin.toml"
    cli("calibrate", "--data", est, "--validation", val, "--free", "moving_mass,static_friction",
        "--no-baseline", "--out", out, "--json", js)
    doc = json.loads(js.read_text())
    c = ipa_sysid.calibrate(est, validation=val, free="moving_mass,static_friction")
    assert [e["parameter"] for e in c["estimates"]] == ["moving_mass", "static_friction"]
    for a, b in zip(c["estimates"], doc["estimates"]):
        assert a["parameter"] == b["parameter"]
        assert a["value"] == pytest.approx(b["value"], rel=1e-12)
    # The same keys as the command line's JSON (and identify's metrics, audit s17 L-d).
    for part in ("estimation", "validation"):
        for key in ("fit_sim_measured_percent", "rmse_sim_measured"):
            assert c["metrics"][part][key] == pytest.approx(doc["metrics"][part][key], rel=1e-12)
            assert c["start_metrics"][part][key] == pytest.approx(doc["start_metrics"][part][key],
                                                                  rel=1e-12)
    assert c["warnings"] == doc["warnings"]
    # The truth (independent of the program): M = 0.7 kg within 2 %.
    mass = next(e["value"] for e in c["estimates"] if e["parameter"] == "moving_mass")
    assert abs(mass / 0.7 - 1) < 0.02
    assert "moving_mass_kg" in c["toml"]
    with pytest.raises(ValueError, match="moving_mass"):
        ipa_sysid.calibrate(est, free="mass")


def test_warnings_of_identify_are_python_warnings():
    # The paper's single RLS pass on the physics IPA gives an unstable model (a pole of modulus >= 1, as
    # `identify --json` says): the same words arrive as IpaSysidWarning.
    t, u, y, _ = ipa_sysid.simulate_plant("ipa", seed=1)
    with pytest.warns(ipa_sysid.IpaSysidWarning) as caught:
        fit = ipa_sysid.identify(u, y, 0.01, method="rls", passes=1)
    assert fit.warnings, "expected the unstable-model warning"
    assert [str(w.message) for w in caught] == [str(w) for w in fit.warnings]
    with _warnings_as_errors():
        with pytest.raises(ipa_sysid.IpaSysidWarning):
            ipa_sysid.identify(u, y, 0.01, method="rls", passes=1)


def _warnings_as_errors():
    import warnings

    cm = warnings.catch_warnings()

    class _Ctx:
        def __enter__(self):
            cm.__enter__()
            warnings.simplefilter("error", ipa_sysid.IpaSysidWarning)

        def __exit__(self, *exc):
            return cm.__exit__(*exc)

    return _Ctx()


# --- hostile sizes and reads (issue 21): the same bounds as the command line ---------------------


def test_simulate_plant_refuses_a_sample_count_beyond_the_bound():
    # 10**10 samples would need 80 GB per signal: refused before anything is allocated, and the
    # interpreter survives to run the next call.
    with pytest.raises(ValueError, match="samples"):
        ipa_sysid.simulate_plant("ipa", samples=10**10)
    with pytest.raises(ValueError, match="samples"):
        ipa_sysid.simulate_plant("paper", samples=0)
    t, u, y, _ = ipa_sysid.simulate_plant("paper", samples=10)
    assert len(t) == len(u) == len(y) == 10


@pytest.mark.skipif(not os.path.exists("/dev/zero"), reason="no /dev/zero on this system")
def test_load_model_refuses_a_device():
    # /dev/zero reports a size of 0 and never ends: a device is refused before it is read.
    with pytest.raises(ValueError, match="not a regular file"):
        ipa_sysid.load_model("/dev/zero")


# --- a Pythonic package (issue 27 item 3) --------------------------------------------------------


def test_str_of_a_model_is_its_equations():
    # The difference equation printed by str(model), parsed back here, gives the model's a and b to the
    # 4 significant digits printed; the deadzone lines carry b_l, b_r, m_l, m_r.
    import re

    m = ipa_sysid.paper_model()
    text = str(m)
    assert text != repr(m)
    assert "Hammerstein" in text and "Ts = 0.01 s" in text and "mm" in text
    line = next(l for l in text.splitlines() if l.strip().startswith("y(k) ="))
    rhs = line.split("=", 1)[1].replace("−", "-").replace(" ", "")
    terms = dict()
    for sign, coef, sig, lag in re.findall(r"([+-]?)([0-9.e+-]+?)(y|x)\(k-(\d+)\)", rhs):
        terms[(sig, int(lag))] = (-1.0 if sign == "-" else 1.0) * float(coef)
    for i, a in enumerate(m.a):
        assert math.isclose(terms[("y", i + 1)], -a, rel_tol=5e-4), (i, a, line)
    for j, b in enumerate(m.b):
        assert math.isclose(terms[("x", m.nk + j)], b, rel_tol=5e-4), (j, b, line)
    dz = m.deadzone
    plain = text.replace("−", "-")
    for key in ("b_l", "b_r"):
        printed = float(re.search(key + r" = (-?[0-9.e+-]+) counts", plain).group(1))
        assert math.isclose(printed, dz[key], rel_tol=5e-4), (key, text)


def test_simulate_without_y0_warns_and_a_number_is_a_start_at_rest():
    m = ipa_sysid.paper_model()
    u = np.full(50, 120.0)
    with pytest.warns(ipa_sysid.IpaSysidWarning, match="y0"):
        m.simulate(u)
    a = m.simulate(u, 100.0)
    b = m.simulate(u, [100.0] * m.k0)
    assert np.array_equal(a, b) and a[0] == 100.0


def test_control_takes_a_model_object(tmp_path):
    m = ipa_sysid.paper_model()
    path = tmp_path / "paper.json"
    m.save(path)
    by_object = ipa_sysid.control(m, setpoint=50, duration=3)
    by_file = ipa_sysid.control(f"model:{path}", setpoint=50, duration=3)
    for k in ("t", "r", "u", "y"):
        assert np.array_equal(by_object[k], by_file[k]), k
    assert by_object["warnings"] == by_file["warnings"]
    with pytest.raises(ValueError, match="plant_config"):
        ipa_sysid.control(m, setpoint=50, plant_config=path)
    with pytest.raises(ValueError, match=r"\bplant\b"):
        ipa_sysid.control(3.0, setpoint=50)


def test_the_figures_the_repr_shows_are_attributes(records):
    # The repr names fit_sim_percent and fit_pred_percent: both read as attributes, equal to the
    # metrics dict's estimation figures (audit s14 L-f).
    est, _ = records
    e = read_csv(est)
    fit = ipa_sysid.identify(e["u"], e["y"], 0.01, model="arx", method="ls")
    assert "fit_sim_percent=" in repr(fit)
    assert fit.fit_sim_percent == fit.metrics["estimation"]["fit_sim_percent"]
    assert fit.fit_pred_percent == fit.metrics["estimation"]["fit_pred_percent"]


def test_fit_parameters_by_name_and_as_a_data_frame(records):
    est, _ = records
    e = read_csv(est)
    import warnings

    with warnings.catch_warnings():  # the model's doubts are not what this test is about
        warnings.simplefilter("ignore", ipa_sysid.IpaSysidWarning)
        fit = ipa_sysid.identify(e["u"], e["y"], 0.01, method="ls")
    listed = fit.parameters
    assert fit.params == {p["name"]: p["value"] for p in listed}
    pd = pytest.importorskip("pandas")
    frame = fit.parameters_frame()
    assert isinstance(frame, pd.DataFrame) and frame.index.name == "name"
    assert list(frame.index) == [p["name"] for p in listed]
    for p in listed:
        assert frame.loc[p["name"], "value"] == p["value"]
        std = frame.loc[p["name"], "std"]
        assert (p["std"] is None and math.isnan(std)) or std == p["std"]
        why = frame.loc[p["name"], "fixed"]  # pandas shows a missing reason as NaN
        assert why == p["fixed"] if "fixed" in p else (why is None or why != why)
    # The deadzone model's b1 = 1 is the key-term normalisation, held fixed; every other is estimated.
    assert [p["name"] for p in listed if "fixed" in p] == ["b1"]
    assert next(p for p in listed if p["name"] == "b1")["fixed"] == "normalisation"


def test_narx_structure_recovers_a_known_polynomial_narx():
    # SysIdentPy's example system, noise free: y(k) = 0.2 y(k-1) + 0.1 y(k-1) u(k-1) + 0.9 u(k-2).
    rng = np.random.default_rng(3)
    u = rng.uniform(-1.0, 1.0, 800)
    y = np.zeros_like(u)
    for k in range(2, len(u)):
        y[k] = 0.2 * y[k - 1] + 0.1 * y[k - 1] * u[k - 1] + 0.9 * u[k - 2]
    fit = ipa_sysid.identify(u, y, 1.0, structure="narx", degree=2, na=2, nb=2, nk=1, offset=True)
    terms = {t["term"]: t["coefficient"] for t in fit.terms}
    assert set(terms) == {"y(k-1)", "y(k-1)*u(k-1)", "u(k-2)"}
    assert abs(terms["y(k-1)"] - 0.2) < 1e-8
    assert abs(terms["y(k-1)*u(k-1)"] - 0.1) < 1e-8
    assert abs(terms["u(k-2)"] - 0.9) < 1e-8
    assert '"kind": "narx"' in fit.model_file()


def test_settings_the_model_would_ignore_are_refused_by_name():
    # As the command line refuses --method with --structure narx and --stop without it: a setting
    # that would be silently ignored is an error naming it (and every other one given).
    rng = np.random.default_rng(4)
    u = rng.uniform(-1.0, 1.0, 300)
    y = np.convolve(u, [0.0, 0.5, 0.2])[: len(u)]
    with pytest.raises(ValueError, match=r'^method: a setting of the ARX.*structure="narx" does not use'):
        ipa_sysid.identify(u, y, 1.0, structure="narx", method="oe")
    with pytest.raises(ValueError, match=r"^forgetting, passes, fallback: settings of .*leave them out"):
        ipa_sysid.identify(u, y, 1.0, structure="narx", forgetting=0.99, passes=1, fallback=True)
    with pytest.raises(ValueError, match=r'^stop, refine: settings of the polynomial NARX search.*"arx"'):
        ipa_sysid.identify(u, y, 1.0, model="arx", stop="aic", refine=False)
    # A structure that does not exist is named as the argument given, with every choice.
    with pytest.raises(ValueError, match=r"invalid setting structure = x: one of arx, hammerstein, narx"):
        ipa_sysid.identify(u, y, 1.0, structure="x")
    # The defaults are not "given": both kinds still run with them.
    assert ipa_sysid.identify(u, y, 1.0, model="arx", method="ls", na=1, nb=2).stable
    ipa_sysid.identify(u, y, 1.0, structure="narx", degree=1, na=1, nb=2, max_iterations=50)


def test_model_methods_warn_of_what_validate_warns_of(tmp_path):
    # An unstable model (A = 1 - 3 q^-1 + 3 q^-2 - 1.5 q^-3: the real root of z^3 - 3z^2 + 3z - 1.5 is
    # 1 + 0.5^(1/3) = 1.79, outside the unit circle) judged on a record: Model.metrics and
    # Model.simulate issue IpaSysidWarning (as validate and simulate print warning: lines), and the
    # metrics dict carries them; a stable model fitted to its own output raises none.
    path = tmp_path / "unstable.json"
    path.write_text(json.dumps({"format": "ipa-sysid-model", "version": 2, "model": {
        "kind": "arx", "ts": 0.01, "na": 3, "nb": 1, "nk": 1, "a": [-3.0, 3.0, -1.5], "b": [0.01],
        "offset": None}}))
    m = ipa_sysid.load_model(str(path))
    u = np.sin(np.arange(300) * 0.05)
    y = np.zeros(300)
    with pytest.warns(ipa_sysid.IpaSysidWarning, match=r"unstable model: a pole has modulus 1\.79"):
        d = m.metrics(u, y)
    assert any("unstable model" in w for w in d["warnings"])
    with pytest.warns(ipa_sysid.IpaSysidWarning, match="unstable model"):
        m.simulate(u, 0.0)
    stable = ipa_sysid.paper_model()
    u = 100.0 * u  # beyond the deadzone (|b| < 1.5 counts), so the output moves
    y = stable.simulate(u, 0.0)
    import warnings as w
    with w.catch_warnings():
        w.simplefilter("error", ipa_sysid.IpaSysidWarning)
        assert stable.metrics(u, y)["warnings"] == []


def test_control_warnings_speak_pythons_words_and_a_models_units():
    # A Model plant's signals are in its record's units, and Python's run length is duration=: the
    # loop's warnings say both (audit s14 L-p; the words of the command line were "mm" and "--duration").
    # The paper's model after 2 s of a 5-mm step still creeps into its band (warned as not final).
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ipa_sysid.IpaSysidWarning)
        r = ipa_sysid.control(ipa_sysid.paper_model(), setpoint=5, y0=0, duration=2)
    said = " ".join(r["warnings"])
    assert "still creeps" in said and "(run longer: duration=)" in said, said
    # The paper's model is the paper plant, in counts and mm (session 17: it said "(y's units)").
    assert " mm" in said and "(y's units)" not in said and "--duration" not in said, said
    # The same model with its first a coefficient changed is another record's model: its units.
    doc = json.loads(ipa_sysid.paper_model().to_json())
    doc["model"]["a"][0] *= 1.0001
    other_path = tempfile.mkdtemp() + "/other.json"
    with open(other_path, "w") as f:
        json.dump(doc, f)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ipa_sysid.IpaSysidWarning)
        r = ipa_sysid.control(ipa_sysid.load_model(other_path), setpoint=5, y0=0, duration=2)
    said = " ".join(r["warnings"])
    assert "(y's units)" in said and " mm" not in said, said


# --- audit s16: extrapolation, in-sample validation, pandas indexes ---------------------------------


def test_model_exposes_its_data_range_and_simulate_predict_warn_beyond_it(records):
    # The data range is the [min, max] of the estimation record's u and y (computed here with numpy);
    # an input three times as wide leaves it by far more than a tenth of its span (the command line's
    # rule): simulate and predict warn, as `simulate --plant model:` does (audit s16 M5).
    est, _ = records
    e = read_csv(est)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ipa_sysid.IpaSysidWarning)
        m = ipa_sysid.identify(e["u"], e["y"], 0.01, model="arx", method="ls").model
    r = m.data_range
    assert r == {"u": [[e["u"].min(), e["u"].max()]], "y": [e["y"].min(), e["y"].max()]}
    with pytest.raises(AttributeError):
        m.data_range = None  # read-only
    wide = 3.0 * e["u"]
    lo, hi = 3.0 * e["u"].min(), 3.0 * e["u"].max()
    for run in (lambda: m.simulate(wide, y0=e["y"]), lambda: m.predict(wide, e["y"], horizon=10)):
        with pytest.warns(ipa_sysid.IpaSysidWarning) as caught:
            run()
        said = [str(w.message) for w in caught]
        assert any(f"the input spans [{lo:g}, {hi:g}]" in s and "extrapolates" in s for s in said), said
    # Within the data: no word about the input. (This ARX model of the IPA has a pole on the unit
    # circle, so its free-run simulation drifts out of y's range and is rightly said to; its one-step
    # prediction follows the measured y and stays in.)
    for run in (lambda: m.simulate(e["u"], y0=e["y"]), lambda: m.predict(e["u"], e["y"])):
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            yhat = run()
        said = [str(w.message) for w in caught]
        assert not any("the input spans" in s for s in said), said
        outside = yhat.min() < r["y"][0] - 0.1 * (r["y"][1] - r["y"][0]) or (
            yhat.max() > r["y"][1] + 0.1 * (r["y"][1] - r["y"][0]))
        assert any("the simulated output spans" in s for s in said) == outside, said
    # The paper's model was not estimated here: it has no range and nothing to warn of.
    assert ipa_sysid.paper_model().data_range is None


def test_validation_with_the_estimation_data_is_said_to_be_in_sample(records):
    # As `identify --validation est.csv` on its own estimation file (audit s16 M12); a held-out record
    # gets no such warning.
    est, val = records
    e, v = read_csv(est), read_csv(val)
    for structure in ("arx", "narx"):
        kw = {"structure": structure} if structure == "narx" else {"model": "arx", "method": "ls"}
        with pytest.warns(ipa_sysid.IpaSysidWarning, match="in-sample, not held out"):
            f = ipa_sysid.identify(e["u"], e["y"], 0.01, validation=(e["u"].copy(), e["y"].copy()), **kw)
        assert any("in-sample" in w for w in f.warnings), structure
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            f = ipa_sysid.identify(e["u"], e["y"], 0.01, validation=(v["u"], v["y"]), **kw)
        assert not any("in-sample" in str(w.message) for w in caught)
        assert not any("in-sample" in w for w in f.warnings)


def test_pandas_series_with_different_indexes_are_refused_naming_both(records):
    # A Series is paired by position; a y reordered with its index kept (pandas would align it by label)
    # was identified against the wrong u without a word (audit s16 L7): refused, naming u's and y's
    # labels at the first position where they differ.
    pd = pytest.importorskip("pandas")
    est, _ = records
    e = read_csv(est)
    su = pd.Series(e["u"])
    sy = pd.Series(e["y"]).iloc[::-1]  # index N-1 .. 0
    n = len(e["y"])
    with pytest.raises(ValueError, match=rf"u and y: .*position 0 u's index has .*\b0\b.* where y's has .*\b{n - 1}\b"):
        ipa_sysid.identify(su, sy, 0.01, model="arx", method="ls")
    m = ipa_sysid.paper_model()
    with pytest.raises(ValueError, match="u and y: pandas objects whose indexes differ"):
        m.predict(su, sy)
    with pytest.raises(ValueError, match="indexes differ"):
        m.metrics(su, sy.iloc[:-1])
    with pytest.raises(ValueError, match="indexes differ"):
        ipa_sysid.identify(su, pd.Series(e["y"]), 0.01, model="arx", method="ls",
                           validation=(su, sy))
    # The same index (any labels), or a Series with an array: paired by position, the index dropped.
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ipa_sysid.IpaSysidWarning)
        a = ipa_sysid.identify(e["u"], e["y"], 0.01, model="arx", method="ls").to_dict()
        idx = pd.date_range("2026-01-01", periods=n, freq="10ms")
        b = ipa_sysid.identify(pd.Series(e["u"], index=idx), pd.Series(e["y"], index=idx), 0.01,
                               model="arx", method="ls").to_dict()
        c = ipa_sysid.identify(su, e["y"], 0.01, model="arx", method="ls").to_dict()
    assert_same(b, a)
    assert_same(c, a)



def test_str_of_a_wiener_model_shows_its_output_map(tmp_path):
    # Audit s31 M-4 / L-2: str(model) printed a Wiener model's recursion as y(k) (the output map left
    # out) and a polynomial input map as a Rust debug dump. A Hammerstein–Wiener model written here by
    # hand: x = 0.5 u − 0.25 u² into v, y = 2 clamp(v, −1, 3).
    import json

    path = tmp_path / "hw.json"
    fit = ipa_sysid.identify(
        np.sin(np.arange(300) * 0.37), np.cos(np.arange(300) * 0.11), ts=0.1, na=1, nb=1, nk=1,
        structure="arx", method="ls",
    )
    fit.model.save(path)
    doc = json.loads(path.read_text())
    doc["model"]["output_nonlinearity"] = {"kind": "saturation", "s_l": -1.0, "s_r": 3.0, "m": 2.0}
    path.write_text(json.dumps(doc))
    text = str(ipa_sysid.load_model(path))
    import re

    assert "Wiener" in text, text
    assert "v(k) =" in text and "v(k−1)" in text, text
    assert re.search(r"y\(k\) = g\(v\(k\)\) = 2 clamp\(v\(k\), -1( mm)?, 3( mm)?\)", text), text
    assert "Polynomial {" not in text and "Saturation {" not in text, text


def test_predict_of_an_output_error_model_is_the_prediction_metrics_score():
    # Audit s31 M-3: for an output-error model Model.predict gave the simulation from the measured
    # initial outputs, while validate's y_pred and metrics()["fit_pred_percent"] start from the estimated
    # ones. The fit of predict's output, computed here over k >= k0, is the metrics' figure.
    rng = np.random.default_rng(3)
    u = rng.choice([-1.0, 1.0], size=400)
    y = np.zeros(400)
    for k in range(2, 400):
        y[k] = 1.5 * y[k - 1] - 0.7 * y[k - 2] + 0.5 * u[k - 1]
    y_meas = y + rng.normal(0.0, 0.05, size=400)
    fit = ipa_sysid.identify(u, y_meas, ts=0.1, na=2, nb=1, nk=1, structure="arx", method="oe")
    m = fit.model
    p = m.predict(u, y_meas)
    k0 = m.k0
    e = y_meas[k0:] - p[k0:]
    d = y_meas[k0:] - y_meas[k0:].mean()
    mine = 100.0 * (1.0 - np.linalg.norm(e) / np.linalg.norm(d))
    got = m.metrics(u, y_meas)["fit_pred_percent"]
    assert math.isclose(mine, got, rel_tol=0, abs_tol=1e-9), (mine, got)


def test_predict_refuses_a_record_no_longer_than_k0():
    # Audit s31 L-3: a record of k0 samples came back unchanged, without a word.
    m = ipa_sysid.paper_model()
    with pytest.raises(ValueError, match="not enough to predict"):
        m.predict(np.ones(m.k0), np.ones(m.k0))
