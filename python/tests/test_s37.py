"""Session 37 (helper rd37). `Rls.update_many` answers Ctrl-C between chunks of rows and puts back the
state from before the call, so a KeyboardInterrupt means nothing was applied (audit s36 L-9: the
exception came after every row had been applied). `Rls(n=-1)` says what `identify(na=-1)` says.

The interrupted call runs in a fresh interpreter (a subprocess), which receives a SIGINT that another
process sends 0.3 s into the call (`sh -c "sleep 0.3; kill -INT PID"`), as a terminal's Ctrl-C: the
timer thread of test_s33_fixpy.py cannot send it here, since update_many holds the GIL and that thread
cannot run before it returns (audit s36 L-9 measured that way, which alone made its interrupt late)."""

import math
import subprocess
import sys
import textwrap

import numpy as np
import pytest

import ipa_sysid as s

# One interpreter: an uninterrupted call on n0 rows (its length measured), or the interrupted call on
# n rows with SIGINT 0.3 s in. It prints the outcome and whether the state after the call equals the
# one before it (theta, P and samples, to the bit), then feeds the first 1000 rows again and prints
# whether theta equals that of a fresh Rls fed with the 1000 rows after the same first 1000 (the state
# an uninterrupted history gives; if the interrupted call had applied rows, it would differ).
SCRIPT = textwrap.dedent(
    """
    import os, subprocess, sys, time
    import numpy as np
    import ipa_sysid as s
    n_par, n = 40, int(sys.argv[2])
    rng = np.random.default_rng(7)
    Phi = rng.standard_normal((n, n_par))
    y = Phi @ np.linspace(-1.0, 1.0, n_par) + 0.01 * rng.standard_normal(n)
    r = s.Rls(n_par)
    r.update_many(Phi[:1000], y[:1000])
    before = (r.theta.copy(), r.P.copy(), r.samples)
    if sys.argv[1] == "interrupt":
        # Sent by another process, as a terminal's Ctrl-C: a timer thread of this interpreter could not
        # run (to call os.kill) before update_many, which holds the GIL, returns.
        subprocess.Popen(["sh", "-c", f"sleep 0.3; kill -INT {os.getpid()}"])
    start = time.monotonic()
    try:
        r.update_many(Phi, y)
        print("finished", time.monotonic() - start)
    except KeyboardInterrupt:
        print("KeyboardInterrupt", time.monotonic() - start)
    same = (np.array_equal(r.theta, before[0]) and np.array_equal(r.P, before[1])
            and r.samples == before[2])
    print("same-state", same)
    if sys.argv[1] == "interrupt":
        r.update_many(Phi[1000:2000], y[1000:2000])
        fresh = s.Rls(n_par)
        fresh.update_many(Phi[:1000], y[:1000])
        fresh.update_many(Phi[1000:2000], y[1000:2000])
        print("as-if-never-called", np.array_equal(r.theta, fresh.theta) and r.samples == 2000)
    """
)

# The interrupted call is sized to take at least this long uninterrupted (s), and must end this soon
# after its start (the signal at 0.3 s; the handlers run every 4 096 rows, about 4 ms of n = 40 at
# the release build's speed).
LONG_S = 4.0
PROMPT_S = 2.0
# Rows of the measured call, and the most the test may ask for (Phi: n × 40 × 8 bytes; 1.5 M rows are
# 480 MB).
N0, N_MAX = 50_000, 1_500_000


def _run(mode, n):
    r = subprocess.run(
        [sys.executable, "-c", SCRIPT, mode, str(n)],
        capture_output=True,
        text=True,
        timeout=900,
    )
    assert "PanicException" not in r.stderr and "panicked" not in r.stderr, r.stderr
    lines = [line.split() for line in r.stdout.splitlines()]
    assert lines and lines[0][0] in ("finished", "KeyboardInterrupt"), (r.stdout, r.stderr)
    return lines, r


