"""Audit s33 (coordinator's fixes), the Python side.

M-2: `Model.metrics` left out validate's warning that the validation residuals are correlated with
past inputs (a wrong delay nk): the same model gave `[]` in Python and the warning in `validate`. Now
`Model.metrics` is validate's one assembly (`sysid_summary::ValidationReport`): the same warnings and
the residual analysis ("residuals").

H-1: a model identified on a one-sided input (its left deadzone branch held fixed) had p = 8 in
`Model.parameter_count` and `Model.metrics` while identify counted 5 (so FPE and AIC differed). The
count is now the parameters identify estimated, wherever the model is scored.
"""

import json
import subprocess

import numpy as np

import ipa_sysid
from binary import cli_path


def delayed_record(n=1200, seed=5):
    """y(k) = 0.7 y(k-1) + 0.5 u(k-3) + noise: a true delay of 3 samples."""
    rng = np.random.default_rng(seed)
    u = rng.choice([-1.0, 1.0], size=n).repeat(1)
    y = np.zeros(n)
    for k in range(3, n):
        y[k] = 0.7 * y[k - 1] + 0.5 * u[k - 3] + 0.01 * rng.standard_normal()
    return u, y


def test_metrics_warn_as_validate_of_a_wrong_delay(tmp_path):
    u, y = delayed_record()
    # nk = 1 where the delay is 3: input dynamics are left out of the model.
    fit = ipa_sysid.identify(u[:600], y[:600], 0.01, model="arx", method="ls", na=1, nb=1, nk=1)
    m = fit.model.metrics(u[600:], y[600:], name="val")
    assert any("correlated with the input" in w for w in m["warnings"]), m["warnings"]
    assert m["residuals"]["cross_correlation"], m["residuals"].keys()
    # The command line on the same model and record says the same words.
    model = tmp_path / "m.json"
    model.write_text(fit.model.to_json())
    data = tmp_path / "val.csv"
    t = np.arange(600) * 0.01
    np.savetxt(data, np.column_stack([t, u[600:], y[600:]]), delimiter=",", header="t,u,y",
               comments="", fmt="%.17g")
    out = tmp_path / "v.json"
    subprocess.run([cli_path(), "validate", "--model", str(model), "--data", str(data),
                    "--json", str(out)], check=True, capture_output=True)
    doc = json.loads(out.read_text())
    cli = [w for w in doc["warnings"] if "correlated with the input" in w]
    assert cli and all(w in m["warnings"] for w in cli), (cli, m["warnings"])
    for key in ["fit_sim_percent", "rmse_pred", "fpe", "p", "n"]:
        assert doc["metrics"]["validation"][key] == m[key], key


def test_a_one_sided_models_p_is_the_estimated_parameters():
    rng = np.random.default_rng(7)
    n = 1200
    u = np.repeat(rng.choice([0.0, 20.0, 45.0, 70.0, 100.0], size=n // 10), 10)
    y = np.zeros(n)
    for k in range(1, n):
        y[k] = 0.8 * y[k - 1] + 0.01 * max(u[k - 1] - 10.0, 0.0) + 0.001 * rng.standard_normal()
    fit = ipa_sysid.identify(u[:800], y[:800], 0.01, model="hammerstein", method="ls", na=1, nb=2)
    free = [q for q in fit.parameters if q.get("fixed") is None]
    fixed = [q for q in fit.parameters if q.get("fixed") == "one-sided input"]
    assert fixed, fit.parameters
    assert fit.model.parameter_count == len(free)
    m = fit.model.metrics(u[800:], y[800:])
    assert m["p"] == len(free)
    # FPE = (N + p)/(N - p) V by hand.
    n_, p, v = m["n"], m["p"], m["loss"]
    assert abs(m["fpe"] - (n_ + p) / (n_ - p) * v) <= 1e-12 * m["fpe"]
