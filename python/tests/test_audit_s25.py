"""Audit s25: an output into a FIFO waits for its reader (and a full pipe for it to read) without
blocking Python's signals: Ctrl-C, or an exception raised by a signal handler, ends the wait. Before,
`Model.save` into a FIFO nobody read hung for good (the blocking open is restarted after each signal,
so the handler never ran). A signal handler runs in the main thread, where these tests run."""

import os
import signal
import stat
import time

import pytest

import ipa_sysid
from ipa_sysid import _core


class Alarm(Exception):
    pass


def _raise_alarm(signum, frame):
    raise Alarm("alarm")


@pytest.fixture
def alarm_in_half_a_second():
    old = signal.signal(signal.SIGALRM, _raise_alarm)
    signal.setitimer(signal.ITIMER_REAL, 0.5)
    yield
    signal.setitimer(signal.ITIMER_REAL, 0)
    signal.signal(signal.SIGALRM, old)


def test_save_into_a_fifo_nobody_opens_ends_with_the_handlers_exception(tmp_path, alarm_in_half_a_second):
    fifo = tmp_path / "pipe"
    os.mkfifo(fifo)
    t0 = time.monotonic()
    with pytest.raises(Alarm):
        ipa_sysid.paper_model().save(fifo)
    # The wait polls every 10 ms: the alarm (0.5 s) ends it well before a generous bound.
    assert time.monotonic() - t0 < 20
    assert stat.S_ISFIFO(os.lstat(fifo).st_mode), "the FIFO stays a FIFO"
    assert os.listdir(tmp_path) == ["pipe"], "no temporary file is left"


def test_a_fifo_whose_reader_does_not_read_ends_with_the_handlers_exception(tmp_path, alarm_in_half_a_second):
    fifo = tmp_path / "pipe"
    os.mkfifo(fifo)
    # A reader that opens the FIFO and never reads: 1 MB fills the pipe (64 KiB on Linux) and the
    # write waits.
    fd = os.open(fifo, os.O_RDONLY | os.O_NONBLOCK)
    try:
        with pytest.raises(Alarm):
            _core.write_output(os.fspath(fifo), b"x" * 1_000_000, "path", False)
    finally:
        os.close(fd)
    assert stat.S_ISFIFO(os.lstat(fifo).st_mode)
