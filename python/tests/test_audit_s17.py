"""Audit s17 fixes (H-1, M-e, M-d, M-a, L-i) checked through the command line, every expectation
computed here with numpy (stacked least squares, a plain simulation loop, min/max of the rows)."""

import json
import subprocess

import numpy as np
import pytest

from binary import cli_path


def run(*args):
    return subprocess.run([cli_path(), *map(str, args)], capture_output=True, text=True)


def write(path, u, y):
    with open(path, "w") as f:
        f.write("u,y\n")
        for a, b in zip(u, y):
            f.write(f"{float(a)!r},{float(b)!r}\n")


def arx_record(n, seed, level=0.0):
    """y(k) = 1.5 y(k-1) - 0.7 y(k-2) + u(k-1) + 0.5 u(k-2) + e(k), then shifted by `level`."""
    rng = np.random.default_rng(seed)
    u = np.sign(rng.standard_normal(n))
    y = np.zeros(n)
    for k in range(2, n):
        y[k] = 1.5 * y[k - 1] - 0.7 * y[k - 2] + u[k - 1] + 0.5 * u[k - 2] + 0.05 * rng.standard_normal()
    return u, y + level


def regression(u, y):
    """ARX(2, 2, 1) rows k >= 2: y(k) = -a1 y(k-1) - a2 y(k-2) + b1 u(k-1) + b2 u(k-2)."""
    X = np.column_stack([-y[1:-1], -y[:-2], u[1:-1], u[:-2]])
    return X, y[2:]


def simulate_measured(theta, u, y):
    a1, a2, b1, b2 = theta
    s = y.copy()
    for k in range(2, len(y)):
        s[k] = -a1 * s[k - 1] - a2 * s[k - 2] + b1 * u[k - 1] + b2 * u[k - 2]
    return s


# H-1: merged records at different levels. The pooled fit is 100 (1 - ||y - y_sim|| / sqrt(sum_r
# ||y_r - mean_r||^2)), each record against its own mean; each record's own fit is judged.
def test_merged_fit_is_against_each_records_own_mean_and_each_record_is_judged(tmp_path):
    u1, y1 = arx_record(400, 1)
    u2, y2 = arx_record(400, 2, level=5.0)
    write(tmp_path / "lo.csv", u1, y1)
    write(tmp_path / "hi.csv", u2, y2)
    out = tmp_path / "m.json"
    r = run("identify", "--data", tmp_path / "lo.csv", tmp_path / "hi.csv", "--merge", "--ts", "1",
            "--structure", "arx", "--method", "ls", "--na", 2, "--nb", 2, "--nk", 1, "--json", out)
    assert r.returncode == 0, r.stderr
    d = json.loads(out.read_text())
    X1, t1 = regression(u1, y1)
    X2, t2 = regression(u2, y2)
    theta = np.linalg.lstsq(np.vstack([X1, X2]), np.concatenate([t1, t2]), rcond=None)[0]
    m = d["model"]
    assert np.allclose(theta, m["a"] + m["b"], rtol=1e-8, atol=1e-10)
    sse, dev, fits = 0.0, 0.0, []
    for u, y in [(u1, y1), (u2, y2)]:
        s = simulate_measured(theta, u, y)
        e = np.sum((y[2:] - s[2:]) ** 2)
        v = np.sum((y[2:] - y[2:].mean()) ** 2)
        fits.append(100 * (1 - np.sqrt(e / v)))
        sse, dev = sse + e, dev + v
    pooled = 100 * (1 - np.sqrt(sse / dev))
    assert d["metrics"]["estimation"]["fit_sim_measured_percent"] == pytest.approx(pooled, abs=1e-6)
    for rec, f in zip(d["records"], fits):
        assert rec["metrics"]["fit_sim_measured_percent"] == pytest.approx(f, abs=1e-6)
        # Each record's y0-measured fit is printed in the records table.
        assert f"{f:.6g}" in r.stdout + r.stderr
    # The model without an offset cannot reach both levels: a record with a negative fit is warned
    # by name, and --strict refuses the run.
    negative = [rec["data"] for rec, f in zip(d["records"], fits) if f < 0]
    assert negative, fits
    for name in negative:
        assert any(w.startswith(f"merged record {name}: negative simulation fit") for w in d["warnings"])
    strict = run("identify", "--data", tmp_path / "lo.csv", tmp_path / "hi.csv", "--merge", "--ts", "1",
                 "--structure", "arx", "--method", "ls", "--na", 2, "--nb", 2, "--nk", 1, "--strict")
    assert strict.returncode == 1


