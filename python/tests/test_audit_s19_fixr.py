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
    assert "MAX_ESTIMATION_BYTES" not in str(e.value)
