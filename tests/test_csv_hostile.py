"""CSVs no sensor log is, refused by name before they are read whole (issue 40: a 2 GB
sparse CSV reached 2.17 GB and said only ``MemoryError:``; 10⁶ columns 3.89 GB; a FIFO
hung ``convert``), and the layouts real CSVs have, kept by the block-by-block reader.

The memory figures themselves are ``benchmarks/bench_csv_memory.py``'s; these files are
small or sparse (a hole costs no disk), and each case is refused at once.
"""

import os
import re
import threading
import time
from decimal import Decimal

import numpy as np
import pytest

from wheelcal.cli.main import main
from wheelcal.io import InputError, convert_csv, csv_table, read_recording
from wheelcal.io.csv_convert import CsvLayout
from wheelcal.io.csv_log import plan_csv_log, read_csv_log
from wheelcal.recording.samples import InputPolicy

HEADER = "t,ax,ay,az\n"


def _rows(n: int, start: int = 0) -> str:
    return "".join(f"{i / 200:.3f},{np.sin(i / 7):.5f},0.5,9.7\n" for i in range(start, n))


def _convert(path, tmp_path, capsys) -> str:
    """``wheelcal convert path`` refused (exit 1, nothing written): its error text."""
    out = tmp_path / "out.mcap"
    assert main(["convert", str(path), str(out), "--accel-unit", "m/s^2"]) == 1
    assert not out.exists()
    return capsys.readouterr().err


def test_a_fifo_a_device_and_a_folder_are_refused_unread(tmp_path, capsys):
    fifo = tmp_path / "live.csv"
    os.mkfifo(fifo)

    def unblock():  # were the FIFO opened, this writer would end the wait (and the test fail)
        time.sleep(5)
        try:  # never blocks: without a reader waiting, there is nothing to unblock
            os.close(os.open(fifo, os.O_WRONLY | os.O_NONBLOCK))
        except OSError:
            pass

    threading.Thread(target=unblock, daemon=True).start()
    started = time.monotonic()
    # the command line refuses them before the reader is reached (usage, exit 2) …
    out = tmp_path / "out.mcap"
    for path, kind in ((fifo, "a FIFO"), ("/dev/zero", "a device"), (tmp_path, "a folder")):
        assert main(["convert", str(path), str(out), "--accel-unit", "m/s^2"]) == 2
        assert f"{path} is {kind}" in capsys.readouterr().err and not out.exists()
    assert time.monotonic() - started < 4
    # … and the reader itself, for the API
    for path, kind in ((fifo, "a FIFO (named pipe)"), ("/dev/zero", "a device")):
        with pytest.raises(InputError, match=f"is {re.escape(kind)}, not a CSV file"):
            convert_csv(str(path), out, CsvLayout(accel_unit="m/s^2"))


def test_a_sparse_file_is_refused_at_its_first_hole(tmp_path, capsys):
    holey = tmp_path / "holey.csv"
    holey.write_text(HEADER + _rows(3))
    os.truncate(holey, 256 << 20)  # 256 MiB of NUL bytes after 3 rows, no disk used
    assert "holey.csv: line 5: NUL bytes (binary data" in _convert(holey, tmp_path, capsys)
    hole = tmp_path / "hole.csv"  # nothing but a hole (the 2 GB file)
    hole.write_bytes(b"")
    os.truncate(hole, 2_000_000_000)
    assert "hole.csv: line 1: NUL bytes" in _convert(hole, tmp_path, capsys)
    with pytest.raises(InputError, match=r"hole\.csv: not an MCAP file"):
        read_recording(hole)  # the direct reader's dispatch: binary, so no CSV
    with pytest.raises(InputError, match=r"holey\.csv: line 5: NUL bytes"):
        read_recording(holey)  # a CSV up to its hole


def test_a_file_too_large_for_any_log_is_refused_by_its_size(tmp_path, capsys):
    huge = tmp_path / "huge.csv"
    huge.write_text(HEADER + _rows(3))
    os.truncate(huge, csv_table.MAX_CSV_BYTES + 1)
    assert "huge.csv: is 2 GiB, larger than any IMU CSV log" in _convert(huge, tmp_path, capsys)
    with pytest.raises(InputError, match=r"huge\.csv: is 2 GiB, larger than any IMU CSV log"):
        read_recording(huge)  # a CSV by its first bytes


