"""Session 36 (audit s36 H-1): `simulate_plant` bounds its run's buffers by `max_memory_gb` before the
run (5 x 10^7 samples, an accepted size, aborted the interpreter on a failed allocation under a 1.5 GB
limit). The expectation is the budget's arithmetic: 16 numbers of 8 bytes per sample."""

import pytest

import ipa_sysid

GIB = 1 << 30
BYTES_PER_SAMPLE = 16 * 8


def test_simulate_plant_refuses_a_run_beyond_its_memory_budget():
    with pytest.raises(ValueError, match=r"samples.*at most %d samples within max_memory_gb" % (4 * GIB // BYTES_PER_SAMPLE)):
        ipa_sysid.simulate_plant("ipa", samples=50_000_000)
    # 0.001 GiB holds 8388 samples: 8388 run, 8389 are refused (the paper model: no physics, quick).
    fit = int(0.001 * GIB) // BYTES_PER_SAMPLE
    t, u, y, _ = ipa_sysid.simulate_plant("paper", samples=fit, max_memory_gb=0.001)
    assert len(y) == fit
    with pytest.raises(ValueError, match="max_memory_gb"):
        ipa_sysid.simulate_plant("paper", samples=fit + 1, max_memory_gb=0.001)
