"""Text recordings read in bounded memory: the file as lines (never whole), its numeric
columns by a fast CSV engine, and the inputs that are no file refused.

* :func:`check_regular`: a FIFO, a character device (``/dev/zero``, a terminal), a socket
  or a block device is refused with one line (InputError) before a byte is read: such an
  input may never end, and a reader that waits for its end would fill the memory;
* :class:`TextFile`: the lines of a (gzip-compressed) UTF-8 text file, decoded a line at a
  time (an undecodable byte is one line naming the file); its first line; a line number;
* :func:`numeric_columns`: the named columns of a delimited file as float64 arrays by
  ``pyarrow.csv`` (within 2x ``pandas.read_csv``), batch by batch into one array per column
  (never held twice). It answers None wherever it
  cannot promise the numbers of the reader's own loop (pyarrow missing, runs of spaces as
  the separator, a cell the engine does not read as a finite number, a row of another
  width, a type it infers other than a number): the caller then reads the rows itself, and
  its loop names the line and column at fault. Cells are parsed by Arrow's correctly
  rounded float parser, which gives the bits of Python's ``float`` (the tests compare them).
"""

from __future__ import annotations

import codecs
import gzip
import os
import stat
from collections.abc import Iterator, Mapping
from pathlib import Path

import numpy as np

from gyrodenoise.errors import InputError

GZIP_MAGIC = b"\x1f\x8b"
#: integers of more than 15 digits (ns since 1970): the reader keeps them as integers
EXACT_INT = 10 ** 15
_KINDS = ((stat.S_ISFIFO, "a FIFO (named pipe)"), (stat.S_ISCHR, "a character device"),
          (stat.S_ISSOCK, "a socket"), (stat.S_ISBLK, "a block device"))


def check_regular(path: str | os.PathLike[str]) -> None:
    """InputError (one line) unless ``path`` is a regular file (a folder is left to the
    caller, which names what it expected)."""
    try:
        mode = os.stat(path).st_mode
    except OSError:
        return                    # the reader's own open says why
    for test, what in _KINDS:
        if test(mode):
            raise InputError(f"is {what}, not a file: a stream may never end; save it to a file first", str(path))


class TextFile:
    """A text recording read a line at a time (gzip-compressed or not; a UTF-8 BOM dropped)."""

    def __init__(self, path: str | os.PathLike[str]) -> None:
        p = Path(path)
        self.source = str(path)
        if not p.exists():
            raise InputError("no such file", self.source)
        if p.is_dir():
            raise InputError("is a directory, expected a CSV file", self.source)
        check_regular(p)
        self.path = p
        try:
            with open(p, "rb") as f:
                self.gzipped = f.read(2) == GZIP_MAGIC
        except OSError as exc:
            raise InputError(f"cannot read: {exc}", self.source) from None

    def _binary(self):
        return gzip.open(self.path, "rb") if self.gzipped else open(self.path, "rb")

    def lines(self) -> Iterator[str]:
        """Every line, with its line ending (the text as ``io.StringIO`` would give it)."""
        dec = codecs.getincrementaldecoder("utf-8-sig")()
        try:
            with self._binary() as f:
                for raw in f:
                    yield from dec.decode(raw).splitlines(keepends=True)
                tail = dec.decode(b"", final=True)
                if tail:
                    yield tail
        except (OSError, EOFError, gzip.BadGzipFile) as exc:
            raise InputError(f"cannot read: {exc}", self.source) from None
        except UnicodeDecodeError:
            raise InputError("not a text CSV file (undecodable bytes)", self.source) from None

    def first_line(self) -> str:
        """The first line that is not blank ("" when there is none)."""
        return next((ln for ln in self.lines() if ln.strip()), "")

    def line_of(self, sample_index: int, header_lines: int = 1) -> int:
        """File line number of data sample ``sample_index`` (blank lines and the
        ``header_lines`` first lines skipped)."""
        line, count = 1, -1
        for line, raw in enumerate(self.lines(), start=1):
            if line <= header_lines or not raw.strip():
                continue
            count += 1
            if count == sample_index:
                return line
        return line

    def check_decodable(self) -> None:
        """InputError when some byte is not UTF-8 (read in 16 MB blocks)."""
        dec = codecs.getincrementaldecoder("utf-8")()
        try:
            with self._binary() as f:
                while block := f.read(1 << 24):
                    dec.decode(block)
                dec.decode(b"", final=True)
        except (OSError, EOFError, gzip.BadGzipFile) as exc:
            raise InputError(f"cannot read: {exc}", self.source) from None
        except UnicodeDecodeError:
            raise InputError("not a text CSV file (undecodable bytes)", self.source) from None