def test_update_many_interrupted_puts_back_the_state_from_before_the_call():
    lines, r = _run("run", N0)
    assert lines[0][0] == "finished" and lines[1] == ["same-state", "False"], (r.stdout, r.stderr)
    t0 = float(lines[0][1])
    n = N0 * max(1, math.ceil(1.5 * LONG_S / max(t0, 1e-3)))
    if n > N_MAX:
        pytest.skip(f"{t0:.3f} s for {N0} rows: a call of {LONG_S} s needs {n} rows, beyond {N_MAX}")
    lines, r = _run("interrupt", n)
    assert lines[0][0] == "KeyboardInterrupt", (
        f"{n} rows (about {t0 * n / N0:.1f} s uninterrupted) finished although SIGINT came at 0.3 s",
        r.stdout,
    )
    assert float(lines[0][1]) < PROMPT_S, r.stdout
    assert lines[1] == ["same-state", "True"], r.stdout
    assert lines[2] == ["as-if-never-called", "True"], r.stdout


def test_rls_n_is_worded_as_identify_na():
    # The same rule, the same words (the argument's own name): a negative whole number, and a float.
    with pytest.raises(ValueError) as rls:
        s.Rls(-1)
    u = np.sin(np.arange(100.0))
    with pytest.raises(ValueError) as ident:
        s.identify(u, u, 0.01, model="arx", method="ls", na=-1)
    assert str(rls.value) == "invalid setting n = -1: expected a whole number >= 0"
    assert str(ident.value) == "invalid setting na = -1: expected a whole number >= 0"
    with pytest.raises(TypeError) as rls:
        s.Rls(2.5)
    with pytest.raises(TypeError) as ident:
        s.identify(u, u, 0.01, model="arx", method="ls", na=2.5)
    assert str(rls.value) == "n: 'float' object cannot be interpreted as an integer"
    assert str(ident.value) == "na: 'float' object cannot be interpreted as an integer"


def test_a_ms_time_column_is_advised_as_milliseconds():
    # Audit s35 L-5: t in ms with the right ts = 0.01 s (step 10 s, 1000 times ts): the advice is to
    # convert t, with "pass ts = 10" only for a column that truly is in seconds; a step of 2 x ts is not
    # a unit and keeps the one advice.
    fleet = pytest.importorskip("ipa_sysid.fleet")
    note = fleet._ts_note(0.01, 10.0)
    assert "if t holds milliseconds, ts is right and t is not in seconds: divide t by 1000" in note
    assert note.endswith("if t is in seconds, pass ts = 10 to use the column")
    assert "microseconds" in fleet._ts_note(0.01, 1e4)
    plain = fleet._ts_note(0.01, 0.02)
    assert plain.endswith("pass ts = 0.02 to use the column") and "milliseconds" not in plain


