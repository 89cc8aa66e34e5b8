"""Emulations of co-simulation hosts our tests cannot run, over fmpy's low-level API.

fmusim (the Modelica Reference-FMUs' command-line host, v0.0.39, co-simulation): written from
its sources (fmusim/FMI2CSSimulation.c, FMI3CSSimulation.c, FMIStaticInput.c, FMIRecorder.c,
FMIUtil.c of github.com/modelica/Reference-FMUs at tag v0.0.39; read, not copied):

* the input file: a header of variable names (the first column the time), one row a time; an
  array variable is one column whose cells hold its values separated by spaces;
* at initialisation the inputs at the start time are set in initialisation mode, then
  ExitInitializationMode, then the outputs are recorded at the start time;
* each step: the next regular point is start + (n + 1) * interval (n the regular steps taken);
  past the stop time (and not within 1e-5 of it) an FMU that cannot vary its step stops; the
  inputs at the step's start time are set, the step is taken, the outputs are recorded at its end;
* an input at time t: a continuous Real interpolated linearly between the rows around t (the row
  whose successor's time is > t, exactly the row at a row's time); a discrete one (Boolean) the
  last row whose time is <= t within fmusim's closeness (after the event);
* closeness: |a - b| <= 1e-5, or relatively <= 1e-5.

A master that accumulates its time (OMSimulator, the FMU Compliance Checker): t += h after each
step, stepping while t < stop, the last step shortened to end at the stop time.
"""
from __future__ import annotations

import numpy as np
import pytest

pytest.importorskip("fmpy")
from fmpy.fmi3 import FMU3Slave  # noqa: E402

FMUSIM_EPSILON = 1e-5


def is_close(a, b):
    """fmusim's FMIIsClose."""
    if not (np.isfinite(a) and np.isfinite(b)):
        return False
    d = abs(a - b)
    return d <= FMUSIM_EPSILON or d <= FMUSIM_EPSILON * max(abs(a), abs(b))


def read_table(text):
    """{column: values} of a CSV in fmusim's format: a column of one value per cell is an array of
    n rows, a column of several (space-separated) an n x m array; quotes around names dropped."""
    lines = [ln for ln in text.splitlines() if ln.strip()]
    names = [n.strip().strip('"') for n in lines[0].split(",")]
    cells = [ln.split(",") for ln in lines[1:]]
    out = {}
    for i, name in enumerate(names):
        rows = [[float(x) for x in row[i].split()] for row in cells]
        arr = np.array(rows)
        out[name] = arr[:, 0] if arr.shape[1] == 1 else arr
    return out


class Driver:
    """Uniform set/get of Real and Boolean variables (scalars or arrays) of an fmpy FMU2Slave or
    FMU3Slave, by name."""

    def __init__(self, slave, md):
        self.s = slave
        self.fmi3 = isinstance(slave, FMU3Slave)
        self.vars = {v.name: v for v in md.modelVariables}

    def _size(self, v):
        return int(np.prod([int(d.start) for d in v.dimensions])) if getattr(v, "dimensions", None) else 1

    def set(self, name, value):
        v = self.vars[name]
        vals = [float(x) for x in np.atleast_1d(value)]
        if v.type == "Boolean":
            self.s.setBoolean([v.valueReference], [bool(x) for x in vals])
        elif self.fmi3:
            self.s.setFloat64([v.valueReference], vals)
        else:
            self.s.setReal([v.valueReference], vals)

    def get(self, name):
        v = self.vars[name]
        n = self._size(v)
        if v.type == "Boolean":
            return float(self.s.getBoolean([v.valueReference])[0])
        vals = self.s.getFloat64([v.valueReference], n) if self.fmi3 else self.s.getReal([v.valueReference])
        return float(vals[0]) if n == 1 else np.array(vals, dtype=float)

    def is_discrete(self, name):
        return self.vars[name].variability in ("discrete", "tunable") or self.vars[name].type == "Boolean"


def fmusim_input_at(inputs, name, time, discrete):
    """The value fmusim sets for input column ``name`` at ``time`` (inputs: read_table's dict)."""
    t = inputs["time"]
    x = inputs[name]
    n = len(t)
    if discrete:
        row = 0
        for j in range(1, n):
            if t[j] > time or is_close(t[j], time):
                break
            row = j
        while row < n - 1 and not (t[row + 1] > time and not is_close(t[row + 1], time)):
            row += 1        # after the event
        return x[row]
    row = 0
    while row < n - 1 and not t[row + 1] > time:
        row += 1
    if row >= n - 1:
        return x[row]
    return x[row] + (time - t[row]) * (x[row + 1] - x[row]) / (t[row + 1] - t[row])


def fmusim_run(slave, md, inputs, outputs, stop_time, interval, start_time=0.0):
    """Drive ``slave`` (an fmpy FMU2Slave or FMU3Slave, instantiated, its experiment set up and in
    initialisation mode) as fmusim's co-simulation loop does for an FMU that cannot vary its step;
    returns {"time": ..., output name: ...} as fmusim records them."""
    d = Driver(slave, md)
    names = [n for n in inputs if n != "time"]

    def apply(time):
        for n in names:
            d.set(n, fmusim_input_at(inputs, n, time, d.is_discrete(n)))

    rec = {"time": []}
    rec.update({o: [] for o in outputs})

    def sample(time):
        rec["time"].append(time)
        for o in outputs:
            rec[o].append(d.get(o))

    time = start_time
    apply(time)
    slave.exitInitializationMode()
    sample(time)
    n_steps = 0
    while not (time > stop_time or is_close(time, stop_time)):
        regular = start_time + (n_steps + 1) * interval
        nxt = regular
        if nxt > stop_time and not is_close(nxt, stop_time):
            break
        apply(time)
        slave.doStep(time, nxt - time)
        time = nxt
        if is_close(time, regular):
            n_steps += 1
        sample(time)
    return {k: np.array(v) for k, v in rec.items()}


def accumulated_run(slave, md, inputs_at, stop_time, h, on_step=None):
    """Drive ``slave`` (initialised, in step mode) as a master that accumulates its time does
    (OMSimulator, the FMU Compliance Checker): t = 0; while t < stop: the inputs ``inputs_at(t)``
    ({name: value}) are set, a step of min(h, stop - t) is taken, t += that step. ``on_step(t, size)``
    is called after each step. Returns the step sizes taken."""
    d = Driver(slave, md)
    t, sizes = 0.0, []
    while t < stop_time:
        size = min(h, stop_time - t)
        for name, value in inputs_at(t).items():
            d.set(name, value)
        slave.doStep(t, size)
        t += size
        sizes.append(size)
        if on_step is not None:
            on_step(t, size)
    return sizes


def row_at(times, t, tol):
    """The row of ``times`` a time ``t`` belongs to: the one within ``tol`` of it, else the last before it."""
    k = int(np.searchsorted(times, t + tol, side="right")) - 1
    return max(k, 0)