def numeric_columns(text: TextFile, skip_lines: int, width: int, index: Mapping[str, int],
                    sep: str | None, exact_int: str | None = None) -> dict[str, np.ndarray] | None:
    """{name: float64 array} of the columns ``index`` (name -> position among ``width``
    fields) of the rows after the first ``skip_lines`` lines, read by pyarrow; None where
    the reader's own loop must read them (module docstring). ``exact_int``: the column
    (a time column) whose integers of more than 15 digits stay int64, as the loop keeps them."""
    try:
        import pyarrow as pa
        import pyarrow.csv as pcsv
    except ImportError:
        return None
    if sep not in (",", ";", "\t") or not index:
        return None
    head = text.lines()
    if any(not next(head, "").strip() for _ in range(skip_lines)):   # a blank line among the header's
        return None
    head.close()
    text.check_decodable()
    names = [f"f{i}" for i in range(width)]
    wanted = {name: names[i] for name, i in index.items()}
    types = {col: pa.float64() for name, col in wanted.items() if name != exact_int}
    size = None if text.gzipped else text.path.stat().st_size
    try:
        stream = pa.input_stream(str(text.path), compression="gzip" if text.gzipped else None)
        reader = pcsv.open_csv(
            stream, read_options=pcsv.ReadOptions(skip_rows=skip_lines, column_names=names, block_size=BLOCK),
            parse_options=pcsv.ParseOptions(delimiter=sep),
            convert_options=pcsv.ConvertOptions(include_columns=sorted(set(wanted.values())), column_types=types,
                                                null_values=[], strings_can_be_null=False,
                                                quoted_strings_can_be_null=False))
        cols = _collect(reader, sorted(set(wanted.values())), size)
    except (pa.ArrowInvalid, pa.ArrowNotImplementedError, pa.ArrowTypeError):
        return None
    if cols is None:
        return None
    return _as_the_loop_reads({name: cols[col] for name, col in wanted.items()}, exact_int)


#: bytes of text per batch of the CSV engine
BLOCK = 1 << 24


def _collect(reader, cols: list[str], size: int | None) -> dict[str, np.ndarray] | None:
    """The columns of every record batch, each in one array sized from the file's length
    and the first batch's rows per byte (grown by half where that falls short, cut to the
    rows read at the end): the columns are never held twice. None: a column not all numbers,
    a float that is not finite, or no data rows."""
    import pyarrow as pa
    out: dict[str, np.ndarray] = {}
    n = 0
    for batch in reader:
        k = batch.num_rows
        for col in cols:
            a = batch.column(col)
            if a.null_count or a.type not in (pa.float64(), pa.int64()):
                return None
            v = a.to_numpy(zero_copy_only=False)
            if v.dtype.kind == "f" and not np.isfinite(v).all():
                return None
            if col not in out:
                cap = k if size is None else max(k, int(k * size / min(size, BLOCK) * 1.02) + 1024)
                out[col] = np.empty(cap, dtype=v.dtype)
            buf = out[col]
            if buf.dtype != v.dtype:
                return None
            if n + k > buf.shape[0]:
                buf = out[col] = _grown(buf, n + k)
            buf[n:n + k] = v
        n += k
    if n == 0:
        return None
    for col, buf in out.items():
        buf.resize(n, refcheck=False)        # in place: the rows read
    return out


