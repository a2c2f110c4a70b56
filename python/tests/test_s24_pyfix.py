"""Session 24 (audit s23 L-P3, L-P5): models and fits pickle, copy and cross to worker processes;
`Model.from_json` reads `to_json()` back; fleet rows without an actuator id are one error row."""

import copy
import pickle
import warnings
from concurrent.futures import ProcessPoolExecutor

import numpy as np
import pytest

import ipa_sysid


def _record(seed=1, samples=3000):
    _, u, y, _ = ipa_sysid.simulate_plant("ipa", input="calibration", samples=samples, seed=seed)
    return u, y


def _simulate(model, u):
    """Run in a worker process: the model arrives by pickle."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return model.simulate(u, y0=0.0)


def test_model_from_json_is_the_model_bit_for_bit(tmp_path):
    m = ipa_sysid.paper_model()
    back = ipa_sysid.Model.from_json(m.to_json())
    assert back.to_json() == m.to_json()
    # The same text through a file and load_model (the other, file-based path) gives the same model.
    path = tmp_path / "m.json"
    m.save(str(path))
    loaded = ipa_sysid.load_model(str(path))
    for name in ("a", "b"):
        np.testing.assert_array_equal(getattr(back, name), getattr(loaded, name))
    u = np.linspace(-255.0, 255.0, 500)
    np.testing.assert_array_equal(back.simulate(u, y0=0.0), m.simulate(u, y0=0.0))


def test_model_from_json_refuses_text_that_is_not_a_model():
    with pytest.raises(ValueError, match="the model text"):
        ipa_sysid.Model.from_json('{"kind": "arx"')
    with pytest.raises(ValueError, match="the model text"):
        ipa_sysid.Model.from_json("[]")


def test_models_and_fits_pickle_and_copy():
    u, y = _record()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        fit = ipa_sysid.identify(u, y, 0.01, method="ls")
        narx = ipa_sysid.identify(u, y, 0.01, structure="narx", degree=2, max_terms=6)
    for m in (fit.model, ipa_sysid.paper_model()):
        for back in (pickle.loads(pickle.dumps(m)), copy.deepcopy(m), copy.copy(m)):
            assert back.to_json() == m.to_json()
            np.testing.assert_array_equal(back.a, m.a)
            np.testing.assert_array_equal(back.b, m.b)
    for back in (pickle.loads(pickle.dumps(fit)), copy.deepcopy(fit)):
        assert back.to_json() == fit.to_json()
        assert back.to_dict() == fit.to_dict()
        assert back.fit_sim_percent == fit.fit_sim_percent
        np.testing.assert_array_equal(back.poles, fit.poles)
        assert back.model.to_json() == fit.model.to_json()
    back = pickle.loads(pickle.dumps(narx))
    assert back.to_json() == narx.to_json()
    assert back.model_file() == narx.model_file()


def test_a_model_crosses_to_a_worker_process():
    u, y = _record(seed=2, samples=1500)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        m = ipa_sysid.identify(u, y, 0.01, method="ls").model
        here = m.simulate(u, y0=0.0)
    with ProcessPoolExecutor(max_workers=1) as pool:
        there = pool.submit(_simulate, m, u).result(timeout=120)
    np.testing.assert_array_equal(there, here)


def test_fleet_rows_without_an_actuator_id_are_one_error_row():
    pd = pytest.importorskip("pandas", reason="ipa_sysid.fleet needs pandas")
    from ipa_sysid import fleet

    frames = []
    for seed, aid in ((3, 7), (4, 8)):
        u, y = _record(seed=seed, samples=4000)
        frames.append(pd.DataFrame({"actuator_id": float(aid), "t": np.arange(4000) * 0.01, "u": u, "y": y}))
    whole = pd.concat(frames, ignore_index=True)
    holed = whole.copy()
    holed.loc[holed.index[:10], "actuator_id"] = np.nan
    with warnings.catch_warnings(record=True) as said:
        warnings.simplefilter("always")
        r = fleet.identify_partition(holed)
    errors = r[r["error"] != ""]
    assert len(errors) == 1  # the rows without an id (actuator 7 keeps one whole window)
    unnamed = r[r["actuator_id"].isna()]
    assert len(unnamed) == 1
    assert int(unnamed["samples"].iloc[0]) == 10
    assert "no actuator_id" in unnamed["error"].iloc[0]
    assert any("10 of 8000 rows have no actuator_id" in str(w.message) for w in said)
    # Actuator 8 is untouched: its windows equal those of the partition without the hole.
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        ref = fleet.identify_partition(whole)
    a8 = r[r["actuator_id"] == 8.0].reset_index(drop=True)
    pd.testing.assert_frame_equal(a8, ref[ref["actuator_id"] == 8.0].reset_index(drop=True))
    # All ids missing: one row, not 8000 "actuators".
    holed["actuator_id"] = np.nan
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        r = fleet.identify_partition(holed)
    assert len(r) == 1 and int(r["samples"].iloc[0]) == 8000
