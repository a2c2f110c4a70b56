"""Audit s26 (fixap): fleet.run's walk of its input folder (M-1: linked folders, files outside it; L-4:
a missing folder, one file, a CSV folder, a hive-partitioned folder), the fleet summary's per-actuator
doubts (M-2) and a failed window's words (L-3). Each expectation is built from the records the test
writes, not from the program's output."""

import os
import warnings

import numpy as np
import pytest

pd = pytest.importorskip("pandas", reason="ipa_sysid.fleet needs pandas: pip install 'ipa-sysid[fleet]'")
pytest.importorskip("pyarrow", reason="ipa_sysid.fleet needs pyarrow: pip install 'ipa-sysid[fleet]'")
pytest.importorskip("dask.dataframe", reason="ipa_sysid.fleet needs dask[dataframe]: pip install 'ipa-sysid[fleet]'")

import ipa_sysid  # noqa: E402
from ipa_sysid import fleet  # noqa: E402

from test_ipa_sysid import cli  # noqa: E402

ACTUATORS, WINDOWS, PER_FILE = 8, 4, 4


@pytest.fixture(scope="module")
def fleet_dir(tmp_path_factory):
    d = tmp_path_factory.mktemp("fleet26") / "records"
    cli(
        "simulate", "--fleet", ACTUATORS, "--worn", 0.25, "--windows", WINDOWS, "--seed", 7,
        "--per-file", PER_FILE, "--out", d,
    )
    return d


def _one_file(fleet_dir):
    return sorted(fleet_dir.glob("*.parquet"))[0]


def test_run_does_not_follow_a_link_loop_nor_a_link_out_of_the_folder(fleet_dir, tmp_path):
    # Audit s26 M-1: glob("**") followed sub/self -> ../sub ~40 times (one file read as 41 partitions,
    # then a false "rows in several files" error) and up -> .. into sibling folders.
    src = _one_file(fleet_dir)
    ids = sorted(pd.read_parquet(src)["actuator_id"].unique())
    top = tmp_path / "loop"
    (top / "sub").mkdir(parents=True)
    os.symlink(src, top / "sub" / "part-0.parquet")  # a file link to a file outside: not read
    (top / "sub" / "own.parquet").write_bytes(src.read_bytes())
    os.symlink("own.parquet", top / "sub" / "again.parquet")  # a second name of the same file
    os.symlink("../sub", top / "sub" / "self")
    os.symlink("..", top / "up")
    sibling = tmp_path / "other"
    sibling.mkdir()
    (sibling / "x.parquet").write_bytes(b"not parquet")  # outside: would fail the run if read
    with pytest.warns(ipa_sysid.IpaSysidWarning) as said:
        files = fleet._parquet_files(top)
    assert files == [str(top / "sub" / "own.parquet")]
    text = " ".join(str(w.message) for w in said)
    assert "2 linked folder(s)" in text and "not descended into" in text
    assert "1 file link(s)" in text and "outside" in text and "part-0.parquet" in text
    assert "again.parquet" in text and "read once" in text
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ipa_sysid.IpaSysidWarning)
        r = fleet.run(top, tmp_path / "out")
    assert sorted(r["actuator_id"].unique()) == ids
    assert not r.duplicated(["actuator_id", "window"]).any()


def test_run_says_what_the_input_is_when_it_is_not_a_parquet_folder(fleet_dir, tmp_path):
    # Audit s26 L-4: "no *.parquet files" for all four.
    with pytest.raises(FileNotFoundError, match="no such folder"):
        fleet.run(tmp_path / "nonexist", tmp_path / "o1")
    src = _one_file(fleet_dir)
    with pytest.raises(ValueError, match="a file; run reads a folder of Parquet files: pass the folder"):
        fleet.run(src, tmp_path / "o2")
    csvdir = tmp_path / "csvdir"
    csvdir.mkdir()
    pd.read_parquet(src).to_csv(csvdir / "part-0.csv", index=False)
    with pytest.raises(ValueError, match=r"1 CSV file\(s\).*run reads Parquet only.*read_csv"):
        fleet.run(csvdir, tmp_path / "o3")
    hive = tmp_path / "hive"
    pd.read_parquet(src).to_parquet(hive, partition_cols=["actuator_id"], index=False)
    with pytest.raises(ValueError, match=r"the id is in the folder name actuator_id=\d+ \(a hive"):
        fleet.run(hive, tmp_path / "o4")