def _grown(buf: np.ndarray, need: int) -> np.ndarray:
    new = np.empty(max(need, buf.shape[0] + buf.shape[0] // 2), dtype=buf.dtype)
    new[:buf.shape[0]] = buf
    return new


def _as_the_loop_reads(cols: dict[str, np.ndarray], exact_int: str | None) -> dict[str, np.ndarray] | None:
    """Integer cells as the reader's loop keeps them: int64 when every one has more than 15
    digits (ns since 1970), float64 when none has (exact below 2^53); None for a mix."""
    if exact_int is None or exact_int not in cols or cols[exact_int].dtype.kind != "i":
        return cols
    t = cols[exact_int]
    big = t >= EXACT_INT
    if big.all():
        return cols
    if (np.abs(t) >= EXACT_INT).any():
        return None
    cols[exact_int] = t.astype(np.float64)
    return cols


def csv_tables(text: TextFile, skip_lines: int, names: list[str], sep: str, include: list[str],
               types: Mapping[str, object], block: int) -> Iterator[object] | None:
    """The rows after the first ``skip_lines`` lines as pyarrow tables (the columns
    ``include`` of ``names``; ``types``: column -> pyarrow type, the others inferred from the
    first block and then held), parsed a block of about ``block`` bytes of whole lines at a
    time: the memory of one block whatever the file's length (pyarrow's streaming reader
    reads ahead of its consumer, its buffers growing with the file). None where the skipped
    lines are not the reader's (a line ending other than a newline among them). Parsing
    errors: pyarrow's (ArrowInvalid ...), raised while iterating."""
    import itertools

    import pyarrow as pa
    import pyarrow.csv as pcsv
    head = "".join(itertools.islice(text.lines(), skip_lines))
    if head.count("\n") != skip_lines or "\r" in head.replace("\r\n", "\n"):
        return None
    with text._binary() as f:
        offset = len(head.encode("utf-8")) + (3 if f.read(3) == codecs.BOM_UTF8 else 0)
    return _tables(text, offset, names, sep, include, dict(types), block, pa, pcsv)


def _tables(text: TextFile, offset: int, names: list[str], sep: str, include: list[str], types: dict,
            block: int, pa, pcsv) -> Iterator[object]:
    ro = pcsv.ReadOptions(column_names=names, use_threads=False, block_size=max(block, 1 << 16))
    po = pcsv.ParseOptions(delimiter=sep)
    with text._binary() as f:
        if text.gzipped:
            f.read(offset)
        else:
            f.seek(offset)
        carry = b""
        while True:
            data = f.read(block)
            buf = carry + data
            cut = buf.rfind(b"\n") + 1 if data else len(buf)
            part, carry = buf[:cut], buf[cut:]
            if part.strip():
                co = pcsv.ConvertOptions(include_columns=include, column_types=types, null_values=[],
                                         strings_can_be_null=False, quoted_strings_can_be_null=False)
                table = pcsv.read_csv(pa.py_buffer(part), read_options=ro, parse_options=po, convert_options=co)
                for col in include:           # the first block's types held, as the streaming reader does
                    types.setdefault(col, table.schema.field(col).type)
                yield table
            if not data:
                return


#: samples per chunk of the filters and the CSV writer (16 MB of float64 a column)
CHUNK = 1 << 21


def chunk_bounds(n: int, size: int | None = None) -> Iterator[tuple[int, int]]:
    """(start, stop) of the chunks of ``size`` samples (default CHUNK) covering 0..n-1."""
    size = int(size or CHUNK)
    for a in range(0, n, size):
        yield a, min(a + size, n)


def process_chunks(filt, z: np.ndarray, restarts: np.ndarray | None = None, size: int | None = None) -> np.ndarray:
    """``filt.process`` (a :class:`gyrodenoise.denoiser.Denoiser`: its whole state carried
    from chunk to chunk) over ``z`` a chunk at a time: the one-shot run's output, bit for
    bit, without its whole-record temporaries."""
    out = np.empty(len(z))
    for a, b in chunk_bounds(len(z), size):
        out[a:b] = filt.process(z[a:b], None if restarts is None else restarts[a:b])
    return out


def save_columns(path: str | os.PathLike[str], columns: list[np.ndarray], header: str, fmt: str = "%.10g",
                 size: int | None = None) -> None:
    """``np.savetxt(path, np.column_stack(columns), delimiter=",", header=header,
    comments="", fmt=fmt)``, the same bytes, written a chunk of rows at a time (the stacked
    table is never made). OSError as savetxt's."""
    n = len(columns[0])
    with open(path, "wb") as f:
        f.write((header + "\n").encode())
        for a, b in chunk_bounds(n, size):
            write_rows(f, [np.asarray(c[a:b]) for c in columns], fmt)


#: rows formatted at a time by write_rows
ROWS = 1 << 14


def write_rows(f, columns: list[np.ndarray], fmt: str = "%.10g") -> None:
    """Append the rows of ``columns`` to the binary file ``f`` as ``np.savetxt`` writes them
    (``fmt`` per value, commas, a newline a row), the bytes of savetxt: one ``%`` format of
    a block of rows at a time instead of one a row."""
    row = ",".join([fmt] * len(columns)) + "\n"
    n = len(columns[0])
    for a in range(0, n, ROWS):
        b = min(a + ROWS, n)
        block = np.column_stack([np.asarray(c[a:b], dtype=np.float64) for c in columns])
        f.write(((row * (b - a)) % tuple(block.ravel().tolist())).encode())
