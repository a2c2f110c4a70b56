"""Session 34 (helper fix34), the Python side of audit s33 L-5, L-3 and L-6.

L-5: `identify` and `Model.metrics` say when the identified deadzone is no valve deadzone around
u = 0 (b_l <= 0 <= b_r, both slopes > 0), which `control(compensate_deadzone=...)`, `tune` and the C API
refuse.
L-3: `control(plant="paper", plant_config=...)` answered with the command line's flags
(`--plant-config x applies to --plant ipa only`), and the setpoint/profile error showed an empty value.
L-6: `Rls`'s failure messages quoted `--rls-form` / `--p0`, which `Rls` does not have; under
forgetting rho < 1 the cause is covariance windup and the remedies are `Rls`'s own.
"""

import math
import warnings

import numpy as np
import pytest

import ipa_sysid

NOT_A_VALVE = "the deadzone is not a valve deadzone around u = 0"


def deadzone_record(b_l, b_r, n=2000):
    """A Hammerstein record by a plain loop: a staircase of 20 levels in +-200 counts (25 samples
    each), the deadzone (b_l, b_r, slopes 0.01) and y(k) = 0.8 y(k-1) + x(k-1), from rest."""
    levels = [-200, -150, -100, -80, -40, -20, 0, 20, 40, 80, 120, 160, 200, -120, 60, -60, 100,
              -180, 30, -30]
    u = np.array([levels[(k // 25) % len(levels)] for k in range(n)], dtype=float)
    x = np.where(u >= b_r, 0.01 * (u - b_r), np.where(u <= b_l, 0.01 * (u - b_l), 0.0))
    y = np.zeros(n)
    for k in range(1, n):
        y[k] = 0.8 * y[k - 1] + x[k - 1]
    return u, y


def test_identify_and_metrics_say_a_deadzone_left_of_zero():
    # The plant's deadzone lies wholly left of u = 0 (a zero command drives it): the estimate is the
    # plant's (noise-free record, true structure), and both the fit and Model.metrics say it once.
    u, y = deadzone_record(-55.0, -12.5)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        fit = ipa_sysid.identify(u, y, 0.01, model="hammerstein", na=1, nb=1, nk=1)
        m = fit.model.metrics(u, y)
    said = [w for w in fit.warnings if w.startswith(NOT_A_VALVE)]
    assert len(said) == 1, fit.warnings
    assert "b_r = -12.5" in said[0] and "compensator will refuse it" in said[0], said[0]
    assert sum(w.startswith(NOT_A_VALVE) for w in m["warnings"]) == 1, m["warnings"]
    # The compensator refuses the same model, as the warning announces.
    with pytest.raises(ValueError, match="b_l <= 0 <= b_r"):
        ipa_sysid.control("ipa", setpoint=50, duration=1, compensate_deadzone=fit.model)
    # A valve deadzone: no such warning.
    u, y = deadzone_record(-22.5, 27.5)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        fit = ipa_sysid.identify(u, y, 0.01, model="hammerstein", na=1, nb=1, nk=1)
        m = fit.model.metrics(u, y)
    assert not any(w.startswith(NOT_A_VALVE) for w in fit.warnings + m["warnings"])


def test_plant_config_errors_name_the_python_argument():
    for plant in ["paper", ipa_sysid.paper_model()]:
        with pytest.raises(ValueError) as e:
            ipa_sysid.control(plant, setpoint=50, duration=1, plant_config="x.toml")
        text = str(e.value)
        assert "plant_config = x.toml" in text, text
        assert "--" not in text, text


def test_the_setpoint_profile_error_shows_what_was_given():
    with pytest.raises(ValueError) as e:
        ipa_sysid.control("paper", setpoint=50, profile="fixed:10", duration=1)
    text = str(e.value)
    assert "setpoint/profile = 50 and 'fixed:10'" in text and "--" not in text, text
    with pytest.raises(ValueError) as e:
        ipa_sysid.control("paper", duration=1)
    text = str(e.value)
    assert "setpoint/profile = (neither given)" in text, text


def test_rls_windup_under_forgetting_is_named_with_rls_remedies():
    # phi = (1, 0, 0) for ever: P's unexcited diagonal entries grow by 1/rho per update from p0 and
    # overflow f64 (1.797e308) after k* = ln(f64max / p0) / ln(1 / rho) updates (34 449.5 for
    # rho = 0.98, p0 = 1e6): the update there is refused.
    rho, p0 = 0.98, 1e6
    k_star = math.log(np.finfo(float).max / p0) / math.log(1 / rho)
    r = ipa_sysid.Rls(3, forgetting=rho, p0=p0)
    phi = np.tile([1.0, 0.0, 0.0], (40_000, 1))
    with pytest.raises(ArithmeticError) as e:
        r.update_many(phi, np.zeros(40_000))
    assert abs(r.samples - k_star) <= 2, (r.samples, k_star)
    text = str(e.value)
    assert f"at sample {r.samples}" in text, text
    for words in ["covariance windup", "restart_covariance(p0)", "forgetting=1", "p0"]:
        assert words in text, (words, text)
    assert "--" not in text, text
    # Every later update is refused until the covariance restarts, as the message says; then an
    # exciting sample is taken.
    with pytest.raises(ArithmeticError):
        r.update([0.0, 1.0, 0.0], 1.0)
    r.restart_covariance(p0)
    r.update([0.0, 1.0, 0.0], 1.0)


def test_rls_failure_without_forgetting_names_p0_not_flags():
    # phi = 1e160: phi' P phi = 1e6 * 1e320 overflows at the first update (rho = 1: not windup).
    r = ipa_sysid.Rls(1)
    with pytest.raises(ArithmeticError) as e:
        r.update([1e160], 0.0)
    text = str(e.value)
    assert "p0" in text and "windup" not in text, text
    assert "--rls-form" not in text and "--p0" not in text and "--" not in text, text
