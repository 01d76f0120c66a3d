"""The log, block by block: sinks that write it as the run produces it (log.csv,
log.parquet, a scratch file for the metrics and figures) and readers that give it back a
block of rows at a time, so that no step after the simulation holds the whole log.

- ``CsvLog(path)``, ``ParquetLog(path)``: the log on disk, written block by block (the
  `sink` of ``virtmech.sim.run``).
- ``LogFile(folder, keep)``: the columns in `keep` in an anonymous scratch file (removed
  when closed), read back with ``.blocks(names)``; ``SimResult.source`` when the run kept
  no log in memory.
- ``blocks(result, names)``: a result's log (in memory, memory-mapped or in a LogFile), a
  block of rows of the named columns at a time.
- ``read_csv_blocks(path)``, ``read_parquet_blocks(path)``: a written log, block by block.
- ``Tee(*sinks)``: one sink feeding several.
"""

from __future__ import annotations

import os
import tempfile
from collections.abc import Iterable, Iterator, Sequence
from pathlib import Path

import numpy as np

#: rows per block when a log in memory is read block by block (10 s at 1 kHz)
#: the log's file formats (a run's --format): log.csv (the default) or log.parquet
LOG_FORMATS = ("csv", "parquet")
READ_BLOCK_ROWS = 10000


class CsvLog:
    """log.csv written block by block: a header of column names, then one row per control
    cycle ('%.10g'). Use as the `sink` of virtmech.sim.run, then close() (or `with`); the
    file is created with the first block."""

    def __init__(self, path: str | Path):
        self.path = Path(path)
        self.f = None
        self.rows = 0

    def __call__(self, rows: np.ndarray, columns: list[str]) -> None:
        if self.f is None:
            self.f = open(self.path, "w", encoding="utf-8", newline="")  # noqa: SIM115
            self.f.write(",".join(columns) + "\n")
        np.savetxt(self.f, rows, delimiter=",", fmt="%.10g")
        self.rows += len(rows)

    def close(self) -> None:
        if self.f is not None:
            self.f.close()

    def __enter__(self):
        return self

    def __exit__(self, *exc) -> None:
        self.close()


def require_pyarrow(what: str = "log.parquet"):
    """pyarrow.parquet, or an ImportError saying how to install it."""
    try:
        import pyarrow  # noqa: F401
        import pyarrow.parquet as pq
    except ImportError:
        raise ImportError(
            f"{what} needs pyarrow, which is not installed; install it with: "
            "pip install 'virtmech[parquet]' (or pip install pyarrow)"
        ) from None
    return pq


class ParquetLog(CsvLog):
    """log.parquet written block by block (pyarrow.parquet.ParquetWriter, one row group per
    block, every column float64 under the log's column names): the same log as log.csv
    at full precision. Needs pyarrow (the [parquet] extra)."""

    def __init__(self, path: str | Path):
        super().__init__(path)
        self.pq = require_pyarrow()
        self.writer = None

    def __call__(self, rows: np.ndarray, columns: list[str]) -> None:
        import pyarrow as pa

        if self.writer is None:
            schema = pa.schema([(c, pa.float64()) for c in columns])
            self.writer = self.pq.ParquetWriter(str(self.path), schema, compression="snappy")
        # columns of a C-ordered block are strided: each becomes one contiguous copy
        arrays = [pa.array(np.ascontiguousarray(rows[:, j])) for j in range(len(columns))]
        self.writer.write_table(pa.Table.from_arrays(arrays, names=list(columns)))
        self.rows += len(rows)

    def close(self) -> None:
        if self.writer is not None:
            self.writer.close()
            self.writer = None


class Tee:
    """A sink that hands each block to every one of `sinks`, in order."""

    def __init__(self, *sinks):
        self.sinks = [s for s in sinks if s is not None]

    def __call__(self, rows: np.ndarray, columns: list[str]) -> None:
        for s in self.sinks:
            s(rows, columns)


