"""A batch stopped by a signal, or by a full disk: no half-written file, and a word why.

``SIGTERM`` (a scheduler's stop, ``kill``) and ``SIGHUP`` (a closed terminal)
raise :class:`Terminated` in the batch's main thread
(:func:`terminate_on_signals`), as ``Ctrl-C`` raises ``KeyboardInterrupt``: the
atomic writers remove their temporary files on the way out, the pool's workers
are sent ``SIGTERM`` too (each removes its own, :func:`worker_signals`), and the
command says what was finished.  A ``SIGKILL`` leaves no chance to clean up:
the next batch on the folder removes what it left (:mod:`wheelcal.batch.runner`).

A disk that fills up (``ENOSPC``, a quota, a file-size limit) fails every
session after it; :func:`wheelcal.io.disk_full` tells such a failure from a bad session,
so the batch stops at the first (:class:`BatchStopped`).
"""

from __future__ import annotations

import contextlib
import os
import signal
import threading
from collections.abc import Iterator

#: The signals that stop a batch cleanly.
SIGNALS = tuple(getattr(signal, name) for name in ("SIGTERM", "SIGHUP") if hasattr(signal, name))

_in_worker = False


class Terminated(BaseException):
    """The batch got a stopping signal (a BaseException, like KeyboardInterrupt)."""

    def __init__(self, signum: int) -> None:
        super().__init__(signum)
        self.signum = signum
        self.done = 0
        self.total = 0

    @property
    def name(self) -> str:
        """``SIGTERM``, ``SIGHUP``."""
        return signal.Signals(self.signum).name


class BatchStopped(RuntimeError):
    """The batch stopped before its end (a full disk); the message says what was kept."""


def _raise(signum, frame) -> None:
    raise Terminated(signum)


@contextlib.contextmanager
def terminate_on_signals() -> Iterator[None]:
    """Within the block, :data:`SIGNALS` raise :class:`Terminated` (main thread only)."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    previous = {s: signal.signal(s, _raise) for s in SIGNALS}
    try:
        yield
    finally:
        for s, handler in previous.items():
            signal.signal(s, handler)


def worker_signals() -> None:
    """In a pool worker: :data:`SIGNALS` raise :class:`Terminated` (see :func:`in_worker`)."""
    global _in_worker
    _in_worker = True
    for s in SIGNALS:
        signal.signal(s, _raise)


def in_worker() -> bool:
    """Whether this process is a batch's pool worker (set by :func:`worker_signals`)."""
    return _in_worker


def exit_worker(exc: Terminated) -> None:
    """End a worker that was told to stop (its writers have removed their temporaries)."""
    os._exit(128 + exc.signum)
