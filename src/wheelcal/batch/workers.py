"""Worker processes that do not outlive the batch that started them.

A batch parent killed with SIGKILL cannot tell its pool to stop, and each
worker holds a recording and its fit (hundreds of MB).  Every worker therefore
ties its life to its parent's:

* on Linux, ``prctl(PR_SET_PDEATHSIG, SIGKILL)``: the kernel kills the worker
  the moment its parent dies;
* everywhere, a daemon thread polls :func:`os.getppid` once a second and ends
  the worker when it changes (an orphan is re-parented to init or a
  subreaper).

The parent's pid is passed in rather than read in the worker, so a parent that
died before the worker got this far is noticed too.
"""

from __future__ import annotations

import os
import signal
import sys
import threading

#: From <linux/prctl.h>.
_PR_SET_PDEATHSIG = 1
#: How often the portable fallback looks at the parent, s.
POLL_S = 1.0


def exit_with_parent(parent_pid: int) -> None:
    """Process-pool initializer: end this worker when ``parent_pid`` dies."""
    if sys.platform.startswith("linux"):
        _set_parent_death_signal()
    if os.getppid() != parent_pid:  # the parent died before we were set up
        os._exit(1)
    watcher = threading.Thread(
        target=_watch_parent, args=(parent_pid,), name="wheelcal-parent-watch", daemon=True
    )
    watcher.start()


def _set_parent_death_signal() -> None:
    try:
        import ctypes

        libc = ctypes.CDLL(None, use_errno=True)
        libc.prctl(_PR_SET_PDEATHSIG, int(signal.SIGKILL), 0, 0, 0)
    except (OSError, AttributeError):  # no prctl here: the polling thread still works
        pass


def _watch_parent(parent_pid: int) -> None:
    event = threading.Event()
    while not event.wait(POLL_S):
        if os.getppid() != parent_pid:
            os._exit(1)