# M-e: a validation file cut from the estimation record shares len(val) consecutive samples with it;
# two disjoint halves share none.
def test_a_validation_file_cut_from_the_estimation_record_is_in_sample(tmp_path):
    u, y = arx_record(600, 3)
    write(tmp_path / "all.csv", u, y)
    write(tmp_path / "tail.csv", u[350:], y[350:])
    write(tmp_path / "head.csv", u[:300], y[:300])
    write(tmp_path / "rest.csv", u[300:], y[300:])
    r = run("identify", "--data", tmp_path / "all.csv", "--validation", tmp_path / "tail.csv", "--ts", "1",
            "--structure", "arx", "--method", "ls")
    assert r.returncode == 0, r.stderr
    assert f"holds {600 - 350} consecutive samples of the estimation record" in r.stdout + r.stderr
    # The other way: the validation file contains the whole estimation record.
    r = run("identify", "--data", tmp_path / "head.csv", "--validation", tmp_path / "all.csv", "--ts", "1",
            "--structure", "arx", "--method", "ls")
    assert "holds 300 consecutive samples" in r.stdout + r.stderr
    # Merged: a record and a file containing it count twice.
    r = run("identify", "--data", tmp_path / "head.csv", tmp_path / "all.csv", "--merge", "--ts", "1",
            "--structure", "arx", "--method", "ls")
    assert "holds 300 consecutive samples of" in r.stdout + r.stderr
    # Disjoint halves: held out, no warning.
    r = run("identify", "--data", tmp_path / "head.csv", "--validation", tmp_path / "rest.csv", "--ts", "1",
            "--structure", "arx", "--method", "ls")
    assert "consecutive samples" not in r.stdout + r.stderr and "in-sample" not in r.stdout + r.stderr


def narx_model(tmp_path):
    rng = np.random.default_rng(4)
    n = 600
    u = 0.4 * rng.uniform(-1, 1, n)
    y = np.zeros(n)
    for k in range(1, n):
        y[k] = 0.6 * y[k - 1] + u[k - 1] - 0.3 * u[k - 1] ** 2 + 0.01 * rng.standard_normal()
    write(tmp_path / "narx.csv", u, y)
    model = tmp_path / "narx.json"
    r = run("identify", "--data", tmp_path / "narx.csv", "--ts", "1", "--split", "0.5",
            "--structure", "narx", "--save-model", model)
    assert r.returncode == 0, r.stderr
    return u[:300], y[:300], model


# M-d: a NARX file records its estimation rows' range; simulate warns beyond it and a divergence
# names the start y0 beyond it.
def test_narx_files_store_the_data_range_and_simulate_says_so(tmp_path):
    u, y, model = narx_model(tmp_path)
    d = json.loads(model.read_text())
    assert d["model"]["data_range"]["u"] == [[u.min(), u.max()]]
    assert d["model"]["data_range"]["y"] == [y.min(), y.max()]
    r = run("simulate", "--plant", f"model:{model}", "--input", "step:3", "--y0", 0, "--samples", 50,
            "--out", tmp_path / "s.csv")
    assert r.returncode == 0, r.stderr
    assert f"the model's estimation data had u in [{float(u.min())!r}, {float(u.max())!r}]" in r.stdout + r.stderr
    r = run("simulate", "--plant", f"model:{model}", "--input", "step:0.1", "--y0", 1e200, "--samples", 50,
            "--out", tmp_path / "s2.csv")
    if r.returncode != 0:
        assert "started from y0 = " in r.stdout + r.stderr and "give --y0 inside it" in r.stdout + r.stderr
    # validate on inputs three times as large: the extrapolation warning, as for a linear model.
    write(tmp_path / "u3.csv", 3 * u, y)
    r = run("validate", "--model", model, "--data", tmp_path / "u3.csv", "--ts", "1")
    assert "the model's estimation data had it in" in r.stdout + r.stderr


# L-i: a record whose output never moves is refused by NARX as by ARX.
def test_narx_refuses_a_constant_output(tmp_path):
    u = np.sign(np.random.default_rng(5).standard_normal(200))
    write(tmp_path / "c.csv", u, np.ones(200))
    r = run("identify", "--data", tmp_path / "c.csv", "--ts", "1", "--structure", "narx")
    assert r.returncode != 0 and "never moves" in r.stdout + r.stderr