def test_thousands_of_columns_and_endless_lines_are_refused(tmp_path, capsys):
    wide = tmp_path / "wide.csv"
    wide.write_text("t," + ",".join(f"c{i}" for i in range(10**6)) + "\n0,1\n")
    err = _convert(wide, tmp_path, capsys)
    assert re.search(r"wide\.csv: line 1 has more than [\d,]{6} columns in its first 128 KiB", err)
    assert "a sensor log has at most 256" in err
    wide.write_text("t," + ",".join(f"c{i}" for i in range(1000)) + "\n0,1\n")
    with pytest.raises(InputError, match=r"wide\.csv: line 1 has 1,001 columns; .* at most 256"):
        convert_csv(wide, tmp_path / "w.mcap", CsvLayout(accel_unit="m/s^2"))
    long = tmp_path / "long.csv"  # a line of 300 kB after the rows looked at first
    long.write_text(HEADER + _rows(80) + "0.4," + "9" * 300_000 + ",0,9\n" + _rows(90, 81))
    assert "long.csv: line 82: cannot be read as CSV (longer than 128 KiB)" in _convert(
        long, tmp_path, capsys
    )
    endless = tmp_path / "endless.csv"  # no line end at all
    endless.write_bytes(HEADER.encode() + b"1" * (3 << 20))
    assert "endless.csv: line 2: cannot be read as CSV" in _convert(endless, tmp_path, capsys)


def test_more_rows_than_any_session_are_refused_while_reading(tmp_path, monkeypatch):
    monkeypatch.setattr(csv_table, "MAX_ROWS", 100)
    path = tmp_path / "long.csv"
    path.write_text(HEADER + _rows(150))
    with pytest.raises(InputError, match=r"long\.csv: more than 100 data rows"):
        convert_csv(path, tmp_path / "o.mcap", CsvLayout(accel_unit="m/s^2"))


def test_text_that_is_not_utf8_is_named_with_its_line(tmp_path, capsys):
    latin = tmp_path / "latin.csv"
    latin.write_bytes(b"t,ax,ay,az,Temp (\xb0C)\n0,1,2,3,20\n")
    assert "latin.csv: line 1: not UTF-8 text" in _convert(latin, tmp_path, capsys)


def test_the_layouts_of_real_logs_survive_the_block_reader(tmp_path):
    """Comments, blank lines, CR LF, a repeated header, odd rows, quotes, empty cells."""
    rows = [
        f"{i / 200:.3f},{np.sin(i / 7):.5f},{np.cos(i / 7):.5f},{9.7 + i % 3 / 100}"
        for i in range(400)
    ]
    rows[10] = "# a comment in the middle"
    rows[11] = ""
    rows[12] = "   "
    rows[100] = "t,ax,ay,az"  # a logger restarted, writing its header again
    rows[200] = rows[200] + ",extra"  # one cell more
    rows[201] = '"1.005","0.1","0.5","9.7"'  # quoted cells
    rows[202] = "1.010,,0.5,9.7"  # an empty cell: NaN
    path = tmp_path / "log.csv"
    path.write_text("# exported by a logger\r\n" + HEADER.replace("\n", "\r\n") + "\r\n".join(rows))
    layout = CsvLayout(accel_unit="m/s^2", check_units=False)
    result = convert_csv(path, tmp_path / "log.mcap", layout)
    assert result.rows == 397 and result.skipped_rows == 1 and result.samples == 396
    assert "skipped 1 rows without a numeric time" in result.notes
    assert "1 rows have another number of cells than the first data row (read cell by cell)" in (
        result.notes
    )
    short = InputPolicy(min_duration_s=0.0, min_samples=1)
    back = read_recording(tmp_path / "log.mcap", policy=short)
    assert back.samples == 395  # the NaN row dropped by the reader, and said so
    assert any("dropped 1 NaN/inf samples" in n for n in back.notes)
    # A bad cell is named by its data row and its line (the comment lines counted).
    rows[300] = "1.5,0.1,oops,9.7"
    path.write_text("# exported by a logger\n" + HEADER + "\n".join(rows))
    with pytest.raises(
        InputError, match=r"log\.csv: data row 299: .* number: 'oops' in column 'ay' \(line 303\)"
    ):
        convert_csv(path, tmp_path / "again.mcap", layout)


def test_times_are_exact_to_the_nanosecond_from_their_text(tmp_path):
    """Unix seconds with nine decimals, an exponent, sub-ns halves rounded to even."""
    texts = [
        "1712345678.000000000",
        "1712345678.005000001",
        "1712345678.0100000005",  # half a ns: to the even 10000000 ns
        "1712345678.0150000015",  # half a ns: to the even 15000002 ns
        "1.7123456780200001E9",
        "1712345678.025",
    ]
    texts += [f"{1712345678 + 0.005 * i:.9f}" for i in range(6, 300)]
    path = tmp_path / "epoch.csv"
    path.write_text(HEADER + "\n".join(f"{t},0.1,0.2,9.8" for t in texts) + "\n")
    layout = CsvLayout(accel_unit="m/s^2", check_units=False, time_unit="s")
    log = read_csv_log(plan_csv_log(path, layout), layout)
    stamps = [int((Decimal(t) * 10**9).to_integral_value()) for t in texts]
    np.testing.assert_array_equal(log.stamps_ns, np.array(stamps, dtype=np.int64))
    assert log.stamps_ns[2] == 1712345678_010000000 and log.stamps_ns[3] == 1712345678_015000002
