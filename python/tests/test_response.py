"""Model.frequency_response and Model.to_control's gain convention (audit s20 M-2): expectations
computed here from the model's coefficients."""

import cmath
import json
import math
import warnings

import pytest

import ipa_sysid


def _model(tmp_path, alpha, beta, deadzone=None):
    """A model file y(k) = alpha y(k-1) + beta x(k-1), Ts = 0.05 s; Hammerstein when deadzone is given."""
    model = {
        "kind": "hammerstein" if deadzone else "arx",
        "ts": 0.05, "na": 1, "nb": 1, "nk": 1,
        "a": [-alpha], "b": [beta], "offset": None,
        "noise_model": "output-error" if deadzone else "equation-error",
    }
    if deadzone:
        model["deadzone"] = dict(zip(("b_l", "b_r", "m_l", "m_r"), deadzone))
    path = tmp_path / "m.json"
    path.write_text(json.dumps({"format": "ipa-sysid-model", "version": 2, "model": model}))
    return ipa_sysid.load_model(str(path))


# The proportional controller Kp = 4 at Ts = 0.05 s, as a controller dict (tune()'s "controller").
_P4 = {"ts_s": 0.05, "kp": 4.0, "ki": 0.0, "kd": 0.0, "derivative_filter_s": 0.0, "u_max": 255.0,
       "hold_band_mm": 0.0, "fine_band_mm": 0.0, "reset_on_crossing": False, "compensator": None}


def _assert_hand_derived_margins(r):
    """The margins of L = Kp beta z^-1 / (1 - alpha z^-1) with Kp beta = 1, alpha = 0.5: |L| = 1 at
    cos(theta) = 0.25 (phase margin 180 deg + arg L there); L(-1) = -1/1.5 (gain margin 20 log10 1.5 dB)."""
    th = math.acos(0.25)
    z = cmath.exp(-1j * th)
    pm = 180 + math.degrees(cmath.phase(z / (1 - 0.5 * z)))
    assert r["margins"]["phase_margin_deg"] == pytest.approx(pm, abs=0.01)
    assert r["margins"]["gain_margin_db"] == pytest.approx(20 * math.log10(1.5), abs=1e-6)


def test_first_order_frequency_response_impulse_and_dc_gain(tmp_path):
    alpha, beta, ts = 0.7, 0.4, 0.05
    r = _model(tmp_path, alpha, beta).frequency_response(points=9, samples=6)
    assert r["dc_gain"] == pytest.approx(beta / (1 - alpha), rel=1e-12)
    assert r["impulse"] == pytest.approx([0.0] + [beta * alpha ** (k - 1) for k in range(1, 6)], abs=1e-12)
    for f, mag, ph in zip(r["bode"]["f_hz"], r["bode"]["mag_db"], r["bode"]["phase_deg"]):
        z = cmath.exp(-1j * 2 * math.pi * f * ts)
        g = beta * z / (1 - alpha * z)
        assert mag == pytest.approx(20 * math.log10(abs(g)), abs=1e-9)
        assert ph == pytest.approx(math.degrees(cmath.phase(g)), abs=1e-7)
    assert r["bode"]["f_hz"][-1] == pytest.approx(0.5 / ts)
    assert r["margins"] is None and r["sides"] == []


def test_margins_of_a_hand_derived_loop(tmp_path):
    # L = Kp beta z^-1 / (1 - alpha z^-1), Kp beta = 1, alpha = 0.5: |L| = 1 at cos(theta) = 0.25;
    # at z = -1, L = -1/1.5: gain margin 20 log10 1.5 dB.
    r = _model(tmp_path, 0.5, 0.25).frequency_response(kp=4.0)
    _assert_hand_derived_margins(r)


def test_hammerstein_response_states_the_slopes_and_bad_settings_are_value_errors(tmp_path):
    m = _model(tmp_path, 0.9, 1.0, deadzone=(-20.0, 30.0, 0.02, 0.01))
    r = m.frequency_response()
    right, left = r["sides"]
    assert (right["side"], right["slope"], left["side"], left["slope"]) == ("right", 0.01, "left", 0.02)
    assert right["offset_db"] == pytest.approx(-40.0)
    assert right["dc_gain"] == pytest.approx(0.1) and left["dc_gain"] == pytest.approx(0.2)
    assert "b1 = 1" in r["gain"]
    with pytest.raises(ValueError, match="points"):
        m.frequency_response(points=1)
    with pytest.raises(ValueError, match="kp"):
        m.frequency_response(ki=1.0)