# M-a: a model with an output nonlinearity reports no equation-error loss (n/a, with the reason);
# its loss_sim is (1/N) sum 1/2 e_sim^2 = rmse_sim^2 / 2 of the same rows.
def test_output_nonlinearity_models_have_no_equation_error_loss(tmp_path):
    u, y = arx_record(400, 6)
    write(tmp_path / "w.csv", u, np.tanh(y / 5))
    out = tmp_path / "w.json"
    r = run("identify", "--data", tmp_path / "w.csv", "--ts", "1", "--structure", "arx",
            "--output-nonlinearity", "saturation", "--method", "oe", "--json", out)
    assert r.returncode == 0, r.stderr
    m = json.loads(out.read_text())["metrics"]["estimation"]
    assert m["loss"] is None and m["fpe"] is None and m["aic"] is None
    assert "no one-step equation error" in m["note"]
    assert m["loss_sim"] == pytest.approx(m["rmse_sim"] ** 2 / 2, rel=1e-9)
    assert "loss V (eq. 14)                    n/a" in r.stdout + r.stderr


# L-k: ARX(2, 2, 1) has p = 4 parameters and k0 = 2; 30 samples give N = 28 < 10 p rows, 60 give 58 >= 40.
def test_few_regression_rows_per_parameter_are_warned(tmp_path):
    u, y = arx_record(60, 7)
    write(tmp_path / "short.csv", u[:30], y[:30])
    write(tmp_path / "long.csv", u, y)
    r = run("identify", "--data", tmp_path / "short.csv", "--ts", "1", "--structure", "arx", "--method", "ls",
            "--na", 2, "--nb", 2, "--nk", 1)
    assert f"N = {30 - 2} regression rows for p = 4 parameters" in r.stdout + r.stderr
    r = run("identify", "--data", tmp_path / "long.csv", "--ts", "1", "--structure", "arx", "--method", "ls",
            "--na", 2, "--nb", 2, "--nk", 1)
    assert "regression rows for p" not in r.stdout + r.stderr


# L-j: `order` quotes the test fit it ranks on, the worse of estimated and measured initial outputs.
# One candidate, ARX(2, 2, 1), re-estimated on the estimation file, tested on a held-out file: the
# measured-start figure is numpy's least squares simulated from the test record's first two outputs.
def test_order_quotes_the_lower_test_fit(tmp_path):
    u, y = arx_record(800, 8)
    write(tmp_path / "est.csv", u[:500], y[:500])
    write(tmp_path / "test.csv", u[500:], y[500:])
    out = tmp_path / "o.json"
    r = run("order", "--data", tmp_path / "est.csv", "--validation", tmp_path / "test.csv", "--ts", "1",
            "--na", "2", "--nb", "2", "--nk", "1", "--json", out)
    assert r.returncode == 0, r.stderr
    X, t = regression(u[:500], y[:500])
    theta = np.linalg.lstsq(X, t, rcond=None)[0]
    ut, yt = u[500:], y[500:]
    s = simulate_measured(theta, ut, yt)
    measured = 100 * (1 - np.linalg.norm(yt[2:] - s[2:]) / np.linalg.norm(yt[2:] - yt[2:].mean()))
    m = json.loads(out.read_text())["test"]["metrics"]
    assert m["fit_sim_measured_percent"] == pytest.approx(measured, abs=1e-6)
    lower = min(m["fit_sim_percent"], m["fit_sim_measured_percent"])
    line = next(l for l in (r.stdout + r.stderr).splitlines() if "test fit" in l)
    quoted = float(line.split("test fit ")[1].split(" %")[0])
    assert quoted == pytest.approx(lower, rel=1e-5, abs=1e-4)


# L-c: a hand-edited piecewise-linear map whose breakpoints are not strictly increasing is named.
def test_unsorted_piecewise_linear_breakpoints_are_named(tmp_path):
    rng = np.random.default_rng(9)
    u = rng.uniform(-1, 1, 400)
    y = np.zeros(400)
    for k in range(1, 400):
        y[k] = 0.5 * y[k - 1] + np.tanh(2 * u[k - 1]) + 0.01 * rng.standard_normal()
    write(tmp_path / "d.csv", u, y)
    model = tmp_path / "m.json"
    r = run("identify", "--data", tmp_path / "d.csv", "--ts", "1", "--structure", "hammerstein",
            "--nonlinearity", "piecewise-linear", "--method", "ls", "--save-model", model)
    assert r.returncode == 0, r.stderr
    d = json.loads(model.read_text())
    p = d["model"]["nonlinearity"]["breakpoints"]
    assert all(a < b for a, b in zip(p, p[1:]))
    r = run("validate", "--model", model, "--data", tmp_path / "d.csv", "--ts", "1")
    assert "not strictly increasing" not in r.stdout + r.stderr
    for bad in (p[::-1], [p[0]] * len(p)):
        if len(bad) < 2:
            continue
        d["model"]["nonlinearity"]["breakpoints"] = bad
        model.write_text(json.dumps(d))
        r = run("validate", "--model", model, "--data", tmp_path / "d.csv", "--ts", "1")
        assert "are not strictly increasing" in r.stdout + r.stderr
