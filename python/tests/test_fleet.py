"""Tests of ipa_sysid.fleet: a small simulated fleet (`ipa-sysid simulate --fleet`) identified on a
Dask LocalCluster of 2 worker processes, compared with the command line on the same windows (1e-12), the
worn actuators found against the simulator's truth, a worker killed mid-run, and the statistics
against hand-derived values.

Needs the extra (`pip install ipa-sysid[fleet]`; scripts/test installs it): without dask, distributed
or pyarrow the module is skipped with the reason shown by `pytest -rs`."""

import csv
import json
import math
import os
import re
import signal
import threading
import time

import numpy as np
import pytest

pd = pytest.importorskip("pandas", reason="ipa_sysid.fleet needs pandas: pip install 'ipa-sysid[fleet]'")
pytest.importorskip("pyarrow", reason="ipa_sysid.fleet needs pyarrow: pip install 'ipa-sysid[fleet]'")
pytest.importorskip("dask.dataframe", reason="ipa_sysid.fleet needs dask[dataframe]: pip install 'ipa-sysid[fleet]'")
distributed = pytest.importorskip("distributed", reason="ipa_sysid.fleet needs distributed: pip install 'ipa-sysid[fleet]'")

import ipa_sysid  # noqa: E402
from ipa_sysid import fleet  # noqa: E402

from test_ipa_sysid import cli  # noqa: E402

TOL = 1e-12
ACTUATORS, WORN, WINDOWS, PER_FILE = 10, 0.2, 8, 2


@pytest.fixture(scope="module")
def fleet_dir(tmp_path_factory):
    d = tmp_path_factory.mktemp("fleet") / "records"
    cli(
        "simulate", "--fleet", ACTUATORS, "--worn", WORN, "--windows", WINDOWS, "--seed", 5,
        "--per-file", PER_FILE, "--out", d,
    )
    return d


@pytest.fixture(scope="module")
def client():
    with distributed.LocalCluster(
        n_workers=2, threads_per_worker=1, processes=True, dashboard_address=":0"
    ) as cluster, distributed.Client(cluster) as c:
        yield c


@pytest.fixture(scope="module")
def results(fleet_dir, client, tmp_path_factory):
    out = tmp_path_factory.mktemp("results")
    r = fleet.run(fleet_dir, out, client=client)
    written = pd.read_parquet(out / "results.parquet")
    pd.testing.assert_frame_equal(written, r)
    return r


def test_the_simulated_fleet_is_long_format_parquet_with_its_truth(fleet_dir):
    files = sorted(fleet_dir.glob("*.parquet"))
    assert len(files) == ACTUATORS // PER_FILE
    df = pd.read_parquet(files[0])
    assert list(df.columns) == ["actuator_id", "t", "u", "y"]
    assert len(df) == PER_FILE * WINDOWS * 2000
    truth = pd.read_csv(fleet_dir / "truth.csv")
    assert list(truth.columns) == ["actuator_id", "worn"]
    assert truth["worn"].sum() == round(ACTUATORS * WORN)
    # The folder is not overwritten unless asked.
    r = cli("simulate", "--fleet", 2, "--out", fleet_dir, check=False)
    assert r.returncode == 2 and "--overwrite" in r.stderr


def test_one_row_per_actuator_and_window(results):
    assert len(results) == ACTUATORS * WINDOWS
    assert (results.groupby("actuator_id").size() == WINDOWS).all()
    assert (results["error"] == "").all()


