"""Worker processes that do not outlive the batch that started them.

A batch parent killed with SIGKILL cannot tell its pool to stop, and each
worker holds a recording and its fit (hundreds of MB).  Every worker therefore
ties its life to the batch's — the *batch* process, whose pid it is given, not
its own parent: under the ``forkserver`` start method (Python 3.14's default
on Linux) a worker's parent is the fork server, not the batch.

* on Linux, ``prctl(PR_SET_PDEATHSIG, SIGKILL)``: the kernel kills the worker
  the moment its parent dies (the batch under ``fork``/``spawn``; the fork
  server, which exits with the batch, under ``forkserver``);
* everywhere, a daemon thread watches the batch itself: on Linux through a
  pidfd (``os.pidfd_open``, readable the moment the batch exits: no polling,
  no confusion with a later process of the same pid), elsewhere by asking
  once a second whether the batch's pid still exists.

The batch's pid is passed in rather than read in the worker, so a batch that
died before the worker got this far is noticed too.

The start method is chosen here, explicitly (:func:`worker_context`):
``forkserver`` where the platform has it, so every Python from 3.11 on runs
the batch alike (3.14 made it the default; ``fork`` is unsafe in a process
with threads), with wheelcal's calibration modules and what a session imports
on first use (:data:`SESSION_IMPORTS`) preloaded into the fork server, so a
worker starts without importing them again (≈ 0.8 s of CPU per worker and
batch otherwise).  The environment
variable ``WHEELCAL_START_METHOD`` (``fork``, ``spawn`` or ``forkserver``)
overrides it; CI runs the batch tests under each.
"""

from __future__ import annotations

import multiprocessing
import os
import select
import signal
import sys
import threading

#: From <linux/prctl.h>.
_PR_SET_PDEATHSIG = 1
#: How often the portable fallback looks at the batch, s.
POLL_S = 1.0
#: Environment variable that overrides the start method of the batch's workers.
START_METHOD_ENV = "WHEELCAL_START_METHOD"
#: What a session imports on first use: the window search's ``scipy.signal`` (≈ 0.6 s,
#: with the parts of scipy it pulls in) and the MCAP chunks' ``zstandard``.
SESSION_IMPORTS = ("scipy.signal", "zstandard")
#: Modules the fork server imports once, so that workers forked from it start warm.
_PRELOAD = ["wheelcal.batch.runner", *SESSION_IMPORTS]


def start_method() -> str:
    """The start method of the batch's worker processes (see the module docstring).

    Raises
    ------
    ValueError
        ``WHEELCAL_START_METHOD`` names a method this platform does not have.
    """
    available = multiprocessing.get_all_start_methods()
    wanted = os.environ.get(START_METHOD_ENV, "").strip()
    if wanted:
        if wanted not in available:
            raise ValueError(
                f"{START_METHOD_ENV}={wanted!r} is not a start method of this platform "
                f"(one of {', '.join(available)})"
            )
        return wanted
    return "forkserver" if "forkserver" in available else "spawn"


def worker_context() -> multiprocessing.context.BaseContext:
    """The multiprocessing context the batch's process pools use (explicit start method)."""
    method = start_method()
    context = multiprocessing.get_context(method)
    if method == "forkserver":
        context.set_forkserver_preload(_PRELOAD)
    return context


def start_fork_server() -> None:
    """Start the fork server now, if the workers will come from one (else nothing).

    It imports its preloads (≈ 2 s of CPU) while the batch goes on planning: the
    pool's first workers then fork from a server that is ready, or nearly.
    """
    if start_method() == "forkserver":
        from multiprocessing import forkserver

        worker_context()  # its preloads, set before the server starts
        forkserver.ensure_running()


def exit_with_parent(batch_pid: int) -> None:
    """Process-pool initializer: end this worker when the batch ``batch_pid`` ends."""
    if sys.platform.startswith("linux"):
        _set_parent_death_signal()
    pidfd = _open_pidfd(batch_pid)
    if pidfd is None and not _alive(batch_pid):  # the batch died before we were set up
        os._exit(1)
    watcher = threading.Thread(
        target=_watch_pidfd if pidfd is not None else _poll_batch,
        args=(pidfd if pidfd is not None else batch_pid,),
        name="wheelcal-batch-watch",
        daemon=True,
    )
    watcher.start()


def _set_parent_death_signal() -> None:
    try:
        import ctypes

        libc = ctypes.CDLL(None, use_errno=True)
        libc.prctl(_PR_SET_PDEATHSIG, int(signal.SIGKILL), 0, 0, 0)
    except (OSError, AttributeError):  # no prctl here: the watching thread still works
        pass


def _open_pidfd(pid: int) -> int | None:
    """A pidfd of ``pid`` (Linux ≥ 5.3), or None: not available, or the process is gone."""
    opener = getattr(os, "pidfd_open", None)
    if opener is None:
        return None
    try:
        return opener(pid)
    except ProcessLookupError:
        os._exit(1)  # the batch is already gone
    except OSError:  # an older kernel, or not permitted: fall back to polling
        return None


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:  # it exists, under another user
        return True
    return True


def _watch_pidfd(pidfd: int) -> None:
    select.select([pidfd], [], [])  # readable once the process has exited
    os._exit(1)


def _poll_batch(batch_pid: int) -> None:
    event = threading.Event()
    while not event.wait(POLL_S):
        if not _alive(batch_pid):
            os._exit(1)
