"""Columns of samples appended chunk by chunk, grown in place, without per-message objects.

A reader that keeps every decompressed chunk until the end holds the whole
file's message bytes (~340 B per ROS 2 Imu sample) when it needs 24–56 B.
Decoding each chunk as it is decompressed, into these columns, lets the chunk
go at once (a :class:`ColumnSink` per channel).  The columns grow with
:meth:`numpy.ndarray.resize` — ``realloc``, which for large arrays remaps pages
instead of copying, so the peak is about the final size rather than the 2–3× of
"collect pieces, then concatenate".
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from wheelcal.io.mcap_scan import MessageBlock

_MIN_CAPACITY = 4096


class GrowingColumns:
    """Named columns (1-D, or 2-D with a fixed width) of one length, appended in pieces.

    A column may be absent from some pieces (``None``): its rows there are NaN
    (float columns only); a column that first appears late is NaN before.
    """

    def __init__(self) -> None:
        self.size = 0
        self._capacity = 0
        self._columns: dict[str, np.ndarray] = {}

    def reserve(self, rows: int) -> None:
        """Room for ``rows`` rows in all, when the caller knows a bound.

        Untouched pages cost nothing and :meth:`finish` trims, so the columns need
        not grow (a heap of ever larger copies) as they fill.
        """
        self._reserve(rows)

    def _reserve(self, needed: int) -> None:
        if needed <= self._capacity:
            return
        # Small steps: growing is a remap, not a copy, and numpy zero-fills (so touches)
        # every row it adds, so a large step would cost resident memory never used.
        capacity = max(needed, self._capacity + self._capacity // 8, _MIN_CAPACITY)
        for column in self._columns.values():
            column.resize((capacity, *column.shape[1:]), refcheck=False)
        self._capacity = capacity

    def append(self, **parts: np.ndarray | None) -> None:
        """Append one piece: every given column has the same number of rows."""
        n = next((len(v) for v in parts.values() if v is not None), 0)
        if n == 0:
            return
        self._reserve(self.size + n)
        stop = self.size + n
        for name, values in parts.items():
            column = self._columns.get(name)
            if values is None:
                if column is not None:
                    column[self.size : stop] = np.nan
                continue
            values = np.asarray(values)
            if len(values) != n:
                raise ValueError(f"column {name}: {len(values)} rows, the piece has {n}")
            if column is None:
                column = np.empty((self._capacity, *values.shape[1:]), values.dtype)
                if self.size:
                    column[: self.size] = np.nan
                self._columns[name] = column
            column[self.size : stop] = values
        for name, column in self._columns.items():
            if name not in parts:
                column[self.size : stop] = np.nan
        self.size = stop

    def finish(self) -> dict[str, np.ndarray]:
        """The columns trimmed to their length (the object must not be appended to after)."""
        for column in self._columns.values():
            column.resize((self.size, *column.shape[1:]), refcheck=False)
        self._capacity = self.size
        return dict(self._columns)


class ColumnSink:
    """Decodes a channel block by block as the scan finds it (see ``scan_mcap``).

    Keeps the decoded columns only (no message bytes).  A decoding error
    (one of :attr:`errors`) is kept, the blocks after it are only counted, and
    :meth:`columns` raises it.  A codec implements :meth:`decode`.
    """

    #: The exceptions that mean "this channel cannot be decoded".
    errors: tuple[type[Exception], ...] = (ValueError,)

    def __init__(self) -> None:
        self.count = 0
        self._columns = GrowingColumns()
        self._error: Exception | None = None

    def decode(self, block: MessageBlock, first_message: int) -> dict[str, np.ndarray | None]:
        """One block's columns; ``first_message``: the channel's index of its first message."""
        raise NotImplementedError

    def add(self, block: MessageBlock) -> None:
        """Decode one block's messages into the columns."""
        first = self.count
        self.count += block.count
        if self._error is not None or block.count == 0:
            return
        try:
            columns = self.decode(block, first)
        except self.errors as exc:
            self._error = exc
            return
        self._columns.append(**columns)

    def columns(self) -> dict[str, np.ndarray]:
        """Every column, trimmed (empty if no message); raises the first decoding error."""
        if self._error is not None:
            raise self._error
        return self._columns.finish()
