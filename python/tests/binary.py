"""The command-line binary the tests run beside the package: IPA_SYSID_BIN, else the workspace's
target/debug or target/release build (a test without one is skipped, visibly)."""

import os
import pathlib

import pytest

REPO = pathlib.Path(__file__).resolve().parents[2]


def cli_path():
    env = os.environ.get("IPA_SYSID_BIN")
    if env:
        if not pathlib.Path(env).is_file():
            pytest.fail(f"IPA_SYSID_BIN={env} is not a file")
        return env
    for profile in ("debug", "release"):
        p = REPO / "target" / profile / "ipa-sysid"
        if p.is_file():
            return str(p)
    pytest.skip("no ipa-sysid binary: build it (cargo build -p ipa-sysid) or set IPA_SYSID_BIN")
