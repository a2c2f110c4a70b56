"""Session 26 (helper fixan): audit s25's LOW findings on the Python package (L-2..L-6; L-1 is checked
by test_docs.py) and the `.mat` reader's budget from Python (`calibrate(max_memory_gb=...)`). Each
expectation is written from the finding and the documented rule, not copied from the program."""

import os
import stat
import struct
import warnings
import zlib

import numpy as np
import pytest

import ipa_sysid


@pytest.fixture(scope="module")
def records():
    _, u, y, _ = ipa_sysid.simulate_plant("ipa", seed=1)
    _, uv, yv, _ = ipa_sysid.simulate_plant("ipa", seed=2)
    return u, y, uv, yv


def _quiet(f, *args, **kwargs):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ipa_sysid.IpaSysidWarning)
        return f(*args, **kwargs)


# L-2: the repr names the record of each fit, and shows the validation fit when there is one.
def test_fit_repr_names_the_estimation_and_validation_fits(records):
    u, y, uv, yv = records
    fit = _quiet(ipa_sysid.identify, u, y, 0.01, model="arx", method="ls", validation=(uv, yv))
    text = repr(fit)
    est, val = fit.metrics["estimation"], fit.metrics["validation"]
    assert f"estimation: fit_sim_percent={est['fit_sim_percent']!r}" in text, text
    assert f"validation: fit_sim_percent={val['fit_sim_percent']!r}" in text, text
    assert f"fit_pred_percent={val['fit_pred_percent']!r})" in text, text
    alone = _quiet(ipa_sysid.identify, u, y, 0.01, model="arx", method="ls")
    assert "validation:" not in repr(alone) and "no validation record" in repr(alone), repr(alone)


# L-3: the NARX repr says the terms, the stop rule and the fits.
def test_narx_fit_repr_says_terms_stop_rule_and_fits(records):
    u, y, uv, yv = records
    n = _quiet(ipa_sysid.identify, u, y, 0.01, structure="narx", na=2, nb=2, validation=(uv, yv))
    doc = n.to_dict()
    text = repr(n)
    assert "bytes of JSON" not in text, text
    assert f"terms={len(doc['terms'])} of {doc['selection']['candidates']} candidates" in text, text
    assert f'stop="{doc["selection"]["stop"]["rule"]}"' in text, text
    assert f"estimation: fit_sim_percent={doc['metrics']['estimation']['fit_sim_percent']!r}" in text
    assert f"validation: fit_sim_percent={doc['metrics']['validation']['fit_sim_percent']!r}" in text


# L-4: natural containers.
def test_validation_takes_a_list_or_any_pair(records):
    u, y, uv, yv = records
    as_tuple = _quiet(ipa_sysid.identify, u, y, 0.01, model="arx", method="ls", validation=(uv, yv))
    for pair in ([uv, yv], [list(uv), list(yv)]):
        fit = _quiet(ipa_sysid.identify, u, y, 0.01, model="arx", method="ls", validation=pair)
        assert fit.metrics["validation"] == as_tuple.metrics["validation"]


@pytest.mark.parametrize(
    "bad, kind, words",
    [
        (lambda uv, yv: np.vstack([uv, yv]), ValueError, r"shape \(2, 2000\).*a\[0\], a\[1\]"),
        (lambda uv, yv: {"u": uv, "y": yv}, TypeError, r"got a dict"),
        (lambda uv, yv: [uv, yv, yv], ValueError, r"got a list of 3 items"),
        (lambda uv, yv: "uv", TypeError, r"got a str"),
    ],
)
def test_validation_refused_in_words(records, bad, kind, words):
    u, y, uv, yv = records
    with pytest.raises(kind, match=r"^validation: expected a pair \(u_val, y_val\).*" + words):
        ipa_sysid.identify(u, y, 0.01, model="arx", method="ls", validation=bad(uv, yv))


def test_control_profile_takes_rows_of_t_and_r(tmp_path):
    m = ipa_sysid.paper_model()
    rows = [(0.0, 10.0), (1.0, 20.0)]
    f = tmp_path / "profile.csv"
    f.write_text("t,r\n0,10\n1,20\n")
    from_file = _quiet(ipa_sysid.control, m, profile=f"file:{f}", duration=2)
    for given in (rows, np.array(rows), tuple(rows)):
        c = _quiet(ipa_sysid.control, m, profile=given, duration=2)
        # The same table as the file's: the same loop, sample for sample.
        np.testing.assert_array_equal(c["r"], from_file["r"])
        np.testing.assert_array_equal(c["y"], from_file["y"])
    # r(t) held from each row: 10 mm before t = 1 s, 20 mm from it (Ts = 0.01 s of the paper's model).
    assert c["r"][0] == 10.0 and c["r"][99] == 10.0 and c["r"][100] == 20.0


@pytest.mark.parametrize(
    "bad", [[1.0, 2.0], [(0, 1, 2)], b"fixed:50", {"t": [0], "r": [1]}, [("a", "b")]]
)
def test_control_profile_refused_names_the_string_forms(bad):
    with pytest.raises(TypeError, match=r"^profile: expected a string such as \"fixed:50\".*array of \(t, r\) rows"):
        ipa_sysid.control(ipa_sysid.paper_model(), profile=bad, duration=2)


