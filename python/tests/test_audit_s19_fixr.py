"""Audit s19 H-3: an identification whose N × p matrices would exceed the memory budget of
docs/reliability.md ("Resource bounds", 4 GiB) raises a ValueError before anything is allocated,
instead of killing the interpreter on a failed allocation."""

import numpy as np
import pytest

import ipa_sysid

BUDGET = 4 * 1024**3


def test_identify_over_the_memory_budget_raises_before_allocating():
    # Output error on ARX(100, 100, 1): p = 200, N = n - 100 rows, 5p + 4 numbers of 8 bytes per row
    # (docs/reliability.md): 560 000 samples need 4.5 GB, over the budget.
    n = 560_000
    rows = n - 100
    need = rows * (5 * 200 + 4) * 8
    assert need > BUDGET
    u = np.zeros(n)
    y = np.zeros(n)
    with pytest.raises(ValueError) as e:
        ipa_sysid.identify(u, y, 0.01, model="arx", method="oe", na=100, nb=100, nk=1)
    msg = str(e.value)
    assert f"{rows} regression rows of 200 parameters" in msg
    assert f"about {need / 1e9:.1f} GB" in msg
    assert "slice of the arrays" in msg


def test_the_same_arrays_by_least_squares_fit_the_budget_and_meet_the_data_check():
    # Least squares holds 2p + 4 numbers per row: 1.8 GB, under the budget; the zero input is then
    # refused for what it is (no excitation), not for its size.
    n = 560_000
    assert (n - 100) * (2 * 200 + 4) * 8 < BUDGET
    with pytest.raises(ValueError) as e:
        ipa_sysid.identify(np.zeros(n), np.zeros(n), 0.01, model="arx", method="ls", na=100, nb=100, nk=1)
    assert "max_memory" not in str(e.value)


def test_max_memory_gb_refuses_and_accepts_as_the_command_line_max_memory():
    # Session 20 (fixv): ARX(2, 2, 1) by least squares on 10 000 samples holds 2p + 4 = 12 numbers of
    # 8 bytes for each of N = 10 000 - 2 rows (k0 = max(na, nk + nb - 1) = 2): 959 808 bytes,
    # 0.00096 GB, over max_memory_gb=0.0001 (107 374 bytes), under 0.001 GiB.
    n = 10_000
    rng = np.random.default_rng(20)
    u = rng.uniform(-1.0, 1.0, n)
    y = np.zeros(n)
    for k in range(2, n):
        y[k] = 1.2 * y[k - 1] - 0.5 * y[k - 2] + u[k - 1] + 0.5 * u[k - 2]
    rows = n - 2
    need = rows * 12 * 8
    assert 0.0001 * 1024**3 < need < 0.001 * 1024**3
    kw = dict(model="arx", method="ls", na=2, nb=2, nk=1)
    with pytest.raises(ValueError) as e:
        ipa_sysid.identify(u, y, 0.01, max_memory_gb=0.0001, **kw)
    msg = str(e.value)
    assert f"{rows} regression rows of 4 parameters" in msg
    assert "about 0.00096 GB" in msg
    assert "max_memory_gb" in msg
    # The command line's --stream hint is not offered where there is no stream.
    assert "--stream" not in msg
    fit = ipa_sysid.identify(u, y, 0.01, max_memory_gb=0.001, **kw)
    assert abs(fit.params["a1"] + 1.2) < 1e-6
    # The NARX search takes the same budget.
    with pytest.raises(ValueError) as e:
        ipa_sysid.identify(u, y, 0.01, structure="narx", max_memory_gb=0.0001)
    assert "max_memory_gb" in str(e.value)


@pytest.mark.parametrize("bad", [0.0, -1.0, float("nan"), float("inf"), 2000.0])
def test_max_memory_gb_that_is_no_size_is_refused_naming_the_keyword(bad):
    with pytest.raises(ValueError) as e:
        ipa_sysid.identify(np.zeros(100), np.zeros(100), 0.01, max_memory_gb=bad)
    assert "max_memory_gb" in str(e.value) and "GiB" in str(e.value)