class LogFile:
    """A sink keeping the columns `keep` (all if None; names the log lacks are skipped) of
    every block in an anonymous scratch file in `folder` (the system's temporary folder if
    None), row after row as float64; read back with `blocks`. Closing it removes the data.
    This is how `virtmech run` keeps what the metrics and the figures read without holding
    the log in memory."""

    def __init__(self, folder: str | Path | None = None, keep: Iterable[str] | None = None):
        self.keep = None if keep is None else list(keep)
        self.f = tempfile.TemporaryFile(prefix=".virtmech-log-", dir=folder)  # noqa: SIM115
        self.columns: list[str] | None = None
        self._idx: np.ndarray | None = None
        self.rows = 0
        self.block_rows = 0  # the largest block written: blocks are read back in that size

    def __call__(self, rows: np.ndarray, columns: list[str]) -> None:
        if self.columns is None:
            have = set(columns)
            names = list(columns) if self.keep is None else [c for c in self.keep if c in have]
            names = list(dict.fromkeys(names))
            self.columns = names
            self._idx = np.array([columns.index(c) for c in names], dtype=np.intp)
        part = np.ascontiguousarray(rows[:, self._idx], dtype=np.float64)
        self.f.seek(0, os.SEEK_END)
        self.f.write(part.tobytes())
        self.rows += len(rows)
        self.block_rows = max(self.block_rows, len(rows))

    def blocks(self, names: Sequence[str], rows: int | None = None) -> Iterator[np.ndarray]:
        """The named columns, `rows` rows at a time (default: the size written), as
        (rows x len(names)) float64 arrays, first row first."""
        cols = self.columns or []
        missing = [n for n in names if n not in cols]
        if missing:
            raise KeyError(f"the log file does not keep the columns {missing}")
        idx = [cols.index(n) for n in names]
        width = len(cols)
        step = max(1, int(rows or self.block_rows or READ_BLOCK_ROWS))
        self.f.flush()
        for k in range(0, self.rows, step):
            count = min(step, self.rows - k)
            self.f.seek(k * width * 8)
            data = np.fromfile(self.f, dtype=np.float64, count=count * width)
            yield data.reshape(count, width)[:, idx]

    def close(self) -> None:
        self.f.close()

    def __enter__(self):
        return self

    def __exit__(self, *exc) -> None:
        self.close()


def blocks(result, names: Sequence[str], rows: int | None = None) -> Iterator[np.ndarray]:
    """A SimResult's log, the named columns `rows` rows at a time (default READ_BLOCK_ROWS,
    or the block size of its LogFile): from result.source when the run kept no log in
    memory, else from result.log (in memory or memory-mapped); each block a copy
    (rows x len(names))."""
    source = getattr(result, "source", None)
    if source is not None:
        yield from source.blocks(names, rows)
        return
    log = result.log
    idx = [result.columns.index(n) for n in names]
    step = max(1, int(rows or READ_BLOCK_ROWS))
    for k in range(0, log.shape[0], step):
        yield np.asarray(log[k : k + step][:, idx], dtype=np.float64)


def read_csv_blocks(path: str | Path, rows: int = READ_BLOCK_ROWS):
    """(columns, iterator of row blocks) of a log.csv, `rows` rows at a time."""
    f = open(path, encoding="utf-8")  # noqa: SIM115
    columns = f.readline().strip().split(",")

    def gen():
        with f:
            while True:
                lines = [line for _, line in zip(range(rows), f)]
                if not lines:
                    return
                yield np.loadtxt(lines, delimiter=",", ndmin=2).reshape(len(lines), -1)

    return columns, gen()


def read_parquet_blocks(path: str | Path, rows: int = READ_BLOCK_ROWS):
    """(columns, iterator of row blocks) of a log.parquet, `rows` rows at a time."""
    pq = require_pyarrow()
    pf = pq.ParquetFile(str(path))
    columns = list(pf.schema_arrow.names)

    def gen():
        for batch in pf.iter_batches(batch_size=rows):
            yield np.column_stack(
                [batch.column(j).to_numpy(zero_copy_only=False) for j in range(len(columns))]
            )

    return columns, gen()