def test_control_profile_rows_must_increase():
    with pytest.raises(ValueError, match="strictly increasing"):
        ipa_sysid.control(ipa_sysid.paper_model(), profile=[(1, 10), (0, 20)], duration=2)


def test_from_json_takes_bytes_and_names_text():
    m = ipa_sysid.paper_model()
    assert ipa_sysid.Model.from_json(m.to_json().encode()) == m
    with pytest.raises(TypeError, match=r"^text: expected the model file's text \(a str, or bytes in UTF-8\), got a int"):
        ipa_sysid.Model.from_json(3)
    with pytest.raises(ValueError, match=r"^text: the model text is not UTF-8"):
        ipa_sysid.Model.from_json(b"\xff{}")


# L-5: Python keywords in the messages.
def test_a_block_device_refusal_names_force_true(tmp_path):
    dev = next(
        (p for p in ("/dev/loop0", "/dev/sda", "/dev/vda", "/dev/nvme0n1")
         if os.path.exists(p) and stat.S_ISBLK(os.stat(p).st_mode)),
        None,
    )
    if dev is None:
        pytest.skip("no block device to look at")
    with pytest.raises(ValueError) as e:
        ipa_sysid.paper_model().save(dev, force=True)
    assert "not even with force=True" in str(e.value), e.value
    assert "--force" not in str(e.value), e.value


def test_a_symbolic_link_refusal_names_force_true(tmp_path):
    target = tmp_path / "m.json"
    ipa_sysid.paper_model().save(target)
    link = tmp_path / "link.json"
    link.symlink_to(target)
    with pytest.raises(ValueError) as e:
        ipa_sysid.paper_model().save(link)
    assert "pass force=True" in str(e.value) and "--force" not in str(e.value), e.value


def test_the_operating_point_advice_names_python_keywords():
    # An ARX plant about a level of 50: y(k) = 0.8 y(k-1) + 0.5 u(k-1) + 10 (mean 50 with u about 0).
    rng = np.random.default_rng(4)
    n = 3000
    u = rng.uniform(-1, 1, n)
    y = np.empty(n)
    y[0] = 50.0
    for k in range(1, n):
        y[k] = 0.8 * y[k - 1] + 0.5 * u[k - 1] + 10.0
    y += rng.normal(0, 0.05, n)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", ipa_sysid.IpaSysidWarning)
        fit = ipa_sysid.identify(u, y, 1.0, model="arx", method="ls", na=1, nb=1)
    hints = [w for w in fit.warnings if "non-zero operating point" in w]
    assert hints, fit.warnings
    hint = hints[0]
    assert 'offset=True or detrend="mean"' in hint, hint
    # One name for the record the figures are on.
    assert "the selection part here: the last third of the estimation record" in hint, hint
    assert "figures on" not in hint, hint
    assert any(hint == str(w.message) for w in caught)


# L-6: plain integers in the index message.
def test_index_mismatch_message_has_plain_labels():
    pd = pytest.importorskip("pandas")
    u = pd.Series(np.zeros(20))
    y = pd.Series(np.zeros(20), index=np.arange(1, 21))
    with pytest.raises(ValueError, match=r"at position 0 u's index has 0 where y's has 1\)") as e:
        ipa_sysid.identify(u, y, 0.01, model="arx", method="ls")
    assert "np.int64" not in str(e.value)
    ys = pd.Series(np.zeros(20), index=["a"] + list(range(1, 20)))
    with pytest.raises(ValueError, match=r"at position 0 u's index has 0 where y's has 'a'\)"):
        ipa_sysid.identify(u, ys, 0.01, model="arx", method="ls")


# The record budget from Python: calibrate's reader within max_memory_gb.
def _hostile_mat(path, samples=50_000_000):
    """A .mat whose compressed variable u declares 8 * samples bytes (400 MB) and holds 64 KiB."""

    def tag(ty, data):
        out = struct.pack("<II", ty, len(data)) + data
        return out + b"\0" * (-len(out) % 8)

    head = tag(6, bytes([6, 0, 0, 0, 0, 0, 0, 0])) + tag(5, struct.pack("<ii", samples, 1)) + tag(1, b"u")
    head += struct.pack("<II", 9, 8 * samples)
    declared = len(head) + 8 * samples
    zipped = zlib.compress(struct.pack("<II", 14, declared) + head + b"\0" * 65536, 9)
    header = b"MATLAB 5.0 MAT-file, fixan".ljust(116, b" ") + b"\0" * 8 + struct.pack("<H", 0x0100) + b"IM"
    path.write_bytes(header + struct.pack("<II", 15, len(zipped)) + zipped)
    return declared + 8


def test_calibrate_holds_a_mat_record_to_max_memory_gb(tmp_path):
    mat = tmp_path / "hostile.mat"
    inflated = _hostile_mat(mat)
    budget = int(0.1 * 2**30)
    assert inflated > budget
    with pytest.raises(ValueError) as e:
        ipa_sysid.calibrate(str(mat), ts=0.01, max_memory_gb=0.1)
    msg = str(e.value)
    assert "hostile.mat" in msg and "variable 'u'" in msg, msg
    assert f"to {inflated} bytes" in msg and f"budget of {budget} bytes" in msg, msg
    with pytest.raises(ValueError, match="max_memory_gb"):
        ipa_sysid.calibrate(str(mat), ts=0.01, max_memory_gb=0)
