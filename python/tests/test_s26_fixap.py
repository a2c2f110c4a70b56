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

ACTUATORS, WINDOWS, PER_FILE = 4, 4, 2


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
