"""Audit s20, the Python side of findings H-1 and M-3: `identify` refuses a record whose input
determines no input term whatever the windup protection (a constant input fits a whole line of
(a1 + a2, b1)), and `load_model` repeats the warnings of the identification that wrote the file."""

import json
import subprocess
import warnings

import numpy as np
import pytest

import ipa_sysid
from binary import cli_path


def run(*args):
    return subprocess.run([cli_path(), *map(str, args)], capture_output=True, text=True)


@pytest.mark.parametrize("level", [0.0, 5.0])
@pytest.mark.parametrize("windup", ["none", "trace", "directional"])
def test_a_constant_input_is_not_persistently_exciting_whatever_the_windup(level, windup):
    # The audit's q2 (u = 0) and q5 (u = 5) records: 20 000 samples, y = 1 throughout.
    u = np.full(20_000, level)
    y = np.ones(20_000)
    with pytest.raises(ValueError, match="not persistently exciting"):
        ipa_sysid.identify(u, y, 0.01, model="arx", na=2, nb=1, method="rls", windup=windup)
