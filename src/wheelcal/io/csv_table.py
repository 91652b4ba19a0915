r"""A delimited text table (a CSV log) read in bounded memory: the header, then typed columns.

A log is read as blocks of whole lines (:data:`BLOCK_BYTES`), never whole: each
block has its comment and blank lines cut out (numpy over the block's bytes),
is parsed by Arrow's CSV reader (``pyarrow.csv``, C++), and only the columns
asked for are kept, as numbers, in growing arrays
(:class:`~wheelcal.io.growing.GrowingColumns`).  So reading holds the result
(8 B per number, 16 B per time) plus one block, whatever the file's size.

Before anything is read whole, what no sensor log is is refused by name: not
a regular file (a FIFO would wait for a writer, ``/dev/zero`` never ends),
larger than :data:`MAX_CSV_BYTES`, a line longer than :data:`MAX_LINE_BYTES`
(a field of 128 KiB, a sparse file's hole), NUL bytes (binary data), more than
:data:`MAX_COLUMNS` columns, more than :data:`MAX_ROWS` rows.

The layout is read as exporters write it: a UTF-8 byte-order mark; ``#``
comment lines and blank lines anywhere; an Excel ``sep=,`` first line (it
sets the delimiter); the Movella (Xsens) DOT app's preamble (``DeviceTag:,…``
lines before the ``PacketCounter,…`` header), kept as key/value pairs; the
delimiter otherwise the one of ``,`` ``;`` tab the header uses most; a
trailing empty column; decimal commas (``9,81``) where the delimiter is not a
comma (seen in the first data rows).  A row whose number of cells differs
from the first data row's is read cell by cell (its cells by position, as the
header names them).

Times are kept exactly as their decimal text says, as an integer part and
the fraction in units of 10⁻¹² (``pico``): ``1700000000.123456789`` is
``(1700000000, 123456789000)``, with no float rounding, whatever the unit
turns out to be.  A row whose time is not a number is skipped (and counted);
an empty or ``NaN`` cell in another column is NaN; any other text is an error
naming the file, the line and the column.
"""

from __future__ import annotations

import csv
import os
import re
import stat
from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np

from wheelcal.io.errors import InputError
from wheelcal.io.file_kind import special_kind
from wheelcal.io.growing import GrowingColumns

#: No IMU log a calibration needs is larger: 10⁷ rows of 200 B, 23 hours at 120 Hz.
MAX_CSV_BYTES = 2 << 30
#: No line of a sensor log is longer (256 columns of 30 characters are 8 KiB).
MAX_LINE_BYTES = 128 << 10
#: Loggers write a few dozen columns (the widest Xsens DOT export has 24).
MAX_COLUMNS = 256
#: 10 million samples: 23 h at 120 Hz, 2.8 h at 1 kHz (a calibration needs minutes).
MAX_ROWS = 10_000_000
#: Bytes of whole lines parsed at a time (its transients are a few times this).
BLOCK_BYTES = 1 << 20
#: Data rows looked at before reading (decimal commas, the number of cells).
_SAMPLE_ROWS = 50
#: Lines before the header that may be an exporter's preamble.
_PREAMBLE_LINES = 32
#: Cells Arrow reads as missing in a number column (NaN), as the current CSV rules do.
_NULLS = ("", "NaN", "nan", "NAN", "-NaN", "-nan", "NA", "N/A", "n/a", "NULL", "null")

_EXCEL_SEP = re.compile(r'^\s*"?sep=(.)"?\s*$', re.IGNORECASE)
_DECIMAL_COMMA = re.compile(r"^\s*[+-]?\d*,\d+(?:[eE][+-]?\d+)?\s*$")
#: A key-value preamble line: ``DeviceTag:,my dot,,,`` (Movella DOT app).
_PREAMBLE = re.compile(r"^[A-Za-z][\w .\-]*:\s*[,;\t]")
#: A time cell Arrow's decimal parser takes (sign, digits, point, exponent).
_TIME_NUMBER = r"^[+-]?(?:\d+\.?\d*|\.\d+)(?:[eE][+-]?\d{1,3})?$"
_PICO = 10**12
_WHITE = np.zeros(256, bool)
_WHITE[[9, 10, 13, 32]] = True


