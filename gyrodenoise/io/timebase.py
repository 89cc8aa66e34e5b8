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


def restart_mask(tb):
    """Bool (n,): True at the first sample of each run after the first (a time
    reversal, or a gap of more than MAX_BRIDGED_MISSING missing samples and as
    long a step); the convention of ``GyroStream.restarts`` and ``Record.restarts``."""
    mask = np.zeros(tb.n, dtype=bool)
    mask[tb.restarts] = True
    return mask


def analyse_time(t, *, unit=None, nominal_rate=None, name="time column", source=None):
    """The :class:`TimeBase` of the timestamp column ``t``.

    unit : str, optional
        s, ms, us (µs) or ns; wins over detection.
    nominal_rate : float, optional
        A stated sample rate (Hz), used when within NOMINAL_TOLERANCE of the
        record's count over span; InputError otherwise.
    name, source : str
        What the error messages call the column and the file.
    """
    def fail(msg):
        raise InputError(f"{name}: {msg}", source)

    stated = time_unit(unit, source) if unit is not None else None
    nominal = _check_nominal(nominal_rate, source)
    t = np.asarray(t)
    if t.dtype.kind == "b":
        fail("values are booleans, not times")
    if t.dtype.kind not in "iuf":
        try:
            t = t.astype(np.float64)
        except (TypeError, ValueError):
            fail(f"values are not numbers (dtype {t.dtype})")
    t = t.ravel()
    n = t.size
    if n < 2:
        fail(f"{n} sample(s); at least 2 are needed")
    if t.dtype.kind == "f":
        bad = ~np.isfinite(t)
        if bad.any():
            i = int(np.argmax(bad))
            fail(f"{int(bad.sum()):,} value(s) not finite (first at sample {i:,}: {t[i]})")
    rel = _relative(t)
    dt = np.diff(rel)
    back = dt < 0
    if not (dt > 0).any():
        if back.any():
            fail("time never advances (it only goes back: reversed order?)")
        fail(f"all {n:,} timestamps are equal ({t[0]}): no time base")

    fwd = dt[~back]
    period, med, pattern, steps = _first_period(fwd)
    del fwd
    if pattern is TimestampKind.VARYING:
        period = _local_period(dt)
    for _ in range(PASSES):   # again with the period from count over span, while it moves
        gaps = _find_gaps(dt, back, period, pattern)
        runs, count, span = _runs(rel, dt, back, gaps)
        if span <= 0:
            fail("time never advances within a run")
        if pattern is TimestampKind.VARYING:         # judged against the blocks' own steps
            break
        moved = abs(span / count / period - 1.0)
        period = span / count
        if moved < 1e-4:
            break
    period = span / count
    kind, spread = _kind(dt, back, gaps, period, pattern)

    t0 = float(t[0])
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
    gi, gm, gr = gaps
    run_objs = tuple(Run(int(a), int(b), int(m), float(s * uobj.seconds), c) for a, b, m, s, c in runs)
    tb = TimeBase(
        n=n, rate_hz=float(used), measured_rate_hz=float(rate),
        median_rate_hz=(math.inf if med == 0 else 1.0 / (med * uobj.seconds)),
        unit=uobj, unit_rule=rule, epoch=epoch,
        epoch_offset_s=(t0 * uobj.seconds if epoch else None), origin=t0, kind=kind,
        spread=spread, repeated=int(np.count_nonzero(dt == 0)),
        gap_index=gi + 1, gap_seconds=dt[gi] * uobj.seconds, gap_missing=gm, gap_restarts=gr,
        reversals=np.flatnonzero(back) + 1, runs=run_objs,
        rate_range_hz=(None if steps is None else (1.0 / (steps[1] * uobj.seconds), 1.0 / (steps[0] * uobj.seconds))))
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
    if t.dtype.kind in "iu" and (t.dtype.kind == "i" or int(t.max()) < 2 ** 63):
        return (t.astype(np.int64) - np.int64(t[0])).astype(np.float64)
    return t.astype(np.float64) - np.float64(t[0])


