"""Session 27 (fixaq): the fleet's facts as fields, not words parsed back. A failed window is worded
from the core's fields (the signal, the sample within the window, its value), a ts that contradicts the
time column is carried by the columns ``ts`` and ``t_step``, and ``trends`` reads those columns, not the
warnings' text. Each expectation is built from the records the test writes."""

import inspect
import math
import warnings

import numpy as np
import pytest

pd = pytest.importorskip("pandas", reason="ipa_sysid.fleet needs pandas: pip install 'ipa-sysid[fleet]'")
pytest.importorskip("pyarrow", reason="ipa_sysid.fleet needs pyarrow: pip install 'ipa-sysid[fleet]'")
pytest.importorskip("dask.dataframe", reason="ipa_sysid.fleet needs dask[dataframe]: pip install 'ipa-sysid[fleet]'")

import ipa_sysid  # noqa: E402
from ipa_sysid import _core, fleet  # noqa: E402

from test_ipa_sysid import cli  # noqa: E402

WINDOWS = 3


@pytest.fixture(scope="module")
def part(tmp_path_factory):
    d = tmp_path_factory.mktemp("fleet27") / "records"
    cli("simulate", "--fleet", 3, "--worn", 0, "--windows", WINDOWS, "--seed", 3, "--per-file", 3, "--out", d)
    return pd.read_parquet(sorted(d.glob("*.parquet"))[0])


def _quiet(f, *args):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ipa_sysid.IpaSysidWarning)
        return f(*args)


def test_the_core_gives_the_non_finite_sample_as_fields():
    # Two actuators of 5 and 7 rows, windows of 2: the NaN at row 5 + 3 is actuator 1's window 1,
    # sample 1 of it; the inf at row 2 actuator 0's window 1, sample 0.
    rng = np.random.default_rng(1)
    u = np.repeat(rng.uniform(-100, 100, 6), 2)
    y = np.cumsum(rng.normal(size=12))
    u[2] = np.inf
    y[5 + 3] = np.nan
    r = _core.fleet_windows(u, y, [0, 5, 12], 0.01, 2, na=1, nb=1, nk=1)
    assert list(r["group"]) == [0, 0, 1, 1, 1] and list(r["window"]) == [0, 1, 0, 1, 2]
    assert list(r["start"]) == [0, 2, 5, 7, 9]
    failed = {(g, w): (s, int(k), v) for g, w, s, k, v in zip(
        r["group"], r["window"], r["error_signal"], r["error_sample"], r["error_value"]) if s}
    assert set(failed) == {(0, 1), (1, 1)}
    assert failed[(0, 1)] == ("u", 0, math.inf)
    s, k, v = failed[(1, 1)]
    assert (s, k) == ("y", 1) and math.isnan(v)
    # The other rows carry no such fields.
    for s, k, v in zip(r["error_signal"], r["error_sample"], r["error_value"]):
        if not s:
            assert k == -1 and math.isnan(v)


def test_a_failed_window_is_worded_from_the_fields(part):
    aid = sorted(part["actuator_id"].unique())[1]
    rows = part.index[part["actuator_id"] == aid]
    t = part.loc[rows, "t"].to_numpy()
    p = part.copy()
    p.loc[rows[2000 + 17], "u"] = -np.inf  # window 1, sample 17
    r = _quiet(fleet.identify_partition, p)
    err = r.loc[r["error"] != "", "error"].tolist()
    assert err == [
        f"actuator {aid}, window 1 (t {t[2000]:g}–{t[3999]:g} s): u at t = {t[2017]:g} s (sample 17 of the "
        "window) is -inf, not a finite number"
    ]


def test_a_ts_contradiction_is_carried_by_columns_and_trends_read_them(part):
    ids = sorted(part["actuator_id"].unique())
    p = part.copy()
    ms = p["actuator_id"] == ids[0]
    p.loc[ms, "t"] *= 1000.0  # a logger writing milliseconds: step 10 s where ts = 0.01 s
    r = _quiet(fleet.identify_partition, p)
    assert (r["ts"] == 0.01).all()
    step = dict(zip(r["actuator_id"], r["t_step"]))
    assert step[ids[0]] == pytest.approx(10.0, rel=1e-9)
    assert all(math.isnan(step[a]) for a in ids[1:])
    # The windows' warning is worded from the same two numbers.
    mine = r.loc[r["actuator_id"] == ids[0], "warnings"]
    assert all("ts = 0.01 s contradicts the time column t (its typical step is 10 s)" in w for w in mine)
    # trends reads the columns, not the words: with the warnings emptied the note stays, and with the
    # column cleared it goes, the words left in place.
    note = "time column step 10 s where ts = 0.01 s (1000x, t in ms?)"
    quiet = r.assign(warnings="")
    assert note in _quiet(fleet.trends, quiet).set_index("actuator_id").loc[ids[0], "notes"]
    cleared = r.assign(t_step=np.nan)
    assert "time column" not in _quiet(fleet.trends, cleared).set_index("actuator_id").loc[ids[0], "notes"]
    # Results written before these columns existed: no note, no error.
    old = r.drop(columns=["ts", "t_step"])
    assert "time column" not in _quiet(fleet.trends, old).set_index("actuator_id").loc[ids[0], "notes"]


def test_the_fleet_module_parses_no_core_text():
    # The fix at its depth: fleet.py builds words from fields; no regular expressions on the core's text.
    src = inspect.getsource(fleet)
    assert "import re\n" not in src and "re.compile" not in src and "re.sub" not in src