@dataclass(frozen=True)
class TableHead:
    """What precedes the data: delimiter, header, preamble, and where the data start."""

    path: str
    delimiter: str
    #: The header's cells (trailing empty cells removed); ``()`` for a file without one.
    header: tuple[str, ...]
    #: The number of cells of the first data row (the width rows are parsed at).
    cells: int
    decimal_comma: bool
    #: ``key: value`` lines before the header (the Movella DOT app writes them).
    preamble: tuple[tuple[str, str], ...]
    #: The file's line number (1-based) of the first line after the header, and its offset.
    first_line: int
    data_offset: int
    notes: tuple[str, ...]


@dataclass(frozen=True, eq=False)
class TableColumns:
    """The rows with a numeric time: the time exactly, the other columns as float64."""

    #: Data rows in the file (comment and blank lines not counted).
    rows: int
    #: Rows skipped because their time is not a number.
    skipped: int
    #: The time: integer part (int64), and the fraction in 10⁻¹² of the unit (int64, ≥ 0).
    time_whole: np.ndarray
    time_pico: np.ndarray
    #: Per group asked for: (N,) for one column, (N, k) for several.
    groups: Mapping[str, np.ndarray]
    #: Rows whose number of cells differs from the first data row's (read cell by cell).
    odd_rows: int


def check_csv_file(path: str) -> int:
    """The size of a readable regular file; a FIFO, device, folder, empty or huge file refused."""
    try:
        info = os.stat(path)
    except FileNotFoundError:
        raise InputError(path, "no such file") from None
    except OSError as exc:
        raise InputError(path, f"cannot be read ({exc.strerror})") from None
    kind = special_kind(info.st_mode)
    if kind is not None:
        raise InputError(path, f"is {kind}, not a CSV file; wheelcal reads regular files")
    if info.st_size == 0:
        raise InputError(path, "the file is empty (0 bytes)")
    if info.st_size > MAX_CSV_BYTES:
        raise InputError(
            path,
            f"is {info.st_size / 2**30:.3g} GiB, larger than any IMU CSV log a calibration "
            f"needs (at most {MAX_CSV_BYTES >> 30} GiB: about 10 million rows); cut the "
            "session out of it first",
        )
    if not stat.S_ISREG(info.st_mode):  # pragma: no cover - special_kind covers the rest
        raise InputError(path, "is not a regular file")
    return info.st_size


class _Lines:
    """The file's first lines, one by one, each bounded by :data:`MAX_LINE_BYTES`."""

    def __init__(self, path: str, stream) -> None:
        self.path = path
        self.stream = stream
        self.number = 0  # of the last line returned
        self.start = 0  # its byte offset

    def next(self, delimiter: str | None = None) -> str | None:
        self.start = self.stream.tell()
        raw = self.stream.readline(MAX_LINE_BYTES + 1)
        if not raw:
            return None
        self.number += 1
        if b"\x00" in raw:
            raise InputError(self.path, _binary(self.number))
        if len(raw) > MAX_LINE_BYTES and not raw.endswith(b"\n"):
            raise InputError(self.path, self._too_long(raw, delimiter))
        if self.number == 1 and raw.startswith(b"\xef\xbb\xbf"):
            raw = raw[3:]
        try:
            return raw.decode("utf-8").rstrip("\r\n")
        except UnicodeDecodeError as exc:
            raise InputError(
                self.path, f"line {self.number}: not UTF-8 text ({exc.reason}); a CSV log is text"
            ) from None

    def _too_long(self, raw: bytes, delimiter: str | None) -> str:
        counts = {d: raw.count(d.encode()) for d in (delimiter,) if d} or {
            d: raw.count(d.encode()) for d in (",", ";", "\t")
        }
        if max(counts.values()) >= MAX_COLUMNS:
            return (
                f"line {self.number} has more than {max(counts.values()):,} columns in its first "
                f"{MAX_LINE_BYTES >> 10} KiB; a sensor log has at most {MAX_COLUMNS} (a foreign "
                "or damaged file?)"
            )
        return _long_line(self.number)


def _long_line(number: int) -> str:
    return (
        f"line {number}: cannot be read as CSV (longer than {MAX_LINE_BYTES >> 10} KiB); no "
        "line of a sensor log is that long (a damaged or foreign file?)"
    )


def _binary(number: int) -> str:
    return f"line {number}: NUL bytes (binary data, or a file's unwritten hole), not CSV text"


def _cells(line: str, delimiter: str) -> list[str]:
    return next(csv.reader([line], delimiter=delimiter), [])


