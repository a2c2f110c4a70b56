"""Audit s19, the Python findings H-2, H-4, L-5 and L-6: the package reads and writes a user's path as
the command line does (the same Rust functions: `open_input` and its 1 MiB bound for a controller file,
`resolve_output` / `write_atomic` for every output), and refuses what the command line refuses, naming
the argument. No test points an output at a real device: a FIFO made in a temporary folder stands for
one (the devices take the same branch of `resolve_output`)."""

import json
import math
import os
import stat
import subprocess
import threading

import numpy as np
import pytest

import ipa_sysid
from binary import cli_path

pd = pytest.importorskip("pandas", reason="ipa_sysid.fleet needs pandas: pip install 'ipa-sysid[fleet]'")
from ipa_sysid import fleet  # noqa: E402


def run(*args):
    return subprocess.run([cli_path(), *map(str, args)], capture_output=True, text=True)


def caused_by(stderr):
    """The last `caused by:` line of the command line's error, without its label (the reader's words)."""
    lines = [l.strip() for l in stderr.splitlines() if l.strip().startswith("caused by:")]
    assert lines, stderr
    return lines[-1].removeprefix("caused by:").strip()


def in_thread(f, timeout=60):
    """Runs f() in a thread; fails (rather than hangs) when it has not returned within `timeout` s."""
    box = {}

    def target():
        try:
            box["value"] = f()
        except BaseException as e:  # noqa: BLE001 - handed to the caller
            box["error"] = e

    t = threading.Thread(target=target, daemon=True)
    t.start()
    t.join(timeout)
    assert not t.is_alive(), f"still running after {timeout} s"
    if "error" in box:
        raise box["error"]
    return box.get("value")


def read_fifo(path, box):
    """A reader thread for the FIFO `path`: its bytes go to box["bytes"]."""

    def target():
        with open(path, "rb") as f:
            box["bytes"] = f.read()

    t = threading.Thread(target=target, daemon=True)
    t.start()
    return t


# A results table of three actuators x five windows, made by hand: actuator 2's deadzone widens by 4
# counts per window and its slopes drop, the others stay put with a little scatter.
def results_table():
    rows = []
    rng = np.random.default_rng(5)
    for aid in (1, 2, 3):
        for w in range(5):
            width = 40.0 + (4.0 * w if aid == 2 else rng.normal(0, 0.3))
            slope = 0.01 - (0.001 * w if aid == 2 else rng.normal(0, 1e-5))
            rows.append({"actuator_id": aid, "window": w, "t_start": 3600.0 * w, "b_l": -width / 2,
                         "b_r": width / 2, "deadzone_width": width, "m_l": slope, "m_r": slope,
                         "error": ""})
    return pd.DataFrame(rows)


# ---------------------------------------------------------------------------------------------------
# H-4: fleet.report (and every other Python output) is written as the command line writes an output.


def test_report_streams_into_a_fifo_and_leaves_it_a_fifo(tmp_path):
    res = results_table()
    reference = tmp_path / "ref.html"
    fleet.report(res, reference)
    fifo = tmp_path / "pipe"
    os.mkfifo(fifo)
    box = {}
    reader = read_fifo(fifo, box)
    in_thread(lambda: fleet.report(res, fifo))
    reader.join(30)
    assert stat.S_ISFIFO(os.lstat(fifo).st_mode), "the FIFO was replaced by a file"
    assert box["bytes"] == reference.read_bytes()
    assert sorted(os.listdir(tmp_path)) == ["pipe", "ref.html"], "no temporary file is left"


def test_report_follows_a_link_refuses_a_folder_and_names_a_missing_folder(tmp_path):
    res = results_table()
    reference = tmp_path / "ref.html"
    fleet.report(res, reference)
    target = tmp_path / "target.html"
    target.write_text("old")
    link = tmp_path / "link.html"
    link.symlink_to(target)
    # Audit s22 M-B9: a link is written through only with force=True (the command line's --force).
    with pytest.raises(ValueError, match=r"not a symbolic link .*pass force=True"):
        fleet.report(res, link)
    assert target.read_text() == "old"
    fleet.report(res, link, force=True)
    assert link.is_symlink() and target.read_bytes() == reference.read_bytes()
    # A folder: the command line's words, with the argument's name (`invalid setting --out = ...`).
    with pytest.raises(ValueError) as e:
        fleet.report(res, tmp_path)
    assert str(e.value) == f"invalid setting path = {tmp_path}: a file name (this is a folder)"
    # A missing folder: the error names the output, not the temporary file beside it.
    missing = tmp_path / "nodir" / "worn.html"
    with pytest.raises(FileNotFoundError) as e:
        fleet.report(res, missing)
    assert e.value.filename == str(missing) and ".tmp" not in str(e.value)
    # A read-only file is refused as the command line refuses it (also as root).
    ro = tmp_path / "ro.html"
    ro.write_text("keep")
    os.chmod(ro, 0o444)
    with pytest.raises(ValueError, match=r"invalid setting path = .*ro\.html: a writable file"):
        fleet.report(res, ro)
    assert ro.read_text() == "keep"