def _fleet_file(path, pd, t=None):
    n = 300
    frame = pd.DataFrame(
        {
            "actuator_id": np.full(n, 1, dtype=np.int64),
            "t": np.arange(n) * 0.01 if t is None else t,
            "u": np.where(np.arange(n) // 25 % 2 == 0, 120.0, -120.0),
            "y": np.linspace(10.0, 20.0, n),
        }
    )
    frame.to_parquet(path, index=False, compression=None)
    return frame


def test_a_fleet_time_column_of_timestamps_is_named_with_its_file(tmp_path):
    # Audit s35 L-4: a t column of timestamps (a logger's layout) was refused without the file and with
    # no way out; now the file and the conversion to seconds are named, and identify_partition names
    # the way out too.
    pd = pytest.importorskip("pandas")
    pytest.importorskip("pyarrow")
    pytest.importorskip("dask.dataframe")
    from ipa_sysid import fleet

    src = tmp_path / "in"
    src.mkdir()
    stamps = pd.date_range("2026-11-29", periods=300, freq="10ms")
    frame = _fleet_file(src / "part-0.parquet", pd, t=stamps)
    with pytest.raises(ValueError) as e:
        fleet.run(str(src), str(tmp_path / "out"))
    msg = str(e.value)
    assert msg.startswith(str(src / "part-0.parquet") + ": column t is timestamp"), msg
    assert ".dt.total_seconds()" in msg
    with pytest.raises(ValueError, match=r"column t: .*datetime64.*holds dates or durations.*total_seconds"):
        fleet.identify_partition(frame, window=100)


def test_a_fleet_file_damaged_past_its_footer_is_named(tmp_path):
    # Audit s35 L-4: a file whose footer reads but whose data do not (one bit flipped in a column
    # chunk) failed inside Dask with pyarrow's words and no file. The damaged copy is found here by
    # flipping one bit at a time of a valid file until pyarrow reads its schema but not its columns.
    pd = pytest.importorskip("pandas")
    pq = pytest.importorskip("pyarrow.parquet")
    pytest.importorskip("dask.dataframe")
    from ipa_sysid import fleet

    good = tmp_path / "good.parquet"
    _fleet_file(good, pd)
    data = good.read_bytes()
    bad = tmp_path / "in" / "part-1.parquet"
    bad.parent.mkdir()
    found = False
    for at in range(4, len(data) - 8):
        for bit in (0x80, 0x01):
            mutant = bytearray(data)
            mutant[at] ^= bit
            bad.write_bytes(bytes(mutant))
            try:
                pq.read_schema(bad)
            except Exception:
                continue
            try:
                pq.read_table(bad, columns=["actuator_id", "t", "u", "y"])
            except Exception:
                found = True
                break
        if found:
            break
    if not found:
        pytest.skip("no single bit flip of this file reads its footer but not its data")
    _fleet_file(tmp_path / "in" / "part-0.parquet", pd)
    with pytest.raises(ValueError) as e:
        fleet.run(str(tmp_path / "in"), str(tmp_path / "out"))
    assert str(e.value).startswith(f"{bad}: not a readable Parquet file ("), str(e.value)


def test_two_messages_name_the_keyword_typed():
    # Audit s35 L-7: an array for Rls.update's y said numpy's words and named nothing; simulate_plant's
    # x0 = NaN was called y0 (the command line's --y0).
    r = s.Rls(4)
    with pytest.raises(TypeError) as e:
        r.update(np.ones(4), np.ones(2))
    assert str(e.value).startswith("y: "), str(e.value)
    assert r.samples == 0
    with pytest.raises(ValueError) as e:
        s.simulate_plant("paper", samples=10, x0=float("nan"))
    assert str(e.value) == "invalid setting x0 = NaN: a finite position in mm"


def test_every_path_argument_takes_str_bytes_and_pathlike(tmp_path):
    # Audit s35 L-8: calibrate(b'rec.csv'), simulate_plant(plant=Path(...)) and plant_config=b'...' were
    # refused ("'bytes' object is not an instance of 'str'") where load_model took them. The same call
    # with each form of the path gives the same result as with the str.
    import os
    import pathlib

    model = tmp_path / "m.json"
    s.paper_model().save(str(model))
    ref = s.simulate_plant(plant=str(model), samples=50)[2]
    for form in (pathlib.Path(model), os.fsencode(str(model)), b"model:" + os.fsencode(str(model))):
        assert np.array_equal(s.simulate_plant(plant=form, samples=50)[2], ref), form
    t, u, y, p = s.simulate_plant("ipa", samples=1500, seed=4)
    rec = tmp_path / "rec.csv"
    rows = ["t,u,y,p_a_pa,p_b_pa"] + [
        ",".join(repr(float(v)) for v in (a, b, c, d[0], d[1])) for a, b, c, d in zip(t, u, y, p)
    ]
    rec.write_text("\n".join(rows) + "\n")
    by_str = s.calibrate(str(rec), max_iterations=1)
    by_bytes = s.calibrate(os.fsencode(str(rec)), max_iterations=1)
    assert by_bytes["toml"] == by_str["toml"]
    with pytest.raises(TypeError, match=r"^data: "):
        s.calibrate(123)