def open_table(path: str | os.PathLike, delimiter: str | None, has_header: bool) -> TableHead:
    """Check the file and read what precedes its data (see the module docstring).

    Raises
    ------
    InputError
        Naming the file: not a regular file, empty, too large, a line too long,
        binary, not UTF-8, too many columns, no data rows.
    """
    path = str(path)
    check_csv_file(path)
    notes: list[str] = []
    preamble: list[tuple[str, str]] = []
    with open(path, "rb") as stream:
        lines = _Lines(path, stream)
        line = _content_line(lines, delimiter)
        if line is not None:
            excel = _EXCEL_SEP.match(line)
            if excel:
                delimiter = delimiter or excel.group(1)
                notes.append(f"skipped the Excel 'sep={excel.group(1)}' line")
                line = _content_line(lines, delimiter)
        if line is not None and has_header and _PREAMBLE.match(line):
            line = _skip_preamble(lines, line, delimiter, preamble, notes)
        if line is None:
            raise InputError(path, "the CSV file has no data")
        delimiter = delimiter or max((",", ";", "\t"), key=line.count)
        header: list[str] = []
        if has_header:
            header = _cells(line, delimiter)
            if len(header) > MAX_COLUMNS:
                raise InputError(path, _too_many(len(header), lines.number))
            width = len(header)
            while header and not header[-1].strip():
                header.pop()
            if len(header) < width:
                notes.append(
                    "ignored the empty trailing column (each line ends with the delimiter)"
                )
            first_line, offset = lines.number + 1, stream.tell()
            line = _content_line(lines, delimiter)
            if line is None:
                raise InputError(path, "the CSV file has a header but no data rows")
        else:
            first_line, offset = lines.number, lines.start
        first = _cells(line, delimiter)
        if len(first) > MAX_COLUMNS:
            raise InputError(path, _too_many(len(first), lines.number))
        sample = [first]
        while len(sample) < _SAMPLE_ROWS:
            more = _content_line(lines, delimiter)
            if more is None:
                break
            sample.append(_cells(more, delimiter))
    comma = delimiter != "," and any(_DECIMAL_COMMA.match(c) for row in sample for c in row)
    if comma:
        notes.append("read decimal commas (9,81 as 9.81)")
    return TableHead(
        path=path,
        delimiter=delimiter,
        header=tuple(header),
        cells=len(first),
        decimal_comma=comma,
        preamble=tuple(preamble),
        first_line=first_line,
        data_offset=offset,
        notes=tuple(notes),
    )


def _too_many(count: int, number: int) -> str:
    return (
        f"line {number} has {count:,} columns; a sensor log has at most {MAX_COLUMNS} (a "
        "foreign or damaged file?)"
    )


def _content_line(lines: _Lines, delimiter: str | None) -> str | None:
    """The next line that is neither blank nor a ``#`` comment (None at the end)."""
    while True:
        line = lines.next(delimiter)
        if line is None or (line.strip() and not line.startswith("#")):
            return line


def _skip_preamble(
    lines: _Lines,
    line: str,
    delimiter: str | None,
    preamble: list[tuple[str, str]],
    notes: list[str],
) -> str | None:
    """Lines ``Key:,value,,,`` up to the header (``PacketCounter,…``); their pairs kept."""
    skipped = 0
    while line is not None and skipped < _PREAMBLE_LINES:
        if "PacketCounter" in line and "SampleTimeFine" in line:
            notes.append(f"skipped the exporter's {skipped} preamble lines before the header")
            return line
        sep = delimiter or max((",", ";", "\t"), key=line.count)
        cells = [c.strip() for c in _cells(line, sep)]
        if cells and cells[0].endswith(":"):
            value = next((c for c in cells[1:] if c), "")
            preamble.append((cells[0][:-1].strip(), value))
        skipped += 1
        line = _content_line(lines, delimiter)
    raise InputError(
        lines.path,
        f"lines {lines.number - skipped + 1}–{lines.number} look like an exporter's preamble "
        f"('{preamble[0][0] if preamble else line}:'), but no PacketCounter,SampleTimeFine "
        "header follows within "
        f"{_PREAMBLE_LINES} lines",
    )