def test_outputs_get_the_permissions_of_a_new_file_or_of_the_file_they_replace(tmp_path):
    # Audit s12: the report was created 0600 (a bare temporary file renamed); now the command line's
    # writer gives 0o666 less the umask, or the mode of the file replaced.
    res = results_table()
    umask = os.umask(0o022)
    try:
        new = tmp_path / "new.html"
        fleet.report(res, new)
        assert stat.S_IMODE(new.stat().st_mode) == 0o666 & ~0o022
        # An earlier report (audit s22 M-B9: only a file of the same kind is replaced without force=True).
        old = tmp_path / "old.html"
        old.write_text("<!DOCTYPE html>\n<p>old</p>\n")
        os.chmod(old, 0o640)
        fleet.report(res, old)
        assert old.read_text().startswith("<!DOCTYPE html>")
        assert stat.S_IMODE(old.stat().st_mode) == 0o640
    finally:
        os.umask(umask)


def test_model_save_streams_into_a_fifo_and_refuses_a_folder_by_name(tmp_path):
    m = ipa_sysid.paper_model()
    fifo = tmp_path / "pipe"
    os.mkfifo(fifo)
    box = {}
    reader = read_fifo(fifo, box)
    in_thread(lambda: m.save(fifo))
    reader.join(30)
    assert stat.S_ISFIFO(os.lstat(fifo).st_mode)
    assert box["bytes"].decode() == m.to_json()
    with pytest.raises(ValueError, match=r"^invalid setting path = .*: a file name \(this is a folder\)$"):
        m.save(tmp_path)


def test_run_writes_results_through_the_same_writer(tmp_path):
    pytest.importorskip("dask.dataframe", reason="fleet.run needs dask[dataframe]")
    t, u, y, _ = ipa_sysid.simulate_plant("paper", samples=1000, seed=2)
    inp = tmp_path / "in"
    inp.mkdir()
    pd.DataFrame({"actuator_id": 7, "t": t, "u": u, "y": y}).to_parquet(inp / "part-0.parquet", index=False)
    out = tmp_path / "out"
    # results.parquet as a folder: refused before anything is computed, naming output_dir.
    (out / "results.parquet").mkdir(parents=True)
    with pytest.raises(ValueError, match=r"^invalid setting output_dir = .*results\.parquet: a file name \(this is a folder\)$"):
        fleet.run(inp, out, window=500)
    (out / "results.parquet").rmdir()
    # A link at results.parquet is followed: the file it names gets the results, the link stays.
    target = tmp_path / "elsewhere.parquet"
    target.write_bytes(b"old")
    (out / "results.parquet").symlink_to(target)
    res = fleet.run(inp, out, window=500, force=True)
    assert (out / "results.parquet").is_symlink()
    pd.testing.assert_frame_equal(pd.read_parquet(target), res)
    assert len(res) == 2 and list(res["window"]) == [0, 1]


# ---------------------------------------------------------------------------------------------------
# H-2: control(controller=PATH) reads the file as `control --controller` does.


def test_a_controller_path_is_read_as_the_command_line_reads_it(tmp_path):
    fifo = tmp_path / "ctl.fifo"
    os.mkfifo(fifo)
    big = tmp_path / "big.json"
    big.write_bytes(b" " * (2**20 + 1))  # one byte over 1 MiB
    cases = {
        str(fifo): "this is a FIFO",
        "/dev/zero": "this is a character device",  # read-only: an input, never an output
        str(tmp_path): "this is a folder",
        str(big): f"may have at most {2**20} bytes",
    }
    for path, words in cases.items():
        with pytest.raises(ValueError) as e:
            in_thread(lambda: ipa_sysid.control("paper", setpoint=50, duration=1, controller=path), timeout=30)
        msg = str(e.value)
        assert msg.startswith("cannot read controller: ") and words in msg, (path, msg)
        # The reader's own words, as the command line prints them after `caused by:`.
        r = run("control", "--plant", "paper", "--setpoint", 50, "--duration", 1, "--controller", path)
        assert r.returncode == 2, r.stderr
        assert caused_by(r.stderr) in msg, (path, r.stderr, msg)
    with pytest.raises(FileNotFoundError):
        ipa_sysid.control("paper", setpoint=50, duration=1, controller=str(tmp_path / "none.json"))