def write_window(path, df):
    with open(path, "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(["t", "u", "y"])
        for t, u, y in zip(df["t"], df["u"], df["y"]):
            w.writerow([repr(float(t)), repr(float(u)), repr(float(y))])


def close(a, b):
    if a is None or (isinstance(a, float) and math.isnan(a)):
        return b is None or (isinstance(b, float) and math.isnan(b))
    return abs(a - b) <= TOL * max(1.0, abs(a))


@pytest.mark.parametrize("which", ["worn", "healthy"])
def test_each_window_equals_the_command_line(fleet_dir, results, tmp_path, which):
    truth = pd.read_csv(fleet_dir / "truth.csv")
    aid = int(truth[truth["worn"] == (which == "worn")]["actuator_id"].iloc[0])
    records = pd.concat(pd.read_parquet(f) for f in sorted(fleet_dir.glob("*.parquet")))
    rec = records[records["actuator_id"] == aid].sort_values("t")
    for window in (0, WINDOWS - 1):
        part = rec.iloc[window * 2000 : (window + 1) * 2000]
        path = tmp_path / f"a{aid}w{window}.csv"
        write_window(path, part)
        ident = json.loads(cli("identify", "--data", path, "--method", "ls", "--ts", 0.01, "--json", "-").stdout)
        summary = tmp_path / "track.json"
        cli(
            "track", "--data", path, "--ts", 0.01, "--detect-warmup", 200, "--detect-calibration", 800,
            "--json", summary,
        )
        track = json.loads(summary.read_text())
        row = results[(results["actuator_id"] == aid) & (results["window"] == window)].iloc[0]
        for p in ident["parameters"]:
            assert close(p["value"], row[p["name"]]), (p, row[p["name"]])
            assert close(p["std"], row[p["name"] + "_sd"]), (p, row[p["name"] + "_sd"])
        est = ident["metrics"]["estimation"]
        assert close(est["fit_sim_percent"], row["fit_sim_percent"])
        assert close(est["fit_pred_percent"], row["fit_pred_percent"])
        assert row["stable"] == ident["stable"]
        # Warnings that name the record name it by file here and by actuator and window there.
        norm = lambda w: re.sub(r"group \d+ window \d+", "<data>", w.replace(str(path), "<data>"))  # noqa: E731
        assert [norm(w) for w in row["warnings"].split("\n") if w] == [norm(w) for w in ident["warnings"]]
        assert row["changes"] == len(track["change_points"])
        if track["change_points"]:
            k = track["change_points"][0]["k"]
            assert row["first_change_t"] == part["t"].iloc[k]


def test_every_worn_actuator_is_flagged_and_no_healthy_one(fleet_dir, results):
    truth = pd.read_csv(fleet_dir / "truth.csv")
    flagged = fleet.worn(results)
    assert list(flagged["rank"]) == list(range(1, len(flagged) + 1))
    assert (np.diff(flagged["p_value"]) >= 0).all()
    expected = set(truth[truth["worn"]]["actuator_id"])
    assert set(flagged["actuator_id"]) == expected
    tr = fleet.trends(results)
    assert (tr["threshold"] == fleet.ALPHA / ACTUATORS).all()


def test_a_worker_killed_mid_run_loses_no_actuator(fleet_dir, results, client, tmp_path):
    done = {}

    def go():
        try:
            done["results"] = fleet.run(fleet_dir, tmp_path, client=client)
        except BaseException as e:  # reported below
            done["error"] = e

    runner = threading.Thread(target=go)
    runner.start()
    killed = None
    deadline = time.monotonic() + 60
    while killed is None and time.monotonic() < deadline and runner.is_alive():
        busy = [w for w, keys in client.processing().items() if keys]
        if busy:
            pid = client.run(os.getpid, workers=[busy[0]])[busy[0]]
            os.kill(pid, signal.SIGKILL)
            killed = pid
        else:
            time.sleep(0.05)
    runner.join(120)
    assert killed is not None, "no worker was ever busy: the run could not be interrupted"
    assert "error" not in done, done.get("error")
    pd.testing.assert_frame_equal(done["results"], results)


def test_student_t_tail_matches_the_tables():
    # Upper percentage points of Student's t (Abramowitz & Stegun Table 26.10; Fisher & Yates).
    for t, dof, p in [
        (12.706205, 1, 0.025),
        (4.302653, 2, 0.025),
        (2.570582, 5, 0.025),
        (2.306004, 8, 0.025),
        (3.169273, 10, 0.005),
        (4.604095, 4, 0.005),
        (3.707428, 6, 0.005),
    ]:
        assert abs(fleet.student_t_sf(t, dof) - p) < 1e-7, (t, dof)
        assert abs(fleet.student_t_sf(-t, dof) - (1 - p)) < 1e-7
    assert fleet.student_t_sf(0.0, 7) == 0.5


def test_a_trend_with_hand_made_residuals():
    # width = 50 + 2 x + e with e = (1, -1, -1, 1) orthogonal to 1 and x (x = 0, 1, 2, 3 hours): slope 2,
    # s^2 = 4 / (4 - 2) = 2, Sxx = 5, se = sqrt(2 / 5), t = 2 / sqrt(0.4); slopes without a trend.
    x = np.arange(4.0)
    e = np.array([1.0, -1.0, -1.0, 1.0])
    res = pd.DataFrame(
        {
            "actuator_id": 7,
            "t_start": 3600.0 * x,
            "deadzone_width": 50 + 2 * x + e,
            "m_l": 0.004 + 1e-5 * e,
            "m_r": 0.004 + 1e-5 * e,
            "error": "",
        }
    )
    tr = fleet.trends(res).iloc[0]
    assert abs(tr["width_trend_per_h"] - 2.0) < 1e-12
    assert abs(tr["width_trend_sd"] - math.sqrt(0.4)) < 1e-12
    assert abs(tr["width_t"] - 2.0 / math.sqrt(0.4)) < 1e-12
    assert abs(tr["slope_trend_per_h"]) < 1e-15
    # Fisher: X = -2 (ln p_w + ln p_s), p = exp(-X / 2) (1 + X / 2).
    chi = -2 * (math.log(tr["p_width"]) + math.log(tr["p_slope"]))
    assert abs(tr["p_value"] - math.exp(-chi / 2) * (1 + chi / 2)) < 1e-15
    assert abs(tr["p_slope"] - 0.5) < 1e-12


def test_a_partition_without_the_columns_is_refused():
    with pytest.raises(ValueError, match="missing column.*actuator_id"):
        fleet.identify_partition(pd.DataFrame({"t": [0.0], "u": [1.0], "y": [0.0]}))


def test_rows_out_of_order_give_the_rows_of_the_ordered_partition(fleet_dir):
    # identify_partition sorts a partition by (actuator_id, t) unless it is in that order already (the
    # simulator's files are): the same records shuffled must give the same windows, to the bit.
    part = pd.read_parquet(sorted(fleet_dir.glob("*.parquet"))[0])
    ordered = fleet.identify_partition(part)
    shuffled = part.sample(frac=1.0, random_state=3)
    assert not fleet._in_order(shuffled) and fleet._in_order(part)
    pd.testing.assert_frame_equal(fleet.identify_partition(shuffled), ordered)


def test_the_report_holds_the_figure_and_the_flagged(results, tmp_path):
    flagged = fleet.report(results, tmp_path / "worn.html")
    text = (tmp_path / "worn.html").read_text()
    assert "<svg" in text and "Fleet at a glance" in text
    for aid in flagged["actuator_id"]:
        assert f"<td>{aid}</td>" in text


def test_the_spark_schema_names_every_column_with_its_type(results):
    schema = [f.split(" ") for f in fleet.spark_schema().split(", ")]
    assert [name for name, _ in schema] == list(results.columns)
    spark_of = {"int64": "long", "float64": "double", "bool": "boolean"}
    for name, spark in schema:
        dtype = str(results[name].dtype)
        assert spark_of.get(dtype, "string") == spark, (name, dtype, spark)


def _one_actuator(fleet_dir):
    """The rows of the first actuator of the first file (WINDOWS windows of 2000 samples)."""
    part = pd.read_parquet(sorted(fleet_dir.glob("*.parquet"))[0])
    first = part["actuator_id"].iloc[0]
    return part[part["actuator_id"] == first].reset_index(drop=True), first


def test_fewer_than_3_windows_are_not_tested_rather_than_healthy(fleet_dir):
    # The trend test needs n >= 3 windows (t with n - 2 degrees of freedom): with 2, `worn` is no verdict
    # (<NA>), `tested` False, and a warning names the actuator; worn() lists nobody (audit s12 F6).
    a, aid = _one_actuator(fleet_dir)
    res = fleet.identify_partition(a.iloc[: 2 * 2000])
    assert len(res) == 2 and (res["error"] == "").all()
    with pytest.warns(ipa_sysid.IpaSysidWarning, match=rf"not tested for wear.*: {aid};"):
        tr = fleet.trends(res)
    assert not tr["tested"].iloc[0] and pd.isna(tr["worn"].iloc[0]) and math.isnan(tr["p_value"].iloc[0])
    with pytest.warns(ipa_sysid.IpaSysidWarning):
        assert len(fleet.worn(res)) == 0
    # With every window, the same actuator is tested and gets a verdict.
    tr = fleet.trends(fleet.identify_partition(a))
    assert tr["tested"].iloc[0] and tr["worn"].iloc[0] in (True, False)


def test_a_short_actuator_is_an_error_row_and_a_cut_window_is_said(fleet_dir):
    # An actuator shorter than one window used to vanish from the results; the samples after the last
    # whole window were dropped without a word (audit s12 F6).
    a, aid = _one_actuator(fleet_dir)
    short = a.iloc[:50].assign(actuator_id=-7)
    with pytest.warns(ipa_sysid.IpaSysidWarning) as caught:
        res = fleet.identify_partition(pd.concat([a.iloc[:2100], short], ignore_index=True))
    said = " | ".join(str(w.message) for w in caught)
    assert re.search(rf"1 actuator\(s\) end with an incomplete window .*: {aid} \(100 samples in all\)", said), said
    assert re.search(r"fewer samples than one window \(window = 2000\): -7;", said), said
    assert list(res["actuator_id"]) == [aid, -7]
    row = res[res["actuator_id"] == -7].iloc[0]
    assert row["samples"] == 50 and "has 50 samples, fewer than one window" in row["error"]
    assert row["t_start"] == short["t"].iloc[0] and row["t_end"] == short["t"].iloc[49]
    assert math.isnan(row["b_l"]) and res.loc[res["actuator_id"] == aid, "error"].iloc[0] == ""


def test_bad_settings_are_refused_naming_the_python_argument(fleet_dir):
    a, _ = _one_actuator(fleet_dir)
    a = a.iloc[:2000]
    # An order too large for identify: the same message identify gives, before anything is sized by it
    # (it was a MemoryError from the column names).
    with pytest.raises(ValueError) as direct:
        ipa_sysid.identify(a["u"], a["y"], 0.01, na=10**9)
    with pytest.raises(ValueError) as fl:
        fleet.identify_partition(a, na=10**9)
    assert str(fl.value) == str(direct.value) and "na = 1000000000" in str(fl.value)
    with pytest.raises(ValueError, match=r"invalid setting ts = NaN") as e:
        fleet.identify_partition(a, ts=float("nan"))
    assert "--ts" not in str(e.value)
    for name, value in [("window", -5), ("na", -1), ("detect_warmup", -1), ("window", 2.5)]:
        with pytest.raises(ValueError, match=rf"invalid setting {name} = {value}: expected a whole number >= 0"):
            fleet.identify_partition(a, **{name: value})
    # The same for the package's functions, where the core's conversion named nothing (OverflowError).
    with pytest.raises(ValueError, match=r"invalid setting na = -1: expected a whole number >= 0"):
        ipa_sysid.identify(a["u"], a["y"], 0.01, na=-1)
    with pytest.raises(ValueError, match=r"invalid setting nk = -1"):
        ipa_sysid.identify(a["u"], a["y"], 0.01, "arx", "ls", 2, 1, -1)
    with pytest.raises(ValueError, match=r"invalid setting seed = -1"):
        ipa_sysid.simulate_plant("paper", samples=10, seed=-1)


def test_run_refuses_an_actuator_split_over_files(fleet_dir, tmp_path):
    # Each file is one partition whose windows count from 0: an actuator in two files had its windows
    # numbered twice, silently (audit s12 F3). Now run() names the actuators and files, says how to
    # regroup, and writes no results.
    part = pd.read_parquet(sorted(fleet_dir.glob("*.parquet"))[0])
    half = part.groupby("actuator_id").cumcount() < (WINDOWS // 2) * 2000
    split = tmp_path / "split"
    split.mkdir()
    part[half].to_parquet(split / "part-a.parquet", index=False)
    part[~half].to_parquet(split / "part-b.parquet", index=False)
    out = tmp_path / "out"
    with pytest.raises(ValueError) as e:
        fleet.run(split, out)
    text = str(e.value)
    assert f"{part['actuator_id'].nunique()} actuator(s) have rows in several files" in text
    assert "part-a.parquet, part-b.parquet" in text and "shuffle('actuator_id')" in text
    assert not (out / "results.parquet").exists()


def test_run_names_a_damaged_or_mismatched_file(fleet_dir, tmp_path):
    # Audit s12: a damaged Parquet among the fleet's files, or one whose actuator_id is text where the
    # others have integers, raised pyarrow's error without the file's name; no results are written.
    part = pd.read_parquet(sorted(fleet_dir.glob("*.parquet"))[0])
    out = tmp_path / "out"
    damaged = tmp_path / "damaged"
    damaged.mkdir()
    part.to_parquet(damaged / "a.parquet", index=False)
    (damaged / "b.parquet").write_bytes(b"PAR1 not really")
    with pytest.raises(ValueError, match=r"b\.parquet: not a readable Parquet file"):
        fleet.run(damaged, out)
    mixed = tmp_path / "mixed"
    mixed.mkdir()
    part.to_parquet(mixed / "a.parquet", index=False)
    other = part.assign(actuator_id=part["actuator_id"].map(lambda a: f"0x{a}"))
    other.to_parquet(mixed / "b.parquet", index=False)
    with pytest.raises(ValueError, match=r"b\.parquet: column actuator_id is .* where .*a\.parquet has"):
        fleet.run(mixed, out)
    assert not (out / "results.parquet").exists()


# --- audit s16: the time column, duplicated results, alpha, outputs ---------------------------------


def test_a_gap_a_nan_time_or_repeated_rows_make_an_error_row_and_the_others_go_on(fleet_dir):
    # The reference actuator a is uniformly sampled (t = 0, 0.01, ...). Each faulty copy gets its own
    # id: a gap (one row dropped: step 0.02 s at sample 2500), a NaN time (sorted last: sample n - 1),
    # every row twice (t repeats at sample 1) and a constant time; each is one error row naming the
    # fault and the sample, and a is identified as when it is alone (audit s16 H1).
    a, aid = _one_actuator(fleet_dir)
    n = len(a)
    step = a["t"].iloc[1] - a["t"].iloc[0]
    gap = a.drop(index=2500).assign(actuator_id=-1)
    nan = a.copy().assign(actuator_id=-2)
    nan.loc[5, "t"] = np.nan
    twice = pd.concat([a, a]).assign(actuator_id=-3)
    const = a.assign(actuator_id=-4, t=0.0)
    alone = fleet.identify_partition(a)
    with pytest.warns(ipa_sysid.IpaSysidWarning) as caught:
        res = fleet.identify_partition(pd.concat([gap, a, nan, twice, const], ignore_index=True))
    said = " | ".join(str(w.message) for w in caught)
    assert "4 actuator(s) have a time column that cannot date" in said and "-4, -3, -2, -1" in said, said
    ok = res[res["actuator_id"] == aid].reset_index(drop=True)
    pd.testing.assert_frame_equal(ok, alone)
    err = res[res["actuator_id"] < 0].set_index("actuator_id")
    assert (err["window"] == 0).all() and err["b_l"].isna().all()
    assert list(err.loc[[-1, -2, -3, -4], "samples"]) == [n - 1, n, 2 * n, n]
    assert f"non-uniform sampling: step {2 * step:g} s" in err.loc[-1, "error"]
    assert "(sample 2500 of the actuator's rows sorted by t)" in err.loc[-1, "error"]
    assert "time nan is not a finite number" in err.loc[-2, "error"].lower()
    assert f"(sample {n - 1} " in err.loc[-2, "error"]
    assert "does not increase" in err.loc[-3, "error"] and "(sample 1 " in err.loc[-3, "error"]
    assert "time 0 s does not increase after 0 s" in err.loc[-4, "error"]


def test_a_ts_that_contradicts_the_time_column_is_said_in_each_window(fleet_dir):
    # t doubled (steps of 0.02 s) with ts = 0.01: identified with ts (the same numbers as before: ts sets
    # the time figures, the samples are the same), each window's warnings say so, and so does a warning.
    a, aid = _one_actuator(fleet_dir)
    a = a.iloc[: 3 * 2000]
    ref = fleet.identify_partition(a)
    with pytest.warns(ipa_sysid.IpaSysidWarning, match=rf"contradicts ts = 0.01 s: {aid};"):
        res = fleet.identify_partition(a.assign(t=2.0 * a["t"]))
    for col in ("b_l", "b_r", "m_l", "m_r", "a1", "fit_sim_percent"):
        assert np.array_equal(res[col].to_numpy(), ref[col].to_numpy()), col
    note = "ts = 0.01 s contradicts the time column t (its typical step is 0.02 s)"
    assert all(note in w for w in res["warnings"]), res["warnings"].tolist()
    assert not any("contradicts" in w for w in ref["warnings"])


def test_trends_refuse_duplicated_windows_and_an_alpha_outside_0_1(results, tmp_path):
    # Results appended twice made a healthy actuator "worn" (p from 0.33 to 7.7e-4; audit s16 H3).
    with pytest.raises(ValueError, match=rf"{ACTUATORS} actuator\(s\) have duplicated \(actuator_id, window\) rows"):
        fleet.trends(pd.concat([results, results]))
    with pytest.raises(ValueError, match="duplicated"):
        fleet.worn(pd.concat([results, results.iloc[:1]]))
    for alpha in (2.0, float("nan"), 0.0, 1.0, -0.1, True, "0.01"):
        with pytest.raises(ValueError, match=r"invalid setting alpha = .*: expected .* in \(0, 1\)"):
            fleet.trends(results, alpha=alpha)
    with pytest.raises(ValueError, match=r"invalid setting path = .*: a file name \(this is a folder\)"):
        fleet.report(results, tmp_path)
    assert os.listdir(tmp_path) == []


def test_run_refuses_an_output_in_the_input_folder(fleet_dir, tmp_path):
    # An input partition named results.parquet was replaced by the results, and an output folder inside
    # the input folder was read back as a partition by the next run (audit s16 M3): both refused before
    # anything is computed or written.
    part = pd.read_parquet(sorted(fleet_dir.glob("*.parquet"))[0])
    d = tmp_path / "in"
    d.mkdir()
    part.to_parquet(d / "results.parquet", index=False)
    before = (d / "results.parquet").read_bytes()
    with pytest.raises(ValueError, match="would replace the input file"):
        fleet.run(d, d)
    with pytest.raises(ValueError, match=r"is inside input_dir"):
        fleet.run(d, d / "out")
    with pytest.raises(ValueError, match="would replace the input file"):
        fleet.run(d, tmp_path / "." / "in")
    assert (d / "results.parquet").read_bytes() == before
    assert sorted(os.listdir(d)) == ["results.parquet"]