def test_to_control_includes_the_slope_per_side_or_warns(tmp_path):
    control = pytest.importorskip("control")
    m = _model(tmp_path, 0.9, 1.0, deadzone=(-20.0, 30.0, 0.02, 0.01))
    with pytest.warns(ipa_sysid.IpaSysidWarning, match="side="):
        g = m.to_control()
    gr = m.to_control(side="right")
    gl = m.to_control(side="left")
    # DC gains: G(1) = 10; m_r G(1) = 0.1, m_l G(1) = 0.2.
    assert control.dcgain(g) == pytest.approx(10.0)
    assert control.dcgain(gr) == pytest.approx(0.1)
    assert control.dcgain(gl) == pytest.approx(0.2)
    with pytest.raises(ValueError, match="side"):
        m.to_control(side="up")
    arx = _model(tmp_path, 0.5, 2.0)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert control.dcgain(arx.to_control()) == pytest.approx(4.0)


def test_to_control_refuses_a_bad_side_before_looking_for_python_control(tmp_path, monkeypatch):
    # sys.modules["control"] = None makes `import control` raise ImportError, as without the package.
    monkeypatch.setitem(__import__("sys").modules, "control", None)
    m = _model(tmp_path, 0.9, 1.0, deadzone=(-20.0, 30.0, 0.02, 0.01))
    with pytest.raises(ValueError, match="invalid setting side = \"up\""):
        m.to_control(side="up")
    arx = _model(tmp_path, 0.5, 2.0)
    with pytest.raises(ValueError, match="no deadzone"):
        arx.to_control(side="right")
    # A good side (or none) meets the missing package, without G's warning first.
    with pytest.raises(ImportError, match="pip install control"):
        m.to_control(side="right")
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        with pytest.raises(ImportError, match="pip install control"):
            m.to_control()


def test_margins_of_a_tuned_controller_are_tunes_and_those_of_its_gains(tmp_path):
    # Session 21: controller= takes what control(controller=...) takes; tune()'s result gives the
    # margins tune reported; without its derivative (Kd = 0) those of its Kp, Ki given as kp, ki.
    m = _model(tmp_path, 0.9, 1.0, deadzone=(-20.0, 30.0, 0.02, 0.01))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ipa_sysid.IpaSysidWarning)
        tuned = ipa_sysid.tune(model=m, variants=1, max_evaluations=10)
    r = m.frequency_response(controller=tuned)
    assert r["margins"] == tuned["margins"]
    path = tmp_path / "c.json"
    path.write_text(tuned["controller_file"])
    assert m.frequency_response(controller=str(path))["margins"] == tuned["margins"]
    # Audit s22 L-B7: the controller of the margins as numbers, as `response --json` gives it.
    c = tuned["controller"]
    gains = {"kp": c["kp"], "ki": c["ki"], "kd": c["kd"], "tf_s": c["derivative_filter_s"]}
    assert m.frequency_response(controller=str(path))["controller"] == dict(gains, file=str(path))
    assert m.frequency_response(controller=tuned)["controller"] == dict(gains, file=None)
    pi = dict(tuned["controller"], kd=0.0, derivative_filter_s=0.0)
    assert (
        m.frequency_response(controller=pi)["margins"]
        == m.frequency_response(kp=pi["kp"], ki=pi["ki"])["margins"]
    )
    with pytest.raises(ValueError, match="not together with kp"):
        m.frequency_response(controller=tuned, kp=1.0)
    with pytest.raises(ValueError, match="invalid setting controller = 0.02: a controller for the model's Ts = 0.05 s"):
        m.frequency_response(controller=dict(tuned["controller"], ts_s=0.02))


def test_margins_of_a_hand_written_controller_are_the_hand_derived_ones(tmp_path):
    # As test_margins_of_a_hand_derived_loop, the PI of Kp = 4 given as a controller dict.
    r = _model(tmp_path, 0.5, 0.25).frequency_response(controller=_P4)
    _assert_hand_derived_margins(r)


def test_a_controller_file_that_did_not_meet_its_spec_is_said(tmp_path):
    # As `control(controller=...)`: a file whose provenance says meets_spec = false gets a
    # "controller: ..." warning (in the dict and as an IpaSysidWarning); the same file without it none.
    m = _model(tmp_path, 0.5, 0.25)
    text = {"format": "ipa-sysid-controller", "version": 1, "controller": _P4}
    r = m.frequency_response(controller=json.dumps(text))
    assert not [w for w in r["warnings"] if w.startswith("controller: ")]
    text["provenance"] = {"meets_spec": False}
    with pytest.warns(ipa_sysid.IpaSysidWarning, match="does not meet the specification"):
        r = m.frequency_response(controller=json.dumps(text))
    assert [w for w in r["warnings"] if w.startswith("controller: ")]