def test_a_controller_file_given_as_a_path_object_runs_as_its_text(tmp_path):
    t = ipa_sysid.tune(model=str(_tune_model(tmp_path)), max_evaluations=10, variants=1)
    ctl = tmp_path / "c.json"
    ctl.write_text(t["controller_file"])
    a = ipa_sysid.control("paper", setpoint=40, duration=1, controller=ctl)
    b = ipa_sysid.control("paper", setpoint=40, duration=1, controller=t["controller_file"])
    assert np.array_equal(a["u"], b["u"]) and np.array_equal(a["y"], b["y"])


def _tune_model(tmp_path):
    path = tmp_path / "m.json"
    path.write_text(json.dumps({
        "format": "ipa-sysid-model", "version": 2,
        "model": {"kind": "hammerstein", "ts": 0.01, "na": 1, "nb": 1, "nk": 1, "a": [-1.0], "b": [1.0],
                  "offset": None, "deadzone": {"b_l": -20.0, "b_r": 20.0, "m_l": 0.005, "m_r": 0.005},
                  "noise_model": "output-error"},
    }))
    return path


# ---------------------------------------------------------------------------------------------------
# L-5: identify refuses another method's settings as the command line does; Rls.update names y.


def _record():
    rng = np.random.default_rng(1)
    u = np.repeat(rng.choice([-60.0, 60.0], 50), 10)
    y = np.zeros_like(u)
    for k in range(1, len(u)):
        y[k] = 0.9 * y[k - 1] + 0.05 * u[k - 1]
    return u, y


def test_settings_of_the_recursive_estimators_are_refused_with_ls(tmp_path):
    u, y = _record()
    kw = dict(model="arx", na=1, nb=1, nk=1)
    for setting in (dict(forgetting=float("nan")), dict(forgetting=-1.0), dict(forgetting=2.0),
                    dict(p0=-1.0), dict(p0=float("inf"))):
        (name, _), = setting.items()
        with pytest.raises(ValueError) as e:
            ipa_sysid.identify(u, y, 0.01, method="ls", **kw, **setting)
        assert str(e.value) == (f'{name} is a setting of the recursive estimators (method="rls" or "iv"); '
                                'method="ls" does not use it; leave it out')
    with pytest.raises(ValueError, match=r'^passes is a setting of recursive least squares \(method="rls"\); method="oe"'):
        ipa_sysid.identify(u, y, 0.01, method="oe", passes=2, **kw)
    # The command line says the same of the same setting, with its flags.
    path = tmp_path / "r.csv"
    np.savetxt(path, np.column_stack([np.arange(len(u)) * 0.01, u, y]), delimiter=",", header="t,u,y", comments="")
    r = run("identify", "--data", path, "--structure", "arx", "--method", "ls", "--na", 1, "--nb", 1, "--nk", 1,
            "--forgetting", "nan")
    assert r.returncode == 2
    assert ("--forgetting is a setting of the recursive estimators (--method rls or iv); --method ls does not "
            "use it") in r.stderr
    # With a recursive method the value itself is checked (a NaN forgetting factor is no factor).
    with pytest.raises(ValueError, match="forgetting"):
        ipa_sysid.identify(u, y, 0.01, method="rls", forgetting=float("nan"), **kw)


def test_rls_update_names_a_non_finite_y_or_phi_and_keeps_its_state():
    est = ipa_sysid.Rls(2, 1.0, 100.0)
    est.update([1.0, 2.0], 3.0)
    theta, P, n = est.theta.copy(), est.P.copy(), est.samples
    with pytest.raises(ValueError, match=r"^y = NaN: expected a finite number; the estimate is unchanged$"):
        est.update([1.0, 0.5], float("nan"))
    with pytest.raises(ValueError, match=r"^y = inf: "):
        est.update([1.0, 0.5], float("inf"))
    with pytest.raises(ValueError, match=r"phi"):
        est.update([1.0, float("nan")], 1.0)
    assert np.array_equal(est.theta, theta) and np.array_equal(est.P, P) and est.samples == n


