"""Session 22 (brief fixab): a model file's warnings are said once per load, a result's own once per
call; one floor (1e-6 s) for every sampling period, Python's ts= included."""
import json
import warnings

import numpy as np
import pytest

import ipa_sysid


def _model_file(tmp_path, a, told):
    # A version-3 model file whose identification warned `told` (what load_model repeats).
    model = {"kind": "arx", "ts": 0.1, "na": len(a), "nb": 1, "nk": 1, "a": a, "b": [1.0],
             "offset": None, "noise_model": "equation-error",
             "identification": {"record": "rec.csv", "fit_estimation_percent": 90.0,
                                "warnings": [told]}}
    path = tmp_path / "m.json"
    path.write_text(json.dumps({"format": "ipa-sysid-model", "version": 3, "model": model}))
    return path


def _caught(call):
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        result = call()
    return result, [str(w.message) for w in caught if issubclass(w.category, ipa_sysid.IpaSysidWarning)]


def test_a_model_files_warning_is_said_once_per_load_and_not_by_each_method(tmp_path):
    told = "a told-once marker"
    path = _model_file(tmp_path, [-0.5], told)
    m, said = _caught(lambda: ipa_sysid.load_model(str(path)))
    assert sum(told in w for w in said) == 1, said
    u = np.sin(np.arange(200) * 0.3)
    y = m.simulate(u, 0.0)
    for call in (lambda: m.frequency_response(), lambda: m.metrics(u, y), lambda: m.simulate(u, 0.0),
                 lambda: m.predict(u, y)):
        result, said = _caught(call)
        assert not any(told in w for w in said), said
    # The results still list it, as validate's and response's JSON do.
    r, _ = _caught(lambda: m.frequency_response())
    assert sum(told in w for w in r["warnings"]) == 1, r["warnings"]
    d, _ = _caught(lambda: m.metrics(u, y))
    assert sum(told in w for w in d["warnings"]) == 1, d["warnings"]
    # A second load says it again: once per load.
    _, said = _caught(lambda: ipa_sysid.load_model(str(path)))
    assert sum(told in w for w in said) == 1, said


def test_a_results_own_warning_is_said_once_per_call(tmp_path):
    # y(k) = 1.5 y(k-1) + u(k-1): a pole at 1.5, outside the unit circle.
    m, _ = _caught(lambda: ipa_sysid.load_model(str(_model_file(tmp_path, [-1.5], "marker"))))
    for _ in range(2):
        r, said = _caught(lambda: m.frequency_response())
        assert sum(w.startswith("unstable model") for w in said) == 1, said
        assert sum(w.startswith("unstable model") for w in r["warnings"]) == 1, r["warnings"]


FLOOR_S = 1e-6  # the shortest Ts of a model file and of the controller (docs/data.md), written here


def test_ts_below_the_floor_is_refused_by_name_and_the_floor_is_accepted():
    u = np.where((np.arange(200) // 10) % 2 == 0, 1.0, -1.0)
    y = np.zeros(200)
    for k in range(1, 200):
        y[k] = 0.5 * y[k - 1] + u[k - 1]
    with pytest.raises(ValueError, match=r"invalid setting ts = .*at least 1e-6 s"):
        ipa_sysid.identify(u, y, FLOOR_S / 2, model="arx", na=1, nb=1)
    with pytest.raises(ValueError, match=r"ts = .*1e-6"):
        ipa_sysid.simulate_plant("ipa", samples=50, ts=FLOOR_S / 2)
    fit = ipa_sysid.identify(u, y, FLOOR_S, model="arx", na=1, nb=1)
    assert fit.model.ts == FLOOR_S