def test_the_summary_names_each_actuator_s_doubts_and_the_counts_add_up(fleet_dir, tmp_path):
    # Audit s26 M-2: an actuator logging t in ms had a width trend 1000x too small beside the others',
    # unmarked; y in metres, a failed window, an untested and an unidentified actuator were named
    # nowhere in trends / worn / report.
    part = pd.concat([pd.read_parquet(f) for f in sorted(fleet_dir.glob("*.parquet"))], ignore_index=True)
    ids = sorted(part["actuator_id"].unique())
    ms, metres, nan_y, short, gap = ids[:5]
    rows = {a: part["actuator_id"] == a for a in ids}
    part.loc[rows[ms], "t"] *= 1000.0  # a logger writing milliseconds
    part.loc[rows[metres], "y"] /= 1000.0  # y in other units
    k = part.index[rows[nan_y]][2 * 2000 + 5]  # a NaN y in window 2 of nan_y
    part.loc[k, "y"] = np.nan
    part = part.drop(part.index[rows[short]][2 * 2000:])  # 2 windows: not tested
    g = part.index[part["actuator_id"] == gap][3000]
    part.loc[part["actuator_id"] == gap, "t"] += np.where(part.index[part["actuator_id"] == gap] >= g, 5.0, 0.0)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ipa_sysid.IpaSysidWarning)
        r = fleet.identify_partition(part)
    with pytest.warns(ipa_sysid.IpaSysidWarning) as said:
        tr = fleet.trends(r)
    assert len([w for w in said if w.category is ipa_sysid.IpaSysidWarning]) == 1  # one per call
    assert sorted(tr["actuator_id"]) == ids  # every actuator has a row, the unidentified one too
    note = dict(zip(tr["actuator_id"], tr["notes"]))
    assert "step 10 s where ts = 0.01 s (1000x, t in ms?)" in note[ms]
    assert "mean slope" in note[metres] and "other units" in note[metres]
    assert note[nan_y].startswith(f"1 of {WINDOWS} window(s) not identified (first: window 2, t ")
    assert f"actuator {nan_y}, window 2 (t " in note[nan_y] and "is NaN, not a finite number" in note[nan_y]
    assert note[short] == "not tested: 2 identified window(s), fewer than 3"
    assert note[gap].startswith("not identified")
    for a in ids[5:]:
        assert note[a] == "", (a, note[a])
    failed = dict(zip(tr["actuator_id"], tr["failed_windows"]))
    assert failed[nan_y] == 1 and failed[gap] == 1 and failed[ids[5]] == 0
    # worn() keeps the notes; the summary's counts add up to the actuators.
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ipa_sysid.IpaSysidWarning)
        assert "notes" in fleet.worn(r).columns
        text = fleet.summary(r)
    assert text.startswith(
        f"{ACTUATORS} actuators: {ACTUATORS - 2} tested for wear ("
    ), text
    assert f"1 identified but not tested (id {short}: not tested: 2 identified window(s)" in text
    assert f"1 not identified (id {gap}: not identified" in text
    assert "3 tested actuator(s) with a doubt on their figures" in text
    assert f"id {ms}: time column step 10 s" in text
    with pytest.warns(ipa_sysid.IpaSysidWarning) as said:
        fleet.report(r, tmp_path / "worn.html")
    assert len([w for w in said if w.category is ipa_sysid.IpaSysidWarning]) == 1  # the report made the trend table once (audit s26 M-2 aside)
    page = (tmp_path / "worn.html").read_text()
    assert f"{ACTUATORS} actuators: {ACTUATORS - 2} tested" in page
    assert "not tested, not identified, or with a doubt" in page and "t in ms?" in page
    assert f"of {ACTUATORS} actuators tested" in page


def test_a_failed_window_names_the_actuator_and_its_time_and_warns(fleet_dir):
    # Audit s26 L-3: "group 2 window 3: y(1000) = NaN" for actuator 7 (group = its position in the
    # partition), no time, no IpaSysidWarning.
    part = pd.read_parquet(sorted(fleet_dir.glob("*.parquet"))[1])
    aid = sorted(part["actuator_id"].unique())[2]  # the partition's third actuator: group 2
    rows = part.index[part["actuator_id"] == aid]
    k = rows[3 * 2000 + 1000]
    part.loc[k, "y"] = np.nan
    t = part.loc[rows, "t"].to_numpy()
    with pytest.warns(ipa_sysid.IpaSysidWarning, match=rf"1 window\(s\) of 1 actuator\(s\) not identified: {aid};"):
        r = fleet.identify_partition(part)
    err = r.loc[r["error"] != "", "error"].tolist()
    assert err == [
        f"actuator {aid}, window 3 (t {t[6000]:g}–{t[7999]:g} s): y at t = {t[7000]:g} s (sample 1000 of "
        "the window) is NaN, not a finite number"
    ]