# ---------------------------------------------------------------------------------------------------
# L-6: identify_partition and the report's helpers name what they refuse.


def _partition():
    t, u, y, _ = ipa_sysid.simulate_plant("paper", samples=1000, seed=4)
    return pd.DataFrame({"actuator_id": 1, "t": t, "u": u, "y": y})


def test_identify_partition_refuses_complex_and_unnamed_bad_arguments():
    base = _partition()
    with pytest.raises(ValueError) as e:
        fleet.identify_partition(base.assign(y=base.y + 50j), window=500)
    assert str(e.value) == ("partition: column y: expected an array of real numbers (integers or floats), "
                            "got dtype complex128")
    with pytest.raises(ValueError, match=r"^partition: column u: .* got dtype bool$"):
        fleet.identify_partition(base.assign(u=base.u > 0), window=500)
    with pytest.raises(ValueError, match=rf"^invalid setting window = {2**64}: expected a whole number that fits 64 bits$"):
        fleet.identify_partition(base, window=2**64)
    with pytest.raises(ValueError, match=r"^invalid setting window = None: "):
        fleet.identify_partition(base, window=None)
    for bad in (None, base.to_numpy()):
        with pytest.raises(TypeError, match=r"^partition: expected a pandas DataFrame with columns actuator_id, t, u, y"):
            fleet.identify_partition(bad)
    for f in (fleet.trends, fleet.worn):
        with pytest.raises(TypeError, match=r"^results: expected a pandas DataFrame"):
            f("x")
    # The real record still gives its two windows.
    assert len(fleet.identify_partition(base, window=500)) == 2


def test_glance_svg_refuses_sizes_that_are_not_pixels():
    tr = fleet.trends(results_table())
    for name in ("width", "height"):
        for v in (float("nan"), -5, 0, 112, math.inf, True):
            with pytest.raises(ValueError, match=rf"^invalid setting {name} = "):
                fleet.glance_svg(tr, **{name: v})
    assert fleet.glance_svg(tr, width=113, height=300).startswith('<svg xmlns="http://www.w3.org/2000/svg" width="113" height="300"')


# L-4 (Python side): tune names the spec key, as the command line does.
def test_tune_names_the_spec_key_when_its_scale_is_out_of_range(tmp_path):
    with pytest.raises(ValueError, match=r"^invalid setting spec = steps=1e-9: steps of at least"):
        ipa_sysid.tune(model=str(_tune_model(tmp_path)), spec="steps=1e-9", max_evaluations=8, variants=1)
    with pytest.raises(ValueError, match=r"^invalid setting spec = u-max=1e308: a command limit of at most 1e6"):
        ipa_sysid.tune(model=str(_tune_model(tmp_path)), spec="u-max=1e308", max_evaluations=8, variants=1)


def test_rls_update_many_checks_every_row_before_applying_any():
    # A non-finite y or phi at row k is refused before rows 0..k-1 are applied: the state after the
    # refusal is the state before the call (fixu; the rows before k used to be applied first).
    rng = np.random.default_rng(3)
    Phi = rng.normal(size=(6, 2))
    y = Phi @ np.array([0.5, -1.0])
    est = ipa_sysid.Rls(2, 1.0, 100.0)
    est.update([1.0, 2.0], 3.0)
    theta, P, n = est.theta.copy(), est.P.copy(), est.samples
    bad_y = y.copy()
    bad_y[4] = np.nan
    with pytest.raises(ValueError, match=r"^y\(4\) = NaN: expected a finite number \(row 4\); the estimate is unchanged$"):
        est.update_many(Phi, bad_y)
    assert np.array_equal(est.theta, theta) and np.array_equal(est.P, P) and est.samples == n
    bad_phi = Phi.copy()
    bad_phi[3, 1] = -np.inf
    with pytest.raises(ValueError, match=r"^Phi\(3, 1\) = -inf: expected finite numbers \(row 3\); "):
        est.update_many(bad_phi, y)
    assert np.array_equal(est.theta, theta) and np.array_equal(est.P, P) and est.samples == n
    # The good record then applies as one update at a time does.
    ref = ipa_sysid.Rls(2, 1.0, 100.0)
    ref.update([1.0, 2.0], 3.0)
    for k in range(len(y)):
        ref.update(Phi[k], y[k])
    est.update_many(Phi, y)
    assert np.array_equal(est.theta, ref.theta) and np.array_equal(est.P, ref.P) and est.samples == n + len(y)