def read_table(
    head: TableHead,
    time: int,
    groups: Mapping[str, Sequence[int]],
    names: Sequence[str] | None = None,
) -> TableColumns:
    """The time column ``time`` exactly and each group of columns as float64, block by block.

    Parameters
    ----------
    head:
        From :func:`open_table`.
    time:
        The 0-based index of the time column.
    groups:
        Named lists of 0-based column indices, read as float64: a group of one
        column gives an (N,) array, of several an (N, k) one.
    names:
        The columns' names, for messages (default: the header's, else ``#i``).

    Raises
    ------
    InputError
        Naming the file and the line: a line too long, binary data, a data
        cell that is not a number, more than :data:`MAX_ROWS` rows, none with
        a numeric time.
    """
    names = list(names or head.header)
    wanted = [time, *(i for group in groups.values() for i in group)]
    if max(wanted) >= head.cells:
        missing = max(wanted)
        label = names[missing] if missing < len(names) else f"#{missing}"
        raise InputError(
            head.path,
            f"line {head.first_line}: the first data row has {head.cells} cells, but column "
            f"{label!r} is number {missing + 1}",
        )
    parser = _BlockParser(head, time, groups, names)
    out = GrowingColumns()
    rows = 0
    with open(head.path, "rb") as stream:
        # A first pass counts the lines (and finds NUL bytes): the columns are made that
        # long at once and filled, instead of grown (a heap of ever larger copies).
        out.reserve(min(_count_lines(head.path, stream, head), MAX_ROWS) + 1)
        stream.seek(head.data_offset)
        for block, numbers in _blocks(head.path, stream, head.first_line):
            if rows + numbers.size > MAX_ROWS:
                raise InputError(
                    head.path,
                    f"more than {MAX_ROWS:,} data rows (line {int(numbers[-1])}): longer than any "
                    "calibration session (23 h at 120 Hz); cut the session out of it first",
                )
            out.append(**parser.parse(block, numbers, rows))
            rows += numbers.size
    if rows == 0:
        raise InputError(head.path, "the CSV file has a header but no data rows")
    columns = out.finish()
    if not columns or columns["whole"].size == 0:
        raise InputError(head.path, f"none of the {rows} rows has a numeric time")
    whole, pico = columns.pop("whole"), columns.pop("pico")
    return TableColumns(
        rows=rows,
        skipped=rows - whole.size,
        time_whole=whole,
        time_pico=pico,
        groups=columns,
        odd_rows=parser.odd_rows,
    )


def _count_lines(path: str, stream, head: TableHead) -> int:
    """The lines after ``head.data_offset`` (an upper bound of the data rows); NULs refused."""
    stream.seek(head.data_offset)
    lines = 0
    while chunk := stream.read(BLOCK_BYTES):
        nul = chunk.find(b"\x00")
        if nul >= 0:
            raise InputError(path, _binary(head.first_line + lines + chunk[:nul].count(b"\n")))
        lines += chunk.count(b"\n")
    return lines + 1


def _blocks(path: str, stream, first_line: int):
    """``(bytes, file line numbers)`` of whole lines, comment and blank lines cut out."""
    carry = b""
    number = first_line  # the file's line number of the next line
    while True:
        chunk = stream.read(BLOCK_BYTES)
        nul = chunk.find(b"\x00")
        if nul >= 0:
            raise InputError(path, _binary(number + (carry + chunk[:nul]).count(b"\n")))
        buf = carry + chunk if carry else chunk
        if not chunk:
            if not buf:
                return
            body, carry = (buf if buf.endswith(b"\n") else buf + b"\n"), b""
        else:
            cut = buf.rfind(b"\n")
            if cut < 0:
                if len(buf) > MAX_LINE_BYTES:
                    raise InputError(path, _long_line(number))
                carry = buf
                continue
            body, carry = buf[: cut + 1], buf[cut + 1 :]
            if len(carry) > MAX_LINE_BYTES:
                raise InputError(path, _long_line(number + body.count(b"\n")))
        data = np.frombuffer(body, np.uint8)
        ends = np.flatnonzero(data == 10)
        starts = np.empty_like(ends)
        starts[0] = 0
        starts[1:] = ends[:-1] + 1
        lengths = ends - starts
        too_long = np.flatnonzero(lengths > MAX_LINE_BYTES)
        if too_long.size:
            raise InputError(path, _long_line(number + int(too_long[0])))
        first = data[starts]  # each line's first byte (its newline, for an empty line)
        keep = first != ord("#")
        # A blank line starts with white space; the few that do are looked at one by one.
        for i in np.flatnonzero(_WHITE[first]).tolist():
            keep[i] = bool(body[starts[i] : ends[i]].strip())
        numbers = number + np.arange(ends.size)
        number += ends.size
        if not keep.any():
            continue
        if not keep.all():
            body = data[np.repeat(keep, lengths + 1)].tobytes()
        yield body, numbers[keep]


