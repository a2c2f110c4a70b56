"""Session 33 (brief scorefrom): Model.metrics(..., score_from=K) scores the samples k >= max(K, k0)
only, as `validate --score-from K`; the expectations are hand computations with numpy over the model's
own simulation (from the measured initial outputs) and one-step prediction, never the figures under
test."""
import json
import warnings

import numpy as np
import pytest

import ipa_sysid

K = 40


def _model(tmp_path):
    # y(k) = 1.5 y(k-1) - 0.7 y(k-2) + u(k-1) + 0.5 u(k-2): A = 1 - 1.5 q^-1 + 0.7 q^-2, k0 = 2, p = 4.
    path = tmp_path / "m.json"
    path.write_text(json.dumps({"format": "ipa-sysid-model", "version": 2, "model": {
        "kind": "arx", "ts": 0.1, "na": 2, "nb": 2, "nk": 1, "a": [-1.5, 0.7], "b": [1.0, 0.5],
        "offset": None}}))
    return ipa_sysid.load_model(str(path))


def _record(n=600):
    # The model's own system with a small output error, started far from rest (y = 12): the first
    # samples are an initial-state transient.
    rng = np.random.default_rng(5)
    u = np.repeat(rng.uniform(-3, 3, n // 4), 4)
    y = np.full(n, 12.0)
    for k in range(2, n):
        y[k] = 1.5 * y[k - 1] - 0.7 * y[k - 2] + u[k - 1] + 0.5 * u[k - 2] + rng.uniform(-0.3, 0.3)
    return u, y


def _rmse_fit(y, yhat, start):
    e = y[start:] - yhat[start:]
    dev = y[start:] - y[start:].mean()
    return np.sqrt(np.mean(e * e)), 100.0 * (1.0 - np.linalg.norm(e) / np.linalg.norm(dev))


def test_metrics_score_from_k_are_the_figures_of_the_samples_from_k(tmp_path):
    m = _model(tmp_path)
    u, y = _record()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        d = m.metrics(u, y, score_from=K)
        d0 = m.metrics(u, y)
        sim = m.simulate(u, y)  # from the measured initial outputs y(0), y(1)
        pred = m.predict(u, y)
    assert d["score_from"] == K and d["n"] == len(y) - K
    assert d0["score_from"] == 2 and d0["n"] == len(y) - 2
    for got, start in ((d, K), (d0, 2)):
        rmse, fit = _rmse_fit(y, sim, start)
        assert got["rmse_sim_measured"] == pytest.approx(rmse, rel=1e-9)
        assert got["fit_sim_measured_percent"] == pytest.approx(fit, rel=1e-9)
        rmse, fit = _rmse_fit(y, pred, start)
        assert got["rmse_pred"] == pytest.approx(rmse, rel=1e-9)
        assert got["fit_pred_percent"] == pytest.approx(fit, rel=1e-9)
        assert got["loss_fcn"] == pytest.approx(rmse * rmse, rel=1e-9)
    assert d["rmse_sim_measured"] != d0["rmse_sim_measured"]


def test_metrics_score_from_past_the_record_is_refused(tmp_path):
    m = _model(tmp_path)
    u, y = _record()
    # 600 samples: K = 600 is past the end; K = 596 leaves 4 samples, not more than p = 4.
    for k in (600, 596):
        with pytest.raises(ValueError, match=r"score_from = %d.*600 samples" % k):
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                m.metrics(u, y, score_from=k)
    for bad in (-1, True):
        with pytest.raises((ValueError, TypeError), match="score_from"):
            m.metrics(u, y, score_from=bad)