def _first_period(fwd):
    """(a first period, the median step, the pattern, the block rates' 10th and 90th
    percentiles or None) in the raw unit, from the forward steps ``fwd`` (a copy:
    reordered here). The pattern: VARYING when the median steps of blocks differ
    by more than RATE_CHANGE (over at least MIN_BURST_BLOCKS blocks), BURSTY when
    the median block mean is more than BURST_RATIO x the median step (over as
    many blocks: a few steps and a long one are a gap), else UNIFORM (uniform or
    jittered, told later). The first period is the median step (of those within
    0.5-1.5x the median), or for bursts the median block mean."""
    k = _block(fwd.size)
    nb = fwd.size // k
    mean = float(fwd.mean())
    blocks = fwd[:nb * k].reshape(nb, k)
    blk = float(np.median(blocks.mean(axis=1))) if nb else mean
    lo = hi = None
    if nb >= MIN_BURST_BLOCKS:
        sample = blocks[::max(1, nb // 1024)]          # at most about 2,000 blocks, evenly spread
        lo, hi = np.quantile(np.median(sample, axis=1), [0.1, 0.9])
    med = float(np.median(fwd, overwrite_input=True))
    if lo is not None and lo > 0 and hi > RATE_CHANGE * lo:
        return med, med, TimestampKind.VARYING, (float(lo), float(hi))
    if med > 0 and (blk <= BURST_RATIO * med or nb < MIN_BURST_BLOCKS):
        # steps of missing samples (2 periods and more) lift the median: the median
        # of the steps within 0.5-1.5x the median (a symmetric cut of the jitter)
        some = fwd[::max(1, fwd.size // 2_000_000)]          # at most about 4 M steps, evenly spread
        mid = some[(some > 0.5 * med) & (some < 1.5 * med)]
        return (float(np.median(mid)) if mid.size else med), med, TimestampKind.UNIFORM, None
    return (blk if blk > 0 else mean), med, TimestampKind.BURSTY, None


def _local_period(dt):
    """Per step, the median step of its block (BLOCK steps; the last block takes
    what is left): the period of a record whose rate varies."""
    k = _block(dt.size)
    nb = -(-dt.size // k)
    pad = np.full(nb * k, np.nan)
    pad[:dt.size] = np.where(dt >= 0, dt, np.nan)
    meds = np.nanmedian(pad.reshape(nb, k), axis=1)
    return np.repeat(meds, k)[:dt.size]


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


def _find_gaps(dt, back, period, pattern):
    """(step indices, samples missing, restarts) of the gaps (module docstring)."""
    cand = np.flatnonzero(dt >= GAP_CANDIDATE * period)
    empty = (np.empty(0, np.int64), np.empty(0, np.int64), np.empty(0, bool))
    if not cand.size:
        return empty
    e = np.empty(dt.size + 1)      # the sample clock: time / period - sample number
    e[0] = 0.0
    np.divide(dt, period, out=e[1:])
    e[1:] -= 1.0
    e[1:][back] = 0.0              # a reversal is a restart, not a level
    np.cumsum(e[1:], out=e[1:])
    excess = dt[cand] / (period if np.ndim(period) == 0 else period[cand]) - 1.0
    w = LEVEL_WINDOW
    bursty = pattern is TimestampKind.BURSTY
    if bursty:                          # a window spans several bursts
        cycle = dt.size / max(1, cand.size)
        w = int(min(1024, max(w, math.ceil(BURST_WINDOW_CYCLES * cycle))))
    # the lower envelope, blind to one early stamp (a repeated timestamp): a sample
    # below both neighbours is raised to the lower of them, then the window's min
    lvl = np.empty_like(e)
    lvl[0], lvl[-1] = e[0], e[-1]
    np.minimum(e[:-2], e[2:], out=lvl[1:-1])
    np.maximum(lvl[1:-1], e[1:-1], out=lvl[1:-1])
    _sliding_min(lvl, w, inplace=True)
    after = lvl[cand + 1]                          # e[k+1 .. k+w]
    before = lvl[np.maximum(cand + 1 - w, 0)]      # e[k+1-w .. k]
    n = e.size
    if not bursty:
        return _gaps_in_clusters(e, cand, after, before, w, excess)
    # a window cut short (an end of the record, or the next step that rises) sees too
    # little of the stamps' scatter: with bursts it may hold only the top of one, so
    # its level is taken down by the sample clock's typical range over a window; near
    # an end of the record too (a gap there must stand out of the scatter); before
    # the next rise, without bursts, the window before is cut to the same length
    rises = after - _level_before(cand, after, before, after - before, w) >= 0.5
    room = np.full(cand.size, n)
    nxt = np.flatnonzero(rises)
    if nxt.size:
        j = np.searchsorted(nxt, np.arange(cand.size), side="right")
        has = j < nxt.size
        room[has] = cand[nxt[j[has]]] + 1
    h = np.minimum(np.minimum(room - cand - 1, cand + 1), w)
    short = np.flatnonzero(h < w)
    scatter = 0.0
    if short.size:
        at = cand[::max(1, cand.size // 1000)] + 1      # the range over at most about 2,000 windows
        win = e[np.minimum(at[:, None] + np.arange(w), n - 1)]
        scatter = float(np.median(win.max(axis=1) - lvl[at]))
    for j in short:
        k, hj = int(cand[j]) + 1, max(1, int(h[j]))
        at_end = k < w or k + w > n
        after[j] = _envelope_min(e, k, k + hj) - (scatter if bursty or at_end else 0.0)
        if not bursty:
            before[j] = _envelope_min(e, k - hj, k)
    rise = after - _level_before(cand, after, before, after - before, w)
    resid = rise - np.rint(rise)
    noise = 1.4826 * float(np.median(np.abs(resid)))
    missing = np.rint(rise)
    if not bursty:       # host-stamped bursts may stamp the samples before a gap late: the step is short
        missing = np.minimum(missing, np.rint(excess))
    keep = (rise >= max(0.5, NOISE_SIGMAS * noise)) & (missing >= 1)
    if not keep.any():
        return empty
    gi = cand[keep]
    gm = missing[keep].astype(np.int64)
    # a restart needs the step itself to span the missing samples too: drops inside
    # bursts add up in the sample clock without a long step, and are no break
    return gi, gm, np.minimum(gm, np.rint(excess[keep])) > MAX_BRIDGED_MISSING


def _envelope_min(e, a, b):
    """min over e[a:b] of the lower envelope (each sample below both neighbours
    raised to the lower of them), as the sliding windows see it."""
    lo, hi = max(a - 1, 0), min(b + 1, e.size)
    x = e[lo:hi]
    f = x.copy()
    if x.size > 2:
        np.maximum(f[1:-1], np.minimum(x[:-2], x[2:]), out=f[1:-1])
    if lo == 0:
        f[0] = x[0]
    if hi == e.size:
        f[-1] = x[-1]
    return float(f[a - lo:a - lo + (b - a)].min())


def _gaps_in_clusters(e, cand, after, before, w, excess):
    """Gaps without bursts: candidate steps less than ``w`` samples apart form a
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
    n = e.size
    k = cand + 1
    edge = np.flatnonzero((k < w) | (k + w > n))
    if edge.size:
        at = np.arange(0, k.size, max(1, k.size // 1000))
        win = e[np.minimum(k[at][:, None] + np.arange(w), n - 1)]
        scatter = float(np.median(win.max(axis=1) - after[at]))
        for j in edge:
            kj = int(k[j])
            h = max(1, min(w, kj, n - kj))
            after[j] = _envelope_min(e, kj, kj + h) - scatter
            before[j] = _envelope_min(e, max(0, kj - w), kj)
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
    gi = cand[keep]
    gm = np.rint(missing[keep]).astype(np.int64)
    return gi, gm, np.minimum(gm, np.rint(excess[keep])) > MAX_BRIDGED_MISSING


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


def _runs(rel, dt, back, gaps):
    """([(start, stop, bridged missing, span, cause)], intervals + bridged missing, span) in the raw unit."""
    gi, gm, gr = gaps
    cuts = np.concatenate([np.flatnonzero(back) + 1, gi[gr] + 1])
    is_gap = np.concatenate([np.zeros(int(back.sum()), bool), np.ones(int(gr.sum()), bool)])
    order = np.argsort(cuts, kind="stable")
    cuts, is_gap = cuts[order], is_gap[order]
    starts = np.concatenate([[0], cuts])
    stops = np.concatenate([cuts, [rel.size]])
    spans = rel[stops - 1] - rel[starts]
    bridged = ~gr
    run_of = np.searchsorted(starts, gi[bridged] + 1, side="right") - 1
    miss = np.bincount(run_of, weights=gm[bridged], minlength=starts.size).astype(np.int64)
    count = float(np.sum(stops - starts - 1) + miss.sum())
    cause = [RunStart.START] + [RunStart.GAP if g else RunStart.REVERSAL for g in is_gap]
    runs = list(zip(starts, stops, miss, spans, cause))
    return runs, count, float(spans.sum())


def _kind(dt, back, gaps, period, pattern):
    """(TimestampKind, spread): module docstring."""
    ok = ~back
    ok[gaps[0]] = False
    r = dt[ok]
    r /= period
    r -= 1.0
    np.abs(r, out=r)
    if r.size == 0:
        return TimestampKind.UNIFORM, 0.0
    sub = r[::-(-r.size // 1_000_000)]          # the spread from at most 1 M steps, evenly spread
    k95 = min(sub.size - 1, int(0.95 * sub.size))
    spread = float(np.partition(sub, k95)[k95])
    if pattern is not TimestampKind.UNIFORM:
        return pattern, spread
    if np.count_nonzero(r > UNIFORM_TOLERANCE) > UNIFORM_SHARE * r.size:
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
