"""One time model for every recording: the unit, the sample rate and the kind of
timestamps, read from the timestamp column itself.

:func:`analyse_time` takes a timestamp column as read (any numbers: seconds,
milliseconds, a ROS ``%time`` in ns since 1970, a boot time in µs) and returns a
:class:`TimeBase`; :func:`restart_mask` gives the samples where a filter starts
over. What each choice does to a user's numbers:

**Unit** (``unit=`` names it and wins; otherwise the first rule that applies):

* *epoch*: the first timestamp is a date between 2000 and 2100 in s, ms, µs or ns
  since 1970 (the four windows are 1000x apart and do not overlap) and the steps
  give 0.01 Hz to 1 MHz in that unit. ``epoch`` is True and ``epoch_offset_s``
  is that date in s; times are then counted from the first sample.
* *sample rate*: ``nominal_rate`` is given and exactly one unit puts the record's
  rate within :data:`NOMINAL_TOLERANCE` of it.
* *spacing*: steps under 1 (fractional) are seconds; whole-number steps are the
  largest of ms, µs, ns that gives at least :data:`MIN_SPACING_RATE_HZ` (10 Hz).
  So 0.01 reads as s (100 Hz), 10 and 1 as ms (100 Hz, 1 kHz), 125 and 1000 as µs
  (8 kHz, 1 kHz), 5e6 as ns (200 Hz). A record in whole seconds (1 Hz and
  slower) or in ms slower than 10 Hz is misread: the note names the other
  reading when it is a plausible one, and ``unit=`` settles it.

**Sample rate**: count over span, never 1/median step. Within each run (below),
(samples - 1 + samples missing in bridged gaps) / (last time - first time),
summed over the runs: jitter and bursts average out, missing samples are
counted, the time of restarting gaps and reversals is left out. The median
step is the check: when 1/median step differs from the rate the note says why
(bursts, jitter). A stated ``nominal_rate`` is used when it is within
:data:`NOMINAL_TOLERANCE` (2 %: a MEMS sensor's own clock may be that far off its
nominal rate) of the record's rate; further off it is an InputError naming both.

**Kind of timestamps** (:class:`TimestampKind`): *varying* when the rate changes
along the record (the median steps of blocks of up to 256 steps differ by more
than :data:`RATE_CHANGE`, 1.5x, between their 10th and 90th percentiles: a
telemetry stream whose rate a ground station changed); the rate is then the
mean (count over span) and gaps are judged against the median step of each
block; else *bursty* when 1/median step is more than 1.25x the rate (a host
stamping USB packets: many samples ~0 apart, then a long step; told only over
32 steps or more: a few steps and a long one are a gap); else *jittered* when more than 1 % of the steps are more than
1 % off the period; else *uniform*.

**Gap** (what counts): samples missing by count, not a long step alone. A step
of at least :data:`GAP_CANDIDATE` (1.5) periods is a candidate; its samples
missing are the rise of the sample clock across it: E = time / period - sample
number, and the rise is the lower envelope of E over the :data:`LEVEL_WINDOW`
samples after the step minus that before it (16 samples, or 16 burst cycles
for bursts; host stamps are late, never early, so the lower envelope is the
steady one; a single stamp below both neighbours, such as a repeated
timestamp, is left out of it). A burst's long step only makes up for the short
steps before it, and a jittered step for its neighbours: their rise is 0.
Candidates closer than the window form a cluster, counted from the level before
its first step, so that two drops a few samples apart are each counted once. A
rise that rounds to 1 or more is a gap of that many missing samples (its
duration is the step), when the clock is locked to whole samples (lone rises
within :data:`LOCKED` of whole numbers); a logging loop that slips by parts of a
period (rises such as 0.7) counts only rises out of that scatter
(:data:`NOISE_SIGMAS` robust sigmas), so its slips are jitter, not drops.
Tested: every gap and count exact with 2 % of samples dropped on uniform stamps
and on ±20 % jittered stamps; with ±30-40 % stamp jitter and 2 % drops together
most drops are counted (median 3-16 of ~300 missed) but some records miss many
(the rate then reads up to 2 % low, as the delivered rate); beyond ±35 % jitter
alone, a rare lone rise reads as one missing sample (1 record in 3,000, the rate
within 0.1 %). Inside bursts a lone dropped sample is hidden by the bursts' own
scatter, so the rate of a bursty record that drops single samples lies between
the delivered rate and the sensor's (tested: 2 % dropped, within 2 %); a lost
packet or a longer outage is found. Within a window of an end of the record, a
gap must also stand out of the stamps' scatter.

**Restarts** (:func:`restart_mask`): a time reversal (time going back: a reboot, a
concatenated log) and a gap of more than :data:`MAX_BRIDGED_MISSING` (4) missing
samples whose step is also more than 4 periods long restart a filter; jitter,
bursts, repeated timestamps and shorter gaps do not (the filter carries on, the
next sample taken as the next one: a dropped sample costs no denoising). This
is the flight-log readers' rule (a step of more than 5 periods). The runs are
the stretches between restarts; the note gives their lengths.

Bad input (an :class:`~gyrodenoise.errors.InputError`, one line): a value that is
not a finite number, fewer than 2 samples, all timestamps equal, time that
never advances, an unknown unit, a ``nominal_rate`` that is not a number above 0
and at most :data:`MAX_RATE_HZ`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from datetime import datetime, timezone
from enum import Enum

import numpy as np

from gyrodenoise.errors import InputError

GAP_CANDIDATE = 1.5          # a step of this many periods may hold missing samples
PASSES = 6                   # at most this many passes: gaps found with a period, the period from them
LEVEL_WINDOW = 16            # (>= 2) samples each side of a step for the sample clock's level
LOCKED = 0.15                # lone rises this close to whole numbers (median): a clock locked to samples
NOISE_SIGMAS = 5.0           # a rise must stand this far out of the rises' own noise
BURST_WINDOW_CYCLES = 16     # for bursts: this many burst cycles (a burst ends with a candidate step)
MAX_BRIDGED_MISSING = 4      # gaps of up to this many missing samples do not restart a filter
NOMINAL_TOLERANCE = 0.02     # a stated rate is used within 2 % of the record's own
MIN_SPACING_RATE_HZ = 10.0   # the spacing rule's floor for whole-number steps
MAX_RATE_HZ = 1.0e7          # above: not a sample rate
BURST_RATIO = 1.25           # 1/median step above this x rate: bursts
MIN_BURST_BLOCKS = 4         # bursts and rate changes are told over at least this many blocks (>= 32 steps)
RATE_CHANGE = 1.5            # block median steps further apart (90th / 10th percentile): the rate varies
UNIFORM_TOLERANCE = 0.01     # a step within 1 % of the period is uniform ...
UNIFORM_SHARE = 0.01         # ... and at most 1 % of the steps may be off
EPOCH_WINDOW_S = (946_684_800.0, 4_102_444_800.0)   # 2000-01-01 .. 2100-01-01
EPOCH_RATE_HZ = (0.01, 1.0e6)                        # steps an epoch column must give


@dataclass(frozen=True)
class TimeUnit:
    name: str
    seconds: float
    aliases: tuple = ()


UNITS = (TimeUnit("s", 1.0, ("sec",)), TimeUnit("ms", 1e-3), TimeUnit("µs", 1e-6, ("us", "μs")),
         TimeUnit("ns", 1e-9))


def time_unit(name, source=None):
    """The :class:`TimeUnit` called ``name`` (s, ms, us/µs, ns); InputError otherwise."""
    for u in UNITS:
        if name == u.name or name in u.aliases:
            return u
    raise InputError(f"unknown time unit {name!r} (use one of s, ms, us, ns)", source)


class UnitRule(Enum):
    """Which rule decided the time unit (the text is the note's)."""
    STATED = "as stated"
    EPOCH = "a Unix epoch"
    NOMINAL = "matching the stated sample rate"
    SPACING = "by its spacing"


class RunStart(Enum):
    """Why a run starts (the note's word)."""
    START = "start"
    GAP = "gap"
    REVERSAL = "reversal"


class TimestampKind(Enum):
    UNIFORM = "uniform"
    JITTERED = "jittered"
    BURSTY = "bursty"
    VARYING = "varying"


@dataclass(frozen=True)
class Gap:
    index: int        # the first sample after the gap
    seconds: float    # the step across it
    missing: int      # samples missing by count
    restarts: bool    # more than MAX_BRIDGED_MISSING missing (and as long a step): a filter restarts


@dataclass(frozen=True)
class Run:
    start: int        # first sample
    stop: int         # one past the last sample
    missing: int      # samples missing in its bridged gaps
    seconds: float    # last time - first time
    cause: RunStart   # why it starts: the record's start, a restarting gap, a time reversal

    @property
    def samples(self):
        return self.stop - self.start


@dataclass(frozen=True, eq=False)
class TimeBase:
    """The time model of one record (see the module docstring for the rules)."""
    n: int
    rate_hz: float             # the rate to use (the stated one when reconciled)
    measured_rate_hz: float    # count over span
    median_rate_hz: float      # 1 / median step (inf when over half the steps are 0)
    unit: TimeUnit
    unit_rule: UnitRule
    epoch: bool
    epoch_offset_s: float | None   # the first timestamp, s since 1970, when epoch
    origin: float              # the first timestamp as read (raw unit)
    kind: TimestampKind
    spread: float              # 95th percentile of |step / period - 1| (0 for uniform)
    repeated: int              # steps of exactly 0
    gap_index: np.ndarray = field(repr=False)     # first sample after each gap
    gap_seconds: np.ndarray = field(repr=False)
    gap_missing: np.ndarray = field(repr=False)
    gap_restarts: np.ndarray = field(repr=False)
    reversals: np.ndarray = field(repr=False)     # first sample after time went back
    runs: tuple = field(repr=False)
    rate_range_hz: tuple | None = None   # VARYING: the block rates' 10th and 90th percentiles
    note: str = ""
    first: object = field(default=None, repr=False)   # the first timestamp as read (exact: an int stays an int)

    @property
    def gaps(self):
        """The gaps as :class:`Gap` objects (built on each call)."""
        return tuple(Gap(int(i), float(s), int(m), bool(r)) for i, s, m, r in
                     zip(self.gap_index, self.gap_seconds, self.gap_missing, self.gap_restarts))

    @property
    def restarts(self):
        """Sample indices where a run starts after the first (sorted)."""
        return np.array([r.start for r in self.runs[1:]], dtype=np.int64)

    @property
    def missing(self):
        return int(self.gap_missing.sum())

    def seconds(self, t):
        """The column ``t`` in seconds: since the first sample for an epoch column,
        else the column's own zero (a boot time stays a boot time)."""
        t = np.asarray(t)
        if self.epoch:
            return _relative(t) * self.unit.seconds
        return t.astype(np.float64) * self.unit.seconds

    def seconds_of_chunk(self, t):
        """:meth:`seconds` of a chunk ``t`` of the column (the same numbers, bit for bit, as
        the whole column's at those samples: an epoch column is counted from the record's
        first sample, not the chunk's)."""
        t = np.asarray(t)
        if self.epoch:
            return _relative_to(t, self.first, _exact_int(t)) * self.unit.seconds
        return t.astype(np.float64) * self.unit.seconds

    def restarts_in(self, a, b):
        """Bool (b - a,): :func:`restart_mask` over samples a..b-1."""
        mask = np.zeros(b - a, dtype=bool)
        r = self.restarts
        r = r[(r >= a) & (r < b)]
        mask[r - a] = True
        return mask


def restart_mask(tb):
    """Bool (n,): True at the first sample of each run after the first (a time
    reversal, or a gap of more than MAX_BRIDGED_MISSING missing samples and as
    long a step); the convention of ``GyroStream.restarts`` and ``Record.restarts``."""
    mask = np.zeros(tb.n, dtype=bool)
    mask[tb.restarts] = True
    return mask


#: steps per chunk of the time analysis (its memory; the results do not depend on it)
CHUNK_STEPS = 1 << 20


class TimeColumn:
    """A timestamp column read a chunk at a time: ``n`` values, the first as read, and
    ``read(a, b)`` giving the values a..b-1 as read (int64 or float64). The analysis holds
    a chunk of ``chunk`` steps, never the column (:func:`analyse_column`)."""

    def __init__(self, n, first, read, chunk=None, exact_int=None):
        self.n = int(n)
        self.first = first
        self._read = read
        self.chunk = max(1, int(chunk or CHUNK_STEPS))
        self.exact_int = np.asarray(first).dtype.kind == "i" if exact_int is None else bool(exact_int)

    @classmethod
    def of_array(cls, t, chunk=None):
        """The column of a whole array ``t`` (1-D, numbers)."""
        return cls(t.size, t[0], lambda a, b: t[a:b], chunk, _exact_int(t))

    def raw_chunks(self):
        for a in range(0, self.n, self.chunk):
            yield a, self._read(a, min(a + self.chunk, self.n))

    def rel(self, a, b):
        """t[a:b] - t[0], float64 (exact for integer columns)."""
        return _relative_to(self._read(a, b), self.first, self.exact_int)

    def take(self, idx):
        """t[idx] - t[0] for a few indices."""
        idx = np.asarray(idx, dtype=np.int64)
        out = np.empty(idx.size)
        for j, i in enumerate(idx):
            out[j] = self.rel(int(i), int(i) + 1)[0]
        return out

    def steps(self):
        """(a, t[a+1:b+1] - t[a:b]) over the n - 1 steps, a chunk at a time."""
        for a in range(0, self.n - 1, self.chunk):
            b = min(a + self.chunk, self.n - 1)
            yield a, np.diff(self.rel(a, b + 1))


def _exact_int(t):
    """Whether an integer column is counted from its first value in integers (int64)."""
    t = np.asarray(t)
    return t.dtype.kind == "i" or (t.dtype.kind == "u" and t.size > 0 and int(t.max()) < 2 ** 63)


def analyse_time(t, *, unit=None, nominal_rate=None, name="time column", source=None, chunk=None):
    """The :class:`TimeBase` of the timestamp column ``t``.

    unit : str, optional
        s, ms, us (µs) or ns; wins over detection.
    nominal_rate : float, optional
        A stated sample rate (Hz), used when within NOMINAL_TOLERANCE of the
        record's count over span; InputError otherwise.
    name, source : str
        What the error messages call the column and the file.
    chunk : int, optional
        Steps per chunk of the analysis (:func:`analyse_column`; the result does not
        depend on it).
    """
    def fail(msg):
        raise InputError(f"{name}: {msg}", source)

    t = np.asarray(t)
    if t.dtype.kind == "b":
        fail("values are booleans, not times")
    if t.dtype.kind not in "iuf":
        try:
            t = t.astype(np.float64)
        except (TypeError, ValueError):
            fail(f"values are not numbers (dtype {t.dtype})")
    t = t.ravel()
    if t.size < 2:
        fail(f"{t.size} sample(s); at least 2 are needed")
    return analyse_column(TimeColumn.of_array(t, chunk), unit=unit, nominal_rate=nominal_rate, name=name,
                          source=source)


def analyse_column(col, *, unit=None, nominal_rate=None, name="time column", source=None):
    """The :class:`TimeBase` of a :class:`TimeColumn` (at least 2 values), read a chunk at
    a time: a few passes over the column, each holding one chunk of steps and what the
    model keeps (block statistics: one value per block of 256 steps; an evenly spread
    sample of at most about 4 M steps for the median; the gap candidates)."""
    def fail(msg):
        raise InputError(f"{name}: {msg}", source)

    stated = time_unit(unit, source) if unit is not None else None
    nominal = _check_nominal(nominal_rate, source)
    n = col.n
    if n < 2:
        fail(f"{n} sample(s); at least 2 are needed")
    bad_count, bad_first = 0, None
    for a, raw in col.raw_chunks():
        if raw.dtype.kind == "f":
            bad = ~np.isfinite(raw)
            if bad.any():
                if bad_first is None:
                    i = int(np.argmax(bad))
                    bad_first = (a + i, raw[i])
                bad_count += int(bad.sum())
    if bad_first is not None:
        fail(f"{bad_count:,} value(s) not finite (first at sample {bad_first[0]:,}: {bad_first[1]})")
    back_idx, forward, repeated = [], False, 0
    for a, dt in col.steps():
        back_idx.append(np.flatnonzero(dt < 0) + a)
        forward = forward or bool((dt > 0).any())
        repeated += int(np.count_nonzero(dt == 0))
    back_idx = np.concatenate(back_idx).astype(np.int64)
    if not forward:
        if back_idx.size:
            fail("time never advances (it only goes back: reversed order?)")
        fail(f"all {n:,} timestamps are equal ({col.first}): no time base")

    period, med, pattern, steps = _first_period(col, n - 1 - back_idx.size)
    if pattern is TimestampKind.VARYING:
        period = _local_period(col)
    for _ in range(PASSES):   # again with the period from count over span, while it moves
        gaps = _find_gaps(col, period, pattern)
        runs, count, span = _runs(col, back_idx, gaps)
        if span <= 0:
            fail("time never advances within a run")
        if pattern is TimestampKind.VARYING:         # judged against the blocks' own steps
            break
        moved = abs(span / count / period - 1.0)
        period = span / count
        if moved < 1e-4:
            break
    period = span / count
    kind, spread = _kind(col, back_idx.size, gaps, period, pattern)

    t0 = float(col.first)
    uobj, rule, alt = _decide_unit(stated, nominal, period, t0)
    rate = 1.0 / (period * uobj.seconds)
    epoch = _is_epoch(t0, uobj)
    used = rate
    if nominal is not None:
        if abs(nominal / rate - 1.0) > NOMINAL_TOLERANCE:
            fail(f"the stated sample rate {nominal:g} Hz and the record's {rate:.6g} Hz (time in "
                 f"{uobj.name}, {n:,} samples over {span * uobj.seconds:.4g} s) differ by more than "
                 f"{NOMINAL_TOLERANCE:.0%}")
        used = float(nominal)
    gi, gm, gr, gdt = gaps
    run_objs = tuple(Run(int(a), int(b), int(m), float(s * uobj.seconds), c) for a, b, m, s, c in runs)
    tb = TimeBase(
        n=n, rate_hz=float(used), measured_rate_hz=float(rate),
        median_rate_hz=(math.inf if med == 0 else 1.0 / (med * uobj.seconds)),
        unit=uobj, unit_rule=rule, epoch=epoch,
        epoch_offset_s=(t0 * uobj.seconds if epoch else None), origin=t0, kind=kind,
        spread=spread, repeated=repeated,
        gap_index=gi + 1, gap_seconds=gdt * uobj.seconds, gap_missing=gm, gap_restarts=gr,
        reversals=back_idx + 1, runs=run_objs,
        rate_range_hz=(None if steps is None else (1.0 / (steps[1] * uobj.seconds), 1.0 / (steps[0] * uobj.seconds))),
        first=col.first)
    return _with_note(tb, med * uobj.seconds, span * uobj.seconds, alt, nominal)


def _check_nominal(nominal_rate, source):
    if nominal_rate is None:
        return None
    try:
        v = float(nominal_rate)
    except (TypeError, ValueError):
        raise InputError(f"the stated sample rate {nominal_rate!r} is not a number", source) from None
    if not (math.isfinite(v) and 0.0 < v <= MAX_RATE_HZ):
        raise InputError(f"the stated sample rate {v:g} Hz is not a sample rate (it must be above 0 and "
                         f"at most {MAX_RATE_HZ:g} Hz)", source)
    return v


def _relative(t):
    """t - t[0] as float64, exact for integer columns (ns since 1970 has 19 digits)."""
    return _relative_to(t, t[0], _exact_int(t))


def _relative_to(t, t0, exact_int):
    if exact_int:
        return (t.astype(np.int64) - np.int64(t0)).astype(np.float64)
    return t.astype(np.float64) - np.float64(t0)


#: the median step is read from an evenly spread sample of at most about this many steps x 2
MEDIAN_SAMPLE = 2_000_000


def _first_period(col, fsize):
    """(a first period, the median step, the pattern, the block rates' 10th and 90th
    percentiles or None) in the raw unit, from the ``fsize`` forward steps (those not
    going back). The pattern: VARYING when the median steps of blocks differ
    by more than RATE_CHANGE (over at least MIN_BURST_BLOCKS blocks), BURSTY when
    the median block mean is more than BURST_RATIO x the median step (over as
    many blocks: a few steps and a long one are a gap), else UNIFORM (uniform or
    jittered, told later). The first period is the median step (of those within
    0.5-1.5x the median), or for bursts the median block mean. The median step is
    that of every step up to 2 x MEDIAN_SAMPLE steps, beyond of an evenly spread
    sample of 2 to 4 M of them (every s-th)."""
    k = _block(fsize)
    nb = fsize // k
    s = max(1, fsize // MEDIAN_SAMPLE)
    means, meds, some = [], [], []
    rest = np.empty(0)
    seen = done = 0
    for _, dt in col.steps():
        f = dt[dt >= 0]
        some.append(f[(-seen) % s::s].copy())      # a copy: a view would hold the whole chunk
        seen += f.size
        cat = np.concatenate([rest, f]) if rest.size else f
        take = min(cat.size // k, nb - done) * k
        if take:
            b = cat[:take].reshape(-1, k)
            means.append(b.mean(axis=1))
            meds.append(np.median(b, axis=1))
            done += take // k
        rest = cat[take:]
    some = np.concatenate(some)
    means = np.concatenate(means) if means else np.empty(0)
    meds = np.concatenate(meds) if meds else np.empty(0)
    mean = float(rest.mean()) if not nb else (math.fsum(means) * k + math.fsum(rest)) / fsize
    blk = float(np.median(means)) if nb else mean
    lo = hi = None
    if nb >= MIN_BURST_BLOCKS:
        lo, hi = np.quantile(meds[::max(1, nb // 1024)], [0.1, 0.9])   # at most about 2,000 blocks
    med = float(np.median(some))
    if lo is not None and lo > 0 and hi > RATE_CHANGE * lo:
        return med, med, TimestampKind.VARYING, (float(lo), float(hi))
    if med > 0 and (blk <= BURST_RATIO * med or nb < MIN_BURST_BLOCKS):
        # steps of missing samples (2 periods and more) lift the median: the median
        # of the steps within 0.5-1.5x the median (a symmetric cut of the jitter)
        mid = some[(some > 0.5 * med) & (some < 1.5 * med)]
        return (float(np.median(mid)) if mid.size else med), med, TimestampKind.UNIFORM, None
    return (blk if blk > 0 else mean), med, TimestampKind.BURSTY, None


class _LocalPeriod:
    """Per step, the median step of its block (blocks of ``k`` steps; the last block takes
    what is left): the period of a record whose rate varies."""

    def __init__(self, meds, k):
        self.meds, self.k = meds, k

    def at(self, a, b):
        return self.meds[np.arange(a, b) // self.k]

    def take(self, idx):
        return self.meds[np.asarray(idx) // self.k]


def _local_period(col):
    k = _block(col.n - 1)
    meds = []
    rest = np.empty(0)
    for _, dt in col.steps():
        x = np.where(dt >= 0, dt, np.nan)
        cat = np.concatenate([rest, x]) if rest.size else x
        take = cat.size // k * k
        if take:
            meds.append(np.nanmedian(cat[:take].reshape(-1, k), axis=1))
        rest = cat[take:]
    if rest.size:
        meds.append(np.nanmedian(rest.reshape(1, -1), axis=1))
    return _LocalPeriod(np.concatenate(meds), k)


def _per(period, a, b):
    return period if np.ndim(period) == 0 and not isinstance(period, _LocalPeriod) else period.at(a, b)


def _block(n_steps):
    return int(min(256, max(8, n_steps // 32)))


def _sliding_min(x, w, inplace=False):
    """min(x[i:i+w]) for every i, windows clipped at the end (doubling: O(n log w))."""
    m = x if inplace else x.copy()
    k = 1
    while 2 * k <= w:
        np.minimum(m[:-k], m[k:], out=m[:-k])
        k *= 2
    if k < w:
        d = w - k
        np.minimum(m[:-d], m[d:], out=m[:-d])
    return m


def _clock(col, period):
    """The sample clock E = time / period - sample number (a reversal adds nothing), a
    chunk at a time: (first index, E there); one running sum over the record (the chunks'
    sums carried), so every value is that of the one sum over the whole record."""
    carry = None
    for a, dt in col.steps():
        x = np.empty(dt.size + 1)
        np.divide(dt, _per(period, a, a + dt.size), out=x[1:])
        x[1:] -= 1.0
        x[1:][dt < 0] = 0.0
        if carry is None:
            x[0] = 0.0
            np.cumsum(x[1:], out=x[1:])
            yield 0, x
        else:
            x[0] = carry
            np.cumsum(x, out=x)
            yield a + 1, x[1:]
        carry = x[-1]


def _windowed(chunks, n, before, after):
    """(j0, j1, buf, start) over consecutive chunks (start, values) of a series of n
    values: buf holds the series from ``start`` and covers j0 - before .. j1 + after
    (clipped to the series)."""
    buf, start, done = np.empty(0), 0, 0
    for _, x in chunks:
        buf = np.concatenate([buf, x]) if buf.size else x
        end = start + buf.size
        ready = n if end >= n else end - after
        if ready > done:
            yield done, ready, buf, start
            done = ready
        keep = max(start, done - before)
        buf, start = buf[keep - start:], keep


def _envelope(x, at_start, at_end):
    """Each value of x below both neighbours raised to the lower of them (the ends of the
    record kept as they are; the ends of x otherwise not used)."""
    f = x.copy()
    if x.size > 2:
        np.maximum(f[1:-1], np.minimum(x[:-2], x[2:]), out=f[1:-1])
    if at_start:
        f[0] = x[0]
    if at_end:
        f[-1] = x[-1]
    return f


def _levels(col, period, js, w):
    """lvl[js] (js sorted, unique): the minimum over the next ``w`` samples (clipped at
    the end) of the lower envelope of the sample clock."""
    n = col.n
    out = np.empty(js.size)
    for j0, j1, buf, start in _windowed(_clock(col, period), n, 1, w + 1):
        a, b = np.searchsorted(js, [j0, j1])
        if a == b:
            continue
        sel = js[a:b]
        lo, hi = int(sel[0]), min(int(sel[-1]) + w, n)
        xlo, xhi = max(lo - 1, 0), min(hi + 1, n)
        env = _envelope(buf[xlo - start:xhi - start], xlo == 0, xhi == n)
        seg = env[lo - xlo:hi - xlo]
        if sel.size * w <= 4 * seg.size:
            idx = np.minimum((sel - lo)[:, None] + np.arange(w), seg.size - 1)
            out[a:b] = seg[idx].min(axis=1)
        else:
            out[a:b] = _sliding_min(seg, w, inplace=True)[sel - lo]
    return out


def _clock_ranges(col, period, lo, hi):
    """[E[lo[i]:hi[i]] for each i] (ranges of at most a few windows), one pass."""
    n = col.n
    order = np.argsort(lo, kind="stable")
    slo = lo[order]
    longest = int((hi - lo).max()) if lo.size else 0
    got = [np.empty(int(h - l_)) for l_, h in zip(lo, hi)]
    for a, x in _clock(col, period):
        b = a + x.size
        i0, i1 = np.searchsorted(slo, [a - longest, b])
        for i in order[i0:i1]:
            l_, h = int(lo[i]), int(hi[i])
            s, e = max(l_, a), min(h, b)
            if s < e:
                got[i][s - l_:e - l_] = x[s - a:e - a]
    del n
    return got


def _envelope_min_of(x, lo, hi, n, a, b):
    """min over E[a:b] of the lower envelope, from x = E[lo:hi] (lo = max(a - 1, 0),
    hi = min(b + 1, n)), as the sliding windows see it."""
    f = _envelope(x, lo == 0, hi == n)
    return float(f[a - lo:a - lo + (b - a)].min())


def _env_range(a, b, n):
    return max(a - 1, 0), min(b + 1, n)


def _candidates(col, period):
    """(step indices, steps, period there) of the steps of at least GAP_CANDIDATE periods."""
    idx, dts, per = [], [], []
    for a, dt in col.steps():
        p = _per(period, a, a + dt.size)
        c = np.flatnonzero(dt >= GAP_CANDIDATE * p)
        idx.append(c + a)
        dts.append(dt[c])
        per.append(np.broadcast_to(p, dt.shape)[c])
    return (np.concatenate(idx).astype(np.int64), np.concatenate(dts), np.concatenate(per))


def _find_gaps(col, period, pattern):
    """(step indices, samples missing, restarts, steps) of the gaps (module docstring)."""
    cand, cdt, cper = _candidates(col, period)
    empty = (np.empty(0, np.int64), np.empty(0, np.int64), np.empty(0, bool), np.empty(0))
    if not cand.size:
        return empty
    n = col.n
    excess = cdt / cper - 1.0
    w = LEVEL_WINDOW
    bursty = pattern is TimestampKind.BURSTY
    if bursty:                          # a window spans several bursts
        cycle = (n - 1) / max(1, cand.size)
        w = int(min(1024, max(w, math.ceil(BURST_WINDOW_CYCLES * cycle))))
    # the lower envelope, blind to one early stamp (a repeated timestamp): a sample
    # below both neighbours is raised to the lower of them, then the window's min
    k = cand + 1
    kb = np.maximum(k - w, 0)
    js = np.unique(np.concatenate([k, kb]))
    lv = _levels(col, period, js, w)
    after = lv[np.searchsorted(js, k)]              # e[k+1 .. k+w]
    before = lv[np.searchsorted(js, kb)]            # e[k+1-w .. k]
    if not bursty:
        keep = _gaps_in_clusters(col, period, cand, after, before, w, excess)
    else:
        keep = _gaps_in_bursts(col, period, cand, after, before, w, excess)
    if keep is None:
        return empty
    sel, gm = keep
    # a restart needs the step itself to span the missing samples too: drops inside
    # bursts add up in the sample clock without a long step, and are no break
    return cand[sel], gm, np.minimum(gm, np.rint(excess[sel])) > MAX_BRIDGED_MISSING, cdt[sel]


def _gaps_in_bursts(col, period, cand, after, before, w, excess):
    """Gaps among bursts: (indices into cand, samples missing) or None."""
    # a window cut short (an end of the record, or the next step that rises) sees too
    # little of the stamps' scatter: with bursts it may hold only the top of one, so
    # its level is taken down by the sample clock's typical range over a window
    n = col.n
    rises = after - _level_before(cand, after, before, after - before, w) >= 0.5
    room = np.full(cand.size, n)
    nxt = np.flatnonzero(rises)
    if nxt.size:
        j = np.searchsorted(nxt, np.arange(cand.size), side="right")
        has = j < nxt.size
        room[has] = cand[nxt[j[has]]] + 1
    h = np.minimum(np.minimum(room - cand - 1, cand + 1), w)
    short = np.flatnonzero(h < w)
    if short.size:
        step = max(1, cand.size // 1000)                 # the range over at most about 2,000 windows
        at = cand[::step] + 1
        lvl_at = after[::step].copy()
        ks = cand[short] + 1
        hs = np.maximum(1, h[short])
        s_lo, s_hi = np.maximum(ks - 1, 0), np.minimum(ks + hs + 1, n)
        got = _clock_ranges(col, period, np.concatenate([at, s_lo]), np.concatenate([np.minimum(at + w, n), s_hi]))
        scatter = float(np.median(np.array([g.max() for g in got[:at.size]]) - lvl_at))
        for i, j in enumerate(short):
            kj = int(ks[i])
            after[j] = _envelope_min_of(got[at.size + i], int(s_lo[i]), int(s_hi[i]), n, kj, kj + int(hs[i])) - scatter
    rise = after - _level_before(cand, after, before, after - before, w)
    resid = rise - np.rint(rise)
    noise = 1.4826 * float(np.median(np.abs(resid)))
    missing = np.rint(rise)
    keep = (rise >= max(0.5, NOISE_SIGMAS * noise)) & (missing >= 1)
    if not keep.any():
        return None
    return np.flatnonzero(keep), missing[keep].astype(np.int64)


def _gaps_in_clusters(col, period, cand, after, before, w, excess):
    """Gaps without bursts: (indices into cand, samples missing) or None. Candidate
    steps less than ``w`` samples apart form a
    cluster, whose level before is that before its first step. Each step's rise
    is the level after it less the level after the cluster's previous step; a
    rise of at least max(0.5, NOISE_SIGMAS x the scatter about whole numbers of
    the rises of lone steps) counts: its samples missing are the rounded level from the cluster's
    start, less the count already given in the cluster (two drops a few samples
    apart are counted once each; a clock that slips by parts of a period, not
    whole samples, has rises that are no whole numbers: they do not count). Within
    ``w`` samples of an end of the record the windows are as long as the record
    allows and the level after is taken down by the stamps' scatter over a
    window (a gap there must stand out of it)."""
    n = col.n
    k = cand + 1
    edge = np.flatnonzero((k < w) | (k + w > n))
    if edge.size:
        at = np.arange(0, k.size, max(1, k.size // 1000))
        ka = k[at]
        ke = k[edge]
        he = np.maximum(1, np.minimum(np.minimum(w, ke), n - ke))
        a_lo, a_hi = np.maximum(ke - 1, 0), np.minimum(ke + he + 1, n)
        bs = np.maximum(0, ke - w)
        b_lo, b_hi = np.maximum(bs - 1, 0), np.minimum(ke + 1, n)
        got = _clock_ranges(col, period, np.concatenate([ka, a_lo, b_lo]),
                            np.concatenate([np.minimum(ka + w, n), a_hi, b_hi]))
        m = at.size
        scatter = float(np.median(np.array([g.max() for g in got[:m]]) - after[at]))
        for i, j in enumerate(edge):
            kj = int(ke[i])
            after[j] = _envelope_min_of(got[m + i], int(a_lo[i]), int(a_hi[i]), n, kj, kj + int(he[i])) - scatter
            before[j] = _envelope_min_of(got[m + edge.size + i], int(b_lo[i]), int(b_hi[i]), n, int(bs[i]), kj)
    first = np.concatenate([[True], np.diff(cand) >= w])
    cluster = np.cumsum(first) - 1
    x = after - before[first][cluster]             # the level from the cluster's start
    rise = x - np.concatenate([[0.0], x[:-1]])
    rise[first] = x[first]
    alone = first & np.concatenate([first[1:], [True]])   # clusters of one step: clean windows
    judge = rise[alone] if alone.any() else rise
    off = float(np.median(np.abs(judge - np.rint(judge))))
    # a clock locked to whole samples: lone rises near whole numbers, any missing
    # sample counts; else (a loop that slips by parts of a period) only a rise out
    # of the scatter does
    counts = rise >= (0.5 if off < LOCKED else max(0.5, NOISE_SIGMAS * 1.4826 * off))
    level = np.where(counts, np.maximum(np.rint(x), 0.0), 0.0)
    # the count given so far within each cluster (it never falls)
    big = float(level.max()) + 1.0
    level = np.maximum.accumulate(cluster * big + level) - cluster * big
    missing = level - np.concatenate([[0.0], level[:-1]])
    missing[first] = level[first]
    keep = missing >= 1
    if not keep.any():
        return None
    return np.flatnonzero(keep), np.rint(missing[keep]).astype(np.int64)


def _level_before(cand, after, before, rise, w):
    """The level before each candidate step: where an earlier candidate within the
    window before rose (``rise`` >= 0.5), the level after that one."""
    pos = np.flatnonzero(rise >= 0.5)
    if not pos.size:
        return before
    prev = np.full(cand.size, -1)
    prev[pos] = pos
    prev = np.maximum.accumulate(np.concatenate([[-1], prev[:-1]]))
    has = (prev >= 0) & (cand - cand[np.maximum(prev, 0)] < w)
    return np.maximum(before, np.where(has, after[np.maximum(prev, 0)], -np.inf))


def _runs(col, back_idx, gaps):
    """([(start, stop, bridged missing, span, cause)], intervals + bridged missing, span) in the raw unit."""
    gi, gm, gr, _ = gaps
    cuts = np.concatenate([back_idx + 1, gi[gr] + 1])
    is_gap = np.concatenate([np.zeros(back_idx.size, bool), np.ones(int(gr.sum()), bool)])
    order = np.argsort(cuts, kind="stable")
    cuts, is_gap = cuts[order], is_gap[order]
    starts = np.concatenate([[0], cuts]).astype(np.int64)
    stops = np.concatenate([cuts, [col.n]]).astype(np.int64)
    spans = col.take(stops - 1) - col.take(starts)
    bridged = ~gr
    run_of = np.searchsorted(starts, gi[bridged] + 1, side="right") - 1
    miss = np.bincount(run_of, weights=gm[bridged], minlength=starts.size).astype(np.int64)
    count = float(np.sum(stops - starts - 1) + miss.sum())
    cause = [RunStart.START] + [RunStart.GAP if g else RunStart.REVERSAL for g in is_gap]
    runs = list(zip(starts, stops, miss, spans, cause))
    return runs, count, float(spans.sum())


#: the spread (95th percentile) is read from an evenly spread sample of at most this many steps
SPREAD_SAMPLE = 1_000_000


def _kind(col, nback, gaps, period, pattern):
    """(TimestampKind, spread): module docstring."""
    gi = gaps[0]
    size = col.n - 1 - nback - gi.size      # the steps neither going back nor gaps
    if size <= 0:
        return TimestampKind.UNIFORM, 0.0
    s = -(-size // SPREAD_SAMPLE)
    sub, off, seen = [], 0, 0
    for a, dt in col.steps():
        ok = dt >= 0
        g = gi[(gi >= a) & (gi < a + dt.size)] - a
        ok[g] = False
        r = dt[ok]
        r /= period
        r -= 1.0
        np.abs(r, out=r)
        off += int(np.count_nonzero(r > UNIFORM_TOLERANCE))
        sub.append(r[(-seen) % s::s].copy())      # a copy: a view would hold the whole chunk
        seen += r.size
    sub = np.concatenate(sub)
    k95 = min(sub.size - 1, int(0.95 * sub.size))
    spread = float(np.partition(sub, k95)[k95])
    if pattern is not TimestampKind.UNIFORM:
        return pattern, spread
    if off > UNIFORM_SHARE * size:
        return TimestampKind.JITTERED, spread
    return TimestampKind.UNIFORM, spread


def _is_epoch(t0, u):
    lo, hi = EPOCH_WINDOW_S
    return lo <= t0 * u.seconds <= hi


def _decide_unit(stated, nominal, period, t0):
    """(unit, rule, the other plausible unit or None) for a period in the raw unit."""
    if stated is not None:
        return stated, UnitRule.STATED, None
    rates = [1.0 / (period * u.seconds) for u in UNITS]
    for u, r in zip(UNITS, rates):
        if _is_epoch(t0, u) and EPOCH_RATE_HZ[0] <= r <= EPOCH_RATE_HZ[1]:
            return u, UnitRule.EPOCH, None
    if nominal is not None:
        fits = [u for u, r in zip(UNITS, rates) if abs(nominal / r - 1.0) <= NOMINAL_TOLERANCE]
        if len(fits) == 1:
            return fits[0], UnitRule.NOMINAL, None
    if period < 1.0:
        return UNITS[0], UnitRule.SPACING, None
    for i in range(1, len(UNITS)):
        if rates[i] >= MIN_SPACING_RATE_HZ or i == len(UNITS) - 1:
            other = UNITS[i - 1] if rates[i - 1] >= 0.5 else None
            return UNITS[i], UnitRule.SPACING, other


def _count(n, word):
    return f"{n:,} {word}{'' if n == 1 else 's'}"


def _with_note(tb, med_s, span_s, alt, nominal):
    u = tb.unit
    head = f"time column in {u.name} ({tb.unit_rule.value}"
    if tb.epoch:
        when = datetime.fromtimestamp(tb.epoch_offset_s, timezone.utc).strftime("%Y-%m-%d %H:%M:%S UTC")
        head += f" from {when}" if tb.unit_rule is UnitRule.EPOCH else f", epoch from {when}"
    head += f"; median step {med_s / u.seconds:.6g} {u.name})"
    what = f"{tb.n:,} samples over {span_s:.1f} s" if span_s >= 10 else f"{tb.n:,} samples over {span_s:.4g} s"
    if len(tb.runs) > 1:
        what += f" in {len(tb.runs)} runs"
    if nominal is not None:
        head += f": rate {tb.rate_hz:.6g} Hz as stated (the record gives {tb.measured_rate_hz:.6g} Hz from {what})"
    else:
        head += f": rate {tb.rate_hz:.6g} Hz from {what}"
    parts = [head]
    if tb.kind is TimestampKind.BURSTY:
        med = "infinite" if math.isinf(tb.median_rate_hz) else f"{tb.median_rate_hz:.4g} Hz"
        parts.append(f"host-stamped bursts (1/median step would say {med}); bursts do not restart the filter")
    elif tb.kind is TimestampKind.JITTERED:
        parts.append(f"jittered timestamps (95 % of steps within ±{tb.spread:.0%} of the period; "
                     f"1/median step {tb.median_rate_hz:.4g} Hz); jitter does not restart the filter")
    elif tb.kind is TimestampKind.VARYING:
        lo, hi = tb.rate_range_hz
        parts.append(f"the rate varies along the record ({lo:.4g} to {hi:.4g} Hz over blocks of steps): the rate "
                     f"given is the mean; gaps are judged against each block's median step")
    else:
        parts.append("uniform steps")
    if tb.repeated and tb.kind is not TimestampKind.BURSTY:
        parts.append(f"{_count(tb.repeated, 'repeated timestamp')} (kept)")
    bridged = ~tb.gap_restarts
    if bridged.any():
        parts.append(f"{_count(int(bridged.sum()), 'short gap')} ({_count(int(tb.gap_missing[bridged].sum()), 'sample')} "
                     f"missing) bridged: no restart")
    if tb.gap_restarts.any():
        j = int(np.argmax(np.where(tb.gap_restarts, tb.gap_seconds, -np.inf)))
        parts.append(f"{_count(int(tb.gap_restarts.sum()), 'gap')} of more than {MAX_BRIDGED_MISSING} missing samples "
                     f"({int(tb.gap_missing[tb.gap_restarts].sum()):,} missing; longest {tb.gap_seconds[j]:.4g} s "
                     f"before sample {int(tb.gap_index[j]):,}) restart the filter")
    if tb.reversals.size:
        parts.append(f"{_count(int(tb.reversals.size), 'time reversal')} (first before sample "
                     f"{int(tb.reversals[0]):,}) restart the filter")
    if len(tb.runs) > 1:
        shown = " | ".join(f"{r.samples:,}" for r in tb.runs[:4])
        more = f" | ... (shortest {min(r.samples for r in tb.runs):,})" if len(tb.runs) > 4 else ""
        parts.append(f"runs of {shown}{more} samples")
    if alt is not None:
        parts.append(f"read as {alt.name} it would be {tb.measured_rate_hz * u.seconds / alt.seconds:.3g} Hz: "
                     f"state the unit if so")
    return replace(tb, note="; ".join(parts))
