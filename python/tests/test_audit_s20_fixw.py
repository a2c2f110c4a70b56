"""Audit s20, the Python side of findings H-1 and M-3: `identify` refuses a record whose input
determines no input term whatever the windup protection (a constant input fits a whole line of
(a1 + a2, b1)), and `load_model` repeats the warnings of the identification that wrote the file."""

import json
import subprocess
import warnings

import numpy as np
import pytest

import ipa_sysid
from binary import cli_path


def run(*args):
    return subprocess.run([cli_path(), *map(str, args)], capture_output=True, text=True)


@pytest.mark.parametrize("level", [0.0, 5.0])
@pytest.mark.parametrize("windup", ["none", "trace", "directional"])
def test_a_constant_input_is_not_persistently_exciting_whatever_the_windup(level, windup):
    # The audit's q2 (u = 0) and q5 (u = 5) records: 20 000 samples, y = 1 throughout.
    u = np.full(20_000, level)
    y = np.ones(20_000)
    with pytest.raises(ValueError, match="not persistently exciting"):
        ipa_sysid.identify(u, y, 0.01, model="arx", na=2, nb=1, method="rls", windup=windup)


def test_load_model_repeats_the_warnings_of_the_identification_that_wrote_the_file(tmp_path):
    # pos(k) = 0.999999 pos(k-1) + cmd(k-1): a pole 1e-6 from the unit circle, inside the integrator
    # margin 1e-5, so identify warns; the saved file carries the warning and load_model repeats it.
    rng = np.random.default_rng(11)
    u = rng.uniform(-0.5, 0.5, 2000)
    y = np.zeros(2000)
    for k in range(1, 2000):
        y[k] = 0.999999 * y[k - 1] + u[k - 1]
    data = tmp_path / "int.csv"
    with open(data, "w") as f:
        f.write("t,cmd,pos\n")
        for k in range(2000):
            f.write(f"{k * 0.01!r},{float(u[k])!r},{float(y[k])!r}\n")
    model = tmp_path / "m.json"
    out = tmp_path / "id.json"
    r = run("identify", "--data", data, "--u-col", "cmd", "--y-col", "pos", "--structure", "arx",
            "--na", 1, "--nb", 1, "--method", "ls", "--save-model", model, "--json", out)
    assert r.returncode == 0, r.stderr
    said = json.loads(out.read_text())["warnings"]
    assert any("0.999999" in w for w in said), said
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        ipa_sysid.load_model(str(model))
    got = [str(w.message) for w in caught if issubclass(w.category, ipa_sysid.IpaSysidWarning)]
    prefix = f"this model's identification on {data} (free-run fit "
    for w in said:
        assert any(g.startswith(prefix) and g.endswith(f"warned: {w}") for g in got), (w, got)