class _BlockParser:
    """Parses blocks with Arrow: typed at once, or as text when a cell needs a closer look."""

    def __init__(
        self, head: TableHead, time: int, groups: Mapping[str, Sequence[int]], names: list[str]
    ) -> None:
        import pyarrow as pa
        import pyarrow.csv as pcsv

        # malloc's pool: Arrow's default one (mimalloc) keeps what each block freed.
        self.pool = pa.system_memory_pool()
        self.head = head
        self.time = time
        self.groups = {k: list(v) for k, v in groups.items()}
        self.floats = sorted({i for v in self.groups.values() for i in v} - {time})
        self.names = names
        self.odd_rows = 0
        self._odd: list[tuple[int, str]] = []
        columns = [f"c{i}" for i in range(head.cells)]
        self._read = pcsv.ReadOptions(column_names=columns, use_threads=False)
        self._parse = pcsv.ParseOptions(delimiter=head.delimiter, invalid_row_handler=self._odd_row)
        include = [f"c{i}" for i in [time, *self.floats]]
        common = {
            "include_columns": include,
            "strings_can_be_null": False,
            "quoted_strings_can_be_null": False,
        }
        typed = {f"c{time}": pa.string(), **{f"c{i}": pa.float64() for i in self.floats}}
        self._typed = pcsv.ConvertOptions(
            column_types=typed,
            null_values=list(_NULLS),
            decimal_point="," if head.decimal_comma else ".",
            **common,
        )
        as_text = {c: pa.string() for c in include}
        self._as_text = pcsv.ConvertOptions(column_types=as_text, **common)

    def _odd_row(self, row) -> str:
        self._odd.append((int(row.number), row.text))
        return "skip"

    def _name(self, index: int) -> str:
        return self.names[index].strip() if index < len(self.names) else f"#{index}"

    def parse(self, block: bytes, numbers: np.ndarray, before: int) -> dict[str, np.ndarray]:
        """One block's rows with a numeric time: whole, pico and the groups' columns."""
        import pyarrow as pa
        import pyarrow.csv as pcsv

        source = pa.py_buffer(block)
        self._odd.clear()
        try:
            table = pcsv.read_csv(source, self._read, self._parse, self._typed, self.pool)
            typed = True
        except pa.ArrowInvalid:
            self._odd.clear()
            try:
                table = pcsv.read_csv(source, self._read, self._parse, self._as_text, self.pool)
            except pa.ArrowInvalid as exc:
                raise InputError(
                    self.head.path,
                    f"lines {int(numbers[0])}–{int(numbers[-1])}: cannot be read as CSV ({exc})",
                ) from None
            typed = False
        odd = sorted(self._odd)
        self.odd_rows += len(odd)
        n = numbers.size
        if table.num_rows + len(odd) != n:
            raise InputError(
                self.head.path,
                f"lines {int(numbers[0])}–{int(numbers[-1])}: {table.num_rows + len(odd)} rows "
                f"parsed from {n} lines (a quoted field spanning lines?); not a sensor log's CSV",
            )
        in_table = np.ones(n, bool)
        at = np.array([number - 1 for number, _ in odd], dtype=np.int64)
        in_table[at] = False
        whole = np.zeros(n, np.int64)
        pico = np.zeros(n, np.int64)
        valid = np.zeros(n, bool)
        whole[in_table], pico[in_table], valid[in_table] = self._times(table)
        values = np.full((n, len(self.floats)), np.nan)
        rows_of_table = np.flatnonzero(in_table)
        for k, index in enumerate(self.floats):
            column = table.column(f"c{index}")
            if typed:
                values[in_table, k] = column.to_numpy()
            else:
                values[in_table, k] = self._text_numbers(
                    column, valid[in_table], rows_of_table, numbers, before, index
                )
        for (_, text), row in zip(odd, at.tolist(), strict=True):
            whole[row], pico[row], valid[row], values[row] = self._odd_cells(
                text, int(numbers[row]), before + row + 1
            )
        out = {"whole": whole[valid], "pico": pico[valid]}
        for group, indices in self.groups.items():
            picked = values[valid][:, [self.floats.index(i) for i in indices]]
            out[group] = picked[:, 0].copy() if len(indices) == 1 else picked
        return out

    def _times(self, table) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Whole and pico parts of the time cells (exact, via Arrow's decimals) and validity."""
        import pyarrow as pa
        import pyarrow.compute as pc

        text = pc.utf8_trim_whitespace(
            table.column(f"c{self.time}").combine_chunks(self.pool), memory_pool=self.pool
        )
        if self.head.decimal_comma:
            text = pc.replace_substring(text, ",", ".", memory_pool=self.pool)
        valid = pc.match_substring_regex(text, _TIME_NUMBER, memory_pool=self.pool).to_numpy(
            zero_copy_only=False
        )
        whole = np.zeros(valid.size, np.int64)
        pico = np.zeros(valid.size, np.int64)
        if valid.any():
            numbers = pc.filter(text, pa.array(valid), memory_pool=self.pool)
            magnitude = pc.abs(
                pc.cast(numbers, pa.float64(), memory_pool=self.pool), memory_pool=self.pool
            ).to_numpy()
            if np.any(magnitude > 9.2e18):
                bad = numbers[int(np.argmax(magnitude > 9.2e18))].as_py()
                raise InputError(
                    self.head.path,
                    f"time {bad!r} in column {self._name(self.time)!r} is beyond any clock's "
                    "count (2⁶³)",
                )
            exact = pc.cast(numbers, pa.decimal128(37, 12), safe=False, memory_pool=self.pool)
            floor = pc.floor(exact, memory_pool=self.pool)
            fraction = pc.cast(
                pc.subtract(exact, floor, memory_pool=self.pool),
                pa.decimal128(13, 12),
                memory_pool=self.pool,
            )
            scaled = pc.multiply(
                fraction, pa.scalar(_PICO, pa.decimal128(13, 0)), memory_pool=self.pool
            )
            whole[valid] = pc.cast(floor, pa.int64(), memory_pool=self.pool).to_numpy()
            pico[valid] = pc.cast(scaled, pa.int64(), memory_pool=self.pool).to_numpy()
        return whole, pico, valid

    def _text_numbers(self, column, valid, rows, numbers, before, index) -> np.ndarray:
        """A column read as text (a block whose typed read failed): numbers, or the bad cell."""
        import pyarrow as pa
        import pyarrow.compute as pc

        text = pc.utf8_trim_whitespace(column.combine_chunks(self.pool), memory_pool=self.pool)
        if self.head.decimal_comma:
            text = pc.replace_substring(text, ",", ".", memory_pool=self.pool)
        missing = pc.is_in(text, value_set=pa.array(_NULLS), memory_pool=self.pool).to_numpy(
            zero_copy_only=False
        )
        out = np.full(len(text), np.nan)
        use = valid & ~missing
        try:
            out[use] = pc.cast(
                pc.filter(text, pa.array(use), memory_pool=self.pool),
                pa.float64(),
                memory_pool=self.pool,
            ).to_numpy()
        except pa.ArrowInvalid:
            cells = text.to_pylist()
            for i in np.flatnonzero(use).tolist():
                try:
                    float(cells[i])
                except ValueError:
                    row = int(rows[i])
                    raise InputError(
                        self.head.path,
                        self._not_a_number(numbers[row], before + row + 1, cells[i], index),
                    ) from None
            raise  # pragma: no cover - Arrow refused what Python reads
        return out

    def _not_a_number(self, line, data_row: int, cell: str, index: int) -> str:
        row = data_row + (1 if self.head.header else 0)
        return (
            f"data row {row}: a data cell is not a number: {cell!r} in column "
            f"{self._name(index)!r} (line {int(line)})"
        )

    def _odd_cells(self, text: str, line: int, data_row: int):
        """A row whose number of cells differs from the first data row's, read cell by cell."""
        from decimal import Decimal

        cells = [c.strip() for c in _cells(text, self.head.delimiter)]
        if self.head.decimal_comma:
            cells = [c.replace(",", ".") if _DECIMAL_COMMA.match(c) else c for c in cells]
        values = np.full(len(self.floats), np.nan)
        stamp = cells[self.time] if self.time < len(cells) else ""
        if not re.fullmatch(_TIME_NUMBER, stamp):
            return 0, 0, False, values
        exact = Decimal(stamp)
        whole = int(exact.to_integral_value(rounding="ROUND_FLOOR"))
        pico = int((exact - whole) * _PICO)
        for k, index in enumerate(self.floats):
            if index >= len(cells):
                raise InputError(
                    self.head.path,
                    self._not_a_number(line, data_row, "", index)
                    + f" (the row has {len(cells)} cells, no {index + 1}th)",
                )
            if cells[index] in _NULLS:
                continue
            try:
                values[k] = float(cells[index])
            except ValueError:
                raise InputError(
                    self.head.path, self._not_a_number(line, data_row, cells[index], index)
                ) from None
        return whole, pico, True, values
