"""Issue 28: a session lock holds for its whole life, whatever else the process opens.

POSIX record locks are released when *any* descriptor of the file is closed in
the owning process; the batch's locks must not be.
"""

import subprocess
import sys
import threading
import time

from wheelcal.batch.locking import LOCK_FILE, _offset, report_lock, session_lock

_PROBE = """
import fcntl, os, sys
fd = os.open(sys.argv[1], os.O_RDWR)
try:
    fcntl.lockf(fd, fcntl.LOCK_EX | fcntl.LOCK_NB, 1, int(sys.argv[2]))
except OSError:
    print("held")
else:
    print("free")
"""


def _seen_from_another_process(path, offset) -> str:
    out = subprocess.run(
        [sys.executable, "-c", _PROBE, str(path), str(offset)],
        capture_output=True,
        text=True,
        check=True,
    )
    return out.stdout.strip()


def test_closing_another_handle_on_the_lock_file_keeps_the_lock(tmp_path):
    lock_file = tmp_path / LOCK_FILE
    with session_lock(tmp_path, "r1"):
        assert _seen_from_another_process(lock_file, _offset("r1")) == "held"
        with open(lock_file, "rb"):  # any code of this process reading the file, then closing
            pass
        with report_lock(tmp_path):  # another lock of the same process on the same file
            pass
        assert _seen_from_another_process(lock_file, _offset("r1")) == "held"
        assert _seen_from_another_process(lock_file, 0) == "free"
    assert _seen_from_another_process(lock_file, _offset("r1")) == "free"


def test_two_threads_of_one_process_exclude_each_other(tmp_path):
    inside, overlaps = [], []

    def work():
        with session_lock(tmp_path, "same"):
            inside.append(1)
            overlaps.append(len(inside))
            time.sleep(0.05)
            inside.pop()

    threads = [threading.Thread(target=work) for _ in range(4)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    assert overlaps == [1, 1, 1, 1]
