"""Session 35 (fix35): audit s34 L-6, the fleet's "u in other units?" note for a command logged in volts
(1/51 of the counts) or in % duty (1/2.55); fix34's leftover (c), Python argument names in the plant
library's and identify's RLS failures. Each expectation is built from what the test changes or computes,
not from the program's output."""

import re
import warnings

import numpy as np
import pytest

import ipa_sysid

from test_ipa_sysid import cli


def test_a_command_in_volts_or_percent_duty_is_noted_with_its_factor(tmp_path):
    # An actuator whose u the test divides by c must be noted with c, and no other actuator may be.
    pd = pytest.importorskip("pandas", reason="ipa_sysid.fleet needs pandas: pip install 'ipa-sysid[fleet]'")
    pytest.importorskip("pyarrow", reason="ipa_sysid.fleet needs pyarrow: pip install 'ipa-sysid[fleet]'")
    pytest.importorskip("dask.dataframe", reason="ipa_sysid.fleet needs dask[dataframe]")
    from ipa_sysid import fleet

    d = tmp_path / "records"
    cli("simulate", "--fleet", 8, "--worn", 0.25, "--windows", 4, "--seed", 7, "--per-file", 8, "--out", d)
    part = pd.concat([pd.read_parquet(f) for f in sorted(d.glob("*.parquet"))], ignore_index=True)
    ids = sorted(part["actuator_id"].unique())
    volts, duty = ids[1], ids[2]
    part.loc[part["actuator_id"] == volts, "u"] /= 51.0  # 0-5 V for 0-255 counts
    part.loc[part["actuator_id"] == duty, "u"] /= 2.55  # % duty for 0-255 counts
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ipa_sysid.IpaSysidWarning)
        tr = fleet.trends(fleet.identify_partition(part))
    note = dict(zip(tr["actuator_id"], tr["notes"]))
    for a, c in ((volts, 51.0), (duty, 2.55)):
        assert "u in other units?" in note[a], (a, note[a])
        # The factor the note names is the one the test applied, within a factor 2: the actuators' own
        # scatter and a worn valve's (at the mean width about 1.5x, slope 0.7x: sqrt(0.7 / 1.5) = 0.68).
        scaled = float(re.search(r"the command scaled by ([0-9.e+-]+)", note[a]).group(1))
        assert 0.5 < scaled * c < 2.0, (a, note[a])
    for a in ids:
        if a not in (volts, duty):
            assert "other units" not in note[a], (a, note[a])


def test_plant_library_and_rls_failures_name_python_arguments_not_flags():
    # fix34 leftover (c): IpaError::Config texts (simulate's input / samples) and identify's RLS
    # failure advice named the command line's --input, --samples, --rls-form, --p0.
    with pytest.raises(ValueError) as e:
        ipa_sysid.simulate_plant(plant="paper", input="step:100@20", samples=10)
    text = str(e.value)
    assert "input step:100@20: the step comes at sample 20" in text and "more than 20 samples" in text, text
    assert "--" not in text, text
    # u = 0 after a short excitation, under forgetting 0.98: the unexcited covariance grows by 1/0.98
    # per sample and overflows after about ln(1.8e308 / 1e6) / ln(1 / 0.98) = 34 449 samples.
    n = 40_000
    u = np.zeros(n)
    u[:20] = [1.0, -1.0] * 10
    y = np.zeros(n)
    for k in range(1, n):
        y[k] = 0.5 * y[k - 1] + u[k - 1]
    with pytest.raises((ArithmeticError, ValueError)) as e:
        ipa_sysid.identify(u, y, 0.01, model="arx", method="rls", na=1, nb=1, nk=1, forgetting=0.98)
    text = str(e.value)
    assert "--" not in text, text
    assert "forgetting" in text, text
